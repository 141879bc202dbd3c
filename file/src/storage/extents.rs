//! The fragment list: which byte ranges of the file are free for new runs.
//!
//! Space released by a change is *pending* until the commit that stops
//! referring to it is durable; only then may it be reused. That is what keeps
//! the previous commit intact while the next one is being written, so a crash at
//! any instant leaves at least one complete, consistent commit on disk.
//!
//! The list is never stored: on open it is derived from the gaps between the
//! runs the current commit refers to.

use std::collections::{BTreeMap, BTreeSet};

use super::format::Extent;

/// Free and pending byte ranges above the fixed header, and the logical end of the file.
#[derive(Debug, Clone, Default)]
pub struct Extents {
    /// Free ranges by offset (value: length), coalesced.
    free: BTreeMap<u64, u64>,
    /// The same ranges by (length, offset) for best-fit allocation.
    by_size: BTreeSet<(u64, u64)>,
    /// Released since the last commit; reusable once the next commit is durable.
    pending: Vec<Extent>,
    /// One past the last byte in use (the file may be longer until it is trimmed).
    end: u64,
}

/// Found while deriving the free list: two runs claim the same bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Overlap {
    /// The earlier run.
    pub first: Extent,
    /// The run that starts inside it.
    pub second: Extent,
}

impl Extents {
    /// Derives the free list from the extents in use (any order) above `start`.
    pub fn from_used(start: u64, mut used: Vec<Extent>) -> Result<Extents, Overlap> {
        used.retain(|e| e.len > 0);
        used.sort_unstable();
        let mut x = Extents {
            end: start,
            ..Extents::default()
        };
        let mut prev: Option<Extent> = None;
        for e in used {
            if e.offset < start {
                // Inside the fixed header: claimed by the header itself.
                return Err(Overlap {
                    first: Extent { offset: 0, len: start },
                    second: e,
                });
            }
            if let Some(p) = prev {
                if e.offset < p.end() {
                    return Err(Overlap { first: p, second: e });
                }
            }
            if e.offset > x.end {
                // Gaps between sorted, disjoint extents never touch one another.
                x.insert_free_raw(Extent {
                    offset: x.end,
                    len: e.offset - x.end,
                });
            }
            x.end = x.end.max(e.end());
            prev = Some(e);
        }
        Ok(x)
    }

    /// One past the last byte in use.
    pub fn end(&self) -> u64 {
        self.end
    }

    /// Total free bytes below the end (holes in the file).
    pub fn free_bytes(&self) -> u64 {
        self.free.values().sum::<u64>() + self.pending.iter().map(|e| e.len).sum::<u64>()
    }

    /// Number of separate holes.
    pub fn fragments(&self) -> usize {
        self.free.len() + self.pending.len()
    }

    fn insert_free(&mut self, mut e: Extent) {
        // Bytes past the end are not tracked (a damaged file's metadata can
        // lie past it): freeing them frees nothing.
        e.len = e.len.min(self.end.saturating_sub(e.offset));
        if e.len == 0 {
            return;
        }
        if let Some((&off, &len)) = self.free.range(..e.offset).next_back() {
            if off + len == e.offset {
                self.remove(off, len);
                e = Extent {
                    offset: off,
                    len: len + e.len,
                };
            }
        }
        if let Some(&len) = self.free.get(&e.end()) {
            self.remove(e.end(), len);
            e.len += len;
        }
        if e.end() == self.end {
            self.end = e.offset;
        } else {
            self.free.insert(e.offset, e.len);
            self.by_size.insert((e.len, e.offset));
        }
    }

    fn remove(&mut self, off: u64, len: u64) {
        self.free.remove(&off);
        self.by_size.remove(&(len, off));
    }

    /// Finds room for `len` bytes: the smallest free hole that fits, else the end.
    pub fn allocate(&mut self, len: u64) -> u64 {
        // With no limit there is always room at the end.
        self.allocate_below(len, u64::MAX).unwrap_or(self.end)
    }

