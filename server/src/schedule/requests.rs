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
//! Pure bookkeeping: no I/O, no clock.

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
mod tests;
