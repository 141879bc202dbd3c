//! The path tracer: unbiased Monte Carlo estimates of the radiance arriving
//! along a ray, with next-event estimation of area lights and the sun,
//! multiple importance sampling (power heuristic), Russian roulette, a bounce
//! limit, and the distance to the first hit (or, with VDISTANCE, the virtual
//! distance through flat mirrors and thin glass). Never returns NaN or infinity.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use glam::Vec3;

use super::bsdf::{self, is_delta, transmits};
use super::lights::Lights;
use super::rng::Rng;
use super::sampling::{power_heuristic, Frame};
use super::sky::SkyModel;
use crate::accel::{BuildOptions, Hit, KdTree, WideBvh, PACKET};
use crate::geom::{offset_origin, Ray};
use crate::ooc::{Fetch, InCoreReport, OocError, OocScene, OocSurface};
use crate::scene::{Material, Scene};

/// Settings of the estimator.
#[derive(Clone, Copy, Debug)]
pub struct TraceOptions {
    /// Largest number of bounces after the first hit.
    pub max_bounces: u32,
    /// Bounce after which Russian roulette may end paths.
    pub roulette_after: u32,
    /// Report virtual distances through flat mirrors and thin glass.
    pub vdistance: bool,
    /// Independent estimates averaged per ray (a holodeck ray's radiance is
    /// their mean; its distance is the first estimate's).
    pub samples: u32,
    /// Sample lights and the sun directly (next-event estimation with MIS).
    /// Off, paths find light only by BSDF sampling: a baseline for comparisons.
    pub light_sampling: bool,
    /// Out-of-core scenes: a voxel stands in for its subtree on the first
    /// segment of a path when its radius is below this share of its distance
    /// (pixels of error times the pixel's angle; 0: never).
    pub lod_primary: f32,
    /// The same for every later segment and shadow ray (from a solid angle).
    pub lod_secondary: f32,
}

impl Default for TraceOptions {
    fn default() -> Self {
        TraceOptions {
            max_bounces: 8,
            roulette_after: 3,
            vdistance: false,
            light_sampling: true,
            samples: 1,
            lod_primary: 0.0,
            lod_secondary: 0.0,
        }
    }
}

/// One radiance estimate.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Radiance arriving along the ray (linear RGB).
    pub radiance: Vec3,
    /// Distance to the first hit (or the virtual distance); infinity if the ray escaped.
    pub distance: f32,
}

/// A scene ready to trace: geometry (in memory with its wide BVH for single
/// rays and its kd-tree for packets of coherent rays, or a scene file traced
/// out of core), lights and sky.
pub struct Tracer {
    scene: Scene,
    tree: KdTree,
    /// `None` for a scene file, and for scenes beyond the BVH's size (the
    /// kd-tree then traces single rays too).
    bvh: Option<WideBvh>,
    ooc: Option<Arc<OocScene>>,
    lights: Lights,
    sky: SkyModel,
    /// Whether any material is a thin pane (shadow rays then look through panes).
    has_panes: bool,
    /// Estimator settings.
    pub options: TraceOptions,
    non_finite: AtomicU64,
    first_hits: FirstHitTimes,
    /// For a scene file assembled in memory: what that took.
    assembled: Option<InCoreReport>,
}

/// Transmittance of a thin pane for a ray crossing it at incidence cosine `cos`,
/// or `None` if the material is not a thin pane.
fn pane_transmittance(m: &Material, cos: f32) -> Option<Vec3> {
    match m {
        Material::Glass { ior, color, thin: true } => {
            Some(Vec3::from_array(*color) * (1.0 - bsdf::thin_reflectance(cos, *ior)))
        }
        _ => None,
    }
}

/// The emitters a scene file's header lists, with their materials' emission.
fn file_lights(ooc: &OocScene) -> Lights {
    let h = ooc.header();
    Lights::from_emitters(h.emitters.iter().map(|e| {
        let le = h.materials.get(e.material as usize).map_or([0.0; 3], |m| m.emission());
        (e.id, e.vertices.map(Vec3::from), Vec3::from_array(le))
    }))
}

