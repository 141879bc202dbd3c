//! Finding the state of a file on open: every copy of the header, the commit
//! slots, the roots and the directory blocks is read and checked, damage is
//! told apart from a commit a crash interrupted, and a directory is planned
//! from what verifies. It never writes.
//!
//! The rules that tell damage from a torn commit follow from how a commit is
//! written (see [`disk`](super::disk)): its root and directory blocks are
//! synced before either copy of its slot is written, copy 1 of the slot is
//! written and synced before copy 2, and the commit counts only once both are.
//! So:
//! * a slot copy that verifies points at a root and blocks that were synced:
//!   if they do not verify, that is damage, never a crash;
//! * a crash tears at most one slot copy, and only copy 1 while copy 2 still
//!   holds an older commit, or copy 2 while copy 1 already holds the new one:
//!   either way no completed commit is lost, so a failing copy is reported
//!   (it may be damage) but costs nothing while its twin verifies;
//! * both copies of a slot failing is damage, and may hide the newest commit.
//!
//! When the newest commit cannot be read in full, the plan keeps every beam of
//! it that can be, takes each chunk whose directory is lost from the commit
//! before (its runs may have been overwritten since: their checksums tell),
//! and drops beams whose runs lie past the end of the file or overlap others.

use std::fs::File;
use std::path::Path;

use super::error::{CommitDamage, Result, StorageError};
use super::format::{self, BeamEntry, ChunkRef, Extent, FormatError, Prefix, Slot, COPIES, HEADER_ALIGN, MAX_TEXT_LEN};
use super::found::{read_part, Survey};
use super::io;
use crate::settings::Settings;

/// A slot copy as found.
#[derive(Clone, Debug)]
enum SlotCopy {
    Good(Slot),
    Empty,
    Bad(String),
}

fn format_err(path: &Path, source: FormatError) -> StorageError {
    StorageError::Format {
        path: path.to_path_buf(),
        source,
    }
}

/// Finds the settings-text length: from the first prefix, else from a second
/// header copy at a page boundary that agrees with its own prefix.
fn find_prefix(
    file: &File,
    path: &Path,
    file_len: u64,
    bad: &mut [bool; COPIES],
    repaired: &mut Vec<String>,
) -> Result<format::Prefix> {
    let first = read_part(file, path, 0, format::PREFIX_LEN.min(file_len), file_len, "file prefix")?;
    let first = match first {
        Ok(bytes) => format::decode_prefix(&bytes, 0),
        Err(e) => Err(e),
    };
    // A damaged first copy (even one whose version field reads as another
    // format's) is passed over if the second copy verifies.
    let err = match first {
        Ok(p) => return Ok(p),
        Err(e) => e,
    };
    // The first copy is damaged: look for the second one where it can be.
    let last = (format::header_span(MAX_TEXT_LEN).max(format::COPY_GAP) + format::PREFIX_LEN).min(file_len);
    let mut at = HEADER_ALIGN;
    let mut buf = Vec::new();
    while at + format::PREFIX_LEN <= last {
        io::read_at(file, path, at, format::PREFIX_LEN as usize, &mut buf)?;
        if let Ok(p) = format::decode_prefix(&buf, at) {
            if p.version >= 2 && format::header_stride(p) == at {
                bad[0] = true;
                repaired.push(format!("header copy 1: {err}; copy 2 at byte {at} verifies"));
                return Ok(p);
            }
        }
        at += HEADER_ALIGN;
    }
    Err(format_err(path, err))
}

