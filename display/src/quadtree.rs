//! The paper's X11 display driver (section 2.4.3): an image-plane quadtree
//! whose leaves hold at most one reprojected sample, drawn as constant-color
//! rectangles, with empty leaves taking the average of their siblings.
//!
//! The sample bookkeeping (projection, the closest-miss rule for samples that
//! land on one pixel, the local cache and its reprojection on view changes) is
//! shared with the splat baseline through [`Store`], so that the two drivers
//! keep exactly the same samples and differ only in how they fill the gaps.
//!
//! Speed comes from memory order, not arithmetic: a batch is projected first,
//! sorted by each sample's path down the tree (a Morton code), and then
//! inserted, so consecutive insertions walk the same, cached, branch of the
//! tree and new nodes are laid out in drawing order.

use glam::{DVec3, Vec3};
use holodeck_protocol::{Picture, ViewProjector};
use rayon::prelude::*;

use crate::driver::{Driver, DriverStats, Viewport};
use crate::sample::Sample;

/// A view change that turns the view direction by more than this many degrees
/// drops the local sample cache: the paper's drivers "ignore their locally
/// cached samples and use only new ones" after such a rotation (section 3),
/// because samples taken for a very different direction are poor stand-ins
/// for the view-dependent shading of the new one.
pub const CACHE_DROP_DEGREES: f64 = 20.0;

/// Two samples on one pixel whose depths differ by more than this fraction of
/// the nearer depth are a multidepth collision (paper, Figure 6 and the 2%
/// threshold of section 2.4.4).
pub const MULTIDEPTH_TOLERANCE: f64 = 0.02;

/// A node index or slot that stands for "nothing here".
const NONE: u32 = u32::MAX;

/// Fewest off-frame samples kept for a return to earlier views, so that tiny
/// frames still remember a useful surrounding.
const MIN_PARKED: usize = 1 << 16;

/// Samples projected and sorted together: large enough that sorting pays
/// (a sorted run walks the tree in order), small enough that the scratch
/// buffers stay a few megabytes.
const CHUNK: usize = 1 << 18;

/// Batches smaller than this are inserted in arrival order: sorting them
/// costs more than it saves.
const SORT_MIN: usize = 256;

/// [`Viewport::pixel`] with the view's projector made once (the basis and
/// the tangents are not recomputed per point); the same arithmetic, so the
/// pixels agree exactly.
#[derive(Clone, Debug)]
pub(crate) struct Projector {
    view: ViewProjector,
    width: u32,
    height: u32,
}

impl Projector {
    /// Precomputes the constants of `viewport`.
    pub(crate) fn new(viewport: &Viewport) -> Projector {
        Projector {
            view: viewport.view.projector(),
            width: viewport.width,
            height: viewport.height,
        }
    }

    /// The pixel (column, row from the top) and depth of a world point, as
    /// [`Viewport::pixel`].
    #[inline]
    pub(crate) fn pixel(&self, p: DVec3) -> Option<(u32, u32, f64)> {
        let (x, y, depth) = self.view.project(p)?;
        // A hand-built zero-sized viewport has no pixels to land on.
        if self.width == 0 || self.height == 0 || !(0.0..1.0).contains(&x) || !(0.0..1.0).contains(&y) {
            return None;
        }
        let col = (x * f64::from(self.width)) as u32;
        let row = ((1.0 - y) * f64::from(self.height)) as u32;
        Some((col.min(self.width - 1), row.min(self.height - 1), depth))
    }
}

/// What a driver keeps of one sample for the current view.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(crate) struct Entry {
    /// Its pixel, in the pixel index's own numbering ([`PixelIndex::key`]).
    pub(crate) key: u64,
    /// Linear RGB radiance.
    pub(crate) color: [f32; 3],
    /// Reprojected depth.
    pub(crate) depth: f32,
    /// Distance from the eye to the sample's ray.
    pub(crate) miss: f64,
    /// Where its original is in the store's cache.
    src: u32,
}

/// Where a sample goes in a pixel index.
pub(crate) enum Spot {
    /// Nothing on its pixel yet: the index position to record its slot at.
    Free(usize),
    /// The slot of the sample already on its pixel.
    Taken(u32),
}

/// A spatial index over the frame's pixels that maps a pixel to at most one
/// sample slot: the quadtree, or the splat baseline's plain grid.
pub(crate) trait PixelIndex {
    /// Empties the index for a frame of this size.
    fn reset(&mut self, width: u32, height: u32);
    /// A number for pixel (`col`, `row`), unique to it, whose order is the
    /// index's memory order (batches are inserted sorted by it).
    fn key(&self, col: u32, row: u32) -> u64;
    /// Keys are below `1 << key_bits()`.
    fn key_bits(&self) -> u32;
    /// Finds the spot of the pixel with `key`, restructuring as needed
    /// (`entries` gives the keys of the slots already in the index).
    fn find(&mut self, entries: &[Entry], key: u64) -> Spot;
    /// Records `slot` at a spot [`PixelIndex::find`] returned as free.
    fn fill(&mut self, at: usize, slot: u32);
}

/// A projected sample waiting in a batch: everything insertion needs, so
/// that inserting in tree order never reads the samples out of order.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    key: u64,
    miss: f64,
    color: [f32; 3],
    depth: f32,
    /// Its position in the batch being inserted.
    src: u32,
}

/// Where a sample of a batch lands.
#[derive(Clone, Copy, Debug)]
enum Projected {
    On(Pending),
    Off,
    NonFinite,
}

/// Batches at least this large are projected on every core.
const PARALLEL_MIN: usize = 1 << 14;

/// Stable least-significant-digit radix sort of `v` by key (`bits` wide),
/// with `spare` as the second buffer. Stability keeps samples of one pixel in
/// arrival order, so ties and counters come out as without sorting.
fn radix_sort(v: &mut Vec<Pending>, spare: &mut Vec<Pending>, bits: u32) {
    const MAX_DIGIT: u32 = 11;
    if bits == 0 {
        return;
    }
    let passes = bits.div_ceil(MAX_DIGIT);
    let digit = bits.div_ceil(passes);
    let mask = (1u64 << digit) - 1;
    let mut counts = vec![0usize; 1 << digit];
    spare.clear();
    spare.resize(v.len(), Pending::default());
    for pass in 0..passes {
        let shift = pass * digit;
        counts.fill(0);
        for p in v.iter() {
            counts[((p.key >> shift) & mask) as usize] += 1;
        }
        if counts.contains(&v.len()) {
            continue;
        }
        let mut sum = 0;
        for c in counts.iter_mut() {
            let n = *c;
            *c = sum;
            sum += n;
        }
        for p in v.iter() {
            let d = ((p.key >> shift) & mask) as usize;
            spare[counts[d]] = *p;
            counts[d] += 1;
        }
        std::mem::swap(v, spare);
    }
}

