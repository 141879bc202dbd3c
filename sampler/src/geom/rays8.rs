//! The watertight ray/triangle test of [`intersect_triangle`] for eight rays
//! against one triangle at once, one ray per SIMD lane: the leaf test of a
//! coherent packet, whose rays share a leaf's triangles. The rays must share
//! the test's axis permutation (rays of one beam do: they run in nearly one
//! direction), so that each triangle coordinate is broadcast to all lanes.
//! Every lane does the scalar test's operations in the scalar test's order,
//! without fused multiply-adds, so it finds exactly the scalar hit; lanes on
//! an edge in single precision go to the scalar test. The arithmetic repeats
//! [`super::Ray4::intersect`]'s on other lanes: shared through a macro it
//! read all nine coordinates up front, which spills eight-lane registers
//! without AVX and cost coherent packets 15%.

use glam::Vec3;
use wide::f32x8;

use super::lanes::Lanes;
use super::triangle::{axis_permutation, intersect_triangle, RayPrep, TriangleHit};

/// Lanes, one ray each.
const LANES: usize = 8;

/// Up to eight rays with one axis permutation, prepared for
/// [`Rays8::intersect`], in lanes of kind `L` (portable by default; the
/// crate's AVX walks use AVX registers).
#[derive(Clone, Copy, Debug)]
pub struct Rays8<L = f32x8> {
    k: [usize; 3],
    o: [L; 3],
    s: [L; 3],
    /// The rays, for the scalar test of lanes on an edge (rare: prepared then).
    rays: [(Vec3, Vec3); LANES],
}

impl<L: Lanes> Rays8<L> {
    /// Prepares the rays `(origin, dir)` of `rays` whose lanes are set in
    /// `lanes`, or `None` when their axis permutations differ (or no lane is set).
    #[inline(always)]
    pub fn new(rays: &[(Vec3, Vec3)], lanes: u32) -> Option<Rays8<L>> {
        let first = lanes.trailing_zeros() as usize;
        let k = axis_permutation(rays.get(first)?.1);
        let [kx, ky, kz] = k;
        let (mut o, mut s) = ([[0f32; LANES]; 3], [[0f32; LANES]; 3]);
        let mut kept = [(Vec3::ZERO, Vec3::ONE); LANES];
        for (i, &(origin, dir)) in rays.iter().enumerate().take(LANES) {
            if lanes & (1 << i) == 0 {
                continue;
            }
            if axis_permutation(dir) != k {
                return None;
            }
            o[0][i] = origin[kx];
            o[1][i] = origin[ky];
            o[2][i] = origin[kz];
            s[0][i] = dir[kx] / dir[kz];
            s[1][i] = dir[ky] / dir[kz];
            s[2][i] = 1.0 / dir[kz];
            kept[i] = (origin, dir);
        }
        Some(Rays8 {
            k,
            o: [L::new(o[0]), L::new(o[1]), L::new(o[2])],
            s: [L::new(s[0]), L::new(s[1]), L::new(s[2])],
            rays: kept,
        })
    }

