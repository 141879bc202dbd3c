//! The batch request list: every beam of every section, weighted by its world
//! volume (the chance that a random view point lies in it), served in order of
//! increasing computed / desired sample count. Beams start at zero, so every
//! beam gets its first rays before any beam gets a second batch: a fill is
//! usable whenever it stops. Pure scheduling; no I/O.

use std::cmp::{Ordering, Reverse};
use std::collections::BinaryHeap;

use holodeck_protocol::{BeamKey, Section, SectionError};

/// One entry of the request list.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    /// Rays stored divided by the beam's weight.
    ratio: f64,
    /// Larger weights first among equal ratios.
    weight: f64,
    key: BeamKey,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        self.ratio
            .total_cmp(&o.ratio)
            .then(o.weight.total_cmp(&self.weight))
            .then(self.key.cmp(&o.key))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// The volume-weighted request list of a batch fill.
pub struct BatchSchedule {
    heap: BinaryHeap<Reverse<Entry>>,
    /// Weight of each beam, by section.
    weights: Vec<Vec<f64>>,
}

impl BatchSchedule {
    /// Builds the list over all beams; `stored` gives the rays each beam holds already.
    pub fn new(sections: &[Section], stored: impl Fn(BeamKey) -> u64) -> Result<BatchSchedule, SectionError> {
        let mut weights = Vec::with_capacity(sections.len());
        let mut total = 0.0;
        for s in sections {
            let w: Vec<f64> = (0..s.beam_count())
                .map(|b| s.beam_volume(b))
                .collect::<Result<_, _>>()?;
            total += w.iter().sum::<f64>();
            weights.push(w);
        }
        let mut heap = BinaryHeap::with_capacity(weights.iter().map(Vec::len).sum());
        for (si, w) in weights.iter_mut().enumerate() {
            for (b, weight) in w.iter_mut().enumerate() {
                *weight = (*weight / total).max(f64::MIN_POSITIVE);
                let key = BeamKey::new(si as u32, b as u32);
                heap.push(Reverse(Entry {
                    ratio: stored(key) as f64 / *weight,
                    weight: *weight,
                    key,
                }));
            }
        }
        Ok(BatchSchedule { heap, weights })
    }

    /// The next `count` beams to trace, `rays` rays each, in priority order.
    pub fn next(&mut self, count: usize, rays: u32) -> Vec<(BeamKey, u32)> {
        let mut out = Vec::with_capacity(count);
        let mut taken = Vec::with_capacity(count);
        while out.len() < count {
            let Some(Reverse(e)) = self.heap.pop() else { break };
            out.push((e.key, rays));
            taken.push(e);
        }
        for mut e in taken {
            e.ratio += f64::from(rays) / e.weight;
            self.heap.push(Reverse(e));
        }
        out
    }

    /// Returns rays that were handed out but never came back (a sampler that
    /// died mid-packet), so the beam is scheduled for them again.
    pub fn give_back(&mut self, key: BeamKey, rays: u32) {
        let Some(weight) = self.weight(key) else { return };
        let entries = std::mem::take(&mut self.heap).into_vec();
        self.heap = entries
            .into_iter()
            .map(|Reverse(mut e)| {
                if e.key == key {
                    e.ratio = (e.ratio - f64::from(rays) / weight).max(0.0);
                }
                Reverse(e)
            })
            .collect();
    }

    /// The weight (share of the desired samples) of a beam.
    pub fn weight(&self, key: BeamKey) -> Option<f64> {
        self.weights.get(key.section as usize)?.get(key.beam as usize).copied()
    }

    /// Number of beams in the list.
    pub fn len(&self) -> usize {
        self.heap.len()
    }

    /// True when there are no beams.
    pub fn is_empty(&self) -> bool {
        self.heap.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::SectionKind;
    use std::collections::HashMap;

    fn section() -> Section {
        Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [4, 3, 2],
            SectionKind::Interior,
        )
        .unwrap()
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
