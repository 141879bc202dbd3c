//! Building the wide BVH: binned SAH over triangle centroids splits a node's
//! triangles in two, and the largest of its parts is split again until it has
//! eight children; parts of up to eight triangles become leaves
//! (a block of four, or a [`Pair`] of eight side by side), or a node of two
//! leaves where SAH finds two clusters ([`small`]). Subtrees are
//! built in parallel, then laid out depth first, also in parallel.

use std::mem::MaybeUninit;

use glam::Vec3;
use rayon::prelude::*;

use super::node::{Child, Node, EMPTY, LEAF_MAX, MAX_BLOCKS, MAX_NODES, WIDTH};
use super::{Block, Pair, WideBvh};
use crate::geom::{Aabb, Tri4, Tri8};
use crate::scene::Scene;

/// SAH bins per axis.
const BINS: usize = 32;
/// SAH bins per axis for parts of at least [`WIDE_FROM`] triangles: the
/// upper levels' splits decide most of a ray's walk, and finer bins there
/// gave the 1M landscape's primary rays 9% more speed at no cost in build
/// time (the bins cost a part a constant, the binning a part's size).
const WIDE_BINS: usize = 128;
/// Parts this large are binned with [`WIDE_BINS`].
const WIDE_FROM: usize = 1024;
/// Parts at least this large are binned and built in parallel.
const PARALLEL: usize = 1 << 14;
/// Below this many levels, SAH chooses splits; deeper, parts are halved at
/// the median, which bounds the depth (and the traversal stack) on any input.
const SAH_DEPTH: usize = 32;

/// A triangle's box and index.
#[derive(Clone, Copy)]
struct Prim {
    lo: Vec3,
    hi: Vec3,
    id: u32,
}

impl Prim {
    /// Twice the box's centre (the factor cancels in binning).
    #[inline]
    fn centre2(&self) -> Vec3 {
        self.lo + self.hi
    }
}

/// A subtree before layout: a leaf over a run of the primitive array, or up
/// to [`WIDTH`] children with their boxes and the subtree's size.
enum Sub {
    Leaf { start: usize, count: usize },
    Inner { children: Vec<(Aabb, Sub)>, size: Size },
}

/// Inner nodes and leaf blocks of a subtree: where its layout ends.
#[derive(Clone, Copy)]
struct Size {
    nodes: usize,
    blocks: usize,
}

impl Sub {
    fn size(&self) -> Size {
        match self {
            Sub::Leaf { count, .. } => Size {
                nodes: 0,
                blocks: count.div_ceil(4),
            },
            Sub::Inner { size, .. } => *size,
        }
    }
}

#[derive(Clone, Copy)]
struct Bin {
    bounds: Aabb,
    count: usize,
}

const EMPTY_BIN: Bin = Bin {
    bounds: Aabb::EMPTY,
    count: 0,
};

/// Bins of the three axes, and how centroids map to them.
#[derive(Clone)]
struct Bins<const N: usize> {
    bins: [[Bin; N]; 3],
}

impl<const N: usize> Bins<N> {
    fn merge(mut self, o: Bins<N>) -> Bins<N> {
        for (a, b) in self.bins.iter_mut().flatten().zip(o.bins.iter().flatten()) {
            a.bounds = a.bounds.union(&b.bounds);
            a.count += b.count;
        }
        self
    }
}

/// Where centroids fall: the bin of axis `a` is `(c - lo[a]) * scale[a]`.
#[derive(Clone, Copy)]
struct Binning {
    lo: Vec3,
    scale: Vec3,
}

impl Binning {
    #[inline]
    fn bin<const N: usize>(&self, c: Vec3, axis: usize) -> usize {
        (((c[axis] - self.lo[axis]) * self.scale[axis]) as usize).min(N - 1)
    }

    fn fill<const N: usize>(&self, prims: &[Prim]) -> Bins<N> {
        let mut b = Bins {
            bins: [[EMPTY_BIN; N]; 3],
        };
        for p in prims {
            let c = p.centre2();
            let pb = Aabb { lo: p.lo, hi: p.hi };
            for (axis, bins) in b.bins.iter_mut().enumerate() {
                let bin = &mut bins[self.bin::<N>(c, axis)];
                bin.bounds.include(&pb);
                bin.count += 1;
            }
        }
        b
    }
}

