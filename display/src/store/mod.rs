//! The sample store every driver shares: one running [`Estimate`] per pixel
//! of the current view, built from every ray that lands there, and kept
//! across view changes by reprojecting the estimates themselves.
//!
//! Invariants:
//! * Memory is bounded by the frame, not by the rays: at most one estimate
//!   per pixel, plus at most [`Store::park_limit`] estimates parked off the
//!   frame, plus fixed scratch for one batch.
//! * A ray joins the estimate of the pixel it reprojects to only if it hit
//!   the estimate's surface (see [`estimate`]); counters account for every
//!   ray received: `received = kept + merged + replaced + discarded + outside
//!   + rejected_nonfinite + passed_over` until the first view change or clear.
//! * A view change turns each estimate into a world point (the centroid of
//!   its rays within the pixel, at their mean depth) carrying its sums,
//!   reprojects it, and merges estimates that meet on one pixel by the same
//!   depth rule. Nothing of the rays themselves is kept, and nothing snaps to
//!   pixel centers, so a long motion in small steps does not drift.
//! * Drivers only read: the index maps a pixel to a slot of [`Store::entries`],
//!   and [`Store::colors`] gives each slot's value.
//!
//! Speed comes from memory order: a batch is projected (on every core when
//! large), sorted by pixel key in the index's order, and inserted, so that
//! the rays of one pixel arrive together and consecutive pixels share the
//! index's cached path.

pub mod estimate;
pub mod index;
mod insert;
mod lanes;
mod lens;
mod radix;
mod spread;
#[cfg(test)]
mod tests;

use glam::{DVec3, Vec3};
use holodeck_protocol::{BeamKey, RayRecord};
use rayon::prelude::*;

pub use estimate::{luminance, Estimate, EstimatorOptions, Fit};
pub use index::{PixelIndex, Spot};
use radix::radix_sort;

use crate::project::Projector;
use crate::sample::Sample;
use crate::stats::{DriverStats, InsertTimes};
use crate::viewport::Viewport;

/// A view change that turns the view direction by more than this many degrees
/// drops the stored estimates: the paper's drivers "ignore their locally
/// cached samples and use only new ones" after such a rotation (section 3),
/// because samples taken for a very different direction are poor stand-ins
/// for the view-dependent shading of the new one.
pub const CACHE_DROP_DEGREES: f64 = 20.0;

/// Fewest off-frame estimates kept for a return to earlier views, so that
/// tiny frames still remember a useful surrounding.
const MIN_PARKED: usize = 1 << 16;

/// Rays projected and sorted together: large enough that sorting pays, small
/// enough that the scratch buffers stay a few megabytes.
pub(super) const CHUNK: usize = 1 << 18;

/// Batches at least this large are projected on every core.
const PARALLEL_MIN: usize = 1 << 14;

/// The part of a view's rays spread evenly over its pixels; the rest goes
/// where rays disagree (see [`Store::needs`]).
const EVEN_SHARE: f32 = 0.3;

/// Estimates sampled to find the frame's typical luminance (the firefly floor).
const FLOOR_SAMPLES: usize = 1 << 14;

/// One pixel's estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Entry {
    /// Its pixel, in the pixel index's own numbering ([`PixelIndex::key`]).
    pub key: u64,
    /// What the rays there say.
    pub estimate: Estimate,
}

/// An estimate off its pixel: its world point (or, for rays that escaped,
/// its direction), for reprojection and for parking off the frame.
#[derive(Clone, Copy, Debug)]
struct Aggregate {
    point: DVec3,
    escaped: bool,
    estimate: Estimate,
}

/// How far from a pixel (in pixels) [`crate::Driver::point_at`] looks for
/// a surface: a cursor between sparse samples still finds the one beside it.
pub const POINT_REACH: u32 = 4;

/// What a driver asks of its sample store, object-safe so that the
/// [`Driver`](crate::Driver) trait's provided methods delegate to whichever
/// store a driver holds (each [`Store`] is one).
pub trait SampleStore: Send {
    /// Adds rays ([`Store::add`]).
    fn add(&mut self, samples: &[Sample]);
    /// Changes the view ([`Store::set_view`]).
    fn set_view(&mut self, viewport: Viewport);
    /// The current viewport.
    fn viewport(&self) -> &Viewport;
    /// The counters.
    fn stats(&self) -> DriverStats;
    /// Forgets every ray.
    fn clear(&mut self);
    /// Heap bytes held.
    fn heap_bytes(&self) -> usize;
    /// Heap bytes held, by what holds them ([`Store::heap_parts`]).
    fn heap_parts(&self) -> HeapParts;
    /// The world point nearest pixel (`col`, `row`) within `reach` pixels.
    fn point_near(&self, col: u32, row: u32, reach: u32) -> Option<DVec3>;
    /// How many more rays each pixel wants ([`Store::needs`]).
    fn needs(&self, density: f32) -> Vec<f32>;
    /// The denoiser's guide ([`Store::guide`]).
    fn guide(&self) -> crate::denoise::Guide;
    /// Adds the stored rays of whole beams ([`Store::add_beams`]).
    fn add_beams(&mut self, decoder: &crate::SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]);
    /// Adds stored rays only to pixels that have no estimate yet
    /// ([`Store::add_beams_where_empty`]).
    fn add_beams_where_empty(&mut self, decoder: &crate::SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]);
    /// Adds samples only to pixels that have no estimate yet
    /// ([`Store::add_where_empty`]).
    fn add_where_empty(&mut self, samples: &[Sample]);
    /// Which pixels have no estimate ([`Store::empty_pixels`]).
    fn empty_pixels(&self) -> Vec<bool>;
    /// How long adding rays took, by stage ([`Store::insert_times`]).
    fn insert_times(&self) -> InsertTimes;
}

