//! A kd-tree from nodes and leaf lists made elsewhere (a scene file assembled
//! in memory), checked so that the walk can trust every index in it.

use super::leaf::LeafTris;
use super::traverse::STACK;
use super::{KdTree, Node};
use crate::geom::Aabb;
use crate::scene::Scene;

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
    /// A tree over the triangles of `scene` from its nodes (root first,
    /// children of an inner node adjacent and after it), leaf lists and bounds.
    pub fn from_parts(
        nodes: Vec<Node>,
        leaf_tris: Vec<u32>,
        bounds: Aabb,
        scene: &Scene,
    ) -> Result<KdTree, PartsError> {
        let triangles = scene.triangles.len();
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
            leaves: LeafTris::new(scene, &leaf_tris),
            grid: std::sync::OnceLock::new(),
            nodes,
            leaf_tris,
            bounds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::{Material, SceneBuilder};
    use glam::{Mat4, Vec3};

    /// A scene of `n` triangles.
    fn scene(n: u32) -> Scene {
        let mut b = SceneBuilder::new();
        let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
        let p: Vec<Vec3> = (0..n * 3)
            .map(|i| Vec3::new(i as f32, (i % 3 == 1) as u8 as f32, (i % 3 == 2) as u8 as f32))
            .collect();
        let t: Vec<[u32; 3]> = (0..n).map(|i| [3 * i, 3 * i + 1, 3 * i + 2]).collect();
        if n > 0 {
            b.add_mesh("tris", &p, &t, &[m], Mat4::IDENTITY).unwrap();
        }
        b.finish()
    }

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
            &scene(2),
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
            assert!(KdTree::from_parts(nodes, list, bounds, &scene(tris)).is_err());
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
            KdTree::from_parts(nodes, vec![], bounds, &scene(0)),
            Err(PartsError::TooDeep(_))
        ));
    }
}