/// The samples of a driver: the kept samples with their reprojections, the
/// local cache of the originals, the counters and the view.
///
/// The cache holds the original of every sample that won a pixel, in the
/// order they won it, and each entry points at its original. Samples that
/// later lose their pixel stay behind as garbage until it outweighs the live
/// samples and [`Store::compact`] squeezes it out.
#[derive(Clone, Debug)]
pub(crate) struct Store<I> {
    pub(crate) viewport: Viewport,
    projector: Projector,
    pub(crate) index: I,
    pub(crate) entries: Vec<Entry>,
    cache: Vec<Sample>,
    /// Cached samples that a view change moved off the frame: kept (up to
    /// [`Store::park_limit`]) so that turning back brings them back, the
    /// paper's "movement outside the current view".
    parked: Vec<Sample>,
    park: bool,
    stats: DriverStats,
    /// Scratch for batches.
    pending: Vec<Pending>,
    projected: Vec<Projected>,
    spare: Vec<Pending>,
}

impl<I: PixelIndex + Sync> Store<I> {
    /// An empty store; `park` keeps samples a view change moves off-frame.
    pub(crate) fn new(viewport: Viewport, mut index: I, park: bool) -> Store<I> {
        index.reset(viewport.width, viewport.height);
        Store {
            projector: Projector::new(&viewport),
            viewport,
            index,
            entries: Vec::new(),
            cache: Vec::new(),
            parked: Vec::new(),
            park,
            stats: DriverStats::default(),
            pending: Vec::new(),
            projected: Vec::new(),
            spare: Vec::new(),
        }
    }

    /// Counters, with `kept` as of now.
    pub(crate) fn stats(&self) -> DriverStats {
        DriverStats {
            kept: self.entries.len() as u64,
            ..self.stats
        }
    }

    /// Samples held for reprojection: the kept ones and the parked ones.
    pub(crate) fn cached(&self) -> usize {
        self.entries.len() + self.parked.len()
    }

    /// Adds samples: the body of [`Driver::add`].
    pub(crate) fn add(&mut self, samples: &[Sample]) {
        self.stats.received += samples.len() as u64;
        for chunk in samples.chunks(CHUNK) {
            self.insert_batch(chunk, false);
        }
    }

    /// Projects a batch, sorts it into tree order and inserts it. New samples
    /// are checked and counted; cached ones (`cached`) are known finite, and
    /// those off the frame are parked instead of counted.
    fn insert_batch(&mut self, samples: &[Sample], cached: bool) {
        let eye = self.viewport.view.position;
        let mut pending = std::mem::take(&mut self.pending);
        pending.clear();
        // Projection is independent per sample: large batches use every core.
        let (projector, index) = (&self.projector, &self.index);
        let project = |(i, s): (usize, &Sample)| -> Projected {
            if !cached && !s.is_finite() {
                return Projected::NonFinite;
            }
            match projector.pixel(s.target(eye)) {
                Some((col, row, depth)) => {
                    let miss = s.miss_distance(eye);
                    Projected::On(Pending {
                        key: index.key(col, row),
                        // A NaN distance (from overflow on absurd
                        // coordinates) would never lose a comparison: make
                        // it the worst.
                        miss: if miss.is_nan() { f64::INFINITY } else { miss },
                        color: s.color,
                        depth: depth as f32,
                        src: i as u32,
                    })
                }
                None => Projected::Off,
            }
        };
        let mut projected = std::mem::take(&mut self.projected);
        projected.clear();
        if samples.len() >= PARALLEL_MIN {
            projected.par_extend(samples.par_iter().enumerate().map(project));
        } else {
            projected.extend(samples.iter().enumerate().map(project));
        }
        for (i, p) in projected.iter().enumerate() {
            match p {
                Projected::On(p) => pending.push(*p),
                Projected::NonFinite => self.stats.rejected_nonfinite += 1,
                Projected::Off if !cached => self.stats.outside += 1,
                Projected::Off if self.parked.len() < self.park_limit() => self.parked.push(samples[i]),
                Projected::Off => {}
            }
        }
        self.projected = projected;
        if pending.len() >= SORT_MIN {
            radix_sort(&mut pending, &mut self.spare, self.index.key_bits());
        }
        self.entries.reserve(pending.len());
        // Samples of one pixel are adjacent after the sort: after the first,
        // the rest go straight to its slot instead of down the tree again.
        let mut last: Option<(u64, u32)> = None;
        for p in &pending {
            let slot = match last {
                Some((key, slot)) if key == p.key => {
                    self.collide(slot, p, samples);
                    slot
                }
                _ => self.insert(p, samples),
            };
            last = Some((p.key, slot));
        }
        self.pending = pending;
        if self.cache.len() > 2 * self.entries.len() + SORT_MIN {
            self.compact();
        }
    }

    /// Puts one projected sample in, resolving a pixel collision by the
    /// closest miss (ties keep the sample already there).
    #[inline]
    fn insert(&mut self, p: &Pending, batch: &[Sample]) -> u32 {
        match self.index.find(&self.entries, p.key) {
            Spot::Free(at) => {
                let slot = self.entries.len() as u32;
                // Only winners are copied into the cache: most samples of a
                // dense batch lose their pixel and never cost a copy.
                self.entries.push(Entry {
                    key: p.key,
                    color: p.color,
                    depth: p.depth,
                    miss: p.miss,
                    src: self.cache.len() as u32,
                });
                self.index.fill(at, slot);
                self.cache.push(batch[p.src as usize]);
                slot
            }
            Spot::Taken(slot) => {
                self.collide(slot, p, batch);
                slot
            }
        }
    }

    /// A sample lands on the pixel whose entry is `slot`: the closer miss
    /// wins (ties keep the sample already there).
    #[inline]
    fn collide(&mut self, slot: u32, p: &Pending, batch: &[Sample]) {
        let src = self.cache.len() as u32;
        let old = &mut self.entries[slot as usize];
        let (a, b) = (f64::from(old.depth).abs(), f64::from(p.depth).abs());
        if (a - b).abs() > MULTIDEPTH_TOLERANCE * a.min(b) {
            self.stats.multidepth += 1;
        }
        if p.miss < old.miss {
            *old = Entry {
                key: p.key,
                color: p.color,
                depth: p.depth,
                miss: p.miss,
                src,
            };
            self.cache.push(batch[p.src as usize]);
            self.stats.replaced += 1;
        } else {
            self.stats.discarded += 1;
        }
    }

    /// Drops the cached samples no entry points at, keeping arrival order.
    fn compact(&mut self) {
        let mut owner = vec![NONE; self.cache.len()];
        for (slot, e) in self.entries.iter().enumerate() {
            owner[e.src as usize] = slot as u32;
        }
        let mut n = 0;
        for (i, &slot) in owner.iter().enumerate() {
            if slot != NONE {
                self.cache[n] = self.cache[i];
                self.entries[slot as usize].src = n as u32;
                n += 1;
            }
        }
        self.cache.truncate(n);
    }

    /// How many off-frame samples to remember (if parking at all): about a
    /// frame's worth.
    fn park_limit(&self) -> usize {
        if !self.park {
            return 0;
        }
        let pixels = u64::from(self.viewport.width) * u64::from(self.viewport.height);
        usize::try_from(pixels).unwrap_or(usize::MAX).max(MIN_PARKED)
    }

