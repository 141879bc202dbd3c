//! What a ray finds where it hits a textured surface: holes cut by alpha
//! masks (which every ray, shadow rays included, passes through), the
//! material at the hit's texture coordinates, and the shading normal a
//! normal or height map gives.
//!
//! Texture footprints follow a ray cone (Akenine-Möller et al., "Texture
//! Level of Detail Strategies for Real-Time Ray Tracing", 2019): a cone of
//! [`CONE_SPREAD`] radians around every ray, as wide at the hit as the path
//! is long times the spread, measured in texture coordinates through the
//! triangle's ratio of texture area to world area.

use glam::{Vec2, Vec3};

use super::hit::SurfaceHit;
use super::lights::LightSample;
use super::tracer::Tracer;
use crate::accel::Hit;
use crate::geom::{intersect_triangle, offset_origin, Ray, RayPrep};
use crate::scene::maps::tinted;
use crate::scene::pattern::{effect_of, PatternHit};
use crate::scene::Material;

/// Angle a ray's footprint widens by per unit of length: about a pixel of
/// a 1000-pixel-wide view with a 60 degree field.
pub const CONE_SPREAD: f32 = 1e-3;

/// Most alpha-cut surfaces one ray passes before it counts as blocked (a
/// forest seen edge-on).
const MAX_CUTOUTS: usize = 64;

/// A uniform number in [0, 1) from a hit and the ray's direction: which
/// rays partial coverage lets through, the same for the same ray whichever
/// way (packets, wavefront, one by one) it was traced.
#[inline]
fn coverage_number(tri: u32, bary: Vec2, dir: Vec3) -> f32 {
    let mut h = u64::from(tri) ^ 0x9e37_79b9_7f4a_7c15;
    for bits in [bary.x, bary.y, dir.x, dir.y, dir.z].map(f32::to_bits) {
        h = (h ^ u64::from(bits)).wrapping_mul(0xff51_afd7_ed55_8ccd);
        h ^= h >> 33;
    }
    (h >> 40) as f32 / (1u64 << 24) as f32
}

impl Tracer {
    /// The texture coordinates of triangle `tri`'s vertices (in core, or
    /// kept by a scene file), if it has any.
    #[inline]
    fn tri_uvs(&self, tri: u32) -> Option<[Vec2; 3]> {
        match self.caster.file() {
            Some(ooc) => ooc.triangle_uvs(tri),
            None if self.scene.uvs.is_empty() => None,
            None => Some(self.scene.triangle_uvs(tri as usize)),
        }
    }

    /// The tangents of triangle `tri`'s vertices, where its file gave them.
    #[inline]
    fn tri_tangents(&self, tri: u32) -> Option<[glam::Vec4; 3]> {
        match self.caster.file() {
            Some(ooc) => ooc.triangle_tangents(tri),
            None if self.scene.tangents.is_empty() => None,
            None => self.scene.triangle_tangents(tri as usize),
        }
    }

    /// The texture coordinates of triangle `tri` at barycentrics `bary`.
    #[inline]
    fn uv_at(&self, tri: u32, bary: Vec2) -> Vec2 {
        let [a, b, c] = self.tri_uvs(tri).unwrap_or([Vec2::ZERO; 3]);
        a * (1.0 - bary.x - bary.y) + b * bary.x + c * bary.y
    }

    /// Whether a ray along `dir` passes through triangle `tri` (of
    /// `material`) at `bary` (a hole of its material's alpha mask).
    #[inline]
    pub(super) fn cut_at(&self, tri: u32, material: u32, bary: Vec2, dir: Vec3) -> bool {
        let Some(maps) = self.scene.maps_of(material) else {
            return false;
        };
        maps.cuts()
            && maps.passes(
                &self.scene.textures,
                self.uv_at(tri, bary),
                coverage_number(tri, bary, dir),
            )
    }

    /// Whether triangle `tri` of `material` with `vertices`, crossed by
    /// `ray`, is a hole there (for shadow rays, which learn only which
    /// triangle they met).
    pub(super) fn cut_along(&self, ray: &Ray, tri: u32, material: u32, [a, b, c]: [Vec3; 3]) -> bool {
        if !self.cutouts {
            return false;
        }
        let prep = RayPrep::new(ray.origin, ray.dir);
        match intersect_triangle(&prep, a, b, c, f32::INFINITY) {
            Some(h) => self.cut_at(tri, material, Vec2::new(h.u, h.v), ray.dir),
            None => false,
        }
    }

