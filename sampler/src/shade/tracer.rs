//! The tracer: a scene ready to trace, with its one ray caster
//! ([`Caster`]), its lights, its sky and its estimator settings, and the
//! geometric queries the estimator makes of it (nearest surfaces, shadow
//! rays through thin panes and alpha masks, the surface a denoiser's
//! buffers want). The estimator itself is in `estimate.rs` (the entry
//! points), `path.rs` (one path's steps) and `wavefront.rs` (paths stepped
//! together); texture and pattern lookups in `surface.rs`.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use glam::{Vec2, Vec3};

use super::bsdf;
use super::cast::Caster;
use super::hit::SurfaceHit;
use super::lights::Lights;
use super::measured::TwoWays;
use super::options::{way_of, FirstHits, TraceOptions, AUTO_MIN_PATHS};
use super::sky::SkyModel;
use crate::geom::Ray;
use crate::ooc::{Fetch, InCoreReport, OocError, OocScene, OocSurface};
use crate::scene::{Material, Scene};

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

/// A scene ready to trace: its one ray caster (in memory, the wide BVH or
/// the kd-tree or another library's; or a scene file traced out of core),
/// lights and sky, and the estimator's settings.
pub struct Tracer {
    pub(super) scene: Scene,
    /// What every ray is cast against.
    pub(super) caster: Caster,
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
    pub(super) non_finite: AtomicU64,
    /// Times of first hits in packets (way 0) and one by one (way 1).
    pub(super) first_hits: TwoWays,
    /// Times of paths sorted a segment at a time (way 0) and each to its
    /// end (way 1), for [`Reorder::Auto`](super::Reorder::Auto).
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

impl Tracer {
    /// A tracer over a scene in memory, cast by the wide BVH where the
    /// scene fits it and by the kd-tree otherwise ([`Caster::in_core`]).
    pub fn new(scene: Scene, options: TraceOptions) -> Tracer {
        let caster = Caster::in_core(&scene);
        Tracer::with_caster(scene, caster, options)
    }

    /// A tracer over `scene` whose rays `caster` casts (which must hold
    /// the scene's triangles with their indices, or for
    /// [`Caster::OutOfCore`] be the file `scene` is the shell of).
    pub fn with_caster(scene: Scene, caster: Caster, options: TraceOptions) -> Tracer {
        let lights = match caster.file() {
            Some(ooc) => file_lights(ooc, &scene),
            None => Lights::new(&scene),
        };
        Tracer::assemble(scene, caster, lights, options)
    }

    /// A tracer over an open scene file: materials, sky, sections and lights
    /// come from its header, triangles from its blocks as rays need them.
    pub fn out_of_core(ooc: Arc<OocScene>, options: TraceOptions) -> Tracer {
        let scene = ooc.shell();
        Tracer::with_caster(scene, Caster::OutOfCore(ooc), options)
    }

    /// A tracer over a scene file assembled in memory (see
    /// [`OocScene::in_core`]): the in-core walk, with the hits the
    /// out-of-core walk finds; no LOD, since there are no voxels in core.
    pub fn in_core_from_file(ooc: &OocScene, options: TraceOptions) -> Result<Tracer, OocError> {
        let (scene, tree, report) = ooc.in_core()?;
        let lights = file_lights(ooc, &scene);
        let caster = Caster::around_tree(&scene, tree);
        let mut t = Tracer::assemble(scene, caster, lights, options);
        t.assembled = Some(report);
        Ok(t)
    }

    /// For a tracer made with [`Tracer::in_core_from_file`]: what assembling took.
    pub fn assembled(&self) -> Option<&InCoreReport> {
        self.assembled.as_ref()
    }

    /// The tracer around its caster: the sky model and whether thin panes
    /// need their shadow-ray pass follow from the scene.
    fn assemble(scene: Scene, caster: Caster, lights: Lights, options: TraceOptions) -> Tracer {
        let sky = SkyModel::new(&scene.sky);
        let has_panes = scene
            .materials
            .iter()
            .any(|m| matches!(m, Material::Glass { thin: true, .. }));
        let file = caster.file().is_some();
        // A scene file keeps its texture coordinates; in core they are in the scene.
        let cutouts = (file || !scene.uvs.is_empty()) && scene.maps.iter().any(|m| m.cuts());
        let textured_any = scene.maps.iter().any(|m| !m.is_empty());
        let in_core_bytes = caster.bytes()
            + scene.positions.len() * std::mem::size_of::<Vec3>()
            + scene.triangles.len() * std::mem::size_of::<crate::scene::Triangle>();
        Tracer {
            in_core_bytes,
            scene,
            caster,
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

    /// What the tracer casts its rays against.
    pub fn caster(&self) -> &Caster {
        &self.caster
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

    /// How [`FirstHits::Measured`] finds first hits now, by the times so far.
    pub fn first_hits_preferred(&self) -> FirstHits {
        way_of(self.first_hits.preferred())
    }

    /// Estimates that came out NaN or infinite and were replaced by black.
    pub fn non_finite_count(&self) -> u64 {
        self.non_finite.load(Ordering::Relaxed)
    }

    /// The nearest hit: a triangle, or out of core a voxel (LOD, or a proxy
    /// for missing data, which `fetch` notes).
    pub(super) fn nearest(&self, ray: &Ray, lod: f32, fetch: &mut Fetch) -> Option<SurfaceHit> {
        let Caster::OutOfCore(ooc) = &self.caster else {
            return self.caster.intersect(ray).and_then(|h| self.surface(ray, h));
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
        match &self.caster {
            Caster::OutOfCore(ooc) => ooc.occluded_by(ray, self.options.lod_secondary, fetch, blocks),
            caster => caster.occluded_by(ray, |t: u32| {
                blocks(
                    t,
                    self.scene.triangles[t as usize].material,
                    self.scene.vertices(t as usize),
                )
            }),
        }
    }

    /// How much light gets through along a shadow ray: 1 if nothing is in the
    /// way, the product of pane transmittances if only thin panes are, else 0.
    /// One traversal: panes are noted and skipped, the first opaque hit ends it.
    pub(super) fn visibility(&self, ray: Ray, fetch: &mut Fetch) -> Vec3 {
        if !self.has_panes && !self.cutouts {
            let blocked = match &self.caster {
                Caster::OutOfCore(_) => self.blocked(&ray, fetch, |_, _, _| true),
                caster => caster.occluded(&ray),
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
