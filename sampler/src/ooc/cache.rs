//! The memory manager over a scene file (Áfra 2012, section 5): the
//! compressed bytes are memory-mapped; decompressed blocks live in a cache of
//! fixed byte budget. Lookups on the tracing path are one atomic load (and a
//! timestamp store when it changed); blocks are freed through epoch-based
//! reclamation, so a block a ray is walking through stays valid until that ray
//! is done even if it is evicted meanwhile. Fetcher threads load requested
//! blocks, most requested (then coarsest) first; eviction is least recently
//! used and spares blocks touched since the oldest batch still in flight.

use std::cmp::Reverse;
use std::collections::{BTreeMap, BinaryHeap, HashMap, HashSet, VecDeque};
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, Condvar, Mutex, MutexGuard};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use crossbeam_epoch::{self as epoch, Atomic, Guard, Owned, Shared};
use memmap2::Mmap;

use super::block::Block;
use super::codec::Codec;
use super::format::IndexEntry;
use super::OocError;

/// Longest list of pending requests kept; older, rarer ones are dropped.
const MAX_PENDING: usize = 1 << 16;

/// Counters of the cache, for reports and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct CacheStats {
    /// Decompressed bytes resident now.
    pub resident_bytes: usize,
    /// Blocks resident now.
    pub resident_blocks: usize,
    /// Blocks loaded so far (by fetchers or on demand).
    pub loads: u64,
    /// Blocks evicted so far.
    pub evictions: u64,
    /// Compressed bytes read so far.
    pub read_bytes: u64,
    /// Decompressed bytes of the blocks read so far.
    pub loaded_bytes: u64,
    /// Blocks that failed their checks.
    pub errors: u64,
}

struct Queue {
    /// Block -> requests since it was last asked for.
    pending: HashMap<u32, u32>,
    loading: HashSet<u32>,
    /// Blocks a fetcher loaded but found no room for (everything resident was in use).
    declined: HashSet<u32>,
    /// (timestamp when pushed, !block): lazily refreshed LRU order, finer
    /// blocks first among blocks last used at the same time (every ray of a
    /// batch passes through the coarse ones).
    lru: BinaryHeap<Reverse<(u32, u32)>>,
    /// Batch id -> clock when it began.
    in_flight: BTreeMap<u64, u32>,
    next_batch: u64,
    /// The first error met, reported to whoever asks.
    error: Option<OocError>,
    /// Blocks a batch that loads on the spot will want next, in order: the
    /// fetchers decode them ahead into `staged`, outside the cache.
    ahead: VecDeque<u32>,
    /// Decoded ahead and waiting for `load_now`.
    staged: HashMap<u32, Block>,
    /// Bytes in `staged`.
    staged_bytes: usize,
}

/// The shared state of the cache.
pub struct Cache {
    mmap: Mmap,
    index: Vec<IndexEntry>,
    codec: Codec,
    materials: u32,
    budget: usize,
    slots: Box<[Atomic<Block>]>,
    sizes: Box<[AtomicUsize]>,
    stamps: Box<[AtomicU32]>,
    clock: AtomicU32,
    resident: AtomicUsize,
    resident_blocks: AtomicUsize,
    loads: AtomicU64,
    evictions: AtomicU64,
    read_bytes: AtomicU64,
    loaded_bytes: AtomicU64,
    errors: AtomicU64,
    queue: Mutex<Queue>,
    wake_fetchers: Condvar,
    loaded: Condvar,
    shutdown: AtomicBool,
}