    /// Changes the view: the body of [`Driver::set_view`].
    ///
    /// The turn is measured from the view the cache was last reprojected for
    /// (the current one), so a long motion in small steps keeps its cache,
    /// as a continuous drag in the paper's drivers does. Collisions between
    /// reprojected samples count like those of new samples (their losers leave
    /// the cache); samples that leave the frame are not counted as `outside`,
    /// since they stay cached.
    pub(crate) fn set_view(&mut self, viewport: Viewport) {
        if viewport == self.viewport {
            return;
        }
        let (a, b) = (
            self.viewport.view.direction.normalize_or_zero(),
            viewport.view.direction.normalize_or_zero(),
        );
        let turn = a.cross(b).length().atan2(a.dot(b)).to_degrees();
        self.compact();
        self.viewport = viewport;
        self.projector = Projector::new(&self.viewport);
        self.index.reset(self.viewport.width, self.viewport.height);
        self.entries.clear();
        // Visible samples first, so the most recently seen are parked first
        // when the limit bites.
        let mut old = std::mem::take(&mut self.cache);
        old.append(&mut self.parked);
        if turn > CACHE_DROP_DEGREES {
            if !old.is_empty() {
                self.stats.cache_drops += 1;
            }
            return;
        }
        for chunk in old.chunks(CHUNK) {
            self.insert_batch(chunk, true);
        }
    }

    /// Forgets every sample; the counters of what was seen stay.
    pub(crate) fn clear(&mut self) {
        self.entries.clear();
        self.cache.clear();
        self.parked.clear();
        self.index.reset(self.viewport.width, self.viewport.height);
    }

    /// The originals of the kept samples, in the order they won their pixels.
    #[cfg(test)]
    pub(crate) fn kept_samples(&mut self) -> Vec<Sample> {
        self.compact();
        self.cache.clone()
    }
}

/// A quadtree node in 4 bytes: [`NONE`] for an empty leaf, a sample slot for
/// a full leaf, or [`BRANCH`] plus the index of the first of four consecutive
/// children (top-left, top-right, bottom-left, bottom-right).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Node(u32);

/// The tag bit of a branch node.
const BRANCH: u32 = 1 << 31;

impl Node {
    const EMPTY: Node = Node(NONE);

    #[inline]
    fn is_branch(self) -> bool {
        self.0 & BRANCH != 0 && self.0 != NONE
    }

    #[inline]
    fn children(self) -> usize {
        (self.0 & !BRANCH) as usize
    }
}

/// Spreads the bits of `v` to the even bit positions.
#[inline]
fn spread(v: u32) -> u64 {
    let mut x = u64::from(v);
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// The image-plane quadtree: an arena of 4-byte nodes with u32 links.
///
/// The root is the smallest power-of-two square holding the frame, anchored
/// at its top-left corner, so every node is a square block of pixels whatever
/// the frame's aspect (parts off the frame are never filled nor drawn), a
/// node at depth `levels` is a single pixel, and a pixel's path from the root
/// is its Morton code: quadrant `(y bit << 1) | x bit` of the column and row,
/// most significant first.
#[derive(Clone, Debug, Default)]
pub(crate) struct Tree {
    nodes: Vec<Node>,
    /// Depth of the single-pixel nodes.
    levels: u32,
}

impl PixelIndex for Tree {
    fn reset(&mut self, width: u32, height: u32) {
        self.nodes.clear();
        self.nodes.push(Node::EMPTY);
        let side = width.max(height);
        self.levels = if side <= 1 { 0 } else { 32 - (side - 1).leading_zeros() };
    }

    #[inline]
    fn key(&self, col: u32, row: u32) -> u64 {
        spread(col) | (spread(row) << 1)
    }

    fn key_bits(&self) -> u32 {
        2 * self.levels
    }

    #[inline]
    fn find(&mut self, entries: &[Entry], key: u64) -> Spot {
        let mut node = 0usize;
        // Twice the current node's height above the pixels: its children's
        // quadrant is at key bits shift - 2 and shift - 1.
        let mut shift = 2 * self.levels;
        loop {
            let n = self.nodes[node];
            if n.is_branch() {
                shift -= 2;
                node = n.children() + ((key >> shift) & 3) as usize;
                continue;
            }
            if n == Node::EMPTY {
                return Spot::Free(node);
            }
            let old = entries[n.0 as usize].key;
            if old == key {
                return Spot::Taken(n.0);
            }
            // Two pixels in one leaf: the leaf is bigger than a pixel (keys
            // differ below here), so push its sample one level down and go on
            // (the new sample may meet it again below).
            let first = self.nodes.len();
            debug_assert!(first + 4 < BRANCH as usize, "quadtree arena overflow");
            self.nodes.extend([Node::EMPTY; 4]);
            self.nodes[first + ((old >> (shift - 2)) & 3) as usize] = n;
            self.nodes[node] = Node(BRANCH | first as u32);
        }
    }

    #[inline]
    fn fill(&mut self, at: usize, slot: u32) {
        self.nodes[at] = Node(slot);
    }
}

/// The CPU quadtree display driver of the paper's section 2.4.3.
///
/// Each leaf of an image-plane quadtree holds at most one sample; a leaf is
/// split when a second sample falls in it, down to single pixels, where the
/// sample whose ray passed closer to the eye wins. Rendering fills each leaf's
/// square with its sample's color, and each empty leaf with the average of
/// its non-empty siblings (a sibling with children standing in with the
/// average of its own children, recursively).
#[derive(Clone, Debug)]
pub struct QuadtreeDriver {
    store: Store<Tree>,
    /// The render's traversal stack, kept to avoid reallocating.
    stack: Vec<Frame>,
}

/// A branch being drawn: its square (corner and log2 of the side), the next
/// child to visit and the sum of its non-empty children's colors so far.
#[derive(Clone, Copy, Debug)]
struct Frame {
    node: u32,
    x0: u32,
    y0: u32,
    lg: u32,
    next: u32,
    sum: Vec3,
    count: u32,
}

impl Frame {
    fn new(node: u32, x0: u32, y0: u32, lg: u32) -> Frame {
        Frame {
            node,
            x0,
            y0,
            lg,
            next: 0,
            sum: Vec3::ZERO,
            count: 0,
        }
    }
}

impl QuadtreeDriver {
    /// An empty driver for `viewport`.
    pub fn new(viewport: Viewport) -> QuadtreeDriver {
        QuadtreeDriver {
            store: Store::new(viewport, Tree::default(), true),
            stack: Vec::new(),
        }
    }

    /// Nodes in the quadtree (for memory and benchmark reports).
    pub fn node_count(&self) -> usize {
        self.store.index.nodes.len()
    }

    /// Samples held in the local cache, on and off the frame.
    pub fn cached(&self) -> usize {
        self.store.cached()
    }
}

impl Driver for QuadtreeDriver {
    fn name(&self) -> &'static str {
        "quadtree"
    }

    fn add(&mut self, samples: &[Sample]) {
        self.store.add(samples);
    }

    fn set_view(&mut self, viewport: Viewport) {
        self.store.set_view(viewport);
    }

    fn viewport(&self) -> &Viewport {
        &self.store.viewport
    }

    fn render(&mut self) -> Picture {
        let (w, h) = (self.store.viewport.width, self.store.viewport.height);
        let width = w as usize;
        let mut pixels = vec![Vec3::ZERO; width * h as usize];
        let nodes = &self.store.index.nodes;
        let entries = &self.store.entries;
        let color = |slot: u32| Vec3::from_array(entries[slot as usize].color);
        let fill = |pixels: &mut [Vec3], x0: u32, y0: u32, side: u32, color: Vec3| {
            // Clipped to the frame: the root square may stick out of it.
            let (x1, y1) = ((x0 + side).min(w) as usize, (y0 + side).min(h) as usize);
            for row in y0 as usize..y1 {
                pixels[row * width + x0 as usize..row * width + x1].fill(color);
            }
        };
        let root = nodes.first().copied().unwrap_or(Node::EMPTY);
        if !root.is_branch() {
            if root != Node::EMPTY {
                fill(&mut pixels, 0, 0, 1 << self.store.index.levels, color(root.0));
            }
            return Picture {
                width,
                height: h as usize,
                pixels,
            };
        }
        // One depth-first walk: full leaves are drawn on the way down and
        // summed into their parent; a branch, once all its children are
        // summed, draws its empty children with the mean and passes the mean
        // up as its own color. Every branch holds a sample somewhere (it was
        // made by splitting a full leaf, and samples are only ever replaced),
        // so the mean is over at least one child.
        let stack = &mut self.stack;
        stack.clear();
        stack.push(Frame::new(0, 0, 0, self.store.index.levels));
        while let Some(top) = stack.last_mut() {
            let first = nodes[top.node as usize].children();
            let half = 1u32 << (top.lg - 1);
            if top.next < 4 {
                let q = top.next;
                top.next += 1;
                let (x, y) = (top.x0 + (q & 1) * half, top.y0 + (q >> 1) * half);
                let c = nodes[first + q as usize];
                if c.is_branch() {
                    let (child, lg) = ((first + q as usize) as u32, top.lg - 1);
                    stack.push(Frame::new(child, x, y, lg));
                } else if c != Node::EMPTY {
                    let k = color(c.0);
                    top.sum += k;
                    top.count += 1;
                    fill(&mut pixels, x, y, half, k);
                }
                continue;
            }
            let done = *top;
            stack.pop();
            let mean = done.sum / done.count.max(1) as f32;
            for q in 0..4u32 {
                let (x, y) = (done.x0 + (q & 1) * half, done.y0 + (q >> 1) * half);
                if nodes[first + q as usize] == Node::EMPTY && x < w && y < h {
                    fill(&mut pixels, x, y, half, mean);
                }
            }
            if let Some(parent) = stack.last_mut() {
                parent.sum += mean;
                parent.count += 1;
            }
        }
        Picture {
            width,
            height: h as usize,
            pixels,
        }
    }

    fn stats(&self) -> DriverStats {
        self.store.stats()
    }

    fn clear(&mut self) {
        self.store.clear();
    }
}

