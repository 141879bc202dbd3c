//! Test scenes for the acceleration structure: random triangle soups with the
//! cases that break naive tracers.

use glam::{Mat4, Vec3};
use rand::{Rng, SeedableRng};

use crate::scene::{Material, Scene, SceneBuilder};

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