impl Cache {
    /// A cache over the mapped file with the given index and byte budget.
    pub fn new(mmap: Mmap, index: Vec<IndexEntry>, codec: Codec, materials: u32, budget: usize) -> Cache {
        let n = index.len();
        Cache {
            mmap,
            codec,
            materials,
            budget,
            slots: (0..n).map(|_| Atomic::null()).collect(),
            sizes: (0..n).map(|_| AtomicUsize::new(0)).collect(),
            stamps: (0..n).map(|_| AtomicU32::new(0)).collect(),
            index,
            clock: AtomicU32::new(1),
            resident: AtomicUsize::new(0),
            resident_blocks: AtomicUsize::new(0),
            loads: AtomicU64::new(0),
            evictions: AtomicU64::new(0),
            read_bytes: AtomicU64::new(0),
            loaded_bytes: AtomicU64::new(0),
            errors: AtomicU64::new(0),
            queue: Mutex::new(Queue {
                pending: HashMap::new(),
                loading: HashSet::new(),
                declined: HashSet::new(),
                lru: BinaryHeap::new(),
                in_flight: BTreeMap::new(),
                next_batch: 0,
                error: None,
                ahead: VecDeque::new(),
                staged: HashMap::new(),
                staged_bytes: 0,
            }),
            wake_fetchers: Condvar::new(),
            loaded: Condvar::new(),
            shutdown: AtomicBool::new(false),
        }
    }

    fn lock(&self) -> MutexGuard<'_, Queue> {
        self.queue.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Blocks in the file.
    pub fn blocks(&self) -> usize {
        self.index.len()
    }
    /// The byte budget.
    pub fn budget(&self) -> usize {
        self.budget
    }
    /// The index entry of a block.
    pub fn entry(&self, id: u32) -> Option<&IndexEntry> {
        self.index.get(id as usize)
    }

