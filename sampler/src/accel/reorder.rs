//! Hit-point ray reordering (Moon et al. 2010): before a batch of incoherent
//! rays is traced, each ray's hit point is estimated on a coarse level of
//! the tree (an occupancy grid made from its top levels, small enough to
//! stay in cache: `coarse_grid`), quantized
//! in the scene's bounds and given a Z-curve key; the batch is radix-sorted
//! by key and traced in that order, so that rays which will touch the same
//! nodes and triangles follow one another. Results come back in the rays'
//! own order and are exactly those of tracing each ray alone.

use super::coarse_grid::CoarseGrid;
use super::{Hit, KdTree};
use crate::geom::Ray;

/// Bits per axis of the quantized hit point (a 30-bit Z-curve key).
const BITS: u32 = 10;

/// The order in which a batch of rays is traced.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub enum RayOrder {
    /// As given.
    AsGiven,
    /// By the Z-curve key of each ray's estimated hit point (Moon et al.).
    #[default]
    HitPoint,
    /// By the Z-curve key of each ray's origin: no estimate to make, and as
    /// good as hit points for diffuse bounces, whose origins are the last
    /// hits (measured in `holodeck bench tracer`).
    Origin,
}

impl KdTree {
    /// Nearest hits of a batch of rays, traced in `order`; the hits are in
    /// the rays' order and equal those of [`KdTree::intersect`] on each ray.
    pub fn intersect_batch(&self, rays: &[Ray], order: RayOrder) -> Vec<Option<Hit>> {
        self.in_order(rays, order, |r| self.intersect(r))
    }

    /// `f` of every ray, called in `order`, returned in the rays' order.
    pub fn in_order<T: Default + Clone>(&self, rays: &[Ray], order: RayOrder, mut f: impl FnMut(&Ray) -> T) -> Vec<T> {
        let sorted = match order {
            RayOrder::AsGiven => return rays.iter().map(f).collect(),
            RayOrder::HitPoint => self.hit_point_order(rays),
            RayOrder::Origin => self.origin_order(rays),
        };
        let mut out = vec![T::default(); rays.len()];
        for i in sorted {
            out[i as usize] = f(&rays[i as usize]);
        }
        out
    }

    /// The indices of `rays` sorted by the Z-curve key of their estimated hit
    /// points; rays that miss the coarse level come last, in their order.
    pub fn hit_point_order(&self, rays: &[Ray]) -> Vec<u32> {
        let grid = self.grid();
        self.order_by(rays, |r| grid.first_hit(r, &self.bounds).map(|t| r.at(t)))
    }

    /// The coarse grid of the hit-point estimates, made on first use.
    pub(super) fn grid(&self) -> &CoarseGrid {
        self.grid.get_or_init(|| CoarseGrid::new(&self.nodes, &self.bounds))
    }

    /// The indices of `rays` sorted by the Z-curve key of their origins
    /// (clamped to the scene's bounds).
    pub fn origin_order(&self, rays: &[Ray]) -> Vec<u32> {
        self.order_by(rays, |r| Some(r.origin))
    }

    /// Indices sorted by the Z-curve key of a point per ray (`None` last).
    fn order_by(&self, rays: &[Ray], point: impl Fn(&Ray) -> Option<glam::Vec3>) -> Vec<u32> {
        let lo = self.bounds.lo;
        let extent = (self.bounds.hi - lo).max(glam::Vec3::splat(f32::MIN_POSITIVE));
        let top = ((1u32 << BITS) - 1) as f32;
        let scale = top / extent;
        let mut keyed: Vec<(u32, u32)> = rays
            .iter()
            .enumerate()
            .map(|(i, r)| {
                // NaN (from a non-finite ray) clamps to 0 in the cast.
                let key = point(r).map_or(u32::MAX, |p| {
                    let q = ((p - lo) * scale).clamp(glam::Vec3::ZERO, glam::Vec3::splat(top));
                    morton(q.x as u32, q.y as u32, q.z as u32)
                });
                (key, i as u32)
            })
            .collect();
        radsort::sort_by_key(&mut keyed, |&(key, _)| key);
        keyed.into_iter().map(|(_, i)| i).collect()
    }
}

/// Interleaves the low ten bits of x, y and z (x lowest).
fn morton(x: u32, y: u32, z: u32) -> u32 {
    fn spread(v: u32) -> u32 {
        let mut v = v & 0x3ff;
        v = (v | v << 16) & 0x0300_00ff;
        v = (v | v << 8) & 0x0300_f00f;
        v = (v | v << 4) & 0x030c_30c3;
        (v | v << 2) & 0x0924_9249
    }
    spread(x) | spread(y) << 1 | spread(z) << 2
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::random_vec3;
    use crate::accel::testing::soup;
    use crate::accel::BuildOptions;
    use glam::Vec3;
    use rand::SeedableRng;

    #[test]
    fn morton_keys_interleave_bits() {
        assert_eq!(morton(1, 0, 0), 1);
        assert_eq!(morton(0, 1, 0), 2);
        assert_eq!(morton(0, 0, 1), 4);
        assert_eq!(morton(0b11, 0, 0), 0b1001);
        assert_eq!(morton(1023, 1023, 1023), (1 << 30) - 1);
        // Neighbours along the curve are near in space: the key orders cells
        // of one octant before the next.
        assert!(morton(511, 511, 511) < morton(512, 0, 0));
    }

    #[test]
    fn reordered_batches_find_exactly_what_single_rays_find() {
        for seed in 0..4 {
            let scene = soup(seed, 400);
            let tree = KdTree::build(&scene, &BuildOptions::default());
            let mut rng = rand::rngs::StdRng::seed_from_u64(seed + 30);
            let rays: Vec<Ray> = (0..3000)
                .map(|_| {
                    let o = random_vec3(&mut rng, 7.0);
                    let d = random_vec3(&mut rng, 1.0);
                    Ray::new(o, d)
                })
                .filter(|r| r.dir.length() > 1e-3)
                .collect();
            let order = tree.hit_point_order(&rays);
            let mut seen = order.clone();
            seen.sort_unstable();
            assert_eq!(seen, (0..rays.len() as u32).collect::<Vec<_>>(), "a permutation");
            assert_ne!(order, seen, "the order changed");
            let want: Vec<_> = rays.iter().map(|r| tree.intersect(r)).collect();
            for o in [RayOrder::AsGiven, RayOrder::HitPoint, RayOrder::Origin] {
                let got = tree.intersect_batch(&rays, o);
                assert_eq!(got, want, "seed {seed}, {o:?}");
            }
            assert!(want.iter().flatten().count() > 500);
        }
    }

    #[test]
    fn rays_with_nearby_hits_end_up_near_each_other() {
        // Rays toward two far-apart clusters, interleaved: sorted, each
        // cluster's rays form one run.
        let scene = soup(2, 400);
        let tree = KdTree::build(&scene, &BuildOptions::default());
        let targets = [Vec3::new(-4.0, -4.0, 0.0), Vec3::new(4.0, 3.0, 0.0)];
        let rays: Vec<Ray> = (0..200)
            .map(|i| {
                let o = Vec3::new(0.0, 0.0, 9.0) + Vec3::new((i % 7) as f32, (i % 5) as f32, 0.0) * 0.01;
                Ray::new(o, targets[i % 2] - o)
            })
            .collect();
        let order = tree.hit_point_order(&rays);
        let switches = order.windows(2).filter(|w| w[0] % 2 != w[1] % 2).count();
        // Unsorted, the clusters alternate 199 times; sorted, each is a run or two.
        assert!(switches <= 3, "{switches}: {order:?}");
    }
}
