//! Packet traversal of the wide BVH (Wald et al. 2001; Embree's coherent
//! packets): up to eight rays that run nearly one way walk the hierarchy as
//! one ray would, with the packet's interval bounds ([`super::frustum`]) in
//! place of the ray and the farthest of their nearest hits as its limit.
//! Coherent rays (a beam's, a pixel tile's) share nearly every node, so a
//! node costs the packet about what it costs one ray. At a leaf each
//! triangle is tested against all rays at once, with the tie rule per ray,
//! so each ray finds exactly the hit its single-ray walk finds. Rays that
//! run apart are traced one by one.

use wide::f32x8;

use super::frustum::Frustum;
use super::node::EMPTY;
use super::packet_rays::PacketRays;
use super::slab::ROBUST;
use super::{better, WideBvh};
use crate::accel::packet::{PACKET, SHARED_LEAF};
use crate::accel::Hit;
#[cfg(target_arch = "x86_64")]
use crate::geom::avx;
use crate::geom::{Lanes, Ray, Rays8};

impl WideBvh {
    /// Nearest hits of up to [`PACKET`] rays (the rest are ignored), each
    /// exactly the hit [`WideBvh::intersect`] finds; rays may point anywhere,
    /// but rays that run nearly one way gain the most (others are traced one
    /// by one). A ray with a non-finite origin or direction finds nothing.
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        #[cfg(target_arch = "x86_64")]
        if avx::available() {
            let mut out = [None; PACKET];
            // SAFETY: the CPU has AVX.
            unsafe { self.packet_avx(rays, &mut out) };
            return out;
        }
        self.intersect_packet_portable(rays)
    }

    /// [`WideBvh::intersect_packet`] in `wide`'s portable lanes, whatever
    /// the CPU has (the AVX walk must agree with it bit for bit; rays traced
    /// one by one take the single-ray walk, which chooses its own lanes).
    fn intersect_packet_portable(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        self.packet::<f32x8>(rays, &mut out);
        out
    }

    /// [`WideBvh::packet`] compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn packet_avx(&self, rays: &[Ray], out: &mut [Option<Hit>; PACKET]) {
        self.packet::<avx::Avx>(rays, out);
    }

    /// The rays set up in lanes once, then walked octant by octant.
    #[inline(always)]
    fn packet<L: Lanes>(&self, rays: &[Ray], out: &mut [Option<Hit>; PACKET]) {
        if self.root == EMPTY || rays.is_empty() {
            return;
        }
        let p = PacketRays::new::<L>(rays);
        if p.lanes.count_ones() < SHARED_LEAF || !p.coherent::<L>() {
            self.one_by_one(rays, p.lanes, out);
            return;
        }
        let signs = p.signs::<L>();
        let mut left = p.lanes;
        while left != 0 {
            let mask = PacketRays::octant(signs, left);
            left &= !mask;
            let only;
            let q = if mask == p.lanes {
                &p
            } else {
                only = p.only(mask);
                &only
            };
            self.packet_octant::<L>(rays, q, mask, out);
        }
    }

    /// The walk of the rays in `mask`, whose direction signs agree (`p`'s
    /// other lanes repeat one of them). Coherent rays walk as one ray
    /// would, with the packet's bounds for the ray ([`Frustum`]) and the
    /// farthest of their nearest hits for its limit, and test each leaf's
    /// triangles against all rays at once. Others, and packets of one or
    /// two rays, walk one by one: bounds around rays that run apart take
    /// in most of the scene.
    #[inline(always)]
    fn packet_octant<L: Lanes>(&self, rays: &[Ray], p: &PacketRays, mask: u32, out: &mut [Option<Hit>; PACKET]) {
        // The packet runs nearly one way (see `packet`); `None` for mixed axis permutations.
        let shared = match Rays8::<L>::from_lanes(p.o, p.d) {
            Some(shared) if mask.count_ones() >= SHARED_LEAF => shared,
            _ => {
                self.one_by_one(rays, mask, out);
                return;
            }
        };
        let mut closest = [f32::NEG_INFINITY; PACKET];
        for i in lanes(mask) {
            closest[i] = p.t_max[i];
        }
        let widest = |closest: &[f32; PACKET]| closest.iter().fold(f32::NEG_INFINITY, |a, &b| a.max(b));
        self.walk(&Frustum::<L>::new(p), widest(&closest), |block, lanes| {
            let mut found = false;
            // `lanes` is a run of low bits (`popcnt` is not among the AVX
            // walk's instructions).
            let count = (lanes + 1).trailing_zeros() as usize;
            // Coordinates read from the leaf as the test picks them: copying
            // each triangle out first cost packets a tenth of their speed.
            if lanes < 16 {
                let b = &self.blocks[block];
                for lane in 0..count {
                    let coordinate = |i: usize| b.tris.p[i].as_array_ref()[lane];
                    found |= packet_triangle(&shared, coordinate, b.ids[lane], mask, &mut closest, out);
                }
            } else {
                let pair = self.pair(block);
                for lane in 0..count {
                    let coordinate = |i: usize| pair.tris.p[i].as_array_ref()[lane];
                    found |= packet_triangle(&shared, coordinate, pair.ids[lane], mask, &mut closest, out);
                }
            }
            Ok(found.then(|| widest(&closest)))
        });
    }

    /// The rays of `mask` traced alone (out of line: the packet walk stays small).
    fn one_by_one(&self, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
        for i in lanes(mask) {
            out[i] = self.intersect(&rays[i]);
        }
    }
}