impl<I: PixelIndex + Sync + Send> SampleStore for Store<I> {
    fn add(&mut self, samples: &[Sample]) {
        Store::add(self, samples)
    }
    fn set_view(&mut self, viewport: Viewport) {
        Store::set_view(self, viewport)
    }
    fn viewport(&self) -> &Viewport {
        Store::viewport(self)
    }
    fn stats(&self) -> DriverStats {
        Store::stats(self)
    }
    fn clear(&mut self) {
        Store::clear(self)
    }
    fn heap_bytes(&self) -> usize {
        Store::heap_bytes(self)
    }
    fn heap_parts(&self) -> HeapParts {
        Store::heap_parts(self)
    }
    fn point_near(&self, col: u32, row: u32, reach: u32) -> Option<DVec3> {
        Store::point_near(self, col, row, reach)
    }
    fn needs(&self, density: f32) -> Vec<f32> {
        Store::needs(self, density)
    }
    fn guide(&self) -> crate::denoise::Guide {
        Store::guide(self)
    }
    fn add_beams(&mut self, decoder: &crate::SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]) {
        Store::add_beams(self, decoder, chunks)
    }
    fn add_beams_where_empty(&mut self, decoder: &crate::SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]) {
        Store::add_beams_where_empty(self, decoder, chunks)
    }
    fn add_where_empty(&mut self, samples: &[Sample]) {
        Store::add_where_empty(self, samples)
    }
    fn empty_pixels(&self) -> Vec<bool> {
        Store::empty_pixels(self)
    }
    fn insert_times(&self) -> InsertTimes {
        Store::insert_times(self)
    }
}

/// A store's heap bytes by what holds them ([`Store::heap_parts`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct HeapParts {
    /// The estimates on the frame, with their pixel keys (the vector's
    /// capacity: it grows by doubling as estimates arrive).
    pub estimates: usize,
    /// The estimates parked off the frame, with their world points.
    pub parked: usize,
    /// The pixel index, and each pixel's nearest depth.
    pub index: usize,
    /// Rays being added: the projected batches and the runs merged.
    pub batches: usize,
    /// A frame's values, the neighbourhoods fireflies are judged by and
    /// the light they spread.
    pub frame: usize,
}

impl HeapParts {
    /// Every part together.
    pub fn total(&self) -> usize {
        self.estimates + self.parked + self.index + self.batches + self.frame
    }
}

/// "No slot": in [`Store::moved_from`], an estimate that was not on the
/// frame before the last view change.
pub const NO_SLOT: u32 = u32::MAX;

/// In reprojection, the key of an estimate that leaves the frame.
const OFF: u64 = u64::MAX - 1;

/// In reprojection, the key of an estimate whose pixel has no ray in the
/// old view (dropped).
const GONE: u64 = u64::MAX;

/// A projected ray waiting in a batch: everything insertion needs, so that
/// inserting in index order never reads the rays out of order.
#[derive(Clone, Copy, Debug, Default)]
struct Pending {
    key: u64,
    color: [f32; 3],
    /// The ray's weight; negative when it passed too far from the eye for
    /// its hit point to be trusted to its sub-pixel (see [`Store::add`]).
    /// A ray that escaped weighs 1 and keeps here, negated, how far it
    /// passed from the eye (0: it passed through it, trusted).
    weight: f32,
    depth: f32,
    /// Where in the pixel, in 65536ths.
    at: [u16; 2],
}

impl Pending {
    /// A ray that lands on no pixel: `key` says why.
    const fn nowhere(key: u64) -> Pending {
        Pending {
            key,
            color: [0.0; 3],
            weight: 0.0,
            depth: 0.0,
            at: [0; 2],
        }
    }

    #[inline]
    fn trusted(&self) -> bool {
        self.weight > 0.0
    }

    /// The weight the ray joins its estimate with.
    #[inline]
    fn ray_weight(&self) -> f32 {
        if self.depth == f32::INFINITY {
            1.0
        } else {
            self.weight.abs()
        }
    }

    /// True when a surface of depth `near` in its pixel may hide it from
    /// the eye: an untrusted ray behind that surface, or an escaped ray
    /// that passed the eye farther than `footprint` (the width of a pixel
    /// at depth 1) times `near`, so that the surface may stand between the
    /// eye and the sky it saw.
    #[inline]
    fn hidden_by(&self, near: f32, tolerance: f32, footprint: f32) -> bool {
        if self.trusted() {
            false
        } else if self.depth == f32::INFINITY {
            near.is_finite() && -self.weight > near * footprint
        } else {
            self.depth > near * tolerance
        }
    }