/// Reads both header copies: the settings and the text length.
/// Reads both header copies of a file whose prefix gives `text_len`: the
/// settings (from either copy of the text).
fn read_header(file: &File, path: &Path, file_len: u64, prefix: Prefix, s: &mut Findings) -> Result<Settings> {
    let text_len = prefix.text_len;
    let second_at = format::header_stride(prefix);
    if !s.bad_header[0] {
        let second = read_part(file, path, second_at, format::PREFIX_LEN, file_len, "file prefix")?;
        let ok = second.and_then(|b| format::decode_prefix(&b, second_at));
        match ok {
            Ok(p) if p == prefix => {}
            Ok(p) => {
                s.bad_header[1] = true;
                s.repaired.push(format!(
                    "header copy 2 at byte {second_at} says format {} with a settings text of {} bytes, copy 1 says \
                     format {} with {text_len}",
                    p.version, p.text_len, prefix.version
                ));
            }
            Err(e) => {
                s.bad_header[1] = true;
                s.repaired.push(format!("header copy 2: {e}; copy 1 verifies"));
            }
        }
    }
    let copies: Vec<Extent> = (0..COPIES)
        .map(|copy| Extent {
            offset: format::text_offset(prefix, copy),
            len: u64::from(text_len) + 4,
        })
        .collect();
    let (text, errors) = first_good_copy(file, path, &copies, file_len, "settings text", |b, e| {
        format::decode_text(b, e.offset)
    })?;
    for (copy, _) in &errors {
        s.bad_header[*copy] = true;
    }
    let text = settle(text, errors, "settings text", "settings text", &mut s.repaired).map_err(|detail| {
        format_err(
            path,
            FormatError::Invalid {
                what: "settings text".into(),
                at: format::text_offset(prefix, 0),
                detail,
            },
        )
    })?;
    let settings = Settings::from_text(&text).map_err(|source| StorageError::Settings {
        path: path.to_path_buf(),
        source,
    })?;
    Ok(settings)
}

/// Notes gathered while surveying.
#[derive(Default)]
struct Findings {
    repaired: Vec<String>,
    torn: Vec<String>,
    problems: Vec<String>,
    bad_header: [bool; COPIES],
    uneven_slots: [bool; 2],
}

const SIDE: [&str; 2] = ["A", "B"];

/// Reads the four slot copies and classifies them; returns the good slots,
/// newest first, as (side, slot).
fn read_slots(file: &File, path: &Path, prefix: Prefix, file_len: u64, s: &mut Findings) -> Result<Vec<(usize, Slot)>> {
    let mut copies = [[SlotCopy::Empty, SlotCopy::Empty], [SlotCopy::Empty, SlotCopy::Empty]];
    for (copy, row) in copies.iter_mut().enumerate() {
        for (side, cell) in row.iter_mut().enumerate() {
            let at = format::slot_offset(prefix, copy, side);
            let what = format!("commit slot at byte {at}");
            *cell = match read_part(file, path, at, format::SLOT_LEN, file_len, &what)?
                .and_then(|b| format::decode_slot(&b, at))
            {
                Ok(Some(slot)) => SlotCopy::Good(slot),
                Ok(None) => SlotCopy::Empty,
                Err(e) => SlotCopy::Bad(e.to_string()),
            };
        }
    }
    let newest = copies
        .iter()
        .flatten()
        .filter_map(|c| match c {
            SlotCopy::Good(s) => Some(s.generation),
            _ => None,
        })
        .max()
        .unwrap_or(0);
    for side in 0..2 {
        let (one, two) = (&copies[0][side], &copies[1][side]);
        let name = SIDE[side];
        s.uneven_slots[side] = match (one, two) {
            (SlotCopy::Good(a), SlotCopy::Good(b)) => a != b,
            (SlotCopy::Empty, SlotCopy::Empty) => false,
            _ => true,
        };
        match (one, two) {
            (SlotCopy::Bad(e1), SlotCopy::Bad(e2)) => s.problems.push(format!(
                "both copies of commit slot {name} are damaged, so a commit newer than {newest} may be lost ({e1}; {e2})"
            )),
            (SlotCopy::Bad(e), SlotCopy::Good(g)) if g.generation == newest => s
                .repaired
                .push(format!("copy 1 of commit slot {name}: {e}; copy 2 holds commit {newest}")),
            // Copy 1 is written first: failing while copy 2 is older, it is
            // damage or a commit a crash cut short. Either way no completed
            // commit is lost.
            (SlotCopy::Bad(e), _) => s.repaired.push(format!(
                "copy 1 of commit slot {name}: {e} (damage, or a commit cut short by a crash); \
                 no completed commit is lost"
            )),
            (SlotCopy::Good(g), SlotCopy::Bad(e)) => s.repaired.push(format!(
                "copy 2 of commit slot {name}: {e}; copy 1 holds commit {}",
                g.generation
            )),
            (SlotCopy::Empty, SlotCopy::Bad(e)) => s
                .repaired
                .push(format!("copy 2 of commit slot {name}: {e}; the slot was never used")),
            (SlotCopy::Empty, SlotCopy::Good(g)) => s.repaired.push(format!(
                "copy 1 of commit slot {name} is blank; copy 2 holds commit {}",
                g.generation
            )),
            (SlotCopy::Good(a), SlotCopy::Good(b)) if a != b && a.generation > b.generation => s.torn.push(format!(
                "a crash interrupted commit {} between its two slot copies; copy 1 holds it, nothing is lost",
                a.generation
            )),
            (SlotCopy::Good(a), SlotCopy::Empty) => s.torn.push(format!(
                "a crash interrupted commit {} between its two slot copies; copy 1 holds it, nothing is lost",
                a.generation
            )),
            (SlotCopy::Good(a), SlotCopy::Good(b)) if a != b => s.repaired.push(format!(
                "copy 1 of commit slot {name} holds commit {}, copy 2 commit {}",
                a.generation, b.generation
            )),
            _ => {}
        }
    }
    let mut good: Vec<(usize, Slot)> = Vec::new();
    for row in &copies {
        for (side, c) in row.iter().enumerate() {
            if let SlotCopy::Good(slot) = c {
                if !good.iter().any(|(_, g)| g == slot) {
                    good.push((side, *slot));
                }
            }
        }
    }
    good.sort_by_key(|(_, s)| std::cmp::Reverse(s.generation));
    Ok(good)
}

