//! The batch request list: every beam of every section (or only the beams
//! given views see), weighted by its world volume (the chance that a random
//! view point lies in it) or by how much of the views it covers, served in
//! order of increasing computed / desired sample count. Beams start at zero,
//! so every beam gets its first rays before any beam gets a second batch: a
//! fill is usable whenever it stops. Pure scheduling; no I/O.
//!
//! Updates are lazy: each beam's current ratio lives in a table, and heap
//! entries that no longer match it are fixed up when they surface, so giving
//! rays back or crediting rays traced for a display costs O(log n).

use std::cmp::Reverse;
use std::collections::BinaryHeap;

use holodeck_protocol::wire::MAX_PACKET_RAYS;
use holodeck_protocol::{BeamKey, Section, SectionError};

/// One entry of the request list, 16 bytes, ordered by its fields: ratio,
/// then rank (larger weights first, then lower keys), so that comparing two
/// is comparing integers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Entry {
    /// Rays stored divided by the beam's weight, as the bits of a
    /// non-negative float (which order as the numbers do).
    ratio: u64,
    /// The beam's place among the weighted beams sorted by decreasing
    /// weight, then by key.
    rank: u32,
    /// The beam's sequence number when pushed: only the newest entry of a
    /// beam is live, so no beam is ever in the list twice.
    seq: u32,
}

/// The bits of non-negative `r` that order as the numbers do (-0 made +0).
#[inline]
fn ratio_bits(r: f64) -> u64 {
    (r + 0.0).to_bits()
}

/// Marks a rank not handed out in the current call of [`BatchSchedule::next`].
const NOT_HANDED: u32 = u32::MAX;

/// The weighted request list of a batch fill.
pub struct BatchSchedule {
    heap: BinaryHeap<Reverse<Entry>>,
    /// Each beam's weight (normalised to sum to 1; 0 for beams not scheduled), by section.
    weights: Vec<Vec<f64>>,
    /// The rank of each beam, by section (`u32::MAX` for beams not scheduled).
    ranks: Vec<Vec<u32>>,
    /// By rank: the beam, its weight, its current ratio and sequence number.
    keys: Vec<BeamKey>,
    weight_of: Vec<f64>,
    ratios: Vec<f64>,
    seqs: Vec<u32>,
    /// By rank: where the beam is in the packets of the current call.
    handed: Vec<u32>,
}

impl BatchSchedule {
    /// Builds the list over all beams, weighted by volume; `stored` gives the
    /// rays each beam holds already.
    pub fn new(sections: &[Section], stored: impl Fn(BeamKey) -> u64) -> Result<BatchSchedule, SectionError> {
        let mut weights = Vec::with_capacity(sections.len());
        for s in sections {
            let w: Vec<f64> = (0..s.beam_count())
                .map(|b| s.beam_volume(b))
                .collect::<Result<_, _>>()?;
            weights.push(w);
        }
        Ok(BatchSchedule::with_weights(weights, stored))
    }

    /// Builds the list over the beams some views see (like Radiance's `rholo`
    /// given views): each beam weighted by the view rays that fell in it.
    pub fn for_views(sections: &[Section], seen: &[(BeamKey, u32)], stored: impl Fn(BeamKey) -> u64) -> BatchSchedule {
        let mut weights: Vec<Vec<f64>> = sections.iter().map(|s| vec![0.0; s.beam_count() as usize]).collect();
        for &(k, n) in seen {
            if let Some(w) = weights
                .get_mut(k.section as usize)
                .and_then(|w| w.get_mut(k.beam as usize))
            {
                *w += f64::from(n);
            }
        }
        BatchSchedule::with_weights(weights, stored)
    }

