//! The on-disk side of the engine: loads the current commit, writes beam runs,
//! and commits directories. Knows nothing of the cache.
//!
//! Crash safety rests on three rules. (1) Bytes the durable commit refers to are
//! never overwritten: new runs go to free space, and space released by a change
//! becomes free only after the commit that drops it is durable. (2) A commit
//! writes its directory blocks and root to free space, syncs, then writes the
//! slot that is *not* the one the current state was loaded from, and syncs
//! again. (3) Opening takes the highest-generation slot whose checksums, root
//! and directories all verify; a torn last commit falls back to the one before.

use std::collections::HashSet;
use std::fs::File;
use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, RayRecord, Section};

use super::error::{Result, StorageError};
use super::extents::Extents;
use super::format::{self, BeamEntry, DirRef, Extent, Slot, SLOT_LEN, SLOT_OFFSETS};
use super::io::{self, WriteBatch};
use crate::settings::Settings;

/// How the current state was found on open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpenInfo {
    /// Generation of the commit in use.
    pub generation: u64,
    /// Slot (0 or 1) it was read from.
    pub slot: usize,
    /// Why newer commits were passed over (a torn or corrupt last commit), if any.
    pub skipped: Vec<String>,
}

/// Counters of engine work since open.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct IoStats {
    /// Rays written to beam runs.
    pub rays_written: u64,
    /// Runs written or extended.
    pub runs_written: u64,
    /// Runs moved because they could not grow in place.
    pub relocations: u64,
    /// Commits made.
    pub commits: u64,
}

/// One loaded commit: directories and where they and the root live.
pub(crate) struct Loaded {
    pub dirs: Vec<Vec<BeamEntry>>,
    pub blocks: Vec<Extent>,
    pub root: Extent,
    pub extents: Extents,
}

/// The file and its in-memory directories.
pub struct Store {
    pub(crate) path: PathBuf,
    pub(crate) file: File,
    pub(crate) writable: bool,
    pub(crate) dirs: Vec<Vec<BeamEntry>>,
    /// Records each beam's run has room for (its count plus an in-memory growth
    /// reserve). No commit refers to the reserve, so reopening frees it.
    capacity: Vec<Vec<u32>>,
    dir_dirty: Vec<bool>,
    blocks: Vec<Extent>,
    root: Extent,
    generation: u64,
    next_slot: usize,
    pub(crate) extents: Extents,
    writes: WriteBatch,
    /// Offsets of runs written since the last commit: no commit refers to them,
    /// so they can be freed at once when their beam moves again.
    fresh: HashSet<u64>,
    file_len: u64,
    pub(crate) stats: IoStats,
    pub(crate) info: OpenInfo,
    /// Set when a write or sync failed: what is on disk is then uncertain
    /// (a failed fsync may drop dirty pages), so nothing more is written.
    poisoned: bool,
    /// No allocation may end past this byte (DISKSPACE; `u64::MAX`: no limit).
    limit: u64,
}

const RECORD: u64 = holodeck_protocol::RAY_RECORD_BYTES as u64;

/// Room given to a run that must move: a quarter again its size, so that a beam
/// growing by small appends moves O(log n) times instead of O(n).
fn grow(count: u32) -> u32 {
    count.saturating_add(count / 4).max(count.saturating_add(4))
}

fn format_err(path: &Path) -> impl Fn(format::FormatError) -> StorageError + '_ {
    move |source| StorageError::Format {
        path: path.to_path_buf(),
        source,
    }
}

/// Reads the prefix and settings text; returns them with the data start offset.
pub(crate) fn read_header(file: &File, path: &Path, file_len: u64) -> Result<(Settings, u64)> {
    let mut buf = Vec::new();
    io::read_at(file, path, 0, file_len.min(format::PREFIX_LEN) as usize, &mut buf)?;
    let text_len = format::decode_prefix(&buf).map_err(format_err(path))?;
    let data_start = format::data_start(text_len);
    if file_len < data_start {
        return Err(StorageError::Format {
            path: path.to_path_buf(),
            source: format::FormatError::Truncated {
                what: "file header".into(),
                start: 0,
                end: data_start,
                have: file_len,
            },
        });
    }
    io::read_at(file, path, format::TEXT_OFFSET, text_len as usize + 4, &mut buf)?;
    let text = format::decode_text(&buf).map_err(format_err(path))?;
    let settings = Settings::from_text(&text).map_err(|source| StorageError::Settings {
        path: path.to_path_buf(),
        source,
    })?;
    Ok((settings, data_start))
}