    /// The block if it is resident: lock-free, marks it used now.
    #[inline]
    pub fn get<'g>(&self, id: u32, guard: &'g Guard) -> Option<&'g Block> {
        let slot = self.slots.get(id as usize)?;
        let p = slot.load(Ordering::Acquire, guard);
        // SAFETY: blocks are only freed through `defer_destroy` after being
        // unlinked, so a pointer loaded under a pinned guard stays valid for 'g.
        let block = unsafe { p.as_ref() }?;
        let now = self.clock.load(Ordering::Relaxed);
        let stamp = &self.stamps[id as usize];
        if stamp.load(Ordering::Relaxed) != now {
            stamp.store(now, Ordering::Relaxed);
        }
        Some(block)
    }

    /// True if the block is resident.
    pub fn is_resident(&self, id: u32) -> bool {
        let guard = epoch::pin();
        self.slots
            .get(id as usize)
            .is_some_and(|s| !s.load(Ordering::Acquire, &guard).is_null())
    }

    /// The stored (compressed) bytes of block `id` and its index entry,
    /// their checksum verified.
    fn checked_packed(&self, id: u32) -> Result<(&[u8], IndexEntry), OocError> {
        let e = *self.entry(id).ok_or(OocError::Block {
            block: id,
            message: "no such block".into(),
        })?;
        let start = e.offset as usize;
        let packed = self.mmap.get(start..start + e.packed as usize).ok_or(OocError::Block {
            block: id,
            message: "lies past the end of the file".into(),
        })?;
        self.read_bytes.fetch_add(u64::from(e.packed), Ordering::Relaxed);
        self.loaded_bytes.fetch_add(u64::from(e.len), Ordering::Relaxed);
        if crc32c::crc32c(packed) != e.crc {
            return Err(OocError::Checksum(format!("block {id}")));
        }
        Ok((packed, e))
    }

    /// Reads and checks a block that holds no treelet (textures, their
    /// coordinates): its decompressed bytes.
    pub fn read_raw(&self, id: u32) -> Result<Vec<u8>, OocError> {
        let (packed, e) = self.checked_packed(id)?;
        self.codec
            .decompress(packed, e.len as usize)
            .map_err(|c| OocError::Block {
                block: id,
                message: c.to_string(),
            })
    }

    /// Reads, checks and decodes a block from the file (no caching).
    pub fn read(&self, id: u32) -> Result<Block, OocError> {
        let (packed, e) = self.checked_packed(id)?;
        let bad = |message: String| OocError::Block { block: id, message };
        thread_local! {
            /// Each thread's decompression buffer, reused from block to block.
            static RAW: std::cell::RefCell<Vec<u8>> = const { std::cell::RefCell::new(Vec::new()) };
        }
        let mut block = RAW.with_borrow_mut(|buf| {
            let raw = self
                .codec
                .decompress_into(packed, e.len as usize, buf)
                .map_err(|c| bad(c.to_string()))?;
            Block::decode(raw, self.index.len() as u32, self.materials).map_err(|b| bad(b.to_string()))
        })?;
        block.resolve_local_links(id);
        Ok(block)
    }

    /// Makes a block resident now (on demand): the exact path, used when a
    /// ray must not wait. Evicts as needed, sparing nothing if it must.
    pub fn load_now<'g>(&self, id: u32, guard: &'g Guard) -> Result<&'g Block, OocError> {
        if let Some(b) = self.get(id, guard) {
            return Ok(b);
        }
        let block = match self.take_staged(id) {
            Some(b) => b,
            None => self.read(id).inspect_err(|e| self.note_error(e))?,
        };
        // A tick per load on the spot: when a batch's blocks do not all fit, the
        // ones its rays used least recently go first, not those that every ray
        // passes through but that share the batch's stamp.
        self.clock.fetch_add(1, Ordering::Relaxed);
        let p = self.insert(id, block, true, guard);
        // SAFETY: as in `get`: the pointer was loaded or stored under `guard`,
        // and is freed only after every guard pinned before its eviction is gone.
        unsafe { p.as_ref() }.ok_or(OocError::Block {
            block: id,
            message: "could not be cached".into(),
        })
    }

    /// Asks the fetchers to decode `ids` ahead, in this order, for a batch
    /// about to load them on the spot (replacing what was asked before). At
    /// most an eighth of the budget waits decoded outside the cache.
    pub fn decode_ahead(&self, ids: &[u32]) {
        let mut q = self.lock();
        q.ahead.clear();
        q.ahead
            .extend(ids.iter().copied().filter(|&id| (id as usize) < self.index.len()));
        drop(q);
        self.wake_fetchers.notify_all();
    }

    /// Waits until the fetchers have decoded all that was asked for ahead,
    /// or `timeout` passed; true if they have.
    #[cfg(test)]
    pub(crate) fn wait_decoded_ahead(&self, timeout: Duration) -> bool {
        let until = Instant::now() + timeout;
        let mut q = self.lock();
        while !(q.ahead.is_empty() && q.loading.is_empty()) {
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            q = self.loaded.wait_timeout(q, left).unwrap_or_else(|p| p.into_inner()).0;
        }
        true
    }

    /// The block if a fetcher decoded it ahead, waiting for one that is
    /// decoding it now.
    fn take_staged(&self, id: u32) -> Option<Block> {
        let mut q = self.lock();
        loop {
            if let Some(b) = q.staged.remove(&id) {
                q.staged_bytes -= b.memory();
                drop(q);
                // Room for the next one.
                self.wake_fetchers.notify_all();
                return Some(b);
            }
            if !q.loading.contains(&id) || self.shutdown.load(Ordering::Relaxed) {
                return None;
            }
            q = self
                .loaded
                .wait_timeout(q, Duration::from_millis(50))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    fn note_error(&self, e: &OocError) {
        self.errors.fetch_add(1, Ordering::Relaxed);
        let mut q = self.lock();
        if q.error.is_none() {
            tracing::error!("{e}");
            q.error = Some(e.clone());
        }
    }

    /// The first error met while loading blocks, if any.
    pub fn error(&self) -> Option<OocError> {
        self.lock().error.clone()
    }

    /// Puts a decoded block in its slot, evicting least recently used blocks
    /// to stay within budget. Without `force`, blocks used since the oldest
    /// batch in flight are spared and the block is dropped if no room is left.
    /// Returns the resident block (null if dropped).
    fn insert<'g>(&self, id: u32, block: Block, force: bool, guard: &'g Guard) -> Shared<'g, Block> {
        let size = block.memory();
        let mut q = self.lock();
        let present = self.slots[id as usize].load(Ordering::Acquire, guard);
        if !present.is_null() {
            return present;
        }
        let protect_from = q.in_flight.values().min().copied().unwrap_or(u32::MAX);
        while self.resident.load(Ordering::Relaxed) + size > self.budget {
            let Some(Reverse((stamp, rank))) = q.lru.pop() else {
                break;
            };
            let victim = !rank;
            let slot = &self.slots[victim as usize];
            if slot.load(Ordering::Acquire, guard).is_null() {
                continue;
            }
            let now = self.stamps[victim as usize].load(Ordering::Relaxed);
            if now != stamp {
                q.lru.push(Reverse((now, rank)));
                continue;
            }
            if !force && now >= protect_from {
                q.lru.push(Reverse((now, rank)));
                break;
            }
            let old = slot.swap(Shared::null(), Ordering::AcqRel, guard);
            if !old.is_null() {
                // SAFETY: unlinked above; readers pinned before the swap keep it alive.
                unsafe { guard.defer_destroy(old) };
                self.resident
                    .fetch_sub(self.sizes[victim as usize].load(Ordering::Relaxed), Ordering::Relaxed);
                self.resident_blocks.fetch_sub(1, Ordering::Relaxed);
                self.evictions.fetch_add(1, Ordering::Relaxed);
            }
        }
        // A block bigger than the whole budget still goes in when forced.
        if !force && self.resident.load(Ordering::Relaxed) + size > self.budget {
            return Shared::null();
        }
        let now = self.clock.load(Ordering::Relaxed);
        self.stamps[id as usize].store(now, Ordering::Relaxed);
        self.sizes[id as usize].store(size, Ordering::Relaxed);
        let p = Owned::new(block).into_shared(guard);
        self.slots[id as usize].store(p, Ordering::Release);
        self.resident.fetch_add(size, Ordering::Relaxed);
        self.resident_blocks.fetch_add(1, Ordering::Relaxed);
        self.loads.fetch_add(1, Ordering::Relaxed);
        q.lru.push(Reverse((now, !id)));
        q.pending.remove(&id);
        p
    }

    /// Asks the fetchers for blocks (each id once per ray that missed it).
    pub fn request(&self, ids: &[u32]) {
        if ids.is_empty() {
            return;
        }
        let mut q = self.lock();
        for &id in ids {
            if (id as usize) < self.index.len() && !q.loading.contains(&id) {
                q.declined.remove(&id);
                *q.pending.entry(id).or_insert(0) += 1;
            }
        }
        if q.pending.len() > MAX_PENDING {
            let mut v: Vec<(u32, u32)> = q.pending.drain().collect();
            v.sort_unstable_by_key(|&(id, n)| (Reverse(n), id));
            v.truncate(MAX_PENDING / 2);
            q.pending.extend(v);
        }
        drop(q);
        self.wake_fetchers.notify_all();
    }

    /// Starts a batch of rays: blocks used from now on are spared by
    /// eviction until the batch ends.
    pub fn begin_batch(&self) -> u64 {
        let now = self.clock.fetch_add(1, Ordering::Relaxed) + 1;
        let mut q = self.lock();
        let id = q.next_batch;
        q.next_batch += 1;
        q.in_flight.insert(id, now);
        id
    }

    /// Ends a batch started with [`Cache::begin_batch`].
    pub fn end_batch(&self, batch: u64) {
        let mut q = self.lock();
        q.in_flight.remove(&batch);
        if q.in_flight.is_empty() {
            // Nothing will ask for what was decoded ahead.
            q.ahead.clear();
            q.staged.clear();
            q.staged_bytes = 0;
        }
    }

    /// Waits until every block of `ids` is resident, a load failed, one could
    /// not be cached for lack of room, or `timeout` passed; true if all are resident.
    pub fn wait_resident(&self, ids: &[u32], timeout: Duration) -> bool {
        let until = Instant::now() + timeout;
        let mut q = self.lock();
        loop {
            if ids.iter().all(|&id| self.is_resident(id)) {
                return true;
            }
            if q.error.is_some() || ids.iter().any(|id| q.declined.contains(id)) {
                return false;
            }
            let left = until.saturating_duration_since(Instant::now());
            if left.is_zero() {
                return false;
            }
            q = self
                .loaded
                .wait_timeout(q, left.min(Duration::from_millis(50)))
                .unwrap_or_else(|p| p.into_inner())
                .0;
        }
    }

    /// One fetcher: loads the most requested pending block, coarsest first
    /// among equals, until shut down.
    fn fetch_loop(&self) {
        loop {
            let id = {
                let mut q = self.lock();
                loop {
                    if self.shutdown.load(Ordering::Relaxed) {
                        return;
                    }
                    let best = q
                        .pending
                        .iter()
                        .max_by_key(|&(&id, &n)| (n, Reverse(self.index[id as usize].level), Reverse(id)))
                        .map(|(&id, _)| id);
                    if let Some(id) = best {
                        q.pending.remove(&id);
                        if self.is_resident(id) {
                            continue;
                        }
                        q.loading.insert(id);
                        break (id, false);
                    }
                    if q.staged_bytes < (self.budget / 8).max(1) {
                        if let Some(id) = q.ahead.pop_front() {
                            if self.is_resident(id) || q.staged.contains_key(&id) || q.loading.contains(&id) {
                                continue;
                            }
                            q.loading.insert(id);
                            break (id, true);
                        }
                    }
                    q = self.wake_fetchers.wait(q).unwrap_or_else(|p| p.into_inner());
                }
            };
            let (id, ahead) = id;
            match self.read(id) {
                Ok(block) if ahead => {
                    let mut q = self.lock();
                    q.staged_bytes += block.memory();
                    q.staged.insert(id, block);
                }
                Ok(block) => {
                    let guard = epoch::pin();
                    if self.insert(id, block, false, &guard).is_null() {
                        self.lock().declined.insert(id);
                    }
                }
                Err(e) => self.note_error(&e),
            }
            self.lock().loading.remove(&id);
            self.loaded.notify_all();
        }
    }

    /// Counters now.
    pub fn stats(&self) -> CacheStats {
        CacheStats {
            resident_bytes: self.resident.load(Ordering::Relaxed),
            resident_blocks: self.resident_blocks.load(Ordering::Relaxed),
            loads: self.loads.load(Ordering::Relaxed),
            evictions: self.evictions.load(Ordering::Relaxed),
            read_bytes: self.read_bytes.load(Ordering::Relaxed),
            loaded_bytes: self.loaded_bytes.load(Ordering::Relaxed),
            errors: self.errors.load(Ordering::Relaxed),
        }
    }

    /// Drops every resident block (a cold start for measurements).
    pub fn clear(&self) {
        let guard = epoch::pin();
        let mut q = self.lock();
        for (i, slot) in self.slots.iter().enumerate() {
            let old = slot.swap(Shared::null(), Ordering::AcqRel, &guard);
            if !old.is_null() {
                // SAFETY: unlinked above; pinned readers keep it alive.
                unsafe { guard.defer_destroy(old) };
                self.resident
                    .fetch_sub(self.sizes[i].load(Ordering::Relaxed), Ordering::Relaxed);
                self.resident_blocks.fetch_sub(1, Ordering::Relaxed);
            }
        }
        q.lru.clear();
        q.pending.clear();
    }
}