fn bounds_of(prims: &[Prim]) -> (Aabb, Aabb) {
    let one = |p: &Prim| {
        let c = p.centre2();
        (Aabb { lo: p.lo, hi: p.hi }, Aabb { lo: c, hi: c })
    };
    let join = |a: (Aabb, Aabb), b: (Aabb, Aabb)| (a.0.union(&b.0), a.1.union(&b.1));
    if prims.len() >= PARALLEL {
        prims
            .par_chunks(PARALLEL / 4)
            .map(|c| c.iter().map(one).fold((Aabb::EMPTY, Aabb::EMPTY), join))
            .reduce(|| (Aabb::EMPTY, Aabb::EMPTY), join)
    } else {
        prims.iter().map(one).fold((Aabb::EMPTY, Aabb::EMPTY), join)
    }
}

/// Splits `prims` (more than [`LEAF_MAX`]) in two in place; returns the size
/// of the first part and both parts' boxes.
fn split(prims: &mut [Prim], depth: usize) -> (usize, Aabb, Aabb) {
    let (_, centres) = bounds_of(prims);
    let extent = centres.hi - centres.lo;
    if depth < SAH_DEPTH && extent.max_element() > 0.0 {
        let k = if prims.len() >= WIDE_FROM {
            sah_split::<WIDE_BINS>(prims, &centres)
        } else {
            sah_split::<BINS>(prims, &centres)
        };
        if let Some(k) = k {
            return k;
        }
    }
    // All centres in one point, or too deep: halve at the median of the
    // longest centre axis.
    let axis = if extent.x >= extent.y && extent.x >= extent.z {
        0
    } else if extent.y >= extent.z {
        1
    } else {
        2
    };
    let mid = prims.len() / 2;
    prims.select_nth_unstable_by(mid, |a, b| a.centre2()[axis].total_cmp(&b.centre2()[axis]));
    (mid, bounds_of(&prims[..mid]).0, bounds_of(&prims[mid..]).0)
}

/// Splits `prims` where binned SAH over `N` bins per axis finds it
/// cheapest, as [`split`] returns it; `None` where it finds no split.
// Out of line: its bins are kilobytes of stack, which the recursion must
// not carry down a deep tree.
#[inline(never)]
fn sah_split<const N: usize>(prims: &mut [Prim], centres: &Aabb) -> Option<(usize, Aabb, Aabb)> {
    let extent = centres.hi - centres.lo;
    // Extents too small to divide get a scale of 0: one bin, never split.
    let scale = Vec3::select(
        extent.cmpgt(Vec3::ZERO),
        Vec3::splat(N as f32 * (1.0 - 1e-6)) / extent,
        Vec3::ZERO,
    );
    let binning = Binning { lo: centres.lo, scale };
    let bins = if prims.len() >= PARALLEL {
        prims
            .par_chunks(PARALLEL / 4)
            .map(|c| binning.fill::<N>(c))
            .reduce_with(Bins::merge)
    } else {
        Some(binning.fill::<N>(prims))
    };
    let (axis, at, lb, rb) = best_split(&bins?)?;
    let k = partition(prims, |p| binning.bin::<N>(p.centre2(), axis) < at);
    (k > 0 && k < prims.len()).then_some((k, lb, rb))
}

