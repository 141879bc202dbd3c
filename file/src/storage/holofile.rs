//! [`HoloFile`]: a holodeck file opened for use — append rays to beams, read
//! beams (from the cache, else from disk in file order), and flush.
//!
//! Memory stays within the cache budget plus the directories (16 bytes per
//! beam) plus the free list and a read buffer of a few MiB, whatever the file size.

use std::path::Path;
use std::time::{Duration, Instant};

use holodeck_protocol::{BeamKey, RayRecord, Section, SectionError, RAY_RECORD_BYTES};

use super::bulk::SequentialWriter;
use super::cache::BeamCache;
use super::disk::{Disk, IoStats, OpenInfo};
use super::error::{Result, StorageError};
use super::format::BeamEntry;
use super::space::{Charge, SpaceBound};
use crate::settings::Settings;

/// Runs closer than this are read in one request, gap included.
const MERGE_GAP: u64 = 16 << 10;
/// Largest single read when merging runs.
const MERGE_LIMIT: u64 = 8 << 20;
/// How far ahead of the current read the kernel is told what comes next.
const READ_AHEAD: u64 = 32 << 20;
/// Closing compacts a file whose free space passes 1/`COMPACT_SHARE` of it.
pub const COMPACT_SHARE: u64 = 20;
/// Bytes of runs each compaction step moves: the most the file grows meanwhile.
pub const COMPACT_WINDOW: u64 = 64 << 20;
/// Default interval between automatic flushes.
pub const DEFAULT_FLUSH_INTERVAL: Duration = Duration::from_secs(2);

/// How to open a holodeck file.
#[derive(Clone, Debug)]
pub struct OpenOptions {
    /// Open for writing (takes an exclusive lock) or reading (shared lock).
    pub writable: bool,
    /// Cache budget in bytes; `None` uses the file's CACHE setting.
    pub cache_bytes: Option<u64>,
    /// Flush automatically when this much time has passed since the last flush.
    pub flush_interval: Option<Duration>,
    /// Open for writing even when the newest commit is damaged, making what
    /// can still be read the new state (the rest is lost for good). Without
    /// it, such a file is refused with [`StorageError::Damaged`]. Reading
    /// never needs it: a read-only open shows what can be read.
    pub accept_loss: bool,
}

impl Default for OpenOptions {
    fn default() -> Self {
        OpenOptions {
            writable: true,
            cache_bytes: None,
            flush_interval: Some(DEFAULT_FLUSH_INTERVAL),
            accept_loss: false,
        }
    }
}

impl OpenOptions {
    /// Options for reading only.
    pub fn read_only() -> Self {
        OpenOptions {
            writable: false,
            flush_interval: None,
            ..Self::default()
        }
    }
}

/// What a batch read delivered.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ReadReport {
    /// Beams delivered.
    pub beams: u64,
    /// Rays delivered.
    pub rays: u64,
    /// Beams served from the cache.
    pub cache_hits: u64,
    /// Beams whose records failed their checksum (not delivered).
    pub corrupt: Vec<BeamKey>,
}

/// Per-file summary for reports (like Radiance's rhinfo).
#[derive(Clone, Debug, PartialEq)]
pub struct FileSummary {
    /// Per section: (beams, beams holding rays, rays).
    pub sections: Vec<(u32, u32, u64)>,
    /// Bytes in the file.
    pub file_bytes: u64,
    /// Bytes of ray records.
    pub ray_bytes: u64,
    /// Bytes of the current directories and root.
    pub metadata_bytes: u64,
    /// Free bytes inside the file (holes, plus growth reserves that reopening frees).
    pub free_bytes: u64,
    /// Number of free holes.
    pub fragments: usize,
    /// Generation of the current commit.
    pub generation: u64,
}

impl FileSummary {
    /// Rays in all sections.
    pub fn rays(&self) -> u64 {
        self.sections.iter().map(|s| s.2).sum()
    }
    /// Whole-file bytes per ray.
    pub fn bytes_per_ray(&self) -> f64 {
        self.file_bytes as f64 / self.rays().max(1) as f64
    }
}

/// An open holodeck file.
pub struct HoloFile {
    store: Disk,
    settings: Settings,
    cache: BeamCache,
    flush_interval: Option<Duration>,
    last_flush: Instant,
    read_buf: Vec<u8>,
    /// The DISKSPACE bound, when the file has a size limit.
    space: Option<SpaceBound>,
}

