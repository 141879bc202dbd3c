//! Rays into estimates: the body of [`crate::Driver::add`] and of
//! [`Store::add_beams`].
//!
//! A batch goes in three stages, each timed ([`InsertTimes`]):
//! * **Project** (on every core when large): each ray becomes the pixel key
//!   it lands on, its weight and depth. Stored records are decoded in the
//!   same pass, so that no decoded ray is ever written to memory.
//! * **Sort** by key, in the index's memory order (a stable radix sort), so
//!   that the rays of one pixel are adjacent and arrive in batch order.
//! * **Merge**: one serial pass finds each distinct pixel's slot in the
//!   index (the index restructures as it goes, so it is walked in key
//!   order, as before) and merges a pixel's rays there when they are few;
//!   the long runs of rays on one slot are then merged into their estimates
//!   on every core. Runs touch distinct estimates and each run is merged in
//!   arrival order, so the estimates are bit-identical to one ray after
//!   another on one thread.

use std::ops::Range;
use web_time::Instant;

use holodeck_protocol::{BeamKey, RayRecord, ViewType};
use rayon::prelude::*;

use super::lanes;
use super::lens::{Lens, NOT_FINITE, OFF};
use super::radix::radix_sort;
use super::{Entry, Estimate, Fit, Pending, PixelIndex, Spot, Store, CHUNK};
use crate::sample::{Sample, SampleDecoder};
use crate::stats::InsertTimes;

/// Batches smaller than this are inserted in arrival order: sorting them
/// costs more than it saves.
const SORT_MIN: usize = 256;

/// Batches of at least this many rays are projected on every core.
const PARALLEL_RAYS: usize = 1 << 14;

/// Records of one beam decoded and projected together by one task.
const RAYS_PER_TASK: usize = 1 << 12;

/// Batches of at least this many runs (distinct pixels with rays to merge)
/// merge them on every core.
const PARALLEL_RUNS: usize = 1 << 12;

/// Runs of fewer rays are merged as their estimate is found; longer ones
/// wait to be merged on every core.
const DEFER_MIN: usize = 8;

/// Runs merged together by one task.
const RUNS_PER_TASK: usize = 1 << 9;

impl Lens<'_> {
    /// Projects the records of one beam into `out` (one slot per record);
    /// a beam the decoder does not know leaves every ray not finite, so
    /// that it is rejected and counted as a broken sample would be.
    #[inline]
    fn project_beam(&self, decoder: &SampleDecoder, key: BeamKey, records: &[RayRecord], out: &mut [Pending]) {
        let Some(d) = decoder.beam(key.section, key.beam) else {
            out.fill(Pending::nowhere(NOT_FINITE));
            return;
        };
        let done = if self.projector.view().kind == ViewType::Perspective {
            lanes::project_perspective(self, &d, records, out)
        } else {
            0
        };
        for (slot, r) in out[done..].iter_mut().zip(&records[done..]) {
            *slot = self.project(&SampleDecoder::sample(&d, r));
        }
    }
}

/// The rays of a sorted batch that land on one estimate, merged together.
#[derive(Clone, Debug)]
pub(super) struct Run {
    slot: u32,
    rays: Range<u32>,
}

/// What merging rays into estimates counted.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Tally {
    merged: u64,
    replaced: u64,
    discarded: u64,
}

impl std::ops::AddAssign for Tally {
    fn add_assign(&mut self, o: Tally) {
        self.merged += o.merged;
        self.replaced += o.replaced;
        self.discarded += o.discarded;
    }
}

/// When a ray may be hidden from the eye by the nearest surface of its
/// whole pixel (with sub-pixels only; see [`Pending::hidden_by`]).
#[derive(Clone, Copy, Debug)]
struct Hiding {
    shift: u32,
    tolerance: f32,
    footprint: f32,
}

impl Hiding {
    /// True when `p` may be hidden, given each pixel's nearest depth.
    #[inline]
    fn hides<I: PixelIndex>(&self, index: &I, near: &[f32], p: &Pending) -> bool {
        self.shift > 0 && p.hidden_by(near[index.block(p.key, self.shift)], self.tolerance, self.footprint)
    }
}

/// Merges `rays` (all on the pixel of `e`, in arrival order) into `e` by
/// the depth rule, skipping the hidden ones.
#[inline(always)]
fn merge_run<I: PixelIndex>(e: &mut Estimate, rays: &[Pending], seen: (&I, &[f32], Hiding), tolerance: f32) -> Tally {
    let (index, near, hiding) = seen;
    let mut t = Tally::default();
    for p in rays {
        if hiding.hides(index, near, p) {
            t.discarded += 1;
            continue;
        }
        match e.fit(p.depth, p.depth, tolerance) {
            Fit::Joins => {
                e.add_ray(p.color, p.ray_weight(), p.depth, p.at());
                t.merged += 1;
            }
            Fit::Nearer => {
                *e = Estimate::of_ray(p.color, p.ray_weight(), p.depth, p.at());
                t.replaced += 1;
            }
            Fit::Behind => t.discarded += 1,
        }
    }
    t
}

