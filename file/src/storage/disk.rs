//! The on-disk side of the engine: loads the current commit, writes beam runs,
//! and commits directories. Knows nothing of the cache.
//!
//! Crash safety rests on three rules. (1) Bytes the durable commit refers to are
//! never overwritten: new runs go to free space, and space released by a change
//! becomes free only after the commit that drops it is durable. (2) A commit
//! writes its directory blocks and root, two copies of each, to free space,
//! syncs, then writes copy 1 of the slot that is *not* the one the current
//! state was loaded from, syncs, writes copy 2, and syncs again. (3) Opening
//! takes the highest-generation slot copy that verifies (see
//! [`survey`](super::survey)): a torn last commit falls back to the one
//! before, and damage to a durable commit is reported as damage, never taken
//! for a crash.

use std::collections::HashSet;
use std::fs::File;
use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, RayRecord, Section};

use super::error::CommitDamage;
use super::error::{Result, StorageError};
use super::extents::Extents;
use super::format::{self, BeamEntry, ChunkRef, Extent, Prefix, Slot, COPIES, DIR_CHUNK_BEAMS};
use super::found::Survey;
use super::io::{self, WriteBatch};
use super::survey;
use crate::settings::Settings;

/// How the current state was found on open.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct OpenInfo {
    /// Generation of the newest commit: the one in use, or the damaged one
    /// whose readable part is in use.
    pub generation: u64,
    /// Slot side (0: A, 1: B) it was read from.
    pub slot: usize,
    /// Commits a crash interrupted between their two slot copies: the newer
    /// copy is used and nothing is lost.
    pub skipped: Vec<String>,
    /// Damaged copies of metadata whose other copy verified: nothing was lost.
    /// A writable open rewrites them at once.
    pub repaired: Vec<String>,
    /// Set when the newest commit cannot be read in full: what is lost.
    pub damage: Option<CommitDamage>,
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
    /// Beams found damaged (failing their checksum) when rays were added to
    /// them: their old rays were dropped and the new ones kept.
    pub damaged_beams: u64,
    /// The rays those beams lost.
    pub damaged_rays: u64,
}

/// A range of one section's beams that one directory block describes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) struct Chunk {
    pub section: u32,
    pub first: u32,
    pub beams: u32,
}

/// The chunks a file with these sections is cut into: [`DIR_CHUNK_BEAMS`] beams each.
pub(crate) fn chunks_of(sections: &[Section]) -> Vec<Chunk> {
    let mut out = Vec::new();
    for (s, section) in sections.iter().enumerate() {
        let n = section.beam_count();
        let mut first = 0;
        while first < n {
            let beams = DIR_CHUNK_BEAMS.min(n - first);
            out.push(Chunk {
                section: s as u32,
                first,
                beams,
            });
            first += beams;
        }
    }
    out
}

/// The file and its in-memory directories.
pub struct Disk {
    pub(crate) path: PathBuf,
    pub(crate) file: File,
    pub(crate) writable: bool,
    pub(crate) dirs: Vec<Vec<BeamEntry>>,
    /// Records each beam's run has room for (its count plus an in-memory growth
    /// reserve). No commit refers to the reserve, so reopening frees it.
    capacity: Vec<Vec<u32>>,
    /// Beams whose run was read and verified (or written) since opening: a
    /// beam's first append in a session checks what it appends to.
    verified: Vec<Vec<bool>>,
    chunks: Vec<Chunk>,
    /// Index of each section's first chunk.
    chunk_start: Vec<usize>,
    /// Chunks whose directory must be written at the next commit.
    chunk_dirty: Vec<bool>,
    /// The two copies of each chunk's block in the durable commit (`None`:
    /// not in it, so the chunk is dirty).
    blocks: Vec<Option<[Extent; COPIES]>>,
    /// The two copies of the durable commit's root, if it is this store's own.
    root: Option<[Extent; COPIES]>,
    /// The next commit must be made even with no chunk dirty (to restore a
    /// damaged copy).
    root_dirty: bool,
    /// Metadata a damaged commit was read from: kept until the next commit.
    stale: Vec<Extent>,
    text_len: u32,
    /// The file's format version: where its header copies lie.
    version: u32,
    generation: u64,
    next_side: usize,
    pub(crate) extents: Extents,
    writes: WriteBatch,
    /// Offsets of runs written since the last commit: no commit refers to them,
    /// so they can be freed at once when their beam moves again.
    fresh: HashSet<u64>,
    /// Where the next commit's metadata goes (compaction steers it).
    placement: Placement,
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

/// Where a commit puts its directory blocks and root.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Placement {
    /// The first copy where it fits best, the second as low as it fits, so
    /// that the two tend to lie apart.
    Normal,
    /// Both at the end of the file, above everything.
    End,
    /// Both as low as they fit.
    Low,
}

