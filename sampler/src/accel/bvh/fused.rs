//! The slab test with fused multiply-subtracts, for CPUs with AVX2 and FMA:
//! each slab distance is `b * inv - c` in one rounding and one operation,
//! where `c` is the origin's product with the reciprocal direction, moved
//! outward past its rounding once per ray (above it for the near planes,
//! below it for the far ones). As conservative as [`super::slab::SlabRay`]
//! (no box exact arithmetic finds the ray touching is dropped), with one
//! operation less on the path from loading a node to choosing the next:
//! rays that visit many nodes gain most (10% on a 10M-triangle landscape's
//! primary rays). Rays with a zero direction component and an origin off
//! zero on its axis are left to the plain test (their products can
//! overflow, and where they do not, the plain test's answer for a ray lying
//! in a box's far face is kept, so that every box test gives the same hits);
//! so are rays whose reciprocals or products are not finite.

#![cfg(target_arch = "x86_64")]

use std::arch::x86_64::*;

use super::node::{Node, WIDTH};
use super::slab::{BoxTest, FAR_WIDENING, ROBUST};
use crate::geom::Ray;

/// Whether this CPU has AVX2 and FMA (detected once, then a relaxed load).
#[inline]
pub(super) fn available() -> bool {
    std::arch::is_x86_feature_detected!("avx2") && std::arch::is_x86_feature_detected!("fma")
}

/// One ray's constants for the fused test, each in every lane: the
/// reciprocal direction and the origin's product with it for the near
/// planes, the widened reciprocal and its product for the far ones; and
/// which corner array is nearer on each axis. Made and used only in
/// functions compiled with AVX2 and FMA, run where [`available`] found them.
pub(super) struct SlabFused {
    inv: [__m256; 3],
    c: [__m256; 3],
    inv_far: [__m256; 3],
    c_far: [__m256; 3],
    near: [usize; 3],
    far: [usize; 3],
}

/// `o * inv` moved outward past its rounding, lane by lane: by a relative
/// `2^-22` (four times the product's relative error; the sum's own rounding
/// takes back at most one) and an absolute `2^-126` (a product below the
/// normal floats is off by up to `2^-150`). Above the exact product for
/// `up`, below it otherwise.
#[inline(always)]
unsafe fn product_outward(o: __m128, inv: __m128, up: bool) -> __m128 {
    let p = _mm_mul_ps(o, inv);
    let abs = _mm_andnot_ps(_mm_set1_ps(-0.0), p);
    let slack = _mm_add_ps(
        _mm_mul_ps(abs, _mm_set1_ps(2f32.powi(-22))),
        _mm_set1_ps(2f32.powi(-126)),
    );
    if up {
        _mm_add_ps(p, slack)
    } else {
        _mm_sub_ps(p, slack)
    }
}

// Helpers of `SlabFused::new`, functions rather than closures: a closure is
// compiled on its own, without its caller's instructions, unless inlined,
// and these are always inlined into callers compiled with AVX2.

/// `|x|`, lane by lane.
#[inline(always)]
unsafe fn abs(x: __m128) -> __m128 {
    _mm_andnot_ps(_mm_set1_ps(-0.0), x)
}

/// The largest finite float with `x`'s sign, lane by lane.
#[inline(always)]
unsafe fn largest_of_sign(x: __m128) -> __m128 {
    _mm_or_ps(_mm_and_ps(x, _mm_set1_ps(-0.0)), _mm_set1_ps(f32::MAX))
}

/// Lanes 0, 1 and 2 of `v`, each in all eight lanes of its own register.
#[inline(always)]
unsafe fn lanes(v: __m128) -> [__m256; 3] {
    [
        _mm256_broadcastss_ps(v),
        _mm256_broadcastss_ps(_mm_permute_ps::<0b01_01_01_01>(v)),
        _mm256_broadcastss_ps(_mm_permute_ps::<0b10_10_10_10>(v)),
    ]
}

