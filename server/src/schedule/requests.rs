//! The interactive request list: beams the connected displays asked for, each
//! with the samples wanted (the largest any display wants) and the samples
//! computed so far (stored plus in flight), served in order of increasing
//! computed / desired (paper, 2.2). Requests from every display are merged
//! into one list; a display's requests leave it when the display does.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, HashMap, HashSet};

use holodeck_protocol::wire::EyePoint;
use holodeck_protocol::BeamKey;

/// Identifies a connected display.
pub type DisplayId = u64;

/// One requested beam.
#[derive(Clone, Debug)]
struct Wanted {
    /// Rays known stored.
    stored: u64,
    /// Rays handed to samplers and not back yet.
    in_flight: u64,
    /// Each requesting display and the total it wants.
    displays: Vec<(DisplayId, u32)>,
    /// Eye of the latest requester: new rays are traced near it.
    eye: Option<EyePoint>,
    /// Bumped on every change, to recognize stale heap entries.
    version: u32,
}

impl Wanted {
    fn desired(&self) -> u64 {
        self.displays.iter().map(|d| u64::from(d.1)).max().unwrap_or(0)
    }

    fn computed(&self) -> u64 {
        self.stored + self.in_flight
    }
}

#[derive(Clone, Copy, Debug, PartialEq)]
struct Entry {
    ratio: f64,
    version: u32,
    key: BeamKey,
}

impl Eq for Entry {}

impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        self.ratio.total_cmp(&o.ratio).then(self.key.cmp(&o.key))
    }
}

impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}

/// A packet's worth of work for a requested beam.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RequestPacket {
    /// The beam.
    pub key: BeamKey,
    /// Rays to trace.
    pub rays: u32,
    /// Trace near this eye (`None`: uniformly).
    pub eye: Option<EyePoint>,
}

/// The merged requests of every display.
#[derive(Default)]
pub struct RequestList {
    beams: HashMap<BeamKey, Wanted>,
    heap: BinaryHeap<Reverse<Entry>>,
    by_display: HashMap<DisplayId, HashSet<BeamKey>>,
}

impl RequestList {
    /// An empty list.
    pub fn new() -> RequestList {
        RequestList::default()
    }

    fn requeue(&mut self, key: BeamKey) {
        let Some(w) = self.beams.get_mut(&key) else { return };
        w.version = w.version.wrapping_add(1);
        let desired = w.desired();
        if w.computed() < desired {
            self.heap.push(Reverse(Entry {
                ratio: w.computed() as f64 / desired as f64,
                version: w.version,
                key,
            }));
        }
        if self.heap.len() > 4 * self.beams.len() + 1024 {
            self.compact();
        }
    }

    fn compact(&mut self) {
        let live: Vec<BeamKey> = self.beams.keys().copied().collect();
        self.heap.clear();
        for key in live {
            self.requeue(key);
        }
    }

    /// Records a display's request: `beams` as (beam, desired total, rays
    /// stored now). With `replace`, the display's earlier requests not in
    /// `beams` are dropped (a new view).
    pub fn request(&mut self, display: DisplayId, beams: &[(BeamKey, u32, u64)], eye: Option<EyePoint>, replace: bool) {
        let mine = self.by_display.entry(display).or_default();
        let old: HashSet<BeamKey> = if replace { std::mem::take(mine) } else { HashSet::new() };
        let mine = self.by_display.entry(display).or_default();
        for &(key, _, _) in beams {
            mine.insert(key);
        }
        for key in old {
            if !self.by_display.get(&display).is_some_and(|m| m.contains(&key)) {
                self.forget(display, key);
            }
        }
        for &(key, desired, stored) in beams {
            let w = self.beams.entry(key).or_insert_with(|| Wanted {
                stored,
                in_flight: 0,
                displays: Vec::new(),
                eye,
                version: 0,
            });
            w.stored = w.stored.max(stored);
            w.eye = eye;
            match w.displays.iter_mut().find(|d| d.0 == display) {
                Some(d) => d.1 = desired,
                None => w.displays.push((display, desired)),
            }
            self.requeue(key);
        }
    }

    fn forget(&mut self, display: DisplayId, key: BeamKey) {
        if let Some(w) = self.beams.get_mut(&key) {
            w.displays.retain(|d| d.0 != display);
            if w.displays.is_empty() && w.in_flight == 0 {
                self.beams.remove(&key);
            }
        }
    }

    /// Removes every request of a display that left.
    pub fn drop_display(&mut self, display: DisplayId) {
        for key in self.by_display.remove(&display).unwrap_or_default() {
            self.forget(display, key);
        }
    }

    /// The next packets for requested beams, neediest first, until `budget`
    /// rays are handed out; no packet over `max_packet` rays.
    pub fn next(&mut self, budget: u64, max_packet: u32) -> Vec<RequestPacket> {
        let mut out = Vec::new();
        let mut handed = 0u64;
        let max_packet = max_packet.max(1);
        while handed < budget {
            let Some(Reverse(e)) = self.heap.pop() else { break };
            let Some(w) = self.beams.get_mut(&e.key) else { continue };
            if w.version != e.version {
                continue;
            }
            let missing = w.desired().saturating_sub(w.computed());
            let rays = missing.min(u64::from(max_packet)).min(budget - handed).max(1) as u32;
            if missing == 0 {
                continue;
            }
            w.in_flight += u64::from(rays);
            handed += u64::from(rays);
            out.push(RequestPacket {
                key: e.key,
                rays,
                eye: w.eye.filter(|eye| eye.radius > 0.0),
            });
            self.requeue(e.key);
        }
        out
    }

