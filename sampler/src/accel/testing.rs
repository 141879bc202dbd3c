//! Test scenes for the acceleration structure: random triangle soups with the
//! cases that break naive tracers.

use glam::{Mat4, Vec3};
use rand::{Rng, SeedableRng};

use crate::accel::Hit;
use crate::geom::{intersect_triangle, Aabb, Ray, RayPrep};
use crate::scene::{Material, Scene, SceneBuilder};

/// The nearest hit within `(0, ray.t_max]` with every triangle tested on its
/// own, ties in distance going to the lowest triangle index: what the wide
/// BVH must find exactly, and the kd-tree to rounding at shared edges.
pub fn nearest_of_all(scene: &Scene, ray: &Ray) -> Option<Hit> {
    let prep = RayPrep::new(ray.origin, ray.dir);
    let mut best: Option<Hit> = None;
    for i in 0..scene.triangles.len() {
        let [a, b, c] = scene.vertices(i);
        // A limit a little beyond, so that the scaled comparison's rounding
        // never drops a triangle at exactly `t_max`; then the exact check.
        let Some(h) = intersect_triangle(&prep, a, b, c, ray.t_max * (1.0 + 1e-6)) else {
            continue;
        };
        if h.t <= ray.t_max && best.is_none_or(|b| h.t < b.t) {
            best = Some(Hit {
                t: h.t,
                tri: i as u32,
                u: h.u,
                v: h.v,
            });
        }
    }
    best
}

/// A point just off a random triangle of `scene` (inside its edges, 1e-5
/// along its normal), and that normal: where a sampler's bounce rays start.
pub fn point_off_surface(scene: &Scene, rng: &mut impl Rng) -> (Vec3, Vec3) {
    let t = rng.gen_range(0..scene.triangles.len());
    let [a, b, c] = scene.vertices(t);
    let n = (b - a).cross(c - a).normalize();
    let (u, v) = (rng.gen_range(0.05..0.45), rng.gen_range(0.05..0.45));
    (a + u * (b - a) + v * (c - a) + n * 1e-5, n)
}

/// A ray and a box whose entry and exit fall at one point of the ray, the
/// hardest case for a conservative slab test: the ray enters the slab of
/// one axis and leaves the slab of another at the same distance, the third
/// slab wide around it, each face through that point rounded to single
/// precision, so that exact arithmetic finds about half of such boxes
/// touched and half missed by a hair. Origins at scale 1, 100 or 3,000,
/// some directions short, every pair of axes, each drawn on its own; `None`
/// for a direction with a component too small to aim with.
pub fn grazed_box(rng: &mut impl Rng) -> Option<(Ray, Aabb)> {
    let scale = [1.0f32, 100.0, 3000.0][rng.gen_range(0..3)];
    let origin = random_vec3(rng, 1.0) * scale;
    let dir = random_vec3(rng, 1.0) * if rng.gen_bool(0.15) { 1e-3 } else { 1.0 };
    if dir.abs().min_element() < 1e-4 * dir.length() {
        return None;
    }
    let ray = Ray::new(origin, dir);
    let (enter, leave) = [(0, 1), (1, 0), (0, 2), (2, 0), (1, 2), (2, 1)][rng.gen_range(0..6)];
    let t = rng.gen_range(0.01..50.0) * f64::from(scale) / f64::from(dir.length());
    let p = ray.origin.as_dvec3() + t * ray.dir.as_dvec3();
    let p = p.as_vec3();
    let (mut lo, mut hi) = (p - Vec3::splat(scale), p + Vec3::splat(scale));
    if ray.dir[enter] > 0.0 {
        lo[enter] = p[enter];
    } else {
        hi[enter] = p[enter];
    }
    if ray.dir[leave] > 0.0 {
        hi[leave] = p[leave];
    } else {
        lo[leave] = p[leave];
    }
    Some((ray, Aabb { lo, hi }))
}

/// Whether `ray` meets `b` within `[0, closest]`, worked out in double
/// precision on the single-precision inputs (relative error near 1e-16),
/// or `None` where that is too close to call.
pub fn touches_exactly(ray: &Ray, b: &Aabb, closest: f32) -> Option<bool> {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    let (lo, hi) = (b.lo.as_dvec3(), b.hi.as_dvec3());
    let (mut near, mut far) = (0f64, f64::from(closest));
    for c in 0..3 {
        let (t0, t1) = ((lo[c] - o[c]) / d[c], (hi[c] - o[c]) / d[c]);
        near = near.max(t0.min(t1));
        far = far.min(t0.max(t1));
    }
    ((far - near).abs() > 1e-13 * near.abs().max(far.abs())).then_some(near <= far)
}

/// The distance at which `ray` enters `b` (at least 0), in double precision.
pub fn entry_exactly(ray: &Ray, b: &Aabb) -> f64 {
    let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
    (0..3)
        .map(|c| ((f64::from(b.lo[c]) - o[c]) / d[c]).min((f64::from(b.hi[c]) - o[c]) / d[c]))
        .fold(0f64, f64::max)
}