impl SlabFused {
    /// The ray's constants, or `None` for a ray the fused test does not
    /// take. Worked out for the three axes in one register: a ray that
    /// visits few nodes pays this once per few nodes, and scalar code for
    /// it cost the furnished room's rays more than the fused test saved.
    ///
    /// # Safety
    /// The CPU must have AVX2 and FMA ([`available`]), and the caller must
    /// be compiled with them, as must every caller of [`BoxTest::test`] on
    /// the value made (it is inlined there). Holding a `SlabFused` is thus
    /// proof that the CPU has them.
    #[inline(always)]
    pub(super) unsafe fn new(ray: &Ray) -> Option<SlabFused> {
        // SAFETY: the caller guarantees AVX2 and FMA.
        unsafe {
            let d = _mm_setr_ps(ray.dir.x, ray.dir.y, ray.dir.z, 1.0);
            let o = _mm_setr_ps(ray.origin.x, ray.origin.y, ray.origin.z, 0.0);
            let max = _mm_set1_ps(f32::MAX);
            // As `safe_recip`: a zero component gives the largest float of its sign.
            let zero = _mm_cmpeq_ps(d, _mm_setzero_ps());
            let inv = _mm_blendv_ps(_mm_div_ps(_mm_set1_ps(1.0), d), largest_of_sign(d), zero);
            // As `far_recip`: widened, unless that overflows a finite one.
            let wide = _mm_mul_ps(inv, _mm_set1_ps(FAR_WIDENING));
            let overflowed = _mm_andnot_ps(
                _mm_cmpeq_ps(abs(inv), _mm_set1_ps(f32::INFINITY)),
                _mm_cmpgt_ps(abs(wide), max),
            );
            let inv_far = _mm_blendv_ps(wide, largest_of_sign(inv), overflowed);
            let c = product_outward(o, inv, true);
            let c_far = product_outward(o, inv_far, false);
            // Every product and reciprocal finite (a NaN fails too), and
            // no zero direction component with an origin off zero.
            let finite = _mm_and_ps(
                _mm_cmple_ps(abs(inv_far), max),
                _mm_and_ps(_mm_cmple_ps(abs(c), max), _mm_cmple_ps(abs(c_far), max)),
            );
            let lying_off_zero = _mm_and_ps(zero, _mm_cmpneq_ps(o, _mm_setzero_ps()));
            if _mm_movemask_ps(_mm_andnot_ps(lying_off_zero, finite)) != 0b1111 {
                return None;
            }
            // As `corners`: a negative reciprocal meets the high side first.
            let neg = _mm_movemask_ps(inv) as usize;
            let near = [(neg & 1) * 3, ((neg >> 1) & 1) * 3 + 1, ((neg >> 2) & 1) * 3 + 2];
            let far = [3 - near[0], 5 - near[1], 7 - near[2]];
            Some(SlabFused {
                inv: lanes(inv),
                c: lanes(c),
                inv_far: lanes(inv_far),
                c_far: lanes(c_far),
                near,
                far,
            })
        }
    }
}

/// The eight slab distances `corner * inv - c` of one corner array, one
/// fused operation (a function, not a closure, for the reason above).
#[inline(always)]
unsafe fn slab(corner: &wide::f32x8, inv: __m256, c: __m256) -> __m256 {
    // `f32x8` is eight floats aligned to 32 bytes.
    _mm256_fmsub_ps(_mm256_load_ps(corner.as_array_ref().as_ptr()), inv, c)
}

impl BoxTest for SlabFused {
    #[inline(always)]
    fn test(&self, n: &Node, closest: f32) -> (u32, [f32; WIDTH]) {
        // SAFETY: a `SlabFused` exists only where the CPU has AVX2 and FMA
        // (`new`), and this is inlined only into functions compiled with
        // them; the corner arrays are 32-byte aligned (`f32x8`).
        unsafe {
            let b = &n.b;
            let (near, far) = (self.near, self.far);
            let t_near = _mm256_max_ps(
                _mm256_max_ps(
                    slab(&b[near[0]], self.inv[0], self.c[0]),
                    slab(&b[near[1]], self.inv[1], self.c[1]),
                ),
                _mm256_max_ps(slab(&b[near[2]], self.inv[2], self.c[2]), _mm256_setzero_ps()),
            );
            let t_far = _mm256_min_ps(
                _mm256_min_ps(
                    slab(&b[far[0]], self.inv_far[0], self.c_far[0]),
                    slab(&b[far[1]], self.inv_far[1], self.c_far[1]),
                ),
                _mm256_min_ps(
                    slab(&b[far[2]], self.inv_far[2], self.c_far[2]),
                    _mm256_set1_ps(closest * ROBUST),
                ),
            );
            let hit = _mm256_movemask_ps(_mm256_cmp_ps::<_CMP_LE_OQ>(t_near, t_far)) as u32;
            let mut t = [0f32; WIDTH];
            _mm256_storeu_ps(t.as_mut_ptr(), t_near);
            (hit, t)
        }
    }
}

#[cfg(test)]
mod tests {
    use glam::Vec3;
    use rand::{Rng, SeedableRng};

    use super::*;
    use crate::accel::testing::{every_touched_box_passes, random_vec3};
    use crate::geom::Aabb;

    /// Whether the fused test passes box `b` for `ray` within `closest`,
    /// or `None` where it leaves the ray to the plain test.
    #[target_feature(enable = "avx,avx2,fma")]
    unsafe fn passes(ray: &Ray, b: Aabb, closest: f32) -> Option<bool> {
        // SAFETY: compiled with AVX2 and FMA, called where the CPU has them.
        let boxes = unsafe { SlabFused::new(ray) }?;
        Some(boxes.test(&Node::new(&[(b, 0)]), closest).0 & 1 != 0)
    }

    /// Every box that exact arithmetic finds the ray touching, the fused
    /// test passes: boxes entered and left at one point, from origins up to
    /// thousands of units out (where the origin's product with the
    /// reciprocal dwarfs the distances, and rounding it to nearest would
    /// drop boxes), with no limit or the limit at the entry itself.
    #[test]
    fn boxes_touched_in_exact_arithmetic_always_pass() {
        if !available() {
            return;
        }
        every_touched_box_passes(43, |ray, b, closest| {
            // SAFETY: the CPU has AVX2 and FMA.
            match unsafe { passes(ray, b, closest) } {
                Some(pass) => pass,
                None => panic!("ray {ray:?} left to the plain test"),
            }
        });
    }

