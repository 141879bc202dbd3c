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

use wide::f32x8;

use super::node::{Child, EMPTY, WIDTH};
use super::slab::{corners, safe_recip, ROBUST};
use super::traverse::STACK;
use super::{better, reach, WideBvh};
use crate::accel::packet::{for_each_octant, shared_leaf_rays, PACKET, SHARED_LEAF};
use crate::accel::Hit;
#[cfg(target_arch = "x86_64")]
use crate::geom::avx;
use crate::geom::{Lanes, Ray, Ray4};

impl WideBvh {
    /// Nearest hits of up to [`PACKET`] rays (the rest are ignored); rays
    /// may point anywhere (they are grouped by direction octant), but
    /// coherent rays gain the most.
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        #[cfg(target_arch = "x86_64")]
        if self.root != EMPTY && avx::available() {
            let mut out = [None; PACKET];
            // SAFETY: the CPU has AVX.
            for_each_octant(rays, |mask| unsafe { self.packet_octant_avx(rays, mask, &mut out) });
            return out;
        }
        self.intersect_packet_portable(rays)
    }

    /// [`WideBvh::intersect_packet`] in `wide`'s portable lanes, whatever
    /// the CPU has (the AVX walk must agree with it bit for bit).
    fn intersect_packet_portable(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        if self.root != EMPTY {
            for_each_octant(rays, |mask| self.packet_octant::<f32x8>(rays, mask, &mut out));
        }
        out
    }

    /// [`WideBvh::packet_octant`] compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn packet_octant_avx(&self, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
        self.packet_octant::<avx::Avx>(rays, mask, out);
    }

    /// The walk of the rays in `mask`, whose direction signs agree.
    #[inline(always)]
    fn packet_octant<L: Lanes>(&self, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
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
        let o = origin.map(L::new);
        let id = inv.map(L::new);
        let robust = L::splat(ROBUST);
        // The corner arrays nearer and farther on each axis, as for one ray.
        let (near, far) = corners([0, 1, 2].map(|c| safe_recip(first.dir[c])));
        let shared = shared_leaf_rays::<L>(rays, mask);
        let mut preps: [Option<Ray4>; PACKET] = [None; PACKET];
        // Entries below `sp` are written before they are read.
        let mut stack = [MaybeUninit::<(u32, u32, L)>::uninit(); STACK];
        let mut sp = 0usize;
        let (mut cur, mut active) = (self.root, mask);
        let mut limit = L::new(closest);
        loop {
            match Child::decode(cur) {
                Child::Inner(i) => {
                    let n = &self.nodes[i];
                    // Per child lane: the rays entering it and their entry distances;
                    // `order[..k]` the entered lanes, nearest first.
                    let mut entries = [(0u32, L::splat(0.0)); WIDTH];
                    let mut order = [(0f32, 0usize); WIDTH];
                    let mut k = 0usize;
                    for (lane, &r) in n.child.iter().enumerate() {
                        if r == EMPTY {
                            continue;
                        }
                        let slab =
                            |corner: usize, c: usize| L::splat(n.b[corner].as_array_ref()[lane]).sub(o[c]).mul(id[c]);
                        let t_near = slab(near[0], 0)
                            .max(slab(near[1], 1))
                            .max(slab(near[2], 2).max(L::splat(0.0)));
                        let t_far = slab(far[0], 0).min(slab(far[1], 1)).min(slab(far[2], 2).min(limit));
                        let hit = t_near.le(t_far.mul(robust)) & active;
                        if hit == 0 {
                            continue;
                        }
                        // Ordered by the entry of the packet's first ray in the box:
                        // coherent rays agree on the order, and a horizontal minimum
                        // costs more than it saves.
                        let key = t_near.to_array()[hit.trailing_zeros() as usize];
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
                                let mut limits = closest.map(reach);
                                shared.intersect(tris.get(lane), active, &mut limits, |i, h| {
                                    if better(h.t, tri, closest[i], out[i].map_or(u32::MAX, |o| o.tri)) {
                                        closest[i] = h.t;
                                        out[i] = Some(Hit {
                                            t: h.t,
                                            tri,
                                            u: h.u,
                                            v: h.v,
                                        });
                                    }
                                });
                            }
                        }
                        _ => {
                            for i in lanes(active) {
                                // Prepared when first needed: coherent packets may never test ray by ray.
                                let prep = preps[i].get_or_insert_with(|| Ray4::new(rays[i].origin, rays[i].dir));
                                prep.intersect(tris, (1u32 << count) - 1, reach(closest[i]), |lane, h| {
                                    if better(h.t, ids[lane], closest[i], out[i].map_or(u32::MAX, |o| o.tri)) {
                                        closest[i] = h.t;
                                        out[i] = Some(Hit {
                                            t: h.t,
                                            tri: ids[lane],
                                            u: h.u,
                                            v: h.v,
                                        });
                                    }
                                    Some(reach(closest[i]))
                                });
                            }
                        }
                    }
                    limit = L::new(closest);
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
                let live = rays_in & t.le(limit.mul(robust));
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
    use crate::accel::testing::{heightfield_and_rays, nearest_of_all, point_off_surface, random_vec3, soup};
    use crate::scene::gen::{generate, GenParams};
    use crate::scene::Scene;

    /// A packet's hit for `ray` against the single ray's and against every
    /// triangle tested on its own: exactly the same hit (distance, triangle,
    /// barycentrics), ties at shared edges going to the lower index.
    fn agree(scene: &Scene, bvh: &WideBvh, ray: &Ray, packet: Option<Hit>, what: &str) -> bool {
        let single = bvh.intersect(ray);
        assert_eq!(packet, single, "{what} {ray:?}: packet against single");
        assert_eq!(
            single,
            nearest_of_all(scene, ray),
            "{what} {ray:?}: against every triangle"
        );
        single.is_some()
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
                assert_eq!(
                    packet,
                    bvh.intersect_packet_portable(&rays),
                    "seed {seed} packet {k}: portable lanes"
                );
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

    /// Rays from inside the furnished room to points on the edges where its
    /// walls, floor and ceiling meet (each wall triangle gives the shared
    /// point its own distance, an ulp apart), in packets with rays of
    /// neighbouring origins: every ray gets the same triangle alone and in
    /// any packet.
    #[test]
    fn rays_onto_shared_room_edges_agree_in_any_packet() {
        let room = generate("room", &GenParams::default()).unwrap();
        let bvh = WideBvh::build(&room).unwrap();
        let (lo, hi) = room.bounds();
        let mut rng = rand::rngs::StdRng::seed_from_u64(12);
        let mut edges = 0;
        for k in 0..4000 {
            let t = rand::Rng::gen_range(&mut rng, 0..room.triangles.len());
            let v = room.vertices(t);
            let (a, b) = (v[k % 3], v[(k + 1) % 3]);
            let target = a + (b - a) * rand::Rng::gen_range(&mut rng, 0.05f32..0.95);
            let centre = lo + (hi - lo) * Vec3::new(0.5, 0.4, 0.6);
            let rays: Vec<Ray> = (0..PACKET)
                .map(|i| {
                    let o = centre + random_vec3(&mut rng, 0.3);
                    Ray::new(
                        o,
                        if i == k % PACKET {
                            target - o
                        } else {
                            target + random_vec3(&mut rng, 0.2) - o
                        },
                    )
                })
                .collect();
            let packet = bvh.intersect_packet(&rays);
            assert_eq!(
                packet,
                bvh.intersect_packet_portable(&rays),
                "packet {k}: portable lanes"
            );
            for (i, r) in rays.iter().enumerate() {
                agree(&room, &bvh, r, packet[i], &format!("packet {k} ray {i}"));
            }
            edges += usize::from(packet[k % PACKET].is_some_and(|h| h.u == 0.0 || h.v == 0.0 || h.u + h.v == 1.0));
        }
        assert!(edges > 100, "{edges} rays met an edge");
    }

    /// The rays where a packet of four beam rays once chose the ceiling and
    /// the single ray the wall, at the edge they share.
    #[test]
    fn a_beam_packet_at_the_wall_and_ceiling_edge_agrees() {
        let room = generate("room", &GenParams::default()).unwrap();
        let bvh = WideBvh::build(&room).unwrap();
        let ray = |o: [f32; 3], d: [f32; 3]| Ray::new(Vec3::from(o), Vec3::from(d));
        let rays = [
            ray([5.0553384, 0.93815106, 2.2], [0.82397807, -0.40502366, 0.39625245]),
            ray([5.0214844, 0.92122394, 2.2], [0.8206435, -0.3882086, 0.4193308]),
            ray([5.1347656, 1.1269531, 2.2], [0.85292625, -0.3570389, 0.38084152]),
            ray([4.870443, 1.016276, 2.2], [0.78420997, -0.43528834, 0.44219768]),
        ];
        let packet = bvh.intersect_packet(&rays);
        for (i, r) in rays.iter().enumerate() {
            agree(&room, &bvh, r, packet[i], &format!("ray {i}"));
        }
    }
}
