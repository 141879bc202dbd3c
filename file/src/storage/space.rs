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
//!   allocated space ([`Disk::write_growth_bound`](super::disk::Disk)).
//!   A written beam's amount stays counted until the next flush, so evictions
//!   never make the bound smaller than what they took.
//! * `metadata` adds, for every directory chunk touched since the last flush,
//!   the longest directory block its commit can write, and once the root; each
//!   twice, since every block and root is stored in two copies; and once
//!   [`format::COPY_GAP`], the free stretch the commit may open at the end to
//!   keep second copies that far from the first. There is no other padding
//!   in the data area.
//!
//! Freed space is never subtracted, so the bound only falls at a flush, where
//! it becomes exact again.

use super::format::{self, COPIES};

/// What one append would add to the bound.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Charge {
    chunk: usize,
    /// The beam held no rays before this append.
    newly_filled: bool,
    /// Extra worst-case growth of the beam's next write.
    write: u64,
}

impl Charge {
    /// A charge for an append to a beam of directory chunk `chunk`.
    pub fn new(chunk: usize, newly_filled: bool, write: u64) -> Charge {
        Charge {
            chunk,
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
    /// Chunks touched since the last flush: their directories will be rewritten.
    touched: Vec<bool>,
    /// Beams per chunk that hold rays, on disk or cached.
    filled: Vec<u64>,
    beams: Vec<u32>,
    root: u64,
}

impl SpaceBound {
    /// A bound for a file limited to `limit` bytes, whose directory chunks
    /// have `beams` beams of which `filled` hold rays, and whose chunks in
    /// `touched` have changes not yet committed; `base` and `writes` as in the
    /// module docs.
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
            root: COPIES as u64 * format::root_len(beams.len()) + format::COPY_GAP,
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

    /// Most bytes of directory (both copies) for one filled beam.
    fn per_filled(&self) -> u64 {
        COPIES as u64 * (format::directory_len_bound(1, 1, self.limit) - format::directory_len_bound(1, 0, self.limit))
    }

    /// What touching chunk `s` (and filling one more of its beams, if
    /// `newly_filled`) adds to `metadata`.
    fn metadata_added(&self, s: usize, newly_filled: bool) -> u64 {
        if self.touched[s] {
            return if newly_filled { self.per_filled() } else { 0 };
        }
        // Some section is touched exactly when metadata is counted: the root is in.
        let root = if self.metadata > 0 { 0 } else { self.root };
        let filled = self.filled[s] + u64::from(newly_filled);
        root + COPIES as u64 * format::directory_len_bound(self.beams[s], filled, self.limit)
    }

    /// The bound if `c` were charged.
    pub fn with(&self, c: Charge) -> u64 {
        self.bound()
            .saturating_add(c.write)
            .saturating_add(self.metadata_added(c.chunk, c.newly_filled))
    }

    /// Charges an append.
    pub fn charge(&mut self, c: Charge) {
        self.metadata += self.metadata_added(c.chunk, c.newly_filled);
        self.writes = self.writes.saturating_add(c.write);
        self.touched[c.chunk] = true;
        if c.newly_filled {
            self.filled[c.chunk] += 1;
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
    fn charges_count_each_directory_and_the_root_once_per_copy_and_the_gap_once() {
        let limit = 300 << 10;
        // The expectations come from the format's own sizes: a directory
        // block of 100 beams with one filled is 20 bytes of framing, one byte
        // per empty beam and at most 2 + 3 + 4 more for the filled one (the
        // rest of a 3-byte count of at most 30,720 rays, a 3-byte offset delta
        // below 2^21 and a CRC); a root of two chunks is 20 + 2 * 44 + 4 bytes.
        let per = 2 + 3 + 4;
        let dir0 = 20 + 100 + per;
        let root = 20 + 2 * 44 + 4;
        assert_eq!(format::directory_len_bound(100, 1, limit), dir0);
        assert_eq!(format::root_len(2), root);
        let mut b = SpaceBound::new(limit, 1000, 0, vec![100, 10], vec![0, 0], vec![false, false]);
        assert_eq!(b.bound(), 1000);
        assert!(!b.has_pending());
        // With the root comes, once, the gap kept between first and second copies.
        let gap = format::COPY_GAP;
        let first = Charge::new(0, true, 50);
        assert_eq!(b.with(first), 1000 + 50 + 2 * (dir0 + root) + gap);
        b.charge(first);
        assert_eq!(b.bound(), 1000 + 50 + 2 * (dir0 + root) + gap);
        // Another beam of the same chunk: its directory entry only, twice.
        assert_eq!(b.with(Charge::new(0, true, 0)), b.bound() + 2 * per);
        // The other chunk: its whole directory twice, no second root.
        assert_eq!(b.with(Charge::new(1, false, 7)), b.bound() + 7 + 2 * (20 + 10));
        b.flushed(2000);
        assert_eq!(b.bound(), 2000);
        assert!(!b.has_pending());
        // Filled beams are remembered across flushes.
        assert_eq!(b.with(Charge::new(0, false, 0)), 2000 + 2 * (dir0 + root) + gap);
    }
}