/// Synthetic scenes and helpers shared by the quadtree and splat tests.
#[cfg(test)]
pub(crate) mod testkit {
    use glam::DVec3;
    use holodeck_protocol::{Picture, View};

    use crate::driver::{Driver, Viewport};
    use crate::sample::Sample;

    /// The perspective view of the tests: looking along +y, z up.
    pub(crate) const EYE_VIEW: &str = "-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45";

    /// A viewport from a view spec.
    pub(crate) fn viewport(spec: &str, width: u32, height: u32) -> Viewport {
        Viewport::new(View::parse(spec).unwrap(), width, height).unwrap()
    }

    /// A tiny deterministic generator (xorshift64*), so tests need no rand.
    pub(crate) struct Rng(pub(crate) u64);

    impl Rng {
        /// Uniform in [0, 1).
        pub(crate) fn next(&mut self) -> f64 {
            self.0 ^= self.0 >> 12;
            self.0 ^= self.0 << 25;
            self.0 ^= self.0 >> 27;
            (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
        }
    }

    /// The scene: the plane y - 0.3 x = 4, in front of the test eye.
    pub(crate) fn hit_plane(origin: DVec3, dir: DVec3) -> Option<DVec3> {
        let n = DVec3::new(-0.3, 1.0, 0.0);
        let denom = n.dot(dir);
        if denom <= 1e-9 {
            return None;
        }
        let t = (4.0 - n.dot(origin)) / denom;
        (t > 0.0).then(|| origin + dir * t)
    }

    /// The plane's radiance: smooth, strictly positive.
    pub(crate) fn plane_color(p: DVec3) -> [f32; 3] {
        [
            (0.5 + 0.4 * (2.0 * p.x).sin()) as f32,
            (0.5 + 0.4 * (1.5 * p.z).cos()) as f32,
            (0.3 + 0.2 * (p.x + p.z).sin()) as f32,
        ]
    }

    /// A sample of the plane seen through image point (x, y) of `view`, whose
    /// ray starts `offset` away from the eye (sideways) and passes through the
    /// same hit point: it reprojects to that image point and misses the eye
    /// by about `offset`.
    pub(crate) fn plane_sample(view: &View, x: f64, y: f64, offset: DVec3) -> Option<Sample> {
        let (eye, dir) = view.ray(x, y)?;
        let hit = hit_plane(eye, dir)?;
        let origin = eye + offset + dir;
        Some(Sample {
            origin,
            direction: (hit - origin).normalize(),
            hit: Some(hit),
            color: plane_color(hit),
        })
    }

    /// `n` samples of the plane at random image points with random small
    /// origin offsets (so miss distances differ).
    pub(crate) fn random_plane_samples(view: &View, n: usize, seed: u64) -> Vec<Sample> {
        let mut rng = Rng(seed | 1);
        let mut out = Vec::with_capacity(n);
        while out.len() < n {
            let (x, y) = (rng.next(), rng.next());
            let offset = DVec3::new(rng.next() - 0.5, 0.0, rng.next() - 0.5) * 0.2;
            if let Some(s) = plane_sample(view, x, y, offset) {
                out.push(s);
            }
        }
        out
    }

    /// The analytic picture: the plane's color through each pixel center.
    pub(crate) fn analytic(vp: &Viewport) -> Picture {
        let (w, h) = (vp.width as usize, vp.height as usize);
        let mut pixels = Vec::with_capacity(w * h);
        for row in 0..h {
            for col in 0..w {
                let (x, y) = ((col as f64 + 0.5) / w as f64, 1.0 - (row as f64 + 0.5) / h as f64);
                let c = vp
                    .view
                    .ray(x, y)
                    .and_then(|(o, d)| hit_plane(o, d))
                    .map_or([0.0; 3], plane_color);
                pixels.push(glam::Vec3::from_array(c));
            }
        }
        Picture {
            width: w,
            height: h,
            pixels,
        }
    }