    /// Builds the list from raw weights (0: not scheduled), normalized to sum 1.
    fn with_weights(mut weights: Vec<Vec<f64>>, stored: impl Fn(BeamKey) -> u64) -> BatchSchedule {
        let total: f64 = weights.iter().flatten().sum();
        let mut beams: Vec<(f64, BeamKey)> = Vec::new();
        for (si, w) in weights.iter_mut().enumerate() {
            for (b, weight) in w.iter_mut().enumerate() {
                if *weight <= 0.0 || !weight.is_finite() {
                    *weight = 0.0;
                    continue;
                }
                *weight = (*weight / total).max(f64::MIN_POSITIVE);
                beams.push((*weight, BeamKey::new(si as u32, b as u32)));
            }
        }
        // Larger weights first among equal ratios, then lower keys.
        beams.sort_by(|a, b| b.0.total_cmp(&a.0).then(a.1.cmp(&b.1)));
        let mut ranks: Vec<Vec<u32>> = weights.iter().map(|w| vec![u32::MAX; w.len()]).collect();
        let mut keys = Vec::with_capacity(beams.len());
        let mut weight_of = Vec::with_capacity(beams.len());
        let mut ratios = Vec::with_capacity(beams.len());
        for (rank, &(weight, key)) in beams.iter().enumerate() {
            ranks[key.section as usize][key.beam as usize] = rank as u32;
            keys.push(key);
            weight_of.push(weight);
            ratios.push(stored(key) as f64 / weight);
        }
        let n = keys.len();
        let mut schedule = BatchSchedule {
            heap: BinaryHeap::new(),
            weights,
            ranks,
            keys,
            weight_of,
            ratios,
            seqs: vec![0; n],
            handed: vec![NOT_HANDED; n],
        };
        schedule.compact();
        schedule
    }

    /// Pushes the beam's live entry for its current ratio, retiring older ones.
    fn push(&mut self, rank: u32) {
        let r = rank as usize;
        let seq = self.seqs[r].wrapping_add(1);
        self.seqs[r] = seq;
        self.heap.push(Reverse(Entry {
            ratio: ratio_bits(self.ratios[r]),
            rank,
            seq,
        }));
        // Retired entries are dropped once they could double the heap.
        if self.heap.len() > 2 * self.keys.len() + 1024 {
            self.compact();
        }
    }

    /// The rank of a scheduled beam.
    fn rank(&self, key: BeamKey) -> Option<u32> {
        let r = *self.ranks.get(key.section as usize)?.get(key.beam as usize)?;
        (r != u32::MAX).then_some(r)
    }

    /// The next `count` packets' worth of work (`count` x `rays` rays), at
    /// most one packet per beam: rays go, a packet of `rays` (a single ray
    /// for a beam that holds none yet) at a time, to the beam of lowest
    /// ratio, so that beams fill in proportion to their weights however few
    /// they are; a beam's turns in one call are merged into one packet of
    /// at most [`MAX_PACKET_RAYS`] rays. Packets come in the order their
    /// beams were first served.
    pub fn next(&mut self, count: usize, rays: u32) -> Vec<(BeamKey, u32)> {
        let rays = rays.max(1);
        let budget = count as u64 * u64::from(rays);
        let mut out: Vec<(BeamKey, u32)> = Vec::new();
        let mut touched: Vec<u32> = Vec::new();
        let mut full = Vec::new();
        let mut handed = 0u64;
        while handed < budget {
            let Some(Reverse(e)) = self.heap.pop() else { break };
            let r = e.rank as usize;
            if self.seqs[r] != e.seq {
                continue; // retired: the beam has a newer entry
            }
            let n = if self.ratios[r] == 0.0 { 1 } else { rays };
            if self.handed[r] == NOT_HANDED {
                self.handed[r] = out.len() as u32;
                touched.push(e.rank);
                out.push((self.keys[r], 0));
            }
            let i = self.handed[r] as usize;
            if out[i].1 + n > MAX_PACKET_RAYS {
                full.push(Reverse(e));
                continue;
            }
            out[i].1 += n;
            handed += u64::from(n);
            self.ratios[r] += f64::from(n) / self.weight_of[r];
            self.push(e.rank);
        }
        for r in touched {
            self.handed[r as usize] = NOT_HANDED;
        }
        self.heap.extend(full);
        out.retain(|o| o.1 > 0);
        out
    }