fn same_range(r: &ChunkRef, c: &Chunk) -> bool {
    (r.section, r.first, r.beams) == (c.section, c.first, c.beams)
}

/// Records a run of `count` records is given room for when it is written to
/// a new place (`moved`: the beam had a run and outgrew it), so that a beam
/// growing by small appends moves O(log n) times instead of O(n).
///
/// A beam's first run is exact: a beam written once wastes nothing, and the
/// first runs of a flush lie end to end, written in few large writes. A run
/// that moved has shown it grows: it gets as much room again as it holds, so
/// a beam that keeps growing copies its rays about twice in all. Under a size
/// limit (`limited`) it gets a quarter again (about five copies), so that
/// reserves and the holes moves leave stay a fifth to a quarter of the file.
/// Reserves are in memory only; closing compacts them away.
fn room(count: u32, moved: bool, limited: bool) -> u32 {
    match (moved, limited) {
        (false, _) => count,
        (true, true) => count.saturating_add(count / 4).max(count.saturating_add(4)),
        (true, false) => count.saturating_mul(2).max(count.saturating_add(4)),
    }
}

impl Disk {
    /// Opens the file's newest commit. Returns the settings too. A writable
    /// open refuses a file whose newest commit is damaged, unless
    /// `accept_loss`: then what can be read is committed at once as the new
    /// state. A writable open also rewrites at once any damaged copy whose
    /// twin verified, so the file is whole again.
    pub fn open(path: &Path, writable: bool, accept_loss: bool) -> Result<(Disk, Settings)> {
        Self::open_locked(path, writable, writable, accept_loss)
    }

    /// Like [`Disk::open`], but `exclusive` takes the writer's lock even for
    /// reading (for tools that replace the file when done).
    pub(crate) fn open_locked(
        path: &Path,
        writable: bool,
        exclusive: bool,
        accept_loss: bool,
    ) -> Result<(Disk, Settings)> {
        let file = std::fs::OpenOptions::new()
            .read(true)
            .write(writable)
            .open(path)
            .map_err(|source| StorageError::Io {
                path: path.to_path_buf(),
                op: "opening",
                source,
            })?;
        io::lock(&file, path, exclusive)?;
        let sv = survey::survey(&file, path)?;
        refuse_or_warn(&sv, path, writable, accept_loss)?;
        let chunks = chunks_of(&sv.settings.sections);
        let mut chunk_start = Vec::with_capacity(sv.settings.sections.len());
        for (i, c) in chunks.iter().enumerate() {
            if c.first == 0 {
                chunk_start.push(i);
            }
        }
        let (blocks, root, stale) = committed_blocks(&sv, &chunks);
        let mut extents = extents_in_use(&sv, root.is_some(), path)?;
        // What a damaged commit was read from stays untouched until the commit that replaces it.
        let stale: Vec<Extent> = stale.into_iter().flat_map(|e| extents.claim_free_within(e)).collect();
        let chunk_dirty: Vec<bool> = blocks
            .iter()
            .zip(&chunks)
            .map(|(b, c)| b.is_none() || sv.weak_chunks.contains(&(c.section, c.first)))
            .collect();
        let repaired = !sv.repaired.is_empty() || !sv.torn.is_empty() || sv.uneven_slots.iter().any(|&u| u);
        let newest_uneven = sv.uneven_slots[sv.side];
        let mut store = Disk {
            path: path.to_path_buf(),
            file,
            writable,
            capacity: sv.dirs.iter().map(|d| d.iter().map(|e| e.count).collect()).collect(),
            verified: sv.dirs.iter().map(|d| vec![false; d.len()]).collect(),
            dirs: sv.dirs,
            chunks,
            chunk_start,
            chunk_dirty,
            blocks,
            root,
            root_dirty: repaired,
            stale,
            text_len: sv.text_len,
            version: sv.version,
            generation: sv.generation,
            next_side: 1 - sv.side,
            extents,
            writes: WriteBatch::default(),
            fresh: HashSet::new(),
            placement: Placement::Normal,
            file_len: sv.file_len,
            stats: IoStats::default(),
            info: OpenInfo {
                generation: sv.generation,
                slot: sv.side,
                skipped: sv.torn,
                repaired: sv.repaired,
                damage: sv.damage,
            },
            poisoned: false,
            limit: u64::MAX,
        };
        if writable {
            store.restore_headers(&sv.settings, sv.bad_header)?;
            if store.has_changes() {
                // Make what was read (or the restored copies) the durable state before anything else.
                store.commit()?;
            }
            if newest_uneven {
                // The first commit went to the other side; this one rewrites the damaged slot.
                store.root_dirty = true;
                store.commit()?;
            }
        }
        Ok((store, sv.settings))
    }