    /// Like [`Extents::allocate`], but only room that ends at or before
    /// `limit`; `None` (and nothing changed) when there is none. While the end
    /// is within the limit every hole is too, so this costs what `allocate` does.
    pub fn allocate_below(&mut self, len: u64, limit: u64) -> Option<u64> {
        if len == 0 {
            return Some(self.end);
        }
        let fits = |off: u64| off.checked_add(len).is_some_and(|end| end <= limit);
        let hole = self.by_size.range((len, 0)..).find(|&&(_, off)| fits(off)).copied();
        if let Some((hole, off)) = hole {
            return Some(self.take_from_hole(off, hole, len));
        }
        if !fits(self.end) {
            return None;
        }
        let off = self.end;
        self.end += len;
        Some(off)
    }

    /// Like [`Extents::allocate_below`], but the lowest hole that fits rather
    /// than the smallest: where a second copy of metadata goes, so that it
    /// tends to lie far from the first and a truncated file keeps it.
    pub fn allocate_low_below(&mut self, len: u64, limit: u64) -> Option<u64> {
        if len == 0 {
            return Some(self.end);
        }
        let fits = |off: u64| off.checked_add(len).is_some_and(|end| end <= limit);
        let hole = self
            .free
            .iter()
            .find(|&(&off, &hole)| hole >= len && fits(off))
            .map(|(&off, &hole)| (off, hole));
        match hole {
            Some((off, hole)) => Some(self.take_from_hole(off, hole, len)),
            None => self.allocate_below(len, limit),
        }
    }

    /// Room for `len` bytes ending at or before `limit` that lies at least
    /// `gap` bytes from `avoid` on either side: the lowest such place in a
    /// hole, else at the end (leaving the gap free). Where the second copy
    /// of a piece of metadata goes, so that no damaged stretch of the disk
    /// shorter than `gap` takes both copies. `None` (nothing changed) when it
    /// does not fit below the limit.
    pub fn allocate_apart(&mut self, len: u64, limit: u64, avoid: Extent, gap: u64) -> Option<u64> {
        let near_lo = avoid.offset.saturating_sub(gap);
        let near_hi = avoid.end().saturating_add(gap);
        // The first start in [lo, hi) of room for len bytes clear of the zone.
        let place = |lo: u64, hi: u64| -> Option<u64> {
            let end = |at: u64| at.checked_add(len);
            if end(lo).is_some_and(|e| e <= hi && e <= near_lo && e <= limit) {
                return Some(lo);
            }
            let at = lo.max(near_hi);
            end(at).filter(|&e| e <= hi && e <= limit).map(|_| at)
        };
        let found = self
            .free
            .iter()
            .find_map(|(&off, &hole)| place(off, off + hole).map(|at| (off, hole, at)));
        if let Some((off, hole, at)) = found {
            self.remove(off, hole);
            if at > off {
                self.insert_free_raw(Extent {
                    offset: off,
                    len: at - off,
                });
            }
            if off + hole > at + len {
                self.insert_free_raw(Extent {
                    offset: at + len,
                    len: off + hole - at - len,
                });
            }
            return Some(at);
        }
        let at = place(self.end, u64::MAX)?;
        if at > self.end {
            let skipped = Extent {
                offset: self.end,
                len: at - self.end,
            };
            self.end = at;
            self.insert_free_raw(skipped);
        }
        self.end = at + len;
        Some(at)
    }

    /// Takes the first `len` bytes of the free hole of `hole` bytes at `off`.
    fn take_from_hole(&mut self, off: u64, hole: u64, len: u64) -> u64 {
        self.remove(off, hole);
        if hole > len {
            self.insert_free_raw(Extent {
                offset: off + len,
                len: hole - len,
            });
        }
        off
    }

    /// Claims every free byte of `e` (and the end, if `e` passes it): keeps
    /// bytes that something may still read from being allocated. Returns the
    /// pieces claimed, for releasing later.
    pub fn claim_free_within(&mut self, e: Extent) -> Vec<Extent> {
        let mut claimed = Vec::new();
        if e.len == 0 {
            return claimed;
        }
        let holes: Vec<(u64, u64)> = self
            .free
            .range(..e.end())
            .filter(|&(&off, &len)| off + len > e.offset)
            .map(|(&off, &len)| (off, len))
            .collect();
        for (off, len) in holes {
            self.remove(off, len);
            let (lo, hi) = (off.max(e.offset), (off + len).min(e.end()));
            if off < lo {
                self.free.insert(off, lo - off);
                self.by_size.insert((lo - off, off));
            }
            if hi < off + len {
                self.free.insert(hi, off + len - hi);
                self.by_size.insert((off + len - hi, hi));
            }
            claimed.push(Extent {
                offset: lo,
                len: hi - lo,
            });
        }
        if e.end() > self.end {
            let lo = e.offset.max(self.end);
            if lo > self.end {
                self.insert_free_raw(Extent {
                    offset: self.end,
                    len: lo - self.end,
                });
            }
            claimed.push(Extent {
                offset: lo,
                len: e.end() - lo,
            });
            self.end = e.end();
        }
        claimed
    }