impl HoloFile {
    /// Creates a new, empty holodeck file with these settings. Refuses to replace an existing file.
    pub fn create(path: &Path, settings: &Settings) -> Result<()> {
        if path.exists() {
            return Err(StorageError::Exists {
                path: path.to_path_buf(),
            });
        }
        SequentialWriter::create(path, settings)?.finish()
    }

    /// Opens an existing file. A file opened for writing is limited to its
    /// DISKSPACE setting, if it has one (see [`HoloFile::set_size_limit`]).
    pub fn open(path: &Path, options: &OpenOptions) -> Result<HoloFile> {
        Self::open_with(path, options, options.writable)
    }

    /// Opens for reading under the writer's exclusive lock: for tools that
    /// replace the file when done (no server may write to it meanwhile).
    pub(crate) fn open_exclusive_read(path: &Path, cache_bytes: u64) -> Result<HoloFile> {
        let options = OpenOptions {
            cache_bytes: Some(cache_bytes),
            ..OpenOptions::read_only()
        };
        Self::open_with(path, &options, true)
    }

    fn open_with(path: &Path, options: &OpenOptions, exclusive: bool) -> Result<HoloFile> {
        let (store, settings) = Disk::open_locked(path, options.writable, exclusive, options.accept_loss)?;
        let budget = options.cache_bytes.unwrap_or(settings.cache_bytes);
        let limit = (options.writable && settings.diskspace_bytes > 0).then_some(settings.diskspace_bytes);
        let mut file = HoloFile {
            store,
            cache: BeamCache::new(usize::try_from(budget).unwrap_or(usize::MAX)),
            settings,
            flush_interval: options.flush_interval,
            last_flush: Instant::now(),
            read_buf: Vec::new(),
            space: None,
        };
        file.set_size_limit(limit);
        Ok(file)
    }

    /// Limits the file to `limit` bytes (`None`: no limit), replacing the
    /// DISKSPACE setting it was opened with. The limit is hard: no write, at an
    /// eviction, a flush or a commit, makes the file longer than this.
    /// [`HoloFile::append`] refuses rays that might not fit, with
    /// [`StorageError::DiskSpace`]. A file already longer than the limit takes
    /// no more rays. Lowering the limit below what rays already appended need
    /// makes the flushes that would write them fail with `DiskSpace` (the rays
    /// stay cached) until it is raised again. Costs a pass over the directories.
    pub fn set_size_limit(&mut self, limit: Option<u64>) {
        self.store.set_limit(limit);
        self.space = limit.map(|limit| {
            let fill = self.store.chunk_fill();
            let beams: Vec<u32> = fill.iter().map(|f| f.0).collect();
            let mut filled: Vec<u64> = fill.iter().map(|f| f.1).collect();
            let mut touched: Vec<bool> = (0..beams.len()).map(|c| self.store.chunk_changed(c)).collect();
            let mut writes = 0u64;
            for key in self.cache.dirty_keys() {
                let c = self.store.chunk_of(key);
                let total = self.beam_len(key).unwrap_or(0);
                if self.entry(key).count == 0 {
                    filled[c] += 1;
                }
                touched[c] = true;
                writes = writes.saturating_add(self.store.write_growth_bound(key, total));
            }
            SpaceBound::new(limit, self.store.data_end(), writes, beams, filled, touched)
        });
    }

    /// The size limit in bytes, if any (see [`HoloFile::set_size_limit`]).
    pub fn size_limit(&self) -> Option<u64> {
        self.space.as_ref().map(|s| s.limit())
    }

    /// Bytes by which the file may still grow, beyond the most that the rays
    /// appended but not yet flushed can take, before the size limit refuses
    /// appends; `None` without a limit. An upper bound on what is used, so the
    /// file may end up holding more than this suggests. A flush makes it exact.
    pub fn headroom(&self) -> Option<u64> {
        self.space.as_ref().map(|s| s.limit().saturating_sub(s.bound()))
    }