/// Tests the triangle `tri`, whose coordinate `i` (`3 * vertex + axis`) is
/// `coordinate(i)`, against the packet's rays in `mask`, keeping each ray's
/// nearest hit by the tie rule; true if one of them changed.
#[inline(always)]
fn packet_triangle<L: Lanes>(
    shared: &Rays8<L>,
    coordinate: impl Fn(usize) -> f32,
    tri: u32,
    mask: u32,
    closest: &mut [f32; PACKET],
    out: &mut [Option<Hit>; PACKET],
) -> bool {
    let mut found = false;
    let mut limits = L::new(*closest).mul(L::splat(ROBUST)).to_array();
    shared.intersect_at(coordinate, mask, &mut limits, |i, h| {
        if better(h.t, tri, closest[i], out[i].map_or(u32::MAX, |o| o.tri)) {
            closest[i] = h.t;
            found = true;
            out[i] = Some(Hit {
                t: h.t,
                tri,
                u: h.u,
                v: h.v,
            });
        }
    });
    found
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

    /// A coherent packet with one ray that has no finite origin or
    /// direction: that ray finds nothing, the others what they find alone.
    #[test]
    fn a_ray_that_is_not_finite_spoils_no_other() {
        let scene = soup(3, 400);
        let bvh = WideBvh::build(&scene).unwrap();
        let mut rng = rand::rngs::StdRng::seed_from_u64(9);
        let mut hits = 0;
        for k in 0..300 {
            let origin = random_vec3(&mut rng, 7.0);
            let towards = random_vec3(&mut rng, 1.0) - origin;
            let mut rays: Vec<Ray> = (0..PACKET)
                .map(|_| {
                    Ray::new(
                        origin + random_vec3(&mut rng, 0.05),
                        towards + random_vec3(&mut rng, 0.05),
                    )
                })
                .collect();
            let bad = k % PACKET;
            rays[bad] = match k % 3 {
                0 => Ray {
                    origin: Vec3::splat(f32::NAN),
                    ..rays[bad]
                },
                1 => Ray {
                    dir: Vec3::new(f32::INFINITY, 0.0, 1.0),
                    ..rays[bad]
                },
                _ => Ray {
                    origin: Vec3::new(f32::NEG_INFINITY, 0.0, 0.0),
                    ..rays[bad]
                },
            };
            let got = bvh.intersect_packet(&rays);
            assert_eq!(got[bad], None, "packet {k}");
            for (i, r) in rays.iter().enumerate().filter(|&(i, _)| i != bad) {
                if agree(&scene, &bvh, r, got[i], "beside a ray that is not finite") {
                    hits += 1;
                }
            }
        }
        assert!(hits > 500, "{hits} hits");
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
