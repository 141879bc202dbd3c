//! Reading a Radiance holodeck: its header, its chain of sections and their
//! directories, checked against the file's length before any ray is read;
//! then every beam copied into a new holodeck file, in this program's beam
//! order, with each ray's bytes kept (only a big-endian depth code is
//! swapped) and its sections set to Radiance's depth coding.

use std::path::Path;
use std::time::Instant;

use holodeck_protocol::{
    BeamKey, DepthCoding, RayRecord, Section, SectionError, SectionKind, SectionSpec, RAY_RECORD_BYTES,
};

use super::error::{RadianceError, Result};
use super::header::{self, Header, Variables, MAX_HEADER};
use super::layout::{GridRecord, Layout};
use super::numbering::RadianceBeams;
use super::source::{FileSource, Source};
use crate::settings::Settings;
use crate::storage::bulk::SequentialWriter;

const RECORD: u64 = RAY_RECORD_BYTES as u64;

/// Bytes `start..end` of a Radiance file and what lies there: `None` a
/// record (the header, a section's record and directory), `Some((s, k))`
/// the rays of section `s`'s beam at index `k`.
type Span = (u64, u64, Option<(usize, usize)>);

/// One section of a Radiance holodeck.
#[derive(Clone, Debug)]
pub struct RadianceSection {
    /// Where its record starts.
    pub at: u64,
    /// The grid as stored.
    pub grid: GridRecord,
    /// The section it makes here (interior, Radiance's depth coding).
    pub section: Section,
    /// Per Radiance beam number `1..=n` (at `number - 1`): ray count and file position.
    pub beams: Vec<(u32, u64)>,
}

/// A Radiance holodeck's structure, checked: every beam's rays lie in the file.
#[derive(Clone, Debug)]
pub struct RadianceFile {
    /// The header.
    pub header: Header,
    /// Byte order and offset sizes.
    pub layout: Layout,
    /// The sections, in chain order.
    pub sections: Vec<RadianceSection>,
    /// The file's length.
    pub len: u64,
    /// With loss accepted: what was left out (a beam cut off by the file's
    /// end, beams whose rays overlap, sections cut off), one line each, and
    /// the rays the directories gave them.
    pub lost: Vec<String>,
    /// Rays of the beams left out (as their directories counted them).
    pub lost_rays: u64,
}

fn read(src: &(impl Source + ?Sized), what: impl Fn() -> String, at: u64, n: u64) -> Result<Vec<u8>> {
    let end = at.checked_add(n).filter(|e| *e <= src.len());
    let Some(end) = end else {
        return Err(RadianceError::Truncated {
            what: what(),
            start: at,
            end: at.saturating_add(n),
            len: src.len(),
        });
    };
    let mut buf = vec![0u8; (end - at) as usize];
    src.read_at(at, &mut buf).map_err(|e| RadianceError::Invalid {
        what: what(),
        at,
        detail: format!("cannot be read: {e}"),
    })?;
    Ok(buf)
}

impl RadianceFile {
    /// Reads and checks the structure: header, magic number, the section
    /// chain and every directory entry, and that no two beams' rays overlap
    /// each other or the file's records. Reads no rays.
    pub fn parse(src: &(impl Source + ?Sized)) -> Result<RadianceFile> {
        Self::parse_salvaging(src, false)
    }

