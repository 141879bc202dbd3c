//! The ray casters, siblings behind one trait ([`RayCaster`]: nearest hit
//! and any hit, single rays and packets): a SAH kd-tree over the scene's
//! triangles with 8-byte nodes (Áfra 2012, Table 2), built with binned SAH
//! and empty-space cutting, in parallel (this module's [`KdTree`]); a wide
//! BVH (`bvh`, [`WideBvh`]); and, with the `embree` cargo feature, Intel
//! Embree 3 (`embree`). The out-of-core scene file's walk is in `crate::ooc`.

mod build;
mod bvh;
mod caster;
mod coarse_grid;
#[cfg(feature = "embree")]
pub mod embree;
mod leaf;
mod node;
mod packet;
mod parts;
mod reorder;
#[cfg(test)]
pub(crate) mod testing;
mod traverse;

pub use build::BuildOptions;
pub use bvh::{BvhStats, WideBvh, MAX_TRIANGLES};
pub use caster::RayCaster;
pub use node::Node;
pub use packet::PACKET;
pub use parts::PartsError;
pub use reorder::RayOrder;
pub use traverse::Hit;

use crate::geom::Aabb;

/// A kd-tree: nodes (children of an inner node are adjacent), the triangle
/// index lists of the leaves, and the leaves' triangles copied in list order.
pub struct KdTree {
    nodes: Vec<Node>,
    leaf_tris: Vec<u32>,
    leaves: leaf::LeafTris,
    bounds: Aabb,
    /// Where reordering estimates hit points: made on first use, as most
    /// trees (a scene file's chunks, trees that never reorder) never need it.
    grid: std::sync::OnceLock<coarse_grid::CoarseGrid>,
}

/// Sizes of a built tree, for reports and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TreeStats {
    /// Nodes (inner and leaf).
    pub nodes: usize,
    /// Leaves.
    pub leaves: usize,
    /// Empty leaves.
    pub empty_leaves: usize,
    /// Triangle references in leaves (a triangle may be in several).
    pub references: usize,
    /// Deepest leaf.
    pub depth: usize,
    /// Most triangles in one leaf.
    pub max_leaf: usize,
    /// Bytes of nodes, leaf lists and the leaves' triangles (36 per reference).
    pub bytes: usize,
}

impl KdTree {
    /// The scene bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Counts of the tree's parts.
    pub fn stats(&self) -> TreeStats {
        let mut s = TreeStats {
            nodes: self.nodes.len(),
            references: self.leaf_tris.len(),
            bytes: self.nodes.len() * std::mem::size_of::<Node>() + self.leaf_tris.len() * 4 + self.leaves.bytes(),
            ..TreeStats::default()
        };
        let mut stack = vec![(0usize, 0usize)];
        while let Some((i, d)) = stack.pop() {
            let Some(n) = self.nodes.get(i) else { continue };
            if n.is_leaf() {
                s.leaves += 1;
                s.empty_leaves += usize::from(n.count() == 0);
                s.max_leaf = s.max_leaf.max(n.count());
                s.depth = s.depth.max(d);
            } else {
                stack.push((n.left(), d + 1));
                stack.push((n.left() + 1, d + 1));
            }
        }
        s
    }
}
