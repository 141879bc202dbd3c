//! The watertight ray/triangle test of [`intersect_triangle`] for one ray
//! against four triangles at once, in SIMD lanes (`wide`: SSE on x86-64, NEON
//! on AArch64, plain code elsewhere). Every lane does the scalar test's
//! operations in the scalar test's order, without fused multiply-adds, so a
//! lane finds exactly the hit the scalar test finds; lanes where the ray meets
//! an edge in single precision are handed to the scalar test, which settles
//! them in double precision.

use glam::Vec3;
use wide::{f32x4, f32x8};

use super::lanes::{LaneOps, Lanes};
use super::triangle::{axis_permutation, intersect_triangle, RayPrep, TriangleHit};

/// Four triangles in structure-of-arrays form: `p[3 * v + c]` holds
/// coordinate `c` of vertex `v` of the four triangles, one per lane.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Tri4 {
    /// Coordinates, lane-wise.
    pub p: [f32x4; 9],
}

impl Default for Tri4 {
    fn default() -> Tri4 {
        Tri4 { p: [f32x4::ZERO; 9] }
    }
}

impl Tri4 {
    /// Up to four triangles, one per lane from lane 0 (the lanes left over
    /// hold zeros). Each coordinate's lanes are gathered in an array and
    /// loaded as one vector: blocks are built by the million, and rewriting
    /// a vector per lane cost twice as much.
    pub fn from_triangles(tris: impl IntoIterator<Item = [Vec3; 3]>) -> Tri4 {
        Tri4 {
            p: lanewise::<4>(tris).map(f32x4::new),
        }
    }

    /// The triangle in lane `lane`.
    #[inline]
    pub fn get(&self, lane: usize) -> [Vec3; 3] {
        triangle_of(|i| self.p[i].as_array_ref()[lane])
    }
}

/// Up to `N` triangles' coordinates lane by lane: `[3 * v + c][lane]` is
/// coordinate `c` of vertex `v` of the triangle in `lane` (zeros past the
/// last triangle).
fn lanewise<const N: usize>(tris: impl IntoIterator<Item = [Vec3; 3]>) -> [[f32; N]; 9] {
    let mut p = [[0f32; N]; 9];
    for (lane, tri) in tris.into_iter().take(N).enumerate() {
        for (v, point) in tri.iter().enumerate() {
            for c in 0..3 {
                p[3 * v + c][lane] = point[c];
            }
        }
    }
    p
}

/// The triangle whose coordinate `i` (`3 * vertex + axis`) is `c(i)`.
#[inline]
fn triangle_of(c: impl Fn(usize) -> f32) -> [Vec3; 3] {
    [
        Vec3::new(c(0), c(1), c(2)),
        Vec3::new(c(3), c(4), c(5)),
        Vec3::new(c(6), c(7), c(8)),
    ]
}

/// Eight triangles in structure-of-arrays form: `p[3 * v + c]` holds
/// coordinate `c` of vertex `v` of the eight triangles, one per lane, so
/// that an eight-lane test loads each coordinate with one 256-bit load.
#[derive(Clone, Copy, Debug)]
#[repr(C)]
pub struct Tri8 {
    /// Coordinates, lane-wise.
    pub p: [f32x8; 9],
}

impl Tri8 {
    /// Up to eight triangles, one per lane from lane 0 (the lanes left over
    /// hold zeros).
    pub fn from_triangles(tris: impl IntoIterator<Item = [Vec3; 3]>) -> Tri8 {
        Tri8 {
            p: lanewise::<8>(tris).map(f32x8::new),
        }
    }

    /// The triangle in lane `lane`.
    #[inline]
    pub fn get(&self, lane: usize) -> [Vec3; 3] {
        triangle_of(|i| self.p[i].as_array_ref()[lane])
    }
}

/// The watertight test's per-ray constants, each in every lane (`splat`):
/// the axis permutation, the origin permuted, and the shear.
#[inline(always)]
fn shear<V>(origin: Vec3, dir: Vec3, splat: impl Fn(f32) -> V) -> ([usize; 3], [V; 3], [V; 3]) {
    let k = axis_permutation(dir);
    let [kx, ky, kz] = k;
    // Arrays, not `Vec3`'s indexing, which branches on the index.
    let (o, d) = (origin.to_array(), dir.to_array());
    (
        k,
        [splat(o[kx]), splat(o[ky]), splat(o[kz])],
        [splat(d[kx] / d[kz]), splat(d[ky] / d[kz]), splat(1.0 / d[kz])],
    )
}