    #[inline]
    fn at(&self) -> [f32; 2] {
        [
            (f32::from(self.at[0]) + 0.5) / 65536.0,
            (f32::from(self.at[1]) + 0.5) / 65536.0,
        ]
    }
}

/// The estimates of a driver, the index that finds them, the estimates parked
/// off the frame, the counters and the view.
#[derive(Clone, Debug)]
pub struct Store<I> {
    viewport: Viewport,
    /// The viewport at sub-pixel resolution: what the index and the
    /// projector work in.
    grid: Viewport,
    projector: Projector,
    options: EstimatorOptions,
    /// Sub-pixels follow the frame size (see [`EstimatorOptions::subpixels`]).
    auto_subpixels: bool,
    index: I,
    entries: Vec<Entry>,
    /// Estimates that a view change moved off the frame: kept (up to
    /// [`Store::park_limit`]) so that turning back brings them back, the
    /// paper's "movement outside the current view".
    parked: Vec<Aggregate>,
    park: bool,
    stats: DriverStats,
    /// Scratch for batches: the projected rays, and the radix sort's
    /// second buffer.
    projected: Vec<Pending>,
    spare: Vec<Pending>,
    /// The second batch buffer of [`Store::add_beams`], which projects one
    /// batch while it merges another.
    projected_next: Vec<Pending>,
    /// Per pixel of the frame, whether it takes no rays: those that had an
    /// estimate when [`Store::add_beams_where_empty`] was called (empty
    /// otherwise).
    sealed: Vec<bool>,
    /// The runs of a batch's rays on one estimate, and their merged estimates.
    runs: Vec<insert::Run>,
    merged: Vec<(Estimate, insert::Tally)>,
    /// How long adding rays took, by stage.
    times: InsertTimes,
    /// Per-frame buffers, kept so that drawing allocates nothing.
    frame: FrameScratch,
    /// The nearest depth of any estimate or ray in each pixel, by the
    /// index's block numbers ([`PixelIndex::block`]).
    near: Vec<f32>,
    /// For each slot made by the last view change, the slot its estimate
    /// had before (see [`Store::moved_from`]).
    moved_from: Vec<u32>,
}

/// What [`Store::update_colors`] works in: kept between frames.
#[derive(Clone, Debug, Default)]
struct FrameScratch {
    /// The value of each estimate, by slot.
    colors: Vec<Vec3>,
    /// Per estimate: its pixel, and its body's luminance sum and weight.
    bodies: Vec<(u32, f32, f32)>,
    /// Per pixel: luminance sum and weight, then their 3 x 3 box sums.
    sums: Vec<[f32; 2]>,
    across: Vec<[f32; 2]>,
    /// The light cut off each estimate's brightest ray, by slot.
    excess: Vec<[f32; 3]>,
    /// Estimates per pixel, for sharing a pixel's excess among them.
    per_pixel: Vec<u32>,
    /// Per pixel: the excess of its estimates (their mean), how widely it
    /// is spread, and the light it receives.
    pixel_excess: Vec<[f32; 3]>,
    pixel_wave: Vec<u8>,
    received: Vec<[f32; 3]>,
    spread: spread::Spread,
}

impl<I: PixelIndex + Sync> Store<I> {
    /// An empty store; `park` keeps estimates a view change moves off-frame.
    pub fn new(viewport: Viewport, mut index: I, park: bool, mut options: EstimatorOptions) -> Store<I> {
        let auto_subpixels = options.subpixels == 0;
        options.subpixels = subpixels_for(&viewport, options.subpixels);
        let grid = sub_grid(&viewport, options.subpixels);
        index.reset(grid.width, grid.height);
        let near = vec![f32::INFINITY; index.blocks(options.subpixels.trailing_zeros())];
        Store {
            projector: Projector::new(&grid),
            grid,
            viewport,
            options,
            auto_subpixels,
            index,
            entries: Vec::new(),
            parked: Vec::new(),
            park,
            stats: DriverStats::default(),
            projected: Vec::new(),
            spare: Vec::new(),
            projected_next: Vec::new(),
            sealed: Vec::new(),
            runs: Vec::new(),
            merged: Vec::new(),
            times: InsertTimes::default(),
            frame: FrameScratch::default(),
            near,
            moved_from: Vec::new(),
        }
    }

    /// The current viewport.
    pub fn viewport(&self) -> &Viewport {
        &self.viewport
    }

    /// Sub-pixels per pixel along each axis: the index and the estimates
    /// are at this finer resolution.
    pub fn subpixels(&self) -> u32 {
        self.options.subpixels
    }

    /// The pixel index (at sub-pixel resolution).
    pub fn index(&self) -> &I {
        &self.index
    }

    /// The estimates, by slot.
    pub fn entries(&self) -> &[Entry] {
        &self.entries
    }

    /// For each slot the last [`Store::set_view`] made, the slot the same
    /// estimate had before it, or [`NO_SLOT`] (it was parked off the
    /// frame). Slots made by later [`Store::add`] calls are past its end.
    /// Drivers that keep their own per-estimate state (the mesh) carry it
    /// across a view change with this instead of rebuilding it.
    pub fn moved_from(&self) -> &[u32] {
        &self.moved_from
    }