    /// What appending `n` rays to `key` (a valid key) adds to the space bound.
    fn charge_for(&self, key: BeamKey, n: u64) -> Charge {
        let len = self.beam_len(key).unwrap_or(0);
        let unwritten = self.cache.peek(&key).map_or(0, |e| e.unwritten);
        // The beam's next write carries all its unwritten rays: charge the
        // difference from what the appends since its last write were charged.
        let before = if unwritten > 0 {
            self.store.write_growth_bound(key, len)
        } else {
            0
        };
        let after = self.store.write_growth_bound(key, len + n);
        Charge::new(self.store.chunk_of(key), len == 0, after.saturating_sub(before))
    }

    /// Makes sure the file has room for `n` more rays in `key`, flushing first
    /// if the bound says it might not; charges them to the bound.
    fn reserve_space(&mut self, key: BeamKey, n: u64) -> Result<()> {
        let Some(space) = &self.space else {
            return Ok(());
        };
        let mut charge = self.charge_for(key, n);
        if space.with(charge) > space.limit() && space.has_pending() {
            // The bound only falls at a flush, where it becomes exact.
            self.flush()?;
            charge = self.charge_for(key, n);
        }
        let Some(space) = &mut self.space else {
            return Ok(());
        };
        let needed = space.with(charge);
        if needed > space.limit() {
            return Err(StorageError::DiskSpace {
                path: self.store.path.clone(),
                limit: space.limit(),
                needed,
            });
        }
        space.charge(charge);
        Ok(())
    }

    /// The file's settings (sections included).
    pub fn settings(&self) -> &Settings {
        &self.settings
    }
    /// The sections.
    pub fn sections(&self) -> &[Section] {
        &self.settings.sections
    }
    /// The path opened.
    pub fn path(&self) -> &Path {
        &self.store.path
    }
    /// How the current commit was found.
    pub fn open_info(&self) -> &OpenInfo {
        &self.store.info
    }
    /// I/O counters since open.
    pub fn io_stats(&self) -> IoStats {
        self.store.stats
    }
    /// Bytes now charged to the cache, and its budget.
    pub fn cache_usage(&self) -> (usize, usize) {
        (self.cache.bytes(), self.cache.budget())
    }

    fn check_key(&self, key: BeamKey) -> Result<()> {
        let count = self.settings.sections.len();
        let section = self
            .settings
            .sections
            .get(key.section as usize)
            .ok_or(StorageError::NoSuchSection {
                section: key.section,
                count,
            })?;
        if key.beam >= section.beam_count() {
            let source = SectionError::BeamOutOfRange {
                beam: key.beam,
                count: section.beam_count(),
            };
            return Err(StorageError::Beam {
                section: key.section,
                source,
            });
        }
        Ok(())
    }

    fn entry(&self, key: BeamKey) -> BeamEntry {
        self.store.dirs[key.section as usize][key.beam as usize]
    }

    /// The error for a beam whose rays on disk fail their checksum, naming its byte range.
    pub(crate) fn corrupt(&self, key: BeamKey) -> StorageError {
        let e = self
            .directory(key.section)
            .and_then(|d| d.get(key.beam as usize))
            .map(|b| b.extent())
            .unwrap_or_default();
        StorageError::BeamCorrupt {
            path: self.path().to_path_buf(),
            key,
            start: e.offset,
            end: e.end(),
        }
    }

    /// Rays stored in a beam, written or not.
    pub fn beam_len(&self, key: BeamKey) -> Result<u64> {
        self.check_key(key)?;
        let on_disk = u64::from(self.entry(key).count);
        Ok(match self.cache.peek(&key) {
            Some(e) if e.loaded => e.rays.len() as u64,
            Some(e) => on_disk + e.unwritten as u64,
            None => on_disk,
        })
    }

