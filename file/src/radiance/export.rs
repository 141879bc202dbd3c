//! Writing a holodeck file as a Radiance holodeck that rholo, rhinfo, rhcopy
//! and rhpict read: rholo's header, then each section's record followed by
//! its beams in Radiance's beam order (the layout rhoptimize leaves). Rays
//! keep their bytes; depth codes of sections in this program's coding are
//! converted to Radiance's, those of imported sections are kept.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::Path;
use std::time::Instant;

use holodeck_protocol::{BeamKey, DepthCoding, RayRecord, Section, RAY_RECORD_BYTES};

use super::error::{RadianceError, Result};
use super::header;
use super::layout::{ByteOrder, GridRecord, Layout};
use super::numbering::RadianceBeams;
use crate::storage::bulk::temp_path;
use crate::storage::{HoloFile, OpenOptions};

const RECORD: u64 = RAY_RECORD_BYTES as u64;
/// Most rays held in memory at once while beams are put in Radiance's order.
const BATCH_RAYS: u64 = 1 << 22;

/// What an export did.
#[derive(Clone, Debug, PartialEq)]
pub struct ExportReport {
    /// Sections written.
    pub sections: usize,
    /// Beams holding rays.
    pub beams: u64,
    /// Rays written.
    pub rays: u64,
    /// Rays whose depth code was converted to Radiance's coding.
    pub converted: u64,
    /// Bytes of the new file.
    pub bytes: u64,
    /// Seconds taken.
    pub seconds: f64,
}

/// A record's depth in Radiance's coding for `section`.
fn to_radiance(section: &Section, radiance: &Section, r: &mut RayRecord) {
    let code = match section.decode_depth(r.depth_code()) {
        Some(d) => radiance.encode_depth(d),
        None => holodeck_protocol::DepthCode::INFINITE,
    };
    r.depth = code.0.to_le_bytes();
}

/// The error of an I/O operation `op` on `path`.
fn io(op: &'static str, path: &Path) -> impl FnOnce(std::io::Error) -> RadianceError {
    let path = path.to_path_buf();
    move |source| RadianceError::Io { path, op, source }
}

/// Writes the holodeck file `src` as the Radiance holodeck `dest` (which
/// must not exist) in `layout` (Radiance's own on 64-bit systems is
/// [`Layout::LP64`]). `progress(rays_done, rays_total)` is called as beams are written.
pub fn export(src: &Path, dest: &Path, layout: Layout, mut progress: impl FnMut(u64, u64)) -> Result<ExportReport> {
    let start = Instant::now();
    let holo = HoloFile::open(src, &OpenOptions::read_only())?;
    let tmp = temp_path(dest, "export");
    let file = File::create(&tmp).map_err(io("creating", &tmp))?;
    let mut export = Export {
        total: holo.summary().rays(),
        holo,
        src,
        tmp: &tmp,
        layout,
        out: BufWriter::with_capacity(1 << 20, file),
        bytes: Vec::new(),
        report: ExportReport {
            sections: 0,
            beams: 0,
            rays: 0,
            converted: 0,
            bytes: 0,
            seconds: 0.0,
        },
    };
    let mut report = match export.write(&mut progress) {
        Ok(r) => r,
        Err(e) => {
            let _ = std::fs::remove_file(&tmp);
            return Err(e);
        }
    };
    // Linking fails if the name exists: an export never replaces a file.
    let linked = std::fs::hard_link(&tmp, dest).map_err(io("creating", dest));
    let _ = std::fs::remove_file(&tmp);
    linked?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// An export under way into its temporary file.
struct Export<'a> {
    holo: HoloFile,
    src: &'a Path,
    tmp: &'a Path,
    layout: Layout,
    out: BufWriter<File>,
    /// Rays in the file, for progress.
    total: u64,
    /// Rays in Radiance's layout, reused beam after beam.
    bytes: Vec<u8>,
    report: ExportReport,
}