    /// A sample on the exact image grid of a parallel view "-vtl -vp 0 0 0
    /// -vd 0 1 0 -vu 0 0 1 -vh W -vv H" drawn on W x H pixels: pixel column c
    /// starts at world x = c - W/2 and row r at world z = H/2 - r, so
    /// (`px`, `py`) in pixel units lands exactly where asked.
    pub(crate) fn grid_sample(w: u32, h: u32, px: f64, py: f64, depth: f64, miss: f64, color: [f32; 3]) -> Sample {
        let hit = DVec3::new(px - f64::from(w) / 2.0, depth, f64::from(h) / 2.0 - py);
        Sample {
            origin: DVec3::new(miss, 0.0, 0.0),
            direction: DVec3::Y,
            hit: Some(hit),
            color,
        }
    }

    /// The parallel view that [`grid_sample`] is exact for.
    pub(crate) fn grid_viewport(w: u32, h: u32) -> Viewport {
        viewport(&format!("-vtl -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh {w} -vv {h}"), w, h)
    }

    /// Times a driver on 1M plane samples at 1024x768: one batch, batches of
    /// 10,000, rendering (best of three) and a 5-degree turn; prints the
    /// numbers and the RMSE against the analytic image.
    pub(crate) fn time_driver(make: impl Fn(Viewport) -> Box<dyn Driver>) {
        use std::time::Instant;
        let vp = viewport(EYE_VIEW, 1024, 768);
        let samples = random_plane_samples(&vp.view, 1_000_000, 42);
        let truth = analytic(&vp);
        let n = samples.len() as f64;
        for round in 0..3 {
            let mut d = make(vp.clone());
            let t = Instant::now();
            d.add(&samples);
            let one = t.elapsed().as_secs_f64();
            let mut d = make(vp.clone());
            let t = Instant::now();
            for batch in samples.chunks(10_000) {
                d.add(batch);
            }
            let many = t.elapsed().as_secs_f64();
            let mut render = f64::INFINITY;
            let mut pic = None;
            for _ in 0..3 {
                let t = Instant::now();
                pic = Some(d.render());
                render = render.min(t.elapsed().as_secs_f64());
            }
            let kept = d.stats().kept;
            let t = Instant::now();
            d.set_view(viewport(&format!("{EYE_VIEW} -vd 0.0875 1 0"), 1024, 768));
            let turn = t.elapsed().as_secs_f64();
            println!(
                "{} round {round}: add {:.2} M/s in one batch, {:.2} M/s in batches of 10k; \
                 render {:.1} ms; {kept} kept; 5-degree reprojection {:.1} ms; RMSE {:.4}",
                d.name(),
                1e-6 * n / one,
                1e-6 * n / many,
                render * 1e3,
                turn * 1e3,
                pic.map_or(f64::NAN, |p| rmse(&p, &truth)),
            );
        }
    }

    /// Root-mean-square difference per channel.
    pub(crate) fn rmse(a: &Picture, b: &Picture) -> f64 {
        a.mse(b).unwrap().sqrt()
    }
}

#[cfg(test)]
mod tests {
    use super::testkit::*;
    use super::*;
    use crate::driver::{DriverError, MAX_VIEWPORT_PIXELS};
    use crate::splat::SplatDriver;
    use holodeck_protocol::View;
    use proptest::prelude::*;
    use std::collections::HashMap;

    fn px(p: &Picture, col: u32, row: u32) -> Vec3 {
        p.pixels[row as usize * p.width + col as usize]
    }

    fn rgb(c: Vec3) -> [f32; 3] {
        c.to_array()
    }

    /// The winner of each pixel by the closest-miss rule (first on ties), by
    /// brute force.
    fn winners(vp: &Viewport, samples: &[Sample]) -> HashMap<(u32, u32), Sample> {
        let eye = vp.view.position;
        let mut best: HashMap<(u32, u32), Sample> = HashMap::new();
        for s in samples.iter().filter(|s| s.is_finite()) {
            if let Some((c, r, _)) = vp.pixel(s.target(eye)) {
                let e = best.entry((c, r)).or_insert(*s);
                if s.miss_distance(eye) < e.miss_distance(eye) {
                    *e = *s;
                }
            }
        }
        best
    }

    #[test]
    fn renders_each_kept_sample_color_at_its_pixel() {
        let vp = viewport(EYE_VIEW, 128, 96);
        let samples = random_plane_samples(&vp.view, 30_000, 7);
        let mut d = QuadtreeDriver::new(vp.clone());
        d.add(&samples);
        let pic = d.render();
        let best = winners(&vp, &samples);
        assert_eq!(d.stats().kept, best.len() as u64);
        assert!(best.len() > 10_000, "most pixels have a sample: {}", best.len());
        for (&(c, r), s) in &best {
            assert_eq!(rgb(px(&pic, c, r)), s.color, "pixel {c},{r}");
        }
        let st = d.stats();
        assert_eq!(st.received, 30_000);
        assert_eq!(st.kept + st.replaced + st.discarded + st.outside, st.received);
        assert!(st.replaced > 0 && st.discarded > 0);
    }

    #[test]
    fn dense_samples_match_the_analytic_image() {
        let vp = viewport(EYE_VIEW, 256, 192);
        let truth = analytic(&vp);
        let mut dense = QuadtreeDriver::new(vp.clone());
        dense.add(&random_plane_samples(&vp.view, 2 * 256 * 192, 11));
        let dense_err = rmse(&dense.render(), &truth);
        let mut sparse = QuadtreeDriver::new(vp.clone());
        sparse.add(&random_plane_samples(&vp.view, 500, 11));
        let sparse_err = rmse(&sparse.render(), &truth);
        // A pixel spans about 0.018 world units on the plane, over which the
        // color changes by under 0.02: the dense image is that close.
        assert!(dense_err < 0.01, "dense RMSE {dense_err}");
        assert!(sparse_err > 2.0 * dense_err, "sparse {sparse_err} vs dense {dense_err}");
        assert!(sparse_err < 0.1, "sparse RMSE {sparse_err}");
    }

    #[test]
    fn sparse_samples_leave_no_black_pixels() {
        let vp = viewport(EYE_VIEW, 200, 150);
        let mut d = QuadtreeDriver::new(vp);
        d.add(&random_plane_samples(&d.viewport().view.clone(), 40, 3));
        assert_eq!(d.stats().kept, 40);
        let pic = d.render();
        assert!(pic.pixels.iter().all(|p| p.min_element() > 0.0));
    }

