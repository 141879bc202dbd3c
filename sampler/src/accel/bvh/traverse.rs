//! Walking the wide BVH nearest child first: one ray against a node's eight
//! boxes at once (see [`super::slab`]), and against a leaf's triangles at
//! once (a block of four, or a pair of eight side by side).

use std::mem::MaybeUninit;

use wide::f32x8;

#[cfg(target_arch = "x86_64")]
use super::fused::{self, SlabFused};
use super::node::{Child, EMPTY, WIDTH};
use super::slab::{BoxTest, SlabRay, ROBUST};
use super::{better, reach, WideBvh};
use crate::accel::Hit;
#[cfg(target_arch = "x86_64")]
use crate::geom::avx;
use crate::geom::{Lanes, Ray, RayWide, TriangleHit};

/// Entries of the walk's stack. A level pushes at most `WIDTH - 1`, and the
/// build bounds the depth (32 levels of SAH, then halving: at most 64).
pub(super) const STACK: usize = 64 * (WIDTH - 1);

impl WideBvh {
    /// Visits leaves roughly front to back, testing boxes with `boxes`.
    /// `leaf(block, lanes)` tests a leaf and returns `Some(t)` for a hit
    /// that makes everything beyond `t` irrelevant, or stops the walk with
    /// `Err(())`. Always inlined, so that the caller decides which
    /// instructions the whole walk may use.
    #[inline(always)]
    pub(super) fn walk(
        &self,
        boxes: &impl BoxTest,
        t_max: f32,
        mut leaf: impl FnMut(usize, u32) -> Result<Option<f32>, ()>,
    ) {
        if self.root == EMPTY {
            return;
        }
        let mut closest = t_max;
        // Entries below `sp` are written before they are read; left
        // uninitialized, the stack costs no clearing per ray.
        let mut stack = [MaybeUninit::<(u32, f32)>::uninit(); STACK];
        let mut sp = 0usize;
        let mut cur = self.root;
        loop {
            match Child::decode(cur) {
                Child::Inner(offset) => {
                    let n = self.node(offset);
                    let (mut hit, t) = boxes.test(n, closest);
                    if hit != 0 {
                        if hit & (hit - 1) == 0 {
                            cur = n.child[hit.trailing_zeros() as usize];
                            continue;
                        }
                        // Two or more children: push them farthest first, go to the nearest.
                        let (l0, l1) = (
                            hit.trailing_zeros() as usize,
                            (hit & (hit - 1)).trailing_zeros() as usize,
                        );
                        hit &= hit - 1;
                        hit &= hit - 1;
                        let (mut a, mut b) = ((t[l0], n.child[l0]), (t[l1], n.child[l1]));
                        if b.0 < a.0 {
                            std::mem::swap(&mut a, &mut b);
                        }
                        if hit == 0 {
                            stack[sp] = MaybeUninit::new((b.1, b.0));
                            sp += 1;
                            cur = a.1;
                            continue;
                        }
                        let mut order = [(0f32, 0u32); WIDTH];
                        (order[0], order[1]) = (a, b);
                        let mut k = 2;
                        while hit != 0 {
                            let lane = hit.trailing_zeros() as usize;
                            hit &= hit - 1;
                            // Insert keeping `order` nearest first.
                            let mut j = k;
                            while j > 0 && order[j - 1].0 > t[lane] {
                                order[j] = order[j - 1];
                                j -= 1;
                            }
                            order[j] = (t[lane], n.child[lane]);
                            k += 1;
                        }
                        for &(tn, c) in order[1..k].iter().rev() {
                            stack[sp] = MaybeUninit::new((c, tn));
                            sp += 1;
                        }
                        cur = order[0].1;
                        continue;
                    }
                }
                Child::Leaf { block, count } => match leaf(block, (1u32 << count) - 1) {
                    Err(()) => return,
                    Ok(Some(t)) => closest = closest.min(t),
                    Ok(None) => {}
                },
                Child::Empty => {}
            }
            loop {
                if sp == 0 {
                    return;
                }
                sp -= 1;
                // SAFETY: entries below the old `sp` were written by the pushes above.
                let (next, t) = unsafe { stack[sp].assume_init() };
                if t <= closest * ROBUST {
                    cur = next;
                    break;
                }
            }
        }
    }

