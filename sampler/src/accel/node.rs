//! The 8-byte kd-tree node. Inner: split position (f32) and `left << 2 | axis`,
//! with the right child at `left + 1`. Leaf: first index into the leaf list and
//! `count << 2 | 3`.

/// One node.
#[repr(C)]
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Node {
    a: u32,
    b: u32,
}

const LEAF: u32 = 3;

impl Node {
    /// An inner node splitting `axis` at `split`, with children at `left` and `left + 1`.
    pub fn inner(axis: usize, split: f32, left: usize) -> Node {
        debug_assert!(axis < 3 && left < (1 << 30));
        Node {
            a: split.to_bits(),
            b: ((left as u32) << 2) | axis as u32,
        }
    }
    /// A leaf with `count` triangles starting at `first` in the leaf list.
    pub fn leaf(first: usize, count: usize) -> Node {
        debug_assert!(count < (1 << 30));
        Node {
            a: first as u32,
            b: ((count as u32) << 2) | LEAF,
        }
    }
    /// True for a leaf.
    #[inline]
    pub fn is_leaf(&self) -> bool {
        self.b & 3 == LEAF
    }
    /// Split axis of an inner node.
    #[inline]
    pub fn axis(&self) -> usize {
        (self.b & 3) as usize
    }
    /// Split position of an inner node.
    #[inline]
    pub fn split(&self) -> f32 {
        f32::from_bits(self.a)
    }
    /// Index of the left child of an inner node.
    #[inline]
    pub fn left(&self) -> usize {
        (self.b >> 2) as usize
    }
    /// First leaf-list index of a leaf.
    #[inline]
    pub fn first(&self) -> usize {
        self.a as usize
    }
    /// Triangle count of a leaf.
    #[inline]
    pub fn count(&self) -> usize {
        (self.b >> 2) as usize
    }
}

const _: () = assert!(std::mem::size_of::<Node>() == 8);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn packs_and_unpacks() {
        let n = Node::inner(2, -1.25, 123_456);
        assert!(!n.is_leaf());
        assert_eq!((n.axis(), n.split(), n.left()), (2, -1.25, 123_456));
        let l = Node::leaf(987_654, 17);
        assert!(l.is_leaf());
        assert_eq!((l.first(), l.count()), (987_654, 17));
    }
}
