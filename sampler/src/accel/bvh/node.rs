//! The wide node: eight children's boxes in structure-of-arrays form, and a
//! 32-bit reference per child. A reference is an inner node's byte offset in
//! the node array (so that a walk adds it to the array's address as it is,
//! one shift and one addition less between loading a reference and loading
//! the node it names), or a leaf (the top bit set, then the first block's
//! index and the triangle count less one in the low three bits: a leaf of
//! more than four triangles takes two blocks' space, as a
//! [`super::Pair`]), or [`EMPTY`].

use wide::f32x8;

use crate::geom::Aabb;

/// Children per node: one ray tests all eight boxes with one 256-bit
/// operation per slab where the CPU has AVX.
pub(crate) const WIDTH: usize = 8;

/// An unused child slot (its box is empty, so no ray enters it).
pub(crate) const EMPTY: u32 = u32::MAX;
const LEAF: u32 = 1 << 31;
/// Blocks a leaf reference can name (the last code would be [`EMPTY`]).
pub(crate) const MAX_BLOCKS: usize = (1 << 28) - 1;
/// Nodes a hierarchy can hold: their byte offsets must stay below the leaf bit.
pub(crate) const MAX_NODES: usize = (LEAF as usize) / std::mem::size_of::<Node>();
/// Most triangles in a leaf: two blocks.
pub(crate) const LEAF_MAX: usize = 8;

/// A child reference, decoded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Child {
    Empty,
    Leaf {
        block: usize,
        count: usize,
    },
    /// An inner node, by its byte offset in the node array.
    Inner(usize),
}

impl Child {
    /// The reference of a leaf of `count` (1..=8) triangles from block `block` on.
    pub(crate) fn leaf(block: usize, count: usize) -> u32 {
        debug_assert!(block < MAX_BLOCKS && (1..=LEAF_MAX).contains(&count));
        LEAF | ((block as u32) << 3) | (count as u32 - 1)
    }

    /// The reference of the inner node at index `index` of the node array.
    pub(crate) fn inner(index: usize) -> u32 {
        debug_assert!(index < MAX_NODES);
        (index * std::mem::size_of::<Node>()) as u32
    }

    /// What a reference names.
    #[inline]
    pub(crate) fn decode(r: u32) -> Child {
        if r == EMPTY {
            Child::Empty
        } else if r & LEAF != 0 {
            Child::Leaf {
                block: ((r & !LEAF) >> 3) as usize,
                count: (r & 7) as usize + 1,
            }
        } else {
            Child::Inner(r as usize)
        }
    }
}

/// Eight children: `b[0..3]` their boxes' low x, y, z and `b[3..6]` the high
/// ones, one child per lane; `child` their references. Aligned to cache
/// lines (224 bytes, padded to four lines).
#[derive(Clone, Copy, Debug)]
#[repr(C, align(64))]
pub(crate) struct Node {
    pub(crate) b: [f32x8; 6],
    pub(crate) child: [u32; WIDTH],
}

impl Node {
    /// A node of up to [`WIDTH`] children (the rest empty).
    pub(crate) fn new(children: &[(Aabb, u32)]) -> Node {
        debug_assert!(children.len() <= WIDTH);
        let mut b = [
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
            [f32::NEG_INFINITY; WIDTH],
        ];
        let mut child = [EMPTY; WIDTH];
        for (lane, (bx, r)) in children.iter().enumerate() {
            for c in 0..3 {
                b[c][lane] = bx.lo[c];
                b[3 + c][lane] = bx.hi[c];
            }
            child[lane] = *r;
        }
        Node {
            b: b.map(f32x8::new),
            child,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn references_round_trip() {
        for (block, count) in [(0, 1), (7, 4), (9, 8), (MAX_BLOCKS - 1, 8)] {
            assert_eq!(Child::decode(Child::leaf(block, count)), Child::Leaf { block, count });
        }
        assert_eq!(Child::decode(Child::inner(0)), Child::Inner(0));
        assert_eq!(Child::decode(Child::inner(3)), Child::Inner(3 * 256));
        assert_eq!(
            Child::decode(Child::inner(MAX_NODES - 1)),
            Child::Inner(LEAF as usize - 256)
        );
        assert_eq!(Child::decode(EMPTY), Child::Empty);
    }
}
