//! The interactive request list: beams the connected displays asked for, each
//! with the samples every display wants and the samples computed so far
//! (stored plus in flight).
//!
//! Within one display's request, beams are served in order of increasing
//! computed / desired (paper, 2.2). Between displays the rays are shared
//! fairly ([`Share::Fair`]): the next packet goes to the display, among those
//! with unmet requests, that has received the fewest rays, so a display asking
//! for a hundred times the rays of another over fifty times the beams cannot
//! starve it. A ray counts for every display that wants its beam and still
//! lacks rays there: two displays looking at the same beams both receive
//! them. A display whose requests are met takes no turns and earns no credit;
//! when it asks again it starts level with the least-served display waiting.
//! [`Share::Merged`] keeps the paper's single list over every display, for
//! comparison. A display's requests leave the list when the display does.
//!
//! Heap updates are lazy: every change of a beam bumps its version and
//! pushes fresh entries; entries that no longer match are dropped when they
//! surface, and a heap that grows past a few times its beams is rebuilt.

use std::cmp::{Ordering, Reverse};
use std::collections::{BinaryHeap, HashMap, HashSet};

use holodeck_protocol::wire::EyePoint;
use holodeck_protocol::BeamKey;

/// Identifies a connected display.
pub type DisplayId = u64;

/// How the request list divides the rays between displays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Share {
    /// Each display with unmet requests gets an equal share of the rays
    /// handed out; within a display, neediest beam first.
    #[default]
    Fair,
    /// Every display's beams in one list, neediest first (the paper's
    /// order): a display asking for many rays over many beams takes nearly
    /// all of them while another waits.
    Merged,
}

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

    /// What `display` wants of this beam (0: nothing).
    fn desired_by(&self, display: DisplayId) -> u64 {
        self.displays
            .iter()
            .find(|d| d.0 == display)
            .map_or(0, |d| u64::from(d.1))
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

impl Entry {
    fn new(w: &Wanted, desired: u64, key: BeamKey) -> Entry {
        Entry {
            ratio: w.computed() as f64 / desired as f64,
            version: w.version,
            key,
        }
    }
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

/// Beams neediest first; may hold stale entries.
type Queue = BinaryHeap<Reverse<Entry>>;

/// Entries a queue may hold over `beams` live beams before it is rebuilt.
fn queue_bound(beams: usize) -> usize {
    4 * beams + 1024
}

/// One display's requests and its account.
#[derive(Default)]
struct Requester {
    beams: HashSet<BeamKey>,
    /// Its beams by its own computed / desired (unused when merged).
    queue: Queue,
    /// Rays handed out for its beams while it lacked them.
    received: u64,
    /// It had unmet requests at the last look.
    waiting: bool,
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

/// The requests of every display.
#[derive(Default)]
pub struct RequestList {
    share: Share,
    beams: HashMap<BeamKey, Wanted>,
    displays: HashMap<DisplayId, Requester>,
    /// Every beam by the largest count any display wants ([`Share::Merged`]).
    merged: Queue,
    /// What the display served last had received then: a display that
    /// starts waiting again is raised to it, so time spent met earns no
    /// credit. Never decreases.
    clock: u64,
}

impl RequestList {
    /// An empty list sharing rays fairly between displays.
    pub fn new() -> RequestList {
        RequestList::default()
    }

    /// An empty list that divides rays by `share`.
    pub fn with_share(share: Share) -> RequestList {
        RequestList {
            share,
            ..RequestList::default()
        }
    }

    /// How rays are divided between displays.
    pub fn share(&self) -> Share {
        self.share
    }

    /// Divides rays by `share` from now on; every display's account starts
    /// afresh.
    pub fn set_share(&mut self, share: Share) {
        self.share = share;
        self.merged.clear();
        self.clock = 0;
        for r in self.displays.values_mut() {
            r.queue.clear();
            r.received = 0;
            r.waiting = false;
        }
        let keys: Vec<BeamKey> = self.beams.keys().copied().collect();
        for key in keys {
            self.requeue(key);
        }
    }

    /// The beam changed: retires its entries and queues it again wherever
    /// it is still wanted.
    fn requeue(&mut self, key: BeamKey) {
        let Some(w) = self.beams.get_mut(&key) else { return };
        w.version = w.version.wrapping_add(1);
        let w = &self.beams[&key];
        let computed = w.computed();
        match self.share {
            Share::Merged => {
                let desired = w.desired();
                if computed < desired {
                    self.merged.push(Reverse(Entry::new(w, desired, key)));
                }
                if self.merged.len() > queue_bound(self.beams.len()) {
                    rebuild_merged(&mut self.merged, &self.beams);
                }
            }
            Share::Fair => {
                for &(id, desired) in &w.displays {
                    let desired = u64::from(desired);
                    let Some(r) = self.displays.get_mut(&id) else { continue };
                    if computed < desired {
                        r.queue.push(Reverse(Entry::new(w, desired, key)));
                    }
                    if r.queue.len() > queue_bound(r.beams.len()) {
                        rebuild(id, r, &self.beams);
                    }
                }
            }
        }
    }

    /// Records a display's request: `beams` as (beam, desired total, rays
    /// stored now). With `replace`, the display's earlier requests not in
    /// `beams` are dropped (a new view).
    pub fn request(&mut self, display: DisplayId, beams: &[(BeamKey, u32, u64)], eye: Option<EyePoint>, replace: bool) {
        let mine = &mut self.displays.entry(display).or_default().beams;
        let old: HashSet<BeamKey> = if replace { std::mem::take(mine) } else { HashSet::new() };
        mine.extend(beams.iter().map(|b| b.0));
        for key in old {
            if !self.displays.get(&display).is_some_and(|r| r.beams.contains(&key)) {
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
        let Some(w) = self.beams.get_mut(&key) else { return };
        w.displays.retain(|d| d.0 != display);
        if w.displays.is_empty() && w.in_flight == 0 {
            self.beams.remove(&key);
        } else {
            // The largest count wanted may have dropped.
            self.requeue(key);
        }
    }

    /// Removes every request of a display that left.
    pub fn drop_display(&mut self, display: DisplayId) {
        let Some(r) = self.displays.remove(&display) else {
            return;
        };
        for key in r.beams {
            self.forget(display, key);
        }
    }

    /// The beam to serve next and the display it is served for (`None`:
    /// merged), or `None` when no request is unmet.
    fn pick(&mut self) -> Option<(Option<DisplayId>, BeamKey)> {
        if self.share == Share::Merged {
            while let Some(Reverse(e)) = self.merged.pop() {
                let live = self
                    .beams
                    .get(&e.key)
                    .is_some_and(|w| w.version == e.version && w.computed() < w.desired());
                if live {
                    return Some((None, e.key));
                }
            }
            return None;
        }
        let mut best: Option<(u64, DisplayId)> = None;
        for (&id, r) in &mut self.displays {
            if !has_work(id, r, &self.beams) {
                r.waiting = false;
                continue;
            }
            if !r.waiting {
                r.waiting = true;
                r.received = r.received.max(self.clock);
            }
            if best.is_none_or(|b| (r.received, id) < b) {
                best = Some((r.received, id));
            }
        }
        let (received, id) = best?;
        self.clock = self.clock.max(received);
        let Reverse(e) = self.displays.get_mut(&id)?.queue.pop()?;
        Some((Some(id), e.key))
    }

    /// The next packets for requested beams until `budget` rays are handed
    /// out, no packet over `max_packet` rays: the display served next is the
    /// one that has received least, and its neediest beam goes first.
    pub fn next(&mut self, budget: u64, max_packet: u32) -> Vec<RequestPacket> {
        let mut out = Vec::new();
        let mut handed = 0u64;
        let max_packet = max_packet.max(1);
        while handed < budget {
            let Some((display, key)) = self.pick() else { break };
            let Some(w) = self.beams.get_mut(&key) else { break };
            let computed = w.computed();
            let desired = match display {
                Some(id) => w.desired_by(id),
                None => w.desired(),
            };
            let missing = desired.saturating_sub(computed);
            let rays = missing.min(u64::from(max_packet)).min(budget - handed).max(1) as u32;
            // Every display that still lacks rays here receives them.
            for &(id, want) in &w.displays {
                let lacks = u64::from(want).saturating_sub(computed);
                if let Some(r) = self.displays.get_mut(&id) {
                    r.received += lacks.min(u64::from(rays));
                }
            }
            w.in_flight += u64::from(rays);
            handed += u64::from(rays);
            out.push(RequestPacket {
                key,
                rays,
                eye: w.eye.filter(|eye| eye.radius > 0.0),
            });
            self.requeue(key);
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

    /// Rays handed out by this list that will never come back. (The
    /// displays keep what they were counted as receiving: a lost packet is
    /// rare, and the account only orders displays.)
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

/// Drops stale entries off the top of display `id`'s queue; true if a beam
/// it still lacks rays for is left.
fn has_work(id: DisplayId, r: &mut Requester, beams: &HashMap<BeamKey, Wanted>) -> bool {
    while let Some(Reverse(e)) = r.queue.peek() {
        let live = beams
            .get(&e.key)
            .is_some_and(|w| w.version == e.version && w.computed() < w.desired_by(id));
        if live {
            return true;
        }
        r.queue.pop();
    }
    false
}

/// Rebuilds display `id`'s queue from its beams, without stale entries.
fn rebuild(id: DisplayId, r: &mut Requester, beams: &HashMap<BeamKey, Wanted>) {
    r.queue.clear();
    for key in &r.beams {
        let Some(w) = beams.get(key) else { continue };
        let desired = w.desired_by(id);
        if w.computed() < desired {
            r.queue.push(Reverse(Entry::new(w, desired, *key)));
        }
    }
}

/// Rebuilds the merged queue from every beam, without stale entries.
fn rebuild_merged(queue: &mut Queue, beams: &HashMap<BeamKey, Wanted>) {
    queue.clear();
    for (key, w) in beams {
        let desired = w.desired();
        if w.computed() < desired {
            queue.push(Reverse(Entry::new(w, desired, *key)));
        }
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

    /// Hands out `budget`-ray calls of packets of at most 16 rays, each
    /// packet traced at once, until `modest`'s beams hold `asked` rays;
    /// returns the rays that went to its beams and to everyone else's.
    fn serve_until_met(list: &mut RequestList, modest: &[BeamKey], asked: u64, budget: u64) -> (u64, u64) {
        let (mut mine, mut others) = (0u64, 0u64);
        for _ in 0..10_000 {
            if mine >= asked {
                break;
            }
            for p in list.next(budget, 16) {
                list.finished(p.key, p.rays, true);
                if modest.contains(&p.key) {
                    mine += u64::from(p.rays);
                } else {
                    others += u64::from(p.rays);
                }
            }
        }
        (mine, others)
    }

    /// A greedy display served alone for 20 budgets of 256 rays, then a
    /// modest one asks: returns the rays that went to the modest display's
    /// beams and to the greedy one's until the modest request was met.
    fn greedy_then_modest(list: &mut RequestList) -> (u64, u64) {
        // The greedy display: 1,000 beams of 100 rays, asked for first and
        // served alone for a while.
        let greedy: Vec<(BeamKey, u32, u64)> = (1000..2000).map(|b| (k(b), 100, 0)).collect();
        list.request(2, &greedy, None, true);
        let mut alone = 0;
        for _ in 0..20 {
            for p in list.next(256, 16) {
                list.finished(p.key, p.rays, true);
                alone += u64::from(p.rays);
            }
        }
        assert_eq!(alone, 20 * 256, "alone, it takes every budget");
        // The modest one: 20 beams of 50 rays (a 50th of the beams, a 100th of the rays).
        let modest: Vec<BeamKey> = (0..20).map(k).collect();
        let asked = 20 * 50;
        list.request(1, &modest.iter().map(|&b| (b, 50, 0)).collect::<Vec<_>>(), None, true);
        let (mine, others) = serve_until_met(list, &modest, asked, 256);
        assert_eq!(mine, asked, "exactly what it asked for");
        // Met, it takes nothing: the greedy display gets every ray again.
        let rest = list.next(256, 16);
        assert!(rest.iter().all(|p| !modest.contains(&p.key)), "{rest:?}");
        assert_eq!(rest.iter().map(|p| u64::from(p.rays)).sum::<u64>(), 256);
        (mine, others)
    }

    #[test]
    fn a_greedy_display_does_not_starve_a_modest_one() {
        let mut list = RequestList::new();
        let (mine, others) = greedy_then_modest(&mut list);
        let (asked, total) = (mine, mine + others);
        assert!(
            mine as f64 >= 0.45 * total as f64,
            "the modest display got {mine} of {total} rays while both waited"
        );
        assert!(
            others as f64 >= 0.45 * total as f64,
            "an idle spell earns no credit: the greedy display still got {others} of {total}"
        );
        assert!(
            total <= 2 * asked + 256,
            "met after {total} rays, about twice what it asked for"
        );
    }

    #[test]
    fn the_merged_order_lets_the_greedy_display_take_nearly_everything() {
        let mut list = RequestList::with_share(Share::Merged);
        let (mine, others) = greedy_then_modest(&mut list);
        // Its beams reach 50 rays only once the greedy display's 1,000 beams
        // are nearly as full: it gets about a hundredth of the rays.
        assert!(others > 50 * mine, "{mine} vs {others}");
        // Switching to a fair share reorders what is left.
        list.request(3, &[(k(5000), 64, 0)], None, true);
        list.set_share(Share::Fair);
        let p = list.next(64, 16);
        assert_eq!(p.iter().filter(|p| p.key == k(5000)).count(), 2, "{p:?}");
    }

    #[test]
    fn a_beam_two_displays_want_counts_for_both() {
        let mut list = RequestList::new();
        // Display 1 wants 10 beams; display 2 the same beams and 10 more.
        let shared: Vec<(BeamKey, u32, u64)> = (0..10).map(|b| (k(b), 100, 0)).collect();
        let own: Vec<(BeamKey, u32, u64)> = (10..20).map(|b| (k(b), 100, 0)).collect();
        list.request(1, &shared, None, true);
        list.request(2, &[shared.clone(), own].concat(), None, true);
        let (mut one, mut two) = (0u64, 0u64);
        while one < 1000 {
            for p in list.next(16, 16) {
                list.finished(p.key, p.rays, true);
                if p.key.beam < 10 {
                    one += u64::from(p.rays);
                }
                two += u64::from(p.rays);
            }
            // Both receive the shared beams' rays: neither is owed turns.
            assert!(one.abs_diff(two) <= 16, "display 1 got {one}, display 2 {two}");
        }
        // Display 1 is met: display 2's own beams get every ray.
        let p = list.next(160, 16);
        assert!(p.iter().all(|p| p.key.beam >= 10), "{p:?}");
        assert_eq!(list.missing(), 1000 - (two - one) - 160);
    }

    #[test]
    fn many_changes_keep_the_heap_bounded() {
        let mut list = RequestList::new();
        for i in 0..20_000u32 {
            list.request(1, &[(k(i % 7), 1000, 0)], None, false);
        }
        assert!(list.displays[&1].queue.len() <= queue_bound(7));
    }
}
