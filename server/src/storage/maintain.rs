//! Whole-file maintenance: verify every checksum, salvage what verifies into a
//! new file, and optimize (collate beams in beam order, no fragments). None of
//! these ever writes to the file they read, except optimize's final atomic
//! rename of a complete, verified copy over it.

use std::path::Path;

use holodeck_protocol::BeamKey;

use super::bulk::SequentialWriter;
use super::error::{Result, StorageError};
use super::format::{self, Slot};
use super::holofile::{HoloFile, OpenOptions};
use super::io;
use super::store;

/// Outcome of verifying a file.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CheckReport {
    /// Generation of the commit in use.
    pub generation: u64,
    /// Newer commits passed over, with reasons (a torn last commit shows here).
    pub skipped: Vec<String>,
    /// Beams whose records verified.
    pub beams_ok: u64,
    /// Rays in those beams.
    pub rays_ok: u64,
    /// Beams that failed their checksum.
    pub corrupt: Vec<BeamKey>,
}

impl CheckReport {
    /// True when every beam verified.
    pub fn is_clean(&self) -> bool {
        self.corrupt.is_empty()
    }
}

fn all_keys(file: &HoloFile) -> Vec<BeamKey> {
    let mut keys = Vec::new();
    for s in 0..file.sections().len() as u32 {
        if let Some(d) = file.directory(s) {
            keys.extend(
                d.iter()
                    .enumerate()
                    .filter(|(_, e)| e.count > 0)
                    .map(|(b, _)| BeamKey::new(s, b as u32)),
            );
        }
    }
    keys
}

/// Verifies header, commits, directories and every beam's checksum. `progress`
/// receives bytes verified so far and the total.
pub fn check(path: &Path, mut progress: impl FnMut(u64, u64)) -> Result<CheckReport> {
    let mut file = HoloFile::open(path, &OpenOptions::read_only())?;
    let mut report = CheckReport {
        generation: file.open_info().generation,
        skipped: file.open_info().skipped.clone(),
        ..CheckReport::default()
    };
    let total = file.summary().ray_bytes;
    let mut done = 0u64;
    let mut keys = all_keys(&file);
    file.scan_disk(&mut keys, |r| {
        match r {
            Ok((_, rays)) => {
                report.beams_ok += 1;
                report.rays_ok += rays.len() as u64;
                done += rays.len() as u64 * 10;
            }
            Err(key) => report.corrupt.push(key),
        }
        progress(done, total);
        Ok(())
    })?;
    report.corrupt.sort();
    Ok(report)
}

/// Outcome of a salvage.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// Beams copied.
    pub beams: u64,
    /// Rays copied.
    pub rays: u64,
    /// Beams left behind because their records or directory failed to verify.
    pub beams_lost: u64,
    /// Sections whose directory could not be read from any commit (their beams are all lost).
    pub sections_lost: Vec<u32>,
}

/// Copies every beam that verifies from `src` into a new file `dest`, reading
/// `src` only. Works even when no commit of `src` is fully consistent: each
/// section's directory is taken from the newest commit where it verifies.
pub fn repair(src: &Path, dest: &Path) -> Result<RepairReport> {
    if dest.exists() {
        return Err(StorageError::Exists {
            path: dest.to_path_buf(),
        });
    }
    let file = std::fs::File::open(src).map_err(|source| StorageError::Io {
        path: src.to_path_buf(),
        op: "opening",
        source,
    })?;
    io::lock(&file, src, false)?;
    let file_len = io::file_len(&file, src)?;
    let (settings, data_start) = store::read_header(&file, src, file_len)?;
    let slots = store::read_slots(&file, src)?.slots;
    let mut out = SequentialWriter::create(dest, &settings)?;
    let mut report = RepairReport::default();
    let mut buf = Vec::new();
    for (s, section) in settings.sections.iter().enumerate() {
        let Some(dir) = newest_directory(&file, src, &slots, s, section.beam_count(), data_start, file_len) else {
            report.sections_lost.push(s as u32);
            continue;
        };
        for (b, e) in dir.iter().enumerate() {
            if e.count == 0 {
                continue;
            }
            let ok = e.extent().end() <= file_len
                && io::read_at(&file, src, e.offset, e.extent().len as usize, &mut buf).is_ok()
                && crc32c::crc32c(&buf) == e.crc;
            if !ok {
                report.beams_lost += 1;
                continue;
            }
            let rays = holodeck_protocol::RayRecord::slice_from_bytes(&buf).unwrap_or(&[]);
            out.push_beam(BeamKey::new(s as u32, b as u32), rays)?;
            report.beams += 1;
            report.rays += rays.len() as u64;
        }
    }
    out.finish()?;
    Ok(report)
}

