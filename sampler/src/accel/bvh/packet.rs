//! Packet traversal of the wide BVH (Wald et al. 2001, over a wide
//! hierarchy as in Embree's hybrid kernels): up to eight rays with the same
//! direction signs walk the hierarchy together, one ray per SIMD lane. A
//! node's children are tested one at a time against all eight rays, a child
//! is entered when any of its rays reaches its box, and children are visited
//! nearest first by the nearest entry among their rays. Coherent rays (a
//! beam's, a pixel tile's) share nearly every node, so each node's boxes are
//! loaded once for eight rays and its branches are taken once. At a leaf the
//! triangles are tested against all live rays at once when they share the
//! watertight test's axis permutation, ray by ray otherwise; either way each
//! ray finds the nearest distance its single-ray walk finds.

use std::mem::MaybeUninit;

use wide::{f32x8, CmpLe};

use super::node::{Child, EMPTY};
use super::traverse::{safe_recip, ROBUST, STACK};
use super::WideBvh;
use crate::accel::packet::{for_each_octant, shared_leaf_rays, PACKET, SHARED_LEAF};
use crate::accel::Hit;
use crate::geom::{Ray, Ray4};

impl WideBvh {
    /// Nearest hits of up to [`PACKET`] rays (the rest are ignored); rays
    /// may point anywhere (they are grouped by direction octant), but
    /// coherent rays gain the most.
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        if self.root != EMPTY {
            for_each_octant(rays, |mask| self.packet_octant(rays, mask, &mut out));
        }
        out
    }

    /// The walk of the rays in `mask`, whose direction signs agree.
    fn packet_octant(&self, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
        let first = &rays[mask.trailing_zeros() as usize];
        let (mut origin, mut inv) = ([[0f32; PACKET]; 3], [[0f32; PACKET]; 3]);
        // Lanes without a ray get an empty range, so that no box takes them.
        let mut closest = [f32::NEG_INFINITY; PACKET];
        for (i, r) in rays.iter().enumerate().take(PACKET) {
            if mask & (1 << i) != 0 {
                for c in 0..3 {
                    origin[c][i] = r.origin[c];
                    inv[c][i] = safe_recip(r.dir[c]);
                }
                closest[i] = r.t_max;
            }
        }
        let o = origin.map(f32x8::new);
        let id = inv.map(f32x8::new);
        // The corner arrays nearer and farther on each axis, as for one ray.
        let negative = [0, 1, 2].map(|c| safe_recip(first.dir[c]) < 0.0);
        let near = [0, 1, 2].map(|c| if negative[c] { 3 + c } else { c });
        let far = [0, 1, 2].map(|c| if negative[c] { c } else { 3 + c });
        let shared = shared_leaf_rays(rays, mask);
        let mut preps: [Option<Ray4>; PACKET] = [None; PACKET];
        // Entries below `sp` are written before they are read.
        let mut stack = [MaybeUninit::<(u32, u32, f32x8)>::uninit(); STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (self.root, mask);
        let mut limit = f32x8::new(closest);
        loop {
            match Child::decode(cur) {
                Child::Inner(i) => {
                    let n = &self.nodes[i];
                    // Per child lane: the rays entering it and their entry distances;
                    // `order[..k]` the entered lanes, nearest first.
                    let mut entries = [(0u32, f32x8::ZERO); 4];
                    let mut order = [(0f32, 0usize); 4];
                    let mut k = 0usize;
                    for (lane, &r) in n.child.iter().enumerate() {
                        if r == EMPTY {
                            continue;
                        }
                        let slab =
                            |corner: usize, c: usize| (f32x8::splat(n.b[corner].as_array_ref()[lane]) - o[c]) * id[c];
                        let t_near = slab(near[0], 0)
                            .fast_max(slab(near[1], 1))
                            .fast_max(slab(near[2], 2).fast_max(f32x8::ZERO));
                        let t_far = slab(far[0], 0)
                            .fast_min(slab(far[1], 1))
                            .fast_min(slab(far[2], 2).fast_min(limit));
                        let hit = t_near.cmp_le(t_far * f32x8::splat(ROBUST)).move_mask() as u32 & active;
                        if hit == 0 {
                            continue;
                        }
                        // Ordered by the entry of the packet's first ray in the box:
                        // coherent rays agree on the order, and a horizontal minimum
                        // costs more than it saves.
                        let key = t_near.as_array_ref()[hit.trailing_zeros() as usize];
                        entries[lane] = (hit, t_near);
                        let mut j = k;
                        while j > 0 && order[j - 1].0 > key {
                            order[j] = order[j - 1];
                            j -= 1;
                        }
                        order[j] = (key, lane);
                        k += 1;
                    }
                    if k > 0 {
                        for &(_, lane) in order[1..k].iter().rev() {
                            let (hit, t_near) = entries[lane];
                            stack[sp] = MaybeUninit::new((n.child[lane], hit, t_near));
                            sp += 1;
                        }
                        let lane = order[0].1;
                        (cur, active) = (n.child[lane], entries[lane].0);
                        continue;
                    }
                }
                Child::Leaf { block, count } => {
                    let tris = &self.blocks[block];
                    let ids = &self.ids[block];
                    match &shared {
                        Some(shared) if active.count_ones() >= SHARED_LEAF => {
                            for (lane, &tri) in ids.iter().enumerate().take(count) {
                                shared.intersect(tris.get(lane), active, &mut closest, |i, h| {
                                    out[i] = Some(Hit {
                                        t: h.t,
                                        tri,
                                        u: h.u,
                                        v: h.v,
                                    });
                                });
                            }
                        }
                        _ => {
                            for i in lanes(active) {
                                // Prepared when first needed: coherent packets may never test ray by ray.
                                let prep = preps[i].get_or_insert_with(|| Ray4::new(rays[i].origin, rays[i].dir));
                                prep.intersect(tris, (1u32 << count) - 1, closest[i], |lane, h| {
                                    closest[i] = h.t;
                                    out[i] = Some(Hit {
                                        t: h.t,
                                        tri: ids[lane],
                                        u: h.u,
                                        v: h.v,
                                    });
                                    Some(h.t)
                                });
                            }
                        }
                    }
                    limit = f32x8::new(closest);
                }
                Child::Empty => {}
            }
            // The next entry that some of its rays may still need.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                // SAFETY: entries below the old `sp` were written by the pushes above.
                let (next, rays_in, t) = unsafe { stack[sp].assume_init() };
                let live = rays_in & t.cmp_le(limit * f32x8::splat(ROBUST)).move_mask() as u32;
                if live != 0 {
                    (cur, active) = (next, live);
                    break;
                }
            }
        }
    }
}