/// How [`Tracer::trace_rays`] finds the first hits of its rays.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum FirstHits {
    /// In packets of [`PACKET`] consecutive rays (coherent rays, such as one
    /// beam's, share their walk and their leaf tests).
    #[default]
    Packets,
    /// One ray at a time.
    Single,
    /// Whichever of the two has cost less per ray on this tracer's batches
    /// so far, timed as they run, with one batch in [`PROBE_EVERY`] given
    /// to the other (see [`FirstHitTimes`]). Beam rays share an origin cell,
    /// not a point, so whether packets pay depends on the grid and the scene.
    Measured,
}

/// How often a [`FirstHits::Measured`] batch tries the way not chosen.
pub const PROBE_EVERY: u64 = 16;

/// Rays and nanoseconds spent on first hits each way, for [`FirstHits::Measured`].
#[derive(Default)]
struct FirstHitTimes {
    batches: AtomicU64,
    /// (rays, nanoseconds) of packets and of single rays.
    spent: [(AtomicU64, AtomicU64); 2],
}

impl FirstHitTimes {
    /// Rays timed each way before the faster one is trusted.
    const WARM: u64 = 4096;
    /// Past this many rays, both counts halve, so that the choice follows
    /// the views and the parts of the scene the samplers are asked for now.
    const WINDOW: u64 = 1 << 20;

    /// Nanoseconds per ray spent one way (0: packets, 1: single rays), once
    /// it has been timed on enough rays.
    fn per_ray(&self, way: usize) -> Option<f64> {
        let rays = self.spent[way].0.load(Ordering::Relaxed);
        (rays >= Self::WARM).then(|| self.spent[way].1.load(Ordering::Relaxed) as f64 / rays as f64)
    }

    /// The cheaper way, once both are timed.
    fn faster(&self) -> Option<FirstHits> {
        let (p, s) = (self.per_ray(0)?, self.per_ray(1)?);
        Some(if s < p { FirstHits::Single } else { FirstHits::Packets })
    }

    fn choose(&self) -> FirstHits {
        let b = self.batches.fetch_add(1, Ordering::Relaxed);
        let Some(faster) = self.faster() else {
            // Packets first, then single rays, until both are timed.
            return if self.per_ray(0).is_none() {
                FirstHits::Packets
            } else {
                FirstHits::Single
            };
        };
        match (b % PROBE_EVERY == PROBE_EVERY - 1, faster) {
            (true, FirstHits::Single) => FirstHits::Packets,
            (true, _) => FirstHits::Single,
            (false, way) => way,
        }
    }

    fn record(&self, way: FirstHits, rays: usize, ns: u64) {
        let (r, t) = &self.spent[usize::from(way == FirstHits::Single)];
        if r.fetch_add(rays as u64, Ordering::Relaxed) > Self::WINDOW {
            // Racing halvings lose a little history, which only blurs the window.
            r.store(r.load(Ordering::Relaxed) / 2, Ordering::Relaxed);
            t.store(t.load(Ordering::Relaxed) / 2, Ordering::Relaxed);
        }
        t.fetch_add(ns, Ordering::Relaxed);
    }

    /// The way chosen now, for reports: packets until single rays prove faster.
    fn preferred(&self) -> FirstHits {
        self.faster().unwrap_or(FirstHits::Packets)
    }
}

/// Whether a ray can be traced: a finite origin and a finite, non-zero direction.
fn traceable(origin: Vec3, dir: Vec3) -> bool {
    origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0
}

/// A hit as shading needs it.
#[derive(Clone, Copy)]
struct SurfaceHit {
    t: f32,
    /// Unit geometric normal.
    ng: Vec3,
    /// Triangle id (for light pdfs); `u32::MAX` for a voxel.
    tri: u32,
    /// Material index, or `None` for a voxel (a diffuse proxy of `color`).
    material: Option<u32>,
    color: Vec3,
    /// Voxel radius (0 for triangles): later rays start beyond the voxel.
    radius: f32,
}

fn flat_specular(m: &Material) -> bool {
    matches!(m, Material::Mirror { .. } | Material::Glass { thin: true, .. })
        || matches!(m, Material::Metal { roughness, .. } if *roughness < 0.02)
}

impl Tracer {
    /// Builds the kd-tree and light list of a scene.
    pub fn new(scene: Scene, options: TraceOptions) -> Tracer {
        let tree = KdTree::build(&scene, &BuildOptions::default());
        let lights = Lights::new(&scene);
        Tracer::with_geometry(scene, tree, None, lights, options)
    }