/// What [`first_good_copy`] found: the first copy that verifies, if any, and
/// for each copy that does not, its index and why.
type Copies<T> = (Option<T>, Vec<(usize, String)>);

/// Reads and decodes every copy at `copies`; returns the first that
/// verifies, and for each copy that does not, its index and why.
fn first_good_copy<T>(
    file: &File,
    path: &Path,
    copies: &[Extent],
    file_len: u64,
    what: &str,
    mut decode: impl FnMut(&[u8], Extent) -> std::result::Result<T, FormatError>,
) -> Result<Copies<T>> {
    let mut found = None;
    let mut errors = Vec::new();
    // Every copy is read, even after one verified: a damaged twin is reported.
    for (copy, &e) in copies.iter().enumerate() {
        match read_part(file, path, e.offset, e.len, file_len, what)?.and_then(|b| decode(&b, e)) {
            Ok(t) if found.is_none() => found = Some(t),
            Ok(_) => {}
            Err(err) => errors.push((copy, format!("copy {}: {err}", copy + 1))),
        }
    }
    Ok((found, errors))
}

/// What [`first_good_copy`] found: the value, with a note per damaged copy
/// (nothing lost) in `notes`; or, when no copy verifies, why, as a problem
/// that names `lost`.
fn settle<T>(
    found: Option<T>,
    errors: Vec<(usize, String)>,
    label: &str,
    lost: &str,
    notes: &mut Vec<String>,
) -> std::result::Result<T, String> {
    let errors: Vec<String> = errors.into_iter().map(|(_, e)| e).collect();
    match found {
        Some(t) => {
            notes.extend(errors.iter().map(|e| format!("{label}, {e}; the other copy verifies")));
            Ok(t)
        }
        None => Err(format!("{lost}: no copy verifies ({})", errors.join("; "))),
    }
}