/// Checks a slab test against exact arithmetic on 60,000 grazed boxes
/// ([`grazed_box`], drawn from `seed`), with no limit or the limit at the
/// entry itself: `passes(ray, box, limit)` must be true for every box exact
/// arithmetic finds touched. Both sides of the hair must be well represented.
pub fn every_touched_box_passes(seed: u64, mut passes: impl FnMut(&Ray, Aabb, f32) -> bool) {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let (mut touched, mut missed) = (0, 0);
    for k in 0..60_000 {
        let Some((ray, b)) = grazed_box(&mut rng) else {
            continue;
        };
        let closest = if rng.gen_bool(0.5) {
            f32::INFINITY
        } else {
            (entry_exactly(&ray, &b) as f32).next_up()
        };
        match touches_exactly(&ray, &b, closest) {
            Some(true) => {
                touched += 1;
                assert!(passes(&ray, b, closest), "ray {k} {ray:?} box {b:?} limit {closest}");
            }
            Some(false) => missed += 1,
            None => {}
        }
    }
    assert!(
        touched > 10_000 && missed > 10_000,
        "{touched} touched, {missed} missed"
    );
}

/// A random point (or direction) in the cube `[-r, r)^3`.
pub fn random_vec3(rng: &mut impl Rng, r: f32) -> Vec3 {
    Vec3::new(rng.gen_range(-r..r), rng.gen_range(-r..r), rng.gen_range(-r..r))
}

/// A soup of random triangles plus deliberately nasty ones: a grid of
/// triangles sharing edges and vertices, coplanar overlaps, slivers and
/// axis-aligned triangles lying exactly in likely split planes.
pub fn soup(seed: u64, n: usize) -> Scene {
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut p = Vec::new();
    let mut t = Vec::new();
    for _ in 0..n {
        let c = Vec3::new(
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
            rng.gen_range(-5.0..5.0),
        );
        let s = rng.gen_range(0.05..1.5);
        let base = p.len() as u32;
        for _ in 0..3 {
            p.push(c + Vec3::new(rng.gen_range(-s..s), rng.gen_range(-s..s), rng.gen_range(-s..s)));
        }
        t.push([base, base + 1, base + 2]);
    }
    // A shared-edge grid at z = 0 and one in the x = 1 plane.
    for plane in 0..2 {
        let base = p.len() as u32;
        for i in 0..9 {
            for j in 0..9 {
                let (u, v) = (i as f32 - 4.0, j as f32 - 4.0);
                p.push(if plane == 0 {
                    Vec3::new(u, v, 0.0)
                } else {
                    Vec3::new(1.0, u, v)
                });
            }
        }
        for i in 0..8 {
            for j in 0..8 {
                let a = base + i * 9 + j;
                t.push([a, a + 9, a + 1]);
                t.push([a + 1, a + 9, a + 10]);
            }
        }
    }
    // A sliver and an exact duplicate (coplanar overlap).
    let base = p.len() as u32;
    p.extend([
        Vec3::new(-2.0, -2.0, 2.0),
        Vec3::new(2.0, 2.0, 2.0),
        Vec3::new(2.0, 2.0001, 2.0),
    ]);
    t.push([base, base + 1, base + 2]);
    t.push([base, base + 1, base + 2]);
    let mut b = SceneBuilder::new();
    let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
    b.add_mesh("soup", &p, &t, &[m], Mat4::IDENTITY).unwrap();
    b.finish()
}

/// The triangles of an `n` x `n` grid of quads over `(n + 1)^2` vertices in
/// row order, two per quad, sharing the diagonal from `(i, j + 1)` to `(i + 1, j)`.
pub fn grid_triangles(n: u32) -> Vec<[u32; 3]> {
    let mut t = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let a = i * (n + 1) + j;
            t.push([a, a + n + 1, a + 1]);
            t.push([a + 1, a + n + 1, a + n + 2]);
        }
    }
    t
}

/// A gently sloped heightfield of `n` x `n` quads sharing edges and
/// vertices, and `count` rays from above aimed exactly at its vertices and
/// edge midpoints (the third kind is a quad's diagonal): each must hit it,
/// at `t = 1`.
pub fn heightfield_and_rays(n: u32, count: usize, seed: u64) -> (Scene, Vec<Ray>) {
    // Gentle slopes: every ray below crosses the surface, none grazes a ridge.
    let height = |i: u32, j: u32| ((i * 7 + j * 13) % 5) as f32 * 0.005;
    let mut p = Vec::new();
    for i in 0..=n {
        for j in 0..=n {
            p.push(Vec3::new(i as f32 * 0.25, j as f32 * 0.25, height(i, j)));
        }
    }
    let mut b = SceneBuilder::new();
    let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
    b.add_mesh("field", &p, &grid_triangles(n), &[m], Mat4::IDENTITY)
        .unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let rays = (0..count)
        .map(|_| {
            let (i, j) = (rng.gen_range(1..n), rng.gen_range(1..n));
            let at = |i: u32, j: u32| p[(i * (n + 1) + j) as usize];
            let target = match rng.gen_range(0..4) {
                0 => at(i, j),
                1 => (at(i, j) + at(i, j + 1)) * 0.5,
                2 => (at(i, j) + at(i + 1, j)) * 0.5,
                _ => (at(i, j + 1) + at(i + 1, j)) * 0.5,
            };
            let origin = Vec3::new(
                rng.gen_range(-2.0..8.0),
                rng.gen_range(-2.0..8.0),
                rng.gen_range(1.0..6.0),
            );
            Ray::new(origin, target - origin)
        })
        .collect();
    (b.finish(), rays)
}