/// The slots that decode, as (slot index, slot), newest first, and why the others did not.
pub(crate) struct SlotScan {
    pub slots: Vec<(usize, Slot)>,
    pub problems: Vec<String>,
}

/// Reads both commit slots.
pub(crate) fn read_slots(file: &File, path: &Path) -> Result<SlotScan> {
    let mut buf = Vec::new();
    io::read_at(file, path, SLOT_OFFSETS[0], 2 * SLOT_LEN as usize, &mut buf)?;
    let (mut slots, mut problems) = (Vec::new(), Vec::new());
    for (i, &at) in SLOT_OFFSETS.iter().enumerate() {
        let bytes = &buf[(at - SLOT_OFFSETS[0]) as usize..][..SLOT_LEN as usize];
        match format::decode_slot(bytes, at) {
            Ok(Some(s)) => slots.push((i, s)),
            Ok(None) => {}
            Err(e) => problems.push(e.to_string()),
        }
    }
    slots.sort_by_key(|(_, s)| std::cmp::Reverse(s.generation));
    Ok(SlotScan { slots, problems })
}

fn read_extent(file: &File, path: &Path, e: Extent, file_len: u64, what: &str) -> Result<Vec<u8>> {
    if e.end() > file_len {
        return Err(StorageError::Format {
            path: path.to_path_buf(),
            source: format::FormatError::Truncated {
                what: what.into(),
                start: e.offset,
                end: e.end(),
                have: file_len.saturating_sub(e.offset),
            },
        });
    }
    let mut buf = Vec::new();
    io::read_at(file, path, e.offset, e.len as usize, &mut buf)?;
    Ok(buf)
}

/// Loads and fully validates the commit a slot points to.
pub(crate) fn load_commit(
    file: &File,
    path: &Path,
    slot: &Slot,
    sections: &[Section],
    data_start: u64,
    file_len: u64,
) -> Result<Loaded> {
    let invalid = |what: String, at: u64, detail: String| StorageError::Format {
        path: path.to_path_buf(),
        source: format::FormatError::Invalid { what, at, detail },
    };
    if slot.root.len != format::root_len(sections.len()) {
        let detail = format!(
            "root length {} is not {} for {} sections",
            slot.root.len,
            format::root_len(sections.len()),
            sections.len()
        );
        return Err(invalid(format!("commit {}", slot.generation), slot.root.offset, detail));
    }
    let root_bytes = read_extent(file, path, slot.root, file_len, "commit root")?;
    if crc32c::crc32c(&root_bytes) != slot.root_crc {
        return Err(StorageError::Format {
            path: path.to_path_buf(),
            source: format::FormatError::Checksum {
                what: format!("root of commit {}", slot.generation),
                start: slot.root.offset,
                end: slot.root.end(),
                stored: slot.root_crc,
                computed: crc32c::crc32c(&root_bytes),
            },
        });
    }
    let refs = format::decode_root(&root_bytes, slot.root.offset, slot.generation, sections.len())
        .map_err(format_err(path))?;
    let mut dirs = Vec::with_capacity(sections.len());
    let mut used = vec![slot.root];
    for (s, (r, section)) in refs.iter().zip(sections).enumerate() {
        if r.block.len > format::max_directory_len(section.beam_count()) {
            let detail = format!(
                "directory block of {} bytes is too long for {} beams",
                r.block.len,
                section.beam_count()
            );
            return Err(invalid(format!("directory of section {s}"), r.block.offset, detail));
        }
        let bytes = read_extent(file, path, r.block, file_len, &format!("directory of section {s}"))?;
        let d = format::decode_directory(
            &bytes,
            r.block.offset,
            s as u32,
            section.beam_count(),
            data_start,
            file_len,
        )
        .map_err(format_err(path))?;
        used.push(r.block);
        used.extend(d.iter().map(|e| e.extent()));
        dirs.push(d);
    }
    let extents = Extents::from_used(data_start, used).map_err(|o| StorageError::Format {
        path: path.to_path_buf(),
        source: format::FormatError::Invalid {
            what: format!("commit {}", slot.generation),
            at: o.second.offset,
            detail: format!(
                "bytes {}..{} are claimed twice (also by {}..{})",
                o.second.offset,
                o.second.end(),
                o.first.offset,
                o.first.end()
            ),
        },
    })?;
    Ok(Loaded {
        dirs,
        blocks: refs.iter().map(|r| r.block).collect(),
        root: slot.root,
        extents,
    })
}