/// A batch of stored rays to decode and project: pieces of beams, in order,
/// and how many records they hold.
type Batch<'r> = (Vec<(BeamKey, &'r [RayRecord])>, usize);

impl Lens<'_> {
    /// Decodes and projects one batch into `out` (one slot per record), on
    /// every core when it is large.
    fn project_batch(&self, decoder: &SampleDecoder, batch: &Batch<'_>, out: &mut Vec<Pending>) {
        let (beams, rays) = batch;
        out.clear();
        out.resize(*rays, Pending::nowhere(OFF));
        // Pieces of beams, each into its own slice of the batch, in order.
        let mut jobs = Vec::with_capacity(beams.len());
        let mut rest = &mut out[..];
        for &(key, records) in beams {
            for piece in records.chunks(RAYS_PER_TASK) {
                let (mine, tail) = rest.split_at_mut(piece.len());
                jobs.push((key, piece, mine));
                rest = tail;
            }
        }
        if *rays >= PARALLEL_RAYS {
            jobs.into_par_iter()
                .for_each(|(key, records, out)| self.project_beam(decoder, key, records, out));
        } else {
            for (key, records, out) in jobs {
                self.project_beam(decoder, key, records, out);
            }
        }
    }
}

/// What merging needs: the index, the estimates and the counters, borrowed
/// apart from the [`Lens`] so that both work at once.
struct Sink<'a, I> {
    index: &'a mut I,
    entries: &'a mut Vec<Entry>,
    near: &'a mut [f32],
    stats: &'a mut super::DriverStats,
    runs: &'a mut Vec<Run>,
    merged: &'a mut Vec<(Estimate, Tally)>,
    spare: &'a mut Vec<Pending>,
    times: &'a mut InsertTimes,
    hiding: Hiding,
    subpixels: u32,
    tolerance: f32,
    pixels: usize,
    /// Per pixel of the frame, whether it takes no rays (empty: all do).
    sealed: &'a [bool],
    /// The frame's width in pixels.
    width: usize,
}

