//! The DISKSPACE bound: an upper bound, kept up to date in O(1) per append,
//! on how long the file can become before and at the next commit if every
//! ray appended so far is written and committed.
//!
//! The bound is `base + writes + metadata`:
//!
//! * `base` is the end of the file, or of the space allocated in it if that is
//!   further, when the bound was last exact (at open, and after every flush).
//! * `writes` adds, for every stretch of appends to a beam between two of its
//!   writes, the most that the one write ending it can move the end of the
//!   allocated space ([`Store::write_growth_bound`](super::store::Store)).
//!   A written beam's amount stays counted until the next flush, so evictions
//!   never make the bound smaller than what they took.
//! * `metadata` adds, for every section touched since the last flush, the
//!   longest directory block its commit can write, and once the root. There is
//!   no alignment padding in the format.
//!
//! Freed space is never subtracted, so the bound only falls at a flush, where
//! it becomes exact again.

use super::format;

/// What one append would add to the bound.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Charge {
    section: usize,
    /// The beam held no rays before this append.
    newly_filled: bool,
    /// Extra worst-case growth of the beam's next write.
    write: u64,
}

impl Charge {
    /// A charge for an append to a beam of `section`.
    pub fn new(section: usize, newly_filled: bool, write: u64) -> Charge {
        Charge {
            section,
            newly_filled,
            write,
        }
    }
}

/// The running bound for a file with a size limit.
#[derive(Clone, Debug)]
pub(crate) struct SpaceBound {
    limit: u64,
    base: u64,
    writes: u64,
    metadata: u64,
    /// Sections touched since the last flush: their directories will be rewritten.
    touched: Vec<bool>,
    /// Beams per section that hold rays, on disk or cached.
    filled: Vec<u64>,
    beams: Vec<u32>,
    root: u64,
}

impl SpaceBound {
    /// A bound for a file limited to `limit` bytes, whose sections have `beams`
    /// beams of which `filled` hold rays, and whose sections in `touched` have
    /// changes not yet committed; `base` and `writes` as in the module docs.
    pub fn new(
        limit: u64,
        base: u64,
        writes: u64,
        beams: Vec<u32>,
        filled: Vec<u64>,
        touched: Vec<bool>,
    ) -> SpaceBound {
        let mut b = SpaceBound {
            limit,
            base,
            writes,
            metadata: 0,
            touched: vec![false; beams.len()],
            filled,
            root: format::root_len(beams.len()),
            beams,
        };
        for (s, t) in touched.into_iter().enumerate() {
            if t {
                b.metadata += b.metadata_added(s, false);
                b.touched[s] = true;
            }
        }
        b
    }

    /// The limit in bytes.
    pub fn limit(&self) -> u64 {
        self.limit
    }

    /// The current bound on the file length.
    pub fn bound(&self) -> u64 {
        self.base.saturating_add(self.writes).saturating_add(self.metadata)
    }

    /// True when something since the last flush is counted, so that a flush
    /// could lower the bound.
    pub fn has_pending(&self) -> bool {
        self.writes > 0 || self.metadata > 0
    }

    /// Most bytes of directory for one filled beam.
    fn per_filled(&self) -> u64 {
        format::directory_len_bound(1, 1, self.limit) - format::directory_len_bound(1, 0, self.limit)
    }

    /// What touching section `s` (and filling one more of its beams, if
    /// `newly_filled`) adds to `metadata`.
    fn metadata_added(&self, s: usize, newly_filled: bool) -> u64 {
        if self.touched[s] {
            return if newly_filled { self.per_filled() } else { 0 };
        }
        // Some section is touched exactly when metadata is counted: the root is in.
        let root = if self.metadata > 0 { 0 } else { self.root };
        let filled = self.filled[s] + u64::from(newly_filled);
        root + format::directory_len_bound(self.beams[s], filled, self.limit)
    }

    /// The bound if `c` were charged.
    pub fn with(&self, c: Charge) -> u64 {
        self.bound()
            .saturating_add(c.write)
            .saturating_add(self.metadata_added(c.section, c.newly_filled))
    }

    /// Charges an append.
    pub fn charge(&mut self, c: Charge) {
        self.metadata += self.metadata_added(c.section, c.newly_filled);
        self.writes = self.writes.saturating_add(c.write);
        self.touched[c.section] = true;
        if c.newly_filled {
            self.filled[c.section] += 1;
        }
    }

    /// Everything is written and committed: the bound is exact again at `base`.
    pub fn flushed(&mut self, base: u64) {
        self.base = base;
        self.writes = 0;
        self.metadata = 0;
        self.touched.iter_mut().for_each(|t| *t = false);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn charges_count_each_directory_and_the_root_once() {
        let limit = 300 << 10;
        let mut b = SpaceBound::new(limit, 1000, 0, vec![100, 10], vec![0, 0], vec![false, false]);
        assert_eq!(b.bound(), 1000);
        assert!(!b.has_pending());
        let first = Charge::new(0, true, 50);
        let dir0 = format::directory_len_bound(100, 1, limit);
        assert_eq!(b.with(first), 1000 + 50 + dir0 + format::root_len(2));
        b.charge(first);
        assert_eq!(b.bound(), 1000 + 50 + dir0 + format::root_len(2));
        // Another beam of the same section: its directory entry only.
        let per = format::directory_len_bound(100, 2, limit) - dir0;
        assert_eq!(b.with(Charge::new(0, true, 0)), b.bound() + per);
        // The other section: its whole directory, no second root.
        let dir1 = format::directory_len_bound(10, 0, limit);
        assert_eq!(b.with(Charge::new(1, false, 7)), b.bound() + 7 + dir1);
        b.flushed(2000);
        assert_eq!(b.bound(), 2000);
        assert!(!b.has_pending());
        // Filled beams are remembered across flushes.
        assert_eq!(
            b.with(Charge::new(0, false, 0)),
            2000 + format::directory_len_bound(100, 1, limit) + format::root_len(2)
        );
    }
}