/// The root of `slot`, from whichever copy verifies; records damaged copies.
fn read_root(
    file: &File,
    path: &Path,
    slot: &Slot,
    beams: &[u32],
    file_len: u64,
    notes: &mut Vec<String>,
) -> Result<std::result::Result<Vec<ChunkRef>, String>> {
    let label = format!("root of commit {}", slot.generation);
    let (found, errors) = first_good_copy(file, path, &slot.root_copies(), file_len, &label, |b, e| {
        let computed = crc32c::crc32c(b);
        if computed != slot.root_crc {
            return Err(FormatError::Checksum {
                what: label.clone(),
                start: e.offset,
                end: e.end(),
                stored: slot.root_crc,
                computed,
            });
        }
        format::decode_root(b, e.offset, slot.generation, beams)
    })?;
    Ok(settle(found, errors, &label, &label, notes))
}

/// The entries of one chunk, from whichever copy of its block verifies.
fn read_chunk(
    file: &File,
    path: &Path,
    c: &ChunkRef,
    data_start: u64,
    file_len: u64,
    notes: &mut Vec<String>,
) -> Result<std::result::Result<Vec<BeamEntry>, String>> {
    let label = format!(
        "directory of section {} beams {}..{}",
        c.section,
        c.first,
        c.first + c.beams
    );
    let (found, errors) = if c.len > format::max_directory_len(c.beams) {
        let why = format!("a block of {} bytes is too long for {} beams", c.len, c.beams);
        (None, vec![(0, why)])
    } else {
        first_good_copy(file, path, &c.extents(), file_len, &label, |b, e| {
            format::decode_directory(b, e.offset, c.section, c.first, c.beams, data_start)
        })?
    };
    Ok(settle(
        found,
        errors,
        &label,
        &format!("{label} ({} rays)", c.rays),
        notes,
    ))
}

/// Who claims some bytes, in the order that wins an overlap.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
enum Claim {
    NewestMeta,
    NewestBeam(u32, u32),
    OlderMeta,
    OlderBeam(u32, u32),
}

/// Surveys the file. Fails only when nothing can be read: no settings, or no
/// commit slot that verifies.
pub(crate) fn survey(file: &File, path: &Path) -> Result<Survey> {
    let file_len = io::file_len(file, path)?;
    let mut f = Findings::default();
    let prefix = find_prefix(file, path, file_len, &mut f.bad_header, &mut f.repaired)?;
    if prefix.version < 2 {
        return super::legacy::survey_v1(file, path, file_len, prefix.text_len);
    }
    let text_len = prefix.text_len;
    let settings = read_header(file, path, file_len, prefix, &mut f)?;
    let data_start = format::data_start(prefix);
    let beams: Vec<u32> = settings.sections.iter().map(|s| s.beam_count()).collect();
    let slots = read_slots(file, path, prefix, file_len, &mut f)?;
    let Some(&(side, newest)) = slots.first() else {
        let mut problems = std::mem::take(&mut f.problems);
        problems.extend(f.torn);
        if problems.is_empty() {
            problems.push("neither commit slot holds a commit".into());
        }
        return Err(StorageError::NoValidCommit {
            path: path.to_path_buf(),
            problems: problems.join("\n"),
        });
    };
    let at = Place {
        file,
        path,
        beams: &beams,
        data_start,
        file_len,
    };
    let mut read = at.newest(&newest, &mut f)?;
    let fallback = at.fall_back(&slots, &newest, &mut read)?;
    let Directories {
        mut dirs,
        claims,
        claimed_rays,
        clean_chunks,
        weak_chunks,
        ..
    } = read;
    let metadata = plan_claims(&mut dirs, claims, data_start, file_len, &mut f.problems);
    let damage = (!f.problems.is_empty()).then(|| CommitDamage {
        generation: newest.generation,
        problems: std::mem::take(&mut f.problems),
        claimed_rays,
        readable_rays: dirs.iter().flatten().map(|e| u64::from(e.count)).sum(),
        fallback,
    });
    Ok(Survey {
        settings,
        text_len,
        version: prefix.version,
        data_start,
        file_len,
        repaired: f.repaired,
        torn: f.torn,
        bad_header: f.bad_header,
        clean: if damage.is_none() {
            clean_chunks.map(|c| (newest, c))
        } else {
            None
        },
        damage,
        generation: newest.generation,
        side,
        dirs,
        metadata,
        weak_chunks,
        uneven_slots: f.uneven_slots,
        legacy: None,
    })
}