    #[test]
    fn leaf_boundary_samples_fill_exact_quadrants() {
        let vp = grid_viewport(4, 4);
        let (a, b) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let mut d = QuadtreeDriver::new(vp.clone());
        // (2, 2) is exactly the image center x = y = 0.5: it belongs to the
        // lower-right quadrant. (1, 1) is the corner of the upper-left one.
        d.add(&[
            grid_sample(4, 4, 2.0, 2.0, 5.0, 0.1, b),
            grid_sample(4, 4, 1.0, 1.0, 5.0, 0.1, a),
        ]);
        assert_eq!(vp.pixel(DVec3::new(0.0, 5.0, 0.0)).map(|p| (p.0, p.1)), Some((2, 2)));
        let pic = d.render();
        let mean = (Vec3::from(a) + Vec3::from(b)) / 2.0;
        for row in 0..4 {
            for col in 0..4 {
                let want = match (col >= 2, row >= 2) {
                    (false, false) => Vec3::from(a),
                    (true, true) => Vec3::from(b),
                    _ => mean,
                };
                assert_eq!(px(&pic, col, row), want, "{col},{row}");
            }
        }
        assert_eq!(d.node_count(), 5);
    }

    #[test]
    fn odd_frames_clip_the_power_of_two_root() {
        // A 3 x 3 frame sits in the top-left of a 4 x 4 root: the split is at
        // pixel 2, and the right and bottom quadrants are one pixel thick.
        let vp = grid_viewport(3, 3);
        let (a, b) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
        let mut d = QuadtreeDriver::new(vp);
        d.add(&[
            grid_sample(3, 3, 0.5, 0.5, 5.0, 0.1, a),
            grid_sample(3, 3, 2.5, 2.5, 5.0, 0.1, b),
        ]);
        let pic = d.render();
        let (a, b, ab) = (Vec3::from(a), Vec3::from(b), Vec3::new(0.5, 0.0, 0.5));
        let want = [[a, a, ab], [a, a, ab], [ab, ab, b]];
        for (row, line) in want.iter().enumerate() {
            for (col, w) in line.iter().enumerate() {
                assert_eq!(px(&pic, col as u32, row as u32), *w, "{col},{row}");
            }
        }
    }

    #[test]
    fn zero_sized_hand_built_viewports_take_nothing() {
        let vp = Viewport {
            view: View::parse(EYE_VIEW).unwrap(),
            width: 0,
            height: 5,
        };
        let mut d = QuadtreeDriver::new(vp.clone());
        let mut s = SplatDriver::new(vp.clone());
        let samples = random_plane_samples(&vp.view, 10, 1);
        d.add(&samples);
        s.add(&samples);
        assert_eq!((d.stats().outside, s.stats().outside), (10, 10));
        assert!(d.render().pixels.is_empty() && s.render().pixels.is_empty());
    }

    #[test]
    fn empty_leaves_average_siblings_recursively() {
        let vp = grid_viewport(4, 4);
        let (a, b, c) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        let mut d = QuadtreeDriver::new(vp);
        d.add(&[
            grid_sample(4, 4, 0.5, 0.5, 5.0, 0.1, a),
            grid_sample(4, 4, 1.5, 1.5, 5.0, 0.1, b),
            grid_sample(4, 4, 3.5, 3.5, 5.0, 0.1, c),
        ]);
        let pic = d.render();
        // The upper-left quadrant splits into pixels: a, b and two empty
        // pixels with their average; the empty quadrants get the average of
        // that branch's average and c.
        let ab = Vec3::new(0.5, 0.5, 0.0);
        let abc = Vec3::new(0.25, 0.25, 0.5);
        let want = [
            [Vec3::from(a), ab, abc, abc],
            [ab, Vec3::from(b), abc, abc],
            [abc, abc, Vec3::from(c), Vec3::from(c)],
            [abc, abc, Vec3::from(c), Vec3::from(c)],
        ];
        for (row, line) in want.iter().enumerate() {
            for (col, w) in line.iter().enumerate() {
                assert_eq!(px(&pic, col as u32, row as u32), *w, "{col},{row}");
            }
        }
    }

    #[test]
    fn samples_on_one_pixel_keep_the_closest_miss() {
        let vp = grid_viewport(8, 8);
        let mut d = QuadtreeDriver::new(vp);
        let misses = [0.5, 0.3, 0.4, 0.1, 0.2, 0.1, 0.7];
        let samples: Vec<Sample> = misses
            .iter()
            .enumerate()
            .map(|(i, &m)| grid_sample(8, 8, 3.25 + 0.1 * i as f64, 6.5, 5.0, m, [i as f32 + 1.0, 1.0, 1.0]))
            .collect();
        d.add(&samples);
        let st = d.stats();
        // 0.5 kept; 0.3 replaces; 0.4 loses; 0.1 replaces; 0.2 loses; the
        // second 0.1 ties and loses; 0.7 loses.
        assert_eq!((st.kept, st.replaced, st.discarded, st.multidepth), (1, 2, 4, 0));
        let pic = d.render();
        assert!(pic.pixels.iter().all(|&p| p == Vec3::new(4.0, 1.0, 1.0)));
    }

    #[test]
    fn multidepth_counts_depths_more_than_two_percent_apart() {
        let vp = grid_viewport(8, 8);
        let mut d = QuadtreeDriver::new(vp.clone());
        // Parallel-view depth is the distance along the view: the hit's y.
        d.add(&[grid_sample(8, 8, 1.5, 1.5, 1.0, 0.2, [1.0; 3])]);
        d.add(&[grid_sample(8, 8, 1.5, 1.5, 2.0, 0.1, [2.0; 3])]);
        assert_eq!((d.stats().multidepth, d.stats().replaced), (1, 1));
        let mut d = QuadtreeDriver::new(vp);
        d.add(&[
            grid_sample(8, 8, 1.5, 1.5, 1.0, 0.2, [1.0; 3]),
            grid_sample(8, 8, 1.5, 1.5, 1.01, 0.3, [2.0; 3]),
        ]);
        assert_eq!((d.stats().multidepth, d.stats().discarded), (0, 1));
    }

    #[test]
    fn nonfinite_samples_are_rejected_and_counted() {
        let vp = grid_viewport(8, 8);
        let good = grid_sample(8, 8, 1.5, 1.5, 1.0, 0.2, [1.0; 3]);
        let mut bad = Vec::new();
        for f in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
            bad.push(Sample {
                origin: DVec3::new(f, 0.0, 0.0),
                ..good
            });
            bad.push(Sample {
                direction: DVec3::new(0.0, f, 0.0),
                ..good
            });
            bad.push(Sample {
                hit: Some(DVec3::new(0.0, 0.0, f)),
                ..good
            });
            bad.push(Sample {
                color: [1.0, f as f32, 1.0],
                ..good
            });
        }
        let mut d = QuadtreeDriver::new(vp);
        d.add(&bad);
        d.add(&[good]);
        let st = d.stats();
        assert_eq!((st.received, st.rejected_nonfinite, st.kept), (13, 12, 1));
        assert!(d.render().pixels.iter().all(|&p| p == Vec3::ONE));
    }