impl Store {
    /// Opens the file's current commit. Returns the settings too.
    pub fn open(path: &Path, writable: bool) -> Result<(Store, Settings)> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(writable)
            .open(path)
            .map_err(|source| StorageError::Io {
                path: path.to_path_buf(),
                op: "opening",
                source,
            })?;
        io::lock(&file, path, writable)?;
        let file_len = io::file_len(&file, path)?;
        let (settings, data_start) = read_header(&file, path, file_len)?;
        let SlotScan { slots, mut problems } = read_slots(&file, path)?;
        let newest = slots.first().map(|(_, s)| s.generation).unwrap_or(0);
        for (slot_index, slot) in &slots {
            match load_commit(&file, path, slot, &settings.sections, data_start, file_len) {
                Ok(l) => {
                    if !problems.is_empty() {
                        tracing::warn!(path = %path.display(), "using commit {}: {}", slot.generation, problems.join("; "));
                    }
                    let n = settings.sections.len();
                    let store = Store {
                        path: path.to_path_buf(),
                        file,
                        writable,
                        capacity: l.dirs.iter().map(|d| d.iter().map(|e| e.count).collect()).collect(),
                        dirs: l.dirs,
                        dir_dirty: vec![false; n],
                        blocks: l.blocks,
                        root: l.root,
                        generation: newest,
                        next_slot: 1 - slot_index,
                        extents: l.extents,
                        writes: WriteBatch::default(),
                        fresh: HashSet::new(),
                        file_len,
                        stats: IoStats::default(),
                        info: OpenInfo {
                            generation: slot.generation,
                            slot: *slot_index,
                            skipped: problems,
                        },
                        poisoned: false,
                        limit: u64::MAX,
                    };
                    return Ok((store, settings));
                }
                Err(e) => problems.push(format!("commit {} (slot {slot_index}): {e}", slot.generation)),
            }
        }
        if slots.is_empty() {
            problems.push("neither commit slot holds a commit".into());
        }
        Err(StorageError::NoValidCommit {
            path: path.to_path_buf(),
            problems: problems.join("\n"),
        })
    }

    fn push_write(&mut self, offset: u64, bytes: &[u8]) -> Result<()> {
        // Every caller checked its room first (see `allocate` and `write_tail`).
        debug_assert!(offset + bytes.len() as u64 <= self.limit.max(self.file_len));
        self.file_len = self.file_len.max(offset + bytes.len() as u64);
        let r = self.writes.push(&self.file, &self.path, offset, bytes);
        self.poison_on_error(r)
    }

    /// Marks the store unusable after a failed write or sync.
    fn poison_on_error<T>(&mut self, r: Result<T>) -> Result<T> {
        if r.is_err() {
            self.poisoned = true;
            tracing::error!(path = %self.path.display(), "write failed: no more writes until the file is reopened");
        }
        r
    }

    fn check_usable(&self) -> Result<()> {
        if self.poisoned {
            return Err(StorageError::Poisoned {
                path: self.path.clone(),
            });
        }
        Ok(())
    }

    fn flush_writes(&mut self) -> Result<()> {
        let r = self.writes.flush(&self.file, &self.path);
        self.poison_on_error(r)
    }

    fn sync(&mut self) -> Result<()> {
        let r = io::sync(&self.file, &self.path);
        self.poison_on_error(r)
    }

    /// Sets the size limit: from now on no allocation ends past `limit` bytes
    /// and no write makes the file longer than that.
    pub(crate) fn set_limit(&mut self, limit: Option<u64>) {
        self.limit = limit.unwrap_or(u64::MAX);
    }

    /// The error for growing the file to `needed` bytes, past the limit.
    fn no_space(&self, needed: u64) -> StorageError {
        StorageError::DiskSpace {
            path: self.path.clone(),
            limit: self.limit,
            needed,
        }
    }

    /// Finds room for `len` bytes below the limit. On failure nothing changed.
    fn allocate(&mut self, len: u64) -> Result<u64> {
        match self.extents.allocate_below(len, self.limit) {
            Some(offset) => Ok(offset),
            None => Err(self.no_space(self.extents.end().saturating_add(len))),
        }
    }

    /// The longer of the file and the space allocated in it: no write made
    /// before the next allocation reaches past this.
    pub(crate) fn data_end(&self) -> u64 {
        self.file_len.max(self.extents.end())
    }

    /// True when section `s` has runs written since the last commit.
    pub(crate) fn section_changed(&self, s: usize) -> bool {
        self.dir_dirty[s]
    }

    /// Most bytes by which writing a beam's unwritten rays, so that it then
    /// holds `total` rays, can move the end of the allocated space (see
    /// [`Store::write_tail`]): nothing if they fit the run's reserve; the exact
    /// run for a beam with nothing on disk; else a moved run with room to grow,
    /// which is also more than growing in place can take. Valid until the
    /// beam is next written.
    pub(crate) fn write_growth_bound(&self, key: BeamKey, total: u64) -> u64 {
        let (s, b) = (key.section as usize, key.beam as usize);
        let count = self.dirs[s][b].count;
        let total32 = u32::try_from(total).unwrap_or(u32::MAX);
        if count == 0 {
            total.saturating_mul(RECORD)
        } else if total <= u64::from(self.capacity[s][b]) {
            0
        } else {
            u64::from(grow(total32)) * RECORD
        }
    }

    /// Reads `len` bytes at `offset` into the start of `buf`, seeing every write
    /// made so far. `buf` only ever grows (no zero-filling per read); bytes past
    /// `len` are stale.
    pub(crate) fn read_into(&mut self, offset: u64, len: usize, buf: &mut Vec<u8>) -> Result<()> {
        self.flush_writes()?;
        if buf.len() < len {
            buf.resize(len, 0);
        }
        io::read_exact_at(&self.file, &self.path, offset, &mut buf[..len])
    }

    /// Announces reads about to be made (see [`io::will_need`]).
    pub(crate) fn will_need(&self, groups: &[(u64, u64)]) {
        for &(offset, end) in groups {
            io::will_need(&self.file, offset, end - offset);
        }
    }

    /// Reads one beam's run and verifies its checksum.
    pub(crate) fn read_run(&mut self, key: BeamKey) -> Result<Vec<u8>> {
        let e = self.dirs[key.section as usize][key.beam as usize];
        let mut buf = Vec::new();
        self.read_into(e.offset, e.extent().len as usize, &mut buf)?;
        buf.truncate(e.extent().len as usize);
        if crc32c::crc32c(&buf) != e.crc {
            return Err(StorageError::BeamCorrupt {
                path: self.path.clone(),
                key,
                start: e.offset,
                end: e.extent().end(),
            });
        }
        Ok(buf)
    }

    /// Writes rays appended to a beam: into its run's reserve, or by growing the
    /// run in place if the bytes after it are free, else by moving the whole
    /// beam to a new run with room to grow. `on_disk` supplies the beam's
    /// existing rays when it must move and they are already in memory.
    pub(crate) fn write_tail(&mut self, key: BeamKey, on_disk: Option<&[RayRecord]>, tail: &[RayRecord]) -> Result<()> {
        self.check_usable()?;
        if tail.is_empty() {
            return Ok(());
        }
        let (s, b) = (key.section as usize, key.beam as usize);
        let tail_bytes = RayRecord::slice_as_bytes(tail);
        let old = self.dirs[s][b];
        let cap = u64::from(self.capacity[s][b]);
        let count = old.count + tail.len() as u32;
        let run_end = old.extent().end();
        let reserve_end = old.offset + cap * RECORD;
        let tail_end = run_end + tail_bytes.len() as u64;
        let new = if old.count > 0 && u64::from(count) <= cap {
            // The reserve was allocated below the limit, unless it was lowered since.
            if tail_end > self.limit && tail_end > self.file_len {
                return Err(self.no_space(tail_end));
            }
            self.push_write(run_end, tail_bytes)?;
            BeamEntry {
                offset: old.offset,
                count,
                crc: crc32c::crc32c_append(old.crc, tail_bytes),
            }
        } else if old.count > 0
            && tail_end <= self.limit
            && self
                .extents
                .try_claim(reserve_end, u64::from(count) * RECORD - cap * RECORD)
        {
            self.push_write(run_end, tail_bytes)?;
            self.capacity[s][b] = count;
            BeamEntry {
                offset: old.offset,
                count,
                crc: crc32c::crc32c_append(old.crc, tail_bytes),
            }
        } else {
            let existing = match (old.count, on_disk) {
                (0, _) => Vec::new(),
                (_, Some(rays)) if rays.len() == old.count as usize => RayRecord::slice_as_bytes(rays).to_vec(),
                _ => self.read_run(key)?,
            };
            // A beam's first run is exact; only a beam that had to move has shown it grows.
            let room = if old.count == 0 { count } else { grow(count) };
            // The only step that can fail before anything changed: the limit.
            let offset = self.allocate(u64::from(room) * RECORD)?;
            self.push_write(offset, &existing)?;
            self.push_write(offset + existing.len() as u64, tail_bytes)?;
            if old.count > 0 {
                let unreferenced = Extent {
                    offset: run_end,
                    len: reserve_end - run_end,
                };
                if self.fresh.remove(&old.offset) {
                    self.extents.release_now(Extent {
                        offset: old.offset,
                        len: cap * RECORD,
                    });
                } else {
                    self.extents.release(old.extent());
                    self.extents.release_now(unreferenced);
                }
                self.stats.relocations += 1;
            }
            self.fresh.insert(offset);
            self.capacity[s][b] = room;
            let crc = if old.count == 0 {
                crc32c::crc32c(tail_bytes)
            } else {
                crc32c::crc32c_append(old.crc, tail_bytes)
            };
            BeamEntry { offset, count, crc }
        };
        self.dirs[s][b] = new;
        self.dir_dirty[s] = true;
        self.stats.rays_written += tail.len() as u64;
        self.stats.runs_written += 1;
        Ok(())
    }

    /// Empties every beam (the Clobber command): their runs are freed as a
    /// commit frees them, so the last commit stays readable until the next
    /// one is durable.
    pub(crate) fn clear_all(&mut self) -> Result<()> {
        self.check_usable()?;
        for s in 0..self.dirs.len() {
            for b in 0..self.dirs[s].len() {
                let old = self.dirs[s][b];
                if old.count == 0 {
                    continue;
                }
                let cap = u64::from(self.capacity[s][b]) * RECORD;
                if self.fresh.remove(&old.offset) {
                    self.extents.release_now(Extent {
                        offset: old.offset,
                        len: cap,
                    });
                } else {
                    self.extents.release(old.extent());
                    self.extents.release_now(Extent {
                        offset: old.extent().end(),
                        len: cap - old.extent().len,
                    });
                }
                self.dirs[s][b] = BeamEntry::default();
                self.capacity[s][b] = 0;
            }
            self.dir_dirty[s] = true;
        }
        Ok(())
    }

    /// Bytes held in growth reserves (free once the file is reopened or optimized).
    pub fn reserved_bytes(&self) -> u64 {
        self.dirs
            .iter()
            .zip(&self.capacity)
            .map(|(d, c)| {
                d.iter()
                    .zip(c)
                    .map(|(e, &c)| u64::from(c - e.count) * RECORD)
                    .sum::<u64>()
            })
            .sum()
    }

    /// True when something was written since the last commit.
    pub fn has_changes(&self) -> bool {
        self.dir_dirty.iter().any(|&d| d)
    }

    /// Makes everything written so far durable as a new commit.
    pub fn commit(&mut self) -> Result<()> {
        self.check_usable()?;
        if !self.has_changes() {
            return self.flush_writes();
        }
        let generation = self.generation + 1;
        let mut blocks = self.blocks.clone();
        let mut claimed = Vec::new();
        let written = self.write_metadata(generation, &mut blocks, &mut claimed);
        let (root, root_crc) = match written {
            Ok(r) => r,
            Err(e) => {
                // No commit refers to the new blocks: give their space back, in
                // reverse order so that the end shrinks back too. The current
                // commit and its directories are untouched.
                for x in claimed.into_iter().rev() {
                    self.extents.release_now(x);
                }
                return Err(e);
            }
        };
        for s in 0..self.dirs.len() {
            if self.dir_dirty[s] {
                self.extents.release(self.blocks[s]);
            }
        }
        self.blocks = blocks;
        self.flush_writes()?;
        self.sync()?;
        let slot = Slot {
            generation,
            root,
            root_crc,
        };
        // From here on a failure leaves it unknown which commit is durable: poison.
        let r = io::write_at(
            &self.file,
            &self.path,
            SLOT_OFFSETS[self.next_slot],
            &format::encode_slot(&slot),
        );
        self.poison_on_error(r)?;
        self.sync()?;
        // The new commit is durable: the old root and everything released may be reused.
        self.extents.release(self.root);
        self.root = root;
        self.extents.commit_done();
        self.fresh.clear();
        self.generation = generation;
        self.info.generation = generation;
        self.info.slot = self.next_slot;
        self.next_slot = 1 - self.next_slot;
        self.dir_dirty.iter_mut().for_each(|d| *d = false);
        self.stats.commits += 1;
        if self.file_len > self.extents.end() {
            // Space past the end is referenced by no commit: give it back.
            let r = self.file.set_len(self.extents.end());
            let r = r.map_err(|source| StorageError::Io {
                path: self.path.clone(),
                op: "trimming",
                source,
            });
            self.poison_on_error(r)?;
            self.file_len = self.extents.end();
        }
        Ok(())
    }

    /// Writes the changed sections' directory blocks and a root listing
    /// `blocks` (updated) to free space; returns the root and its CRC. Every
    /// extent allocated is pushed to `claimed` first, for undoing on failure.
    fn write_metadata(
        &mut self,
        generation: u64,
        blocks: &mut [Extent],
        claimed: &mut Vec<Extent>,
    ) -> Result<(Extent, u32)> {
        for (s, dir_block) in blocks.iter_mut().enumerate() {
            if !self.dir_dirty[s] {
                continue;
            }
            let bytes = format::encode_directory(s as u32, &self.dirs[s]);
            let block = Extent {
                offset: self.allocate(bytes.len() as u64)?,
                len: bytes.len() as u64,
            };
            claimed.push(block);
            self.push_write(block.offset, &bytes)?;
            *dir_block = block;
        }
        let refs: Vec<DirRef> = self
            .dirs
            .iter()
            .zip(blocks.iter())
            .map(|(d, b)| DirRef {
                block: *b,
                beams: d.len() as u32,
                rays: d.iter().map(|e| u64::from(e.count)).sum(),
            })
            .collect();
        let root_bytes = format::encode_root(generation, &refs);
        let root = Extent {
            offset: self.allocate(root_bytes.len() as u64)?,
            len: root_bytes.len() as u64,
        };
        claimed.push(root);
        self.push_write(root.offset, &root_bytes)?;
        Ok((root, crc32c::crc32c(&root_bytes)))
    }

    /// Current length of the file in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// Bytes taken by the directory blocks and root of the current commit.
    pub fn metadata_bytes(&self) -> u64 {
        self.blocks.iter().map(|b| b.len).sum::<u64>() + self.root.len
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::HoloFile;
    use crate::testing::{pattern_rays, two_sections};

    /// A new file whose section 0 beams `0..beams` hold `n` rays each, committed.
    fn committed_file(dir: &Path, beams: u32, n: u64) -> (PathBuf, Store) {
        let path = dir.join("t.hdk");
        HoloFile::create(&path, &two_sections([4, 3, 2], [2, 2, 2], 1 << 20)).unwrap();
        let (mut store, _) = Store::open(&path, true).unwrap();
        for b in 0..beams {
            let key = BeamKey::new(0, b);
            store.write_tail(key, None, &pattern_rays(key, 0, n)).unwrap();
        }
        store.commit().unwrap();
        (path, store)
    }

    /// Asserts the file at `path` (copied, as a crash would leave it) opens at
    /// `generation` with section 0 beams `0..beams` holding `n` rays each.
    fn assert_committed(path: &Path, generation: u64, beams: u32, n: u64) {
        let copy = path.with_extension("copy");
        std::fs::copy(path, &copy).unwrap();
        let mut f = HoloFile::open(&copy, &crate::storage::OpenOptions::read_only()).unwrap();
        assert_eq!(f.open_info().generation, generation);
        for b in 0..f.sections()[0].beam_count() {
            let key = BeamKey::new(0, b);
            let want = if b < beams { n } else { 0 };
            assert_eq!(f.read_beam(key).unwrap(), pattern_rays(key, 0, want), "beam {b}");
        }
    }

    /// Uses up every free hole, so that any further allocation must extend the end.
    fn fill_holes(store: &mut Store) {
        let end = store.extents.end();
        while store.extents.allocate_below(1, end).is_some() {}
    }

    #[test]
    fn a_commit_that_cannot_place_its_directory_or_root_keeps_the_previous_one() {
        let dir = tempfile::tempdir().unwrap();
        let beams = 500;
        let (path, mut store) = committed_file(dir.path(), beams, 3);
        let generation = store.generation;
        for b in 0..beams {
            let key = BeamKey::new(0, b);
            store.write_tail(key, None, &pattern_rays(key, 3, 2)).unwrap();
        }
        fill_holes(&mut store);
        let end = store.extents.end();
        let free = store.extents.free_bytes();
        let dir_len = format::encode_directory(0, &store.dirs[0]).len() as u64;
        let root_len = format::root_len(store.dirs.len());
        // First no room for the directory, then room for it but not the root.
        for limit in [end + dir_len - 1, end + dir_len + root_len - 1] {
            store.set_limit(Some(limit));
            let e = store.commit().unwrap_err();
            assert!(
                matches!(e, StorageError::DiskSpace { limit: l, needed, .. } if l == limit && needed > limit),
                "{e}"
            );
            assert!(!store.poisoned, "a refused commit must not poison the file");
            assert_eq!(store.extents.end(), end, "the refused allocations are given back");
            assert_eq!(store.extents.free_bytes(), free);
            assert!(store.flush_writes().is_ok());
            assert!(std::fs::metadata(&path).unwrap().len() <= limit);
            assert_committed(&path, generation, beams, 3);
        }
        // With exactly enough room the commit goes through.
        store.set_limit(Some(end + dir_len + root_len));
        store.commit().unwrap();
        assert_eq!(store.generation, generation + 1);
        assert!(std::fs::metadata(&path).unwrap().len() <= end + dir_len + root_len);
        drop(store);
        assert_committed(&path, generation + 1, beams, 5);
    }

    #[test]
    fn runs_are_never_placed_past_the_limit() {
        let dir = tempfile::tempdir().unwrap();
        let (path, mut store) = committed_file(dir.path(), 10, 4);
        fill_holes(&mut store);
        let end = store.extents.end();
        store.set_limit(Some(end + 100));
        // A new beam of 10 rays (100 bytes) fits exactly; the next does not.
        let a = BeamKey::new(0, 20);
        store.write_tail(a, None, &pattern_rays(a, 0, 10)).unwrap();
        assert_eq!(store.extents.end(), end + 100);
        let b = BeamKey::new(0, 21);
        let e = store.write_tail(b, None, &pattern_rays(b, 0, 1)).unwrap_err();
        assert!(
            matches!(e, StorageError::DiskSpace { needed, .. } if needed == end + 110),
            "{e}"
        );
        // Growing a run that would have to move is refused too, and changes nothing.
        let c = BeamKey::new(0, 3);
        let before = store.dirs[0][3];
        assert!(store.write_tail(c, None, &pattern_rays(c, 4, 1)).is_err());
        assert_eq!(store.dirs[0][3], before);
        assert_eq!(store.extents.end(), end + 100);
        assert!(!store.poisoned);
        store.flush_writes().unwrap();
        assert!(std::fs::metadata(&path).unwrap().len() <= end + 100);
        // The run at the end grows in place as far as the limit allows.
        store.set_limit(Some(end + 120));
        store.write_tail(a, None, &pattern_rays(a, 10, 2)).unwrap();
        assert_eq!(store.extents.end(), end + 120);
        assert!(store.write_tail(a, None, &pattern_rays(a, 12, 1)).is_err());
    }
}