    /// Appends rays to a beam. They are durable after the next flush.
    ///
    /// With a size limit, rays that might not fit are refused with
    /// [`StorageError::DiskSpace`] before anything is stored (after a flush,
    /// if that could make room). Each append is judged alone: a smaller one
    /// may still fit.
    pub fn append(&mut self, key: BeamKey, rays: &[RayRecord]) -> Result<()> {
        if !self.store.writable {
            return Err(StorageError::ReadOnly {
                path: self.store.path.clone(),
            });
        }
        // After a failed write nothing more can become durable: refuse at once
        // rather than caching rays that can never be written.
        self.store.check_usable()?;
        self.check_key(key)?;
        let n = rays.len() as u64;
        if self.space.is_some() {
            // The bound is charged before anything is stored.
            if self.beam_len(key)? + n > u64::from(u32::MAX) {
                return Err(StorageError::BeamFull { key });
            }
            if n > 0 {
                self.reserve_space(key, n)?;
            }
        }
        let on_disk = u64::from(self.entry(key).count);
        let full = self.cache.update(key, |e| {
            let len = if e.loaded {
                e.rays.len() as u64
            } else {
                on_disk + e.unwritten as u64
            };
            if len + n > u64::from(u32::MAX) {
                return true;
            }
            if e.rays.is_empty() && e.unwritten == 0 {
                // A beam with nothing on disk is whole in memory from its first ray.
                e.loaded = on_disk == 0;
            }
            e.rays.extend_from_slice(rays);
            e.unwritten += rays.len();
            false
        });
        if full {
            if self
                .cache
                .peek(&key)
                .is_some_and(|e| e.rays.is_empty() && e.unwritten == 0)
            {
                self.cache.remove(&key);
            }
            return Err(StorageError::BeamFull { key });
        }
        if self.cache.over_budget() {
            self.evict()?;
        }
        self.flush_if_due()?;
        Ok(())
    }

    /// Changes the automatic flush interval (`None`: flush only when asked).
    pub fn set_flush_interval(&mut self, interval: Option<Duration>) {
        self.flush_interval = interval;
    }

    /// Flushes if the flush interval has passed since the last flush and there
    /// is something to write; returns whether it flushed. A server calls this
    /// on a timer so that rays appended just before a quiet spell still become
    /// durable within the interval.
    pub fn flush_if_due(&mut self) -> Result<bool> {
        let due = self.flush_interval.is_some_and(|i| self.last_flush.elapsed() >= i);
        if !due || !self.store.writable {
            return Ok(false);
        }
        if self.cache.dirty_count() == 0 && !self.store.has_changes() {
            self.last_flush = Instant::now();
            return Ok(false);
        }
        self.flush()?;
        Ok(true)
    }

    /// Writes least-recently-used beams until the cache is 10% under budget.
    /// Each entry leaves the cache only after its rays are written, so a failed
    /// write loses nothing: the rays stay cached for the next flush.
    fn evict(&mut self) -> Result<()> {
        let excess = self.cache.bytes().saturating_sub(self.cache.budget() / 10 * 9);
        let mut victims = self.cache.lru_keys(excess, false);
        victims.sort_by_key(|k| self.entry(*k).offset);
        for key in victims {
            if let Some(e) = self.cache.peek(&key) {
                if e.unwritten > 0 {
                    let on_disk = e.loaded.then(|| &e.rays[..e.rays.len() - e.unwritten]);
                    self.store.write_tail(key, on_disk, e.tail())?;
                }
            }
            self.cache.remove(&key);
        }
        Ok(())
    }

    /// Drops least-recently-used beams that have nothing unwritten, touching
    /// neither the file nor the directory (safe in the middle of a read).
    fn evict_clean(&mut self) {
        let excess = self.cache.bytes().saturating_sub(self.cache.budget() / 10 * 9);
        for key in self.cache.lru_keys(excess, true) {
            self.cache.remove(&key);
        }
    }

    /// Flushes, then packs the beam runs toward the start of the file in
    /// steps of [`COMPACT_WINDOW`] bytes, each two commits (copies to the
    /// end, then down into the holes, in beam order within the step), until
    /// less than 1% of the file is free, and trims it. (`optimize` collates
    /// the whole file in beam order.)
    /// A crash at any point leaves the last commit, with every ray. Returns
    /// the bytes moved.
    pub fn compact(&mut self) -> Result<u64> {
        if !self.store.writable {
            return Err(StorageError::ReadOnly {
                path: self.store.path.clone(),
            });
        }
        self.flush()?;
        let before = self.store.data_end();
        tracing::info!(
            path = %self.store.path.display(),
            bytes = before,
            free = self.store.slack_bytes(),
            "compacting"
        );
        // What cannot be packed: the gap kept between metadata copies.
        let target = before / 100 + super::format::COPY_GAP;
        let moved = self.store.compact(target, COMPACT_WINDOW, |step, free| {
            tracing::debug!(step, free, "compacting");
        })?;
        tracing::info!(
            path = %self.store.path.display(),
            moved,
            before,
            after = self.store.data_end(),
            "compacted"
        );
        if let Some(space) = &mut self.space {
            space.flushed(self.store.data_end());
        }
        Ok(moved)
    }

