//! The slab test against a node's boxes, made conservative so that rounding
//! never drops a box a ray grazes (the triangle test is watertight, and the
//! box test must not undo that), over eight float lanes of either kind
//! ([`Lanes`]: portable, or AVX chosen at run time).

use super::node::{Node, WIDTH};
use crate::geom::{Lanes, Ray};

/// `1 + 2 gamma(3)` (Pharr, Jakob and Humphreys, 3.9.2): the nearest hit
/// so far, scaled by it, covers the rounding of the slab distances compared
/// with it (in the box tests, and when entries are popped).
pub(super) const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

/// `1 + 2 gamma(5)`: the far planes' reciprocals scaled by it, once per ray,
/// cover the rounding of the far and near slab distances (three roundings
/// each, the scaling's own two on top), so that the test needs no widening
/// at every node.
pub(super) const FAR_WIDENING: f32 = 1.0 + 2.0 * (5.0 * f32::EPSILON * 0.5) / (1.0 - 5.0 * f32::EPSILON * 0.5);

/// The reciprocal of a direction component, finite: a zero component gives
/// the largest float of its sign, so that `0 * inv` is 0, never NaN, and a
/// ray lying in a box's face counts as inside it.
#[inline]
pub(super) fn safe_recip(d: f32) -> f32 {
    if d == 0.0 {
        f32::MAX.copysign(d)
    } else {
        1.0 / d
    }
}

/// Which of a node's corner arrays (`Node::b`) is nearer, and which
/// farther, on each axis for rays whose reciprocal directions have the signs
/// of `inv`.
#[inline]
pub(super) fn corners(inv: [f32; 3]) -> ([usize; 3], [usize; 3]) {
    let neg = [inv[0] < 0.0, inv[1] < 0.0, inv[2] < 0.0];
    let k = |c: usize| usize::from(neg[c]) * 3 + c;
    let kf = |c: usize| usize::from(!neg[c]) * 3 + c;
    ([k(0), k(1), k(2)], [kf(0), kf(1), kf(2)])
}

/// The far planes' reciprocal of a direction component: `inv` widened by
/// [`FAR_WIDENING`]. A zero component's reciprocal, the largest float, stays
/// that (`0 * inv` must stay 0, a ray lying in a face), as does any finite
/// one the widening would overflow (a component within a factor
/// `FAR_WIDENING` of the smallest normal float); an infinite one (a
/// subnormal component) stays infinite. Monotonic in `inv`, so that a
/// packet's bounds on the reciprocals bound their widened values too.
#[inline]
pub(super) fn far_recip(inv: f32) -> f32 {
    let wide = inv * FAR_WIDENING;
    if wide.is_finite() || inv.is_infinite() {
        wide
    } else {
        f32::MAX.copysign(inv)
    }
}

/// One ray's slab test of a node's eight boxes: near planes' distances
/// from the reciprocal direction, far planes' from the widened one.
pub(super) struct SlabRay<L> {
    o: [L; 3],
    inv: [L; 3],
    inv_far: [L; 3],
    near: [usize; 3],
    far: [usize; 3],
}

impl<L: Lanes> SlabRay<L> {
    #[inline(always)]
    pub(super) fn new(ray: &Ray) -> SlabRay<L> {
        let inv = [safe_recip(ray.dir.x), safe_recip(ray.dir.y), safe_recip(ray.dir.z)];
        let (near, far) = corners(inv);
        SlabRay {
            o: [L::splat(ray.origin.x), L::splat(ray.origin.y), L::splat(ray.origin.z)],
            inv: [L::splat(inv[0]), L::splat(inv[1]), L::splat(inv[2])],
            inv_far: [
                L::splat(far_recip(inv[0])),
                L::splat(far_recip(inv[1])),
                L::splat(far_recip(inv[2])),
            ],
            near,
            far,
        }
    }
}

/// A test of a node's eight boxes, for a walk of the hierarchy: one ray's,
/// or a packet's bounds.
pub(super) trait BoxTest {
    /// The children whose boxes may be entered within `[0, closest]`
    /// (widened by [`ROBUST`]), one bit per child lane, and each lane's
    /// entry distance (or a lower bound of it).
    fn test(&self, n: &Node, closest: f32) -> (u32, [f32; WIDTH]);
}

impl<L: Lanes> BoxTest for SlabRay<L> {
    #[inline(always)]
    fn test(&self, n: &Node, closest: f32) -> (u32, [f32; WIDTH]) {
        // The far side's widening is in its reciprocals, not a product at
        // the end: one operation less on the path from loading a node to
        // choosing the next.
        let slab = |k: usize, c: usize, inv: &[L; 3]| L::load(&n.b[k]).sub(self.o[c]).mul(inv[c]);
        let (near, far) = (self.near, self.far);
        let t_near = slab(near[0], 0, &self.inv)
            .max(slab(near[1], 1, &self.inv))
            .max(slab(near[2], 2, &self.inv).max(L::splat(0.0)));
        let t_far = slab(far[0], 0, &self.inv_far)
            .min(slab(far[1], 1, &self.inv_far))
            .min(slab(far[2], 2, &self.inv_far).min(L::splat(closest * ROBUST)));
        (t_near.le(t_far), t_near.to_array())
    }
}

#[cfg(test)]
mod tests {
    use wide::f32x8;

    use super::*;
    use crate::accel::testing::every_touched_box_passes;
    use crate::geom::Aabb;

    fn passes(boxes: &impl BoxTest, b: Aabb, closest: f32) -> bool {
        boxes.test(&Node::new(&[(b, 0)]), closest).0 & 1 != 0
    }

    /// Every box that exact arithmetic finds the ray touching, the slab
    /// test passes (portable lanes and, where the CPU has it, AVX): boxes
    /// entered and left at one point of the ray, from near and far origins,
    /// with no limit or the limit at the entry itself.
    #[test]
    fn boxes_touched_in_exact_arithmetic_always_pass() {
        every_touched_box_passes(41, |ray, b, closest| {
            let portable = passes(&SlabRay::<f32x8>::new(ray), b, closest);
            #[cfg(target_arch = "x86_64")]
            if crate::geom::avx::available() {
                // SAFETY: the CPU has AVX.
                assert!(unsafe { passes_avx(ray, b, closest) }, "AVX: ray {ray:?} box {b:?}");
            }
            portable
        });
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn passes_avx(ray: &Ray, b: Aabb, closest: f32) -> bool {
        passes(&SlabRay::<crate::geom::avx::Avx>::new(ray), b, closest)
    }
}