    #[test]
    fn no_samples_render_black() {
        let mut d = QuadtreeDriver::new(viewport(EYE_VIEW, 33, 17));
        let pic = d.render();
        assert_eq!((pic.width, pic.height, pic.pixels.len()), (33, 17, 33 * 17));
        assert!(pic.pixels.iter().all(|&p| p == Vec3::ZERO));
        assert_eq!(d.stats(), DriverStats::default());
        assert_eq!(d.name(), "quadtree");
    }

    #[test]
    fn one_pixel_viewport_keeps_the_best_sample() {
        let vp = viewport(EYE_VIEW, 1, 1);
        let mut d = QuadtreeDriver::new(vp.clone());
        let samples = random_plane_samples(&vp.view, 100, 5);
        d.add(&samples);
        let best = winners(&vp, &samples);
        assert_eq!(d.stats().kept, 1);
        assert_eq!(d.stats().replaced + d.stats().discarded, 99);
        assert_eq!(rgb(d.render().pixels[0]), best[&(0, 0)].color);
    }

    #[test]
    fn oversized_and_empty_frames_are_refused() {
        let view = View::parse(EYE_VIEW).unwrap();
        assert!(matches!(
            Viewport::new(view.clone(), 16384, 16384),
            Err(DriverError::FrameSize { .. })
        ));
        assert!(Viewport::new(view.clone(), 0, 10).is_err());
        assert!(Viewport::new(view, 8192, 8192).is_ok());
        assert_eq!(MAX_VIEWPORT_PIXELS, 8192 * 8192);
    }

    #[test]
    fn thin_frames_subdivide_along_one_axis() {
        for (w, h) in [(1, 37), (53, 1), (3, 2)] {
            let vp = grid_viewport(w, h);
            let mut d = QuadtreeDriver::new(vp.clone());
            let mut samples = Vec::new();
            for col in 0..w {
                for row in 0..h {
                    let color = [col as f32 + 1.0, row as f32 + 1.0, 1.0];
                    samples.push(grid_sample(w, h, col as f64 + 0.5, row as f64 + 0.5, 3.0, 0.1, color));
                }
            }
            d.add(&samples);
            assert_eq!(d.stats().kept, u64::from(w * h));
            let pic = d.render();
            for col in 0..w {
                for row in 0..h {
                    assert_eq!(px(&pic, col, row), Vec3::new(col as f32 + 1.0, row as f32 + 1.0, 1.0));
                }
            }
        }
    }

    #[test]
    fn outside_and_behind_samples_are_counted() {
        let vp = viewport(EYE_VIEW, 64, 48);
        let mut d = QuadtreeDriver::new(vp);
        let at = |hit: DVec3| Sample {
            origin: DVec3::ZERO,
            direction: hit.normalize(),
            hit: Some(hit),
            color: [1.0; 3],
        };
        // Behind the eye, far to the side, and exactly at the eye.
        d.add(&[at(DVec3::new(0.0, -3.0, 0.0)), at(DVec3::new(10.0, 1.0, 0.0))]);
        d.add(&[Sample {
            hit: Some(DVec3::ZERO),
            ..at(DVec3::Y)
        }]);
        assert_eq!((d.stats().outside, d.stats().kept), (3, 0));
        assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
    }

    #[test]
    fn escaped_rays_stay_put_when_the_eye_moves() {
        let vp = viewport(EYE_VIEW, 64, 48);
        let mut d = QuadtreeDriver::new(vp.clone());
        let (_, dir) = vp.view.ray(0.25, 0.75).unwrap();
        d.add(&[Sample {
            origin: DVec3::new(0.5, 0.0, 0.0),
            direction: dir,
            hit: None,
            color: [0.5, 0.25, 1.0],
        }]);
        let moved = viewport(&format!("{EYE_VIEW} -vp 3 -2 1"), 64, 48);
        d.set_view(moved);
        assert_eq!(d.stats().kept, 1);
        let pic = d.render();
        assert!(pic.pixels.iter().all(|&p| p == Vec3::new(0.5, 0.25, 1.0)));
        assert_eq!(d.stats().cache_drops, 0);
    }

    /// A grid of plane samples every 6 pixels (so that no small turn makes two
    /// share a pixel).
    fn spaced_samples(vp: &Viewport) -> Vec<Sample> {
        let mut out = Vec::new();
        for row in (3..vp.height).step_by(6) {
            for col in (3..vp.width).step_by(6) {
                let (x, y) = (
                    (f64::from(col) + 0.5) / f64::from(vp.width),
                    1.0 - (f64::from(row) + 0.5) / f64::from(vp.height),
                );
                out.extend(plane_sample(&vp.view, x, y, DVec3::new(0.01, 0.0, 0.0)));
            }
        }
        out
    }

    fn turned(degrees: f64) -> Viewport {
        let (s, c) = degrees.to_radians().sin_cos();
        viewport(&format!("{EYE_VIEW} -vd {s} {c} 0"), 160, 120)
    }

    #[test]
    fn a_large_turn_drops_the_cache() {
        let vp = turned(0.0);
        let mut d = QuadtreeDriver::new(vp.clone());
        d.add(&spaced_samples(&vp));
        assert!(d.stats().kept > 400);
        d.set_view(turned(30.0));
        assert_eq!((d.stats().cache_drops, d.stats().kept, d.cached()), (1, 0, 0));
        assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
        // Nothing left to drop: turning again counts nothing.
        d.set_view(turned(-30.0));
        assert_eq!(d.stats().cache_drops, 1);
    }

    #[test]
    fn a_small_turn_reprojects_and_turning_back_restores() {
        let vp = turned(0.0);
        let samples = spaced_samples(&vp);
        let mut d = QuadtreeDriver::new(vp.clone());
        d.add(&samples);
        let before = d.render();
        let kept = d.stats().kept;
        assert_eq!(kept, samples.len() as u64);
        let five = turned(5.0);
        let still_in = samples
            .iter()
            .filter(|s| five.pixel(s.target(five.view.position)).is_some())
            .count() as u64;
        assert!(still_in < kept && still_in > kept / 2, "{still_in} of {kept}");
        d.set_view(five.clone());
        let st = d.stats();
        assert_eq!((st.kept, st.cache_drops, st.discarded), (still_in, 0, 0));
        assert_eq!(d.cached() as u64, kept);
        let pic = d.render();
        for (&(c, r), s) in &winners(&five, &samples) {
            assert_eq!(rgb(px(&pic, c, r)), s.color);
        }
        // Turns are measured step by step: five of 5 degrees drop nothing,
        // and the way back restores the same picture from parked samples.
        for step in [10.0, 15.0, 20.0, 25.0, 20.0, 10.0] {
            d.set_view(turned(step));
        }
        assert_eq!((d.stats().cache_drops, d.cached() as u64), (0, kept));
        d.set_view(vp.clone());
        assert_eq!(d.stats().kept, kept);
        assert_eq!(d.render(), before);
    }

