//! The slab test against a node's boxes, made conservative so that rounding
//! never drops a box a ray grazes (the triangle test is watertight, and the
//! box test must not undo that), over eight float lanes of either kind
//! ([`Lanes`]: portable, or AVX chosen at run time).

use super::node::{Node, WIDTH};
use crate::geom::{Lanes, Ray};

/// `1 + 2 gamma(3)` (Pharr, Jakob and Humphreys, 3.9.2): far distances
/// scaled by it cover the rounding of the slab distances.
pub(super) const ROBUST: f32 = 1.0 + 2.0 * (3.0 * f32::EPSILON * 0.5) / (1.0 - 3.0 * f32::EPSILON * 0.5);

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

/// One ray's slab test of a node's eight boxes.
pub(super) struct SlabRay<L> {
    o: [L; 3],
    inv: [L; 3],
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
        let slab = |k: usize, c: usize| L::load(&n.b[k]).sub(self.o[c]).mul(self.inv[c]);
        let (near, far) = (self.near, self.far);
        let t_near = slab(near[0], 0)
            .max(slab(near[1], 1))
            .max(slab(near[2], 2).max(L::splat(0.0)));
        let t_far = slab(far[0], 0)
            .min(slab(far[1], 1))
            .min(slab(far[2], 2).min(L::splat(closest)));
        (t_near.le(t_far.mul(L::splat(ROBUST))), t_near.to_array())
    }
}
