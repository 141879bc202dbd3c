//! Copying rays from one holodeck into another, like Radiance's rhcopy.
//!
//! A section of the destination equal to one of the source (same geometry,
//! grid, kind and depth coding) takes that section's rays as they are, beam
//! for beam. Rays of any other source section are resampled: each is decoded
//! to its world line, color and hit, and stored in every destination section
//! its line crosses where it is valid there. A record holds the radiance seen
//! along its line from anywhere between its section's entry wall and its hit
//! (a sampler starts it at the entry wall, or at the exit wall of a section
//! declared free of geometry, which comes to the same). So it is valid in a
//! destination section that the line enters no earlier than the source's
//! entry wall and no later than the hit; and, where the destination's
//! sections hold no geometry (OBSTRUCTIONS false, as Radiance's rhcopy
//! allows), also in one the line enters behind the ray's start, when the
//! start lies inside it and the hit past its exit wall (rays crossing a wall
//! two sections share). Colors keep their bytes; cells, sub-cells and depth
//! codes are the destination's.

use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, Hit, RayRecord, Section};

use super::error::{Result, StorageError};
use super::holofile::{HoloFile, OpenOptions};

/// Source beams read per batch.
const BATCH_BEAMS: u32 = 1 << 14;

/// What a copy did.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CopyReport {
    /// The destination did not exist and was created with the source's settings.
    pub created: bool,
    /// Source sections copied beam for beam into an equal destination section.
    pub merged_sections: usize,
    /// Source sections resampled into the destination's sections.
    pub resampled_sections: usize,
    /// Rays read from the source.
    pub rays_read: u64,
    /// Rays stored in the destination (a resampled ray may land in several sections).
    pub rays_written: u64,
    /// Resampled rays valid in no destination section.
    pub rays_dropped: u64,
    /// Why the copy stopped before the end, with every ray stored so far
    /// committed: the destination's DISKSPACE limit was reached.
    pub stopped: Option<String>,
}

/// How to copy.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct CopyOptions {
    /// The destination's size limit for this copy, replacing its DISKSPACE
    /// setting: `Some(0)` for none; `None` keeps the setting.
    pub diskspace: Option<u64>,
}

/// Where, along a source ray, rays go into a destination section.
struct Resampler<'a> {
    source: &'a Section,
    targets: &'a [Section],
    /// The destination's sections hold no geometry (OBSTRUCTIONS false):
    /// a line may be taken back to where it enters one, behind the ray's start.
    unobstructed: bool,
}

impl Resampler<'_> {
    /// Adds `rec` (of source beam `beam`) to every destination section it is valid in.
    fn place(&self, beam: u32, rec: &RayRecord, out: &mut Vec<(BeamKey, RayRecord)>) -> bool {
        let Ok(d) = self.source.decode_record(beam, rec) else {
            return false;
        };
        let ray = d.ray;
        // Distances along the ray's unit direction from the source's entry point.
        let hit = match d.hit {
            Hit::Point(p) => (p - ray.origin).dot(ray.direction),
            Hit::Infinite => f64::INFINITY,
        };
        let mut placed = false;
        for (index, target) in self.targets.iter().enumerate() {
            let Some(at) = target.locate(ray.origin, ray.direction) else {
                continue;
            };
            let slack = 1e-9 * target.diagonal().max(self.source.diagonal());
            let valid = if at.t_entry >= -slack {
                // Entered no earlier than the ray began, no later than its hit.
                at.t_entry <= hit + slack
            } else {
                // The line enters the target behind the ray's start (across a
                // wall the two sections share, say). Where the target holds
                // no geometry and the ray starts inside it, nothing lies on
                // that stretch: the ray is what the target's samplers would
                // trace, provided it ends past the target's exit wall. So
                // Radiance's rhcopy keeps it for unobstructed sections.
                self.unobstructed && at.t_exit >= -slack && hit >= at.t_exit - slack
            };
            if !valid {
                continue;
            }
            let depth = if hit.is_finite() {
                target.encode_depth(hit - at.t_entry)
            } else {
                holodeck_protocol::DepthCode::INFINITE
            };
            let record = RayRecord::new(at.entry_sub, at.exit_sub, rec.color, depth);
            out.push((BeamKey::new(index as u32, at.beam), record));
            placed = true;
        }
        placed
    }
}

