//! One path of the estimator as a state that advances a segment at a time.
//!
//! A segment's work is split where rays are cast: the caller finds the
//! segment's nearest hit, [`Tracer::shade`] turns it into light, the next
//! ray and the shadow rays of next-event estimation, and the caller then
//! answers those shadow rays and hands back what they saw
//! ([`Path::add_direct`]). Walking one path to its end this way is the
//! depth-first estimator ([`Tracer::estimate`]); stepping many paths
//! together, with each step's rays sorted, is the wavefront one
//! (`wavefront.rs`). Both draw the same random numbers in the same order
//! and add the same terms in the same order, so a path's estimate is the
//! same bits either way: the order in which rays are cast changes nothing
//! but speed.
//!
//! Never: cast a ray itself (other than through the depth-first driver), or
//! read a random number anywhere but in [`Tracer::shade`].

use glam::Vec3;

use super::bsdf::{self, is_delta, transmits};
use super::hit::SurfaceHit;
use super::rng::Rng;
use super::sampling::{power_heuristic, Frame};
use super::tracer::Tracer;
use crate::geom::{offset_origin, Ray};
use crate::ooc::Fetch;
use crate::scene::Material;

/// Segments a path may take beyond its bounce limit: crossing a thin pane
/// is not a bounce, and this stops a path that only crosses panes.
const EXTRA_SEGMENTS: u32 = 64;

pub(super) fn flat_specular(m: &Material) -> bool {
    matches!(m, Material::Mirror { .. } | Material::Glass { thin: true, .. })
        || matches!(m, Material::Metal { roughness, .. } if *roughness < 0.02)
}

/// A path between segments: the ray it casts next and what it has gathered.
#[derive(Clone, Debug)]
pub(super) struct Path {
    /// The next segment's ray.
    pub(super) ray: Ray,
    /// Radiance gathered so far.
    l: Vec3,
    /// Throughput to the next vertex.
    beta: Vec3,
    /// The distance to report (first hit, or virtual through flat specular
    /// surfaces with VDISTANCE); infinity until something is hit.
    distance: f32,
    /// Length of the path so far, for virtual distances.
    path: f32,
    /// Whether the distance still grows (VDISTANCE through flat specular hits).
    measuring: bool,
    vdistance: bool,
    /// How the direction of the last scattering was sampled, for MIS at the
    /// light it finds: a delta lobe, or this solid-angle pdf.
    prev_delta: bool,
    prev_pdf: f32,
    /// Distance from the last scattering vertex: panes crossed on the way
    /// do not scatter, so light-sampling pdfs are measured from that vertex.
    travelled: f32,
    /// Length of the whole path so far (texture footprints).
    length: f32,
    /// Scattering events so far (crossing a pane is not one).
    depth: u32,
    /// Segments cast so far.
    pub(super) segment: u32,
    /// Set where a thin pane reflected the path while its distance was still
    /// measured: the ray straight on through the pane, whose first surface
    /// gives the distance instead (see [`Tracer::look_straight_on`]).
    straight: Option<Ray>,
}

/// Light one vertex sampled directly, waiting on its shadow rays: each ray
/// (toward a point on the area lights, toward the sun) with what it adds
/// where nothing is in the way, and the path's throughput at the vertex.
#[derive(Clone, Copy, Debug, Default)]
pub(super) struct Direct {
    beta: Vec3,
    pub(super) shadows: [Option<(Ray, Vec3)>; 2],
}

/// What a segment's shading left to do: whether it sampled light directly
/// (its shadow rays are to be answered), and whether the path goes on with
/// its new ray.
#[derive(Clone, Copy, Debug)]
pub(super) struct Step {
    pub(super) direct: bool,
    pub(super) goes_on: bool,
}

impl Step {
    fn ends(direct: bool) -> Step {
        Step { direct, goes_on: false }
    }
}

impl Path {
    /// A path starting along the unit direction `dir` from `origin`.
    pub(super) fn new(origin: Vec3, dir: Vec3, vdistance: bool) -> Path {
        Path {
            ray: Ray::new(origin, dir),
            l: Vec3::ZERO,
            beta: Vec3::ONE,
            distance: f32::INFINITY,
            path: 0.0,
            measuring: true,
            vdistance,
            prev_delta: true,
            prev_pdf: 0.0,
            travelled: 0.0,
            length: 0.0,
            depth: 0,
            segment: 0,
            straight: None,
        }
    }

    /// Adds the light a vertex sampled directly, given what each of its
    /// shadow rays lets through (asked in the order of [`Direct::shadows`]).
    #[inline(always)]
    pub(super) fn add_direct(&mut self, d: &Direct, mut seen: impl FnMut(&Ray) -> Vec3) {
        let mut l = Vec3::ZERO;
        for (ray, contribution) in d.shadows.iter().flatten() {
            let vis = seen(ray);
            if vis.max_element() > 0.0 {
                l += vis * *contribution;
            }
        }
        self.l += d.beta * l;
    }

