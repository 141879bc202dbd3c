//! Packet traversal for coherent rays (Wald et al. 2001; Manta, Stephens et
//! al. 2006, section 3.2): up to eight rays with the same direction signs walk
//! the kd-tree together, each with its own `[t_min, t_max]` interval in one
//! SIMD lane, and a child is visited when any active ray needs it. The rays
//! of one beam packet pass through the same pair of grid cells, so they stay
//! together deep into the tree. At a leaf, each active ray tests the leaf's
//! triangles four at a time, as a single ray does, so packets find exactly
//! the single rays' hits.

use wide::{f32x8, CmpEq, CmpGe, CmpGt, CmpLe, CmpLt};

use super::{Hit, KdTree};
use crate::geom::{Lanes, Ray, Ray4, Rays8};

/// Rays per packet.
pub const PACKET: usize = 8;

const STACK: usize = 64;
/// Active rays from which a leaf is tested ray-parallel (one triangle against
/// all rays at once) rather than ray by ray.
pub(crate) const SHARED_LEAF: u32 = 3;
const SLACK_UP: f32 = 1.0 + 1e-5;
const SLACK_DOWN: f32 = 1.0 - 1e-5;

/// Smallest cosine between the first active ray's direction and any other's
/// for the packet to share its leaf tests.
pub(crate) const COHERENT_COS: f32 = 0.9;

/// Whether the rays in `mask` run nearly one way, so that they tend to meet
/// the same leaves and the same triangles in them.
fn coherent(rays: &[Ray], mask: u32) -> bool {
    let first = rays[mask.trailing_zeros() as usize].dir;
    let f2 = first.length_squared();
    rays.iter()
        .enumerate()
        .filter(|(i, _)| mask & (1 << i) != 0)
        .all(|(_, r)| {
            // cos >= c, squared, without a square root.
            let d = r.dir.dot(first);
            d > 0.0 && d * d >= COHERENT_COS * COHERENT_COS * f2 * r.dir.length_squared()
        })
}

/// The rays in `mask` prepared to test a leaf's triangles against all of
/// them at once, when they run nearly one way with one axis permutation.
#[inline(always)]
pub(crate) fn shared_leaf_rays<L: Lanes>(rays: &[Ray], mask: u32) -> Option<Rays8<L>> {
    if !coherent(rays, mask) {
        return None;
    }
    let mut pairs = [(glam::Vec3::ZERO, glam::Vec3::ONE); PACKET];
    for (p, r) in pairs.iter_mut().zip(rays) {
        *p = (r.origin, r.dir);
    }
    Rays8::new(&pairs, mask)
}

/// Calls `each` with the mask of the first [`PACKET`] rays in each direction
/// octant, so that a packet walk can take one near-to-far order for all of
/// its rays. By sign bit, so that a -0.0 component walks as it does alone,
/// where its inverse is negative.
pub(crate) fn for_each_octant(rays: &[Ray], mut each: impl FnMut(u32)) {
    let n = rays.len().min(PACKET);
    let octant = |r: &Ray| {
        r.dir.x.is_sign_negative() as u8
            | (r.dir.y.is_sign_negative() as u8) << 1
            | (r.dir.z.is_sign_negative() as u8) << 2
    };
    let mut done = 0u32;
    for i in 0..n {
        if done & (1 << i) != 0 {
            continue;
        }
        let o = octant(&rays[i]);
        let mask = (i..n)
            .filter(|&j| done & (1 << j) == 0 && octant(&rays[j]) == o)
            .fold(0u32, |m, j| m | 1 << j);
        done |= mask;
        each(mask);
    }
}

