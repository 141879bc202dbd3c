//! A packet's box test bounded by interval arithmetic (as Embree's coherent
//! packets do): the origins and reciprocal directions of the packet's rays
//! lie in intervals, and one test of a node's eight boxes against those
//! intervals says which boxes no ray of the packet can enter. It costs about
//! what one ray's test costs, so a coherent packet walks the hierarchy for
//! about what one ray's walk costs.
//!
//! It is conservative bit for bit: float subtraction and multiplication
//! round monotonically, so each bound is computed from the interval ends
//! that make it smallest (entries) or largest (exits), and any ray's own
//! slab test ([`super::slab::SlabRay`]) entering a box implies this test
//! enters it.

use super::node::{Node, WIDTH};
use super::packet_rays::PacketRays;
use super::slab::{corners, far_recip, BoxTest, ROBUST};
use crate::accel::packet::PACKET;
use crate::geom::Lanes;

/// The interval bounds of up to eight rays whose direction signs agree.
pub(super) struct Frustum<L> {
    /// Per axis, the origin bound that gives the smallest entry distance.
    o_near: [L; 3],
    /// Per axis, the origin bound that gives the largest exit distance.
    o_far: [L; 3],
    /// Per axis, the smallest and largest reciprocal direction, widened
    /// for far planes as a ray's own test widens it.
    inv_lo: [L; 3],
    inv_hi: [L; 3],
    /// Per axis, the reciprocal direction nearest zero.
    inv_small: [L; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl<L: Lanes> Frustum<L> {
    /// The bounds of a packet's rays, whose direction components have the
    /// same sign bits (so their reciprocals share signs too).
    #[inline(always)]
    pub(super) fn new(p: &PacketRays) -> Frustum<L> {
        let lo = |a: &[f32; PACKET]| L::new(*a).min_lane();
        let hi = |a: &[f32; PACKET]| L::new(*a).max_lane();
        let (o_lo, o_hi) = (
            [lo(&p.o[0]), lo(&p.o[1]), lo(&p.o[2])],
            [hi(&p.o[0]), hi(&p.o[1]), hi(&p.o[2])],
        );
        let (inv_lo, inv_hi) = (
            [lo(&p.inv[0]), lo(&p.inv[1]), lo(&p.inv[2])],
            [hi(&p.inv[0]), hi(&p.inv[1]), hi(&p.inv[2])],
        );
        let first = [p.inv[0][0], p.inv[1][0], p.inv[2][0]];
        let (near, far) = corners(first);
        // A positive reciprocal makes the distance `(b - o) * inv` fall as the
        // origin grows, so the smallest entry takes the largest origin; a
        // negative one the other way round.
        let pick = |c: usize, smallest: bool| {
            if (first[c] > 0.0) == smallest {
                o_hi[c]
            } else {
                o_lo[c]
            }
        };
        let small = |c: usize| if first[c] > 0.0 { inv_lo[c] } else { inv_hi[c] };
        Frustum {
            o_near: [
                L::splat(pick(0, true)),
                L::splat(pick(1, true)),
                L::splat(pick(2, true)),
            ],
            o_far: [
                L::splat(pick(0, false)),
                L::splat(pick(1, false)),
                L::splat(pick(2, false)),
            ],
            inv_lo: [
                L::splat(far_recip(inv_lo[0])),
                L::splat(far_recip(inv_lo[1])),
                L::splat(far_recip(inv_lo[2])),
            ],
            inv_hi: [
                L::splat(far_recip(inv_hi[0])),
                L::splat(far_recip(inv_hi[1])),
                L::splat(far_recip(inv_hi[2])),
            ],
            inv_small: [L::splat(small(0)), L::splat(small(1)), L::splat(small(2))],
            near,
            far,
        }
    }
}

/// The children that some ray of the packet may enter within `[0,
/// closest]`, `closest` being the largest of the rays' limits, and a lower
/// bound of each child's entry distance over the packet.
impl<L: Lanes> BoxTest for Frustum<L> {
    #[inline(always)]
    fn test(&self, n: &Node, closest: f32) -> (u32, [f32; WIDTH]) {
        // With the reciprocal's sign fixed, `x * inv` is extreme at an end of
        // the reciprocal's interval, which end depending on the sign of `x`.
        // An entry matters only where it is positive (the entry is at least
        // 0), that is where `x` has the reciprocal's sign; there the smallest
        // product takes the reciprocal nearest zero, and elsewhere that
        // product is not positive either.
        let entry = |k: usize, c: usize| L::load(&n.b[k]).sub(self.o_near[c]).mul(self.inv_small[c]);
        let exit = |k: usize, c: usize| {
            let x = L::load(&n.b[k]).sub(self.o_far[c]);
            x.mul(self.inv_lo[c]).max(x.mul(self.inv_hi[c]))
        };
        let (near, far) = (self.near, self.far);
        let t_near = entry(near[0], 0)
            .max(entry(near[1], 1))
            .max(entry(near[2], 2).max(L::splat(0.0)));
        let t_far = exit(far[0], 0)
            .min(exit(far[1], 1))
            .min(exit(far[2], 2).min(L::splat(closest * ROBUST)));
        (t_near.le(t_far), t_near.to_array())
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use proptest::prelude::*;
    use wide::f32x8;

    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::accel::bvh::node::EMPTY;
    use crate::accel::bvh::slab::SlabRay;
    use crate::accel::testing::{entry_exactly, grazed_box};
    use crate::geom::{Aabb, Ray};

    /// Coordinates on a half grid (so that origins lie in box faces and
    /// components are exactly zero), or anywhere.
    fn coordinate() -> impl Strategy<Value = f32> {
        prop_oneof![(-4i32..=4).prop_map(|k| k as f32 * 0.5), -4f32..4.0, Just(-0.0f32)]
    }

    fn point() -> impl Strategy<Value = Vec3> {
        (coordinate(), coordinate(), coordinate()).prop_map(|(x, y, z)| Vec3::new(x, y, z))
    }

    /// Eight rays whose direction components share the first ray's sign
    /// bits (zeros of either sign included), with their limits.
    fn packet() -> impl Strategy<Value = Vec<Ray>> {
        (
            point(),
            proptest::collection::vec((point(), point(), prop_oneof![Just(f32::INFINITY), 0.1f32..20.0]), 8),
        )
            .prop_filter_map("a zero direction", |(signs, rays)| {
                let rays: Vec<Ray> = rays
                    .into_iter()
                    .map(|(o, d, t_max)| {
                        let s = |c: f32, sign: f32| c.abs().copysign(sign);
                        let dir = Vec3::new(s(d.x, signs.x), s(d.y, signs.y), s(d.z, signs.z));
                        Ray { origin: o, dir, t_max }
                    })
                    .collect();
                rays.iter().all(|r| r.dir != Vec3::ZERO).then_some(rays)
            })
    }

    /// Up to eight boxes, some flat on an axis.
    fn node() -> impl Strategy<Value = Node> {
        proptest::collection::vec((point(), point(), 0u8..4), 1..=8).prop_map(|boxes| {
            let children: Vec<(Aabb, u32)> = boxes
                .into_iter()
                .enumerate()
                .map(|(i, (a, b, flat))| {
                    let (lo, mut hi) = (a.min(b), a.max(b));
                    if flat < 3 {
                        hi[flat as usize] = lo[flat as usize];
                    }
                    (Aabb { lo, hi }, i as u32)
                })
                .collect();
            Node::new(&children)
        })
    }

    /// Every box one of the rays enters, the packet's test enters too, at
    /// no later distance.
    fn covers<L: Lanes>(rays: &[Ray], n: &Node) -> Result<(), TestCaseError> {
        let p = PacketRays::new::<L>(rays);
        let widest = rays.iter().fold(f32::NEG_INFINITY, |a, r| a.max(r.t_max));
        let (packet, bound) = Frustum::<L>::new(&p).test(n, widest);
        for r in rays {
            let (hit, t) = SlabRay::<L>::new(r).test(n, r.t_max);
            prop_assert_eq!(hit & !packet, 0, "{:?} enters a box the packet skips", r);
            for lane in 0..WIDTH {
                if hit & (1 << lane) != 0 {
                    prop_assert!(
                        bound[lane] <= t[lane],
                        "lane {}: {} after {}",
                        lane,
                        bound[lane],
                        t[lane]
                    );
                }
            }
        }
        Ok(())
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(3000))]
        #[test]
        fn the_packet_test_enters_every_box_a_ray_enters(rays in packet(), n in node()) {
            prop_assume!(n.child.iter().any(|&c| c != EMPTY));
            covers::<f32x8>(&rays, &n)?;
            #[cfg(target_arch = "x86_64")]
            if crate::geom::avx::available() {
                // SAFETY: the CPU has AVX.
                unsafe { covers_avx(&rays, &n)? };
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn covers_avx(rays: &[Ray], n: &Node) -> Result<(), TestCaseError> {
        covers::<crate::geom::avx::Avx>(rays, n)
    }

    /// Packets of one ray repeated, against boxes that ray enters and
    /// leaves at one point, with no limit or the limit at the entry: the
    /// packet's bounds are then the ray itself, and its test must pass
    /// every box the ray's own test passes, however close the call (the
    /// two must widen their far planes alike).
    #[test]
    fn a_packet_of_one_ray_enters_every_grazed_box_the_ray_enters() {
        let mut rng = rand::rngs::StdRng::seed_from_u64(43);
        let mut entered = 0;
        for _ in 0..30_000 {
            let Some((ray, b)) = grazed_box(&mut rng) else {
                continue;
            };
            let ray = if rng.gen_bool(0.5) {
                Ray {
                    t_max: (entry_exactly(&ray, &b) as f32).next_up(),
                    ..ray
                }
            } else {
                ray
            };
            let rays = [ray; 8];
            let n = Node::new(&[(b, 0)]);
            entered += SlabRay::<f32x8>::new(&ray).test(&n, ray.t_max).0;
            covers::<f32x8>(&rays, &n).unwrap();
            #[cfg(target_arch = "x86_64")]
            if crate::geom::avx::available() {
                // SAFETY: the CPU has AVX.
                unsafe { covers_avx(&rays, &n).unwrap() };
            }
        }
        assert!(entered > 10_000, "{entered}");
    }

    #[test]
    fn rays_in_one_box_and_rays_through_its_faces() {
        let n = Node::new(&[(
            Aabb {
                lo: Vec3::ZERO,
                hi: Vec3::ONE,
            },
            0,
        )]);
        // A fan from a point on the box's face, and one from outside that
        // grazes its edge: each entered by every ray, so by the packet.
        for origin in [Vec3::new(0.5, 0.5, 0.0), Vec3::new(-1.0, 1.0, 0.5)] {
            let rays: Vec<Ray> = (0..8)
                .map(|i| Ray::new(origin, Vec3::new(1.0, -(i as f32) * 0.1, 0.0 + i as f32 * 0.05)))
                .collect();
            let p = PacketRays::new::<f32x8>(&rays);
            let (hit, _) = Frustum::<f32x8>::new(&p).test(&n, f32::INFINITY);
            assert_eq!(hit, 1, "from {origin}");
        }
        // A box behind every ray is skipped.
        let rays: Vec<Ray> = (0..8)
            .map(|i| Ray::new(Vec3::new(2.0, 0.5, 0.5), Vec3::new(1.0, i as f32 * 0.01, 0.0)))
            .collect();
        let p = PacketRays::new::<f32x8>(&rays);
        assert_eq!(Frustum::<f32x8>::new(&p).test(&n, f32::INFINITY).0, 0);
    }
}
