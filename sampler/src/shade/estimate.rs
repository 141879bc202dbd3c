//! The path estimator's entry points: one ray, rays in turn sharing one
//! random sequence, and batches of seeded rays whose samples depend on
//! their own seeds alone (found in packets, or a segment at a time in
//! sorted order). Unbiased Monte Carlo estimates of the radiance arriving
//! along a ray, with next-event estimation of area lights and the sun,
//! multiple importance sampling (power heuristic), Russian roulette, a
//! bounce limit, and the distance to the first hit (or, with VDISTANCE, the
//! virtual distance through flat mirrors and thin glass). Never returns
//! NaN or infinity. What rays are cast against is the tracer's caster
//! (`cast.rs`); one path's steps are in `path.rs`.

use std::sync::atomic::Ordering;
use std::time::Instant;

use glam::Vec3;

use super::hit::SurfaceHit;
use super::options::{way_of, FirstHits};
use super::path::Path;
use super::rng::Rng;
use super::tracer::Tracer;
use crate::accel::{Hit, PACKET};
use crate::geom::Ray;
use crate::ooc::Fetch;

/// One radiance estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Radiance arriving along the ray (linear RGB).
    pub radiance: Vec3,
    /// Distance to the first hit (or the virtual distance); infinity if the ray escaped.
    pub distance: f32,
}

/// A ray to trace and where its estimates draw their random numbers:
/// estimate `j` from stream `stream + j` of `seed`.
#[derive(Clone, Copy, Debug)]
pub struct SeededRay {
    /// Where the ray starts.
    pub origin: Vec3,
    /// Its direction (any length but zero).
    pub dir: Vec3,
    /// The seed of its estimates' random streams.
    pub seed: u64,
    /// The stream of its first estimate.
    pub stream: u64,
}

/// The seed of a batch's random streams ([`Tracer::trace_rays`]), drawn from `rng`.
pub fn batch_seed(rng: &mut Rng) -> u64 {
    u64::from(rng.next_u32()) << 32 | u64::from(rng.next_u32())
}

/// Where the estimates along one ray draw their random numbers.
enum Streams<'a> {
    /// One after another from one generator.
    Shared(&'a mut Rng),
    /// Estimate `j` from its own stream `first + j` of `seed`, so that it
    /// can be traced apart from the others, in any order.
    PerPath { seed: u64, first: u64 },
}

/// Whether a ray can be traced: a finite origin and a finite, non-zero direction.
fn traceable(origin: Vec3, dir: Vec3) -> bool {
    origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0
}

impl Tracer {
    /// One radiance estimate along the ray from `origin` in unit direction
    /// `dir`, with the options' VDISTANCE, out-of-core data loaded as needed.
    pub fn trace(&self, origin: Vec3, dir: Vec3, rng: &mut Rng) -> Sample {
        self.trace_with(origin, dir, self.options.vdistance, rng, &mut Fetch::load())
    }

    /// [`Tracer::trace`] with VDISTANCE chosen per call rather than by the
    /// options (a sampler obeys the setting of the holodeck file it serves,
    /// which it learns only once connected), and out-of-core data fetched
    /// as `fetch` says. When `fetch.missed` comes back true, the path
    /// stopped where data was missing: the sample is incomplete and must
    /// not be kept.
    pub fn trace_with(&self, origin: Vec3, dir: Vec3, vdistance: bool, rng: &mut Rng, fetch: &mut Fetch) -> Sample {
        self.trace_streams(origin, dir, vdistance, Streams::Shared(rng), fetch)
    }

    /// [`Tracer::trace`] of each ray `(origin, direction)` of `rays` in
    /// turn, handing `out` its index and sample: the estimates draw from
    /// `rng` one after another, exactly as calling [`Tracer::trace`] on each
    /// would. In core, the first hits of each [`PACKET`] consecutive rays
    /// are found together, which pays where the rays run nearly one way, as
    /// the samples of one pixel do.
    pub fn trace_together(&self, rays: &[(Vec3, Vec3)], rng: &mut Rng, mut out: impl FnMut(usize, Sample)) {
        let vdistance = self.options.vdistance;
        let fetch = &mut Fetch::load();
        for (c, chunk) in rays.chunks(PACKET).enumerate() {
            let at = c * PACKET;
            if !self.caster.packets() || chunk.iter().any(|&(o, d)| !traceable(o, d)) {
                for (k, &(origin, dir)) in chunk.iter().enumerate() {
                    out(
                        at + k,
                        self.trace_streams(origin, dir, vdistance, Streams::Shared(rng), fetch),
                    );
                }
                continue;
            }
            let mut packet = [Ray::new(Vec3::ZERO, Vec3::ONE); PACKET];
            for (p, &(origin, dir)) in packet.iter_mut().zip(chunk) {
                *p = Ray::new(origin, dir.normalize());
            }
            let packet = &packet[..chunk.len()];
            let hits = self.caster.intersect_packet(packet);
            for (k, (ray, hit)) in packet.iter().zip(hits).enumerate() {
                let first = Some(hit.and_then(|h| self.surface(ray, h)));
                out(
                    at + k,
                    self.estimates(ray.origin, ray.dir, first, vdistance, Streams::Shared(rng), fetch),
                );
            }
        }
    }