    /// As [`RadianceFile::parse`]; with `accept_loss`, what cannot be read
    /// is left out and listed in `lost` instead of refusing the file: a beam
    /// whose rays lie past the file's end or at a negative position, both
    /// beams of an overlap, and the sections after one whose record or
    /// directory is cut off (the header, the magic number and the first
    /// section's record must be whole).
    pub fn parse_salvaging(src: &(impl Source + ?Sized), accept_loss: bool) -> Result<RadianceFile> {
        let len = src.len();
        let mut lost = Vec::new();
        let mut lost_rays = 0u64;
        let head = read(src, || "header".into(), 0, len.min(MAX_HEADER as u64))?;
        let header = header::parse(&head)?;
        let magic_at = header.len;
        let magic = read(src, || "magic number".into(), magic_at, 4)?;
        let magic = [magic[0], magic[1], magic[2], magic[3]];
        let layout = Layout::from_magic(magic).ok_or(RadianceError::Magic {
            at: magic_at,
            little: u32::from_le_bytes(magic),
            big: u32::from_be_bytes(magic),
        })?;
        let big = layout.order == super::layout::ByteOrder::Big;
        if let Some(said) = header.big_endian.filter(|b| (*b == 1) != big) {
            return Err(RadianceError::ByteOrderMismatch {
                said,
                found: layout.order.name(),
            });
        }
        let mut sections = Vec::new();
        let mut at = magic_at + 4;
        loop {
            let index = sections.len();
            let record = match read(src, || format!("section {index}'s record"), at, layout.record_bytes(0)) {
                Err(e) if accept_loss && index > 0 => {
                    lost.push(format!("sections from {index} on: {e}"));
                    break;
                }
                r => r?,
            };
            let next = layout.offset(&record);
            let grid = layout.grid(&record[layout.pointer_bytes() as usize..]);
            let section = section_of(&grid).map_err(|source| RadianceError::Section { index, at, source })?;
            let n = u64::from(section.beam_count());
            let dir_at = at + layout.record_bytes(0);
            let dir = match read(
                src,
                || format!("section {index}'s directory of {n} beams"),
                dir_at,
                n * u64::from(layout.entry_bytes),
            ) {
                Err(e) if accept_loss && index > 0 => {
                    lost.push(format!("sections from {index} on: {e}"));
                    break;
                }
                r => r?,
            };
            let mut beams = Vec::with_capacity(n as usize);
            for (k, e) in dir.chunks_exact(usize::from(layout.entry_bytes)).enumerate() {
                let (count, position) = layout.entry(e);
                let entry_at = dir_at + k as u64 * u64::from(layout.entry_bytes);
                if count == 0 {
                    // rholo marks a directory it is rewriting with position -1 and no rays.
                    beams.push((0, 0));
                    continue;
                }
                let what = || format!("section {index} beam {} (Radiance's numbering)", k + 1);
                let checked = match u64::try_from(position) {
                    Err(_) => Err(RadianceError::Invalid {
                        what: what(),
                        at: entry_at,
                        detail: format!("{count} rays at the negative position {position}"),
                    }),
                    Ok(position) => match position.checked_add(u64::from(count) * RECORD).filter(|e| *e <= len) {
                        Some(_) => Ok(position),
                        None => Err(RadianceError::Truncated {
                            what: format!("{}'s {count} rays", what()),
                            start: position,
                            end: position.saturating_add(u64::from(count) * RECORD),
                            len,
                        }),
                    },
                };
                match checked {
                    Ok(position) => beams.push((count, position)),
                    Err(e) if accept_loss => {
                        lost.push(e.to_string());
                        lost_rays += u64::from(count);
                        beams.push((0, 0));
                    }
                    Err(e) => return Err(e),
                }
            }
            let record_end = dir_at + n * u64::from(layout.entry_bytes);
            sections.push(RadianceSection {
                at,
                grid,
                section,
                beams,
            });
            match next {
                0 => break,
                p if p > 0 && p as u64 >= record_end => at = p as u64,
                p => {
                    return Err(RadianceError::Invalid {
                        what: format!("section {index}'s pointer to the next section"),
                        at,
                        detail: format!("{p} does not lie past the section's record (which ends at byte {record_end})"),
                    })
                }
            }
        }
        let mut file = RadianceFile {
            header,
            layout,
            sections,
            len,
            lost,
            lost_rays,
        };
        file.check_overlaps(magic_at + 4, accept_loss)?;
        Ok(file)
    }

