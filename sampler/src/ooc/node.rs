//! The 8-byte node of a treelet. Inner: split position (f32) and
//! `left << 2 | axis`, the right child at `left + 1`, both in the same block.
//! Leaf (`b & 3 == 3`): a triangle list (`a` = first entry of the block's list,
//! `b >> 3` = count) or, with bit 2 set, a link to another treelet through the
//! block's link table (`a` = link index): the LOD node, which carries the voxel
//! of the treelet it leads to. In memory only, a link into its own block also
//! keeps the linked node (plus one) in `b >> 3`, so that the walk can follow
//! it without reading the link table; it is stored as a plain link.

/// One treelet node.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct TNode {
    pub(crate) a: u32,
    pub(crate) b: u32,
}

/// What a node is.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum NodeKind {
    /// Split `axis` at `split`; children at `left` and `left + 1`.
    Inner { axis: usize, split: f32, left: u32 },
    /// `count` triangles listed from `first`.
    Leaf { first: u32, count: u32 },
    /// The treelet behind link `link` of this block; `local` is that
    /// treelet's root node plus one when it lies in this same block and the
    /// block has resolved it (see `Block::resolve_local_links`), else 0.
    Link { link: u32, local: u32 },
}

const LEAF: u32 = 3;
const LINK: u32 = 4;

impl TNode {
    /// An inner node.
    pub fn inner(axis: usize, split: f32, left: u32) -> TNode {
        debug_assert!(axis < 3 && left < (1 << 30));
        TNode {
            a: split.to_bits(),
            b: (left << 2) | axis as u32,
        }
    }
    /// A triangle leaf.
    pub fn leaf(first: u32, count: u32) -> TNode {
        debug_assert!(count < (1 << 29));
        TNode {
            a: first,
            b: (count << 3) | LEAF,
        }
    }
    /// A link to another treelet.
    pub fn link(link: u32) -> TNode {
        TNode {
            a: link,
            b: LINK | LEAF,
        }
    }
    /// A link into this same block, to node `node` (which comes later).
    pub fn local_link(link: u32, node: u32) -> TNode {
        debug_assert!(node < (1 << 28));
        TNode {
            a: link,
            b: ((node + 1) << 3) | LINK | LEAF,
        }
    }
    /// Decodes the node.
    #[inline]
    pub fn kind(self) -> NodeKind {
        if self.b & 3 != LEAF {
            NodeKind::Inner {
                axis: (self.b & 3) as usize,
                split: f32::from_bits(self.a),
                left: self.b >> 2,
            }
        } else if self.b & LINK != 0 {
            NodeKind::Link {
                link: self.a,
                local: self.b >> 3,
            }
        } else {
            NodeKind::Leaf {
                first: self.a,
                count: self.b >> 3,
            }
        }
    }
    /// The two words, as stored (a resolved local link as a plain link).
    pub fn words(self) -> [u32; 2] {
        if self.b & (LINK | LEAF) == LINK | LEAF {
            [self.a, LINK | LEAF]
        } else {
            [self.a, self.b]
        }
    }
    /// A node from its two stored words (validated by the block decoder).
    pub fn from_words(a: u32, b: u32) -> TNode {
        TNode { a, b }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn kinds_round_trip() {
        assert_eq!(
            TNode::inner(2, -1.5, 77).kind(),
            NodeKind::Inner {
                axis: 2,
                split: -1.5,
                left: 77
            }
        );
        assert_eq!(
            TNode::leaf(123_456, 17).kind(),
            NodeKind::Leaf {
                first: 123_456,
                count: 17
            }
        );
        assert_eq!(TNode::leaf(5, 0).kind(), NodeKind::Leaf { first: 5, count: 0 });
        assert_eq!(TNode::link(9).kind(), NodeKind::Link { link: 9, local: 0 });
        let local = TNode::local_link(9, 40);
        assert_eq!(local.kind(), NodeKind::Link { link: 9, local: 41 });
        assert_eq!(local.words(), TNode::link(9).words());
    }
}