    /// [`Tracer::trace_with`] with the estimates' random numbers drawn
    /// from `streams`.
    fn trace_streams(&self, origin: Vec3, dir: Vec3, vdistance: bool, streams: Streams, fetch: &mut Fetch) -> Sample {
        if !traceable(origin, dir) {
            return self.untraceable();
        }
        let dir = dir.normalize();
        // In core, the first hit is the same for every estimate along the
        // ray: found once. Out of core, each estimate looks again, since
        // data may arrive between them.
        let first = self
            .caster
            .file()
            .is_none()
            .then(|| self.nearest(&Ray::new(origin, dir), 0.0, fetch));
        self.estimates(origin, dir, first, vdistance, streams, fetch)
    }

    /// The sample of a ray with a non-finite origin or direction: black,
    /// escaped, and counted.
    fn untraceable(&self) -> Sample {
        self.non_finite.fetch_add(1, Ordering::Relaxed);
        Sample {
            radiance: Vec3::ZERO,
            distance: f32::INFINITY,
        }
    }

    /// Traces each ray `(origin, direction)` of `rays`, finding the first
    /// hits together as `first` says: [`Tracer::trace_seeded`] with the
    /// estimates along ray `k` drawing from streams `k * samples ..` of one
    /// seed taken from `rng`.
    pub fn trace_rays(
        &self,
        rays: &[(Vec3, Vec3)],
        vdistance: bool,
        first: FirstHits,
        rng: &mut Rng,
    ) -> Vec<Option<Sample>> {
        let seed = batch_seed(rng);
        let n = u64::from(self.options.samples.max(1));
        let seeded: Vec<SeededRay> = rays
            .iter()
            .enumerate()
            .map(|(k, &(origin, dir))| SeededRay {
                origin,
                dir,
                seed,
                stream: k as u64 * n,
            })
            .collect();
        self.trace_seeded(&seeded, vdistance, first)
    }

    /// Traces each ray of `rays`, finding the first hits together as
    /// `first` says, and the paths each to its end or a segment at a time
    /// as [`TraceOptions::reorder`](super::TraceOptions::reorder) says. A ray's sample depends on its own
    /// seed alone: neither on `first`, nor on the order the paths are
    /// traced in, nor on which other rays share the batch. Out of core,
    /// rays are traced one by one until every sample is exact (see
    /// `OocScene::exact_batch`); a sample only unreadable blocks could have
    /// made comes back as `None`.
    pub fn trace_seeded(&self, rays: &[SeededRay], vdistance: bool, first: FirstHits) -> Vec<Option<Sample>> {
        let streams = |r: &SeededRay| Streams::PerPath {
            seed: r.seed,
            first: r.stream,
        };
        if let Some(ooc) = self.caster.file() {
            return ooc.exact_batch(rays.len(), |k, fetch| {
                self.trace_streams(rays[k].origin, rays[k].dir, vdistance, streams(&rays[k]), fetch)
            });
        }
        let walk: Vec<(usize, Ray)> = rays
            .iter()
            .enumerate()
            .filter(|(_, r)| traceable(r.origin, r.dir))
            .map(|(k, r)| (k, Ray::new(r.origin, r.dir.normalize())))
            .collect();
        let mut out: Vec<Option<Sample>> = vec![None; rays.len()];
        let n = self.options.samples.max(1) as usize;
        let (order, timed) = self.path_order_for(walk.len() * n);
        let started = Instant::now();
        let mut fetch = Fetch::load();
        if let Some(order) = order {
            // The first segment sorted too: a batch of many beams' rays is
            // coherent within each beam only.
            let starts: Vec<Ray> = walk.iter().map(|w| w.1).collect();
            let hits = self
                .caster
                .in_order(&starts, order, |r| self.nearest(r, 0.0, &mut fetch));
            let mut paths = Vec::with_capacity(walk.len() * n);
            let mut rngs = Vec::with_capacity(paths.capacity());
            let mut firsts = Vec::with_capacity(paths.capacity());
            for (&(k, ray), hit) in walk.iter().zip(hits) {
                for j in 0..n as u64 {
                    paths.push(Path::new(ray.origin, ray.dir, vdistance));
                    rngs.push(Rng::new(rays[k].seed, rays[k].stream + j));
                    firsts.push(hit);
                }
            }
            let estimates = self.trace_wavefront(paths, rngs, firsts, order);
            for (&(k, _), e) in walk.iter().zip(estimates.chunks(n)) {
                out[k] = Some(self.mean(e.iter().copied()));
            }
        } else {
            let hits = self.first_hits_of(&walk, rays.len(), first);
            for &(k, ray) in &walk {
                let first = Some(hits[k].and_then(|h| self.surface(&ray, h)));
                out[k] = Some(self.estimates(ray.origin, ray.dir, first, vdistance, streams(&rays[k]), &mut fetch));
            }
        }
        if timed {
            let ns = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
            self.path_order.record(usize::from(order.is_none()), walk.len() * n, ns);
        }
        for (o, _) in out.iter_mut().zip(rays).filter(|(_, r)| !traceable(r.origin, r.dir)) {
            *o = Some(self.untraceable());
        }
        out
    }

