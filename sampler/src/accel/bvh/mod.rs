//! An 8-wide bounding volume hierarchy for in-core ray casting: each node
//! holds the boxes of up to eight children in SIMD lanes, so one ray tests all
//! eight with a handful of vector operations (256-bit ones where the CPU has
//! AVX, chosen at run time), and each leaf is a block of up to four
//! triangles or, for five to eight, a [`Pair`] in two blocks' space, tested
//! at once in eight lanes by the watertight test of
//! [`RayWide`](crate::geom::RayWide) (one AVX register where the CPU has
//! it). Built with binned SAH over triangle centroids, in parallel.
//!
//! Why a second structure beside the kd-tree: a kd-tree step decides one
//! split plane, one dependent load at a time, and a walk down a 10M-triangle
//! tree takes dozens of them; a wide node decides eight boxes at once, in
//! about a fifth of the levels. The kd-tree stays what out-of-core scene
//! files are cut along (voxel LOD at inner nodes, 8-byte nodes); this
//! hierarchy is for scenes held in memory.

mod build;
mod frustum;
mod fused;
mod node;
mod packet;
mod packet_rays;

mod slab;
mod traverse;

pub use build::MAX_TRIANGLES;

use crate::geom::{Aabb, Tri4, Tri8};

use node::Node;

/// An 8-wide BVH over a scene's triangles: nodes in depth-first order (the
/// root first), and the leaves' triangles with their triangle indices, a
/// block of up to four or a pair (`Pair`) of five to eight in two blocks' space.
pub struct WideBvh {
    nodes: Vec<Node>,
    blocks: Vec<Block>,
    /// The root: a node, a leaf or nothing (see [`node`]).
    root: u32,
    bounds: Aabb,
}

/// Four triangles of a leaf, and beside them their indices (read when a
/// lane is hit: kept on the block's last cache line, an incoherent ray's hit
/// costs no second miss). Aligned to 32 bytes, so that the indices always
/// share a cache line with the last triangle coordinates whatever the
/// allocation's alignment (160 bytes either way).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Block {
    tris: Tri4,
    ids: [u32; 4],
}

/// A leaf of five to eight triangles, held in the space of two blocks: the
/// eight triangles side by side (each coordinate one 256-bit load, where
/// two blocks would need their halves put together), then their indices.
#[derive(Clone, Copy, Debug)]
#[repr(C, align(32))]
struct Pair {
    tris: Tri8,
    ids: [u32; 8],
}

// A pair is read in place of two consecutive blocks.
const _: () = assert!(
    std::mem::size_of::<Pair>() == 2 * std::mem::size_of::<Block>()
        && std::mem::align_of::<Pair>() == std::mem::align_of::<Block>()
);

/// Sizes of a built hierarchy, for reports and benchmarks.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct BvhStats {
    /// Inner nodes.
    pub nodes: usize,
    /// Leaves (a block of up to four triangles, or a pair of up to eight).
    pub leaves: usize,
    /// Deepest leaf, in nodes from the root.
    pub depth: usize,
    /// Mean triangles per leaf.
    pub fill: f32,
    /// Bytes of nodes, blocks and triangle indices.
    pub bytes: usize,
}

/// Whether a hit at `t` on triangle `tri` beats the nearest so far, at
/// `closest` on triangle `best` (`u32::MAX` for none): nearer, or as near on
/// a lower triangle index. Where a ray meets an edge two triangles share,
/// each triangle's own arithmetic gives its own distance, and the scaled
/// comparison of the watertight test can pass a distance an ulp beyond its
/// limit; deciding here by distance, then index, makes the answer the same
/// whatever order the walk meets the triangles in (single rays and packets
/// order children differently).
#[inline]
fn better(t: f32, tri: u32, closest: f32, best: u32) -> bool {
    t < closest || (t == closest && tri < best)
}

/// The limit handed to the triangle tests for a nearest distance `closest`:
/// a little beyond it, so that a triangle at exactly `closest` passes the
/// test's scaled comparison whatever its rounding, and [`better`] decides.
#[inline]
fn reach(closest: f32) -> f32 {
    closest * slab::ROBUST
}

impl WideBvh {
    /// The inner node at byte offset `offset` of the node array (what an
    /// inner reference holds), read without a bounds check: the walks do
    /// this at every node.
    #[inline(always)]
    fn node(&self, offset: usize) -> &Node {
        debug_assert!(
            offset.is_multiple_of(std::mem::size_of::<Node>())
                && offset / std::mem::size_of::<Node>() < self.nodes.len()
        );
        // SAFETY: inner references are written by the build alone
        // (`Child::inner`), each the offset of a node it wrote into the
        // array, which is never changed after; the array's nodes are
        // aligned, and so is every multiple of their size from its start.
        unsafe { &*self.nodes.as_ptr().cast::<u8>().add(offset).cast::<Node>() }
    }

    /// The leaf of two blocks from block `block`, read as one [`Pair`].
    #[inline]
    fn pair(&self, block: usize) -> &Pair {
        let two = &self.blocks[block..block + 2];
        // SAFETY: `Pair` is `repr(C)` with the size and alignment of two
        // blocks, which lie one after the other in the slice; its fields are
        // floats and integers, valid for any bits. A leaf of more than four
        // triangles was written there as a `Pair` (`build::Layout::place`).
        unsafe { &*two.as_ptr().cast::<Pair>() }
    }

    /// The triangle index of lane `lane` of the leaf from block `block`,
    /// whose lanes are the bits of `lanes` (more than four: a [`Pair`]).
    #[inline]
    fn id(&self, block: usize, lanes: u32, lane: usize) -> u32 {
        if lanes < 16 {
            self.blocks[block].ids[lane]
        } else {
            self.pair(block).ids[lane]
        }
    }

    /// The scene bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }

    /// Counts of the hierarchy's parts.
    pub fn stats(&self) -> BvhStats {
        let mut s = BvhStats {
            nodes: self.nodes.len(),
            bytes: self.nodes.len() * std::mem::size_of::<Node>() + self.blocks.len() * std::mem::size_of::<Block>(),
            ..BvhStats::default()
        };
        let mut tris = 0usize;
        let mut stack = vec![(self.root, 0usize)];
        while let Some((r, d)) = stack.pop() {
            match node::Child::decode(r) {
                node::Child::Empty => {}
                node::Child::Leaf { count, .. } => {
                    tris += count;
                    s.leaves += 1;
                    s.depth = s.depth.max(d);
                }
                node::Child::Inner(offset) => {
                    let n = self.node(offset);
                    stack.extend(n.child.iter().map(|&c| (c, d + 1)));
                }
            }
        }
        s.fill = tris as f32 / s.leaves.max(1) as f32;
        s
    }
}