    /// The file's prefix: its format version and settings text length.
    fn prefix(&self) -> Prefix {
        Prefix {
            version: self.version,
            text_len: self.text_len,
        }
    }

    /// Writes header copy `copy`: the prefix, then the settings text.
    fn write_header_copy(&mut self, prefix: Prefix, copy: usize, text: &str) -> Result<()> {
        let base = copy as u64 * format::header_stride(prefix);
        let r = io::write_at(&self.file, &self.path, base, &format::encode_prefix(prefix)).and_then(|()| {
            io::write_at(
                &self.file,
                &self.path,
                format::text_offset(prefix, copy),
                &format::encode_text(text),
            )
        });
        self.poison_on_error(r)
    }

    /// Rewrites a damaged header copy (prefix and settings text) from the settings.
    fn restore_headers(&mut self, settings: &Settings, bad: [bool; COPIES]) -> Result<()> {
        if !bad.iter().any(|&b| b) {
            return Ok(());
        }
        let text = settings.to_text();
        if text.len() != self.text_len as usize {
            // The settings would not read back to the same text: leave the copies alone.
            return Ok(());
        }
        let prefix = self.prefix();
        for (copy, _) in bad.iter().enumerate().filter(|(_, &b)| b) {
            self.write_header_copy(prefix, copy, &text)?;
            tracing::warn!(path = %self.path.display(), "rewrote header copy {}", copy + 1);
        }
        self.sync()
    }

    /// Replaces the settings text in both header copies, durably. The header
    /// cannot grow (beam runs follow it), so the new text must fit in the
    /// room the old one's copies span. Copy 2 is written and synced first:
    /// a crash before copy 1 is done leaves copy 1 whole (the old settings,
    /// read first) or torn (then copy 2, the new ones, is read).
    pub(crate) fn rewrite_settings(&mut self, settings: &Settings) -> Result<()> {
        if !self.writable {
            return Err(StorageError::ReadOnly {
                path: self.path.clone(),
            });
        }
        self.check_usable()?;
        let text = settings.to_text();
        let span = format::header_span(self.text_len);
        let room = span - format::TEXT_IN_HEADER - 4;
        let fits = u32::try_from(text.len())
            .ok()
            .filter(|&len| format::header_span(len) == span);
        let Some(len) = fits else {
            return Err(StorageError::SettingsTooLong {
                path: self.path.clone(),
                room,
                need: text.len() as u64,
            });
        };
        self.flush_writes()?;
        let prefix = Prefix {
            version: self.version,
            text_len: len,
        };
        for copy in [1, 0] {
            self.write_header_copy(prefix, copy, &text)?;
            self.sync()?;
        }
        self.text_len = len;
        Ok(())
    }

    /// The directory chunk holding a beam.
    pub(crate) fn chunk_of(&self, key: BeamKey) -> usize {
        self.chunk_start[key.section as usize] + (key.beam / DIR_CHUNK_BEAMS) as usize
    }

    /// Beams in each chunk, and how many of them hold rays on disk.
    pub(crate) fn chunk_fill(&self) -> Vec<(u32, u64)> {
        self.chunks
            .iter()
            .map(|c| {
                let d = &self.dirs[c.section as usize][c.first as usize..(c.first + c.beams) as usize];
                (c.beams, d.iter().filter(|e| e.count > 0).count() as u64)
            })
            .collect()
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

    pub(crate) fn check_usable(&self) -> Result<()> {
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

    /// True when chunk `c` must be written at the next commit.
    pub(crate) fn chunk_changed(&self, c: usize) -> bool {
        self.chunk_dirty[c]
    }

    /// Most bytes by which writing a beam's unwritten rays, so that it then
    /// holds `total` rays, can move the end of the allocated space (see
    /// [`Disk::write_tail`]): nothing if they fit the run's reserve; the exact
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
            u64::from(room(total32, true, self.limit != u64::MAX)) * RECORD
        }
    }