impl<I: PixelIndex + Sync> Sink<'_, I> {
    /// Sorts a projected batch into index order and merges it.
    fn insert(&mut self, pending: &mut Vec<Pending>) {
        let start = Instant::now();
        // The rays that land on a pixel, in place, with the index's keys.
        let mut kept = 0;
        for i in 0..pending.len() {
            let mut p = pending[i];
            if p.key < NOT_FINITE {
                let (col, row) = (p.key as u32, (p.key >> 32) as u32);
                // A pixel that takes no rays: nothing of it changes, its
                // nearest depth included.
                if !self.sealed.is_empty() {
                    let sub = self.subpixels;
                    let pixel = (row / sub) as usize * self.width + (col / sub) as usize;
                    if self.sealed.get(pixel).copied().unwrap_or(true) {
                        self.stats.passed_over += 1;
                        continue;
                    }
                }
                p.key = self.index.key(col, row);
                pending[kept] = p;
                kept += 1;
            } else if p.key == OFF {
                self.stats.outside += 1;
            } else {
                self.stats.rejected_nonfinite += 1;
            }
        }
        pending.truncate(kept);
        if pending.len() >= SORT_MIN {
            radix_sort(pending, self.spare, self.index.key_bits(), |p| p.key);
        }
        let sorted = Instant::now();
        self.times.sort += sorted - start;
        self.entries.reserve(pending.len().min(self.pixels));
        // With sub-pixels, a ray that passed far from the eye may hit a point
        // the eye does not see though no ray of its own sub-pixel shows what
        // hides it: it must not be behind the nearest surface of its whole
        // pixel. The batch's own rays count first.
        let shift = self.subpixels.trailing_zeros();
        if self.subpixels > 1 {
            for p in pending.iter() {
                let at = self.index.block(p.key, shift);
                self.near[at] = self.near[at].min(p.depth);
            }
        }
        self.find_runs(pending);
        self.merge_runs(pending);
        self.times.merge += sorted.elapsed();
    }

    /// The serial part of a merge: each distinct pixel of the sorted batch
    /// in key order, its slot found (or made, from its first ray that is
    /// not hidden) in the index, and the rest of its rays as a run.
    fn find_runs(&mut self, pending: &[Pending]) {
        self.runs.clear();
        let hiding = self.hiding;
        let mut discarded = 0u64;
        let mut tally = Tally::default();
        let mut i = 0;
        while i < pending.len() {
            let key = pending[i].key;
            let mut end = i + 1;
            while end < pending.len() && pending[end].key == key {
                end += 1;
            }
            let first = (i..end)
                .find(|&k| !hiding.hides(&*self.index, self.near, &pending[k]))
                .unwrap_or(end);
            discarded += (first - i) as u64;
            if first < end {
                match self.index.find(self.entries, key) {
                    Spot::Free(at) => {
                        let p = &pending[first];
                        let slot = self.entries.len() as u32;
                        self.entries.push(Entry {
                            key,
                            estimate: Estimate::of_ray(p.color, p.ray_weight(), p.depth, p.at()),
                        });
                        self.index.fill(at, slot);
                        self.run(pending, slot, first + 1..end, &mut tally);
                    }
                    Spot::Taken(slot) => self.run(pending, slot, first..end, &mut tally),
                }
            }
            i = end;
        }
        self.stats.discarded += discarded;
        self.count(tally);
    }

    /// The rays `rays` of `pending` on the estimate in `slot`: merged now
    /// when few (the estimate is in cache from the index's walk), kept as a
    /// run for [`Sink::merge_runs`] when many.
    #[inline(always)]
    fn run(&mut self, pending: &[Pending], slot: u32, rays: Range<usize>, tally: &mut Tally) {
        if rays.len() >= DEFER_MIN {
            self.runs.push(Run {
                slot,
                rays: rays.start as u32..rays.end as u32,
            });
        } else if !rays.is_empty() {
            let seen = (&*self.index, &self.near[..], self.hiding);
            *tally += merge_run(
                &mut self.entries[slot as usize].estimate,
                &pending[rays],
                seen,
                self.tolerance,
            );
        }
    }

    fn count(&mut self, tally: Tally) {
        self.stats.merged += tally.merged;
        self.stats.replaced += tally.replaced;
        self.stats.discarded += tally.discarded;
    }

    /// Merges each run into its estimate: on every core for many runs.
    fn merge_runs(&mut self, pending: &[Pending]) {
        let (tolerance, runs) = (self.tolerance, &self.runs[..]);
        let seen = (&*self.index, &self.near[..], self.hiding);
        let mut tally = Tally::default();
        if runs.len() >= PARALLEL_RUNS && rayon::current_num_threads() > 1 {
            self.merged.clear();
            let entries = &*self.entries;
            self.merged
                .par_extend(runs.par_iter().with_min_len(RUNS_PER_TASK).map(|r| {
                    let mut e = entries[r.slot as usize].estimate;
                    let t = merge_run(
                        &mut e,
                        &pending[r.rays.start as usize..r.rays.end as usize],
                        seen,
                        tolerance,
                    );
                    (e, t)
                }));
            for (r, (e, t)) in runs.iter().zip(self.merged.iter()) {
                self.entries[r.slot as usize].estimate = *e;
                tally += *t;
            }
        } else {
            for r in runs {
                let e = &mut self.entries[r.slot as usize].estimate;
                tally += merge_run(e, &pending[r.rays.start as usize..r.rays.end as usize], seen, tolerance);
            }
        }
        self.count(tally);
    }
}

impl<I: PixelIndex + Sync + Send> Store<I> {
    /// Adds rays: the body of [`crate::Driver::add`].
    pub fn add(&mut self, samples: &[Sample]) {
        self.stats.received += samples.len() as u64;
        let mut projected = std::mem::take(&mut self.projected);
        for chunk in samples.chunks(CHUNK) {
            let start = Instant::now();
            projected.clear();
            let (lens, mut sink) = self.split();
            if chunk.len() >= PARALLEL_RAYS {
                projected.par_extend(chunk.par_iter().map(|s| lens.project(s)));
            } else {
                projected.extend(chunk.iter().map(|s| lens.project(s)));
            }
            sink.times.project += start.elapsed();
            sink.insert(&mut projected);
        }
        self.projected = projected;
    }