    /// The radiance gathered and the distance to report.
    pub(super) fn result(&self) -> (Vec3, f32) {
        (self.l, self.distance)
    }
}

impl Tracer {
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

    /// One path's radiance and first distance, walked depth first; `first`,
    /// when given, is the hit of the first segment (found beforehand, in core).
    pub(super) fn estimate(
        &self,
        origin: Vec3,
        dir: Vec3,
        mut first: Option<Option<SurfaceHit>>,
        vdistance: bool,
        rng: &mut Rng,
        fetch: &mut Fetch,
    ) -> (Vec3, f32) {
        let mut p = Path::new(origin, dir, vdistance);
        let mut direct = Direct::default();
        loop {
            let lod = if p.segment == 0 {
                self.options.lod_primary
            } else {
                self.options.lod_secondary
            };
            let hit = match first.take() {
                Some(hit) => hit,
                None => self.nearest(&p.ray, lod, fetch),
            };
            if fetch.missed {
                break;
            }
            let step = self.shade(&mut p, hit, rng, &mut direct);
            self.look_straight_on(&mut p, fetch);
            if step.direct {
                p.add_direct(&direct, |ray| self.visibility(*ray, fetch));
                if fetch.missed {
                    break;
                }
            }
            if !step.goes_on {
                break;
            }
        }
        p.result()
    }

    /// Where a pane reflected `p` while its distance was measured, finds
    /// the distance straight on through the pane (and any panes behind it)
    /// to the first other surface; infinite where the line escapes.
    pub(super) fn look_straight_on(&self, p: &mut Path, fetch: &mut Fetch) {
        const PANES: usize = 8;
        let Some(mut ray) = p.straight.take() else { return };
        let mut t = 0.0;
        for _ in 0..PANES {
            let Some(h) = self.nearest(&ray, 0.0, fetch) else {
                p.distance = f32::INFINITY;
                return;
            };
            t += h.t;
            let pane = h
                .material
                .is_some_and(|m| matches!(self.scene.materials[m as usize], Material::Glass { thin: true, .. }));
            if !pane {
                break;
            }
            let side = if ray.dir.dot(h.ng) > 0.0 { h.ng } else { -h.ng };
            ray = Ray::new(offset_origin(ray.at(h.t), side), ray.dir);
        }
        p.distance = p.path + t;
    }