impl KdTree {
    /// Nearest hits of up to [`PACKET`] rays; rays may point anywhere (they are
    /// grouped by direction octant), but coherent rays gain the most.
    pub fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        let mut out = [None; PACKET];
        for_each_octant(rays, |mask| self.packet_octant(rays, mask, &mut out));
        out
    }

    /// The rays of `rays` in the octant `mask` selects, walked through the
    /// tree together, their nearest hits into `out`.
    ///
    /// Long because it is the packet walk's inner loop: the lanes' origins,
    /// inverse directions, intervals and the node stack stay in locals (and
    /// registers) from the root to the last leaf.
    fn packet_octant(&self, rays: &[Ray], mask: u32, out: &mut [Option<Hit>; PACKET]) {
        let (mut origin, mut inv) = ([[0f32; PACKET]; 3], [[0f32; PACKET]; 3]);
        let mut t_min = [f32::INFINITY; PACKET];
        let mut t_max = [f32::NEG_INFINITY; PACKET];
        let mut closest = [f32::INFINITY; PACKET];
        let mut active = 0u32;
        let mut preps: [Option<Ray4>; PACKET] = [None; PACKET];
        for i in 0..PACKET {
            if mask & (1 << i) == 0 {
                continue;
            }
            let r = &rays[i];
            let d = r.dir.recip();
            for a in 0..3 {
                origin[a][i] = r.origin[a];
                inv[a][i] = d[a];
            }
            closest[i] = r.t_max;
            if let Some((a, b)) = self.bounds.range(r, d) {
                t_min[i] = a;
                t_max[i] = b;
                active |= 1 << i;
            }
        }
        if active == 0 {
            return;
        }
        let shared = shared_leaf_rays::<wide::f32x8>(rays, active);
        let first_lane = active.trailing_zeros() as usize;
        let negative = [
            rays[first_lane].dir.x.is_sign_negative(),
            rays[first_lane].dir.y.is_sign_negative(),
            rays[first_lane].dir.z.is_sign_negative(),
        ];
        let origin = origin.map(f32x8::new);
        let inv = inv.map(f32x8::new);
        let (mut t_min, mut t_max) = (f32x8::new(t_min), f32x8::new(t_max));
        let (zero, slack_up, slack_down) = (f32x8::ZERO, f32x8::splat(SLACK_UP), f32x8::splat(SLACK_DOWN));
        let mut stack = [(0u32, 0u32, f32x8::ZERO, f32x8::ZERO); STACK];
        let mut sp = 0;
        let mut node = 0usize;
        let mut finished = 0u32;
        loop {
            let nd = self.nodes[node];
            if !nd.is_leaf() {
                let axis = nd.axis();
                let split = f32x8::splat(nd.split());
                let (first, second) = if negative[axis] {
                    (nd.left() + 1, nd.left())
                } else {
                    (nd.left(), nd.left() + 1)
                };
                let (o, d) = (origin[axis], inv[axis]);
                let t = (split - o) * d;
                // The single-ray walk's rules exactly, boundaries included, lane by lane.
                let nan = t.is_nan().move_mask() as u32;
                let behind = t.cmp_le(zero).move_mask() as u32;
                let ahead = t.cmp_gt(zero);
                let reaches_first = t.cmp_ge(t_min * slack_down);
                let reaches_second = t.cmp_le(t_max * slack_up);
                // A ray the plane is behind (or that starts on it) visits only the
                // child it starts in, decided as the single-ray walk decides.
                let starts_left = (o.cmp_lt(split) | (o.cmp_eq(split) & d.cmp_le(zero))).move_mask() as u32;
                let starts_first = if negative[axis] { !starts_left } else { starts_left };
                let need_first = active & (nan | (behind & starts_first) | (ahead & reaches_first).move_mask() as u32);
                let need_second =
                    active & (nan | (behind & !starts_first) | (ahead & reaches_second).move_mask() as u32);
                match (need_first != 0, need_second != 0) {
                    (true, true) => {
                        // Rays that need both children split their range at the plane,
                        // as the single-ray walk does (slack included). Lanes not
                        // active here are masked off wherever their range is read.
                        let split_here = ahead & reaches_first & reaches_second;
                        if sp < STACK {
                            stack[sp] = (second as u32, need_second, split_here.blend(t, t_min), t_max);
                            sp += 1;
                        }
                        active = need_first;
                        t_max = split_here.blend(t, t_max);
                        node = first;
                    }
                    (true, false) => {
                        active = need_first;
                        node = first;
                    }
                    (false, true) => {
                        active = need_second;
                        node = second;
                    }
                    (false, false) => active = 0,
                }
                if active != 0 {
                    continue;
                }
            } else if let Some(shared) = shared.as_ref().filter(|_| active.count_ones() >= SHARED_LEAF) {
                for entry in nd.first()..nd.first() + nd.count() {
                    shared.intersect_at(
                        |i| self.leaves.coordinate(entry, i),
                        active,
                        &mut closest,
                        |i, h| {
                            out[i] = Some(Hit {
                                t: h.t,
                                tri: self.leaf_tris[entry],
                                u: h.u,
                                v: h.v,
                            });
                        },
                    );
                }
            } else {
                let mut todo = active;
                while todo != 0 {
                    let i = todo.trailing_zeros() as usize;
                    todo &= todo - 1;
                    // Prepared when first needed: coherent packets may never test ray by ray.
                    let prep = preps[i].get_or_insert_with(|| Ray4::new(rays[i].origin, rays[i].dir));
                    self.leaves
                        .intersect(prep, nd.first(), nd.count(), closest[i], |entry, h| {
                            closest[i] = h.t;
                            out[i] = Some(Hit {
                                t: h.t,
                                tri: self.leaf_tris[entry],
                                u: h.u,
                                v: h.v,
                            });
                            Some(h.t)
                        });
                }
            }
            // Rays whose nearest hit lies within this leaf are done, as a
            // single ray is (which matters when a hit lies on a split plane).
            // After an inner node whose children no ray needs, none is active.
            finished |= active & f32x8::new(closest).cmp_le(t_max).move_mask() as u32;
            // Pop the next node that still has unfinished rays.
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                let (next, m, a, b) = stack[sp];
                let live = m & !finished & a.cmp_le(f32x8::new(closest)).move_mask() as u32;
                if live != 0 {
                    node = next as usize;
                    active = live;
                    t_min = a;
                    t_max = b;
                    break;
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::soup;
    use crate::accel::testing::{point_off_surface, random_vec3};
    use crate::accel::BuildOptions;
    use rand::{Rng, SeedableRng};

    #[test]
    fn packets_find_exactly_what_single_rays_find() {
        for seed in 0..6 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 50);
            let mut hits = 0;
            for k in 0..600 {
                // Coherent packets (a small cone around one direction, as beam
                // rays are), mixed-octant packets, and partial packets.
                let origin = random_vec3(&mut rng, 7.0);
                let centre = random_vec3(&mut rng, 1.0);
                let spread = if k % 3 == 0 { 1.0 } else { 0.05 };
                let n = if k % 5 == 0 { 1 + k % PACKET } else { PACKET };
                let rays: Vec<Ray> = (0..n)
                    .map(|_| {
                        let jitter = random_vec3(&mut rng, 1.0);
                        let o = if k % 7 == 0 { origin } else { origin + jitter * 0.2 };
                        Ray::new(o, centre + jitter * spread)
                    })
                    .filter(|r| r.dir.length() > 1e-3)
                    .collect();
                let packet = tree.intersect_packet(&rays);
                for (i, r) in rays.iter().enumerate() {
                    let single = tree.intersect(r);
                    match (packet[i], single) {
                        (None, None) => {}
                        (Some(p), Some(s)) => {
                            hits += 1;
                            assert_eq!(p, s, "seed {seed} packet {k} ray {i}");
                        }
                        other => panic!("seed {seed} packet {k} ray {i} {r:?}: packet vs single {other:?}"),
                    }
                }
            }
            assert!(hits > 1000, "{hits}");
        }
    }

    /// Rays that start exactly on split planes, with zero (and negative zero)
    /// direction components, and bounce rays leaving a surface: where the
    /// packet walk once dropped rays that the single-ray walk kept.
    #[test]
    fn packets_agree_on_rays_starting_on_split_planes_and_leaving_surfaces() {
        let mut checked = 0;
        let mut near = 0;
        for seed in 0..4 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let planes: Vec<(usize, f32)> = tree
                .nodes()
                .iter()
                .filter(|n| !n.is_leaf())
                .map(|n| (n.axis(), n.split()))
                .collect();
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 90);
            for k in 0..800 {
                let rays: Vec<Ray> = if k % 2 == 0 {
                    let (axis, split) = planes[rng.gen_range(0..planes.len())];
                    let mut origin = random_vec3(&mut rng, 6.0);
                    origin[axis] = split;
                    let centre = random_vec3(&mut rng, 1.0);
                    (0..PACKET)
                        .map(|i| {
                            let mut d = centre + 0.05 * random_vec3(&mut rng, 1.0);
                            match (k / 2 + i) % 4 {
                                0 => d[axis] = 0.0,
                                1 => d[axis] = -0.0,
                                2 => d[(axis + 1) % 3] = -0.0,
                                _ => {}
                            }
                            Ray::new(origin, d)
                        })
                        .collect()
                } else {
                    // Bounce rays from one point just off a triangle, as a sampler makes them.
                    let (p, n) = point_off_surface(&scene, &mut rng);
                    (0..PACKET)
                        .map(|_| {
                            let d = random_vec3(&mut rng, 1.0);
                            Ray::new(p, if d.dot(n) < 0.0 { -d } else { d })
                        })
                        .collect()
                };
                let rays: Vec<Ray> = rays.into_iter().filter(|r| r.dir.length() > 1e-3).collect();
                let packet = tree.intersect_packet(&rays);
                for (i, r) in rays.iter().enumerate() {
                    let single = tree.intersect(r);
                    assert_eq!(
                        packet[i].map(|h| (h.t, h.tri)),
                        single.map(|h| (h.t, h.tri)),
                        "seed {seed} packet {k} ray {i} {r:?}"
                    );
                    checked += 1;
                    near += usize::from(single.is_some_and(|h| h.t < 1e-3));
                }
            }
        }
        assert!(checked > 20_000, "{checked}");
        assert!(near > 0, "some bounce rays hit a neighbour right away");
    }
}