    /// Records a hole below the end without coalescing or trimming.
    fn insert_free_raw(&mut self, e: Extent) {
        self.free.insert(e.offset, e.len);
        self.by_size.insert((e.len, e.offset));
    }

    /// Claims exactly `[at, at + len)` if it is free (or at the end): used to
    /// grow a run in place.
    pub fn try_claim(&mut self, at: u64, len: u64) -> bool {
        if at == self.end {
            self.end += len;
            return true;
        }
        match self.free.get(&at) {
            Some(&hole) if hole >= len => {
                self.take_from_hole(at, hole, len);
                true
            }
            Some(&hole) if at + hole == self.end => {
                self.remove(at, hole);
                self.end = at + len;
                true
            }
            _ => false,
        }
    }

    /// The lowest free hole at or above `at`, if any (pending ranges are not free yet).
    pub fn first_hole_from(&self, at: u64) -> Option<Extent> {
        self.free
            .range(at..)
            .next()
            .map(|(&offset, &len)| Extent { offset, len })
    }

    /// Room for `len` bytes at the end, never in a hole: for copies that must
    /// lie above everything in use.
    pub fn allocate_at_end(&mut self, len: u64) -> u64 {
        let off = self.end;
        self.end += len;
        off
    }

    /// Releases a range that the last durable commit may still refer to.
    pub fn release(&mut self, e: Extent) {
        if e.len > 0 {
            self.pending.push(e);
        }
    }

    /// Releases a range no commit refers to: reusable at once.
    pub fn release_now(&mut self, e: Extent) {
        self.insert_free(e);
    }

