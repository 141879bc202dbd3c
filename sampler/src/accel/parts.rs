//! A kd-tree from nodes and leaf lists made elsewhere (a scene file assembled
//! in memory), checked so that the walk can trust every index in it.

use super::traverse::STACK;
use super::{KdTree, Node};
use crate::geom::Aabb;

/// Why nodes and leaf lists do not make a tree the in-core walk can use.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum PartsError {
    /// A child, leaf list or triangle index out of range, or a child before its parent.
    #[error("node {0}: an index out of range")]
    Index(usize),
    /// Deeper than the walk's stack.
    #[error("the tree is {0} levels deep; the in-core walk takes at most {STACK}")]
    TooDeep(usize),
}

impl KdTree {
    /// A tree over `triangles` triangles from its nodes (root first, children
    /// of an inner node adjacent and after it), leaf lists and bounds.
    pub fn from_parts(
        nodes: Vec<Node>,
        leaf_tris: Vec<u32>,
        bounds: Aabb,
        triangles: usize,
    ) -> Result<KdTree, PartsError> {
        if nodes.is_empty() {
            return Err(PartsError::Index(0));
        }
        if leaf_tris.iter().any(|&t| t as usize >= triangles) {
            return Err(PartsError::Index(0));
        }
        // Depth of each node, known before its children are met (they come after it).
        let mut depth = vec![0u32; nodes.len()];
        let mut deepest = 0;
        for (i, n) in nodes.iter().enumerate() {
            if n.is_leaf() {
                if n.first() + n.count() > leaf_tris.len() {
                    return Err(PartsError::Index(i));
                }
                continue;
            }
            let left = n.left();
            if left <= i || left + 1 >= nodes.len() {
                return Err(PartsError::Index(i));
            }
            let d = depth[i] + 1;
            deepest = deepest.max(d as usize);
            depth[left] = d;
            depth[left + 1] = d;
        }
        if deepest >= STACK {
            return Err(PartsError::TooDeep(deepest));
        }
        Ok(KdTree {
            nodes,
            leaf_tris,
            bounds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn parts_are_checked_before_the_walk_trusts_them() {
        let bounds = Aabb {
            lo: Vec3::ZERO,
            hi: Vec3::ONE,
        };
        let leaf = |f, c| Node::leaf(f, c);
        let ok = KdTree::from_parts(
            vec![Node::inner(0, 0.5, 1), leaf(0, 1), leaf(1, 1)],
            vec![0, 1],
            bounds,
            2,
        );
        assert!(ok.is_ok());
        // A child before its parent (a cycle), past the end, a list past the end, a triangle past the end.
        let bad = [
            (vec![Node::inner(0, 0.5, 0), leaf(0, 1)], vec![0], 1),
            (vec![Node::inner(0, 0.5, 1), leaf(0, 1)], vec![0], 1),
            (vec![Node::inner(0, 0.5, 1), leaf(0, 1), leaf(1, 2)], vec![0, 0], 1),
            (vec![leaf(0, 1)], vec![5], 2),
        ];
        for (nodes, list, tris) in bad {
            assert!(KdTree::from_parts(nodes, list, bounds, tris).is_err());
        }
        // A chain deeper than the walk's stack: each inner node's left child
        // is the next inner node.
        let mut nodes = vec![Node::inner(0, 0.5, 1)];
        for _ in 0..STACK {
            nodes.push(Node::inner(0, 0.5, nodes.len() + 2));
            nodes.push(leaf(0, 0));
        }
        nodes.push(leaf(0, 0));
        nodes.push(leaf(0, 0));
        assert!(matches!(
            KdTree::from_parts(nodes, vec![], bounds, 0),
            Err(PartsError::TooDeep(_))
        ));
    }
}