    /// A tracer over an open scene file: materials, sky, sections and lights
    /// come from its header, triangles from its blocks as rays need them.
    pub fn out_of_core(ooc: Arc<OocScene>, options: TraceOptions) -> Tracer {
        let scene = ooc.shell();
        let lights = file_lights(&ooc);
        let tree = KdTree::build(&Scene::default(), &BuildOptions::default());
        Tracer::with_geometry(scene, tree, Some(ooc), lights, options)
    }

    /// A tracer over a scene file assembled in memory (see
    /// [`OocScene::in_core`]): the in-core walk, with the hits the
    /// out-of-core walk finds; no LOD, since there are no voxels in core.
    pub fn in_core_from_file(ooc: &OocScene, options: TraceOptions) -> Result<Tracer, OocError> {
        let (scene, tree, report) = ooc.in_core()?;
        let lights = file_lights(ooc);
        let mut t = Tracer::with_geometry(scene, tree, None, lights, options);
        t.assembled = Some(report);
        Ok(t)
    }

    /// For a tracer made with [`Tracer::in_core_from_file`]: what assembling took.
    pub fn assembled(&self) -> Option<&InCoreReport> {
        self.assembled.as_ref()
    }

    /// The tracer around its geometry: the sky model and whether thin panes
    /// need their shadow-ray pass follow from the scene.
    fn with_geometry(
        scene: Scene,
        tree: KdTree,
        ooc: Option<Arc<OocScene>>,
        lights: Lights,
        options: TraceOptions,
    ) -> Tracer {
        let sky = SkyModel::new(&scene.sky);
        let bvh = if ooc.is_some() { None } else { WideBvh::build(&scene) };
        let has_panes = scene
            .materials
            .iter()
            .any(|m| matches!(m, Material::Glass { thin: true, .. }));
        Tracer {
            scene,
            tree,
            bvh,
            ooc,
            lights,
            sky,
            has_panes,
            options,
            non_finite: AtomicU64::new(0),
            first_hits: FirstHitTimes::default(),
            assembled: None,
        }
    }

    /// The scene file, for a tracer made with [`Tracer::out_of_core`].
    pub fn scene_file(&self) -> Option<&Arc<OocScene>> {
        self.ooc.as_ref()
    }

    /// The scene (for a scene file: its materials, sky and sections, no triangles).
    pub fn scene(&self) -> &Scene {
        &self.scene
    }
    /// The distance to the first surface along a ray (exact: out-of-core
    /// data is loaded as needed).
    pub fn first_hit(&self, ray: &Ray) -> Option<f32> {
        self.nearest(ray, 0.0, &mut Fetch::load()).map(|h| h.t)
    }

    /// Traces `n` items with `f` (given the item, the random numbers and a
    /// fetch state), keeping only results that no missing data stood in for.
    /// In core, one pass. Out of core, items that met missing blocks are
    /// traced again once the fetchers have loaded what they asked for; after a
    /// few rounds the blocks are loaded on the spot, so every item ends exact.
    pub fn trace_batch<T>(
        &self,
        n: usize,
        rng: &mut Rng,
        mut f: impl FnMut(usize, &mut Rng, &mut Fetch) -> T,
    ) -> Vec<T> {
        let Some(ooc) = &self.ooc else {
            let mut fetch = Fetch::load();
            return (0..n).map(|k| f(k, rng, &mut fetch)).collect();
        };
        ooc.exact_batch(n, |k, fetch| f(k, rng, fetch))
            .into_iter()
            .flatten()
            .collect()
    }

    /// The kd-tree (empty for a scene file).
    pub fn tree(&self) -> &KdTree {
        &self.tree
    }

    /// The wide BVH that traces single rays in memory (`None` for a scene
    /// file, or a scene too large for it).
    pub fn bvh(&self) -> Option<&WideBvh> {
        self.bvh.as_ref()
    }

    /// The nearest in-core hit of a single ray.
    fn intersect_in_core(&self, ray: &Ray) -> Option<Hit> {
        match &self.bvh {
            Some(bvh) => bvh.intersect(ray),
            None => self.tree.intersect(ray),
        }
    }

    /// How [`FirstHits::Measured`] finds first hits now, by the times so far.
    pub fn first_hits_preferred(&self) -> FirstHits {
        self.first_hits.preferred()
    }

    /// Estimates that came out NaN or infinite and were replaced by black.
    pub fn non_finite_count(&self) -> u64 {
        self.non_finite.load(Ordering::Relaxed)
    }

