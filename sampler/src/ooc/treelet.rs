//! Decomposing a kd-tree into treelets of height 3 (Áfra 2012, 4.3): inner
//! nodes three levels below a treelet's root start new treelets, reached
//! through LOD nodes that carry their voxel. Treelets are numbered breadth
//! first, so they come out by level, and packed into blocks of about `target`
//! bytes a subtree at a time (see [`pack`]), with the triangles their leaves
//! list and those triangles' vertices (shared within the block).

use std::collections::{HashMap, VecDeque};

use glam::Vec3;
use rayon::prelude::*;

use super::block::{Block, BlockTri, Link};
use super::node::TNode;
use super::voxel::Voxel;
use crate::geom::Aabb;

/// Levels of inner nodes per treelet: voxels sit at every third level.
pub const TREELET_HEIGHT: usize = 3;
/// Most triangles per block (keeps vertex indices within 16 bits).
const MAX_BLOCK_TRIS: usize = 20_000;

/// A node of the tree being decomposed.
pub enum SrcNode<'a> {
    /// Split `axis` at `split`; children by index.
    Inner {
        /// Split axis.
        axis: usize,
        /// Split position.
        split: f32,
        /// Below and above the split.
        children: [usize; 2],
    },
    /// Triangles (indices the source understands).
    Leaf(&'a [u32]),
    /// A treelet already written elsewhere (a chunk's root, for the top tree).
    External(Link),
}

/// A tree to decompose.
pub trait SourceTree: Sync {
    /// Node `i`.
    fn node(&self, i: usize) -> SrcNode<'_>;
    /// Triangle `t` of a leaf: vertices, material, scene-wide id.
    fn triangle(&self, t: u32) -> ([Vec3; 3], u16, u32);
    /// The voxel of node `i`, whose box is `bounds`.
    fn voxel(&self, i: usize, bounds: &Aabb) -> Voxel;
}

/// Blocks made from a tree, and the link to its root treelet.
pub struct Decomposed {
    /// (level, block), with block ids `first_block..` in order.
    pub blocks: Vec<(u16, Block)>,
    /// Link to the root treelet (voxel included).
    pub root: Link,
    /// One more than the deepest treelet's level (0 without treelets).
    pub levels: u16,
}

enum Member {
    Inner { axis: usize, split: f32, left: usize },
    Leaf(Vec<u32>),
    Treelet(usize),
    External(Link),
}

struct Treelet {
    src: usize,
    bounds: Aabb,
    level: u16,
    members: Vec<Member>,
    tris: usize,
    links: usize,
}

/// Children boxes of `b` split on `axis` at `split`.
pub fn split_box(b: &Aabb, axis: usize, split: f32) -> (Aabb, Aabb) {
    let (mut l, mut r) = (*b, *b);
    l.hi[axis] = split;
    r.lo[axis] = split;
    (l, r)
}

/// Radius of the sphere around a box.
pub fn radius(b: &Aabb) -> f32 {
    if b.is_empty() {
        0.0
    } else {
        0.5 * (b.hi - b.lo).length()
    }
}

fn collect(src: &impl SourceTree, root: usize, bounds: Aabb, base_level: u16) -> Vec<Treelet> {
    let mut treelets: Vec<Treelet> = Vec::new();
    let mut queue = VecDeque::from([(root, bounds, base_level)]);
    let mut next_id = 1usize;
    while let Some((src_root, bounds, level)) = queue.pop_front() {
        let mut t = Treelet {
            src: src_root,
            bounds,
            level,
            members: vec![Member::Leaf(Vec::new())],
            tris: 0,
            links: 0,
        };
        let mut stack = vec![(src_root, 0usize, 0usize, bounds)];
        while let Some((i, local, depth, b)) = stack.pop() {
            t.members[local] = match src.node(i) {
                SrcNode::Inner { axis, split, children } if depth < TREELET_HEIGHT || local == 0 => {
                    let left = t.members.len();
                    t.members.push(Member::Leaf(Vec::new()));
                    t.members.push(Member::Leaf(Vec::new()));
                    let (lb, rb) = split_box(&b, axis, split);
                    stack.push((children[1], left + 1, depth + 1, rb));
                    stack.push((children[0], left, depth + 1, lb));
                    Member::Inner { axis, split, left }
                }
                SrcNode::Inner { .. } => {
                    queue.push_back((i, b, level + 1));
                    next_id += 1;
                    t.links += 1;
                    Member::Treelet(next_id - 1)
                }
                SrcNode::Leaf(tris) => {
                    t.tris += tris.len();
                    Member::Leaf(tris.to_vec())
                }
                SrcNode::External(l) => {
                    t.links += 1;
                    Member::External(l)
                }
            };
        }
        treelets.push(t);
    }
    treelets
}

