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
    /// Origins and directions by axis, for the scalar test of lanes on an
    /// edge (rare: prepared then).
    origin: [[f32; LANES]; 3],
    dir: [[f32; LANES]; 3],
}

impl<L: Lanes> Rays8<L> {
    /// Prepares the rays `(origin, dir)` of `rays` whose lanes are set in
    /// `lanes`, or `None` when their axis permutations differ (or no lane is set).
    #[inline(always)]
    pub fn new(rays: &[(Vec3, Vec3)], lanes: u32) -> Option<Rays8<L>> {
        let first = *rays.get(lanes.trailing_zeros() as usize)?;
        let (mut origin, mut dir) = ([[0f32; LANES]; 3], [[0f32; LANES]; 3]);
        for i in 0..LANES {
            // Lanes not asked for repeat the first ray, so that every lane
            // must agree and none computes with zeros.
            let (o, d) = if lanes & (1 << i) != 0 {
                rays.get(i).copied().unwrap_or(first)
            } else {
                first
            };
            for c in 0..3 {
                origin[c][i] = o[c];
                dir[c][i] = d[c];
            }
        }
        Rays8::from_lanes(origin, dir)
    }

    /// Prepares eight rays given by axis (`origin[axis][lane]`, the same for
    /// `dir`; repeat a ray in lanes that hold none), or `None` when their
    /// axis permutations differ. Each lane computes what
    /// [`axis_permutation`] and the scalar preparation compute.
    #[inline(always)]
    pub(crate) fn from_lanes(origin: [[f32; LANES]; 3], dir: [[f32; LANES]; 3]) -> Option<Rays8<L>> {
        let k = axis_permutation(Vec3::new(dir[0][0], dir[1][0], dir[2][0]));
        let [kx, ky, kz] = k;
        let zero = L::splat(0.0);
        let d = [L::new(dir[0]), L::new(dir[1]), L::new(dir[2])];
        // |d| for the comparisons (the sign of a zero does not matter there).
        let (ax, ay, az) = (
            d[0].max(zero.sub(d[0])),
            d[1].max(zero.sub(d[1])),
            d[2].max(zero.sub(d[2])),
        );
        let (xy, xz, yz) = (ax.gt(ay), ax.gt(az), ay.gt(az));
        let all = (1u32 << LANES) - 1;
        let (z_is_x, z_is_y) = (xy & xz, !xy & yz & all);
        let same_axis = match kz {
            0 => z_is_x == all,
            1 => z_is_y == all,
            _ => (z_is_x | z_is_y) == 0,
        };
        let negative = d[kz].lt(zero);
        if !same_axis || (negative != 0 && negative != all) {
            return None;
        }
        Some(Rays8 {
            k,
            o: [L::new(origin[kx]), L::new(origin[ky]), L::new(origin[kz])],
            s: [d[kx].div(d[kz]), d[ky].div(d[kz]), L::splat(1.0).div(d[kz])],
            origin,
            dir,
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
        hit: impl FnMut(usize, TriangleHit),
    ) {
        let p = [tri[0].to_array(), tri[1].to_array(), tri[2].to_array()];
        self.intersect_at(|i| p[i / 3][i % 3], lanes, limits, hit);
    }

    /// [`Rays8::intersect`] on the triangle whose coordinate `c` of vertex
    /// `v` is `p(3 * v + c)`: read where the triangle lies (a leaf block's
    /// lane, say), each coordinate loaded straight into all lanes, rather
    /// than copied out first and then picked by the ray's axis permutation.
    #[inline(always)]
    pub fn intersect_at(
        &self,
        p: impl Fn(usize) -> f32,
        lanes: u32,
        limits: &mut [f32; LANES],
        mut hit: impl FnMut(usize, TriangleHit),
    ) {
        let [kx, ky, kz] = self.k;
        let [ox, oy, oz] = self.o;
        let [sx, sy, sz] = self.s;
        let at = |v: usize, k: usize| L::splat(p(3 * v + k));
        let (az, bz, cz) = (at(0, kz).sub(oz), at(1, kz).sub(oz), at(2, kz).sub(oz));
        let ax = at(0, kx).sub(ox).sub(sx.mul(az));
        let ay = at(0, ky).sub(oy).sub(sy.mul(az));
        let bx = at(1, kx).sub(ox).sub(sx.mul(bz));
        let by = at(1, ky).sub(oy).sub(sy.mul(bz));
        let cx = at(2, kx).sub(ox).sub(sx.mul(cz));
        let cy = at(2, ky).sub(oy).sub(sy.mul(cz));
        let u = cx.mul(by).sub(cy.mul(bx));
        let v = ax.mul(cy).sub(ay.mul(cx));
        let w = bx.mul(ay).sub(by.mul(ax));
        let zero = L::splat(0.0);
        let edge = u.eq_mask(zero).or(v.eq_mask(zero)).or(w.eq_mask(zero)).sign_bits() & lanes;
        // Lanes off an edge have u, v and w non-zero: the scalar test rejects
        // them where their signs differ (and then det, a sum of non-zero
        // numbers of one sign, is not zero either). A NaN fails the distance
        // test whatever its sign.
        let rejected = u.xor(v).or(u.xor(w)).sign_bits();
        // Most triangles of a leaf miss every ray on the edge functions' signs.
        if rejected & lanes == lanes && edge == 0 {
            return;
        }
        let det = u.add(v).add(w);
        let t_scaled = u.mul(sz.mul(az)).add(v.mul(sz.mul(bz))).add(w.mul(sz.mul(cz)));
        // `x * det.signum()` is `x` with det's sign bit folded in, exactly.
        let sign = det.sign();
        let (ts, bound) = (t_scaled.xor(sign), L::new(*limits).mul(det).xor(sign));
        let pass = ts.gt_mask(zero).and(ts.le_mask(bound)).sign_bits() & !rejected & lanes;
        let mut todo = edge | pass;
        if todo == 0 {
            return;
        }
        // The scalar test's `x * (1 / det)`, in all lanes at once.
        let inv = L::splat(1.0).div(det);
        let (ts, v, w) = (
            t_scaled.mul(inv).to_array(),
            v.mul(inv).to_array(),
            w.mul(inv).to_array(),
        );
        while todo != 0 {
            let lane = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let found = if edge & (1 << lane) != 0 {
                let at = |v: &[[f32; LANES]; 3]| Vec3::new(v[0][lane], v[1][lane], v[2][lane]);
                let vertex = |v: usize| Vec3::new(p(3 * v), p(3 * v + 1), p(3 * v + 2));
                intersect_triangle(
                    &RayPrep::new(at(&self.origin), at(&self.dir)),
                    vertex(0),
                    vertex(1),
                    vertex(2),
                    limits[lane],
                )
            } else {
                Some(TriangleHit {
                    t: ts[lane],
                    u: v[lane],
                    v: w[lane],
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
