//! A choice between two ways of doing the same job, decided by timing both
//! as they run: the tracer's first hits (packets or single rays) and its
//! path order (sorted a segment at a time, or each path to its end). The
//! two ways give the same results, so switching between them is only a
//! question of speed, and the times follow what the work is now.
//!
//! Never: judge from a single batch, or stop trying the way not chosen.

use std::sync::atomic::{AtomicU64, Ordering};

/// How often a batch tries the way not chosen.
pub const PROBE_EVERY: u64 = 16;

/// Items and nanoseconds spent each way (way 0 and way 1).
pub(super) struct TwoWays {
    /// Items timed each way before the faster one is trusted.
    warm: u64,
    /// Past this many items, both counts halve, so that the choice follows
    /// the work asked for now.
    window: u64,
    batches: AtomicU64,
    spent: [(AtomicU64, AtomicU64); 2],
}

impl TwoWays {
    /// Timers that trust a way after `warm` items and forget by halves
    /// past `window`.
    pub(super) fn new(warm: u64, window: u64) -> TwoWays {
        TwoWays {
            warm,
            window,
            batches: AtomicU64::new(0),
            spent: Default::default(),
        }
    }

    /// Nanoseconds per item spent one way, once it has been timed on enough items.
    fn per_item(&self, way: usize) -> Option<f64> {
        let items = self.spent[way].0.load(Ordering::Relaxed);
        (items >= self.warm).then(|| self.spent[way].1.load(Ordering::Relaxed) as f64 / items as f64)
    }

    /// The cheaper way, once both are timed (way 0 on a tie).
    pub(super) fn faster(&self) -> Option<usize> {
        let (a, b) = (self.per_item(0)?, self.per_item(1)?);
        Some(usize::from(b < a))
    }

    /// The way the next batch takes: way 0, then way 1, until both are
    /// timed; then the faster, with one batch in [`PROBE_EVERY`] given to
    /// the other.
    pub(super) fn choose(&self) -> usize {
        let b = self.batches.fetch_add(1, Ordering::Relaxed);
        let Some(faster) = self.faster() else {
            return usize::from(self.per_item(0).is_some());
        };
        if b % PROBE_EVERY == PROBE_EVERY - 1 {
            1 - faster
        } else {
            faster
        }
    }

    /// Records a batch of `items` done `way` in `ns` nanoseconds.
    pub(super) fn record(&self, way: usize, items: usize, ns: u64) {
        let (n, t) = &self.spent[way.min(1)];
        if n.fetch_add(items as u64, Ordering::Relaxed) > self.window {
            // Racing halvings lose a little history, which only blurs the window.
            n.store(n.load(Ordering::Relaxed) / 2, Ordering::Relaxed);
            t.store(t.load(Ordering::Relaxed) / 2, Ordering::Relaxed);
        }
        t.fetch_add(ns, Ordering::Relaxed);
    }

    /// The way chosen now, for reports: way 0 until way 1 proves faster.
    pub(super) fn preferred(&self) -> usize {
        self.faster().unwrap_or(0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_faster_way_is_chosen_and_the_other_keeps_being_tried() {
        let times = TwoWays::new(4096, 1 << 20);
        // Untimed, way 0 comes first, then way 1 until both are warm.
        assert_eq!(times.choose(), 0);
        times.record(0, 8192, 8192 * 300);
        assert_eq!(times.choose(), 1);
        times.record(1, 8192, 8192 * 200);
        let picks: Vec<usize> = (0..64).map(|_| times.choose()).collect();
        assert_eq!(
            picks.iter().filter(|&&w| w == 0).count(),
            64 / PROBE_EVERY as usize,
            "{picks:?}"
        );
        assert_eq!(times.preferred(), 1);
        // Way 0 turns faster: the window forgets the old times.
        for _ in 0..300 {
            times.record(0, 8192, 8192 * 100);
        }
        assert_eq!(times.preferred(), 0);
        let picks: Vec<usize> = (0..64).map(|_| times.choose()).collect();
        assert_eq!(
            picks.iter().filter(|&&w| w == 1).count(),
            64 / PROBE_EVERY as usize,
            "{picks:?}"
        );
    }
}