    /// Where `hit` (of `ray`, from a scene file) is a hole of an alpha
    /// mask, the first solid surface beyond it, as `next` finds nearest
    /// hits; `None` where the ray escapes through the holes.
    pub(super) fn past_cutouts(
        &self,
        ray: &Ray,
        mut hit: SurfaceHit,
        mut next: impl FnMut(&Ray) -> Option<SurfaceHit>,
    ) -> Option<SurfaceHit> {
        if !self.cutouts {
            return Some(hit);
        }
        let mut travelled = 0.0;
        for _ in 0..MAX_CUTOUTS {
            let Some(material) = hit.material else { break };
            if hit.tri == u32::MAX || !self.cut_at(hit.tri, material, hit.bary, ray.dir) {
                break;
            }
            let at = ray.origin + ray.dir * (travelled + hit.t);
            let side = if ray.dir.dot(hit.ng) > 0.0 { hit.ng } else { -hit.ng };
            let origin = offset_origin(at, side);
            let moved = (origin - ray.origin).dot(ray.dir) / ray.dir.length_squared();
            let beyond = Ray {
                origin,
                dir: ray.dir,
                t_max: ray.t_max - moved,
            };
            travelled = moved;
            hit = next(&beyond)?;
        }
        hit.t += travelled;
        Some(hit)
    }

    /// An in-core triangle hit of `ray` as shading needs it: where the hit
    /// is a hole of an alpha mask, the first solid surface beyond it
    /// (`None` where the ray escapes through the holes).
    pub(super) fn surface(&self, ray: &Ray, mut h: Hit) -> Option<SurfaceHit> {
        if self.cutouts {
            let mut r = *ray;
            let mut travelled = 0.0;
            let mut passed = 0;
            let material = |t: u32| self.scene.triangles[t as usize].material;
            while self.cut_at(h.tri, material(h.tri), Vec2::new(h.u, h.v), ray.dir) {
                passed += 1;
                if passed > MAX_CUTOUTS {
                    break;
                }
                let [a, b, c] = self.scene.vertices(h.tri as usize);
                let ng = (b - a).cross(c - a);
                let side = if r.dir.dot(ng) > 0.0 { ng } else { -ng };
                let origin = offset_origin(r.at(h.t), side.normalize());
                let moved = (origin - ray.origin).dot(ray.dir) / ray.dir.length_squared();
                r = Ray {
                    origin,
                    dir: ray.dir,
                    t_max: ray.t_max - moved,
                };
                travelled = moved;
                h = self.caster.intersect(&r)?;
            }
            h.t += travelled;
        }
        let [a, b, c] = self.scene.vertices(h.tri as usize);
        Some(SurfaceHit {
            t: h.t,
            ng: (b - a).cross(c - a).normalize(),
            tri: h.tri,
            verts: [a, b, c],
            bary: Vec2::new(h.u, h.v),
            material: Some(self.scene.triangles[h.tri as usize].material),
            color: Vec3::ZERO,
            radius: 0.0,
        })
    }

    /// The material at `hit` with its textures and patterns applied, the
    /// shading normal its relief map or `texfunc` gives (on the side of
    /// `n`, the geometric normal as shading faces it) and the radiance its
    /// emission texture adds; `None` where the material has none. `length`
    /// is how far the path has come, for the footprint; `dir` the ray's
    /// direction, for patterns.
    #[inline]
    pub(super) fn textured(&self, hit: &SurfaceHit, n: Vec3, length: f32, dir: Vec3) -> Option<Textured> {
        if !self.textured_any {
            return None;
        }
        self.textured_slow(hit, n, length, dir)
    }