    #[test]
    fn a_new_frame_size_rebuilds() {
        // Only pixel winners are cached, so a larger frame shows the samples
        // the smaller one kept, each on its own (finer) pixel.
        let vp = viewport(EYE_VIEW, 64, 48);
        let samples = random_plane_samples(&vp.view, 3000, 9);
        let mut d = QuadtreeDriver::new(vp);
        d.add(&samples);
        let cached = d.store.kept_samples();
        assert!(cached.len() < 3000 && cached.len() > 1500, "{}", cached.len());
        let big = viewport(EYE_VIEW, 256, 192);
        d.set_view(big.clone());
        let mut fresh = QuadtreeDriver::new(big.clone());
        fresh.add(&cached);
        assert_eq!(d.stats().kept, fresh.stats().kept);
        let pic = d.render();
        assert_eq!((pic.width, pic.height), (256, 192));
        assert_eq!(pic, fresh.render());
        for (&(c, r), s) in &winners(&big, &cached) {
            assert_eq!(rgb(px(&pic, c, r)), s.color);
        }
        assert_eq!(d.viewport(), &big);
        // And back down: the collisions at the coarser size count again.
        let discarded = d.stats().discarded;
        d.set_view(viewport(EYE_VIEW, 16, 12));
        assert_eq!(d.stats().kept, winners(d.viewport(), &cached).len() as u64);
        assert!(d.stats().discarded + d.stats().replaced > discarded);
    }

    #[test]
    fn every_view_type_draws_without_gaps() {
        let specs = [
            "-vta -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 180 -vv 180",
            "-vta -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 360 -vv 360",
            "-vth -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 180 -vv 180",
            "-vtl -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 3 -vv 2",
            "-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 90 -vv 60 -vs 0.3 -vl -0.2",
            // The eye is behind the plane here, looking away from it: nothing.
            "-vtv -vp 0 10 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45",
        ];
        for spec in specs {
            let vp = viewport(spec, 48, 40);
            let samples: Vec<Sample> = random_plane_samples(&View::parse(EYE_VIEW).unwrap(), 2000, 13);
            let mut d = QuadtreeDriver::new(vp.clone());
            d.add(&samples);
            let best = winners(&vp, &samples);
            assert_eq!(d.stats().kept, best.len() as u64, "{spec}");
            let pic = d.render();
            for (&(c, r), s) in &best {
                assert_eq!(rgb(px(&pic, c, r)), s.color, "{spec}");
            }
            assert_eq!(
                pic.pixels.iter().all(|p| p.min_element() > 0.0),
                !best.is_empty(),
                "{spec}"
            );
        }
    }

    #[test]
    fn clear_forgets_samples_but_not_counts() {
        let vp = viewport(EYE_VIEW, 64, 48);
        let mut d = QuadtreeDriver::new(vp.clone());
        d.add(&random_plane_samples(&vp.view, 100, 1));
        d.clear();
        assert_eq!((d.stats().kept, d.stats().received, d.cached()), (0, 100, 0));
        assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
        d.add(&random_plane_samples(&vp.view, 1, 2));
        assert_eq!(d.stats().kept, 1);
    }

    /// Random samples on the exact grid of a 16 x 12 parallel view, some off
    /// the frame, some sharing pixels, all with positive colors.
    fn grid_samples() -> impl Strategy<Value = Vec<Sample>> {
        prop::collection::vec(
            (
                -2.0f64..18.0,
                -2.0f64..14.0,
                1.0f64..3.0,
                0.0f64..1.0,
                0.01f32..4.0,
                0.01f32..4.0,
            ),
            0..300,
        )
        .prop_map(|v| {
            v.into_iter()
                .map(|(x, y, depth, miss, r, g)| grid_sample(16, 12, x, y, depth, miss, [r, g, 0.5]))
                .collect()
        })
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(128))]

        #[test]
        fn projector_matches_viewport_pixel(
            kind in 0usize..4,
            (h, v) in (1.0f64..179.0, 1.0f64..179.0),
            (dx, dz, sh, li) in (-1.0f64..1.0, -1.0f64..1.0, -0.5f64..0.5, -0.5f64..0.5),
            p in prop::array::uniform3(-10.0f64..10.0),
            (w, hh) in (1u32..300, 1u32..300),
        ) {
            let t = ["-vtv", "-vta", "-vth", "-vtl"][kind];
            let spec = format!("{t} -vp 0.5 -1 0.25 -vd {dx} 1 {dz} -vu 0 0 1 -vh {h} -vv {v} -vs {sh} -vl {li}");
            let vp = viewport(&spec, w, hh);
            let p = DVec3::from_array(p);
            prop_assert_eq!(Projector::new(&vp).pixel(p), vp.pixel(p));
        }

        #[test]
        fn batches_render_like_one_insertion(
            samples in grid_samples(),
            cuts in prop::collection::vec(0usize..300, 0..8),
        ) {
            let vp = grid_viewport(16, 12);
            let mut whole = QuadtreeDriver::new(vp.clone());
            whole.add(&samples);
            let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c.min(samples.len())).collect();
            cuts.push(0);
            cuts.push(samples.len());
            cuts.sort_unstable();
            let mut parts = QuadtreeDriver::new(vp);
            for pair in cuts.windows(2) {
                parts.add(&samples[pair[0]..pair[1]]);
            }
            prop_assert_eq!(whole.stats(), parts.stats());
            prop_assert_eq!(whole.render(), parts.render());
        }

        #[test]
        fn kept_samples_show_and_nothing_is_black(samples in grid_samples()) {
            let vp = grid_viewport(16, 12);
            let mut d = QuadtreeDriver::new(vp.clone());
            d.add(&samples);
            let best = winners(&vp, &samples);
            let st = d.stats();
            prop_assert_eq!(st.kept, best.len() as u64);
            prop_assert_eq!(st.kept + st.replaced + st.discarded + st.outside, st.received);
            let pic = d.render();
            for (&(c, r), s) in &best {
                prop_assert_eq!(rgb(px(&pic, c, r)), s.color);
            }
            prop_assert_eq!(pic.pixels.iter().all(|p| p.min_element() > 0.0), !best.is_empty());
            prop_assert_eq!(pic.pixels.iter().all(|&p| p == Vec3::ZERO), best.is_empty());
        }

        #[test]
        fn quadtree_agrees_with_splat_where_splat_has_samples(samples in grid_samples()) {
            let vp = grid_viewport(16, 12);
            let mut q = QuadtreeDriver::new(vp.clone());
            let mut s = SplatDriver::new(vp);
            q.add(&samples);
            s.add(&samples);
            prop_assert_eq!(q.stats(), s.stats());
            let (qp, sp) = (q.render(), s.render());
            for (a, b) in qp.pixels.iter().zip(&sp.pixels) {
                if *b != Vec3::ZERO {
                    prop_assert_eq!(a, b);
                }
            }
        }
    }

    /// Release-mode timing: `cargo test --release -p holodeck-display --lib
    /// quadtree -- --ignored --nocapture --test-threads=1`.
    #[test]
    #[ignore]
    fn timing_quadtree_one_million_samples_at_1024x768() {
        time_driver(|vp| Box::new(QuadtreeDriver::new(vp)));
    }
}