/// Copies every ray of the holodeck `src` into the holodeck `dest`, which is
/// created with `src`'s settings if it does not exist. `progress(rays_done,
/// rays_total)` is called as beams are read. The destination is flushed at
/// the end; a failure part way leaves it holding what was flushed before.
pub fn copy(src: &Path, dest: &Path, progress: impl FnMut(u64, u64)) -> Result<CopyReport> {
    copy_with(src, dest, &CopyOptions::default(), progress)
}

/// [`copy`] with `options`. When the destination's DISKSPACE limit is
/// reached, the copy stops, commits every ray stored so far and says so in
/// [`CopyReport::stopped`]: a later copy with a larger limit adds the rest
/// (merged beams take duplicates of what was copied before).
pub fn copy_with(
    src: &Path,
    dest: &Path,
    options: &CopyOptions,
    mut progress: impl FnMut(u64, u64),
) -> Result<CopyReport> {
    let same = |a: &Path, b: &Path| match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    };
    if same(src, dest) {
        return Err(StorageError::Io {
            path: PathBuf::from(dest),
            op: "copying a holodeck into itself",
            source: std::io::ErrorKind::InvalidInput.into(),
        });
    }
    let mut from = HoloFile::open(src, &OpenOptions::read_only())?;
    let mut report = CopyReport::default();
    if !dest.exists() {
        HoloFile::create(dest, from.settings())?;
        report.created = true;
    }
    let mut to = HoloFile::open(
        dest,
        &OpenOptions {
            flush_interval: None,
            ..OpenOptions::default()
        },
    )?;
    if let Some(limit) = options.diskspace {
        to.set_size_limit((limit > 0).then_some(limit));
    }
    let (src_settings, dest_settings) = (from.settings().clone(), to.settings().clone());
    let total = from.summary().rays();
    let mut done = 0u64;
    let mut placed = Vec::new();
    'sections: for (s, section) in src_settings.sections.iter().enumerate() {
        let twin = dest_settings
            .sections
            .iter()
            .position(|d| d == section)
            .map(|d| d as u32);
        match twin {
            Some(_) => report.merged_sections += 1,
            None => report.resampled_sections += 1,
        }
        let resampler = Resampler {
            source: section,
            targets: &dest_settings.sections,
            unobstructed: !dest_settings.obstructions,
        };
        let beams = section.beam_count();
        let mut first = 0u32;
        while first < beams {
            let last = beams.min(first.saturating_add(BATCH_BEAMS));
            let keys: Vec<BeamKey> = (first..last)
                .map(|b| BeamKey::new(s as u32, b))
                .filter(|k| from.directory(k.section).is_some_and(|d| d[k.beam as usize].count > 0))
                .collect();
            let mut batch: Vec<(BeamKey, Vec<RayRecord>)> = Vec::new();
            let read = from.read_beams(&keys, |key, rays| {
                if !rays.is_empty() {
                    batch.push((key, rays.to_vec()));
                }
            })?;
            if let Some(&key) = read.corrupt.first() {
                let e = from
                    .directory(key.section)
                    .map(|d| d[key.beam as usize].extent())
                    .unwrap_or_default();
                return Err(StorageError::BeamCorrupt {
                    path: src.to_path_buf(),
                    key,
                    start: e.offset,
                    end: e.end(),
                });
            }
            for (key, rays) in batch {
                report.rays_read += rays.len() as u64;
                done += rays.len() as u64;
                let stored = if let Some(d) = twin {
                    to.append(BeamKey::new(d, key.beam), &rays)
                        .map(|()| report.rays_written += rays.len() as u64)
                } else {
                    placed.clear();
                    for r in &rays {
                        if !resampler.place(key.beam, r, &mut placed) {
                            report.rays_dropped += 1;
                        }
                    }
                    placed.sort_by_key(|(k, _)| *k);
                    placed.chunk_by(|a, b| a.0 == b.0).try_for_each(|group| {
                        let recs: Vec<RayRecord> = group.iter().map(|(_, r)| *r).collect();
                        to.append(group[0].0, &recs)?;
                        report.rays_written += recs.len() as u64;
                        Ok(())
                    })
                };
                match stored {
                    Ok(()) => {}
                    Err(e @ StorageError::DiskSpace { .. }) => {
                        report.stopped = Some(e.to_string());
                        break 'sections;
                    }
                    Err(e) => return Err(e),
                }
            }
            progress(done, total);
            first = last;
        }
    }
    to.close()?;
    Ok(report)
}