    /// One radiance estimate along the ray from `origin` in unit direction `dir`.
    pub fn trace(&self, origin: Vec3, dir: Vec3, rng: &mut Rng) -> Sample {
        self.trace_measuring(origin, dir, self.options.vdistance, rng)
    }

    /// [`Tracer::trace`] with VDISTANCE chosen per call rather than by the
    /// options: a sampler obeys the setting of the holodeck file it serves,
    /// which it learns only once connected.
    pub fn trace_measuring(&self, origin: Vec3, dir: Vec3, vdistance: bool, rng: &mut Rng) -> Sample {
        self.trace_fetching(origin, dir, vdistance, rng, &mut Fetch::load())
    }

    /// [`Tracer::trace_measuring`] with out-of-core data fetched as `fetch`
    /// says. When `fetch.missed` comes back true, the path stopped where data
    /// was missing: the sample is incomplete and must not be kept.
    pub fn trace_fetching(&self, origin: Vec3, dir: Vec3, vdistance: bool, rng: &mut Rng, fetch: &mut Fetch) -> Sample {
        if !traceable(origin, dir) {
            self.non_finite.fetch_add(1, Ordering::Relaxed);
            return Sample {
                radiance: Vec3::ZERO,
                distance: f32::INFINITY,
            };
        }
        let dir = dir.normalize();
        // In core, the first hit is the same for every estimate along the
        // ray: found once. Out of core, each estimate looks again, since
        // data may arrive between them.
        let first = self
            .ooc
            .is_none()
            .then(|| self.nearest(&Ray::new(origin, dir), 0.0, fetch));
        self.estimates(origin, dir, first, vdistance, rng, fetch)
    }

    /// Traces each ray `(origin, direction)` of `rays` as
    /// [`Tracer::trace_measuring`] would, with the same random numbers in
    /// the same order and so the same samples, but finding the first hits
    /// together as `first` says. Out of core, rays are traced one by one
    /// until every sample is exact (see [`Tracer::trace_batch`]); a sample
    /// only unreadable blocks could have made comes back as `None`.
    pub fn trace_rays(
        &self,
        rays: &[(Vec3, Vec3)],
        vdistance: bool,
        first: FirstHits,
        rng: &mut Rng,
    ) -> Vec<Option<Sample>> {
        if let Some(ooc) = &self.ooc {
            return ooc.exact_batch(rays.len(), |k, fetch| {
                self.trace_fetching(rays[k].0, rays[k].1, vdistance, rng, fetch)
            });
        }
        let walk: Vec<(usize, Ray)> = rays
            .iter()
            .enumerate()
            .filter(|(_, (o, d))| traceable(*o, *d))
            .map(|(k, &(o, d))| (k, Ray::new(o, d.normalize())))
            .collect();
        let mut hits: Vec<Option<Hit>> = vec![None; rays.len()];
        let (way, started) = match first {
            FirstHits::Measured => (self.first_hits.choose(), Some(Instant::now())),
            way => (way, None),
        };
        if way == FirstHits::Packets {
            let mut packet = [Ray::new(Vec3::ZERO, Vec3::ONE); PACKET];
            for chunk in walk.chunks(PACKET) {
                for (p, c) in packet.iter_mut().zip(chunk) {
                    *p = c.1;
                }
                let found = match &self.bvh {
                    Some(bvh) => bvh.intersect_packet(&packet[..chunk.len()]),
                    None => self.tree.intersect_packet(&packet[..chunk.len()]),
                };
                for (&(k, _), h) in chunk.iter().zip(found) {
                    hits[k] = h;
                }
            }
        } else {
            walk.iter().for_each(|&(k, r)| hits[k] = self.intersect_in_core(&r));
        }
        if let Some(started) = started {
            let ns = u64::try_from(started.elapsed().as_nanos()).unwrap_or(u64::MAX);
            self.first_hits.record(way, walk.len(), ns);
        }
        let mut fetch = Fetch::load();
        rays.iter()
            .zip(hits)
            .map(|(&(origin, dir), hit)| {
                Some(if traceable(origin, dir) {
                    let first = Some(hit.map(|h| self.surface(h)));
                    self.estimates(origin, dir.normalize(), first, vdistance, rng, &mut fetch)
                } else {
                    self.trace_fetching(origin, dir, vdistance, rng, &mut fetch)
                })
            })
            .collect()
    }