    /// The nearest hit within `(0, ray.t_max]`.
    pub fn intersect(&self, ray: &Ray) -> Option<Hit> {
        #[cfg(target_arch = "x86_64")]
        if fused::available() {
            // SAFETY: the CPU has AVX2 and FMA.
            return unsafe { self.intersect_fused(ray) };
        }
        #[cfg(target_arch = "x86_64")]
        if avx::available() {
            // SAFETY: the CPU has AVX.
            return unsafe { self.intersect_avx(ray) };
        }
        self.intersect_with::<f32x8>(&SlabRay::<f32x8>::new(ray), ray)
    }

    /// [`WideBvh::intersect`] compiled for AVX, boxes tested 256 bits at once.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn intersect_avx(&self, ray: &Ray) -> Option<Hit> {
        self.intersect_with::<avx::Avx>(&SlabRay::<avx::Avx>::new(ray), ray)
    }

    /// [`WideBvh::intersect`] compiled for AVX2 and FMA, with the fused box test
    /// (rays it does not take go to the AVX one).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,fma")]
    unsafe fn intersect_fused(&self, ray: &Ray) -> Option<Hit> {
        // SAFETY: this function is compiled with AVX2 and FMA, and called
        // only where the CPU has them.
        match unsafe { SlabFused::new(ray) } {
            Some(boxes) => self.intersect_with::<avx::Avx>(&boxes, ray),
            None => self.intersect_avx(ray),
        }
    }

    /// Tests the triangles of the leaf from `block` in `lanes` against
    /// `wide`, as [`Ray4::intersect`](crate::geom::Ray4::intersect) on them
    /// in turn would: a leaf of one block gives that block for both halves,
    /// its upper lanes off; a leaf of more is a [`super::Pair`], its eight
    /// lanes side by side.
    #[inline(always)]
    fn leaf_test<L: Lanes>(
        &self,
        wide: &RayWide<L>,
        block: usize,
        lanes: u32,
        limit: f32,
        hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        if lanes < 16 {
            let tris = &self.blocks[block].tris;
            wide.intersect(tris, tris, lanes, limit, hit)
        } else {
            wide.intersect8(&self.pair(block).tris, lanes, limit, hit)
        }
    }

    #[inline(always)]
    fn intersect_with<L: Lanes>(&self, boxes: &impl BoxTest, ray: &Ray) -> Option<Hit> {
        let wide = RayWide::<L>::new(ray.origin, ray.dir);
        let mut best: Option<Hit> = None;
        let mut closest = ray.t_max;
        self.walk(
            boxes,
            ray.t_max,
            #[inline(always)]
            |block, lanes| {
                let mut found = None;
                self.leaf_test(
                    &wide,
                    block,
                    lanes,
                    reach(closest),
                    #[inline(always)]
                    |lane, h| {
                        let tri = self.id(block, lanes, lane);
                        if better(h.t, tri, closest, best.map_or(u32::MAX, |b| b.tri)) {
                            closest = h.t;
                            found = Some(h.t);
                            best = Some(Hit {
                                t: h.t,
                                tri,
                                u: h.u,
                                v: h.v,
                            });
                        }
                        Some(reach(closest))
                    },
                );
                Ok(found)
            },
        );
        best
    }

    /// True if a triangle for which `blocks(triangle)` is true lies within
    /// `(0, ray.t_max)`. Triangles that do not block are passed to the
    /// filter and skipped.
    pub fn occluded_by(&self, ray: &Ray, blocks: impl FnMut(u32) -> bool) -> bool {
        #[cfg(target_arch = "x86_64")]
        if fused::available() {
            // SAFETY: the CPU has AVX2 and FMA.
            return unsafe { self.occluded_fused(ray, blocks) };
        }
        #[cfg(target_arch = "x86_64")]
        if avx::available() {
            // SAFETY: the CPU has AVX.
            return unsafe { self.occluded_avx(ray, blocks) };
        }
        self.occluded_with::<f32x8>(&SlabRay::<f32x8>::new(ray), ray, blocks)
    }

    /// [`WideBvh::occluded_by`] compiled for AVX.
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx")]
    unsafe fn occluded_avx(&self, ray: &Ray, blocks: impl FnMut(u32) -> bool) -> bool {
        self.occluded_with::<avx::Avx>(&SlabRay::<avx::Avx>::new(ray), ray, blocks)
    }

    /// [`WideBvh::occluded_by`] compiled for AVX2 and FMA, with the fused box test
    /// (rays it does not take go to the AVX one).
    #[cfg(target_arch = "x86_64")]
    #[target_feature(enable = "avx,avx2,fma")]
    unsafe fn occluded_fused(&self, ray: &Ray, blocks: impl FnMut(u32) -> bool) -> bool {
        // SAFETY: as in `intersect_fused`.
        match unsafe { SlabFused::new(ray) } {
            Some(boxes) => self.occluded_with::<avx::Avx>(&boxes, ray, blocks),
            None => self.occluded_avx(ray, blocks),
        }
    }

    #[inline(always)]
    fn occluded_with<L: Lanes>(&self, boxes: &impl BoxTest, ray: &Ray, mut blocks: impl FnMut(u32) -> bool) -> bool {
        let wide = RayWide::<L>::new(ray.origin, ray.dir);
        let mut hit = false;
        self.walk(
            boxes,
            ray.t_max,
            #[inline(always)]
            |block, lanes| {
                let go = self.leaf_test(
                    &wide,
                    block,
                    lanes,
                    ray.t_max,
                    #[inline(always)]
                    |lane, h| {
                        if h.t < ray.t_max && blocks(self.id(block, lanes, lane)) {
                            hit = true;
                            return None;
                        }
                        Some(ray.t_max)
                    },
                );
                if go {
                    Ok(None)
                } else {
                    Err(())
                }
            },
        );
        hit
    }

    /// True if anything lies within `(0, ray.t_max)`.
    pub fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_by(ray, |_| true)
    }
}