/// A ray prepared for [`Ray4::intersect`]: the shear of the watertight test
/// with its constants in every lane, and the ray itself for lanes on an
/// edge (rare, so the scalar test's constants are made only then).
#[derive(Clone, Copy, Debug)]
pub struct Ray4 {
    k: [usize; 3],
    o: [f32x4; 3],
    s: [f32x4; 3],
    ray: (Vec3, Vec3),
}

impl Ray4 {
    /// Prepares a ray with origin `origin` and direction `dir` (non-zero).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> Ray4 {
        let (k, o, s) = shear(origin, dir, f32x4::splat);
        Ray4 {
            k,
            o,
            s,
            ray: (origin, dir),
        }
    }

    /// The scalar test's constants of this ray.
    pub fn scalar(&self) -> RayPrep {
        RayPrep::new(self.ray.0, self.ray.1)
    }

    /// Tests the lanes set in `lanes` in lane order, exactly as calling
    /// [`intersect_triangle`] on each in turn would: `hit(lane, hit)` gets each
    /// hit within `(0, limit]` and returns the limit for the lanes after it, or
    /// `None` to stop. Returns false when stopped.
    #[inline]
    pub fn intersect(
        &self,
        tri: &Tri4,
        lanes: u32,
        limit: f32,
        hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        match lane_test(|i| tri.p[i], self.k, &self.o, &self.s, lanes, limit) {
            None => true,
            Some(todo) => todo.settle(|lane| tri.get(lane), || self.scalar(), limit, hit),
        }
    }
}

/// The watertight test of one ray (permutation `k`, shear constants `o`
/// and `s` in every lane) against the triangles whose coordinate `i`
/// (`3 * vertex + axis`) is `p(i)`, one per lane, within `(0, limit]`: the
/// lanes of `lanes` that pass or lie on an edge, or `None` where none does.
/// Each lane does the scalar test's operations in its order, without fused
/// multiply-adds.
#[inline(always)]
fn lane_test<V: LaneOps<N>, const N: usize>(
    p: impl Fn(usize) -> V,
    k: [usize; 3],
    o: &[V; 3],
    s: &[V; 3],
    lanes: u32,
    limit: f32,
) -> Option<Settle<N>> {
    let [kx, ky, kz] = k;
    let [ox, oy, oz] = *o;
    let [sx, sy, sz] = *s;
    let (az, bz, cz) = (p(kz).sub(oz), p(3 + kz).sub(oz), p(6 + kz).sub(oz));
    let ax = p(kx).sub(ox).sub(sx.mul(az));
    let ay = p(ky).sub(oy).sub(sy.mul(az));
    let bx = p(3 + kx).sub(ox).sub(sx.mul(bz));
    let by = p(3 + ky).sub(oy).sub(sy.mul(bz));
    let cx = p(6 + kx).sub(ox).sub(sx.mul(cz));
    let cy = p(6 + ky).sub(oy).sub(sy.mul(cz));
    let u = cx.mul(by).sub(cy.mul(bx));
    let v = ax.mul(cy).sub(ay.mul(cx));
    let w = bx.mul(ay).sub(by.mul(ax));
    let zero = V::splat(0.0);
    let edge = u.eq_mask(zero).or(v.eq_mask(zero)).or(w.eq_mask(zero));
    let det = u.add(v).add(w);
    let t_scaled = u.mul(sz.mul(az)).add(v.mul(sz.mul(bz))).add(w.mul(sz.mul(cz)));
    // `x * det.signum()` is `x` with det's sign bit folded in, exactly.
    let sign = det.sign();
    let (ts, bound) = (t_scaled.xor(sign), V::splat(limit).mul(det).xor(sign));
    // Lanes off an edge have u, v and w non-zero: the scalar test rejects
    // them where their signs differ (and then det, a sum of non-zero
    // numbers of one sign, is not zero either). A NaN fails the distance
    // test whatever its sign.
    let rejected = u.xor(v).or(u.xor(w)).sign_bits();
    let pass = ts.gt_mask(zero).and(ts.le_mask(bound)).sign_bits() & !rejected & lanes;
    let edge = edge.sign_bits() & lanes;
    let todo = edge | pass;
    (todo != 0).then(|| Settle {
        todo,
        edge,
        ts: t_scaled.to_array(),
        det: det.to_array(),
        v: v.to_array(),
        w: w.to_array(),
    })
}

/// The lanes a block test passed or found on an edge, with what settling
/// them needs: each lane's scaled distance, determinant and barycentric
/// numerators.
struct Settle<const N: usize> {
    todo: u32,
    edge: u32,
    ts: [f32; N],
    det: [f32; N],
    v: [f32; N],
    w: [f32; N],
}