    /// Reads `len` bytes at `offset` into the start of `buf`, seeing every write
    /// made so far. `buf` only ever grows (no zero-filling per read); bytes past
    /// `len` are stale.
    pub(crate) fn read_into(&mut self, offset: u64, len: usize, buf: &mut Vec<u8>) -> Result<()> {
        // After a failed write the batch can never be written: read what the
        // disk holds (runs that were only in the batch then fail their checksum).
        if !self.poisoned && self.writes.overlaps(offset, len as u64) {
            self.flush_writes()?;
        }
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

    /// Checks the committed run of beam `key` before the session's first
    /// append to it: a run that fails its checksum loses its rays (reported
    /// and counted), the beam starts again empty, and writing goes on; the
    /// appended rays then stand alone instead of joining damaged ones.
    fn verify_before_append(&mut self, key: BeamKey) -> Result<()> {
        let (s, b) = (key.section as usize, key.beam as usize);
        let e = self.dirs[s][b];
        // A committed run is never the target of a pending write: read it as
        // the disk holds it, without flushing the write batch.
        let mut buf = vec![0u8; e.extent().len as usize];
        io::read_exact_at(&self.file, &self.path, e.offset, &mut buf)?;
        if crc32c::crc32c(&buf) == e.crc {
            self.verified[s][b] = true;
            return Ok(());
        }
        tracing::warn!(
            path = %self.path.display(),
            "beam {} of section {} (bytes {}..{}) fails its checksum: its {} damaged rays are dropped and writing goes on",
            key.beam,
            key.section,
            e.offset,
            e.extent().end(),
            e.count
        );
        self.stats.damaged_beams += 1;
        self.stats.damaged_rays += u64::from(e.count);
        self.release_run(s, b);
        self.dirs[s][b] = BeamEntry::default();
        self.capacity[s][b] = 0;
        self.verified[s][b] = true;
        let c = self.chunk_of(key);
        self.chunk_dirty[c] = true;
        Ok(())
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
        let in_memory = on_disk.is_some_and(|r| r.len() == self.dirs[s][b].count as usize);
        if self.dirs[s][b].count > 0 && !self.verified[s][b] && !in_memory {
            self.verify_before_append(key)?;
        }
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
                (0, _) => Some(Vec::new()),
                (_, Some(rays)) if rays.len() == old.count as usize => Some(RayRecord::slice_as_bytes(rays).to_vec()),
                _ => match self.read_run(key) {
                    Ok(bytes) => Some(bytes),
                    // A damaged beam stops nothing: its old rays are lost,
                    // the new ones go on, and every other beam is written.
                    Err(StorageError::BeamCorrupt { start, end, .. }) => {
                        tracing::warn!(
                            path = %self.path.display(),
                            "beam {} of section {} (bytes {start}..{end}) fails its checksum: its {} damaged rays are dropped, the {} new ones kept",
                            key.beam,
                            key.section,
                            old.count,
                            tail.len()
                        );
                        self.stats.damaged_beams += 1;
                        self.stats.damaged_rays += u64::from(old.count);
                        None
                    }
                    Err(e) => return Err(e),
                },
            };
            let (existing, count) = match existing {
                Some(bytes) => (bytes, count),
                None => (Vec::new(), tail.len() as u32),
            };
            let kept_old = old.count > 0 && !existing.is_empty();
            let room = room(count, old.count > 0, self.limit != u64::MAX);
            // The only step that can fail before anything changed: the limit.
            let offset = self.allocate(u64::from(room) * RECORD)?;
            self.push_write(offset, &existing)?;
            self.push_write(offset + existing.len() as u64, tail_bytes)?;
            // The reserve is this run's own free space: a run placed right
            // after it may join the same write, the reserve written as zeros.
            self.writes.pad_to(offset + u64::from(room) * RECORD);
            if old.count > 0 {
                self.release_run(s, b);
                self.stats.relocations += 1;
            }
            self.fresh.insert(offset);
            self.capacity[s][b] = room;
            let crc = if kept_old {
                crc32c::crc32c_append(old.crc, tail_bytes)
            } else {
                crc32c::crc32c(tail_bytes)
            };
            BeamEntry { offset, count, crc }
        };
        self.dirs[s][b] = new;
        self.verified[s][b] = true;
        let c = self.chunk_of(key);
        self.chunk_dirty[c] = true;
        self.stats.rays_written += tail.len() as u64;
        self.stats.runs_written += 1;
        Ok(())
    }

    /// Free bytes inside the allocated space: holes, space waiting for the
    /// next commit, and growth reserves.
    pub(crate) fn slack_bytes(&self) -> u64 {
        self.extents.free_bytes() + self.reserved_bytes()
    }

    /// Releases beam (s, b)'s run and its growth reserve, before the beam
    /// moves or empties: a run written since the last commit is free at once;
    /// one the last commit refers to stays pending until the next commit is
    /// durable, while its reserve, which no commit refers to, is free at once.
    fn release_run(&mut self, s: usize, b: usize) {
        let old = self.dirs[s][b];
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
    }

    /// Gives up every run's growth reserve: the bytes after each run that no
    /// commit refers to become holes.
    fn drop_reserves(&mut self) {
        for s in 0..self.dirs.len() {
            for b in 0..self.dirs[s].len() {
                let e = self.dirs[s][b];
                let cap = self.capacity[s][b];
                if e.count > 0 && cap > e.count {
                    self.extents.release_now(Extent {
                        offset: e.extent().end(),
                        len: u64::from(cap - e.count) * RECORD,
                    });
                    self.capacity[s][b] = e.count;
                }
            }
        }
    }

    /// Moves one beam's run to `to` (already allocated): copies and verifies
    /// its bytes, points the directory at the copy, and releases the old place
    /// as a moving write does.
    fn move_run(&mut self, s: usize, b: usize, to: u64) -> Result<()> {
        let old = self.dirs[s][b];
        let bytes = self.read_run(BeamKey::new(s as u32, b as u32))?;
        self.push_write(to, &bytes)?;
        self.release_run(s, b);
        self.fresh.insert(to);
        self.dirs[s][b] = BeamEntry { offset: to, ..old };
        self.capacity[s][b] = old.count;
        // Read and checked on the way: and its new place may still be in the write batch.
        self.verified[s][b] = true;
        let c = self.chunk_of(BeamKey::new(s as u32, b as u32));
        self.chunk_dirty[c] = true;
        self.stats.relocations += 1;
        Ok(())
    }

    /// Packs the beam runs toward the start of the file until at most
    /// `target` bytes are free inside it, then trims it. Each step takes the
    /// runs after the lowest hole, up to `window` bytes of them: it copies
    /// them to the end of the file and commits, then copies them down, in
    /// beam order, into the space they and the hole left and commits again.
    /// Every commit is a consistent state that a crash falls back to, and the
    /// file never grows by more than a window and two copies of the
    /// directories. Growth reserves are given up. Does nothing under a size
    /// limit (DISKSPACE), where that growth might not fit.
    /// `progress(step, bytes_free)` is called after each step.
    pub(crate) fn compact(&mut self, target: u64, window: u64, mut progress: impl FnMut(u64, u64)) -> Result<u64> {
        self.check_usable()?;
        // Under a size limit the steps' copies and rewritten directories
        // might not fit: such a file is left as it is.
        if self.limit != u64::MAX {
            return Ok(0);
        }
        self.drop_reserves();
        // Metadata stays above the runs being packed, then comes down right
        // after them in one last commit, which frees everything above it.
        self.placement = Placement::End;
        let result = self.compact_steps(target, window, &mut progress);
        self.placement = Placement::Low;
        self.root_dirty = true;
        self.chunk_dirty.iter_mut().for_each(|d| *d = true);
        let last = if result.is_ok() { self.commit() } else { Ok(()) };
        self.placement = Placement::Normal;
        let moved = result?;
        last?;
        Ok(moved)
    }

    fn compact_steps(&mut self, target: u64, window: u64, progress: &mut impl FnMut(u64, u64)) -> Result<u64> {
        let mut moved = 0u64;
        let mut step = 0u64;
        // Everything below the cursor is packed as far as it goes.
        let mut cursor = 0u64;
        loop {
            // A commit makes what the last step released free (nothing to
            // commit before the first step: the flush before it committed).
            self.commit()?;
            if self.extents.free_bytes() <= target {
                break;
            }
            let Some(hole) = self.extents.first_hole_from(cursor) else {
                break;
            };
            let mut runs: Vec<(u64, usize, usize)> = Vec::new();
            for (s, dir) in self.dirs.iter().enumerate() {
                for (b, e) in dir.iter().enumerate() {
                    if e.count > 0 && e.offset > hole.offset {
                        runs.push((e.offset, s, b));
                    }
                }
            }
            runs.sort_unstable();
            let mut taken = 0u64;
            let mut batch = Vec::new();
            let staging = self.extents.end();
            for &(_, s, b) in &runs {
                let len = self.dirs[s][b].extent().len;
                // A run larger than the window still moves, alone.
                if taken + len > window && !batch.is_empty() {
                    break;
                }
                taken += len;
                batch.push((s, b));
            }
            if batch.is_empty() {
                break;
            }
            for &(s, b) in &batch {
                let to = self.extents.allocate_at_end(self.dirs[s][b].extent().len);
                self.move_run(s, b, to)?;
            }
            self.commit()?;
            // Down in beam order: a window comes out collated, its directory
            // offsets one byte each, its beams read in order.
            batch.sort_unstable();
            let mut frontier = hole.end();
            for &(s, b) in &batch {
                let len = self.dirs[s][b].extent().len;
                // The lowest room below the staged copies: the hole, grown by what left it.
                if let Some(to) = self.extents.allocate_low_below(len, staging) {
                    self.move_run(s, b, to)?;
                    moved += len;
                    frontier = frontier.max(to + len);
                }
            }
            cursor = frontier;
            step += 1;
            progress(step, self.extents.free_bytes());
        }
        Ok(moved)
    }

    /// Empties every beam (the Clobber command): their runs are freed as a
    /// commit frees them, so the last commit stays readable until the next
    /// one is durable.
    pub(crate) fn clear_all(&mut self) -> Result<()> {
        self.check_usable()?;
        for s in 0..self.dirs.len() {
            for b in 0..self.dirs[s].len() {
                if self.dirs[s][b].count == 0 {
                    continue;
                }
                self.release_run(s, b);
                self.dirs[s][b] = BeamEntry::default();
                self.capacity[s][b] = 0;
            }
        }
        self.chunk_dirty.iter_mut().for_each(|d| *d = true);
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
        self.root_dirty || self.chunk_dirty.iter().any(|&d| d)
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
        let slot = match written {
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
        for (c, old) in self.blocks.iter().enumerate() {
            if let (true, Some(old)) = (self.chunk_dirty[c], old) {
                old.iter().for_each(|e| self.extents.release(*e));
            }
        }
        for e in std::mem::take(&mut self.stale) {
            self.extents.release(e);
        }
        self.blocks = blocks;
        self.flush_writes()?;
        self.sync()?;
        // From here on a failure leaves it unknown which commit is durable: poison.
        // Copy 1 is synced before copy 2 is written, so a crash tears at most one.
        let bytes = format::encode_slot(&slot);
        for copy in 0..COPIES {
            let at = format::slot_offset(self.prefix(), copy, self.next_side);
            let r = io::write_at(&self.file, &self.path, at, &bytes);
            self.poison_on_error(r)?;
            self.sync()?;
        }
        // The new commit is durable: the old root and everything released may be reused.
        if let Some(old) = self.root.replace(slot.root_copies()) {
            old.iter().for_each(|e| self.extents.release(*e));
        }
        self.extents.commit_done();
        self.fresh.clear();
        self.generation = generation;
        self.info.generation = generation;
        self.info.slot = self.next_side;
        self.next_side = 1 - self.next_side;
        self.chunk_dirty.iter_mut().for_each(|d| *d = false);
        self.root_dirty = false;
        self.stats.commits += 1;
        if self.file_len > self.extents.end() {
            // Space past the end is referenced by no commit: give it back.
            let r = io::set_len(&self.file, &self.path, self.extents.end());
            self.poison_on_error(r)?;
            self.file_len = self.extents.end();
        }
        Ok(())
    }

    /// Allocates two copies of `len` bytes: the first where it fits best, the
    /// second as low in the file as it fits at least [`format::COPY_GAP`]
    /// from the first. Both are pushed to `claimed`.
    fn allocate_copies(&mut self, len: u64, claimed: &mut Vec<Extent>) -> Result<[Extent; COPIES]> {
        let first = match self.placement {
            Placement::End => Some(self.extents.allocate_at_end(len)),
            Placement::Low => self.extents.allocate_low_below(len, self.limit),
            _ => self.extents.allocate_below(len, self.limit),
        };
        let first = Extent {
            offset: first.ok_or_else(|| self.no_space(self.extents.end().saturating_add(len)))?,
            len,
        };
        claimed.push(first);
        // At least COPY_GAP from the first: no damaged stretch of the disk
        // shorter than that takes both copies.
        let second = match self.placement {
            Placement::End => self.extents.allocate_apart(len, u64::MAX, first, format::COPY_GAP),
            _ => self.extents.allocate_apart(len, self.limit, first, format::COPY_GAP),
        };
        let second = match second {
            Some(offset) => Extent { offset, len },
            None => {
                let at = self.extents.end().max(first.end().saturating_add(format::COPY_GAP));
                return Err(self.no_space(at.saturating_add(len)));
            }
        };
        claimed.push(second);
        Ok([first, second])
    }

    /// Writes the dirty chunks' directory blocks and a root listing `blocks`
    /// (updated), two copies of each, to free space; returns the slot that
    /// will point at them. Every extent allocated is pushed to `claimed` first,
    /// for undoing on failure.
    fn write_metadata(
        &mut self,
        generation: u64,
        blocks: &mut [Option<[Extent; COPIES]>],
        claimed: &mut Vec<Extent>,
    ) -> Result<Slot> {
        let mut refs = Vec::with_capacity(self.chunks.len());
        for (c, block) in blocks.iter_mut().enumerate() {
            let Chunk { section, first, beams } = self.chunks[c];
            let entries = &self.dirs[section as usize][first as usize..(first + beams) as usize];
            let rays = entries.iter().map(|e| u64::from(e.count)).sum();
            if self.chunk_dirty[c] || block.is_none() {
                let bytes = format::encode_directory(section, first, entries);
                let copies = self.allocate_copies(bytes.len() as u64, claimed)?;
                for e in copies {
                    self.push_write(e.offset, &bytes)?;
                }
                *block = Some(copies);
            }
            let copies = block.unwrap_or_default();
            refs.push(ChunkRef {
                section,
                first,
                beams,
                rays,
                copies: copies.map(|e| e.offset),
                len: copies[0].len,
            });
        }
        let root_bytes = format::encode_root(generation, &refs);
        let roots = self.allocate_copies(root_bytes.len() as u64, claimed)?;

        for e in roots {
            self.push_write(e.offset, &root_bytes)?;
        }
        Ok(Slot {
            generation,
            roots: roots.map(|e| e.offset),
            root_len: root_bytes.len() as u64,
            root_crc: crc32c::crc32c(&root_bytes),
        })
    }

    /// Current length of the file in bytes.
    pub fn file_len(&self) -> u64 {
        self.file_len
    }

    /// Bytes taken by the directory blocks and root of the current commit, both copies.
    pub fn metadata_bytes(&self) -> u64 {
        let blocks: u64 = self.blocks.iter().flatten().flatten().map(|e| e.len).sum();
        blocks + self.root.iter().flatten().map(|e| e.len).sum::<u64>()
    }
}