    /// Writes every unwritten ray and commits, so that all appended rays survive a crash.
    pub fn flush(&mut self) -> Result<()> {
        self.store.check_usable()?;
        let mut keys = self.cache.dirty_keys();
        keys.sort_by_key(|k| self.entry(*k).offset);
        for key in keys {
            if let Some(e) = self.cache.peek(&key) {
                let on_disk = e.loaded.then(|| &e.rays[..e.rays.len() - e.unwritten]);
                self.store.write_tail(key, on_disk, e.tail())?;
                self.cache.mark_written(&key);
            }
        }
        self.store.commit()?;
        if tracing::enabled!(tracing::Level::DEBUG) {
            // What a crash can no longer take away (tests read it).
            tracing::debug!(
                "{}: commit {} made {} rays durable",
                self.store.path.display(),
                self.store.info.generation,
                self.summary().rays()
            );
        }
        self.last_flush = Instant::now();
        if let Some(space) = &mut self.space {
            space.flushed(self.store.data_end());
        }
        Ok(())
    }

    /// Deletes every ray in the file, durably (rays appended and not yet
    /// flushed are dropped too). A crash midway leaves the file as it was.
    /// With no rays left, none is stale any more.
    pub fn clobber(&mut self) -> Result<()> {
        if !self.store.writable {
            return Err(StorageError::ReadOnly {
                path: self.store.path.clone(),
            });
        }
        self.cache = BeamCache::new(self.cache.budget());
        self.store.clear_all()?;
        self.flush()?;
        if self.settings.stale {
            let settings = Settings {
                stale: false,
                ..self.settings.clone()
            };
            self.set_settings(settings)?;
        }
        Ok(())
    }

    /// Records that the file's rays are now for the scene with content hash
    /// `scene`, durably (fsynced). With `stale_rays`, the rays it holds are
    /// marked as traced in an older scene (see [`Settings::stale`]); without,
    /// the mark stays as it was (a clobber clears it).
    pub fn set_scene(&mut self, scene: &str, stale_rays: bool) -> Result<()> {
        let settings = Settings {
            scene: Some(scene.to_string()),
            stale: self.settings.stale || stale_rays,
            ..self.settings.clone()
        };
        self.set_settings(settings)
    }

    /// Replaces the settings in the header, durably; the sections may not change.
    fn set_settings(&mut self, settings: Settings) -> Result<()> {
        settings.validate().map_err(|source| StorageError::Settings {
            path: self.store.path.clone(),
            source,
        })?;
        debug_assert_eq!(settings.sections, self.settings.sections);
        self.store.rewrite_settings(&settings)?;
        self.settings = settings;
        Ok(())
    }

    /// Flushes and closes, reporting any error (dropping flushes too, but can
    /// only log). A file whose free space and growth reserves (less the gap
    /// kept between metadata copies) pass 1/[`COMPACT_SHARE`] of it is
    /// compacted first (see [`HoloFile::compact`]).
    pub fn close(mut self) -> Result<()> {
        if self.store.writable {
            self.flush()?;
            // The gap kept between metadata copies is not waste.
            let waste = self.store.slack_bytes().saturating_sub(super::format::COPY_GAP);
            if waste > self.store.data_end() / COMPACT_SHARE {
                self.compact()?;
            }
        }
        self.store.writable = false;
        Ok(())
    }

    /// Closes without flushing, losing unflushed rays exactly as a crash would.
    /// For tests of crash recovery.
    #[doc(hidden)]
    pub fn abandon(mut self) {
        self.store.writable = false;
    }

    /// Reads one beam, verifying its checksum.
    pub fn read_beam(&mut self, key: BeamKey) -> Result<Vec<RayRecord>> {
        let mut out = Vec::new();
        let report = self.read_beams(&[key], |_, rays| out.extend_from_slice(rays))?;
        if !report.corrupt.is_empty() {
            let e = self.entry(key);
            return Err(StorageError::BeamCorrupt {
                path: self.store.path.clone(),
                key,
                start: e.offset,
                end: e.extent().end(),
            });
        }
        Ok(out)
    }

