//! The slab test against a node's boxes, made conservative so that rounding
//! never drops a box a ray grazes (the triangle test is watertight, and the
//! box test must not undo that), over eight float lanes of either kind:
//! `wide`'s portable ones, or 256-bit AVX registers on CPUs that have them.
//! The walks are generic over [`Lanes`] and always inlined, so that the AVX
//! versions compile into functions built for AVX and chosen at run time; both
//! kinds do the same operations in the same order and give the same bits.

use wide::{f32x8, CmpLe};

use super::node::{Node, WIDTH};
use crate::geom::Ray;

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

/// Eight float lanes: the operations the box tests need. `max` and `min`
/// return `other`'s lane where either is NaN, as the x86 instructions do.
pub(super) trait Lanes: Copy {
    fn splat(x: f32) -> Self;
    fn new(a: [f32; WIDTH]) -> Self;
    /// Corner array `k` of a node.
    fn corner(n: &Node, k: usize) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
    fn max(self, o: Self) -> Self;
    fn min(self, o: Self) -> Self;
    /// Lanes where `self <= o` (false where either is NaN), as bits.
    fn le(self, o: Self) -> u32;
    fn to_array(self) -> [f32; WIDTH];
}

impl Lanes for f32x8 {
    #[inline(always)]
    fn splat(x: f32) -> Self {
        f32x8::splat(x)
    }
    #[inline(always)]
    fn new(a: [f32; WIDTH]) -> Self {
        f32x8::new(a)
    }
    #[inline(always)]
    fn corner(n: &Node, k: usize) -> Self {
        n.b[k]
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        self * o
    }
    #[inline(always)]
    fn max(self, o: Self) -> Self {
        self.fast_max(o)
    }
    #[inline(always)]
    fn min(self, o: Self) -> Self {
        self.fast_min(o)
    }
    #[inline(always)]
    fn le(self, o: Self) -> u32 {
        self.cmp_le(o).move_mask() as u32
    }
    #[inline(always)]
    fn to_array(self) -> [f32; WIDTH] {
        f32x8::to_array(self)
    }
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

    /// The children whose boxes the ray enters within `[0, closest]`
    /// (widened by [`ROBUST`]), one bit per child lane, and each lane's
    /// entry distance.
    #[inline(always)]
    pub(super) fn test(&self, n: &Node, closest: f32) -> (u32, [f32; WIDTH]) {
        let slab = |k: usize, c: usize| L::corner(n, k).sub(self.o[c]).mul(self.inv[c]);
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

/// Lanes in AVX registers.
#[cfg(target_arch = "x86_64")]
pub(super) mod avx {
    use std::arch::x86_64::*;

    use super::{Lanes, Node, WIDTH};

    /// Whether this CPU has AVX (detected once, then a relaxed load).
    #[inline]
    pub(in super::super) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx")
    }

    /// Eight lanes in one AVX register. Its methods must be inlined into
    /// functions compiled for AVX, called only after [`available`].
    #[derive(Clone, Copy)]
    pub(in super::super) struct Avx(__m256);

    // SAFETY (every method): values of this type are made and used only in
    // functions compiled with AVX enabled, which run only where `available`
    // found it.
    impl Lanes for Avx {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            Avx(unsafe { _mm256_set1_ps(x) })
        }
        #[inline(always)]
        fn new(a: [f32; WIDTH]) -> Self {
            Avx(unsafe { _mm256_loadu_ps(a.as_ptr()) })
        }
        #[inline(always)]
        fn corner(n: &Node, k: usize) -> Self {
            // `Node` is 64-byte aligned and starts with six 32-byte arrays of eight floats.
            Avx(unsafe { _mm256_load_ps(n.b.as_ptr().add(k) as *const f32) })
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            Avx(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn mul(self, o: Self) -> Self {
            Avx(unsafe { _mm256_mul_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn max(self, o: Self) -> Self {
            Avx(unsafe { _mm256_max_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn min(self, o: Self) -> Self {
            Avx(unsafe { _mm256_min_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn le(self, o: Self) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0)) as u32 }
        }
        #[inline(always)]
        fn to_array(self) -> [f32; WIDTH] {
            let mut a = [0f32; WIDTH];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
    }
}
