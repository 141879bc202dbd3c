//! Walking the kd-tree front to back with a small stack: nearest hit, or any
//! hit for shadow rays. Rays lying exactly in a split plane visit both sides.

use super::KdTree;
use crate::geom::{Ray, Ray4};

/// The nearest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// Ray parameter.
    pub t: f32,
    /// Triangle index.
    pub tri: u32,
    /// Barycentric weight of vertex 1.
    pub u: f32,
    /// Barycentric weight of vertex 2.
    pub v: f32,
}

pub(crate) const STACK: usize = 64;

/// Split planes this close (relatively) to either end of the ray's range in a
/// node send the ray into both children: rounding in `t_split` must never skip
/// the child holding a triangle whose vertex or edge lies on the plane.
const SLACK_UP: f32 = 1.0 + 1e-5;
const SLACK_DOWN: f32 = 1.0 - 1e-5;

impl KdTree {
    /// Visits leaves along the ray in front-to-back order. `leaf` gets the
    /// leaf's entries in the leaf lists (first, count) and returns `Some(t)`
    /// for a hit that makes everything beyond `t` irrelevant, or stops the
    /// walk by returning `Err(())`.
    #[inline]
    fn walk(&self, ray: &Ray, mut leaf: impl FnMut(usize, usize) -> Result<Option<f32>, ()>) {
        let inv = ray.dir.recip();
        let Some((mut t_min, mut t_max)) = self.bounds.range(ray, inv) else {
            return;
        };
        // Plain arrays: indexing them by a runtime axis is a single load.
        let (org, inv_a) = (ray.origin.to_array(), inv.to_array());
        let mut closest = ray.t_max;
        let mut stack = [(0u32, 0f32, 0f32); STACK];
        let mut sp = 0;
        let mut node = 0usize;
        loop {
            let n = self.nodes[node];
            if !n.is_leaf() {
                let axis = n.axis();
                let o = org[axis];
                let t_split = (n.split() - o) * inv_a[axis];
                let below_first = o < n.split() || (o == n.split() && inv_a[axis] <= 0.0);
                let (first, second) = if below_first {
                    (n.left(), n.left() + 1)
                } else {
                    (n.left() + 1, n.left())
                };
                if t_split.is_nan() {
                    // The ray runs inside the split plane: both children hold its triangles.
                    stack[sp] = (second as u32, t_min, t_max);
                    sp += 1;
                    node = first;
                } else if t_split > t_max * SLACK_UP || t_split <= 0.0 {
                    node = first;
                } else if t_split < t_min * SLACK_DOWN {
                    node = second;
                } else {
                    stack[sp] = (second as u32, t_split, t_max);
                    sp += 1;
                    node = first;
                    t_max = t_split;
                }
                continue;
            }
            match leaf(n.first(), n.count()) {
                Err(()) => return,
                Ok(Some(t)) => closest = closest.min(t),
                Ok(None) => {}
            }
            if closest <= t_max {
                return;
            }
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (next, a, b) = stack[sp];
                if a <= closest {
                    node = next as usize;
                    t_min = a;
                    t_max = b;
                    break;
                }
            }
        }
    }

    /// The nearest hit within `(0, ray.t_max]`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        let prep = Ray4::new(ray.origin, ray.dir);
        let mut best: Option<Hit> = None;
        let mut closest = ray.t_max;
        self.walk(ray, |first, count| {
            self.leaves.intersect(&prep, first, count, closest, |entry, h| {
                closest = h.t;
                best = Some(Hit {
                    t: h.t,
                    tri: self.leaf_tris[entry],
                    u: h.u,
                    v: h.v,
                });
                Some(h.t)
            });
            Ok(best.map(|h| h.t))
        });
        best
    }

    /// True if a triangle for which `blocks(triangle)` is true lies within
    /// `(0, ray.t_max)`. Triangles that do not block are passed to the filter
    /// and skipped (a triangle in several leaves may be passed more than once).
    pub fn occluded_by(&self, ray: &Ray, mut blocks: impl FnMut(u32) -> bool) -> bool {
        let prep = Ray4::new(ray.origin, ray.dir);
        let mut hit = false;
        self.walk(ray, |first, count| {
            let go = self.leaves.intersect(&prep, first, count, ray.t_max, |entry, h| {
                if h.t < ray.t_max && blocks(self.leaf_tris[entry]) {
                    hit = true;
                    return None;
                }
                Some(ray.t_max)
            });
            if go {
                Ok(None)
            } else {
                Err(())
            }
        });
        hit
    }

    /// True if anything lies within `(0, ray.t_max)`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_by(ray, |_| true)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::{grid_triangles, heightfield_and_rays, nearest_of_all, random_vec3, soup};
    use crate::accel::BuildOptions;
    use glam::Vec3;
    use rand::SeedableRng;

    #[test]
    fn a_fine_floor_between_objects_is_split_into_small_leaves() {
        // 20,000 triangles in the plane z = 0, with boxes above and below: no
        // cut through that plane may leave them all in one leaf.
        use crate::scene::{Material, SceneBuilder};
        let mut b = SceneBuilder::new();
        let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
        let n = 100u32;
        let mut p = Vec::new();
        for i in 0..=n {
            for j in 0..=n {
                p.push(Vec3::new(i as f32 * 0.1, j as f32 * 0.1, 0.0));
            }
        }
        let t = grid_triangles(n);
        b.add_mesh("floor", &p, &t, &[m], glam::Mat4::IDENTITY).unwrap();
        for z in [-3.0f32, 3.0] {
            let q = [Vec3::new(2.0, 2.0, z), Vec3::new(8.0, 2.0, z), Vec3::new(8.0, 8.0, z)];
            b.add_mesh("box", &q, &[[0, 1, 2]], &[m], glam::Mat4::IDENTITY).unwrap();
        }
        let scene = b.finish();
        let tree = KdTree::build(&scene, &BuildOptions::default());
        let stats = tree.stats();
        assert!(stats.max_leaf <= 64, "{stats:?}");
    }

    #[test]
    fn nearest_hits_match_brute_force_on_nasty_soups() {
        for seed in 0..12 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let stats = tree.stats();
            assert!(stats.leaves > 50 && stats.depth > 5, "{stats:?}");
            let mut rng = rand::rngs::StdRng::seed_from_u64(100 + seed);
            let mut hits = 0;
            for k in 0..4000 {
                let origin = random_vec3(&mut rng, 7.0);
                let mut dir = random_vec3(&mut rng, 1.0);
                match k % 4 {
                    // Axis-parallel rays, some lying in the grid planes.
                    1 => dir = [Vec3::X, Vec3::Y, Vec3::Z][k % 3] * if k % 8 == 1 { -1.0 } else { 1.0 },
                    2 => {
                        // Aimed at grid vertices and edge midpoints (shared edges).
                        let target = Vec3::new(
                            (k % 9) as f32 - 4.0,
                            ((k / 9) % 9) as f32 - 4.0 + 0.5 * (k % 2) as f32,
                            0.0,
                        );
                        dir = target - origin;
                    }
                    _ => {}
                }
                if dir.length() < 1e-3 {
                    continue;
                }
                let ray = Ray::new(origin, dir);
                let (a, b) = (tree.intersect(&ray), nearest_of_all(&scene, &ray));
                match (a, b) {
                    (None, None) => {}
                    (Some(a), Some(b)) => {
                        hits += 1;
                        // The same hit; at shared edges either triangle may report it.
                        assert!(
                            a.t == b.t || (a.t - b.t).abs() <= 1e-6 * b.t,
                            "seed {seed} ray {k}: {a:?} vs {b:?}"
                        );
                    }
                    _ => panic!("seed {seed} ray {k} {ray:?}: tree {a:?}, brute force {b:?}"),
                }
                assert_eq!(
                    tree.occluded(&Ray {
                        t_max: b.map_or(1e30, |h| h.t * 1.001),
                        ..ray
                    }),
                    b.is_some()
                );
            }
            assert!(hits > 1000, "{hits}");
        }
    }

    /// A heightfield of shared edges and vertices, with rays aimed exactly at
    /// its vertices and edge midpoints from many origins: every ray hits, alone
    /// and in packets of eight, at the same place.
    #[test]
    fn rays_through_shared_edges_and_vertices_never_leak() {
        use crate::accel::PACKET;
        let (scene, rays) = heightfield_and_rays(24, 4000, 7);
        let tree = KdTree::build(&scene, &BuildOptions::default());
        for (k, chunk) in rays.chunks(PACKET).enumerate() {
            let packet = tree.intersect_packet(chunk);
            for (i, r) in chunk.iter().enumerate() {
                let single = tree.intersect(r);
                let Some(h) = single else {
                    panic!("ray {} {r:?} leaked through the field", k * PACKET + i)
                };
                assert!((h.t - 1.0).abs() < 1e-4, "{h:?} {r:?}");
                assert_eq!(packet[i].map(|h| (h.t, h.tri)), Some((h.t, h.tri)), "ray {r:?}");
            }
        }
    }
}
