//! Whole-file maintenance: verify every checksum, salvage what verifies into a
//! new file, and optimize (collate beams in beam order, no fragments). None of
//! these ever writes to the file they read, except optimize's final atomic
//! rename of a complete, verified copy over it.

use std::path::Path;

use holodeck_protocol::BeamKey;

use super::bulk::SequentialWriter;
use super::error::CommitDamage;
use super::error::{Result, StorageError};
use super::holofile::{HoloFile, OpenOptions};

/// Outcome of verifying a file.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CheckReport {
    /// Generation of the newest commit.
    pub generation: u64,
    /// Commits a crash interrupted, passed over as it should be.
    pub skipped: Vec<String>,
    /// Damaged copies of metadata whose other copy verified: nothing is lost.
    pub repaired: Vec<String>,
    /// Set when the newest commit cannot be read in full.
    pub damage: Option<CommitDamage>,
    /// Beams whose records verified: what `repair` saves.
    pub beams_ok: u64,
    /// Rays in those beams.
    pub rays_ok: u64,
    /// Beams that failed their checksum.
    pub corrupt: Vec<BeamKey>,
    /// Rays the directory gives those beams.
    pub corrupt_rays: u64,
}

impl CheckReport {
    /// True when nothing is damaged: every copy of the metadata and every beam verified.
    pub fn is_clean(&self) -> bool {
        self.corrupt.is_empty() && self.damage.is_none() && self.repaired.is_empty()
    }

    /// True when rays are lost: beams that fail, or a newest commit that cannot be read in full.
    pub fn loses_rays(&self) -> bool {
        !self.corrupt.is_empty() || self.damage.is_some()
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

/// Verifies every copy of the header and metadata and every beam's checksum.
/// `progress` receives bytes verified so far and the total.
pub fn check(path: &Path, progress: impl FnMut(u64, u64)) -> Result<CheckReport> {
    let mut file = HoloFile::open(path, &OpenOptions::read_only())?;
    salvage(&mut file, progress, |_, _| Ok(()))
}

/// Verifies every beam of `file` (opened for reading what can be read),
/// handing each that verifies to `keep`; reports the rest.
fn salvage(
    file: &mut HoloFile,
    mut progress: impl FnMut(u64, u64),
    mut keep: impl FnMut(BeamKey, &[holodeck_protocol::RayRecord]) -> Result<()>,
) -> Result<CheckReport> {
    let info = file.open_info().clone();
    let mut report = CheckReport {
        generation: info.generation,
        skipped: info.skipped,
        repaired: info.repaired,
        damage: info.damage,
        ..CheckReport::default()
    };
    let total = file.summary().ray_bytes;
    let mut done = 0u64;
    let mut keys = all_keys(file);
    let mut corrupt = Vec::new();
    file.scan_disk(&mut keys, |r| {
        match r {
            Ok((key, rays)) => {
                report.beams_ok += 1;
                report.rays_ok += rays.len() as u64;
                done += rays.len() as u64 * 10;
                keep(key, rays)?;
            }
            Err(key) => corrupt.push(key),
        }
        progress(done, total);
        Ok(())
    })?;
    corrupt.sort();
    report.corrupt_rays = corrupt
        .iter()
        .map(|k| {
            file.directory(k.section)
                .map_or(0, |d| u64::from(d[k.beam as usize].count))
        })
        .sum();
    report.corrupt = corrupt;
    Ok(report)
}

/// Outcome of a salvage.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct RepairReport {
    /// Beams copied.
    pub beams: u64,
    /// Rays copied.
    pub rays: u64,
    /// Beams left behind because their records failed to verify.
    pub beams_lost: u64,
    /// What the check of the source found.
    pub check: CheckReport,
}

/// Copies every beam that verifies from `src` into a new file `dest`, reading
/// `src` only. Works when the newest commit is damaged: each directory chunk
/// is read from whichever copy verifies, and a chunk lost in the newest commit
/// from the commit before, where it verifies there.
pub fn repair(src: &Path, dest: &Path) -> Result<RepairReport> {
    if dest.exists() {
        return Err(StorageError::Exists {
            path: dest.to_path_buf(),
        });
    }
    let mut file = HoloFile::open(src, &OpenOptions::read_only())?;
    let mut out = SequentialWriter::create(dest, file.settings())?;
    // Beams are copied as they are read, in the source's file order.
    let check = salvage(&mut file, |_, _| {}, |key, rays| out.push_beam(key, rays))?;
    out.finish()?;
    Ok(RepairReport {
        beams: check.beams_ok,
        rays: check.rays_ok,
        beams_lost: check.corrupt.len() as u64,
        check,
    })
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

/// Rewrites the file with beams collated in beam order and no free space, in
/// the current format (converting an older one), then atomically replaces
/// the original. Fails, leaving the original untouched, if
/// the newest commit is damaged, any beam fails its checksum, or another
/// process holds the file: a damaged file is never replaced by a smaller one.
pub fn optimize(path: &Path, mut progress: impl FnMut(u64, u64)) -> Result<OptimizeReport> {
    // The exclusive lock: no server may be filling it meanwhile. A file in an
    // older format is read and rewritten in the current one.
    let mut src = HoloFile::open_exclusive_read(path, 0)?;
    if let Some(damage) = &src.open_info().damage {
        return Err(StorageError::Damaged {
            path: path.to_path_buf(),
            damage: Box::new(damage.clone()),
        });
    }
    let summary = src.summary();
    // The writer builds beside the original and renames over it only when complete.
    let mut out = SequentialWriter::replacing(path, src.settings())?;
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
                return Err(src.corrupt(key));
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
    if rays_copied != summary.rays() {
        // Never replace a file with one that holds fewer rays than it claims.
        return Err(StorageError::Format {
            path: path.to_path_buf(),
            source: super::format::FormatError::Invalid {
                what: "optimized copy".into(),
                at: 0,
                detail: format!("{rays_copied} rays copied of the {} the file holds", summary.rays()),
            },
        });
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