fn newest_directory(
    file: &std::fs::File,
    path: &Path,
    slots: &[(usize, Slot)],
    section: usize,
    beams: u32,
    data_start: u64,
    file_len: u64,
) -> Option<Vec<format::BeamEntry>> {
    let mut buf = Vec::new();
    for (_, slot) in slots {
        if slot.root.end() > file_len
            || io::read_at(file, path, slot.root.offset, slot.root.len as usize, &mut buf).is_err()
        {
            continue;
        }
        let Ok(refs) = format::decode_root(&buf, slot.root.offset, slot.generation, usize::MAX)
            .or_else(|_| decode_root_any(&buf, slot))
        else {
            continue;
        };
        let Some(r) = refs.get(section) else { continue };
        let mut dbuf = Vec::new();
        if r.block.end() > file_len
            || r.block.len > format::max_directory_len(beams)
            || io::read_at(file, path, r.block.offset, r.block.len as usize, &mut dbuf).is_err()
        {
            continue;
        }
        // Beams outside the file are caught one by one when copying.
        if let Ok(d) = format::decode_directory(&dbuf, r.block.offset, section as u32, beams, data_start, u64::MAX) {
            return Some(d);
        }
    }
    None
}

/// Decodes a root without knowing how many sections it should list.
fn decode_root_any(bytes: &[u8], slot: &Slot) -> std::result::Result<Vec<format::DirRef>, format::FormatError> {
    let n = bytes
        .get(12..16)
        .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]) as usize)
        .unwrap_or(0);
    format::decode_root(bytes, slot.root.offset, slot.generation, n)
}

/// Outcome of optimizing.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct OptimizeReport {
    /// File size before.
    pub bytes_before: u64,
    /// File size after.
    pub bytes_after: u64,
    /// Rays copied.
    pub rays: u64,
}

/// Rewrites the file with beams collated in beam order and no free space, then
/// atomically replaces the original. Fails, leaving the original untouched, if
/// any beam fails its checksum or another process holds the file.
pub fn optimize(path: &Path, mut progress: impl FnMut(u64, u64)) -> Result<OptimizeReport> {
    // Opening writable takes the exclusive lock: no server may be filling it meanwhile.
    let options = OpenOptions {
        writable: true,
        cache_bytes: Some(0),
        flush_interval: None,
    };
    let mut src = HoloFile::open(path, &options)?;
    let summary = src.summary();
    // The writer builds beside the original and renames over it only when complete.
    let mut out = SequentialWriter::create(path, src.settings())?;
    let mut done = 0u64;
    let mut rays_copied = 0u64;
    for s in 0..src.sections().len() as u32 {
        let beams = src.sections()[s as usize].beam_count();
        // Output goes in beam order; chunks keep each read pass near file order.
        let mut start = 0u32;
        while start < beams {
            let end = beams.min(start.saturating_add(1 << 16));
            let mut keys: Vec<BeamKey> = (start..end)
                .map(|b| BeamKey::new(s, b))
                .filter(|k| src.directory(s).is_some_and(|d| d[k.beam as usize].count > 0))
                .collect();
            let mut chunk = Vec::with_capacity(keys.len());
            let mut corrupt = None;
            src.scan_disk(&mut keys, |r| {
                match r {
                    Ok((k, rays)) => chunk.push((k, rays.to_vec())),
                    Err(key) => corrupt = corrupt.or(Some(key)),
                }
                Ok(())
            })?;
            if let Some(key) = corrupt {
                let e = src
                    .directory(s)
                    .map(|d| d[key.beam as usize].extent())
                    .unwrap_or_default();
                return Err(StorageError::BeamCorrupt {
                    path: path.to_path_buf(),
                    key,
                    start: e.offset,
                    end: e.end(),
                });
            }
            chunk.sort_by_key(|(k, _)| *k);
            for (k, rays) in chunk {
                out.push_beam(k, &rays)?;
                rays_copied += rays.len() as u64;
                done += rays.len() as u64 * 10;
            }
            progress(done, summary.ray_bytes);
            start = end;
        }
    }
    out.finish()?;
    drop(src);
    let bytes_after = std::fs::metadata(path).map(|m| m.len()).unwrap_or(0);
    Ok(OptimizeReport {
        bytes_before: summary.file_bytes,
        bytes_after,
        rays: rays_copied,
    })
}