/// Where a survey reads: the file, its sections' beam counts and its extent.
struct Place<'a> {
    file: &'a File,
    path: &'a Path,
    /// Beams per section.
    beams: &'a [u32],
    /// Where beam data may start.
    data_start: u64,
    file_len: u64,
}

/// The beam directories a survey read, and who claims which bytes.
struct Directories {
    /// Per section, per beam.
    dirs: Vec<Vec<BeamEntry>>,
    /// Every extent the commits read claim, by whom.
    claims: Vec<(Extent, Claim)>,
    /// Chunks of the newest commit whose directory is lost.
    lost: Vec<ChunkRef>,
    /// Rays the newest commit's root says it holds, where it verifies.
    claimed_rays: Option<u64>,
    /// The newest commit's chunks, where every one of them verified.
    clean_chunks: Option<Vec<ChunkRef>>,
    /// Chunks read only after a repair (section, first beam).
    weak_chunks: Vec<(u32, u32)>,
}

impl Place<'_> {
    /// The newest commit's root and directory chunks; what does not verify
    /// is noted in `f` and its chunks listed as lost.
    fn newest(&self, newest: &Slot, f: &mut Findings) -> Result<Directories> {
        let (file, path, beams, data_start, file_len) =
            (self.file, self.path, self.beams, self.data_start, self.file_len);
        let mut dirs: Vec<Vec<BeamEntry>> = beams.iter().map(|&n| vec![BeamEntry::default(); n as usize]).collect();
        let mut claims: Vec<(Extent, Claim)> = Vec::new();
        // Chunks of the newest commit whose directory is lost: (section, first, beams, rays).
        let mut lost: Vec<ChunkRef> = Vec::new();
        let mut claimed_rays = None;
        let mut clean_chunks = None;
        let mut weak_chunks = Vec::new();
        claims.extend(newest.root_copies().iter().map(|e| (*e, Claim::NewestMeta)));
        match read_root(file, path, newest, beams, file_len, &mut f.repaired)? {
            Ok(chunks) => {
                claimed_rays = Some(chunks.iter().map(|c| c.rays).sum::<u64>());
                let mut all = true;
                for c in &chunks {
                    claims.extend(c.extents().iter().map(|e| (*e, Claim::NewestMeta)));
                    let notes = f.repaired.len();
                    let read = read_chunk(file, path, c, data_start, file_len, &mut f.repaired)?;
                    if f.repaired.len() > notes {
                        weak_chunks.push((c.section, c.first));
                    }
                    match read {
                        Ok(entries) => {
                            let dir = &mut dirs[c.section as usize];
                            for (i, e) in entries.into_iter().enumerate() {
                                let b = c.first + i as u32;
                                dir[b as usize] = e;
                                if e.count > 0 {
                                    claims.push((e.extent(), Claim::NewestBeam(c.section, b)));
                                }
                            }
                        }
                        Err(p) => {
                            f.problems.push(p);
                            lost.push(*c);
                            all = false;
                        }
                    }
                }
                if all {
                    clean_chunks = Some(chunks);
                }
            }
            Err(p) => {
                f.problems.push(p);
                lost.extend(whole_sections(beams));
            }
        }
        Ok(Directories {
            dirs,
            claims,
            lost,
            claimed_rays,
            clean_chunks,
            weak_chunks,
        })
    }

    /// Lost directories taken from the commit before, where it verifies;
    /// the generation they came from, if any did.
    fn fall_back(&self, slots: &[(usize, Slot)], newest: &Slot, d: &mut Directories) -> Result<Option<u64>> {
        let (file, path, beams, data_start, file_len) =
            (self.file, self.path, self.beams, self.data_start, self.file_len);
        let (lost, claims, dirs) = (&d.lost, &mut d.claims, &mut d.dirs);
        let mut fallback = None;
        if !lost.is_empty() {
            if let Some(&(_, older)) = slots.iter().find(|(_, s)| s.generation < newest.generation) {
                let mut ignored = Vec::new();
                if let Ok(chunks) = read_root(file, path, &older, beams, file_len, &mut ignored)? {
                    claims.extend(older.root_copies().iter().map(|e| (*e, Claim::OlderMeta)));
                    for c in chunks.iter().filter(|c| lost.iter().any(|l| overlaps(l, c))) {
                        let Ok(entries) = read_chunk(file, path, c, data_start, file_len, &mut ignored)? else {
                            continue;
                        };
                        fallback = Some(older.generation);
                        claims.extend(c.extents().iter().map(|e| (*e, Claim::OlderMeta)));
                        let dir = &mut dirs[c.section as usize];
                        for (i, e) in entries.into_iter().enumerate() {
                            let b = c.first + i as u32;
                            let inside = lost
                                .iter()
                                .any(|l| l.section == c.section && (l.first..l.first + l.beams).contains(&b));
                            if inside && e.count > 0 {
                                dir[b as usize] = e;
                                claims.push((e.extent(), Claim::OlderBeam(c.section, b)));
                            }
                        }
                    }
                }
            }
        }
        Ok(fallback)
    }
}

