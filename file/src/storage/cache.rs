//! The in-memory beam cache: recently used beams, bounded by a byte budget and
//! evicted in least-recently-used order.
//!
//! An entry holds either the whole beam (`loaded`) or only the rays appended
//! since the beam was last written (`unwritten` counts those, at the end of
//! `rays`). The cache never touches the file: the engine decides what to write.

use holodeck_protocol::{BeamKey, RayRecord, RAY_RECORD_BYTES};
use lru::LruCache;

/// Bytes charged per entry beyond its rays: map node, LRU links and the Vec header.
pub const ENTRY_OVERHEAD: usize = 96;

/// One cached beam.
#[derive(Debug, Default)]
pub struct CachedBeam {
    /// The beam's rays (all of them if `loaded`, else only the unwritten tail).
    pub rays: Vec<RayRecord>,
    /// Whether `rays` starts with everything already on disk.
    pub loaded: bool,
    /// How many rays at the end of `rays` are not on disk yet.
    pub unwritten: usize,
}

impl CachedBeam {
    /// Memory charged for this entry.
    pub fn bytes(&self) -> usize {
        self.rays.capacity() * RAY_RECORD_BYTES + ENTRY_OVERHEAD
    }
    /// The rays not yet on disk.
    pub fn tail(&self) -> &[RayRecord] {
        &self.rays[self.rays.len() - self.unwritten..]
    }
}

/// LRU map of cached beams with byte accounting.
pub struct BeamCache {
    map: LruCache<BeamKey, CachedBeam>,
    bytes: usize,
    budget: usize,
}

impl BeamCache {
    /// An empty cache that aims to hold at most `budget` bytes.
    pub fn new(budget: usize) -> BeamCache {
        BeamCache {
            map: LruCache::unbounded(),
            bytes: 0,
            budget,
        }
    }
    /// Bytes currently charged.
    pub fn bytes(&self) -> usize {
        self.bytes
    }
    /// The budget.
    pub fn budget(&self) -> usize {
        self.budget
    }
    /// Number of cached beams.
    pub fn len(&self) -> usize {
        self.map.len()
    }
    /// True when nothing is cached.
    pub fn is_empty(&self) -> bool {
        self.map.is_empty()
    }
    /// True when over budget.
    pub fn over_budget(&self) -> bool {
        self.bytes > self.budget
    }

    /// Looks at an entry without changing its recency.
    pub fn peek(&self, key: &BeamKey) -> Option<&CachedBeam> {
        self.map.peek(key)
    }

    /// Marks an entry most recently used and returns it.
    pub fn touch(&mut self, key: &BeamKey) -> Option<&CachedBeam> {
        self.map.get(key)
    }

    /// Changes an entry (created empty if absent) through `f`, keeping the byte count right.
    /// One hash lookup for an entry that exists, two for a new one.
    pub fn update<R>(&mut self, key: BeamKey, f: impl FnOnce(&mut CachedBeam) -> R) -> R {
        if let Some(entry) = self.map.get_mut(&key) {
            let before = entry.bytes();
            let r = f(entry);
            self.bytes = self.bytes + entry.bytes() - before;
            return r;
        }
        let mut entry = CachedBeam::default();
        let r = f(&mut entry);
        self.bytes += entry.bytes();
        self.map.push(key, entry);
        r
    }

    /// Inserts a whole beam read from disk (replacing any entry).
    pub fn insert_loaded(&mut self, key: BeamKey, rays: Vec<RayRecord>) {
        let entry = CachedBeam {
            rays,
            loaded: true,
            unwritten: 0,
        };
        self.bytes += entry.bytes();
        if let Some((_, old)) = self.map.push(key, entry) {
            self.bytes -= old.bytes();
        }
    }

    /// Removes an entry.
    pub fn remove(&mut self, key: &BeamKey) -> Option<CachedBeam> {
        let e = self.map.pop(key)?;
        self.bytes -= e.bytes();
        Some(e)
    }

    /// Removes and returns the least recently used entry.
    pub fn pop_lru(&mut self) -> Option<(BeamKey, CachedBeam)> {
        let (k, e) = self.map.pop_lru()?;
        self.bytes -= e.bytes();
        Some((k, e))
    }

    /// Keys from the least recently used end whose entries add up to at least
    /// `bytes`; with `clean_only`, entries with unwritten rays are skipped.
    pub fn lru_keys(&self, bytes: usize, clean_only: bool) -> Vec<BeamKey> {
        let mut keys = Vec::new();
        let mut freed = 0;
        for (k, e) in self.map.iter().rev() {
            if freed >= bytes {
                break;
            }
            if clean_only && e.unwritten > 0 {
                continue;
            }
            freed += e.bytes();
            keys.push(*k);
        }
        keys
    }

    /// Number of entries with unwritten rays.
    pub fn dirty_count(&self) -> usize {
        self.map.iter().filter(|(_, e)| e.unwritten > 0).count()
    }

    /// Keys of entries with unwritten rays.
    pub fn dirty_keys(&self) -> Vec<BeamKey> {
        self.map
            .iter()
            .filter(|(_, e)| e.unwritten > 0)
            .map(|(k, _)| *k)
            .collect()
    }

    /// Marks an entry's tail as written (the rays stay cached only if the entry is loaded).
    pub fn mark_written(&mut self, key: &BeamKey) {
        let Some(e) = self.map.peek_mut(key) else {
            return;
        };
        let before = e.bytes();
        if e.loaded {
            e.unwritten = 0;
        } else {
            // A tail alone is no use for reading; drop it.
            e.rays = Vec::new();
            e.unwritten = 0;
        }
        let after = e.bytes();
        self.bytes = self.bytes - before + after;
        if !e.loaded {
            self.remove(key);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn evicts_in_lru_order_and_accounts_bytes() {
        let mut c = BeamCache::new(10_000);
        for b in 0..3 {
            c.insert_loaded(BeamKey::new(0, b), vec![RayRecord::default(); 100]);
        }
        assert_eq!(c.bytes(), 3 * (1000 + ENTRY_OVERHEAD));
        c.touch(&BeamKey::new(0, 0));
        assert_eq!(c.pop_lru().unwrap().0, BeamKey::new(0, 1));
        c.update(BeamKey::new(0, 7), |e| {
            e.rays.reserve_exact(50);
            e.rays.extend(std::iter::repeat_n(RayRecord::default(), 50));
            e.unwritten = 50;
        });
        assert_eq!(c.dirty_keys(), vec![BeamKey::new(0, 7)]);
        c.mark_written(&BeamKey::new(0, 7));
        assert!(c.peek(&BeamKey::new(0, 7)).is_none(), "a written tail is dropped");
        assert_eq!(c.bytes(), 2 * (1000 + ENTRY_OVERHEAD));
        while c.pop_lru().is_some() {}
        assert_eq!(c.bytes(), 0);
    }
}