/// The cheapest split by SAH: axis, first bin of the second part, and the
/// two parts' boxes.
fn best_split<const N: usize>(b: &Bins<N>) -> Option<(usize, usize, Aabb, Aabb)> {
    let mut best: Option<(f32, usize, usize, Aabb, Aabb)> = None;
    for (axis, bins) in b.bins.iter().enumerate() {
        // Right-hand sweep: boxes and counts of bins i.. for every i.
        let mut right = [(Aabb::EMPTY, 0usize); N];
        let mut acc = (Aabb::EMPTY, 0usize);
        for i in (1..N).rev() {
            acc = (acc.0.union(&bins[i].bounds), acc.1 + bins[i].count);
            right[i] = acc;
        }
        let mut left = (Aabb::EMPTY, 0usize);
        for i in 1..N {
            left = (left.0.union(&bins[i - 1].bounds), left.1 + bins[i - 1].count);
            let (rb, rn) = right[i];
            if left.1 == 0 || rn == 0 {
                continue;
            }
            // A part costs its triangles. Counting blocks of four instead
            // fills leaves (3.9 triangles a leaf on the landscapes against
            // 3.4, 15% fewer bytes), but in the furnished room its shadow
            // rays took a third more instructions and its nearest hits a
            // sixth more (callgrind, a render of the room).
            let cost = left.0.area() * left.1 as f32 + rb.area() * rn as f32;
            if best.is_none_or(|b| cost < b.0) {
                best = Some((cost, axis, i, left.0, rb));
            }
        }
    }
    best.map(|(_, axis, at, l, r)| (axis, at, l, r))
}

/// Moves the primitives for which `first` holds to the front; returns their count.
fn partition(prims: &mut [Prim], first: impl Fn(&Prim) -> bool) -> usize {
    let mut k = 0;
    for i in 0..prims.len() {
        if first(&prims[i]) {
            prims.swap(i, k);
            k += 1;
        }
    }
    k
}

/// Builds the subtree over `prims`, which start at `offset` in the whole array.
fn build(prims: &mut [Prim], offset: usize, bounds: Aabb, depth: usize) -> Sub {
    if prims.len() <= LEAF_MAX {
        return small(prims, offset, bounds);
    }
    // Parts as (start within `prims`, length, box), split until [`WIDTH`].
    let mut parts = vec![(0usize, prims.len(), bounds)];
    while parts.len() < WIDTH {
        let Some(i) = (0..parts.len())
            .filter(|&i| parts[i].1 > LEAF_MAX)
            // The largest box. Splitting the part with the largest SAH cost
            // (area times triangles) instead gave the landscapes 7% fewer
            // nodes and rays 1% faster, but the furnished room's few large
            // triangles 6-10% slower rays.
            .max_by(|&a, &b| parts[a].2.area().total_cmp(&parts[b].2.area()))
        else {
            break;
        };
        let (s, n, _) = parts[i];
        let (k, lb, rb) = split(&mut prims[s..s + n], depth);
        parts[i] = (s, k, lb);
        parts.insert(i + 1, (s + k, n - k, rb));
    }
    // The parts are consecutive runs: cut the slice into them.
    let mut slices = Vec::with_capacity(parts.len());
    let mut rest = prims;
    for &(_, n, b) in &parts {
        let (head, tail) = rest.split_at_mut(n);
        slices.push((head, b));
        rest = tail;
    }
    let one = |((slice, b), &(s, _, _)): ((&mut [Prim], Aabb), &(usize, usize, Aabb))| {
        (b, build(slice, offset + s, b, depth + 1))
    };
    let children: Vec<(Aabb, Sub)> = if parts.iter().map(|p| p.1).sum::<usize>() >= PARALLEL {
        slices.into_par_iter().zip(parts.par_iter()).map(one).collect()
    } else {
        slices.into_iter().zip(parts.iter()).map(one).collect()
    };
    let size = children.iter().fold(Size { nodes: 1, blocks: 0 }, |a, (_, c)| {
        let c = c.size();
        Size {
            nodes: a.nodes + c.nodes,
            blocks: a.blocks + c.blocks,
        }
    });
    Sub::Inner { children, size }
}

/// What testing one more triangle of a leaf costs, against a leaf's test
/// (and a node's, about the same): one ray tests a leaf's eight lanes at
/// once, but a packet tests a leaf one triangle at a time, and every lane a
/// ray hits is settled on its own.
const TRIANGLE_COST: f32 = 0.1;

