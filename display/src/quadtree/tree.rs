//! The image-plane quadtree of the paper's display driver (section 2.4.3):
//! an arena of 4-byte nodes whose leaves hold at most one pixel estimate,
//! split as estimates arrive, down to single pixels.

use crate::store::{Entry, PixelIndex, Spot};

/// A node index or slot that stands for "nothing here".
pub(super) const NONE: u32 = u32::MAX;

/// A quadtree node in 4 bytes: [`NONE`] for an empty leaf, a sample slot for
/// a full leaf, or [`BRANCH`] plus the index of the first of four consecutive
/// children (top-left, top-right, bottom-left, bottom-right).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct Node(pub(super) u32);

/// The tag bit of a branch node.
pub(super) const BRANCH: u32 = 1 << 31;

impl Node {
    pub(super) const EMPTY: Node = Node(NONE);

    #[inline]
    pub(super) fn is_branch(self) -> bool {
        self.0 & BRANCH != 0 && self.0 != NONE
    }

    #[inline]
    pub(super) fn children(self) -> usize {
        (self.0 & !BRANCH) as usize
    }
}

/// Spreads the bits of `v` to the even bit positions.
#[inline]
fn spread(v: u32) -> u64 {
    let mut x = u64::from(v);
    x = (x | (x << 16)) & 0x0000_ffff_0000_ffff;
    x = (x | (x << 8)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x << 4)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x << 2)) & 0x3333_3333_3333_3333;
    (x | (x << 1)) & 0x5555_5555_5555_5555
}

/// Gathers the even bits of `v` (the inverse of [`spread`]).
#[inline]
fn gather(v: u64) -> u32 {
    let mut x = v & 0x5555_5555_5555_5555;
    x = (x | (x >> 1)) & 0x3333_3333_3333_3333;
    x = (x | (x >> 2)) & 0x0f0f_0f0f_0f0f_0f0f;
    x = (x | (x >> 4)) & 0x00ff_00ff_00ff_00ff;
    x = (x | (x >> 8)) & 0x0000_ffff_0000_ffff;
    x = (x | (x >> 16)) & 0x0000_0000_ffff_ffff;
    x as u32
}

/// The image-plane quadtree: an arena of 4-byte nodes with u32 links.
///
/// The root is the smallest power-of-two square holding the frame, anchored
/// at its top-left corner, so every node is a square block of pixels whatever
/// the frame's aspect (parts off the frame are never filled nor drawn), a
/// node at depth `levels` is a single pixel, and a pixel's path from the root
/// is its Morton code: quadrant `(y bit << 1) | x bit` of the column and row,
/// most significant first.
#[derive(Clone, Debug, Default)]
pub struct Tree {
    pub(super) nodes: Vec<Node>,
    /// Depth of the single-pixel nodes.
    pub(super) levels: u32,
    /// The frame's width and height, cells.
    width: u32,
    height: u32,
    /// Whether block numbers go row by row rather than in key order: for
    /// frames so far from square that the root's square would be more
    /// than four times the frame (a 65,536 x 1 frame would otherwise
    /// number 4 billion blocks).
    row_major: bool,
}

impl PixelIndex for Tree {
    fn reset(&mut self, width: u32, height: u32) {
        self.nodes.clear();
        self.nodes.push(Node::EMPTY);
        let side = width.max(height);
        self.levels = if side <= 1 { 0 } else { 32 - (side - 1).leading_zeros() };
        (self.width, self.height) = (width.max(1), height.max(1));
        let square = 1u64 << (2 * self.levels);
        self.row_major = square > 4 * u64::from(self.width) * u64::from(self.height);
    }

    #[inline]
    fn key(&self, col: u32, row: u32) -> u64 {
        spread(col) | (spread(row) << 1)
    }

    #[inline]
    fn pixel(&self, key: u64) -> (u32, u32) {
        (gather(key), gather(key >> 1))
    }

    fn key_bits(&self) -> u32 {
        2 * self.levels
    }

    #[inline]
    fn find(&mut self, entries: &[Entry], key: u64) -> Spot {
        let mut node = 0usize;
        // Twice the current node's height above the pixels: its children's
        // quadrant is at key bits shift - 2 and shift - 1.
        let mut shift = 2 * self.levels;
        loop {
            let n = self.nodes[node];
            if n.is_branch() {
                shift -= 2;
                node = n.children() + ((key >> shift) & 3) as usize;
                continue;
            }
            if n == Node::EMPTY {
                return Spot::Free(node);
            }
            let old = entries[n.0 as usize].key;
            if old == key {
                return Spot::Taken(n.0);
            }
            // Two pixels in one leaf: the leaf is bigger than a pixel (keys
            // differ below here), so push its sample one level down and go on
            // (the new sample may meet it again below).
            let first = self.nodes.len();
            debug_assert!(first + 4 < BRANCH as usize, "quadtree arena overflow");
            self.nodes.extend([Node::EMPTY; 4]);
            self.nodes[first + ((old >> (shift - 2)) & 3) as usize] = n;
            self.nodes[node] = Node(BRANCH | first as u32);
        }
    }

    #[inline]
    fn fill(&mut self, at: usize, slot: u32) {
        self.nodes[at] = Node(slot);
    }

    fn heap_bytes(&self) -> usize {
        self.nodes.capacity() * std::mem::size_of::<Node>()
    }

    #[inline]
    fn block(&self, key: u64, shift: u32) -> usize {
        if self.row_major {
            let (col, row) = self.pixel(key);
            let across = (self.width + (1 << shift) - 1) >> shift;
            return (row >> shift) as usize * across as usize + (col >> shift) as usize;
        }
        (key >> (2 * shift)) as usize
    }

    fn blocks(&self, shift: u32) -> usize {
        if self.row_major {
            let up = |n: u32| ((n + (1 << shift) - 1) >> shift) as usize;
            return up(self.width) * up(self.height);
        }
        1 << (2 * self.levels.saturating_sub(shift))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn frames_far_from_square_number_their_blocks_by_row() {
        let mut t = Tree::default();
        // A usual frame: blocks in key order over the root's square.
        t.reset(1024, 768);
        assert_eq!(t.blocks(0), 1 << 20);
        assert_eq!(t.block(t.key(5, 3), 0), t.key(5, 3) as usize);
        // A line of 65,536 pixels: as many blocks as pixels, not 4 billion.
        t.reset(65_536, 1);
        assert_eq!(t.blocks(0), 65_536);
        assert_eq!(t.blocks(1), 32_768);
        for col in [0u32, 1, 777, 65_535] {
            assert_eq!(t.block(t.key(col, 0), 0), col as usize);
            assert!(t.block(t.key(col, 0), 1) < t.blocks(1));
        }
        t.reset(3, 2_000);
        assert_eq!(t.blocks(0), 6_000);
        assert_eq!(t.block(t.key(2, 1_999), 0), 1_999 * 3 + 2);
    }
    use proptest::prelude::*;

    proptest! {
        #[test]
        fn keys_decode_to_their_pixels(col in 0u32..8192, row in 0u32..8192) {
            let mut t = Tree::default();
            t.reset(8192, 8192);
            prop_assert_eq!(t.pixel(t.key(col, row)), (col, row));
        }
    }
}