/// Refuses to write a file of an older format, or a damaged one unless the
/// user accepts the loss; says what a survey found torn, repaired or lost.
fn refuse_or_warn(sv: &Survey, path: &Path, writable: bool, accept_loss: bool) -> Result<()> {
    if let (true, Some(found)) = (writable, sv.legacy) {
        return Err(StorageError::Format {
            path: path.to_path_buf(),
            source: format::FormatError::OldVersion {
                found,
                supported: format::FORMAT_VERSION,
            },
        });
    }
    if let Some(damage) = &sv.damage {
        if writable && !accept_loss {
            return Err(StorageError::Damaged {
                path: path.to_path_buf(),
                damage: Box::new(damage.clone()),
            });
        }
        tracing::warn!(path = %path.display(), "{}", damage.describe());
    }
    for note in sv.torn.iter().chain(&sv.repaired) {
        tracing::warn!(path = %path.display(), "{note}");
    }
    Ok(())
}

/// Where the newest clean commit keeps each directory chunk and the root,
/// where it matches the sections' chunks; otherwise none (every chunk is
/// written anew) and the metadata read is stale.
#[allow(clippy::type_complexity)]
fn committed_blocks(
    sv: &Survey,
    chunks: &[Chunk],
) -> (Vec<Option<[Extent; COPIES]>>, Option<[Extent; COPIES]>, Vec<Extent>) {
    let mut blocks = vec![None; chunks.len()];
    let mut root = None;
    let mut stale = Vec::new();
    match &sv.clean {
        Some((slot, refs)) if refs.len() == chunks.len() && refs.iter().zip(chunks).all(|(r, c)| same_range(r, c)) => {
            for (b, r) in blocks.iter_mut().zip(refs) {
                *b = Some(r.extents());
            }
            root = Some(slot.root_copies());
        }
        _ => stale.clone_from(&sv.metadata),
    }
    (blocks, root, stale)
}