/// The subtree over at most [`LEAF_MAX`] primitives: one leaf, or, where
/// more than a block's worth falls in two clusters whose boxes SAH finds
/// much smaller than their union's, a node of two leaves. Always taking
/// leaves of up to eight slowed packets of eight by 15-21% against leaves
/// of four; this won back a third to two fifths of that, and single rays
/// ran 1-3% faster too.
fn small(prims: &mut [Prim], offset: usize, bounds: Aabb) -> Sub {
    let n = prims.len();
    let leaf = |start: usize, count: usize| Sub::Leaf { start, count };
    if n <= 4 {
        return leaf(offset, n);
    }
    let (_, centres) = bounds_of(prims);
    if !centres.hi.cmpgt(centres.lo).any() {
        return leaf(offset, n);
    }
    let cost = |b: &Aabb, count: usize| b.area() * (1.0 + TRIANGLE_COST * count as f32);
    match sah_split::<BINS>(prims, &centres) {
        // A leaf costs `bounds.area() * (1 + TRIANGLE_COST * n)` and a node
        // `bounds.area()` more than its leaves.
        Some((k, lb, rb)) if cost(&lb, k) + cost(&rb, n - k) < TRIANGLE_COST * n as f32 * bounds.area() => Sub::Inner {
            children: vec![(lb, leaf(offset, k)), (rb, leaf(offset + k, n - k))],
            size: Size {
                nodes: 1,
                blocks: k.div_ceil(4) + (n - k).div_ceil(4),
            },
        },
        _ => leaf(offset, n),
    }
}

/// The primitives of a scene's first `n` triangles.
fn primitives(scene: &Scene, n: usize) -> Vec<Prim> {
    (0..n)
        .into_par_iter()
        .map(|i| {
            let [a, b, c] = scene.vertices(i);
            Prim {
                lo: a.min(b).min(c),
                hi: a.max(b).max(c),
                id: i as u32,
            }
        })
        .collect()
}

/// What laying out a subtree reads: the scene's vertices and the
/// primitives' order.
struct Layout<'a> {
    scene: &'a Scene,
    prims: &'a [Prim],
}

/// Where a subtree is laid out: its nodes from index `node_at` (the slice
/// `nodes` holds exactly them), its blocks from `block_at`.
struct Place<'s> {
    nodes: &'s mut [MaybeUninit<Node>],
    node_at: usize,
    blocks: &'s mut [MaybeUninit<Block>],
    block_at: usize,
}

impl Layout<'_> {
    /// Lays `sub` out depth first into `at`, writing every slot of it once,
    /// and returns its reference. Subtrees are laid out side by side in
    /// parallel: each knows its size, so each gets its own run of nodes and
    /// blocks, and the arrays come out as a sequential depth-first walk
    /// would fill them.
    fn place(&self, sub: &Sub, at: Place<'_>) -> u32 {
        match sub {
            Sub::Leaf { count: 0, .. } => {
                assert!(at.blocks.is_empty() && at.nodes.is_empty());
                EMPTY
            }
            Sub::Leaf { start, count } => {
                let prims = &self.prims[*start..start + count];
                assert!(at.blocks.len() == count.div_ceil(4) && at.nodes.is_empty());
                let tris = prims.iter().map(|p| self.scene.vertices(p.id as usize));
                if let [block] = at.blocks {
                    block.write(Block {
                        tris: Tri4::from_triangles(tris),
                        ids: ids_of(prims),
                    });
                } else {
                    // Leaves hold at most eight triangles: a pair fills
                    // exactly the two slots, every byte of them.
                    assert!(at.blocks.len() == 2);
                    let pair = Pair {
                        tris: Tri8::from_triangles(tris),
                        ids: ids_of(prims),
                    };
                    // SAFETY: the slice is two blocks' slots, one after the
                    // other, whose size and alignment a `Pair` has (checked
                    // where it is defined); writing it fills both.
                    unsafe { at.blocks.as_mut_ptr().cast::<Pair>().write(pair) };
                }
                Child::leaf(at.block_at, *count)
            }
            Sub::Inner { children, size } => {
                let (this, mut nodes) = at.nodes.split_at_mut(1);
                let mut blocks = at.blocks;
                let (mut node_at, mut block_at) = (at.node_at + 1, at.block_at);
                let mut places = Vec::with_capacity(children.len());
                for (_, c) in children {
                    let s = c.size();
                    let (n, rest) = std::mem::take(&mut nodes).split_at_mut(s.nodes);
                    nodes = rest;
                    let (b, rest) = std::mem::take(&mut blocks).split_at_mut(s.blocks);
                    blocks = rest;
                    places.push(Place {
                        nodes: n,
                        node_at,
                        blocks: b,
                        block_at,
                    });
                    node_at += s.nodes;
                    block_at += s.blocks;
                }
                // The children's runs took up the whole of this subtree's.
                assert!(nodes.is_empty() && blocks.is_empty());
                let refs: Vec<(Aabb, u32)> = if size.blocks >= PARALLEL / 4 {
                    places
                        .into_par_iter()
                        .zip(children.par_iter())
                        .map(|(p, (b, c))| (*b, self.place(c, p)))
                        .collect()
                } else {
                    places
                        .into_iter()
                        .zip(children)
                        .map(|(p, (b, c))| (*b, self.place(c, p)))
                        .collect()
                };
                this[0].write(Node::new(&refs));
                Child::inner(at.node_at)
            }
        }
    }
}