impl Export<'_> {
    /// Writes the header, then each section's record and beams; synced.
    fn write(&mut self, progress: &mut dyn FnMut(u64, u64)) -> Result<ExportReport> {
        let settings = self.holo.settings().clone();
        let text = header::write(&settings, self.layout.order == ByteOrder::Big);
        let mut pos = text.len() as u64 + 4;
        self.out.write_all(text.as_bytes()).map_err(io("writing", self.tmp))?;
        self.out
            .write_all(&self.layout.magic_bytes())
            .map_err(io("writing", self.tmp))?;
        self.report.sections = settings.sections.len();
        for (s, section) in settings.sections.iter().enumerate() {
            let last = s + 1 == settings.sections.len();
            pos = self.section(s, section, pos, last, progress)?;
        }
        self.out.flush().map_err(io("writing", self.tmp))?;
        self.out.get_ref().sync_all().map_err(io("syncing", self.tmp))?;
        self.report.bytes = pos;
        Ok(self.report.clone())
    }

    /// Section `s` at byte `pos`: its record, then its beams right after
    /// it in Radiance's order. Where the next section starts.
    fn section(
        &mut self,
        s: usize,
        section: &Section,
        pos: u64,
        last: bool,
        progress: &mut dyn FnMut(u64, u64),
    ) -> Result<u64> {
        let layout = self.layout;
        let ours = RadianceBeams::ours(section);
        let counts: Vec<u32> = {
            let dir = self.holo.directory(s as u32).unwrap_or(&[]);
            ours.iter()
                .map(|&b| dir.get(b as usize).map_or(0, |e| e.count))
                .collect()
        };
        let record_end = pos + layout.record_bytes(counts.len() as u64);
        let rays_bytes: u64 = counts.iter().map(|&c| u64::from(c) * RECORD).sum();
        let next = if last { 0 } else { record_end + rays_bytes };
        if record_end + rays_bytes > layout.max_offset() {
            return Err(RadianceError::Invalid {
                what: format!("section {s}"),
                at: pos,
                detail: format!(
                    "its rays reach past byte {}, the most this layout can address",
                    layout.max_offset()
                ),
            });
        }
        let mut record = vec![0u8; layout.record_bytes(counts.len() as u64) as usize];
        let p = layout.pointer_bytes() as usize;
        layout.put_offset(next, &mut record[..p]);
        let spec = section.spec();
        let grid = GridRecord {
            origin: spec.origin,
            axes: spec.axes,
            grid: section.grid().map(|g| g as i16),
        };
        record[p..p + super::layout::GRID_BYTES as usize].copy_from_slice(&layout.put_grid(&grid));
        let mut at = record_end;
        let entries = &mut record[p + super::layout::GRID_BYTES as usize..];
        for (k, &count) in counts.iter().enumerate() {
            let e = usize::from(layout.entry_bytes);
            let position = if count > 0 { at } else { 0 };
            layout.put_entry(count, position, &mut entries[k * e..(k + 1) * e]);
            at += u64::from(count) * RECORD;
        }
        self.out.write_all(&record).map_err(io("writing", self.tmp))?;
        // Beams in Radiance's order, read in batches in the file's own order.
        let mut first = 0usize;
        while first < ours.len() {
            let mut end = first;
            let mut rays = 0u64;
            while end < ours.len() && (end == first || rays + u64::from(counts[end]) <= BATCH_RAYS) {
                rays += u64::from(counts[end]);
                end += 1;
            }
            self.beams(s, section, &ours[first..end], &counts[first..end])?;
            progress(self.report.rays, self.total);
            first = end;
        }
        Ok(at)
    }

    /// Writes the beams `ours` (Radiance's numbers, in its order) of
    /// section `s`, holding `counts` rays each, read in one batch.
    fn beams(&mut self, s: usize, section: &Section, ours: &[u32], counts: &[u32]) -> Result<()> {
        let radiance = section.clone().with_depth_coding(DepthCoding::Radiance);
        let convert = section.depth_coding() != DepthCoding::Radiance;
        let keys: Vec<BeamKey> = (0..ours.len())
            .filter(|&k| counts[k] > 0)
            .map(|k| BeamKey::new(s as u32, ours[k]))
            .collect();
        let mut got: Vec<Option<Vec<RayRecord>>> = vec![None; ours.len()];
        let index: std::collections::HashMap<u32, usize> = ours.iter().enumerate().map(|(i, &b)| (b, i)).collect();
        let read = self.holo.read_beams(&keys, |key, rays| {
            if let Some(&i) = index.get(&key.beam) {
                got[i] = Some(rays.to_vec());
            }
        })?;
        if let Some(&key) = read.corrupt.first() {
            return Err(self.holo.corrupt(key).into());
        }
        for (k, got) in got.iter_mut().enumerate() {
            let Some(mut rays) = got.take() else { continue };
            if rays.len() != counts[k] as usize {
                return Err(RadianceError::Invalid {
                    what: format!("{}: section {s} beam {}", self.src.display(), ours[k]),
                    at: 0,
                    detail: format!("read {} rays of the {} its directory lists", rays.len(), counts[k]),
                });
            }
            if convert {
                rays.iter_mut().for_each(|r| to_radiance(section, &radiance, r));
                self.report.converted += rays.len() as u64;
            }
            self.bytes.clear();
            self.layout.records_to_rays(&rays, &mut self.bytes);
            self.out.write_all(&self.bytes).map_err(io("writing", self.tmp))?;
            self.report.rays += rays.len() as u64;
            self.report.beams += 1;
        }
        Ok(())
    }
}