    /// Delivers each requested beam's rays to `visit`: cached beams first, then
    /// the rest read from disk in file order, nearby runs merged into large reads.
    /// Beams that fail their checksum are reported, not delivered.
    pub fn read_beams(&mut self, keys: &[BeamKey], mut visit: impl FnMut(BeamKey, &[RayRecord])) -> Result<ReadReport> {
        let mut report = ReadReport::default();
        let mut misses = Vec::new();
        for &key in keys {
            self.check_key(key)?;
            let on_disk = self.entry(key).count;
            match self.cache.touch(&key) {
                Some(e) if e.loaded => {
                    report.cache_hits += 1;
                    report.beams += 1;
                    report.rays += e.rays.len() as u64;
                    visit(key, &e.rays);
                }
                _ if on_disk == 0 => {
                    report.beams += 1;
                    visit(key, &[]);
                }
                _ => misses.push(key),
            }
        }
        misses.sort_by_key(|k| self.entry(*k).offset);
        misses.dedup();
        // A request bigger than the cache would only churn it: deliver straight
        // from the read buffer instead (scan resistance).
        let miss_bytes: u64 = misses.iter().map(|k| self.entry(*k).extent().len).sum();
        let keep = miss_bytes <= self.cache.budget() as u64 / 2;
        let groups = self.read_groups(&misses);
        let mut announced = 0;
        let mut start = 0;
        for (k, &(end, first, group_end)) in groups.iter().enumerate() {
            announced = self.announce(&groups, k, announced);
            let mut buf = std::mem::take(&mut self.read_buf);
            self.store.read_into(first, (group_end - first) as usize, &mut buf)?;
            for &key in &misses[start..end] {
                let e = self.entry(key);
                let bytes = &buf[(e.offset - first) as usize..][..e.extent().len as usize];
                if crc32c::crc32c(bytes) != e.crc {
                    tracing::error!(
                        section = key.section,
                        beam = key.beam,
                        "beam fails its checksum at bytes {}..{}",
                        e.offset,
                        e.extent().end()
                    );
                    report.corrupt.push(key);
                    continue;
                }
                self.deliver(key, bytes, keep, &mut report, &mut visit)?;
            }
            self.read_buf = buf;
            start = end;
        }
        if self.read_buf.capacity() > 2 * MERGE_LIMIT as usize {
            self.read_buf = Vec::new();
        }
        if self.cache.over_budget() {
            self.evict()?;
        }
        Ok(report)
    }

    /// Splits keys sorted by offset into reads: (index one past the group's last
    /// key, first byte, one past the last byte). Nearby runs share a read.
    fn read_groups(&self, sorted: &[BeamKey]) -> Vec<(usize, u64, u64)> {
        let mut groups = Vec::new();
        let mut i = 0;
        while i < sorted.len() {
            let first = self.entry(sorted[i]).offset;
            let mut end = self.entry(sorted[i]).extent().end();
            let mut j = i + 1;
            while j < sorted.len() {
                let e = self.entry(sorted[j]).extent();
                if e.offset > end + MERGE_GAP || e.end().max(end) - first > MERGE_LIMIT {
                    break;
                }
                end = end.max(e.end());
                j += 1;
            }
            groups.push((j, first, end));
            i = j;
        }
        groups
    }

    /// Keeps the kernel told of the reads up to [`READ_AHEAD`] bytes past group
    /// `at`, so the disk works on many at once; returns how many groups are announced.
    fn announce(&self, groups: &[(usize, u64, u64)], at: usize, announced: usize) -> usize {
        if announced > at + 1 {
            return announced;
        }
        let mut bytes = 0;
        let mut upto = announced.max(at);
        while upto < groups.len() && bytes < READ_AHEAD {
            bytes += groups[upto].2 - groups[upto].1;
            upto += 1;
        }
        let window: Vec<(u64, u64)> = groups[announced.max(at)..upto].iter().map(|g| (g.1, g.2)).collect();
        self.store.will_need(&window);
        upto
    }

