//! The path tracer: unbiased Monte Carlo estimates of the radiance arriving
//! along a ray, with next-event estimation of area lights and the sun,
//! multiple importance sampling (power heuristic), Russian roulette, a bounce
//! limit, and the distance to the first hit (or, with VDISTANCE, the virtual
//! distance through flat mirrors and thin glass). Never returns NaN or infinity.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::Instant;

use glam::{Vec2, Vec3};

use super::bsdf;
use super::lights::Lights;
use super::measured::TwoWays;
use super::path::{Path, SurfaceHit};
use super::rng::Rng;
use super::sky::SkyModel;
use super::wavefront::{Reorder, AUTO_MIN_PATHS};
use crate::accel::{BuildOptions, Hit, KdTree, RayCaster, WideBvh, PACKET};
use crate::geom::Ray;
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
    /// The order in which the paths of a batch are traced (in core): each
    /// to its end, or a segment at a time with each segment's rays sorted.
    /// The samples are the same either way.
    pub reorder: Reorder,
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
            reorder: Reorder::Auto,
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

/// What [`Tracer::first_surface`] finds.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FirstSurface {
    /// Distance to the first surface along the ray.
    pub t: f32,
    /// Its unit geometric normal, facing the ray.
    pub normal: Vec3,
    /// The colour it (and any mirror or glass in front of it) reflects, 0..=1.
    pub albedo: Vec3,
}