    /// The world point seen at pixel (`col`, `row`) of the frame: the
    /// surface of the estimate nearest the pixel's center, within `reach`
    /// pixels, or `None` where only sky or nothing is near (the point under
    /// a cursor, which motion keeps fixed on screen).
    pub fn point_near(&self, col: u32, row: u32, reach: u32) -> Option<DVec3> {
        let sub = f64::from(self.options.subpixels.max(1));
        let (cx, cy) = ((f64::from(col) + 0.5) * sub, (f64::from(row) + 0.5) * sub);
        let limit = (f64::from(reach) + 0.5) * sub;
        let mut best: Option<(f64, &Entry)> = None;
        for e in &self.entries {
            if !e.estimate.depth().is_finite() {
                continue;
            }
            let (c, r) = self.index.pixel(e.key);
            let [ax, ay] = e.estimate.centroid();
            let (dx, dy) = (f64::from(c) + f64::from(ax) - cx, f64::from(r) + f64::from(ay) - cy);
            if dx.abs() > limit || dy.abs() > limit {
                continue;
            }
            let d2 = dx * dx + dy * dy;
            if best.is_none_or(|(b, _)| d2 < b) {
                best = Some((d2, e));
            }
        }
        let (_, e) = best?;
        let (c, r) = self.index.pixel(e.key);
        let (origin, dir) = self.projector.ray(c, r, e.estimate.centroid())?;
        Some(origin + dir * f64::from(e.estimate.depth()))
    }

    /// How rays combine.
    pub fn options(&self) -> &EstimatorOptions {
        &self.options
    }

    /// Which pixels of the frame have no estimate, row-major, top row first.
    pub fn empty_pixels(&self) -> Vec<bool> {
        let (w, h) = (self.viewport.width as usize, self.viewport.height as usize);
        let sub = self.options.subpixels;
        let mut empty = vec![true; w * h];
        for e in &self.entries {
            let (col, row) = self.index.pixel(e.key);
            if let Some(p) = empty.get_mut((row / sub) as usize * w + (col / sub) as usize) {
                *p = false;
            }
        }
        empty
    }

    /// Counters, with `kept` as of now.
    pub fn stats(&self) -> DriverStats {
        DriverStats {
            kept: self.entries.len() as u64,
            ..self.stats
        }
    }

    /// Estimates held for reprojection: on the frame and parked off it.
    pub fn cached(&self) -> usize {
        self.entries.len() + self.parked.len()
    }

    /// Heap bytes held (estimates, index, scratch): bounded by the frame
    /// size whatever the number of rays received.
    pub fn heap_bytes(&self) -> usize {
        self.heap_parts().total()
    }

    /// Heap bytes held, by what holds them.
    pub fn heap_parts(&self) -> HeapParts {
        let f = &self.frame;
        HeapParts {
            estimates: self.entries.capacity() * std::mem::size_of::<Entry>(),
            parked: self.parked.capacity() * std::mem::size_of::<Aggregate>(),
            index: self.index.heap_bytes()
                + (self.near.capacity() + self.moved_from.capacity()) * std::mem::size_of::<f32>(),
            batches: (self.projected.capacity() + self.spare.capacity() + self.projected_next.capacity())
                * std::mem::size_of::<Pending>()
                + self.runs.capacity() * std::mem::size_of::<insert::Run>()
                + self.merged.capacity() * std::mem::size_of::<(Estimate, insert::Tally)>(),
            frame: f.colors.capacity() * std::mem::size_of::<Vec3>()
                + f.bodies.capacity() * std::mem::size_of::<(u32, f32, f32)>()
                + (f.sums.capacity() + f.across.capacity()) * std::mem::size_of::<[f32; 2]>()
                + f.excess.capacity() * std::mem::size_of::<[f32; 3]>()
                + f.per_pixel.capacity() * std::mem::size_of::<u32>()
                + (f.pixel_excess.capacity() + f.received.capacity()) * std::mem::size_of::<[f32; 3]>()
                + f.pixel_wave.capacity()
                + f.spread.heap_bytes(),
        }
    }

    /// Rebuilds the nearest depth of every pixel from the estimates.
    fn rebuild_near(&mut self) {
        let shift = self.options.subpixels.trailing_zeros();
        self.near.clear();
        self.near.resize(self.index.blocks(shift), f32::INFINITY);
        for e in &self.entries {
            let at = self.index.block(e.key, shift);
            self.near[at] = self.near[at].min(e.estimate.depth_range().0);
        }
    }

    /// Sub-pixels in the frame.
    fn pixel_count(&self) -> usize {
        self.grid.width as usize * self.grid.height as usize
    }

    /// How many off-frame estimates to remember (if parking at all): one
    /// per pixel of the frame.
    pub fn park_limit(&self) -> usize {
        if self.park {
            (self.viewport.width as usize * self.viewport.height as usize).max(MIN_PARKED)
        } else {
            0
        }
    }