    /// The mean of the options' number of estimates along a valid ray (unit
    /// `dir`), each starting from `first` when given (an in-core first hit).
    fn estimates(
        &self,
        origin: Vec3,
        dir: Vec3,
        first: Option<Option<SurfaceHit>>,
        vdistance: bool,
        rng: &mut Rng,
        fetch: &mut Fetch,
    ) -> Sample {
        let (mut radiance, distance) = self.estimate(origin, dir, first, vdistance, rng, fetch);
        let n = self.options.samples.max(1);
        for _ in 1..n {
            if fetch.missed {
                break;
            }
            radiance += self.estimate(origin, dir, first, vdistance, rng, fetch).0;
        }
        radiance /= n as f32;
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

    /// The nearest hit: a triangle, or out of core a voxel (LOD, or a proxy
    /// for missing data, which `fetch` notes).
    fn nearest(&self, ray: &Ray, lod: f32, fetch: &mut Fetch) -> Option<SurfaceHit> {
        let Some(ooc) = &self.ooc else {
            return self.intersect_in_core(ray).map(|h| self.surface(h));
        };
        let h = ooc.intersect(ray, lod, fetch)?;
        Some(match h.surface {
            OocSurface::Triangle {
                id,
                material,
                vertices: [a, b, c],
                ..
            } => SurfaceHit {
                t: h.t,
                ng: (b - a).cross(c - a).normalize(),
                tri: id,
                material: Some(material),
                color: Vec3::ZERO,
                radius: 0.0,
            },
            OocSurface::Voxel { sample, radius, .. } => SurfaceHit {
                t: h.t,
                ng: sample.normal,
                tri: u32::MAX,
                material: None,
                color: sample.color,
                radius,
            },
        })
    }

    /// An in-core triangle hit as shading needs it.
    fn surface(&self, h: Hit) -> SurfaceHit {
        let [a, b, c] = self.scene.vertices(h.tri as usize);
        SurfaceHit {
            t: h.t,
            ng: (b - a).cross(c - a).normalize(),
            tri: h.tri,
            material: Some(self.scene.triangles[h.tri as usize].material),
            color: Vec3::ZERO,
            radius: 0.0,
        }
    }

    /// True if a surface for which `blocks(id, material, vertices)` says so
    /// (or a voxel) lies within `(0, ray.t_max)`.
    fn blocked(&self, ray: &Ray, fetch: &mut Fetch, mut blocks: impl FnMut(u32, u32, [Vec3; 3]) -> bool) -> bool {
        match &self.ooc {
            None => {
                let blocks = |t: u32| {
                    blocks(
                        t,
                        self.scene.triangles[t as usize].material,
                        self.scene.vertices(t as usize),
                    )
                };
                match &self.bvh {
                    Some(bvh) => bvh.occluded_by(ray, blocks),
                    None => self.tree.occluded_by(ray, blocks),
                }
            }
            Some(ooc) => ooc.occluded_by(ray, self.options.lod_secondary, fetch, blocks),
        }
    }

    /// [`Tracer::estimate`] walking from the start, for tests that compare
    /// against estimates given their first hit.
    #[cfg(test)]
    pub(crate) fn estimate_walking(
        &self,
        origin: Vec3,
        dir: Vec3,
        vdistance: bool,
        rng: &mut Rng,
        fetch: &mut Fetch,
    ) -> (Vec3, f32) {
        self.estimate(origin, dir, None, vdistance, rng, fetch)
    }

    /// One path's radiance and first distance; `first`, when given, is the
    /// hit of the first segment (found beforehand, in core).
    fn estimate(
        &self,
        origin: Vec3,
        dir: Vec3,
        mut first: Option<Option<SurfaceHit>>,
        vdistance: bool,
        rng: &mut Rng,
        fetch: &mut Fetch,
    ) -> (Vec3, f32) {
        let mut ray = Ray::new(origin, dir);
        let (mut l, mut beta) = (Vec3::ZERO, Vec3::ONE);
        let (mut distance, mut path, mut measuring) = (f32::INFINITY, 0.0f32, true);
        let (mut prev_delta, mut prev_pdf) = (true, 0.0f32);
        // Distance from the last scattering vertex: panes crossed on the way
        // do not scatter, so light-sampling pdfs are measured from that vertex.
        let mut travelled = 0.0f32;
        // Bounces count scattering events; crossing a pane is not one, but a
        // separate limit on segments stops any path that only crosses panes.
        let mut depth = 0u32;
        for segment in 0..self.options.max_bounces.saturating_add(64) {
            let lod = if segment == 0 {
                self.options.lod_primary
            } else {
                self.options.lod_secondary
            };
            let hit = match first.take() {
                Some(hit) => hit,
                None => self.nearest(&ray, lod, fetch),
            };
            if fetch.missed {
                break;
            }
            let Some(hit) = hit else {
                l += beta * self.sky.background(ray.dir);
                let sun = self.sky.sun(ray.dir);
                if sun.max_element() > 0.0 {
                    let w = if prev_delta || !self.options.light_sampling {
                        1.0
                    } else {
                        power_heuristic(prev_pdf, self.sky.sun_pdf())
                    };
                    l += beta * sun * w;
                }
                if measuring {
                    distance = f32::INFINITY;
                }
                break;
            };
            let proxy;
            let m = match hit.material {
                Some(i) => &self.scene.materials[i as usize],
                None => {
                    proxy = Material::lambertian(hit.color.to_array());
                    &proxy
                }
            };
            let ng = hit.ng;
            let p = ray.at(hit.t);
            if measuring {
                path += hit.t;
                distance = path;
                measuring = vdistance && flat_specular(m);
            }
            travelled += hit.t;
            let wo_world = -ray.dir;
            let cos_o = wo_world.dot(ng);
            let le = Vec3::from_array(m.emission());
            if cos_o > 0.0 && le.max_element() > 0.0 {
                let w = if prev_delta || !self.options.light_sampling {
                    1.0
                } else {
                    let pdf_light = self.lights.pdf_area(hit.tri) * travelled * travelled / cos_o;
                    power_heuristic(prev_pdf, pdf_light)
                };
                l += beta * le * w;
            }
            let pane = matches!(m, Material::Glass { thin: true, .. });
            if (depth == self.options.max_bounces && !pane) || matches!(m, Material::Emitter { .. }) {
                break;
            }
            let n = if transmits(m) || cos_o > 0.0 { ng } else { -ng };
            let frame = Frame::new(n);
            let wo = frame.to_local(wo_world);
            // Rays leaving a voxel start beyond it (Áfra 2012, 6.3).
            let skip = 2.0 * hit.radius;
            if !is_delta(m) && self.options.light_sampling {
                l += beta * self.direct(m, p, &frame, wo, skip, rng, fetch);
                if fetch.missed {
                    break;
                }
            }
            let Some(s) = bsdf::sample(m, wo, [rng.f32(), rng.f32(), rng.f32()]) else {
                break;
            };
            beta *= s.weight;
            let passed_pane = pane && s.wi == -wo;
            if !passed_pane && depth == self.options.max_bounces {
                // A pane's reflection at the last bounce would be one bounce too many.
                break;
            }
            if !passed_pane {
                depth += 1;
                // Crossing a pane keeps the direction, so the vertex before it
                // still decides how the light at the end was sampled.
                prev_delta = s.delta;
                prev_pdf = s.pdf;
                travelled = 0.0;
            }
            let wi = if passed_pane {
                ray.dir
            } else {
                frame.to_world(s.wi).normalize()
            };
            let side = if wi.dot(ng) > 0.0 { ng } else { -ng };
            ray = Ray::new(offset_origin(p, side) + wi * skip, wi);
            if !passed_pane && depth > self.options.roulette_after {
                let q = beta.max_element().min(0.95);
                if q.is_nan() || q <= 0.0 || rng.f32() >= q {
                    break;
                }
                beta /= q;
            }
        }
        (l, distance)
    }

    /// How much light gets through along a shadow ray: 1 if nothing is in the
    /// way, the product of pane transmittances if only thin panes are, else 0.
    /// One traversal: panes are noted and skipped, the first opaque hit ends it.
    fn visibility(&self, ray: Ray, fetch: &mut Fetch) -> Vec3 {
        if !self.has_panes {
            let blocked = match &self.ooc {
                None => match &self.bvh {
                    Some(bvh) => bvh.occluded(&ray),
                    None => self.tree.occluded(&ray),
                },
                Some(_) => self.blocked(&ray, fetch, |_, _, _| true),
            };
            return if blocked { Vec3::ZERO } else { Vec3::ONE };
        }
        let mut panes: Vec<(u32, u32, Vec3)> = Vec::new();
        let blocked = self.blocked(&ray, fetch, |tri, material, [a, b, c]| {
            let m = &self.scene.materials[material as usize];
            if matches!(m, Material::Glass { thin: true, .. }) {
                if !panes.iter().any(|p| p.0 == tri) {
                    panes.push((tri, material, (b - a).cross(c - a).normalize()));
                }
                false
            } else {
                true
            }
        });
        if blocked {
            return Vec3::ZERO;
        }
        let dir = ray.dir.normalize();
        let mut through = Vec3::ONE;
        for (_, material, ng) in panes {
            let m = &self.scene.materials[material as usize];
            through *= pane_transmittance(m, dir.dot(ng).abs()).unwrap_or(Vec3::ZERO);
        }
        through
    }

    /// Light arriving directly from one sampled point on the area lights and
    /// one on the sun, MIS-weighted against BSDF sampling.
    #[allow(clippy::too_many_arguments)]
    fn direct(
        &self,
        m: &Material,
        p: Vec3,
        frame: &Frame,
        wo: Vec3,
        skip: f32,
        rng: &mut Rng,
        fetch: &mut Fetch,
    ) -> Vec3 {
        let origin = offset_origin(p, frame.n) + frame.n * skip;
        let mut l = Vec3::ZERO;
        let (u, uv) = (rng.f32(), rng.f32x2());
        if let Some(ls) = self.lights.sample(u, uv) {
            let to = ls.point - origin;
            let dist2 = to.length_squared();
            let wi_world = to / dist2.sqrt();
            let cos_l = -wi_world.dot(ls.normal);
            let wi = frame.to_local(wi_world);
            if cos_l > 0.0 && wi.z > 0.0 && dist2 > 0.0 {
                let e = bsdf::eval(m, wo, wi);
                if e.f_cos.max_element() > 0.0 {
                    // Panes let light through here too, attenuated: BSDF paths
                    // cross them, so light sampling must see through them alike.
                    let vis = self.visibility(
                        Ray {
                            origin,
                            dir: to,
                            t_max: 1.0 - 1e-4,
                        },
                        fetch,
                    );
                    if vis.max_element() > 0.0 {
                        let pdf_light = ls.pdf_area * dist2 / cos_l;
                        l += vis * e.f_cos * ls.radiance * (power_heuristic(pdf_light, e.pdf) / pdf_light);
                    }
                }
            }
        }
        if let Some((wi_world, sun, pdf_sun)) = self.sky.sample_sun(rng.f32x2()) {
            let wi = frame.to_local(wi_world);
            if wi.z > 0.0 {
                let e = bsdf::eval(m, wo, wi);
                if e.f_cos.max_element() > 0.0 {
                    let vis = self.visibility(Ray::new(origin, wi_world), fetch);
                    l += vis * e.f_cos * sun * (power_heuristic(pdf_sun, e.pdf) / pdf_sun);
                }
            }
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn measured_first_hits_follow_the_faster_way_and_keep_probing() {
        let times = FirstHitTimes::default();
        // Untimed, packets come first, then single rays until both are warm.
        assert_eq!(times.choose(), FirstHits::Packets);
        times.record(FirstHits::Packets, 8192, 8192 * 300);
        assert_eq!(times.choose(), FirstHits::Single);
        times.record(FirstHits::Single, 8192, 8192 * 200);
        let picks: Vec<FirstHits> = (0..64).map(|_| times.choose()).collect();
        let packets = picks.iter().filter(|&&w| w == FirstHits::Packets).count();
        assert_eq!(packets, 64 / PROBE_EVERY as usize, "{picks:?}");
        assert_eq!(times.preferred(), FirstHits::Single);
        // Packets turn faster: the window forgets the old times.
        for _ in 0..300 {
            times.record(FirstHits::Packets, 8192, 8192 * 100);
        }
        assert_eq!(times.preferred(), FirstHits::Packets);
        let picks: Vec<FirstHits> = (0..64).map(|_| times.choose()).collect();
        let single = picks.iter().filter(|&&w| w == FirstHits::Single).count();
        assert_eq!(single, 64 / PROBE_EVERY as usize, "{picks:?}");
    }
}
