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
use wide::{f32x8, CmpEq, CmpGt, CmpLe, CmpLt};

use super::triangle::{axis_permutation, intersect_triangle, RayPrep, TriangleHit};

/// Lanes, one ray each.
const LANES: usize = 8;

/// Up to eight rays with one axis permutation, prepared for [`Rays8::intersect`].
#[derive(Clone, Copy, Debug)]
pub struct Rays8 {
    k: [usize; 3],
    o: [f32x8; 3],
    s: [f32x8; 3],
    /// The rays, for the scalar test of lanes on an edge (rare: prepared then).
    rays: [(Vec3, Vec3); LANES],
}

impl Rays8 {
    /// Prepares the rays `(origin, dir)` of `rays` whose lanes are set in
    /// `lanes`, or `None` when their axis permutations differ (or no lane is set).
    pub fn new(rays: &[(Vec3, Vec3)], lanes: u32) -> Option<Rays8> {
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
            o: o.map(f32x8::new),
            s: s.map(f32x8::new),
            rays: kept,
        })
    }

    /// Tests the triangle `(a, b, c)` against the rays set in `lanes`, each
    /// within `(0, limits[lane]]`, exactly as [`intersect_triangle`] would:
    /// `hit(lane, hit)` gets each hit, and the lane's limit becomes its `t`.
    #[inline]
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
        let at = |p: Vec3, k: usize| f32x8::splat(p[k]);
        let (az, bz, cz) = (at(a, kz) - oz, at(b, kz) - oz, at(c, kz) - oz);
        let ax = (at(a, kx) - ox) - sx * az;
        let ay = (at(a, ky) - oy) - sy * az;
        let bx = (at(b, kx) - ox) - sx * bz;
        let by = (at(b, ky) - oy) - sy * bz;
        let cx = (at(c, kx) - ox) - sx * cz;
        let cy = (at(c, ky) - oy) - sy * cz;
        let u = cx * by - cy * bx;
        let v = ax * cy - ay * cx;
        let w = bx * ay - by * ax;
        let zero = f32x8::ZERO;
        let edge = u.cmp_eq(zero) | v.cmp_eq(zero) | w.cmp_eq(zero);
        let negative = u.cmp_lt(zero) | v.cmp_lt(zero) | w.cmp_lt(zero);
        let positive = u.cmp_gt(zero) | v.cmp_gt(zero) | w.cmp_gt(zero);
        let det = u + v + w;
        let t_scaled = u * (sz * az) + v * (sz * bz) + w * (sz * cz);
        // `x * det.signum()` is `x` with det's sign bit folded in, exactly.
        let sign = det & f32x8::splat(-0.0);
        let (ts, bound) = (t_scaled ^ sign, (f32x8::new(*limits) * det) ^ sign);
        let rejected = ((negative & positive) | det.cmp_eq(zero)).move_mask() as u32;
        let pass = (ts.cmp_gt(zero) & ts.cmp_le(bound)).move_mask() as u32 & !rejected & lanes;
        let edge = edge.move_mask() as u32 & lanes;
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
            let Some(packed) = Rays8::new(&rays, lanes) else {
                prop_assert!(!same);
                return Ok(());
            };
            prop_assert!(same);
            let mut limits = [limit; LANES];
            let mut got = Vec::new();
            for (k, &(a, b, c)) in tris.iter().enumerate() {
                packed.intersect([a, b, c], lanes, &mut limits, |lane, h| got.push((lane, k, h.t.to_bits(), h.u.to_bits())));
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
        assert!(Rays8::new(&rays, 0b11).is_none());
        assert!(Rays8::new(&rays, 0b01).is_some());
        assert!(Rays8::new(&rays, 0).is_none());
    }
}