#[cfg(test)]
mod tests {
    use glam::{Mat4, Vec3};
    use rand::SeedableRng;

    use super::*;
    use crate::accel::testing::{heightfield_and_rays, nearest_of_all, random_vec3, soup};
    use crate::accel::{BuildOptions, KdTree};
    use crate::scene::{Material, Scene, SceneBuilder};

    fn scene_of(p: &[Vec3], t: &[[u32; 3]]) -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
        b.add_mesh("mesh", p, t, &[m], Mat4::IDENTITY).unwrap();
        b.finish()
    }

    /// Checks one ray against every triangle tested on its own: exactly the
    /// nearest hit, ties going to the lower triangle index (at a shared
    /// vertex or edge each triangle's own arithmetic gives a slightly
    /// different distance, and the nearest of them must win whichever the
    /// walk meets first); the same answer as the portable box test; and the
    /// same answer to "anything before this distance".
    fn check(scene: &Scene, bvh: &WideBvh, ray: &Ray, what: &str) -> bool {
        let (a, b) = (bvh.intersect(ray), nearest_of_all(scene, ray));
        assert_eq!(a, b, "{what} {ray:?}");
        for (kind, h) in every_box_test(bvh, ray) {
            assert_eq!(a, h, "{what}: {kind} box test");
        }
        let beyond = Ray {
            t_max: b.map_or(1e30, |h| h.t * 1.001),
            ..*ray
        };
        for (kind, o) in every_occluded(bvh, &beyond) {
            assert_eq!(o, b.is_some(), "{what}: occluded, {kind} box test");
        }
        if let Some(h) = b {
            let short = Ray {
                t_max: h.t * 0.999,
                ..*ray
            };
            let expected = nearest_of_all(scene, &short).is_some();
            for (kind, o) in every_occluded(bvh, &short) {
                assert_eq!(o, expected, "{what}: occluded short, {kind} box test");
            }
        }
        b.is_some()
    }

    /// The nearest hit by each box test this CPU can run: portable, AVX, fused.
    fn every_box_test(bvh: &WideBvh, ray: &Ray) -> Vec<(&'static str, Option<Hit>)> {
        let mut all = vec![(
            "portable",
            bvh.intersect_with::<f32x8>(&SlabRay::<f32x8>::new(ray), ray),
        )];
        #[cfg(target_arch = "x86_64")]
        if avx::available() {
            // SAFETY: the CPU has AVX.
            all.push(("AVX", unsafe { bvh.intersect_avx(ray) }));
        }
        #[cfg(target_arch = "x86_64")]
        if fused::available() {
            // SAFETY: the CPU has AVX2 and FMA.
            all.push(("fused", unsafe { bvh.intersect_fused(ray) }));
        }
        all
    }

    /// Whether anything lies within `(0, ray.t_max)` by each box test this
    /// CPU can run.
    fn every_occluded(bvh: &WideBvh, ray: &Ray) -> Vec<(&'static str, bool)> {
        let mut all = vec![(
            "portable",
            bvh.occluded_with::<f32x8>(&SlabRay::<f32x8>::new(ray), ray, |_| true),
        )];
        #[cfg(target_arch = "x86_64")]
        if avx::available() {
            // SAFETY: the CPU has AVX.
            all.push(("AVX", unsafe { bvh.occluded_avx(ray, |_| true) }));
        }
        #[cfg(target_arch = "x86_64")]
        if fused::available() {
            // SAFETY: the CPU has AVX2 and FMA.
            all.push(("fused", unsafe { bvh.occluded_fused(ray, |_| true) }));
        }
        all
    }

    fn close(a: f32, b: f32) -> bool {
        (a - b).abs() <= 1e-6 * b.abs()
    }

    #[test]
    fn nearest_and_any_hits_match_brute_force_on_nasty_soups() {
        for seed in 0..8 {
            let scene = soup(seed, 400);
            let bvh = WideBvh::build(&scene).unwrap();
            let stats = bvh.stats();
            assert!(stats.nodes > 20 && stats.depth > 2 && stats.fill > 1.5, "{stats:?}");
            let mut rng = rand::rngs::StdRng::seed_from_u64(200 + seed);
            let mut hits = 0;
            for k in 0..3000 {
                let origin = random_vec3(&mut rng, 7.0);
                let mut dir = random_vec3(&mut rng, 1.0);
                match k % 4 {
                    // Axis-parallel rays, some lying in the grids' planes.
                    1 => {
                        dir = [Vec3::X, Vec3::Y, Vec3::Z][k % 3] * if k % 8 == 1 { -1.0 } else { 1.0 };
                    }
                    2 => {
                        let target = Vec3::new(
                            (k % 9) as f32 - 4.0,
                            ((k / 9) % 9) as f32 - 4.0 + 0.5 * (k % 2) as f32,
                            0.0,
                        );
                        dir = target - origin;
                    }
                    3 if k % 16 == 3 => {
                        // Starting exactly in a grid plane, as bounce rays do.
                        let o = Vec3::new(origin.x, origin.y, 0.0);
                        let ray = Ray::new(o, dir);
                        hits += usize::from(check(&scene, &bvh, &ray, &format!("seed {seed} ray {k}")));
                        continue;
                    }
                    _ => {}
                }
                if dir.length() < 1e-3 {
                    continue;
                }
                let ray = Ray::new(origin, dir);
                hits += usize::from(check(&scene, &bvh, &ray, &format!("seed {seed} ray {k}")));
            }
            assert!(hits > 700, "{hits}");
        }
    }

    #[test]
    fn empty_tiny_and_coincident_scenes() {
        let empty = WideBvh::build(&Scene::default()).unwrap();
        assert_eq!(empty.intersect(&Ray::new(Vec3::ZERO, Vec3::X)), None);
        assert!(!empty.occluded(&Ray::new(Vec3::ZERO, Vec3::X)));
        // One triangle: the root is a leaf.
        let one = scene_of(
            &[
                Vec3::new(1.0, -1.0, -1.0),
                Vec3::new(1.0, 1.0, -1.0),
                Vec3::new(1.0, 0.0, 1.0),
            ],
            &[[0, 1, 2]],
        );
        let bvh = WideBvh::build(&one).unwrap();
        assert_eq!(bvh.stats().nodes, 0);
        let h = bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).unwrap();
        assert_eq!((h.t, h.tri), (1.0, 0));
        // 2,000 copies of one triangle: every centre in one point, split at
        // the median; the nearest is any copy at the same distance.
        let t: Vec<[u32; 3]> = (0..2000).map(|_| [0, 1, 2]).collect();
        let same = scene_of(
            &[
                Vec3::new(1.0, -1.0, -1.0),
                Vec3::new(1.0, 1.0, -1.0),
                Vec3::new(1.0, 0.0, 1.0),
            ],
            &t,
        );
        let bvh = WideBvh::build(&same).unwrap();
        let stats = bvh.stats();
        assert!(stats.depth <= 8 && stats.fill > 3.5, "{stats:?}");
        assert_eq!(bvh.intersect(&Ray::new(Vec3::ZERO, Vec3::X)).map(|h| h.t), Some(1.0));
        assert!(bvh.occluded(&Ray {
            t_max: 1.5,
            ..Ray::new(Vec3::ZERO, Vec3::X)
        }));
        assert!(!bvh.occluded(&Ray {
            t_max: 0.5,
            ..Ray::new(Vec3::ZERO, Vec3::X)
        }));
    }

    /// Triangles at exponentially growing distances, which SAH peels off one
    /// at a time: the depth stays bounded (the walk's stack with it), and
    /// every triangle is found.
    #[test]
    fn a_lopsided_scene_keeps_its_depth_bounded() {
        let mut p = Vec::new();
        let mut t = Vec::new();
        for i in 0..120u32 {
            let x = 1.5f32.powi(i as i32 - 60);
            p.extend([
                Vec3::new(x, -1.0, -1.0),
                Vec3::new(x, 1.0, -1.0),
                Vec3::new(x, 0.0, 1.0),
            ]);
            t.push([3 * i, 3 * i + 1, 3 * i + 2]);
        }
        let scene = scene_of(&p, &t);
        let bvh = WideBvh::build(&scene).unwrap();
        assert!(bvh.stats().depth <= 64, "{:?}", bvh.stats());
        for i in 0..120u32 {
            let x = 1.5f32.powi(i as i32 - 60);
            // The previous triangle lies at x / 1.5, the next at 1.5 x.
            let ray = Ray::new(Vec3::new(x * 0.8, 0.0, 0.0), Vec3::X);
            assert_eq!(bvh.intersect(&ray).map(|h| h.tri), Some(i), "triangle {i}");
            let back = Ray::new(Vec3::new(x * 1.25, 0.0, 0.0), -Vec3::X);
            assert_eq!(bvh.intersect(&back).map(|h| h.tri), Some(i), "triangle {i} from behind");
        }
    }

    /// Rays aimed exactly at the shared vertices and edges of a heightfield
    /// never slip through, and find what the kd-tree finds.
    #[test]
    fn rays_through_shared_edges_and_vertices_never_leak() {
        let (scene, rays) = heightfield_and_rays(24, 4000, 9);
        let bvh = WideBvh::build(&scene).unwrap();
        let tree = KdTree::build(&scene, &BuildOptions::default());
        for (k, &ray) in rays.iter().enumerate() {
            let Some(h) = bvh.intersect(&ray) else {
                panic!("ray {k} {ray:?} leaked through the field")
            };
            assert!((h.t - 1.0).abs() < 1e-4, "{h:?} {ray:?}");
            let kd = tree.intersect(&ray).map_or(f32::NAN, |h| h.t);
            assert!(close(h.t, kd), "ray {k}: {h:?}, kd-tree {kd}");
        }
    }
}