    /// Changes the view: the body of [`crate::Driver::set_view`].
    ///
    /// The turn is measured from the view the estimates were last
    /// reprojected for (the current one), so a long motion in small steps
    /// keeps them, as a continuous drag in the paper's drivers does.
    /// Estimates that meet on one pixel merge by the depth rule; those that
    /// leave the frame are parked. Their rays become history, which the new
    /// view's rays overrule where they disagree (a surface that looks
    /// different from the new eye), so they are not weighed down for the move:
    /// on a diffuse surface they are as good as new.
    pub fn set_view(&mut self, viewport: Viewport) {
        if viewport == self.viewport {
            return;
        }
        let (a, b) = (
            self.viewport.view.direction.normalize_or_zero(),
            viewport.view.direction.normalize_or_zero(),
        );
        let turn = a.cross(b).length().atan2(a.dot(b)).to_degrees();
        if self.auto_subpixels {
            self.options.subpixels = subpixels_for(&viewport, 0);
        }
        let grid = sub_grid(&viewport, self.options.subpixels);
        let old = std::mem::replace(&mut self.projector, Projector::new(&grid));
        // Each estimate's pixel in the old view, before the index forgets it.
        let index = &self.index;
        let pixels: Vec<(u32, u32)> = if self.entries.len() >= PARALLEL_MIN {
            self.entries.par_iter().map(|e| index.pixel(e.key)).collect()
        } else {
            self.entries.iter().map(|e| index.pixel(e.key)).collect()
        };
        self.index.reset(grid.width, grid.height);
        self.viewport = viewport;
        self.grid = grid;
        if turn > CACHE_DROP_DEGREES {
            if !self.entries.is_empty() || !self.parked.is_empty() {
                self.stats.cache_drops += 1;
            }
            self.entries.clear();
            self.parked.clear();
            self.moved_from.clear();
        } else {
            self.reproject(&old, &pixels);
        }
        self.rebuild_near();
    }

    /// Moves every estimate into the current view: those on the old frame
    /// (`old` is its projector and `pixels` each slot's old pixel) and those
    /// parked off it. Each estimate's new key is found where it lies,
    /// without copying it, and the estimates are
    /// then moved once into their new slots in key order (estimates that
    /// meet on one pixel merge by the depth rule); those that leave the
    /// frame are parked, the most recently seen first.
    fn reproject(&mut self, old: &Projector, pixels: &[(u32, u32)]) {
        // Where an estimate's rays were: a world point, or for rays that
        // escaped, a direction.
        let point = |(col, row): (u32, u32), e: &Entry| -> Option<(DVec3, bool)> {
            let (origin, dir) = old.ray(col, row, e.estimate.centroid())?;
            let depth = e.estimate.depth();
            Some(if depth.is_finite() {
                (origin + dir * f64::from(depth), false)
            } else {
                (dir, true)
            })
        };
        let eye = self.viewport.view.position;
        let (projector, index) = (&self.projector, &self.index);
        // An estimate's key in the new view (it moves to its new place in
        // the pixel and its new depth), or OFF where it leaves the frame.
        let place = |point: DVec3, escaped: bool, estimate: &mut Estimate| -> u64 {
            let target = if escaped { eye + point * 1e9 } else { point };
            let Some((col, row, at, depth)) = projector.locate(target) else {
                return OFF;
            };
            estimate.move_to(at);
            if !escaped {
                estimate.move_to_depth(depth as f32);
            }
            index.key(col, row)
        };
        // What the old view's rays say becomes history for the new one.
        let on_frame = |(e, &at): (&mut Entry, &(u32, u32))| -> u64 {
            match point(at, e) {
                Some((p, escaped)) => {
                    e.estimate.settle();
                    place(p, escaped, &mut e.estimate)
                }
                None => GONE,
            }
        };
        let mut keys: Vec<u64> = if self.entries.len() >= PARALLEL_MIN {
            self.entries.par_iter_mut().zip(pixels).map(on_frame).collect()
        } else {
            self.entries.iter_mut().zip(pixels).map(on_frame).collect()
        };
        let parked_place = |a: &mut Aggregate| place(a.point, a.escaped, &mut a.estimate);
        if self.parked.len() >= PARALLEL_MIN {
            keys.par_extend(self.parked.par_iter_mut().map(parked_place));
        } else {
            keys.extend(self.parked.iter_mut().map(parked_place));
        }
        // Estimates on the frame, in key order (then in the order above:
        // the frame's by slot, then the parked).
        let mut order: Vec<(u64, u32)> = keys
            .iter()
            .enumerate()
            .filter(|(_, &k)| k < OFF)
            .map(|(i, &k)| (k, i as u32))
            .collect();
        radix_sort(&mut order, &mut Vec::new(), self.index.key_bits(), |p| p.0);
        // Those that left it, parked up to the limit in the same order.
        let limit = self.park_limit();
        let n = self.entries.len();
        let mut parked = Vec::new();
        for (i, _) in keys.iter().enumerate().filter(|(_, &k)| k == OFF) {
            if parked.len() >= limit {
                break;
            }
            if i < n {
                let e = &self.entries[i];
                if let Some((point, escaped)) = point(pixels[i], e) {
                    parked.push(Aggregate {
                        point,
                        escaped,
                        estimate: e.estimate,
                    });
                }
            } else {
                parked.push(self.parked[i - n]);
            }
        }
        let old_entries = std::mem::take(&mut self.entries);
        let old_parked = std::mem::replace(&mut self.parked, parked);
        self.entries.reserve(order.len());
        self.moved_from.clear();
        let tolerance = self.options.depth_tolerance;
        for (key, i) in order {
            let i = i as usize;
            let (incoming, from) = if i < n {
                (old_entries[i].estimate, i as u32)
            } else {
                (old_parked[i - n].estimate, NO_SLOT)
            };
            match self.index.find(&self.entries, key) {
                Spot::Free(at) => {
                    let slot = self.entries.len() as u32;
                    self.entries.push(Entry {
                        key,
                        estimate: incoming,
                    });
                    self.moved_from.push(from);
                    self.index.fill(at, slot);
                }
                Spot::Taken(slot) => {
                    let e = &mut self.entries[slot as usize].estimate;
                    let (near, far) = incoming.depth_range();
                    match e.fit(near, far, tolerance) {
                        Fit::Joins => e.merge(&incoming),
                        Fit::Nearer => {
                            *e = incoming;
                            self.moved_from[slot as usize] = from;
                        }
                        Fit::Behind => {}
                    }
                }
            }
        }
    }