/// Packs treelets into blocks of about `target` bytes: each block takes a
/// treelet and then its descendants breadth first while they fit, so a ray
/// crosses into another block only every few treelet levels and a view's
/// blocks hold little it does not need; a block whose subtree runs out takes
/// the next pending treelets (its cousins). Blocks come out ordered by the
/// level of their first treelet: coarse levels first, as Áfra's layout has
/// them, each block spanning a band of levels.
fn pack(treelets: &[Treelet], target: usize) -> Vec<Vec<usize>> {
    let kids: Vec<Vec<usize>> = treelets
        .iter()
        .map(|t| {
            t.members
                .iter()
                .filter_map(|m| match m {
                    Member::Treelet(j) => Some(*j),
                    _ => None,
                })
                .collect()
        })
        .collect();
    let est = |t: &Treelet| t.members.len() * 8 + t.links * 64 + t.tris * 34;
    let mut groups: Vec<Vec<usize>> = Vec::new();
    let mut pending = VecDeque::from([0usize]);
    while !pending.is_empty() {
        let mut group = Vec::new();
        let (mut size, mut tris) = (24usize, 0usize);
        let mut subtree = VecDeque::new();
        while let Some(k) = subtree.pop_front().or_else(|| pending.pop_front()) {
            let t = &treelets[k];
            if !group.is_empty() && (size + est(t) > target || tris + t.tris > MAX_BLOCK_TRIS) {
                // Full: this treelet and what is left of the subtree start the next blocks.
                while let Some(j) = subtree.pop_back() {
                    pending.push_front(j);
                }
                pending.push_front(k);
                break;
            }
            group.push(k);
            size += est(t);
            tris += t.tris;
            subtree.extend(&kids[k]);
        }
        groups.push(group);
    }
    groups.sort_by_key(|g| (treelets[g[0]].level, g[0]));
    groups
}

/// Decomposes the tree under `root` (box `bounds`) into blocks numbered from
/// `first_block`, levels counted from `base_level`.
pub fn decompose(
    src: &impl SourceTree,
    root: usize,
    bounds: Aabb,
    first_block: u32,
    base_level: u16,
    target: usize,
) -> Decomposed {
    if let SrcNode::External(l) = src.node(root) {
        return Decomposed {
            blocks: Vec::new(),
            root: l,
            levels: 0,
        };
    }
    let treelets = collect(src, root, bounds, base_level);
    let voxels: Vec<Voxel> = treelets.par_iter().map(|t| src.voxel(t.src, &t.bounds)).collect();

    let groups = pack(&treelets, target);
    // Treelet -> (block, first node).
    let mut place = vec![(0u32, 0u32); treelets.len()];
    for (g, group) in groups.iter().enumerate() {
        let mut nodes = 0u32;
        for &k in group {
            place[k] = (first_block + g as u32, nodes);
            nodes += treelets[k].members.len() as u32;
        }
    }
    let link_to = |k: usize| Link {
        block: place[k].0,
        node: place[k].1,
        radius_bits: radius(&treelets[k].bounds).to_bits(),
        voxel: voxels[k],
    };
    let blocks = groups
        .par_iter()
        .map(|group| {
            let mut b = Block::default();
            let mut tri_of: HashMap<u32, u16> = HashMap::new();
            let mut vert_of: HashMap<[u32; 3], u16> = HashMap::new();
            for &k in group {
                let t = &treelets[k];
                let base = b.nodes.len() as u32;
                for m in &t.members {
                    let node = match m {
                        Member::Inner { axis, split, left } => TNode::inner(*axis, *split, base + *left as u32),
                        Member::Leaf(list) => {
                            let first = b.list.len() as u32;
                            for &s in list {
                                let local = *tri_of.entry(s).or_insert_with(|| {
                                    let (v, material, id) = src.triangle(s);
                                    let idx = v.map(|p| {
                                        *vert_of.entry(p.to_array().map(f32::to_bits)).or_insert_with(|| {
                                            b.verts.push(p);
                                            (b.verts.len() - 1) as u16
                                        })
                                    });
                                    b.tris.push(BlockTri { v: idx, material });
                                    b.ids.push(id);
                                    (b.tris.len() - 1) as u16
                                });
                                b.list.push(local);
                            }
                            TNode::leaf(first, list.len() as u32)
                        }
                        Member::Treelet(j) => {
                            b.links.push(link_to(*j));
                            TNode::link(b.links.len() as u32 - 1)
                        }
                        Member::External(l) => {
                            b.links.push(*l);
                            TNode::link(b.links.len() as u32 - 1)
                        }
                    };
                    b.nodes.push(node);
                }
            }
            (treelets[group[0]].level, b)
        })
        .collect();
    Decomposed {
        blocks,
        root: link_to(0),
        levels: treelets.iter().map(|t| t.level + 1).max().unwrap_or(0),
    }
}