    /// Tests the triangle `(a, b, c)` against the rays set in `lanes`, each
    /// within `(0, limits[lane]]`, exactly as [`intersect_triangle`] would:
    /// `hit(lane, hit)` gets each hit, and the lane's limit becomes its `t`.
    #[inline(always)]
    pub fn intersect(
        &self,
        tri: [Vec3; 3],
        lanes: u32,
        limits: &mut [f32; LANES],
        mut hit: impl FnMut(usize, TriangleHit),
    ) {
        let [kx, ky, kz] = self.k;
        let [ox, oy, oz] = self.o;
        let [sx, sy, sz] = self.s;
        let [a, b, c] = tri;
        let at = |p: Vec3, k: usize| L::splat(p[k]);
        let (az, bz, cz) = (at(a, kz).sub(oz), at(b, kz).sub(oz), at(c, kz).sub(oz));
        let ax = at(a, kx).sub(ox).sub(sx.mul(az));
        let ay = at(a, ky).sub(oy).sub(sy.mul(az));
        let bx = at(b, kx).sub(ox).sub(sx.mul(bz));
        let by = at(b, ky).sub(oy).sub(sy.mul(bz));
        let cx = at(c, kx).sub(ox).sub(sx.mul(cz));
        let cy = at(c, ky).sub(oy).sub(sy.mul(cz));
        let u = cx.mul(by).sub(cy.mul(bx));
        let v = ax.mul(cy).sub(ay.mul(cx));
        let w = bx.mul(ay).sub(by.mul(ax));
        let zero = L::splat(0.0);
        let edge = u.eq(zero) | v.eq(zero) | w.eq(zero);
        let negative = u.lt(zero) | v.lt(zero) | w.lt(zero);
        let positive = u.gt(zero) | v.gt(zero) | w.gt(zero);
        let det = u.add(v).add(w);
        let t_scaled = u.mul(sz.mul(az)).add(v.mul(sz.mul(bz))).add(w.mul(sz.mul(cz)));
        // `x * det.signum()` is `x` with det's sign bit folded in, exactly.
        let sign = det.sign();
        let (ts, bound) = (t_scaled.xor(sign), L::new(*limits).mul(det).xor(sign));
        let rejected = (negative & positive) | det.eq(zero);
        let pass = ts.gt(zero) & ts.le(bound) & !rejected & lanes;
        let edge = edge & lanes;
        let mut todo = edge | pass;
        if todo == 0 {
            return;
        }
        let (ts, det, v, w) = (t_scaled.to_array(), det.to_array(), v.to_array(), w.to_array());
        while todo != 0 {
            let lane = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let found = if edge & (1 << lane) != 0 {
                let (origin, dir) = self.rays[lane];
                intersect_triangle(&RayPrep::new(origin, dir), a, b, c, limits[lane])
            } else {
                let inv = 1.0 / det[lane];
                Some(TriangleHit {
                    t: ts[lane] * inv,
                    u: v[lane] * inv,
                    v: w[lane] * inv,
                })
            };
            if let Some(h) = found {
                limits[lane] = h.t;
                hit(lane, h);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::testing::vec3;
    use super::*;
    use proptest::prelude::*;

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(2000))]
        /// Every lane gives the scalar test's hit for its ray, bit for bit,
        /// against a sequence of triangles with the limits lowered as they go.
        #[test]
        fn eight_rays_find_what_the_scalar_test_finds(
            tris in proptest::collection::vec((vec3(), vec3(), vec3()), 1..6),
            origin in vec3(),
            dir in vec3(),
            jitter in proptest::collection::vec((vec3(), vec3()), 8),
            lanes in 0u32..256,
            limit in prop_oneof![Just(f32::INFINITY), 0.1f32..20.0],
        ) {
            prop_assume!(dir != Vec3::ZERO && lanes != 0);
            // Rays near one ray (some exactly equal to it), as a beam's are.
            let rays: Vec<(Vec3, Vec3)> = jitter
                .iter()
                .enumerate()
                .map(|(i, &(o, d))| if i % 3 == 0 { (origin, dir) } else { (origin + o * 0.05, dir + d * 0.02) })
                .collect();
            let same = rays
                .iter()
                .enumerate()
                .filter(|(i, _)| lanes & (1 << i) != 0)
                .all(|(_, r)| r.1 != Vec3::ZERO && axis_permutation(r.1) == axis_permutation(rays[lanes.trailing_zeros() as usize].1));
            let Some(packed) = Rays8::<f32x8>::new(&rays, lanes) else {
                prop_assert!(!same);
                return Ok(());
            };
            prop_assert!(same);
            let mut limits = [limit; LANES];
            let mut got = Vec::new();
            for (k, &(a, b, c)) in tris.iter().enumerate() {
                packed.intersect([a, b, c], lanes, &mut limits, |lane, h| got.push((lane, k, h.t.to_bits(), h.u.to_bits())));
            }
            // The AVX lanes, where this CPU has them, give the same bits.
            #[cfg(target_arch = "x86_64")]
            if super::super::avx::available() {
                let packed = Rays8::<super::super::avx::Avx>::new(&rays, lanes);
                prop_assert!(packed.is_some());
                let mut limits = [limit; LANES];
                let mut avx = Vec::new();
                for (k, &(a, b, c)) in tris.iter().enumerate() {
                    if let Some(p) = &packed {
                        p.intersect([a, b, c], lanes, &mut limits, |lane, h| avx.push((lane, k, h.t.to_bits(), h.u.to_bits())));
                    }
                }
                prop_assert_eq!(&avx, &got);
            }
            let mut want = Vec::new();
            for (lane, &(o, d)) in rays.iter().enumerate() {
                if lanes & (1 << lane) == 0 {
                    continue;
                }
                let prep = RayPrep::new(o, d);
                let mut l = limit;
                for (k, &(a, b, c)) in tris.iter().enumerate() {
                    if let Some(h) = intersect_triangle(&prep, a, b, c, l) {
                        want.push((lane, k, h.t.to_bits(), h.u.to_bits()));
                        l = h.t;
                    }
                }
            }
            got.sort_unstable();
            want.sort_unstable();
            prop_assert_eq!(got, want);
        }
    }

    #[test]
    fn rays_with_different_permutations_are_refused() {
        let rays = [(Vec3::ZERO, Vec3::X), (Vec3::ZERO, Vec3::Y)];
        assert!(Rays8::<f32x8>::new(&rays, 0b11).is_none());
        assert!(Rays8::<f32x8>::new(&rays, 0b01).is_some());
        assert!(Rays8::<f32x8>::new(&rays, 0).is_none());
    }
}
