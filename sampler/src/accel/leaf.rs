//! The leaves' triangles, copied beside the leaf lists four to a block in
//! SIMD lanes: reference `i` of the leaf lists sits in lane `i % 4` of block
//! `i / 4`, so a leaf's triangles are read from consecutive memory, with no
//! lookup through the mesh, and tested four at a time. A leaf that starts or
//! ends inside a block masks the other leaves' lanes off; no padding is
//! needed. 36 bytes per reference, bought for speed: the mesh alone would
//! cost four dependent, scattered loads per triangle tested.

use rayon::prelude::*;

use crate::geom::{Ray4, Tri4, TriangleHit};
use crate::scene::Scene;

/// Lanes per block.
const LANES: usize = 4;

/// The leaf triangles, in blocks of four.
pub(crate) struct LeafTris {
    blocks: Vec<Tri4>,
}

impl LeafTris {
    /// Copies the triangles of the leaf lists `leaf_tris` (indices into the scene).
    pub(crate) fn new(scene: &Scene, leaf_tris: &[u32]) -> LeafTris {
        let blocks = leaf_tris
            .par_chunks(LANES)
            .map(|ids| Tri4::from_triangles(ids.iter().map(|&t| scene.vertices(t as usize))))
            .collect();
        LeafTris { blocks }
    }

    /// Bytes held.
    pub(crate) fn bytes(&self) -> usize {
        self.blocks.len() * std::mem::size_of::<Tri4>()
    }

    /// Coordinate `i` (`3 * vertex + axis`) of leaf-list entry `entry`, read
    /// in place.
    #[inline]
    pub(crate) fn coordinate(&self, entry: usize, i: usize) -> f32 {
        self.blocks[entry / LANES].p[i].as_array_ref()[entry % LANES]
    }

    /// Tests the entries `first..first + count` in order, as the scalar test
    /// on each would: `hit(entry, hit)` gets each hit within `(0, limit]` and
    /// returns the limit for the entries after it, or `None` to stop. Returns
    /// false when stopped.
    #[inline]
    pub(crate) fn intersect(
        &self,
        ray: &Ray4,
        first: usize,
        count: usize,
        limit: f32,
        mut hit: impl FnMut(usize, TriangleHit) -> Option<f32>,
    ) -> bool {
        if count == 0 {
            return true;
        }
        let end = first + count;
        let mut limit = limit;
        for b in first / LANES..end.div_ceil(LANES) {
            let base = b * LANES;
            // Lanes of this leaf: from `first` on in the first block, up to `end` in the last.
            let lo = first.saturating_sub(base);
            let hi = (end - base).min(LANES);
            let lanes = (0xF_u32 << lo) & (0xF_u32 >> (LANES - hi));
            let go = ray.intersect(&self.blocks[b], lanes, limit, |lane, h| {
                let l = hit(base + lane, h)?;
                limit = l;
                Some(l)
            });
            if !go {
                return false;
            }
        }
        true
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::soup;

    /// The vertices of entry `i`, read coordinate by coordinate.
    fn vertices(leaves: &LeafTris, i: usize) -> [glam::Vec3; 3] {
        let v = |k: usize| {
            glam::Vec3::new(
                leaves.coordinate(i, 3 * k),
                leaves.coordinate(i, 3 * k + 1),
                leaves.coordinate(i, 3 * k + 2),
            )
        };
        [v(0), v(1), v(2)]
    }

    #[test]
    fn leaves_starting_and_ending_inside_blocks_see_only_their_triangles() {
        let scene = soup(3, 40);
        let ids: Vec<u32> = (0..scene.triangles.len() as u32).rev().collect();
        let leaves = LeafTris::new(&scene, &ids);
        for (i, &t) in ids.iter().enumerate() {
            assert_eq!(vertices(&leaves, i), scene.vertices(t as usize));
        }
        // A ray through every triangle's centroid, one at a time: only the
        // entries asked for may report hits.
        for (first, count) in [(0, 1), (1, 2), (3, 6), (5, 3), (4, 4), (7, 9), (2, 0)] {
            for i in first..first + count {
                let [a, b, c] = vertices(&leaves, i);
                let centre = (a + b + c) / 3.0;
                let n = (b - a).cross(c - a).normalize();
                let ray = Ray4::new(centre + n, -n);
                let mut seen = Vec::new();
                leaves.intersect(&ray, first, count, f32::INFINITY, |e, _| {
                    seen.push(e);
                    Some(f32::INFINITY)
                });
                assert!(seen.contains(&i), "entry {i} of {first}..+{count}: {seen:?}");
                assert!(seen.iter().all(|e| (first..first + count).contains(e)), "{seen:?}");
            }
        }
    }
}
