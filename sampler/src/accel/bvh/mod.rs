//! A 4-wide bounding volume hierarchy for in-core ray casting: each node
//! holds the boxes of up to four children in SIMD lanes, so one ray tests all
//! four with a handful of vector operations, and each leaf is one block of up
//! to four triangles tested at once by the watertight test of
//! [`Ray4`](crate::geom::Ray4). Built with binned SAH over triangle
//! centroids, in parallel.
//!
//! Why a second structure beside the kd-tree: a kd-tree step decides one
//! split plane, one dependent load at a time, and a walk down a 10M-triangle
//! tree takes dozens of them; a wide node decides four boxes at once, in
//! about a third of the levels. The kd-tree stays what out-of-core scene
//! files are cut along (voxel LOD at inner nodes, 8-byte nodes); this
//! hierarchy is for scenes held in memory.

mod build;
mod node;
mod packet;
mod traverse;

pub use build::MAX_TRIANGLES;

use crate::geom::{Aabb, Tri4};

use node::Node4;

/// A 4-wide BVH over a scene's triangles: nodes in depth-first order (the
/// root first), and the leaves' triangles in blocks of four with their
/// triangle indices.
pub struct WideBvh {
    nodes: Vec<Node4>,
    blocks: Vec<Tri4>,
    /// Triangle index of each lane of each block.
    ids: Vec<[u32; 4]>,
    /// The root: a node, a leaf or nothing (see [`node`]).
    root: u32,
    bounds: Aabb,
}

/// Sizes of a built hierarchy, for reports and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Inner nodes.
    pub nodes: usize,
    /// Leaves (blocks of up to four triangles).
    pub leaves: usize,
    /// Deepest leaf, in nodes from the root.
    pub depth: usize,
    /// Mean triangles per leaf.
    pub fill: f32,
    /// Bytes of nodes, blocks and triangle indices.
    pub bytes: usize,
}

impl WideBvh {
    /// The scene bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Counts of the hierarchy's parts.
    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            nodes: self.nodes.len(),
            leaves: self.blocks.len(),
            bytes: self.nodes.len() * std::mem::size_of::<Node4>()
                + self.blocks.len() * (std::mem::size_of::<Tri4>() + 16),
            ..BvhStats::default()
        };
        let mut tris = 0usize;
        let mut stack = vec![(self.root, 0usize)];
        while let Some((r, d)) = stack.pop() {
            match node::Child::decode(r) {
                node::Child::Empty => {}
                node::Child::Leaf { count, .. } => {
                    tris += count;
                    s.depth = s.depth.max(d);
                }
                node::Child::Inner(i) => {
                    if let Some(n) = self.nodes.get(i) {
                        stack.extend(n.child.iter().map(|&c| (c, d + 1)));
                    }
                }
            }
        }
        s.fill = tris as f32 / s.leaves.max(1) as f32;
        s
    }
}
