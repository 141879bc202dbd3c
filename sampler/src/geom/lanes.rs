//! Eight float lanes of either kind: `wide`'s portable ones (SSE pairs on
//! x86-64 without AVX at compile time, NEON on AArch64), or one 256-bit AVX
//! register on CPUs that have it. Kernels are written once, generic over
//! [`Lanes`] and always inlined, so that their AVX versions compile into
//! functions built for AVX and chosen at run time. Both kinds do the same
//! IEEE operations, so a kernel gives the same bits in either. The
//! operations every width has ([`LaneOps`]) are shared with `f32x4`, so that
//! the watertight triangle test serves four lanes and eight alike.

use wide::{f32x4, f32x8, CmpEq, CmpGt, CmpLe, CmpLt};

/// Lanes per value.
pub const WIDTH: usize = 8;

/// The lane operations of every width (four lanes in `f32x4`, eight in a
/// [`Lanes`] kind), so that a kernel such as the watertight triangle test
/// is written once for both.
pub trait LaneOps<const N: usize>: Copy {
    /// `x` in every lane.
    fn splat(x: f32) -> Self;
    /// Lane-wise `self - o`.
    fn sub(self, o: Self) -> Self;
    /// Lane-wise `self + o`.
    fn add(self, o: Self) -> Self;
    /// Lane-wise `self * o`.
    fn mul(self, o: Self) -> Self;
    /// Each lane's sign bit alone (`self & -0.0`).
    fn sign(self) -> Self;
    /// The lanes' sign bits, as bits.
    fn sign_bits(self) -> u32;
    /// Lane-wise bitwise exclusive or.
    fn xor(self, o: Self) -> Self;
    /// Lane-wise bitwise or.
    fn or(self, o: Self) -> Self;
    /// Lane-wise bitwise and.
    fn and(self, o: Self) -> Self;
    /// All bits set in lanes where `self == o`, none elsewhere: masks
    /// combined lane-wise and read with one [`LaneOps::sign_bits`].
    fn eq_mask(self, o: Self) -> Self;
    /// All bits set in lanes where `self > o`.
    fn gt_mask(self, o: Self) -> Self;
    /// All bits set in lanes where `self <= o`.
    fn le_mask(self, o: Self) -> Self;
    /// The lanes as an array.
    fn to_array(self) -> [f32; N];
}

/// Eight float lanes: the operations the box and triangle tests need.
/// `max` and `min` return `o`'s lane where either is NaN, as the x86
/// instructions do; comparisons are false where either is NaN.
pub trait Lanes: LaneOps<WIDTH> {
    /// The lanes of `a`.
    fn new(a: [f32; WIDTH]) -> Self;
    /// The lanes stored in `a`.
    fn load(a: &f32x8) -> Self;
    /// Lanes 0..4 from `lo` and 4..8 from `hi`.
    fn load_halves(lo: &f32x4, hi: &f32x4) -> Self;
    /// Lane `i` from `f(i)`, built in registers: scalars stored one by one
    /// and then loaded as a vector would stall the load.
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self;
    /// Lane-wise `self / o`.
    fn div(self, o: Self) -> Self;
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
    /// The smallest lane (lanes must not be NaN).
    fn min_lane(self) -> f32;
    /// The largest lane (lanes must not be NaN).
    fn max_lane(self) -> f32;
}