impl<const N: usize> Settle<N> {
    /// Settles the lanes in lane order as the scalar test would, edge lanes
    /// by the scalar test itself (`tri(lane)` gives their vertices), and
    /// hands the hits to `hit` as [`Ray4::intersect`] describes.
    #[inline(always)]
    fn settle(
        self,
        tri: impl Fn(usize) -> [Vec3; 3],
        scalar: impl Fn() -> RayPrep,
        mut limit: f32,
        mut hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        let Settle {
            mut todo,
            edge,
            ts,
            det,
            v,
            w,
        } = self;
        while todo != 0 {
            let lane = todo.trailing_zeros() as usize;
            todo &= todo - 1;
            let found = if edge & (1 << lane) != 0 {
                let [a, b, c] = tri(lane);
                intersect_triangle(&scalar(), a, b, c, limit)
            } else {
                // Passed against the limit the block started with; check the
                // limit that earlier lanes may have lowered, as the scalar test would.
                let sign = det[lane].signum();
                (ts[lane] * sign <= limit * det[lane] * sign).then(|| {
                    let inv = 1.0 / det[lane];
                    TriangleHit {
                        t: ts[lane] * inv,
                        u: v[lane] * inv,
                        v: w[lane] * inv,
                    }
                })
            };
            if let Some(h) = found {
                match hit(lane, h) {
                    Some(l) => limit = l,
                    None => return false,
                }
            }
        }
        true
    }
}

/// A ray prepared for [`RayWide::intersect`]: [`Ray4`]'s constants in eight
/// lanes of either kind, for two blocks tested at once (a leaf of up to
/// eight triangles costs one test where the CPU has AVX).
#[derive(Clone, Copy)]
pub struct RayWide<L> {
    k: [usize; 3],
    o: [L; 3],
    s: [L; 3],
    ray: (Vec3, Vec3),
}

impl<L: Lanes> RayWide<L> {
    /// Prepares a ray with origin `origin` and direction `dir` (non-zero).
    #[inline(always)]
    pub fn new(origin: Vec3, dir: Vec3) -> RayWide<L> {
        let (k, o, s) = shear(origin, dir, L::splat);
        RayWide {
            k,
            o,
            s,
            ray: (origin, dir),
        }
    }

    /// Tests the lanes set in `lanes` of blocks `a` (lanes 0..4) and `b`
    /// (lanes 4..8) in lane order, exactly as [`Ray4::intersect`] on `a` and
    /// then on `b` would, given that `hit` never raises the limit (lanes
    /// are first passed against the limit the test starts with, as in
    /// [`Ray4::intersect`]).
    #[inline(always)]
    pub fn intersect(
        &self,
        a: &Tri4,
        b: &Tri4,
        lanes: u32,
        limit: f32,
        hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        let p = |i: usize| L::load_halves(&a.p[i], &b.p[i]);
        match lane_test(p, self.k, &self.o, &self.s, lanes, limit) {
            None => true,
            Some(todo) => {
                let tri = |lane: usize| if lane < 4 { a.get(lane) } else { b.get(lane - 4) };
                todo.settle(tri, || RayPrep::new(self.ray.0, self.ray.1), limit, hit)
            }
        }
    }

