//! Eight float lanes of either kind: `wide`'s portable ones (SSE pairs on
//! x86-64 without AVX at compile time, NEON on AArch64), or one 256-bit AVX
//! register on CPUs that have it. Kernels are written once, generic over
//! [`Lanes`] and always inlined, so that their AVX versions compile into
//! functions built for AVX and chosen at run time. Both kinds do the same
//! IEEE operations, so a kernel gives the same bits in either.

use wide::{f32x8, CmpEq, CmpGt, CmpLe, CmpLt};

/// Lanes per value.
pub const WIDTH: usize = 8;

/// Eight float lanes: the operations the box and triangle tests need.
/// `max` and `min` return `o`'s lane where either is NaN, as the x86
/// instructions do; comparisons are false where either is NaN.
pub trait Lanes: Copy {
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// The lanes of `a`.
    fn new(a: [f32; WIDTH]) -> Self;
    /// The lanes stored in `a`.
    fn load(a: &f32x8) -> Self;
    /// Lane-wise `self - o`.
    fn sub(self, o: Self) -> Self;
    /// Lane-wise `self + o`.
    fn add(self, o: Self) -> Self;
    /// Lane-wise `self * o`.
    fn mul(self, o: Self) -> Self;
    /// Lane-wise maximum.
    fn max(self, o: Self) -> Self;
    /// Lane-wise minimum.
    fn min(self, o: Self) -> Self;
    /// Lanes where `self <= o`, as bits.
    fn le(self, o: Self) -> u32;
    /// Lanes where `self < o`, as bits.
    fn lt(self, o: Self) -> u32;
    /// Lanes where `self > o`, as bits.
    fn gt(self, o: Self) -> u32;
    /// Lanes where `self == o`, as bits.
    fn eq(self, o: Self) -> u32;
    /// Each lane's sign bit alone (`self & -0.0`).
    fn sign(self) -> Self;
    /// Lane-wise bitwise exclusive or.
    fn xor(self, o: Self) -> Self;
    /// The lanes as an array.
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
    fn load(a: &f32x8) -> Self {
        *a
    }
    #[inline(always)]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline(always)]
    fn add(self, o: Self) -> Self {
        self + o
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
    fn lt(self, o: Self) -> u32 {
        self.cmp_lt(o).move_mask() as u32
    }
    #[inline(always)]
    fn gt(self, o: Self) -> u32 {
        self.cmp_gt(o).move_mask() as u32
    }
    #[inline(always)]
    fn eq(self, o: Self) -> u32 {
        self.cmp_eq(o).move_mask() as u32
    }
    #[inline(always)]
    fn sign(self) -> Self {
        self & f32x8::splat(-0.0)
    }
    #[inline(always)]
    fn xor(self, o: Self) -> Self {
        self ^ o
    }
    #[inline(always)]
    fn to_array(self) -> [f32; WIDTH] {
        f32x8::to_array(self)
    }
}

/// Lanes in AVX registers.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx {
    use std::arch::x86_64::*;

    use wide::f32x8;

    use super::{Lanes, WIDTH};

    /// Whether this CPU has AVX (detected once, then a relaxed load).
    #[inline]
    pub(crate) fn available() -> bool {
        std::arch::is_x86_feature_detected!("avx")
    }

    /// Eight lanes in one AVX register. Its methods must be inlined into
    /// functions compiled for AVX, called only after [`available`]; the type
    /// stays inside this crate for that reason.
    #[derive(Clone, Copy)]
    pub(crate) struct Avx(__m256);

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
        fn load(a: &f32x8) -> Self {
            // `f32x8` is eight floats aligned to 32 bytes.
            Avx(unsafe { _mm256_load_ps(a as *const f32x8 as *const f32) })
        }
        #[inline(always)]
        fn sub(self, o: Self) -> Self {
            Avx(unsafe { _mm256_sub_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn add(self, o: Self) -> Self {
            Avx(unsafe { _mm256_add_ps(self.0, o.0) })
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
        fn lt(self, o: Self) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LT_OQ>(self.0, o.0)) as u32 }
        }
        #[inline(always)]
        fn gt(self, o: Self) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0)) as u32 }
        }
        #[inline(always)]
        fn eq(self, o: Self) -> u32 {
            unsafe { _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0)) as u32 }
        }
        #[inline(always)]
        fn sign(self) -> Self {
            Avx(unsafe { _mm256_and_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
        #[inline(always)]
        fn xor(self, o: Self) -> Self {
            Avx(unsafe { _mm256_xor_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; WIDTH] {
            let mut a = [0f32; WIDTH];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
    }
}