    /// Conservative, not blind: random boxes that a random ray clearly
    /// meets or clearly misses (by a thousandth of the distances, in
    /// double precision) get exact arithmetic's answer.
    #[test]
    fn clear_hits_and_misses_get_the_exact_answer() {
        if !available() {
            return;
        }
        let mut rng = rand::rngs::StdRng::seed_from_u64(44);
        let (mut hits, mut misses) = (0, 0);
        for k in 0..40_000 {
            let scale = [1.0f32, 100.0, 3000.0][k % 3];
            let ray = Ray::new(random_vec3(&mut rng, scale), random_vec3(&mut rng, 1.0));
            // Around a point of the ray (or behind it), so that about
            // half the boxes are met.
            let centre = ray.at(rng.gen_range(-0.5..3.0) * scale) + random_vec3(&mut rng, scale);
            let half = Vec3::new(
                rng.gen_range(0.01..1.0),
                rng.gen_range(0.01..1.0),
                rng.gen_range(0.01..1.0),
            ) * scale;
            let b = Aabb {
                lo: centre - half,
                hi: centre + half,
            };
            let (o, d) = (ray.origin.as_dvec3(), ray.dir.as_dvec3());
            let (mut near, mut far) = (0f64, f64::INFINITY);
            for c in 0..3 {
                let (t0, t1) = ((f64::from(b.lo[c]) - o[c]) / d[c], (f64::from(b.hi[c]) - o[c]) / d[c]);
                near = near.max(t0.min(t1));
                far = far.min(t0.max(t1));
            }
            if (far - near).abs() < 1e-3 * near.abs().max(far.abs()).max(1e-3 * f64::from(scale)) {
                continue;
            }
            // SAFETY: the CPU has AVX2 and FMA.
            let pass = unsafe { passes(&ray, b, f32::INFINITY) };
            assert_eq!(pass, Some(near <= far), "ray {k} {ray:?} box {b:?}");
            if near <= far {
                hits += 1;
            } else {
                misses += 1;
            }
        }
        assert!(hits > 10_000 && misses > 10_000, "{hits} hits, {misses} misses");
    }

    /// Rays with zero direction components whose origin is zero on those
    /// axes: the fused test takes them and answers as the plain test does,
    /// whichever zero the component is (a box whose near face holds the
    /// ray passes, boxes beside it do not; one whose far face holds it is
    /// passed by, as `TRACER.md` says; the zero's sign says which face is
    /// near). With an origin off zero on such an
    /// axis, small or large, and with a subnormal component, the ray is left
    /// to the plain test.
    #[test]
    fn rays_parallel_to_an_axis() {
        if !available() {
            return;
        }
        let cube = |lo: Vec3| Aabb { lo, hi: lo + Vec3::ONE };
        // (box's low corner, whether it passes for a direction x component
        // of +0, and of -0: the sign of a zero picks which face is near).
        for (lo, plus, minus) in [
            (Vec3::new(0.0, 0.0, 0.0), true, false),
            (Vec3::new(-1.0, 0.0, 0.0), false, true),
            (Vec3::new(-0.5, 0.0, -0.5), true, true),
            (Vec3::new(0.0, 0.0, -1.0), false, false),
            (Vec3::new(1e-30, 0.0, 0.0), false, false),
            (Vec3::new(-1.0 - f32::EPSILON, 0.0, 0.0), false, false),
            (Vec3::new(0.0, -7.0, 0.0), false, false),
        ] {
            for (x, expected) in [(0.0, plus), (-0.0, minus)] {
                let ray = Ray::new(Vec3::new(0.0, -5.0, 0.0), Vec3::new(x, 1.0, 0.0));
                let plain = super::super::slab::SlabRay::<wide::f32x8>::new(&ray);
                let b = cube(lo);
                let reference = plain.test(&Node::new(&[(b, 0)]), f32::INFINITY).0 & 1 != 0;
                assert_eq!(reference, expected, "{lo}, direction {x}");
                // SAFETY: the CPU has AVX2 and FMA.
                assert_eq!(
                    unsafe { passes(&ray, b, f32::INFINITY) },
                    Some(expected),
                    "{lo}, direction {x}"
                );
            }
        }
        // SAFETY (all calls): the CPU has AVX2 and FMA.
        unsafe {
            for z in [0.5, 2.0, 1e-30] {
                let off = Ray::new(Vec3::new(0.0, -5.0, z), Vec3::new(0.0, 1.0, 0.0));
                assert_eq!(
                    passes(&off, cube(Vec3::new(0.0, 0.0, z - 1.0)), f32::INFINITY),
                    None,
                    "{z}"
                );
            }
            let subnormal = Ray::new(Vec3::ZERO, Vec3::new(1e-40, 1.0, 0.0));
            assert_eq!(passes(&subnormal, cube(Vec3::ZERO), f32::INFINITY), None);
        }
    }
}