    /// [`RayWide::intersect`] on eight triangles held side by side, each
    /// coordinate of all eight loaded at once (no halves put together).
    #[inline(always)]
    pub fn intersect8(
        &self,
        t: &Tri8,
        lanes: u32,
        limit: f32,
        hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        match lane_test(|i| L::load(&t.p[i]), self.k, &self.o, &self.s, lanes, limit) {
            None => true,
            Some(todo) => todo.settle(|lane| t.get(lane), || RayPrep::new(self.ray.0, self.ray.1), limit, hit),
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
        /// Every lane gives the scalar test's hit, bit for bit, with the limit
        /// lowered by earlier lanes as a sequential loop lowers it.
        #[test]
        fn four_lanes_find_what_the_scalar_test_finds(
            tris in proptest::collection::vec((vec3(), vec3(), vec3()), 4),
            origin in vec3(),
            dir in vec3(),
            lanes in 0u32..16,
            limit in prop_oneof![Just(f32::INFINITY), 0.1f32..20.0],
        ) {
            prop_assume!(dir != Vec3::ZERO);
            let block = Tri4::from_triangles(tris.iter().map(|&(a, b, c)| [a, b, c]));
            for (i, &(a, b, c)) in tris.iter().enumerate() {
                prop_assert_eq!(block.get(i), [a, b, c]);
            }
            let ray = Ray4::new(origin, dir);
            let mut got = Vec::new();
            ray.intersect(&block, lanes, limit, |lane, h| {
                got.push((lane, h.t));
                Some(h.t)
            });
            let mut want = Vec::new();
            let mut l = limit;
            for (i, &(a, b, c)) in tris.iter().enumerate() {
                if lanes & (1 << i) == 0 {
                    continue;
                }
                if let Some(h) = intersect_triangle(&ray.scalar(), a, b, c, l) {
                    want.push((i, h.t));
                    l = h.t;
                }
            }
            prop_assert_eq!(got, want);
        }
    }

    /// Tests `lanes` of two blocks with [`RayWide`] over lanes of kind `L`,
    /// as two halves and as the same eight triangles side by side
    /// ([`Tri8`]); the two must agree.
    fn eight<L: Lanes>(ray: &Ray4, a: &Tri4, b: &Tri4, lanes: u32, limit: f32) -> Vec<(usize, f32)> {
        type OnHit<'a> = &'a mut dyn FnMut(usize, TriangleHit) -> Option<f32>;
        let wide = RayWide::<L>::new(ray.ray.0, ray.ray.1);
        let run = |test: &dyn Fn(OnHit)| {
            let mut got = Vec::new();
            // The limit never rises, as in the walks (a hit may lie an ulp past it).
            let mut cur = limit;
            test(&mut |lane, h| {
                got.push((lane, h.t));
                cur = cur.min(h.t);
                Some(cur)
            });
            got
        };
        let halves = run(&|hit| {
            wide.intersect(a, b, lanes, limit, hit);
        });
        let side_by_side =
            Tri8::from_triangles((0..8).map(|lane| if lane < 4 { a.get(lane) } else { b.get(lane - 4) }));
        let whole = run(&|hit| {
            wide.intersect8(&side_by_side, lanes, limit, hit);
        });
        assert_eq!(halves, whole, "eight triangles side by side");
        halves
    }

    proptest! {
        #![proptest_config(ProptestConfig::with_cases(1000))]
        /// Two blocks tested in eight lanes give what [`Ray4`] gives on the
        /// first block and then the second, bit for bit, in portable lanes
        /// and in AVX ones.
        #[test]
        fn eight_lanes_find_what_two_blocks_of_four_find(
            tris in proptest::collection::vec((vec3(), vec3(), vec3()), 8),
            origin in vec3(),
            dir in vec3(),
            lanes in 0u32..256,
            limit in prop_oneof![Just(f32::INFINITY), 0.1f32..20.0],
        ) {
            prop_assume!(dir != Vec3::ZERO);
            let a = Tri4::from_triangles(tris[..4].iter().map(|&(a, b, c)| [a, b, c]));
            let b = Tri4::from_triangles(tris[4..].iter().map(|&(a, b, c)| [a, b, c]));
            let ray = Ray4::new(origin, dir);
            let mut want = Vec::new();
            let mut l = limit;
            ray.intersect(&a, lanes & 0xF, l, |lane, h| {
                want.push((lane, h.t));
                l = l.min(h.t);
                Some(l)
            });
            ray.intersect(&b, lanes >> 4, l, |lane, h| {
                want.push((lane + 4, h.t));
                l = l.min(h.t);
                Some(l)
            });
            prop_assert_eq!(&eight::<wide::f32x8>(&ray, &a, &b, lanes, limit), &want);
            #[cfg(target_arch = "x86_64")]
            if crate::geom::avx::available() {
                // SAFETY: the CPU has AVX.
                let got = unsafe { eight_avx(&ray, &a, &b, lanes, limit) };
                prop_assert_eq!(&got, &want);
            }
        }
    }

    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn eight_avx(ray: &Ray4, a: &Tri4, b: &Tri4, lanes: u32, limit: f32) -> Vec<(usize, f32)> {
        eight::<crate::geom::avx::Avx>(ray, a, b, lanes, limit)
    }

    #[test]
    fn stopping_skips_the_later_lanes() {
        let t = [
            Vec3::new(-1.0, -1.0, 1.0),
            Vec3::new(1.0, -1.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        ];
        let block = Tri4::from_triangles((0..4).map(|lane| t.map(|p| p + Vec3::Z * lane as f32)));
        let ray = Ray4::new(Vec3::ZERO, Vec3::Z);
        let mut seen = Vec::new();
        let finished = ray.intersect(&block, 0b1110, f32::INFINITY, |lane, h| {
            seen.push((lane, h.t));
            (lane < 2).then_some(f32::INFINITY)
        });
        assert!(!finished);
        assert_eq!(seen, vec![(1, 2.0), (2, 3.0)]);
    }
}