    /// Refuses (or, with `accept_loss`, leaves out) beams whose rays overlap
    /// another beam's rays, a section's record or directory, or the header:
    /// a flipped position would otherwise import another beam's bytes as rays.
    fn check_overlaps(&mut self, header_end: u64, accept_loss: bool) -> Result<()> {
        let mut extents: Vec<Span> = vec![(0, header_end, None)];
        for (s, section) in self.sections.iter().enumerate() {
            let n = section.beams.len() as u64;
            let end = section.at + self.layout.record_bytes(0) + n * u64::from(self.layout.entry_bytes);
            extents.push((section.at, end, None));
            for (k, &(count, position)) in section.beams.iter().enumerate() {
                if count > 0 {
                    extents.push((position, position + u64::from(count) * RECORD, Some((s, k))));
                }
            }
        }
        extents.sort_unstable();
        let name = |o: Option<(usize, usize)>| match o {
            Some((s, k)) => format!("section {s} beam {} (Radiance's numbering)", k + 1),
            None => "a section's record and directory, or the header".to_string(),
        };
        let mut bad: Vec<(usize, usize)> = Vec::new();
        // The extent reaching furthest so far, to catch overlaps with any earlier one.
        let mut reach: Option<Span> = None;
        for &(start, end, owner) in &extents {
            if let Some((r_start, r_end, r_owner)) = reach {
                if start < r_end {
                    if !accept_loss {
                        return Err(RadianceError::Invalid {
                            what: format!("{}'s rays at bytes {start}..{end}", name(owner)),
                            at: start,
                            detail: format!("they overlap {} at bytes {r_start}..{r_end}", name(r_owner)),
                        });
                    }
                    bad.extend(owner);
                    bad.extend(r_owner);
                }
            }
            if reach.is_none_or(|r| end > r.1) {
                reach = Some((start, end, owner));
            }
        }
        bad.sort_unstable();
        bad.dedup();
        for (s, k) in bad {
            let (count, position) = self.sections[s].beams[k];
            self.lost.push(format!(
                "{}'s {count} rays at bytes {position}..{} overlap other data",
                name(Some((s, k))),
                position + u64::from(count) * RECORD
            ));
            self.lost_rays += u64::from(count);
            self.sections[s].beams[k] = (0, 0);
        }
        Ok(())
    }

    /// Rays in all sections.
    pub fn rays(&self) -> u64 {
        self.sections
            .iter()
            .flat_map(|s| s.beams.iter())
            .map(|(n, _)| u64::from(*n))
            .sum()
    }

    /// The rays of one beam (Radiance numbering, from 1) as this program's records.
    pub fn read_beam(&self, src: &(impl Source + ?Sized), section: usize, number: u64) -> Result<Vec<RayRecord>> {
        let (count, position) = self.sections[section].beams[(number - 1) as usize];
        let mut bytes = read(
            src,
            || format!("section {section} beam {number}'s rays"),
            position,
            u64::from(count) * RECORD,
        )?;
        self.layout.rays_to_records(&mut bytes);
        // The length is a whole number of records by construction.
        Ok(RayRecord::vec_from_bytes(&bytes).unwrap_or_default())
    }
}

/// The section a stored grid makes: any grid this program holds, with
/// Radiance's depth coding; interior until told otherwise.
fn section_of(g: &GridRecord) -> std::result::Result<Section, SectionError> {
    let mut grid = [0u16; 3];
    for (axis, &n) in g.grid.iter().enumerate() {
        grid[axis] = u16::try_from(n).map_err(|_| SectionError::GridOutOfRange { axis, size: n as u32 })?;
    }
    SectionSpec {
        depth: Some(DepthCoding::Radiance),
        ..SectionSpec::new(SectionKind::Interior, g.origin, g.axes, grid)
    }
    .resolve(None, None)
}

/// How to import.
#[derive(Clone, Debug, Default)]
pub struct ImportOptions {
    /// The kind of every section; without it, the kinds the file records
    /// (if this program wrote it), else interior.
    pub kind: Option<SectionKind>,
    /// Import what can be read of a damaged file (see
    /// [`RadianceFile::parse_salvaging`]), listing what was left out.
    pub accept_loss: bool,
}