/// The set bits of `mask`, lowest first.
#[inline]
fn lanes(mut mask: u32) -> impl Iterator<Item = usize> {
    std::iter::from_fn(move || {
        (mask != 0).then(|| {
            let j = mask.trailing_zeros() as usize;
            mask &= mask - 1;
            j
        })
    })
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::SeedableRng;

    use super::*;
    use crate::accel::testing::{brute, heightfield_and_rays, point_off_surface, random_vec3, soup};
    use crate::geom::{intersect_triangle, RayPrep};
    use crate::scene::Scene;

    /// A packet's hit for `ray` against the single ray's: the same nearest
    /// distance (to rounding, as where two triangles share the hit point
    /// each gives its own; see the single-ray tests), on a triangle the
    /// scalar test hits at exactly the reported point, and none where brute
    /// force finds none.
    fn agree(scene: &Scene, bvh: &WideBvh, ray: &Ray, packet: Option<Hit>, what: &str) -> bool {
        let single = bvh.intersect(ray);
        match (packet, single) {
            (None, None) => {
                assert_eq!(brute(scene, ray), None, "{what}");
                false
            }
            (Some(p), Some(s)) => {
                assert!(
                    (p.t - s.t).abs() <= 1e-6 * s.t.abs(),
                    "{what}: packet {p:?} single {s:?}"
                );
                let [a, b, c] = scene.vertices(p.tri as usize);
                let own = intersect_triangle(&RayPrep::new(ray.origin, ray.dir), a, b, c, ray.t_max);
                assert_eq!(own.map(|h| (h.t, h.u, h.v)), Some((p.t, p.u, p.v)), "{what}");
                true
            }
            other => panic!("{what} {ray:?}: packet vs single {other:?}"),
        }
    }

    #[test]
    fn packets_find_what_single_rays_find_on_nasty_soups() {
        let mut hits = 0;
        let mut near = 0;
        for seed in 0..6 {
            let scene = soup(seed, 400);
            let bvh = WideBvh::build(&scene).unwrap();
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 70);
            for k in 0..700 {
                let origin = random_vec3(&mut rng, 7.0);
                let centre = random_vec3(&mut rng, 1.0);
                let rays: Vec<Ray> = match k % 4 {
                    // Coherent packets (a small cone, as a beam's rays) and
                    // mixed-octant ones, some partial.
                    0 | 1 => {
                        let spread = if k % 4 == 0 { 0.05 } else { 1.0 };
                        let n = if k % 5 == 0 { 1 + k % PACKET } else { PACKET };
                        (0..n)
                            .map(|_| {
                                let jitter = random_vec3(&mut rng, 1.0);
                                let o = if k % 3 == 0 { origin } else { origin + jitter * 0.2 };
                                Ray::new(o, centre + jitter * spread)
                            })
                            .collect()
                    }
                    // Zero and negative-zero components, rays in the grids' planes.
                    2 => (0..PACKET)
                        .map(|i| {
                            let mut d = centre + 0.05 * random_vec3(&mut rng, 1.0);
                            let mut o = origin;
                            match i % 4 {
                                0 => d.z = 0.0,
                                1 => d.z = -0.0,
                                2 => {
                                    o.z = 0.0;
                                    d.x = -0.0;
                                }
                                _ => d = [Vec3::X, Vec3::Y, Vec3::Z][k % 3],
                            }
                            Ray::new(o, d)
                        })
                        .collect(),
                    // Bounce rays from a point just off a triangle.
                    _ => {
                        let (p, n) = point_off_surface(&scene, &mut rng);
                        (0..PACKET)
                            .map(|_| {
                                let d = (n + 0.3 * random_vec3(&mut rng, 1.0)).normalize();
                                Ray::new(p, if d.dot(n) < 0.0 { -d } else { d })
                            })
                            .collect()
                    }
                };
                let rays: Vec<Ray> = rays.into_iter().filter(|r| r.dir.length() > 1e-3).collect();
                let packet = bvh.intersect_packet(&rays);
                for (i, r) in rays.iter().enumerate() {
                    let what = format!("seed {seed} packet {k} ray {i}");
                    hits += usize::from(agree(&scene, &bvh, r, packet[i], &what));
                    near += usize::from(packet[i].is_some_and(|h| h.t < 1e-3));
                }
                assert!(packet[rays.len()..].iter().all(Option::is_none));
            }
        }
        assert!(hits > 5000, "{hits}");
        assert!(near > 0, "some bounce rays hit a neighbour right away");
    }

    /// Packets of rays aimed at a heightfield's shared vertices and edges
    /// never slip through: scattered rays, and tiles of rays from one eye at
    /// neighbouring vertices, as a camera's pixels are (these share their
    /// leaf tests).
    #[test]
    fn packets_through_shared_edges_and_vertices_never_leak() {
        let (scene, mut rays) = heightfield_and_rays(24, 4000, 9);
        let eye = Vec3::new(3.1, 2.9, 9.0);
        for i in (1..20).step_by(4) {
            for j in (1..22).step_by(2) {
                for (di, dj) in (0..4).flat_map(|a| (0..2).map(move |b| (a, b))) {
                    let target = scene.positions[((i + di) * 25 + j + dj) as usize];
                    rays.push(Ray::new(eye, target - eye));
                }
            }
        }
        let bvh = WideBvh::build(&scene).unwrap();
        for (k, chunk) in rays.chunks(PACKET).enumerate() {
            let packet = bvh.intersect_packet(chunk);
            for (i, r) in chunk.iter().enumerate() {
                let Some(h) = packet[i] else {
                    panic!("packet {k} ray {i} {r:?} leaked through the field")
                };
                assert!((h.t - 1.0).abs() < 1e-4, "{h:?} {r:?}");
                agree(&scene, &bvh, r, packet[i], &format!("packet {k} ray {i}"));
            }
        }
    }

    #[test]
    fn empty_scenes_and_short_rays_find_nothing() {
        let empty = WideBvh::build(&Scene::default()).unwrap();
        let rays = [Ray::new(Vec3::ZERO, Vec3::X); 3];
        assert_eq!(empty.intersect_packet(&rays), [None; PACKET]);
        assert_eq!(empty.intersect_packet(&[]), [None; PACKET]);
        // Rays that end before the nearest triangle.
        let scene = soup(1, 200);
        let bvh = WideBvh::build(&scene).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(5);
        let rays: Vec<Ray> = (0..PACKET)
            .map(|_| {
                let r = Ray::new(random_vec3(&mut rng, 7.0), random_vec3(&mut rng, 1.0));
                let t_max = bvh.intersect(&r).map_or(1.0, |h| h.t * 0.999);
                Ray { t_max, ..r }
            })
            .collect();
        assert_eq!(bvh.intersect_packet(&rays), [None; PACKET]);
    }
}