    /// [`Tracer::textured`] where some material has textures: out of line,
    /// so that untextured scenes shade as before.
    #[inline(never)]
    fn textured_slow(&self, hit: &SurfaceHit, n: Vec3, length: f32, dir: Vec3) -> Option<Textured> {
        let material = hit.material?;
        let maps = self.scene.maps_of(material)?;
        if hit.tri == u32::MAX {
            return None;
        }
        let mut t = match self.tri_uvs(hit.tri) {
            Some(uvs) => self.mapped(hit, n, length, uvs, maps, material),
            None => Textured {
                material: self.scene.materials[material as usize].clone(),
                normal: None,
                emission: Vec3::ZERO,
            },
        };
        if !maps.patterns.is_empty() {
            let [pa, pb, pc] = hit.verts;
            let point = pa * (1.0 - hit.bary.x - hit.bary.y) + pb * hit.bary.x + pc * hit.bary.y;
            let at = PatternHit {
                point,
                normal: hit.ng,
                dir: dir.normalize_or_zero(),
                path: length,
                length: hit.t,
            };
            let e = effect_of(&maps.patterns, &at);
            t.material = tinted(&t.material, e.color);
            t.emission *= e.color;
            if e.bend != Vec3::ZERO {
                let bent = (t.normal.unwrap_or(n) + e.bend).try_normalize();
                t.normal = bent.or(t.normal);
            }
        }
        Some(t)
    }

    /// The material, normal and emission the texture maps give at `hit`,
    /// whose triangle has texture coordinates `uvs`.
    fn mapped(
        &self,
        hit: &SurfaceHit,
        n: Vec3,
        length: f32,
        [ta, tb, tc]: [Vec2; 3],
        maps: &crate::scene::MaterialMaps,
        material: u32,
    ) -> Textured {
        let [pa, pb, pc] = hit.verts;
        let uv = ta * (1.0 - hit.bary.x - hit.bary.y) + tb * hit.bary.x + tc * hit.bary.y;
        let (e1, e2) = (pb - pa, pc - pa);
        let (d1, d2) = (tb - ta, tc - ta);
        let world_area = e1.cross(e2).length();
        let uv_area = (d1.x * d2.y - d1.y * d2.x).abs();
        let width = CONE_SPREAD * length * (uv_area / world_area).sqrt();
        let textures = &self.scene.textures;
        let m = maps.material_at(&self.scene.materials[material as usize], textures, uv, width);
        let emission = maps.emission_at(textures, uv, width);
        let normal = maps.relief.and_then(|_| {
            // The file's tangents where it gives them (glTF): the bitangent,
            // cross(n, t) * w, is where the map's green points, against +v.
            if let Some(tangents) = self.tri_tangents(hit.tri) {
                let w = [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y];
                let t: Vec3 = tangents.iter().zip(w).map(|(t, w)| t.truncate() * w).sum();
                let side = tangents[0].w;
                return maps.normal_at(textures, uv, n, t, -n.cross(t) * side);
            }
            // The directions in which u and v grow, from the triangle's edges.
            let det = d1.x * d2.y - d1.y * d2.x;
            if det == 0.0 || !det.is_finite() {
                return None;
            }
            let t = (e1 * d2.y - e2 * d1.y) / det;
            let b = (e2 * d1.x - e1 * d2.x) / det;
            maps.normal_at(textures, uv, n, t, b)
        });
        Textured {
            material: m,
            normal,
            emission,
        }
    }

    /// The radiance a light sample brings toward a point `distance` away
    /// along `dir` (unit, from the point toward the light): its light's,
    /// or where the light glows through an emission texture, what the
    /// texture says there, times what its patterns say for that ray.
    #[inline]
    pub(super) fn light_radiance(&self, ls: &LightSample, dir: Vec3, distance: f32) -> Vec3 {
        if !self.textured_any {
            return ls.radiance;
        }
        let Some(maps) = self.scene.maps_of(ls.material) else {
            return ls.radiance;
        };
        let mut le = ls.radiance;
        if maps.emissive.is_some() && self.tri_uvs(ls.tri).is_some() {
            let uv = self.uv_at(ls.tri, Vec2::new(ls.bary.0, ls.bary.1));
            let base = self
                .scene
                .materials
                .get(ls.material as usize)
                .map_or([0.0; 3], Material::emission);
            le = Vec3::from_array(base) + maps.emission_at(&self.scene.textures, uv, 0.0);
        }
        if !maps.patterns.is_empty() {
            let at = PatternHit {
                point: ls.point,
                normal: ls.normal,
                dir,
                path: distance,
                length: distance,
            };
            le *= effect_of(&maps.patterns, &at).color;
        }
        le
    }
}

/// A textured hit's material, shading normal and emission.
pub(super) struct Textured {
    /// The material with its textures applied.
    pub(super) material: Material,
    /// The relief map's shading normal, if any.
    pub(super) normal: Option<Vec3>,
    /// Radiance the emission texture adds.
    pub(super) emission: Vec3,
}