    /// The commit that stopped referring to the pending ranges is durable.
    pub fn commit_done(&mut self) {
        for e in std::mem::take(&mut self.pending) {
            self.insert_free(e);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn ext(offset: u64, len: u64) -> Extent {
        Extent { offset, len }
    }

    #[test]
    fn derives_holes_and_detects_overlaps() {
        let x = Extents::from_used(100, vec![ext(150, 10), ext(100, 20), ext(300, 5)]).unwrap();
        assert_eq!(x.end(), 305);
        assert_eq!(x.free_bytes(), 30 + 140);
        assert_eq!(x.fragments(), 2);
        let o = Extents::from_used(100, vec![ext(100, 20), ext(110, 5)]).unwrap_err();
        assert_eq!(o.second, ext(110, 5));
        let o = Extents::from_used(100, vec![ext(64, 10)]).unwrap_err();
        assert_eq!(o.first, ext(0, 100), "runs inside the header are refused");
    }

    #[test]
    fn pending_space_is_not_reused_before_commit() {
        let mut x = Extents::from_used(0, vec![ext(0, 100)]).unwrap();
        x.release(ext(0, 50));
        assert_eq!(x.allocate(10), 100, "pending space must wait for the commit");
        x.commit_done();
        assert_eq!(x.allocate(10), 0);
        assert_eq!(x.allocate(40), 10);
        assert_eq!(x.free_bytes(), 0);
    }

    #[test]
    fn coalesces_and_trims_the_tail() {
        let mut x = Extents::from_used(0, vec![ext(0, 10), ext(10, 10), ext(20, 10), ext(30, 10)]).unwrap();
        x.release_now(ext(10, 10));
        x.release_now(ext(20, 10));
        assert_eq!(x.fragments(), 1);
        assert_eq!(x.allocate(20), 10, "the two holes merged into one");
        x.release_now(ext(30, 10));
        assert_eq!(x.end(), 30, "free space at the end shortens the file");
        assert!(x.try_claim(30, 25));
        assert_eq!(x.end(), 55);
    }

    #[test]
    fn allocations_below_a_limit_never_pass_it_and_failures_change_nothing() {
        let mut x = Extents::from_used(0, vec![ext(0, 10), ext(20, 10), ext(60, 10)]).unwrap();
        // Holes: 10..20 and 30..60; end 70.
        assert_eq!(x.allocate_below(20, 100), Some(30), "a hole that fits is used");
        assert_eq!(x.allocate_below(20, 85), None, "the end would pass the limit");
        assert_eq!(x.end(), 70);
        assert_eq!(x.free_bytes(), 10 + 10);
        assert_eq!(x.allocate_below(15, 85), Some(70));
        assert_eq!(x.end(), 85);
        assert_eq!(x.allocate_below(10, 15), None, "the hole 10..20 ends past 15");
        assert_eq!(x.allocate_below(10, 20), Some(10));
        assert_eq!(x.allocate_below(0, 0), Some(85), "empty allocations need no room");
    }

    #[test]
    fn the_first_hole_is_the_lowest_and_end_allocations_skip_holes() {
        let mut x = Extents::from_used(100, vec![ext(120, 10), ext(150, 10), ext(200, 10)]).unwrap();
        assert_eq!(x.first_hole_from(0), Some(ext(100, 20)));
        assert_eq!(x.first_hole_from(101), Some(ext(130, 20)));
        assert_eq!(x.allocate_at_end(5), 210);
        assert_eq!(x.end(), 215);
        x.release(ext(120, 10));
        // Pending space is no hole until the commit is durable.
        assert_eq!(x.first_hole_from(0), Some(ext(100, 20)));
        x.commit_done();
        assert_eq!(x.first_hole_from(0), Some(ext(100, 50)));
        assert_eq!(x.first_hole_from(160), Some(ext(160, 40)));
    }

    #[test]
    fn freeing_past_the_end_leaves_no_hole_there() {
        let mut x = Extents::from_used(0, vec![ext(0, 10), ext(20, 10)]).unwrap();
        x.release_now(ext(25, 20));
        assert_eq!(x.end(), 25);
        x.release_now(ext(40, 10));
        assert_eq!((x.end(), x.fragments()), (25, 1));
        assert_eq!(x.allocate(10), 10, "the hole below the end, never one past it");
        assert_eq!(x.allocate(10), 25);
    }

    #[test]
    fn low_allocations_take_the_first_hole_and_claims_skip_used_bytes() {
        let mut x = Extents::from_used(0, vec![ext(0, 10), ext(30, 10), ext(45, 10)]).unwrap();
        // Holes: 10..30 (20 bytes) and 40..45 (5); end 55.
        assert_eq!(x.allocate_below(5, 100), Some(40), "best fit: the smallest hole");
        x.release_now(ext(40, 5));
        assert_eq!(x.allocate_low_below(5, 100), Some(10), "first fit: the lowest hole");
        assert_eq!(x.allocate_low_below(30, 100), Some(55), "no hole fits: the end");
        let mut x = Extents::from_used(0, vec![ext(0, 10), ext(30, 10)]).unwrap();
        let claimed = x.claim_free_within(ext(5, 45));
        assert_eq!(claimed, vec![ext(10, 20), ext(40, 10)]);
        assert_eq!(x.end(), 50);
        assert_eq!(x.free_bytes(), 0);
        for c in claimed {
            x.release_now(c);
        }
        assert_eq!(x.end(), 40);
        assert_eq!(x.free_bytes(), 20);
    }

    proptest! {
        #[test]
        fn allocations_never_overlap(ops in prop::collection::vec((1u64..50, any::<bool>(), any::<bool>()), 1..200)) {
            let mut x = Extents::from_used(64, vec![]).unwrap();
            let mut live: Vec<Extent> = Vec::new();
            for (len, free_one, commit) in ops {
                let off = x.allocate(len);
                let e = ext(off, len);
                prop_assert!(off >= 64);
                for l in &live {
                    prop_assert!(e.end() <= l.offset || l.end() <= e.offset, "{e:?} overlaps {l:?}");
                }
                live.push(e);
                if free_one && live.len() > 1 {
                    let gone = live.remove(live.len() / 2);
                    x.release(gone);
                }
                if commit { x.commit_done(); }
            }
            let used: u64 = live.iter().map(|e| e.len).sum();
            prop_assert_eq!(used + x.free_bytes(), x.end() - 64);
        }
    }
}