/// What an import did.
#[derive(Clone, Debug, PartialEq)]
pub struct ImportReport {
    /// Byte order and offset sizes of the source.
    pub layout: Layout,
    /// Sections imported.
    pub sections: usize,
    /// Beams holding rays.
    pub beams: u64,
    /// Rays imported.
    pub rays: u64,
    /// Seconds taken.
    pub seconds: f64,
    /// Header lines not carried over, as written.
    pub unused: Vec<String>,
    /// Anything else worth telling (a section count that disagrees with the `section=` lines).
    pub notes: Vec<String>,
    /// With loss accepted: what was left out, one line each.
    pub lost: Vec<String>,
    /// Rays left out (as the damaged file's directories counted them).
    pub lost_rays: u64,
}

/// The settings a Radiance file makes, with its sections.
pub fn settings_of(file: &RadianceFile, options: &ImportOptions) -> (Settings, Variables) {
    let vars = file.header.variables();
    let mut settings = vars.settings.clone();
    let recorded = vars.kinds.as_ref().filter(|k| k.len() == file.sections.len());
    settings.sections = file
        .sections
        .iter()
        .enumerate()
        .map(|(i, s)| {
            let kind = options
                .kind
                .or_else(|| recorded.map(|k| k[i]))
                .unwrap_or(SectionKind::Interior);
            let spec = SectionSpec {
                kind,
                ..s.section.spec()
            };
            // Changing the kind keeps a valid section valid.
            spec.resolve(None, None).unwrap_or_else(|_| s.section.clone())
        })
        .collect();
    (settings, vars)
}

/// Imports the Radiance holodeck `src` into a new holodeck file `dest` (which
/// must not exist). `progress(rays_done, rays_total)` is called as beams are copied.
pub fn import(
    src: &Path,
    dest: &Path,
    options: &ImportOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<ImportReport> {
    let start = Instant::now();
    let io = |op: &'static str| {
        let path = src.to_path_buf();
        move |source| RadianceError::Io { path, op, source }
    };
    let file = std::fs::File::open(src).map_err(io("opening"))?;
    let source = FileSource::new(file).map_err(io("reading the length of"))?;
    let radiance = RadianceFile::parse_salvaging(&source, options.accept_loss)?;
    let (settings, vars) = settings_of(&radiance, options);
    let mut notes = Vec::new();
    if vars.section_lines != radiance.sections.len() {
        notes.push(format!(
            "the header has {} section= line(s) for {} section(s): the sections' binary grids were used",
            vars.section_lines,
            radiance.sections.len()
        ));
    }
    let total = radiance.rays();
    let mut out = SequentialWriter::create(dest, &settings)?;
    let (mut done, mut beams) = (0u64, 0u64);
    for (s, section) in radiance.sections.iter().enumerate() {
        let table = RadianceBeams::new(section.section.grid());
        // In this program's beam order, so that the new file is collated.
        let mut order: Vec<(u32, u64)> = Vec::new();
        for beam in 0..section.section.beam_count() {
            let Ok(cells) = section.section.beam_cells(beam) else {
                continue;
            };
            let number = table.index(cells);
            if section.beams[(number - 1) as usize].0 > 0 {
                order.push((beam, number));
            }
        }
        for (beam, number) in order {
            let rays = radiance.read_beam(&source, s, number)?;
            out.push_beam(BeamKey::new(s as u32, beam), &rays)?;
            done += rays.len() as u64;
            beams += 1;
            if beams.is_multiple_of(4096) {
                progress(done, total);
            }
        }
    }
    out.finish()?;
    progress(done, total);
    Ok(ImportReport {
        layout: radiance.layout,
        sections: radiance.sections.len(),
        beams,
        rays: done,
        seconds: start.elapsed().as_secs_f64(),
        unused: vars.unused,
        notes,
        lost: radiance.lost.clone(),
        lost_rays: radiance.lost_rays,
    })
}