    /// Shades the hit of `p`'s ray (`None`: it escaped): adds what it
    /// emits or what the sky sends, samples lights for shadow rays, and
    /// samples the BSDF for the next ray. Every random number a path uses
    /// is drawn here.
    ///
    /// Long because it is the estimator's one place of randomness: the order
    /// in which it draws random numbers is what makes the depth-first and
    /// wavefront estimates the same bits (see the module doc), and it reads
    /// as that order, top to bottom.
    #[inline(always)]
    pub(super) fn shade(&self, p: &mut Path, hit: Option<SurfaceHit>, rng: &mut Rng, direct: &mut Direct) -> Step {
        let o = &self.options;
        let Some(hit) = hit else {
            p.l += p.beta * self.sky.background(p.ray.dir);
            let sun = self.sky.sun(p.ray.dir);
            if sun.max_element() > 0.0 {
                let w = if p.prev_delta || !o.light_sampling {
                    1.0
                } else {
                    power_heuristic(p.prev_pdf, self.sky.sun_pdf())
                };
                p.l += p.beta * sun * w;
            }
            if p.measuring {
                p.distance = f32::INFINITY;
            }
            return Step::ends(false);
        };
        let proxy;
        let ng = hit.ng;
        p.length += hit.t;
        let (textured, relief, glow) = match self.textured(&hit, ng, p.length, p.ray.dir) {
            Some(t) => (Some(t.material), t.normal, t.emission),
            None => (None, None, Vec3::ZERO),
        };
        let m = match (&textured, hit.material) {
            (Some(m), _) => m,
            (None, Some(i)) => &self.scene.materials[i as usize],
            (None, None) => {
                proxy = Material::lambertian(hit.color.to_array());
                &proxy
            }
        };
        let point = p.ray.at(hit.t);
        if p.measuring {
            p.path += hit.t;
            p.distance = p.path;
            p.measuring = p.vdistance && flat_specular(m);
        }
        p.travelled += hit.t;
        let wo_world = -p.ray.dir;
        let cos_o = wo_world.dot(ng);
        let le = Vec3::from_array(m.emission()) + glow;
        if cos_o > 0.0 && le.max_element() > 0.0 {
            let w = if p.prev_delta || !o.light_sampling {
                1.0
            } else {
                let pdf_light = self.lights.pdf_area(hit.tri) * p.travelled * p.travelled / cos_o;
                power_heuristic(p.prev_pdf, pdf_light)
            };
            p.l += p.beta * le * w;
        }
        let pane = matches!(m, Material::Glass { thin: true, .. });
        if (p.depth == o.max_bounces && !pane) || matches!(m, Material::Emitter { .. }) {
            return Step::ends(false);
        }
        let n = if transmits(m) || cos_o > 0.0 { ng } else { -ng };
        // A relief map's normal shades where the ray sees its side of it;
        // where it would face away from the ray, the geometric normal does.
        let shading = match relief {
            Some(r) if !transmits(m) => {
                let r = if n == ng { r } else { -r };
                if r.dot(wo_world) > 0.0 {
                    r
                } else {
                    n
                }
            }
            _ => n,
        };
        let frame = Frame::new(shading);
        let wo = frame.to_local(wo_world);
        // Rays leaving a voxel start beyond it (Áfra 2012, 6.3).
        let skip = 2.0 * hit.radius;
        let sampled = !is_delta(m) && o.light_sampling;
        if sampled {
            direct.beta = p.beta;
            self.sample_direct(m, point, &frame, wo, skip, rng, &mut direct.shadows);
        }
        let Some(s) = bsdf::sample(m, wo, [rng.f32(), rng.f32(), rng.f32()]) else {
            return Step::ends(sampled);
        };
        p.beta *= s.weight;
        let passed_pane = pane && s.wi == -wo;
        if pane && !passed_pane && p.measuring {
            // What a window shows is what lies straight on through it: its
            // reflection is reported at that distance too, so the few paths
            // a pane reflects join the view through it instead of standing
            // in front of it and hiding it from a display's depth test.
            p.measuring = false;
            let side = if p.ray.dir.dot(ng) > 0.0 { ng } else { -ng };
            p.straight = Some(Ray::new(offset_origin(point, side), p.ray.dir));
        }
        if !passed_pane && p.depth == o.max_bounces {
            // A pane's reflection at the last bounce would be one bounce too many.
            return Step::ends(sampled);
        }
        if !passed_pane {
            p.depth += 1;
            // Crossing a pane keeps the direction, so the vertex before it
            // still decides how the light at the end was sampled.
            p.prev_delta = s.delta;
            p.prev_pdf = s.pdf;
            p.travelled = 0.0;
        }
        let wi = if passed_pane {
            p.ray.dir
        } else {
            frame.to_world(s.wi).normalize()
        };
        if shading != n && wi.dot(n) <= 0.0 {
            // A bent normal sent the ray into the surface: it ends there
            // rather than leak light from behind.
            return Step::ends(sampled);
        }
        let side = if wi.dot(ng) > 0.0 { ng } else { -ng };
        p.ray = Ray::new(offset_origin(point, side) + wi * skip, wi);
        if !passed_pane && p.depth > o.roulette_after {
            let q = p.beta.max_element().min(0.95);
            if q.is_nan() || q <= 0.0 || rng.f32() >= q {
                return Step::ends(sampled);
            }
            p.beta /= q;
        }
        p.segment += 1;
        Step {
            direct: sampled,
            goes_on: p.segment < o.max_bounces.saturating_add(EXTRA_SEGMENTS),
        }
    }

    /// Shadow rays toward one sampled point on the area lights and one on
    /// the sun, each with the light it brings (MIS-weighted against BSDF
    /// sampling) where nothing is in the way, into `shadows`.
    #[inline(always)]
    #[allow(clippy::too_many_arguments)]
    fn sample_direct(
        &self,
        m: &Material,
        p: Vec3,
        frame: &Frame,
        wo: Vec3,
        skip: f32,
        rng: &mut Rng,
        shadows: &mut [Option<(Ray, Vec3)>; 2],
    ) {
        let origin = offset_origin(p, frame.n) + frame.n * skip;
        *shadows = [None, None];
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
                    let pdf_light = ls.pdf_area * dist2 / cos_l;
                    // Panes let light through here too, attenuated: BSDF paths
                    // cross them, so light sampling must see through them alike.
                    let ray = Ray {
                        origin,
                        dir: to,
                        t_max: 1.0 - 1e-4,
                    };
                    shadows[0] = Some((
                        ray,
                        e.f_cos
                            * self.light_radiance(&ls, wi_world, dist2.sqrt())
                            * (power_heuristic(pdf_light, e.pdf) / pdf_light),
                    ));
                }
            }
        }
        if let Some((wi_world, sun, pdf_sun)) = self.sky.sample_sun(rng.f32x2()) {
            let wi = frame.to_local(wi_world);
            if wi.z > 0.0 {
                let e = bsdf::eval(m, wo, wi);
                if e.f_cos.max_element() > 0.0 {
                    shadows[1] = Some((
                        Ray::new(origin, wi_world),
                        e.f_cos * sun * (power_heuristic(pdf_sun, e.pdf) / pdf_sun),
                    ));
                }
            }
        }
    }
}