fn whole_sections(beams: &[u32]) -> Vec<ChunkRef> {
    beams
        .iter()
        .enumerate()
        .map(|(s, &n)| ChunkRef {
            section: s as u32,
            first: 0,
            beams: n,
            ..ChunkRef::default()
        })
        .collect()
}

fn overlaps(a: &ChunkRef, b: &ChunkRef) -> bool {
    a.section == b.section && a.first < b.first + b.beams && b.first < a.first + a.beams
}

/// Drops beams whose runs lie past the end of the file or below the data
/// area, then settles overlaps: the higher claim keeps the bytes. Returns the
/// metadata extents kept; problems are recorded for every beam dropped from
/// the newest commit.
fn plan_claims(
    dirs: &mut [Vec<BeamEntry>],
    mut claims: Vec<(Extent, Claim)>,
    data_start: u64,
    file_len: u64,
    problems: &mut Vec<String>,
) -> Vec<Extent> {
    let (mut past_end, mut past_end_rays) = (0u64, 0u64);
    let (mut in_header, mut in_header_rays) = (0u64, 0u64);
    claims.retain(|(e, claim)| {
        let inside = e.offset >= data_start && e.end() <= file_len;
        if !inside {
            if let Claim::NewestBeam(s, b) | Claim::OlderBeam(s, b) = *claim {
                let entry = &mut dirs[s as usize][b as usize];
                if matches!(claim, Claim::NewestBeam(..)) {
                    let (n, rays) = if e.end() > file_len {
                        (&mut past_end, &mut past_end_rays)
                    } else {
                        (&mut in_header, &mut in_header_rays)
                    };
                    *n += 1;
                    *rays += u64::from(entry.count);
                }
                *entry = BeamEntry::default();
            }
        }
        inside && e.len > 0
    });
    if past_end > 0 {
        problems.push(format!(
            "{past_end} beams ({past_end_rays} rays) lie past the end of the file at byte {file_len}: the file is truncated"
        ));
    }
    if in_header > 0 {
        problems.push(format!(
            "{in_header} beams ({in_header_rays} rays) point into the header copies, before byte {data_start}"
        ));
    }
    claims.sort_by_key(|(e, c)| (e.offset, *c));
    let mut kept: Vec<(Extent, Claim)> = Vec::with_capacity(claims.len());
    let mut clashes = 0u64;
    for (e, c) in claims {
        // Only the last kept claim can reach past `e.offset`: kept claims never overlap.
        let clash = kept.last().filter(|(k, _)| k.end() > e.offset).copied();
        let Some((k, kc)) = clash else {
            kept.push((e, c));
            continue;
        };
        if k == e && kc == c {
            continue; // the same block listed twice (two chunks can't, but be safe)
        }
        let (loser, winner_replaced) = if c < kc { (kc, true) } else { (c, false) };
        if winner_replaced {
            kept.pop();
            kept.push((e, c));
        }
        if let Claim::NewestBeam(s, b) | Claim::OlderBeam(s, b) = loser {
            dirs[s as usize][b as usize] = BeamEntry::default();
        }
        if matches!(loser, Claim::NewestBeam(..) | Claim::NewestMeta) {
            clashes += 1;
        }
    }
    if clashes > 0 {
        problems.push(format!(
            "{clashes} runs or blocks of the newest commit claim bytes that others claim too"
        ));
    }
    kept.into_iter()
        .filter(|(_, c)| matches!(c, Claim::NewestMeta | Claim::OlderMeta))
        .map(|(e, _)| e)
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn beam(offset: u64, count: u32) -> BeamEntry {
        BeamEntry { offset, count, crc: 0 }
    }

    fn ext(offset: u64, len: u64) -> Extent {
        Extent { offset, len }
    }

    #[test]
    fn overlapping_claims_go_to_the_newest_metadata_then_beams_then_older() {
        // Runs of 10 records (100 bytes) each; the data area starts at 1,000.
        let mut dirs = vec![vec![
            beam(1_050, 10), // 0: overlaps the newest commit's directory block
            beam(2_000, 10), // 1: an older commit's run under the newest's beam 2
            beam(2_050, 10), // 2
            beam(3_000, 10), // 3: clear of everything
            beam(9_950, 10), // 4: runs past the end of the file
            beam(500, 10),   // 5: below the data area
            beam(4_050, 10), // 6: an older run overlapping older metadata
        ]];
        let claims = vec![
            (ext(1_000, 100), Claim::NewestMeta),
            (dirs[0][0].extent(), Claim::NewestBeam(0, 0)),
            (dirs[0][1].extent(), Claim::OlderBeam(0, 1)),
            (dirs[0][2].extent(), Claim::NewestBeam(0, 2)),
            (dirs[0][3].extent(), Claim::NewestBeam(0, 3)),
            (dirs[0][4].extent(), Claim::NewestBeam(0, 4)),
            (dirs[0][5].extent(), Claim::NewestBeam(0, 5)),
            (ext(4_000, 100), Claim::OlderMeta),
            (dirs[0][6].extent(), Claim::OlderBeam(0, 6)),
        ];
        let mut problems = Vec::new();
        let meta = plan_claims(&mut dirs, claims, 1_000, 10_000, &mut problems);
        // Metadata keeps its bytes, the newest first; older metadata beats older runs.
        assert_eq!(meta, vec![ext(1_000, 100), ext(4_000, 100)]);
        let counts: Vec<u32> = dirs[0].iter().map(|b| b.count).collect();
        // Lost: 0 (under the newest metadata), 1 (an older run under a newest
        // one), 4 (past the end), 5 (below the data area), 6 (under older metadata).
        assert_eq!(counts, vec![0, 0, 10, 10, 0, 0, 0]);
        assert_eq!(problems.len(), 3, "{problems:?}");
        assert!(
            problems[0].contains("1 beams (10 rays) lie past the end"),
            "{problems:?}"
        );
        assert!(
            problems[1].contains("1 beams (10 rays) point into the header copies"),
            "{problems:?}"
        );
        assert!(
            problems[2].contains("1 runs or blocks of the newest commit"),
            "{problems:?}"
        );
    }
}