    /// Adds the stored rays of whole beams, decoded by `decoder`, in
    /// `chunks`: the same estimates as decoding every record into a
    /// [`Sample`] and calling [`Store::add`] once per chunk with them in
    /// this order, without the samples ever being written out (what replay
    /// from a file does with millions of rays a view). Each chunk is taken
    /// a batch of [`CHUNK`] rays at a time (a beam split where it does not
    /// fit), and each batch is decoded and projected while the one before
    /// it is merged. Records of a beam the decoder does not know count as
    /// rejected, as samples that are not finite.
    pub fn add_beams(&mut self, decoder: &SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]) {
        let mut batches: Vec<Batch<'_>> = Vec::new();
        for chunk in chunks {
            let mut batch = (Vec::new(), 0);
            for &(key, mut records) in *chunk {
                while !records.is_empty() {
                    let take = records.len().min(CHUNK - batch.1);
                    let (now, later) = records.split_at(take);
                    batch.0.push((key, now));
                    batch.1 += take;
                    records = later;
                    if batch.1 == CHUNK {
                        batches.push(std::mem::take(&mut batch));
                    }
                }
            }
            if batch.1 > 0 {
                batches.push(batch);
            }
        }
        self.stats.received += batches.iter().map(|b| b.1 as u64).sum::<u64>();
        // Two buffers, kept between calls: one batch projected into one
        // while the other is merged.
        let mut free = vec![
            std::mem::take(&mut self.projected),
            std::mem::take(&mut self.projected_next),
        ];
        let mut ready: Option<Vec<Pending>> = None;
        for i in 0..=batches.len() {
            let (lens, mut sink) = self.split();
            let mut next = free.pop().unwrap_or_default();
            let (done, took) = rayon::join(
                || {
                    ready.take().map(|mut r| {
                        sink.insert(&mut r);
                        (r, sink)
                    })
                },
                || {
                    let start = Instant::now();
                    if let Some(b) = batches.get(i) {
                        lens.project_batch(decoder, b, &mut next);
                    }
                    start.elapsed()
                },
            );
            match done {
                Some((r, sink)) => {
                    sink.times.project += took;
                    free.push(r);
                }
                None => self.times.project += took,
            }
            if i < batches.len() {
                ready = Some(next);
            } else {
                free.push(next);
            }
        }
        self.projected = free.pop().unwrap_or_default();
        self.projected_next = free.pop().unwrap_or_default();
    }

    /// [`Store::add_beams`], but only pixels that had no estimate when it
    /// was called take rays: a ray that lands on a pixel with one is
    /// counted as passed over. For rays of beams next to the ones a view
    /// sees, which pass near the eye rather than through it: where a sparse
    /// file left pixels without a ray, they fill them (as Radiance's rhpict
    /// fills from neighbours), and nowhere else do they change a thing.
    pub fn add_beams_where_empty(&mut self, decoder: &SampleDecoder, chunks: &[&[(BeamKey, &[RayRecord])]]) {
        self.sealed = self.empty_pixels().into_iter().map(|empty| !empty).collect();
        self.add_beams(decoder, chunks);
        self.sealed = Vec::new();
    }

    /// [`Store::add`], but only pixels that had no estimate when it was
    /// called take the samples, as [`Store::add_beams_where_empty`] does
    /// with stored records (for a server's samples of neighbouring beams).
    pub fn add_where_empty(&mut self, samples: &[Sample]) {
        self.sealed = self.empty_pixels().into_iter().map(|empty| !empty).collect();
        self.add(samples);
        self.sealed = Vec::new();
    }

    /// How long the stages of adding rays took so far (projecting overlaps
    /// merging in [`Store::add_beams`], so the stages may add up to more
    /// than the time taken).
    pub fn insert_times(&self) -> InsertTimes {
        self.times
    }

    /// The view's constants, to project rays with.
    #[cfg(test)]
    pub(super) fn lens(&self) -> Lens<'_> {
        Lens {
            eye: self.viewport.view.position,
            projector: &self.projector,
            options: &self.options,
        }
    }

    /// The store as a [`Lens`] and a [`Sink`], which may work at once.
    fn split(&mut self) -> (Lens<'_>, Sink<'_, I>) {
        let hiding = self.hiding();
        let pixels = self.pixel_count();
        let Store {
            viewport,
            projector,
            options,
            index,
            entries,
            near,
            stats,
            runs,
            merged,
            spare,
            times,
            sealed,
            ..
        } = self;
        (
            Lens {
                eye: viewport.view.position,
                projector,
                options,
            },
            Sink {
                index,
                entries,
                near,
                stats,
                runs,
                merged,
                spare,
                times,
                hiding,
                subpixels: options.subpixels,
                tolerance: options.depth_tolerance,
                pixels,
                sealed,
                width: viewport.width as usize,
            },
        )
    }

    /// When rays are hidden from the eye now.
    fn hiding(&self) -> Hiding {
        let sub = self.options.subpixels;
        Hiding {
            shift: sub.trailing_zeros(),
            tolerance: 1.0 + self.options.depth_tolerance,
            // A pixel's width at depth 1 (a parallel view has no eye point
            // for a ray to pass: its sky is trusted as before).
            footprint: if self.projector.is_parallel() {
                f32::INFINITY
            } else {
                (self.projector.pixel_angle(1.0) * f64::from(sub)) as f32
            },
        }
    }
}