    /// Forgets every estimate; the counters of what was seen stay.
    pub fn clear(&mut self) {
        self.entries.clear();
        self.moved_from.clear();
        self.parked.clear();
        self.index.reset(self.grid.width, self.grid.height);
        self.rebuild_near();
    }

    /// The typical luminance of the frame: the median of the estimates'
    /// mean luminance (over a fixed-size subset), the least any ray is
    /// judged against, so that a rare bright ray on a dark surface is not
    /// taken for a firefly.
    fn typical_luminance(&self) -> f32 {
        let step = self.entries.len().div_ceil(FLOOR_SAMPLES).max(1);
        let mut l: Vec<f32> = self
            .entries
            .iter()
            .step_by(step)
            .filter_map(|e| e.estimate.body_luminance())
            .collect();
        if l.is_empty() {
            return 0.0;
        }
        let mid = l.len() / 2;
        *l.select_nth_unstable_by(mid, f32::total_cmp).1
    }

    /// Each pixel's neighborhood luminance, into `frame.sums` (as [mean,
    /// weight]): the mean over the 3 x 3 pixels around it of the rays in
    /// the estimates' bodies (the brightest apart), what a pixel's brightest
    /// rays are judged against beside its own mean. Estimates of few rays
    /// (sub-pixels, early frames) are judged too.
    fn neighborhood_luminance(&mut self) {
        let (w, h) = (self.viewport.width as usize, self.viewport.height as usize);
        let (sub, index) = (self.options.subpixels, &self.index);
        let f = &mut self.frame;
        f.sums.clear();
        if w == 0 || h == 0 {
            return;
        }
        let body = |e: &Entry| {
            let (col, row) = index.pixel(e.key);
            let (sum, wt) = e.estimate.body_sums();
            ((row / sub) * w as u32 + col / sub, luminance(sum), wt)
        };
        f.bodies.clear();
        if self.entries.len() >= PARALLEL_MIN {
            f.bodies.par_extend(self.entries.par_iter().map(body));
        } else {
            f.bodies.extend(self.entries.iter().map(body));
        }
        f.sums.resize(w * h, [0.0; 2]);
        for &(at, l, wt) in &f.bodies {
            let s = &mut f.sums[at as usize];
            s[0] += l;
            s[1] += wt;
        }
        // Separable 3 x 3 box sums, rows in parallel.
        f.across.clear();
        f.across.resize(w * h, [0.0; 2]);
        let sums = &f.sums;
        f.across.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
            let line = &sums[row * w..(row + 1) * w];
            for (col, o) in out.iter_mut().enumerate() {
                for s in &line[col.saturating_sub(1)..=(col + 1).min(w - 1)] {
                    o[0] += s[0];
                    o[1] += s[1];
                }
            }
        });
        let across = &f.across;
        f.sums.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
            for o in out.iter_mut() {
                *o = [0.0; 2];
            }
            for r in row.saturating_sub(1)..=(row + 1).min(h - 1) {
                for (o, s) in out.iter_mut().zip(&across[r * w..(r + 1) * w]) {
                    o[0] += s[0];
                    o[1] += s[1];
                }
            }
            for o in out.iter_mut() {
                o[0] = if o[1] > 0.0 { o[0] / o[1] } else { 0.0 };
            }
        });
    }

    /// The denoiser's guide of the current frame: each pixel's nearest
    /// estimate's depth, the normals they make, and the variance of each
    /// pixel's mean from its rays.
    pub fn guide(&self) -> crate::denoise::Guide {
        let (w, h) = (self.viewport.width as usize, self.viewport.height as usize);
        let sub = self.options.subpixels;
        let mut depth = vec![f32::NAN; w * h];
        let mut sums = vec![(0.0f32, 0.0f32, 0.0f32, 0u32); w * h];
        for e in &self.entries {
            let (col, row) = self.index.pixel(e.key);
            let p = (row / sub) as usize * w + (col / sub) as usize;
            let d = e.estimate.depth();
            if depth[p].is_nan() || d < depth[p] {
                depth[p] = d;
            }
            let (wt, l, lsq, n) = e.estimate.noise();
            let s = &mut sums[p];
            *s = (s.0 + wt, s.1 + l, s.2 + lsq, s.3 + n);
        }
        crate::denoise::Guide::new(&self.viewport, depth, &sums)
    }

    /// How many more rays each pixel wants for `density` rays per pixel on
    /// average, spent where they reduce the error most, less the rays it
    /// holds. Most of a pixel's share is in proportion to how much its rays
    /// disagree (their standard deviation: Neyman's allocation, which
    /// minimizes the summed variance for a number of rays); a fixed part is
    /// spread evenly, so that dark, quiet regions still converge on screen.
    /// Pixels without two rays count as typical. Row-major, top row first.
    pub fn needs(&self, density: f32) -> Vec<f32> {
        let (w, h) = (self.viewport.width as usize, self.viewport.height as usize);
        let sub = self.options.subpixels;
        // Per pixel: weight, luminance sum, squared sum, rays.
        let mut acc = vec![(0.0f32, 0.0f32, 0.0f32, 0u32); w * h];
        for e in &self.entries {
            let (col, row) = self.index.pixel(e.key);
            let a = &mut acc[(row / sub) as usize * w + (col / sub) as usize];
            let (wt, l, lsq, n) = e.estimate.noise();
            *a = (a.0 + wt, a.1 + l, a.2 + lsq, a.3 + n);
        }
        let spread: Vec<Option<f32>> = acc
            .iter()
            .map(|&(wt, l, lsq, n)| {
                (n >= 2 && wt > 0.0).then(|| {
                    let mean = l / wt;
                    (lsq / wt - mean * mean).max(0.0).sqrt()
                })
            })
            .collect();
        let known: Vec<f32> = spread.iter().flatten().copied().collect();
        let typical = if known.is_empty() {
            1.0
        } else {
            known.iter().sum::<f32>() / known.len() as f32
        };
        let typical = if typical > 0.0 { typical } else { 1.0 };
        acc.iter()
            .zip(&spread)
            .map(|(a, s)| {
                let s = s.unwrap_or(typical);
                let share = EVEN_SHARE + (1.0 - EVEN_SHARE) * s / typical;
                (density * share - a.3 as f32).max(0.0)
            })
            .collect()
    }

    /// Computes the value of every estimate (see [`Store::colors`]): fireflies
    /// cut, and what was cut spread over the estimates around them
    /// ([`EstimatorOptions::firefly_spread`]); counts the estimates whose
    /// brightest ray was cut.
    pub fn update_colors(&mut self) {
        let ratio = self.options.firefly_ratio;
        let mut colors = std::mem::take(&mut self.frame.colors);
        let mut excess = std::mem::take(&mut self.frame.excess);
        colors.clear();
        colors.resize(self.entries.len(), Vec3::ZERO);
        excess.clear();
        excess.resize(self.entries.len(), [0.0; 3]);
        let reference: Option<f32> = ratio.is_finite().then(|| self.typical_luminance());
        if reference.is_some() {
            self.neighborhood_luminance();
        }
        let (near, bodies) = (&self.frame.sums, &self.frame.bodies);
        // The pixel of each estimate was found with its body.
        let value = |(((c, x), e), i): (((&mut Vec3, &mut [f32; 3]), &Entry), usize)| -> u64 {
            let (v, cut) = match reference {
                Some(floor) => e.estimate.value(ratio, near[bodies[i].0 as usize][0].max(floor)),
                None => e.estimate.value(f32::INFINITY, 0.0),
            };
            *c = Vec3::from_array(v);
            *x = cut;
            u64::from(cut != [0.0; 3])
        };
        self.stats.fireflies = if self.entries.len() >= PARALLEL_MIN {
            colors
                .par_iter_mut()
                .zip(excess.par_iter_mut())
                .zip(self.entries.par_iter())
                .zip(0..self.entries.len())
                .map(value)
                .sum()
        } else {
            colors
                .iter_mut()
                .zip(excess.iter_mut())
                .zip(self.entries.iter())
                .zip(0..)
                .map(value)
                .sum()
        };
        if let (Some(floor), true) = (reference, self.stats.fireflies > 0 && self.options.firefly_spread > 0.0) {
            self.spread_excess(&mut colors, &excess, floor);
        }
        self.frame.colors = colors;
        self.frame.excess = excess;
    }

    /// Adds to `colors` the light cut off the estimates' brightest rays
    /// (`excess`, by slot), spread over the pixels around each: every
    /// estimate of a pixel gets what the pixel receives, so a pixel (the
    /// mean of its estimates) keeps the light its neighborhood gave out.
    ///
    /// A pixel's excess goes over the square of radius
    /// [`EstimatorOptions::firefly_spread`], or of twice, four, eight or
    /// sixteen times that where it needs more room to stay under the
    /// firefly limit ([`EstimatorOptions::firefly_ratio`] times the typical
    /// luminance there, `floor` at least): a very bright firefly becomes a
    /// wide faint glow rather than a bright blot.
    fn spread_excess(&mut self, colors: &mut [Vec3], excess: &[[f32; 3]], floor: f32) {
        const WIDER: usize = 5;
        let (w, h) = (self.viewport.width as usize, self.viewport.height as usize);
        let f = &mut self.frame;
        f.per_pixel.clear();
        f.per_pixel.resize(w * h, 0);
        f.pixel_excess.clear();
        f.pixel_excess.resize(w * h, [0.0; 3]);
        for (x, b) in excess.iter().zip(&f.bodies) {
            let p = b.0 as usize;
            f.per_pixel[p] += 1;
            for (e, v) in f.pixel_excess[p].iter_mut().zip(x) {
                *e += v;
            }
        }
        let base = self.options.firefly_spread.round().max(1.0) as usize;
        let limit = self.options.firefly_ratio;
        // Each pixel's share of the light and the widest of the radii it
        // needs; each radius's senders' bounds (rows, then columns: first,
        // last), so that a radius few pixels need costs its reach, not a frame.
        let mut wave: [Option<[usize; 4]>; WIDER] = [None; WIDER];
        f.pixel_wave.clear();
        f.pixel_wave.resize(w * h, 0);
        for p in 0..w * h {
            let n = f.per_pixel[p];
            if n == 0 {
                continue;
            }
            let x = f.pixel_excess[p].map(|v| v / n as f32);
            f.pixel_excess[p] = x;
            let l = luminance(x);
            if l <= 0.0 {
                continue;
            }
            // Pixels the light must cover to stay under the limit.
            let cover = l / (limit * f.sums[p][0].max(floor)).max(f32::MIN_POSITIVE);
            let side = cover.sqrt();
            let k = (0..WIDER)
                .find(|&k| (2 * (base << k) + 1) as f32 >= side)
                .unwrap_or(WIDER - 1);
            f.pixel_wave[p] = k as u8;
            let (row, col) = (p / w, p % w);
            let b = wave[k].get_or_insert([row, row, col, col]);
            *b = [b[0].min(row), b[1].max(row), b[2].min(col), b[3].max(col)];
        }
        f.received.clear();
        f.received.resize(w * h, [0.0; 3]);
        for (k, bounds) in wave.iter().enumerate() {
            let Some([first_row, last_row, first_col, last_col]) = *bounds else {
                continue;
            };
            // The window the senders' squares reach: outside it nothing is
            // received, and inside it every filled pixel counts as in the
            // whole frame (the squares lie within it).
            let radius = base << k;
            let (r0, r1) = (first_row.saturating_sub(radius), (last_row + radius + 1).min(h));
            let (c0, c1) = (first_col.saturating_sub(radius), (last_col + radius + 1).min(w));
            let bw = c1 - c0;
            let (per_pixel, pixel_excess, pixel_wave) = (&f.per_pixel, &f.pixel_excess, &f.pixel_wave);
            let items = (r0..r1)
                .flat_map(|r| (c0..c1).map(move |c| (r, c)))
                .filter(|&(r, c)| per_pixel[r * w + c] > 0)
                .map(|(r, c)| {
                    let p = r * w + c;
                    let x = if pixel_wave[p] as usize == k {
                        pixel_excess[p]
                    } else {
                        [0.0; 3]
                    };
                    ((r - r0) * bw + (c - c0), x)
                });
            let got = f.spread.run(bw, r1 - r0, radius, items);
            for (row, line) in got.chunks(bw).enumerate() {
                let at = (r0 + row) * w + c0;
                for (r, g) in f.received[at..at + bw].iter_mut().zip(line) {
                    for c in 0..3 {
                        r[c] += g[c];
                    }
                }
            }
        }
        for (c, b) in colors.iter_mut().zip(&f.bodies) {
            let r = f.received[b.0 as usize];
            *c += Vec3::from_array(r);
        }
    }

    /// The values [`Store::update_colors`] computed last, by slot.
    pub fn colors(&self) -> &[Vec3] {
        &self.frame.colors
    }
}

/// Estimates a frame may hold with automatic sub-pixels (about 100 MB).
const AUTO_ESTIMATES: u64 = 1 << 20;

/// Sub-pixels per pixel along each axis: `asked` (1, 2 or 4), or for 0 the
/// most of 4, 2 and 1 that keep the frame within [`AUTO_ESTIMATES`].
fn subpixels_for(viewport: &Viewport, asked: u32) -> u32 {
    if asked > 0 {
        return asked.clamp(1, 4).next_power_of_two();
    }
    let pixels = u64::from(viewport.width) * u64::from(viewport.height);
    [4u32, 2]
        .into_iter()
        .find(|&s| pixels * u64::from(s * s) <= AUTO_ESTIMATES)
        .unwrap_or(1)
}

/// `viewport` with `s` x `s` sub-pixels per pixel.
fn sub_grid(viewport: &Viewport, s: u32) -> Viewport {
    Viewport {
        view: viewport.view.clone(),
        width: viewport.width * s,
        height: viewport.height * s,
    }
}