/// The file's space as the survey found it used: the beams' extents, and
/// the metadata where the commit is kept (`committed`). Bytes claimed twice
/// are a format error.
fn extents_in_use(sv: &Survey, committed: bool, path: &Path) -> Result<Extents> {
    let mut used: Vec<Extent> = sv.dirs.iter().flatten().map(|e| e.extent()).collect();
    if committed {
        used.extend(sv.metadata.iter().copied());
    }
    Extents::from_used(sv.data_start, used).map_err(|o| StorageError::Format {
        path: path.to_path_buf(),
        source: format::FormatError::Invalid {
            what: format!("commit {}", sv.generation),
            at: o.second.offset,
            detail: format!(
                "bytes {}..{} are claimed twice (also by {}..{})",
                o.second.offset,
                o.second.end(),
                o.first.offset,
                o.first.end()
            ),
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::storage::HoloFile;
    use crate::testing::{pattern_rays, two_sections};

    /// A new file whose section 0 beams `0..beams` hold `n` rays each, committed.
    fn committed_file(dir: &Path, beams: u32, n: u64) -> (PathBuf, Disk) {
        let path = dir.join("t.hdk");
        HoloFile::create(&path, &two_sections([4, 3, 2], [2, 2, 2], 1 << 20)).unwrap();
        let (mut store, _) = Disk::open(&path, true, false).unwrap();
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
    fn fill_holes(store: &mut Disk) {
        let end = store.extents.end();
        while store.extents.allocate_below(1, end).is_some() {}
    }

    #[test]
    fn a_moved_run_gets_as_much_room_again_or_a_quarter_under_a_limit_and_joins_the_next_write() {
        let dir = tempfile::tempdir().unwrap();
        for limited in [false, true] {
            let sub = dir.path().join(if limited { "limited" } else { "free" });
            std::fs::create_dir(&sub).unwrap();
            let (path, mut store) = committed_file(&sub, 3, 10);
            if limited {
                store.set_limit(Some(1 << 30));
            }
            fill_holes(&mut store);
            // First runs are exact: nothing is reserved.
            assert_eq!(store.reserved_bytes(), 0);
            // Beams 0 and 1 outgrow their runs (each lies against the next):
            // both move to the end of the file, one after the other.
            for b in 0..2 {
                let key = BeamKey::new(0, b);
                store.write_tail(key, None, &pattern_rays(key, 10, 10)).unwrap();
            }
            let (room, reserve) = if limited { (25, 5) } else { (40, 20) };
            assert_eq!(store.capacity[0][0], room);
            assert_eq!(store.capacity[0][1], room);
            assert_eq!(store.reserved_bytes(), 2 * reserve * RECORD);
            let (first, second) = (store.dirs[0][0].offset, store.dirs[0][1].offset);
            assert_eq!(
                second,
                first + u64::from(room) * RECORD,
                "the second run follows the first's reserve"
            );
            // Both moves are one write still queued: the first run, its
            // reserve as zeros, the second run.
            assert_eq!(
                store.writes.queued(),
                (first, ((u64::from(room) + 20) * RECORD) as usize)
            );
            // Appends land in the reserve, in place.
            let key = BeamKey::new(0, 0);
            store.write_tail(key, None, &pattern_rays(key, 20, reserve)).unwrap();
            assert_eq!(store.dirs[0][0].offset, first);
            store.commit().unwrap();
            drop(store);
            let mut f = HoloFile::open(&path, &crate::storage::OpenOptions::read_only()).unwrap();
            assert_eq!(f.read_beam(key).unwrap(), pattern_rays(key, 0, u64::from(room)));
            let key = BeamKey::new(0, 1);
            assert_eq!(f.read_beam(key).unwrap(), pattern_rays(key, 0, 20));
        }
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
        // Every chunk of section 0 changed; each is written twice.
        let dir_len: u64 = store
            .chunks
            .iter()
            .filter(|c| c.section == 0)
            .map(|c| {
                let d = &store.dirs[0][c.first as usize..(c.first + c.beams) as usize];
                2 * format::encode_directory(0, c.first, d).len() as u64
            })
            .sum();
        let root_len = 2 * format::root_len(store.chunks.len());
        // First no room for the directories, then room for them but not the
        // root (nor the gap between copies).
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
        // With room for both copies and the gap kept between them, the commit goes through.
        let room = end + dir_len + root_len + 2 * format::COPY_GAP;
        store.set_limit(Some(room));
        store.commit().unwrap();
        assert_eq!(store.generation, generation + 1);
        assert!(std::fs::metadata(&path).unwrap().len() <= room);
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