/// `wide`'s portable types, which have the same operators at every width.
macro_rules! wide_lane_ops {
    ($t:ident, $n:literal) => {
        impl LaneOps<$n> for $t {
            #[inline(always)]
            fn splat(x: f32) -> Self {
                $t::splat(x)
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
            fn sign(self) -> Self {
                self & $t::splat(-0.0)
            }
            #[inline(always)]
            fn sign_bits(self) -> u32 {
                self.move_mask() as u32
            }
            #[inline(always)]
            fn xor(self, o: Self) -> Self {
                self ^ o
            }
            #[inline(always)]
            fn or(self, o: Self) -> Self {
                self | o
            }
            #[inline(always)]
            fn and(self, o: Self) -> Self {
                self & o
            }
            #[inline(always)]
            fn eq_mask(self, o: Self) -> Self {
                self.cmp_eq(o)
            }
            #[inline(always)]
            fn gt_mask(self, o: Self) -> Self {
                self.cmp_gt(o)
            }
            #[inline(always)]
            fn le_mask(self, o: Self) -> Self {
                self.cmp_le(o)
            }
            #[inline(always)]
            fn to_array(self) -> [f32; $n] {
                $t::to_array(self)
            }
        }
    };
}

wide_lane_ops!(f32x4, 4);
wide_lane_ops!(f32x8, 8);

impl Lanes for f32x8 {
    #[inline(always)]
    fn new(a: [f32; WIDTH]) -> Self {
        f32x8::new(a)
    }
    #[inline(always)]
    fn load(a: &f32x8) -> Self {
        *a
    }
    #[inline(always)]
    fn load_halves(lo: &f32x4, hi: &f32x4) -> Self {
        let (l, h) = (lo.to_array(), hi.to_array());
        f32x8::new([l[0], l[1], l[2], l[3], h[0], h[1], h[2], h[3]])
    }
    #[inline(always)]
    fn from_fn(f: impl FnMut(usize) -> f32) -> Self {
        f32x8::new(std::array::from_fn(f))
    }
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        self / o
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
    fn min_lane(self) -> f32 {
        self.to_array().iter().fold(f32::INFINITY, |m, &x| m.min(x))
    }
    #[inline(always)]
    fn max_lane(self) -> f32 {
        self.to_array().iter().fold(f32::NEG_INFINITY, |m, &x| m.max(x))
    }
}

/// Lanes in AVX registers.
#[cfg(target_arch = "x86_64")]
pub(crate) mod avx {
    use std::arch::x86_64::*;

    use wide::{f32x4, f32x8};

    use super::{LaneOps, Lanes, WIDTH};

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
    impl LaneOps<8> for Avx {
        #[inline(always)]
        fn splat(x: f32) -> Self {
            Avx(unsafe { _mm256_set1_ps(x) })
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
        fn sign(self) -> Self {
            Avx(unsafe { _mm256_and_ps(self.0, _mm256_set1_ps(-0.0)) })
        }
        #[inline(always)]
        fn sign_bits(self) -> u32 {
            unsafe { _mm256_movemask_ps(self.0) as u32 }
        }
        #[inline(always)]
        fn xor(self, o: Self) -> Self {
            Avx(unsafe { _mm256_xor_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn or(self, o: Self) -> Self {
            Avx(unsafe { _mm256_or_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn and(self, o: Self) -> Self {
            Avx(unsafe { _mm256_and_ps(self.0, o.0) })
        }
        #[inline(always)]
        fn eq_mask(self, o: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_EQ_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn gt_mask(self, o: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_GT_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn le_mask(self, o: Self) -> Self {
            Avx(unsafe { _mm256_cmp_ps::<_CMP_LE_OQ>(self.0, o.0) })
        }
        #[inline(always)]
        fn to_array(self) -> [f32; 8] {
            let mut a = [0f32; WIDTH];
            unsafe { _mm256_storeu_ps(a.as_mut_ptr(), self.0) };
            a
        }
    }

    // SAFETY: as above.
    impl Lanes for Avx {
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
        fn load_halves(lo: &f32x4, hi: &f32x4) -> Self {
            // `f32x4` is four floats aligned to 16 bytes.
            Avx(unsafe {
                _mm256_set_m128(
                    _mm_load_ps(hi as *const f32x4 as *const f32),
                    _mm_load_ps(lo as *const f32x4 as *const f32),
                )
            })
        }
        #[inline(always)]
        fn from_fn(mut f: impl FnMut(usize) -> f32) -> Self {
            let (a, b, c, d) = (f(0), f(1), f(2), f(3));
            let (e, g, h, i) = (f(4), f(5), f(6), f(7));
            Avx(unsafe { _mm256_setr_ps(a, b, c, d, e, g, h, i) })
        }
        #[inline(always)]
        fn div(self, o: Self) -> Self {
            Avx(unsafe { _mm256_div_ps(self.0, o.0) })
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
        fn min_lane(self) -> f32 {
            unsafe {
                let h = _mm_min_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
                let h = _mm_min_ps(h, _mm_movehl_ps(h, h));
                _mm_cvtss_f32(_mm_min_ss(h, _mm_shuffle_ps::<1>(h, h)))
            }
        }
        #[inline(always)]
        fn max_lane(self) -> f32 {
            unsafe {
                let h = _mm_max_ps(_mm256_castps256_ps128(self.0), _mm256_extractf128_ps::<1>(self.0));
                let h = _mm_max_ps(h, _mm_movehl_ps(h, h));
                _mm_cvtss_f32(_mm_max_ss(h, _mm_shuffle_ps::<1>(h, h)))
            }
        }
    }
}