    /// Returns rays that were handed out but never came back (a sampler that
    /// died mid-packet), so the beam is scheduled for them again.
    pub fn give_back(&mut self, key: BeamKey, rays: u32) {
        self.adjust(key, -f64::from(rays));
    }

    /// Counts rays a beam got outside this list (traced for a display).
    pub fn credit(&mut self, key: BeamKey, rays: u32) {
        self.adjust(key, f64::from(rays));
    }

    fn adjust(&mut self, key: BeamKey, rays: f64) {
        let Some(rank) = self.rank(key) else { return };
        let r = rank as usize;
        self.ratios[r] = (self.ratios[r] + rays / self.weight_of[r]).max(0.0);
        self.push(rank);
    }

    /// Rebuilds the heap from the ratio table, dropping retired entries.
    fn compact(&mut self) {
        let entries: Vec<Reverse<Entry>> = (0..self.keys.len())
            .map(|r| {
                Reverse(Entry {
                    ratio: ratio_bits(self.ratios[r]),
                    rank: r as u32,
                    seq: self.seqs[r],
                })
            })
            .collect();
        self.heap = entries.into();
    }

    /// The weight (share of the desired samples) of a beam; 0 if not scheduled.
    pub fn weight(&self, key: BeamKey) -> Option<f64> {
        self.weights.get(key.section as usize)?.get(key.beam as usize).copied()
    }

    /// Number of beams in the list.
    pub fn len(&self) -> usize {
        self.keys.len()
    }