    /// Joins a beam's disk records with any cached unwritten tail, visits it, and
    /// caches it if `keep` and it is small enough to be worth a place.
    fn deliver(
        &mut self,
        key: BeamKey,
        bytes: &[u8],
        keep: bool,
        report: &mut ReadReport,
        visit: &mut impl FnMut(BeamKey, &[RayRecord]),
    ) -> Result<()> {
        let on_disk = RayRecord::slice_from_bytes(bytes).unwrap_or(&[]);
        // Note: nothing here may write to the file (see `evict_clean`).
        let tail: &[RayRecord] = self.cache.peek(&key).map(|e| e.tail()).unwrap_or(&[]);
        if tail.is_empty() && !keep {
            report.beams += 1;
            report.rays += on_disk.len() as u64;
            visit(key, on_disk);
            return Ok(());
        }
        let mut rays = Vec::with_capacity(on_disk.len() + tail.len());
        rays.extend_from_slice(on_disk);
        rays.extend_from_slice(tail);
        let unwritten = tail.len();
        report.beams += 1;
        report.rays += rays.len() as u64;
        visit(key, &rays);
        if (keep && rays.len() * RAY_RECORD_BYTES <= self.cache.budget() / 8) || unwritten > 0 {
            self.cache.remove(&key);
            self.cache.insert_loaded(key, rays);
            self.cache.update(key, |e| e.unwritten = unwritten);
            if self.cache.over_budget() {
                // Writing here could move runs this read is still using.
                self.evict_clean();
            }
        }
        Ok(())
    }

    /// Summary counts for reports.
    pub fn summary(&self) -> FileSummary {
        let sections = self
            .store
            .dirs
            .iter()
            .map(|d| {
                let filled = d.iter().filter(|e| e.count > 0).count() as u32;
                (d.len() as u32, filled, d.iter().map(|e| u64::from(e.count)).sum())
            })
            .collect::<Vec<_>>();
        let rays: u64 = sections.iter().map(|s: &(u32, u32, u64)| s.2).sum();
        FileSummary {
            sections,
            file_bytes: self.store.file_len(),
            ray_bytes: rays * RAY_RECORD_BYTES as u64,
            metadata_bytes: self.store.metadata_bytes(),
            free_bytes: self.store.extents.free_bytes() + self.store.reserved_bytes(),
            fragments: self.store.extents.fragments(),
            generation: self.store.info.generation,
        }
    }

    /// The directory entry of every beam (section, beam, entry), for tools that walk the file.
    pub fn directory(&self, section: u32) -> Option<&[BeamEntry]> {
        self.store.dirs.get(section as usize).map(|d| d.as_slice())
    }

    /// Asks the OS to forget its cached pages of this file (for cold-read measurements).
    pub fn drop_os_cache(&self) {
        super::io::drop_page_cache(&self.store.file);
    }

    /// Reads runs straight from disk in file order, bypassing the cache; used by
    /// maintenance tools on closed files. `visit` gets `Err(key)` for a bad checksum.
    pub fn scan_disk(
        &mut self,
        keys: &mut [BeamKey],
        mut visit: impl FnMut(std::result::Result<(BeamKey, &[RayRecord]), BeamKey>) -> Result<()>,
    ) -> Result<()> {
        keys.sort_by_key(|k| self.entry(*k).offset);
        let groups = self.read_groups(keys);
        let mut buf = Vec::new();
        let mut announced = 0;
        let mut start = 0;
        for (k, &(end, first, group_end)) in groups.iter().enumerate() {
            announced = self.announce(&groups, k, announced);
            self.store.read_into(first, (group_end - first) as usize, &mut buf)?;
            for &key in &keys[start..end] {
                let e = self.entry(key);
                let bytes = &buf[(e.offset - first) as usize..][..e.extent().len as usize];
                if crc32c::crc32c(bytes) == e.crc {
                    visit(Ok((key, RayRecord::slice_from_bytes(bytes).unwrap_or(&[]))))?;
                } else {
                    visit(Err(key))?;
                }
            }
            start = end;
        }
        Ok(())
    }
}

impl Drop for HoloFile {
    fn drop(&mut self) {
        if self.store.writable {
            if let Err(e) = self.flush() {
                tracing::error!("flushing {} on close failed: {e}", self.store.path.display());
            }
        }
    }
}