/// A scene ready to trace: geometry (in memory with its wide BVH for single
/// rays and its kd-tree for packets of coherent rays, or a scene file traced
/// out of core), lights and sky.
pub struct Tracer {
    pub(super) scene: Scene,
    pub(super) tree: KdTree,
    /// `None` for a scene file, and for scenes beyond the BVH's size (the
    /// kd-tree then traces single rays too).
    pub(super) bvh: Option<WideBvh>,
    /// Casts the single rays in place of the tracer's own hierarchy, where
    /// set ([`Tracer::with_caster`]).
    caster: Option<Arc<dyn RayCaster>>,
    pub(super) ooc: Option<Arc<OocScene>>,
    pub(super) lights: Lights,
    pub(super) sky: SkyModel,
    /// Whether any material is a thin pane (shadow rays then look through panes).
    pub(super) has_panes: bool,
    /// Whether any material has an alpha mask (rays then look through its holes).
    pub(super) cutouts: bool,
    /// Whether any material has textures: shading looks them up only then.
    pub(super) textured_any: bool,
    /// Estimator settings.
    pub options: TraceOptions,
    non_finite: AtomicU64,
    /// Times of first hits in packets (way 0) and one by one (way 1).
    first_hits: TwoWays,
    /// Times of paths sorted a segment at a time (way 0) and each to its
    /// end (way 1), for [`Reorder::Auto`].
    pub(super) path_order: TwoWays,
    /// For a scene file assembled in memory: what that took.
    assembled: Option<InCoreReport>,
    /// Bytes rays walk through in core: the structure that traces single
    /// rays, and the mesh.
    in_core_bytes: usize,
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

/// The emitters a scene file's header lists, with their materials'
/// emission (emission textures included) from `shell`, the file's scene
/// without triangles.
fn file_lights(ooc: &OocScene, shell: &Scene) -> Lights {
    let h = ooc.header();
    Lights::from_emitters(
        shell,
        h.emitters
            .iter()
            .map(|e| (e.id, e.vertices.map(Vec3::from), e.material)),
    )
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
    /// so far, timed as they run, with one batch in [`PROBE_EVERY`](super::measured::PROBE_EVERY) given
    /// to the other (see `measured.rs`). Beam rays share an origin cell,
    /// not a point, so whether packets pay depends on the grid and the scene.
    Measured,
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

/// The way of finding first hits a [`TwoWays`] index stands for.
fn way_of(i: usize) -> FirstHits {
    if i == 0 {
        FirstHits::Packets
    } else {
        FirstHits::Single
    }
}

/// Whether a ray can be traced: a finite origin and a finite, non-zero direction.
fn traceable(origin: Vec3, dir: Vec3) -> bool {
    origin.is_finite() && dir.is_finite() && dir.length_squared() > 0.0
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
        let lights = file_lights(&ooc, &scene);
        let tree = KdTree::build(&Scene::default(), &BuildOptions::default());
        Tracer::with_geometry(scene, tree, Some(ooc), lights, options)
    }

    /// A tracer over a scene file assembled in memory (see
    /// [`OocScene::in_core`]): the in-core walk, with the hits the
    /// out-of-core walk finds; no LOD, since there are no voxels in core.
    pub fn in_core_from_file(ooc: &OocScene, options: TraceOptions) -> Result<Tracer, OocError> {
        let (scene, tree, report) = ooc.in_core()?;
        let lights = file_lights(ooc, &scene);
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
        // A scene file keeps its texture coordinates; in core they are in the scene.
        let cutouts = (ooc.is_some() || !scene.uvs.is_empty()) && scene.maps.iter().any(|m| m.cuts());
        let textured_any = scene.maps.iter().any(|m| !m.is_empty());
        let in_core_bytes = match (&bvh, &ooc) {
            (_, Some(_)) => 0,
            (Some(b), None) => b.stats().bytes,
            (None, None) => tree.stats().bytes,
        } + scene.positions.len() * std::mem::size_of::<Vec3>()
            + scene.triangles.len() * std::mem::size_of::<crate::scene::Triangle>();
        Tracer {
            in_core_bytes,
            scene,
            tree,
            bvh,
            caster: None,
            ooc,
            lights,
            sky,
            has_panes,
            cutouts,
            textured_any,
            options,
            non_finite: AtomicU64::new(0),
            first_hits: TwoWays::new(4096, 1 << 20),
            path_order: TwoWays::new(AUTO_MIN_PATHS as u64, 1 << 24),
            assembled: None,
        }
    }

    /// Bytes rays walk through in core (the structure that traces single
    /// rays, and the mesh); 0 for a scene file.
    pub fn in_core_bytes(&self) -> usize {
        self.in_core_bytes
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

    /// The surface a ray sees first, as a denoiser's auxiliary buffers want
    /// it: its unit normal facing the ray, and the colour it reflects
    /// (its albedo). Through perfect mirrors and smooth glass it looks on,
    /// up to four times, to the first surface that is not such (as Cycles
    /// writes its denoising passes), the reflectance or tint multiplied in.
    /// `None` where the ray escapes; an emitter's albedo is its colour.
    pub fn first_surface(&self, ray: &Ray) -> Option<FirstSurface> {
        const DELTA_STEPS: usize = 4;
        let mut ray = *ray;
        let mut tint = Vec3::ONE;
        let mut fetch = Fetch::load();
        let mut first_normal = None;
        for _ in 0..=DELTA_STEPS {
            let hit = self.nearest(&ray, 0.0, &mut fetch)?;
            let facing = if hit.ng.dot(ray.dir) > 0.0 { -hit.ng } else { hit.ng };
            let normal = *first_normal.get_or_insert(facing);
            let textured = self.textured(&hit, hit.ng, hit.t, ray.dir).map(|t| t.material);
            let m = textured
                .as_ref()
                .or_else(|| hit.material.map(|i| &self.scene.materials[i as usize]));
            let (albedo, next) = match m {
                None => (hit.color, None),
                Some(Material::Lambertian { albedo, .. }) | Some(Material::Plastic { albedo, .. }) => {
                    (Vec3::from_array(*albedo), None)
                }
                Some(Material::Metal { color, roughness }) if *roughness >= 0.02 => (Vec3::from_array(*color), None),
                Some(Material::Metal { color, .. }) | Some(Material::Mirror { color }) => {
                    let d = ray.dir - 2.0 * ray.dir.dot(facing) * facing;
                    (Vec3::from_array(*color), Some(d))
                }
                Some(Material::Glass { ior, color, thin }) => {
                    let d = if *thin {
                        Some(ray.dir)
                    } else {
                        let entering = hit.ng.dot(ray.dir) < 0.0;
                        let eta = if entering { 1.0 / ior } else { *ior };
                        let cos_i = -ray.dir.dot(facing);
                        let k = 1.0 - eta * eta * (1.0 - cos_i * cos_i);
                        Some(if k < 0.0 {
                            ray.dir + 2.0 * cos_i * facing
                        } else {
                            eta * ray.dir + (eta * cos_i - k.sqrt()) * facing
                        })
                    };
                    (Vec3::from_array(*color), d)
                }
                Some(Material::Emitter { radiance }) => {
                    let r = Vec3::from_array(*radiance);
                    (r / r.max_element().max(f32::MIN_POSITIVE), None)
                }
            };
            tint *= albedo.clamp(Vec3::ZERO, Vec3::ONE);
            let Some(dir) = next else {
                return Some(FirstSurface {
                    t: hit.t,
                    normal,
                    albedo: tint,
                });
            };
            let at = ray.at(hit.t);
            ray = Ray::new(at + dir * (1e-4 * (1.0 + at.abs().max_element())), dir.normalize());
        }
        // Still in a hall of mirrors: what it looked through so far.
        Some(FirstSurface {
            t: ray.t_max,
            normal: first_normal.unwrap_or(Vec3::ZERO),
            albedo: tint,
        })
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

    /// The same tracer with every ray cast by `caster` (first hits one ray
    /// at a time, no packets), which must hold the scene's triangles with
    /// their indices: for comparing whole path tracing over another
    /// library's hierarchy. Ignored for a scene file.
    pub fn with_caster(mut self, caster: Arc<dyn RayCaster>) -> Tracer {
        if self.ooc.is_none() {
            self.caster = Some(caster);
        }
        self
    }

    /// The nearest in-core hit of a single ray.
    #[inline]
    pub(super) fn intersect_in_core(&self, ray: &Ray) -> Option<Hit> {
        if self.caster.is_some() {
            return self.intersect_cast(ray);
        }
        match &self.bvh {
            Some(bvh) => bvh.intersect(ray),
            None => self.tree.intersect(ray),
        }
    }

    /// [`Tracer::intersect_in_core`] by a stand-in caster: out of line and
    /// cold, so that the tracer's own path stays as it was, inlined.
    #[cold]
    #[inline(never)]
    fn intersect_cast(&self, ray: &Ray) -> Option<Hit> {
        self.caster.as_ref().and_then(|c| c.intersect(ray))
    }

    /// How [`FirstHits::Measured`] finds first hits now, by the times so far.
    pub fn first_hits_preferred(&self) -> FirstHits {
        way_of(self.first_hits.preferred())
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
        self.trace_streams(origin, dir, vdistance, Streams::Shared(rng), fetch)
    }

    /// [`Tracer::trace`] of each ray `(origin, direction)` of `rays` in
    /// turn, handing `out` its index and sample: the estimates draw from
    /// `rng` one after another, exactly as calling [`Tracer::trace`] on each
    /// would. In core, the first hits of each [`PACKET`] consecutive rays
    /// are found together, which pays where the rays run nearly one way, as
    /// the samples of one pixel do.
    pub fn trace_together(&self, rays: &[(Vec3, Vec3)], rng: &mut Rng, mut out: impl FnMut(usize, Sample)) {
        if self.caster.is_some() {
            return self.trace_cast(rays, rng, &mut out);
        }
        let vdistance = self.options.vdistance;
        let fetch = &mut Fetch::load();
        for (c, chunk) in rays.chunks(PACKET).enumerate() {
            let at = c * PACKET;
            if self.ooc.is_some() || chunk.iter().any(|&(o, d)| !traceable(o, d)) {
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
            let hits = match &self.bvh {
                Some(bvh) => bvh.intersect_packet(packet),
                None => self.tree.intersect_packet(packet),
            };
            for (k, (ray, hit)) in packet.iter().zip(hits).enumerate() {
                let first = Some(hit.and_then(|h| self.surface(ray, h)));
                out(
                    at + k,
                    self.estimates(ray.origin, ray.dir, first, vdistance, Streams::Shared(rng), fetch),
                );
            }
        }
    }

    /// [`Tracer::trace_together`] with a stand-in caster: one ray at a
    /// time, out of line, so that the tracer's own path stays as it was.
    #[cold]
    #[inline(never)]
    fn trace_cast(&self, rays: &[(Vec3, Vec3)], rng: &mut Rng, out: &mut dyn FnMut(usize, Sample)) {
        let fetch = &mut Fetch::load();
        for (k, &(origin, dir)) in rays.iter().enumerate() {
            out(
                k,
                self.trace_streams(origin, dir, self.options.vdistance, Streams::Shared(rng), fetch),
            );
        }
    }

    /// [`Tracer::trace_fetching`] with the estimates' random numbers drawn
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
            .ooc
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
    /// as [`TraceOptions::reorder`] says. A ray's sample depends on its own
    /// seed alone: neither on `first`, nor on the order the paths are
    /// traced in, nor on which other rays share the batch. Out of core,
    /// rays are traced one by one until every sample is exact (see
    /// [`Tracer::trace_batch`]); a sample only unreadable blocks could have
    /// made comes back as `None`.
    pub fn trace_seeded(&self, rays: &[SeededRay], vdistance: bool, first: FirstHits) -> Vec<Option<Sample>> {
        let streams = |r: &SeededRay| Streams::PerPath {
            seed: r.seed,
            first: r.stream,
        };
        if let Some(ooc) = &self.ooc {
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
            let hits = self.tree.in_order(&starts, order, |r| self.nearest(r, 0.0, &mut fetch));
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
        if way == FirstHits::Packets && self.caster.is_none() {
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

    /// The nearest hit: a triangle, or out of core a voxel (LOD, or a proxy
    /// for missing data, which `fetch` notes).
    pub(super) fn nearest(&self, ray: &Ray, lod: f32, fetch: &mut Fetch) -> Option<SurfaceHit> {
        let Some(ooc) = &self.ooc else {
            return self.intersect_in_core(ray).and_then(|h| self.surface(ray, h));
        };
        let first = self.ooc_surface(ooc.intersect(ray, lod, fetch)?);
        self.past_cutouts(ray, first, |r| {
            ooc.intersect(r, lod, fetch).map(|h| self.ooc_surface(h))
        })
    }

    /// A scene file's hit as shading needs it.
    fn ooc_surface(&self, h: crate::ooc::OocHit) -> SurfaceHit {
        match h.surface {
            OocSurface::Triangle {
                id,
                material,
                vertices: [a, b, c],
                u,
                v,
            } => SurfaceHit {
                t: h.t,
                ng: (b - a).cross(c - a).normalize(),
                tri: id,
                verts: [a, b, c],
                bary: Vec2::new(u, v),
                material: Some(material),
                color: Vec3::ZERO,
                radius: 0.0,
            },
            OocSurface::Voxel { sample, radius, .. } => SurfaceHit {
                t: h.t,
                ng: sample.normal,
                tri: u32::MAX,
                verts: [Vec3::ZERO; 3],
                bary: Vec2::ZERO,
                material: None,
                color: sample.color,
                radius,
            },
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

    /// How much light gets through along a shadow ray: 1 if nothing is in the
    /// way, the product of pane transmittances if only thin panes are, else 0.
    /// One traversal: panes are noted and skipped, the first opaque hit ends it.
    pub(super) fn visibility(&self, ray: Ray, fetch: &mut Fetch) -> Vec3 {
        if self.caster.is_some() {
            return self.visibility_cast(ray);
        }
        if !self.has_panes && !self.cutouts {
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
        let blocked = self.blocked(&ray, fetch, |tri, material, vertices| {
            self.opaque_or_pane(&mut panes, &ray, tri, material, vertices)
        });
        if blocked {
            return Vec3::ZERO;
        }
        self.through_panes(&ray, &panes)
    }

    /// [`Tracer::visibility`] with the ray cast by a stand-in caster: a
    /// function of its own, so that the tracer's own walk keeps its filter
    /// inlined.
    #[cold]
    #[inline(never)]
    fn visibility_cast(&self, ray: Ray) -> Vec3 {
        let Some(caster) = &self.caster else {
            return Vec3::ONE;
        };
        if !self.has_panes && !self.cutouts {
            return if caster.occluded_by(&ray, &mut |_| true) {
                Vec3::ZERO
            } else {
                Vec3::ONE
            };
        }
        let mut panes: Vec<(u32, u32, Vec3)> = Vec::new();
        let blocked = caster.occluded_by(&ray, &mut |tri| {
            let material = self.scene.triangles[tri as usize].material;
            self.opaque_or_pane(&mut panes, &ray, tri, material, self.scene.vertices(tri as usize))
        });
        if blocked {
            return Vec3::ZERO;
        }
        self.through_panes(&ray, &panes)
    }

    /// Whether triangle `tri` (of `material`, with `vertices`) stops the
    /// shadow ray `ray`: true unless it is a thin pane, which is noted in
    /// `panes` (once) and looked past, or a hole of an alpha mask there.
    #[inline(always)]
    fn opaque_or_pane(
        &self,
        panes: &mut Vec<(u32, u32, Vec3)>,
        ray: &Ray,
        tri: u32,
        material: u32,
        [a, b, c]: [Vec3; 3],
    ) -> bool {
        if self.cut_along(ray, tri, material, [a, b, c]) {
            return false;
        }
        let m = &self.scene.materials[material as usize];
        if matches!(m, Material::Glass { thin: true, .. }) {
            if !panes.iter().any(|p| p.0 == tri) {
                panes.push((tri, material, (b - a).cross(c - a).normalize()));
            }
            false
        } else {
            true
        }
    }

    /// The light a shadow ray that nothing opaque stops carries through the
    /// thin panes noted along it (triangle, material, normal).
    fn through_panes(&self, ray: &Ray, panes: &[(u32, u32, Vec3)]) -> Vec3 {
        let dir = ray.dir.normalize();
        let mut through = Vec3::ONE;
        for &(_, material, ng) in panes {
            let m = &self.scene.materials[material as usize];
            through *= pane_transmittance(m, dir.dot(ng).abs()).unwrap_or(Vec3::ZERO);
        }
        through
    }
}