    /// Whether no beam is scheduled.
    pub fn is_empty(&self) -> bool {
        self.keys.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashMap;

    fn section() -> Section {
        crate::schedule::test_section()
    }

    #[test]
    fn every_beam_is_served_once_before_any_twice() {
        let s = section();
        let n = s.beam_count() as usize;
        let mut sched = BatchSchedule::new(std::slice::from_ref(&s), |_| 0).unwrap();
        let first: Vec<BeamKey> = sched.next(n, 4).into_iter().map(|(k, _)| k).collect();
        let mut unique = first.clone();
        unique.sort();
        unique.dedup();
        assert_eq!(unique.len(), n, "the first round covers every beam exactly once");
        // Bigger beams come first within the round.
        let w0 = sched.weight(first[0]).unwrap();
        let wl = sched.weight(first[n - 1]).unwrap();
        assert!(w0 >= wl);
    }

    #[test]
    fn long_fills_follow_the_volume_weights() {
        let s = section();
        let mut sched = BatchSchedule::new(std::slice::from_ref(&s), |_| 0).unwrap();
        let mut got: HashMap<BeamKey, u64> = HashMap::new();
        for _ in 0..200 {
            for (k, r) in sched.next(s.beam_count() as usize / 3, 2) {
                *got.entry(k).or_default() += u64::from(r);
            }
        }
        let total: u64 = got.values().sum();
        for (k, n) in &got {
            let expected = sched.weight(*k).unwrap() * total as f64;
            assert!(
                (*n as f64 - expected).abs() <= 2.0 + 0.05 * expected,
                "{k:?}: {n} vs {expected:.1}"
            );
        }
    }

    #[test]
    fn rays_given_back_are_scheduled_again_first_and_credited_rays_wait() {
        let s = section();
        let n = s.beam_count() as usize;
        let mut sched = BatchSchedule::new(std::slice::from_ref(&s), |_| 0).unwrap();
        let first = sched.next(n, 4);
        let lost = first[n / 2].0;
        sched.give_back(lost, 4);
        assert_eq!(sched.next(1, 4)[0].0, lost, "a beam whose packet was lost comes first");
        let credited = first[0].0;
        sched.credit(credited, 4000);
        let round: Vec<BeamKey> = sched.next(n - 1, 4).into_iter().map(|(k, _)| k).collect();
        assert!(!round.contains(&credited), "rays traced for a display count");
        // Many adjustments keep the heap bounded.
        for _ in 0..10_000 {
            sched.give_back(lost, 1);
            sched.credit(lost, 1);
        }
        assert!(sched.heap.len() <= 2 * n + 1024);
    }

    #[test]
    fn a_beam_given_back_is_never_in_the_list_twice() {
        let s = section();
        let n = s.beam_count() as usize;
        let mut sched = BatchSchedule::new(std::slice::from_ref(&s), |_| 0).unwrap();
        let first = sched.next(n, 4);
        let x = first[0].0;
        // Its packet is lost, then handed out again: back at its old ratio.
        sched.give_back(x, 1);
        assert_eq!(sched.next(1, 4)[0].0, x);
        for _ in 0..50 {
            let round = sched.next(n, 4);
            let mut keys: Vec<BeamKey> = round.iter().map(|r| r.0).collect();
            keys.sort();
            keys.dedup();
            assert_eq!(keys.len(), round.len(), "a beam handed out twice in one call");
        }
        let asked: usize = sched.next(10 * n, 4).len();
        assert_eq!(asked, n, "one packet per beam per call, however many are asked for");
    }

    #[test]
    fn a_fill_for_views_touches_only_the_beams_they_see() {
        let s = section();
        let seen = vec![
            (BeamKey::new(0, 3), 30),
            (BeamKey::new(0, 9), 10),
            (BeamKey::new(5, 1), 1),
        ];
        let mut sched = BatchSchedule::for_views(std::slice::from_ref(&s), &seen, |_| 0);
        assert_eq!(sched.len(), 2, "beams of unknown sections are ignored");
        let mut got: HashMap<BeamKey, u64> = HashMap::new();
        for _ in 0..400 {
            for (k, r) in sched.next(1, 1) {
                *got.entry(k).or_default() += u64::from(r);
            }
        }
        assert_eq!(got.len(), 2);
        assert_eq!(got[&BeamKey::new(0, 3)], 300);
        assert_eq!(got[&BeamKey::new(0, 9)], 100);
    }

    #[test]
    fn a_few_beams_fill_in_proportion_even_when_every_call_covers_them_all() {
        let s = section();
        let seen = vec![(BeamKey::new(0, 3), 900), (BeamKey::new(0, 9), 100)];
        let mut sched = BatchSchedule::for_views(std::slice::from_ref(&s), &seen, |_| 0);
        let mut got: HashMap<BeamKey, u64> = HashMap::new();
        for _ in 0..50 {
            let round = sched.next(4096, 4);
            assert_eq!(round.len(), 2, "one packet per beam per call");
            for (k, r) in round {
                *got.entry(k).or_default() += u64::from(r);
            }
        }
        let (a, b) = (got[&BeamKey::new(0, 3)], got[&BeamKey::new(0, 9)]);
        // Each call hands out its budget, overshooting by less than a packet.
        let budget = 50 * 4096 * 4;
        assert!(a + b >= budget && a + b < budget + 50 * 4, "{}", a + b);
        assert!((a as f64 / (a + b) as f64 - 0.9).abs() < 0.001, "{a} vs {b}");
        // A single beam asked for more than a packet holds gets a full packet.
        let mut one = BatchSchedule::for_views(std::slice::from_ref(&s), &seen[..1], |_| 0);
        assert_eq!(one.next(1 << 20, 4), vec![(BeamKey::new(0, 3), MAX_PACKET_RAYS - 3)]);
    }

    #[test]
    fn rays_already_stored_count() {
        let s = section();
        let full = BeamKey::new(0, 5);
        let mut sched = BatchSchedule::new(std::slice::from_ref(&s), |k| if k == full { 1000 } else { 0 }).unwrap();
        let round: Vec<BeamKey> = sched
            .next(s.beam_count() as usize - 1, 1)
            .into_iter()
            .map(|(k, _)| k)
            .collect();
        assert!(!round.contains(&full), "a beam that is already full waits");
    }
}
