//! The top of the tree: the spatial-median splits made out of core, with
//! empty-space cuts where a node's triangles leave part of its box empty,
//! down to the chunks (already written, reached through links). Its voxels
//! are made from the children's voxels, face by face: side by side the
//! children's samples are weighted by the share of the face they cover; one
//! behind the other, the front one hides the back one by its coverage.

use glam::Vec3;

use super::super::block::Link;
use super::super::treelet::{split_box, SourceTree, SrcNode};
use super::super::voxel::{grey, FaceAccumulator, FaceSample, Voxel, FACES};
use crate::geom::Aabb;

/// Share of a node's extent that an empty margin must exceed to be cut off
/// (Áfra uses 10–20%).
pub const EMPTY_CUT: f32 = 0.15;

/// A node of the top tree.
#[derive(Clone, Debug)]
pub enum TopNode {
    /// A split.
    Inner {
        /// Split axis.
        axis: usize,
        /// Split position.
        split: f32,
        /// Children by index.
        children: [usize; 2],
    },
    /// Nothing here.
    Empty,
    /// A chunk, written: the link to its root treelet.
    Chunk(Link),
}

/// The top tree, root at index 0.
#[derive(Default)]
pub struct TopTree {
    /// Nodes.
    pub nodes: Vec<TopNode>,
    voxels: Vec<Option<Voxel>>,
}

impl TopTree {
    /// Adds a node; returns its index.
    pub fn push(&mut self, n: TopNode) -> usize {
        self.nodes.push(n);
        self.nodes.len() - 1
    }

    /// Puts empty-space cuts in place of node `i` (box `b`) around `content`:
    /// node `i` becomes the outermost cut, and what it was moves below the cuts.
    pub fn cut_empty(&mut self, i: usize, b: &Aabb, content: &Aabb) {
        if content.is_empty() {
            return;
        }
        let mut chain: Vec<(usize, f32, bool)> = Vec::new();
        let mut cur = *b;
        for axis in 0..3 {
            let extent = cur.hi[axis] - cur.lo[axis];
            if extent <= 0.0 {
                continue;
            }
            let (lo, hi) = (content.lo[axis].max(cur.lo[axis]), content.hi[axis].min(cur.hi[axis]));
            if lo - cur.lo[axis] > EMPTY_CUT * extent {
                chain.push((axis, lo, true));
                cur.lo[axis] = lo;
            }
            if cur.hi[axis] - hi > EMPTY_CUT * extent {
                chain.push((axis, hi, false));
                cur.hi[axis] = hi;
            }
        }
        if chain.is_empty() {
            return;
        }
        let moved = std::mem::replace(&mut self.nodes[i], TopNode::Empty);
        let mut node = self.push(moved);
        for (k, &(axis, split, empty_below)) in chain.iter().enumerate().rev() {
            let empty = self.push(TopNode::Empty);
            let children = if empty_below { [empty, node] } else { [node, empty] };
            let cut = TopNode::Inner { axis, split, children };
            if k == 0 {
                self.nodes[i] = cut;
            } else {
                node = self.push(cut);
            }
        }
    }

    /// Computes the composite voxels bottom-up from node `root` with box `b`.
    pub fn compute_voxels(&mut self, root: usize, b: &Aabb) {
        self.voxels = vec![None; self.nodes.len()];
        self.voxel_of(root, b);
    }

    fn voxel_of(&mut self, i: usize, b: &Aabb) -> Option<Voxel> {
        let v = match self.nodes[i].clone() {
            TopNode::Empty => None,
            TopNode::Chunk(l) => Some(l.voxel),
            TopNode::Inner { axis, split, children } => {
                let (lb, rb) = split_box(b, axis, split);
                let l = self.voxel_of(children[0], &lb);
                let r = self.voxel_of(children[1], &rb);
                composite(axis, b, split, l, r)
            }
        };
        self.voxels[i] = v;
        v
    }
}

fn composite(axis: usize, b: &Aabb, split: f32, l: Option<Voxel>, r: Option<Voxel>) -> Option<Voxel> {
    let extent = (b.hi[axis] - b.lo[axis]).max(1e-30);
    let wl = ((split - b.lo[axis]) / extent).clamp(0.0, 1.0);
    let none = FaceSample {
        normal: Vec3::Z,
        color: Vec3::ZERO,
        coverage: 0.0,
    };
    let faces: [FaceSample; FACES] = std::array::from_fn(|f| {
        let (sl, sr) = (l.map_or(none, |v| v.face(f)), r.map_or(none, |v| v.face(f)));
        let mut acc = FaceAccumulator::default();
        let coverage = if f / 2 == axis {
            // Seen along the split axis: the near child hides the far one.
            let (front, back) = if f % 2 == 1 { (sr, sl) } else { (sl, sr) };
            acc.add_sample(&front, 1.0);
            acc.add_sample(&back, 1.0 - front.coverage);
            front.coverage + (1.0 - front.coverage) * back.coverage
        } else {
            acc.add_sample(&sl, wl);
            acc.add_sample(&sr, 1.0 - wl);
            wl * sl.coverage + (1.0 - wl) * sr.coverage
        };
        acc.finish(Some(coverage)).unwrap_or(none)
    });
    if faces.iter().all(|f| f.coverage <= 0.0) {
        return None;
    }
    Some(Voxel::new(faces))
}

impl SourceTree for TopTree {
    fn node(&self, i: usize) -> SrcNode<'_> {
        match &self.nodes[i] {
            TopNode::Inner { axis, split, children } => SrcNode::Inner {
                axis: *axis,
                split: *split,
                children: *children,
            },
            TopNode::Empty => SrcNode::Leaf(&[]),
            TopNode::Chunk(l) => SrcNode::External(*l),
        }
    }
    fn triangle(&self, _t: u32) -> ([Vec3; 3], u16, u32) {
        // The top tree's leaves are all empty.
        ([Vec3::ZERO; 3], 0, 0)
    }
    fn voxel(&self, i: usize, _b: &Aabb) -> Voxel {
        self.voxels.get(i).copied().flatten().unwrap_or_else(grey)
    }
}