/// The triangle indices of up to `N` primitives, one per lane (zeros after).
fn ids_of<const N: usize>(prims: &[Prim]) -> [u32; N] {
    let mut ids = [0u32; N];
    for (id, prim) in ids.iter_mut().zip(prims) {
        *id = prim.id;
    }
    ids
}

/// The most triangles a hierarchy can hold: a leaf's first block must fit
/// in a reference, and there are never more blocks than triangles.
pub const MAX_TRIANGLES: usize = MAX_BLOCKS;

impl WideBvh {
    /// Builds the hierarchy of a scene's triangles on all cores, or `None`
    /// for a scene of more than [`MAX_TRIANGLES`] triangles or whose
    /// hierarchy would take more than 8,388,608 nodes (2 GiB; some 180
    /// million triangles at a landscape's 21 triangles a node): the kd-tree
    /// holds those.
    pub fn build(scene: &Scene) -> Option<WideBvh> {
        let n = scene.triangles.len();
        if n > MAX_TRIANGLES {
            return None;
        }
        let mut prims = primitives(scene, n);
        let (bounds, _) = bounds_of(&prims);
        let sub = build(&mut prims, 0, bounds, 0);
        let size = sub.size();
        if size.nodes > MAX_NODES {
            return None;
        }
        // Written in place, in parallel: filling the arrays first would be
        // a serial pass over hundreds of MiB.
        let mut nodes: Vec<Node> = Vec::with_capacity(size.nodes);
        let mut blocks: Vec<Block> = Vec::with_capacity(size.blocks);
        let layout = Layout { scene, prims: &prims };
        let root = layout.place(
            &sub,
            Place {
                nodes: &mut nodes.spare_capacity_mut()[..size.nodes],
                node_at: 0,
                blocks: &mut blocks.spare_capacity_mut()[..size.blocks],
                block_at: 0,
            },
        );
        // SAFETY: `place` wrote every slot of the runs it was given (it
        // asserts that the children's runs make up each subtree's, and each
        // node and leaf writes its own slots), and the runs were exactly the
        // first `size` slots.
        unsafe {
            nodes.set_len(size.nodes);
            blocks.set_len(size.blocks);
        }
        drop(sub);
        Some(WideBvh {
            nodes,
            blocks,
            root,
            bounds,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::heightfield_and_rays;
    use crate::accel::{BuildOptions, KdTree};

    /// Eight small triangles: one leaf where they lie together, a node of
    /// two leaves of four where they form two clusters far apart; either
    /// way every triangle is found.
    #[test]
    fn eight_triangles_make_one_leaf_unless_they_form_two_clusters() {
        use glam::Mat4;

        use crate::geom::Ray;
        use crate::scene::{Material, SceneBuilder};
        for (gap, nodes) in [(0.1f32, 0), (100.0, 1)] {
            let mut p = Vec::new();
            let mut t = Vec::new();
            for i in 0..8u32 {
                let x = i as f32 * 0.1 + if i >= 4 { gap } else { 0.0 };
                p.extend([
                    Vec3::new(x, 0.0, 1.0),
                    Vec3::new(x + 0.05, 0.0, 1.0),
                    Vec3::new(x, 0.05, 1.0),
                ]);
                t.push([3 * i, 3 * i + 1, 3 * i + 2]);
            }
            let mut b = SceneBuilder::new();
            let m = b.material("grey", Material::lambertian([0.5; 3])).unwrap();
            b.add_mesh("mesh", &p, &t, &[m], Mat4::IDENTITY).unwrap();
            let scene = b.finish();
            let bvh = WideBvh::build(&scene).unwrap();
            let stats = bvh.stats();
            assert_eq!((stats.nodes, stats.leaves), (nodes, nodes + 1), "gap {gap}: {stats:?}");
            for i in 0..8u32 {
                let [a, b, c] = scene.vertices(i as usize);
                let ray = Ray::new((a + b + c) / 3.0 - Vec3::Z, Vec3::Z);
                assert_eq!(bvh.intersect(&ray).map(|h| h.tri), Some(i), "gap {gap}, triangle {i}");
            }
        }
    }

    /// A hierarchy big enough to be laid out in parallel (over 4,096
    /// blocks): every triangle sits in exactly one leaf lane, every node's
    /// boxes hold what lies below them, the node and block arrays are filled
    /// to the last slot, and rays find what the kd-tree finds.
    #[test]
    fn a_parallel_layout_holds_every_triangle_once() {
        let (scene, rays) = heightfield_and_rays(96, 3000, 4);
        let n = scene.triangles.len();
        let bvh = WideBvh::build(&scene).unwrap();
        assert!(bvh.blocks.len() > PARALLEL / 4, "{}", bvh.blocks.len());
        let mut seen = vec![0u32; n];
        let mut nodes_seen = 0;
        // (reference, box its parent gave it)
        let mut stack = vec![(bvh.root, bvh.bounds)];
        while let Some((r, within)) = stack.pop() {
            match Child::decode(r) {
                Child::Empty => {}
                Child::Leaf { block, count } => {
                    let lanes = (1u32 << count) - 1;
                    for lane in 0..count {
                        let id = bvh.id(block, lanes, lane) as usize;
                        seen[id] += 1;
                        let tri = if count > 4 {
                            bvh.pair(block).tris.get(lane)
                        } else {
                            bvh.blocks[block].tris.get(lane)
                        };
                        assert_eq!(tri, scene.vertices(id));
                        for p in scene.vertices(id) {
                            assert!(
                                p.cmpge(within.lo).all() && p.cmple(within.hi).all(),
                                "{id} outside {within:?}"
                            );
                        }
                    }
                }
                Child::Inner(offset) => {
                    nodes_seen += 1;
                    let node = bvh.node(offset);
                    for lane in 0..WIDTH {
                        if node.child[lane] == EMPTY {
                            continue;
                        }
                        let b = |k: usize| node.b[k].as_array_ref()[lane];
                        let child = Aabb {
                            lo: Vec3::new(b(0), b(1), b(2)),
                            hi: Vec3::new(b(3), b(4), b(5)),
                        };
                        stack.push((node.child[lane], child));
                    }
                }
            }
        }
        assert!(seen.iter().all(|&s| s == 1), "a triangle missing or repeated");
        assert_eq!(nodes_seen, bvh.nodes.len());
        let tree = KdTree::build(&scene, &BuildOptions::default());
        // The rays aim at shared edges and vertices, where each triangle's
        // own arithmetic gives a distance a rounding apart.
        for ray in &rays {
            let (a, b) = (bvh.intersect(ray).unwrap().t, tree.intersect(ray).unwrap().t);
            assert!((a - b).abs() <= 1e-6 * b, "{ray:?}: {a} against {b}");
        }
    }
}