impl Drop for Cache {
    fn drop(&mut self) {
        // SAFETY: no reader can exist once the cache is dropped (`&mut self`).
        let guard = unsafe { epoch::unprotected() };
        for slot in self.slots.iter() {
            let p = slot.swap(Shared::null(), Ordering::AcqRel, guard);
            if !p.is_null() {
                // SAFETY: exclusive access; the block is no longer reachable.
                drop(unsafe { p.into_owned() });
            }
        }
    }
}

/// The cache and its fetcher threads; stops them when dropped.
pub struct Fetchers {
    cache: Arc<Cache>,
    threads: Vec<JoinHandle<()>>,
}

impl Fetchers {
    /// Starts `n` fetcher threads for the cache.
    pub fn start(cache: Arc<Cache>, n: usize) -> Fetchers {
        let threads = (0..n)
            .filter_map(|i| {
                let c = Arc::clone(&cache);
                std::thread::Builder::new()
                    .name(format!("scene-fetch-{i}"))
                    .spawn(move || c.fetch_loop())
                    .ok()
            })
            .collect();
        Fetchers { cache, threads }
    }
    /// The cache they fill.
    pub fn cache(&self) -> &Arc<Cache> {
        &self.cache
    }
}

impl Drop for Fetchers {
    fn drop(&mut self) {
        self.cache.shutdown.store(true, Ordering::Relaxed);
        {
            let _q = self.cache.lock();
            self.cache.wake_fetchers.notify_all();
        }
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}