    /// The first hits of the rays `walk` (index into the batch of `n`, ray),
    /// found as `first` says, by index.
    fn first_hits_of(&self, walk: &[(usize, Ray)], n: usize, first: FirstHits) -> Vec<Option<Hit>> {
        let mut hits: Vec<Option<Hit>> = vec![None; n];
        let (way, started) = match first {
            FirstHits::Measured => (way_of(self.first_hits.choose()), Some(Instant::now())),
            way => (way, None),
        };
        if way == FirstHits::Packets && self.caster.packets() {
            let mut packet = [Ray::new(Vec3::ZERO, Vec3::ONE); PACKET];
            for chunk in walk.chunks(PACKET) {
                for (p, c) in packet.iter_mut().zip(chunk) {
                    *p = c.1;
                }
                let found = self.caster.intersect_packet(&packet[..chunk.len()]);
                for (&(k, _), h) in chunk.iter().zip(found) {
                    hits[k] = h;
                }
            }
        } else {
            walk.iter().for_each(|&(k, r)| hits[k] = self.caster.intersect(&r));
        }
        if let Some(started) = started {
            let ns = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
            self.first_hits
                .record(usize::from(way == FirstHits::Single), walk.len(), ns);
        }
        hits
    }

    /// The mean of the options' number of estimates along a valid ray (unit
    /// `dir`), each starting from `first` when given (an in-core first hit).
    fn estimates(
        &self,
        origin: Vec3,
        dir: Vec3,
        first: Option<Option<SurfaceHit>>,
        vdistance: bool,
        mut streams: Streams,
        fetch: &mut Fetch,
    ) -> Sample {
        let n = self.options.samples.max(1);
        let mut estimate = |j: u32, fetch: &mut Fetch| match &mut streams {
            Streams::Shared(rng) => self.estimate(origin, dir, first, vdistance, rng, fetch),
            Streams::PerPath { seed, first: stream } => {
                let mut rng = Rng::new(*seed, *stream + u64::from(j));
                self.estimate(origin, dir, first, vdistance, &mut rng, fetch)
            }
        };
        let (mut radiance, distance) = estimate(0, fetch);
        for j in 1..n {
            if fetch.missed {
                break;
            }
            radiance += estimate(j, fetch).0;
        }
        self.mean(std::iter::once((radiance, distance)))
    }

    /// One sample from the estimates along a ray (radiance, distance), in
    /// order: the mean of their radiance over the options' number of
    /// estimates, the first one's distance; never NaN or infinite.
    fn mean(&self, mut estimates: impl Iterator<Item = (Vec3, f32)>) -> Sample {
        let (mut radiance, distance) = estimates.next().unwrap_or((Vec3::ZERO, f32::INFINITY));
        for (l, _) in estimates {
            radiance += l;
        }
        radiance /= self.options.samples.max(1) as f32;
        // A NaN distance (it cannot arise from finite input, but is never passed on) reads as "escaped".
        let distance = if distance.is_nan() { f32::INFINITY } else { distance };
        if radiance.is_finite() && radiance.min_element() >= 0.0 {
            Sample { radiance, distance }
        } else {
            self.non_finite.fetch_add(1, Ordering::Relaxed);
            Sample {
                radiance: Vec3::ZERO,
                distance,
            }
        }
    }

    /// Traces `n` items with `f` (given the item, the random numbers and a
    /// fetch state), keeping only results that no missing data stood in for.
    /// In core, one pass. Out of core, items that met missing blocks are
    /// traced again once the fetchers have loaded what they asked for; after a
    /// few rounds the blocks are loaded on the spot, so every item ends exact.
    #[cfg(test)]
    pub(crate) fn trace_batch<T>(
        &self,
        n: usize,
        rng: &mut Rng,
        mut f: impl FnMut(usize, &mut Rng, &mut Fetch) -> T,
    ) -> Vec<T> {
        let Some(ooc) = self.caster.file() else {
            let mut fetch = Fetch::load();
            return (0..n).map(|k| f(k, rng, &mut fetch)).collect();
        };
        ooc.exact_batch(n, |k, fetch| f(k, rng, fetch))
            .into_iter()
            .flatten()
            .collect()
    }
}