    /// Rays of a beam came back from a sampler (`ours`: handed out by this
    /// list). Returns the displays that want them.
    pub fn finished(&mut self, key: BeamKey, rays: u32, ours: bool) -> Vec<DisplayId> {
        let Some(w) = self.beams.get_mut(&key) else {
            return Vec::new();
        };
        if ours {
            w.in_flight = w.in_flight.saturating_sub(u64::from(rays));
        }
        w.stored += u64::from(rays);
        let displays = w.displays.iter().map(|d| d.0).collect();
        if w.displays.is_empty() && w.in_flight == 0 {
            self.beams.remove(&key);
        } else {
            self.requeue(key);
        }
        displays
    }

    /// Rays handed out by this list that will never come back.
    pub fn give_back(&mut self, key: BeamKey, rays: u32) {
        let Some(w) = self.beams.get_mut(&key) else { return };
        w.in_flight = w.in_flight.saturating_sub(u64::from(rays));
        if w.displays.is_empty() && w.in_flight == 0 {
            self.beams.remove(&key);
        } else {
            self.requeue(key);
        }
    }

    /// Forgets what is stored (the file was clobbered): requests are
    /// refilled from nothing.
    pub fn forget_stored(&mut self) {
        let keys: Vec<BeamKey> = self.beams.keys().copied().collect();
        for k in keys {
            if let Some(w) = self.beams.get_mut(&k) {
                w.stored = 0;
            }
            self.requeue(k);
        }
    }

    /// Rays still wanted over all requests.
    pub fn missing(&self) -> u64 {
        self.beams
            .values()
            .map(|w| w.desired().saturating_sub(w.computed()))
            .sum()
    }

    /// Beams requested by at least one display.
    pub fn len(&self) -> usize {
        self.beams.values().filter(|w| !w.displays.is_empty()).count()
    }

    /// True when no display wants anything.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn k(b: u32) -> BeamKey {
        BeamKey::new(0, b)
    }

    #[test]
    fn the_neediest_beam_comes_first_and_nothing_is_handed_out_twice() {
        let mut list = RequestList::new();
        list.request(1, &[(k(1), 100, 50), (k(2), 100, 0), (k(3), 10, 10)], None, true);
        let p = list.next(10, 10);
        assert_eq!(p.len(), 1);
        assert_eq!((p[0].key, p[0].rays), (k(2), 10));
        // Beam 2 is at 10%, beam 1 at 50%: beam 2 keeps coming until it catches up.
        let p = list.next(40, 10);
        assert!(p.iter().all(|x| x.key == k(2)), "{p:?}");
        let p = list.next(1000, 1000);
        let total: u64 = p.iter().map(|x| u64::from(x.rays)).sum();
        assert_eq!(total, 50 + 50, "exactly what is missing, once");
        assert!(list.next(1000, 10).is_empty());
        assert_eq!(list.missing(), 0);
    }

    #[test]
    fn merged_requests_want_the_most_any_display_wants_and_leave_with_their_display() {
        let mut list = RequestList::new();
        list.request(1, &[(k(1), 10, 0)], None, true);
        list.request(2, &[(k(1), 30, 0), (k(2), 5, 0)], None, true);
        assert_eq!(list.missing(), 35);
        assert_eq!(list.finished(k(1), 4, false), vec![1, 2]);
        list.drop_display(2);
        assert_eq!(list.missing(), 6, "beam 1 back to display 1's 10, beam 2 gone");
        assert_eq!(list.len(), 1);
        list.drop_display(1);
        assert!(list.is_empty());
        assert!(list.next(100, 10).is_empty());
    }

    #[test]
    fn a_new_view_replaces_the_old_requests_and_lost_packets_are_rescheduled() {
        let mut list = RequestList::new();
        let eye = EyePoint {
            position: [1.0, 2.0, 3.0],
            radius: 0.1,
            frustum: None,
        };
        list.request(1, &[(k(1), 10, 0), (k(2), 10, 0)], Some(eye), true);
        let out = list.next(20, 10);
        assert_eq!(out.len(), 2);
        assert!(out.iter().all(|p| p.eye == Some(eye)));
        list.give_back(k(1), 10);
        assert_eq!(list.missing(), 10);
        list.request(1, &[(k(3), 4, 0)], None, true);
        // Beam 2 still has rays in flight; when they land nobody wants them.
        assert!(list.finished(k(2), 10, true).is_empty());
        assert_eq!(list.missing(), 4);
        let out = list.next(100, 10);
        assert_eq!(
            out,
            vec![RequestPacket {
                key: k(3),
                rays: 4,
                eye: None
            }]
        );
        // Adding (not replacing) keeps the earlier request.
        list.request(1, &[(k(4), 2, 0)], None, false);
        assert_eq!(list.len(), 2);
    }

    #[test]
    fn many_changes_keep_the_heap_bounded() {
        let mut list = RequestList::new();
        for i in 0..20_000u32 {
            list.request(1, &[(k(i % 7), 1000, 0)], None, false);
        }
        assert!(list.heap.len() <= 4 * 7 + 1024);
    }
}
