//! Building the kd-tree: binned SAH over triangle bounds clipped to the node,
//! a bonus for cutting off empty space, recursion in parallel for big nodes,
//! then flattening into the compact node array.

use rayon::prelude::*;

use super::leaf::LeafTris;
use super::{KdTree, Node};
use crate::geom::Aabb;
use crate::scene::Scene;

/// Tuning of the build.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Cost of one traversal step relative to one triangle test. Triangles
    /// are tested four at a time in SIMD lanes, which makes a test cheap
    /// beside a step: 10 measured fastest for single rays on the 1M
    /// landscape (8 to 16 within noise), and builds 2.6 times faster with
    /// 40% fewer references than 3.
    pub traversal_cost: f32,
    /// Bins per axis.
    pub bins: usize,
    /// SAH discount for a split that leaves one side empty.
    pub empty_bonus: f32,
    /// Leaves at most this small are never split.
    pub leaf_size: usize,
    /// Nodes larger than this are built in parallel.
    pub parallel_above: usize,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            traversal_cost: 10.0,
            bins: 32,
            empty_bonus: 0.8,
            leaf_size: 2,
            parallel_above: 4096,
        }
    }
}

impl BuildOptions {
    /// For the trees of out-of-core scene files, whose walk tests a leaf's
    /// triangles one at a time from decoded blocks: a traversal step costs
    /// three triangle tests, and leaves stay small.
    pub fn one_triangle_at_a_time() -> BuildOptions {
        BuildOptions {
            traversal_cost: 3.0,
            ..BuildOptions::default()
        }
    }
}

/// A triangle reference with its bounds clipped to the current node.
#[derive(Clone, Copy)]
struct Ref {
    tri: u32,
    bounds: Aabb,
}

enum BuildNode {
    Leaf(Vec<u32>),
    Inner {
        axis: usize,
        split: f32,
        children: Box<(BuildNode, BuildNode)>,
        /// Nodes in this subtree, itself included, and leaf references:
        /// where its part of the flattened arrays ends.
        nodes: usize,
        refs: usize,
    },
}

impl BuildNode {
    /// Nodes in the subtree (itself included) and its leaf references.
    fn size(&self) -> (usize, usize) {
        match self {
            BuildNode::Leaf(tris) => (1, tris.len()),
            BuildNode::Inner { nodes, refs, .. } => (*nodes, *refs),
        }
    }
}

struct Split {
    axis: usize,
    pos: f32,
    cost: f32,
}

impl KdTree {
    /// Builds the tree over every triangle of the scene.
    pub fn build(scene: &Scene, options: &BuildOptions) -> KdTree {
        let refs = references(scene, None);
        let bounds = refs.iter().fold(Aabb::EMPTY, |acc, r| acc.union(&r.bounds));
        KdTree::build_refs(scene, refs, bounds, options)
    }

    /// Builds the tree over the parts of the scene's triangles inside
    /// `bounds`, which become the root's box (a chunk of a larger scene).
    pub fn build_within(scene: &Scene, bounds: Aabb, options: &BuildOptions) -> KdTree {
        let refs = references(scene, Some(&bounds));
        KdTree::build_refs(scene, refs, bounds, options)
    }

    fn build_refs(scene: &Scene, refs: Vec<Ref>, bounds: Aabb, options: &BuildOptions) -> KdTree {
        // Bounded so the traversal stack (64 entries) can never overflow.
        let max_depth = (8 + (1.3 * (refs.len().max(1) as f32).log2()) as usize).min(60);
        let root = if refs.is_empty() {
            BuildNode::Leaf(Vec::new())
        } else {
            build_node(scene, refs, bounds, 0, max_depth, options)
        };
        let (count, refs) = root.size();
        let (mut nodes, mut leaf_tris) = (vec![Node::leaf(0, 0); count], vec![0u32; refs]);
        let (first, below) = nodes.split_at_mut(1);
        flatten(root, &mut first[0], below, 1, &mut leaf_tris, 0);
        if leaf_tris.len() >= RELEASE_ABOVE {
            release_freed_memory();
        }
        KdTree {
            leaves: LeafTris::new(scene, &leaf_tris),
            grid: std::sync::OnceLock::new(),
            nodes,
            leaf_tris,
            bounds,
        }
    }

    /// The nodes (root at 0).
    pub fn nodes(&self) -> &[Node] {
        &self.nodes
    }
    /// The leaf triangle lists.
    pub fn leaf_tris(&self) -> &[u32] {
        &self.leaf_tris
    }
}

/// References from which a build hands its freed memory back (smaller
/// builds, such as a scene file's many chunks, leave little behind).
const RELEASE_ABOVE: usize = 1 << 20;

/// Hands the memory the build freed back to the system before the leaf
/// triangles are copied. The build's many reference lists, each below the
/// allocator's threshold for mapping memory of its own, are freed into its
/// heaps, which the system would otherwise count as in use beside the new
/// copy (glibc; elsewhere nothing to do).
fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages to the system; it
    // touches no memory in use.
    unsafe {
        libc::malloc_trim(0);
    }
}

/// One reference per triangle, its bounds clipped to `within` if given
/// (triangles that miss it are left out).
fn references(scene: &Scene, within: Option<&Aabb>) -> Vec<Ref> {
    let bounds = |t: usize| {
        let mut b = Aabb::EMPTY;
        for p in scene.vertices(t) {
            b.grow(p);
        }
        b
    };
    let Some(w) = within else {
        // Every triangle: an indexed collect writes the list in place.
        return (0..scene.triangles.len())
            .into_par_iter()
            .map(|t| Ref {
                tri: t as u32,
                bounds: bounds(t),
            })
            .collect();
    };
    (0..scene.triangles.len())
        .into_par_iter()
        .filter_map(|t| {
            let b = bounds(t).clip(w);
            (!b.is_empty()).then_some(Ref {
                tri: t as u32,
                bounds: b,
            })
        })
        .collect()
}

/// Writes `node` into `slot` and its descendants into `below`, which
/// starts at index `at` of the node array and holds exactly them (children
/// in pairs, each pair before the descendants of its left child, then its
/// right child's); its leaf references go into `tris`, which starts at `first`
/// of the leaf lists. Big subtrees are flattened side by side in parallel:
/// each knows its size, so each gets its own run, and the arrays come out as
/// a sequential depth-first walk would fill them.
fn flatten(node: BuildNode, slot: &mut Node, below: &mut [Node], at: usize, tris: &mut [u32], first: usize) {
    match node {
        BuildNode::Leaf(list) => {
            *slot = Node::leaf(first, list.len());
            tris.copy_from_slice(&list);
        }
        BuildNode::Inner {
            axis,
            split,
            children,
            refs,
            ..
        } => {
            *slot = Node::inner(axis, split, at);
            let (l, r) = *children;
            let ((ln, lr), (rn, rr)) = (l.size(), r.size());
            let (pair, rest) = below.split_at_mut(2);
            let (left_below, right_below) = rest.split_at_mut(ln - 1);
            debug_assert_eq!(right_below.len(), rn - 1);
            let (left_tris, right_tris) = tris.split_at_mut(lr);
            debug_assert_eq!(right_tris.len(), rr);
            let (left_slot, right_slot) = pair.split_at_mut(1);
            let (left_at, right_at) = (at + 2, at + 2 + ln - 1);
            let left = || flatten(l, &mut left_slot[0], left_below, left_at, left_tris, first);
            let right = || flatten(r, &mut right_slot[0], right_below, right_at, right_tris, first + lr);
            if refs > FLATTEN_IN_PARALLEL {
                rayon::join(left, right);
            } else {
                left();
                right();
            }
        }
    }
}

/// Subtrees with more leaf references than this are flattened in parallel.
const FLATTEN_IN_PARALLEL: usize = 1 << 15;

fn build_node(
    scene: &Scene,
    refs: Vec<Ref>,
    bounds: Aabb,
    depth: usize,
    max_depth: usize,
    o: &BuildOptions,
) -> BuildNode {
    let n = refs.len();
    if n <= o.leaf_size || depth >= max_depth {
        return leaf(refs);
    }
    let Some(split) = best_split(&refs, &bounds, o) else {
        return leaf(refs);
    };
    if split.cost >= n as f32 {
        return leaf(refs);
    }
    let (mut left_box, mut right_box) = (bounds, bounds);
    left_box.hi[split.axis] = split.pos;
    right_box.lo[split.axis] = split.pos;
    let (left, right) = if n > o.parallel_above * 16 {
        let parts: Vec<(Vec<Ref>, Vec<Ref>)> = refs
            .par_chunks(1 << 14)
            .map(|c| partition(scene, c, &split, &left_box, &right_box))
            .collect();
        // The parts hold every reference now: the node's own list can go
        // before they are joined.
        drop(refs);
        let (nl, nr) = parts.iter().fold((0, 0), |(a, b), (l, r)| (a + l.len(), b + r.len()));
        let (mut left, mut right) = (Vec::with_capacity(nl), Vec::with_capacity(nr));
        for (l, r) in parts {
            left.extend(l);
            right.extend(r);
        }
        (left, right)
    } else {
        let (mut left, mut right) = partition(scene, &refs, &split, &left_box, &right_box);
        drop(refs);
        // A side that outgrew its guess may hold up to twice what it needs,
        // and it lives on while the other side's subtree is built. (The
        // parallel branch above already joins its parts at their exact size.)
        left.shrink_to_fit();
        right.shrink_to_fit();
        (left, right)
    };
    if left.len() == n && right.len() == n {
        // Nothing was separated: splitting again would only duplicate.
        return leaf(left);
    }
    let (l, r) = if n > o.parallel_above {
        rayon::join(
            || build_node(scene, left, left_box, depth + 1, max_depth, o),
            || build_node(scene, right, right_box, depth + 1, max_depth, o),
        )
    } else {
        (
            build_node(scene, left, left_box, depth + 1, max_depth, o),
            build_node(scene, right, right_box, depth + 1, max_depth, o),
        )
    };
    let ((ln, lr), (rn, rr)) = (l.size(), r.size());
    BuildNode::Inner {
        axis: split.axis,
        split: split.pos,
        children: Box::new((l, r)),
        nodes: 1 + ln + rn,
        refs: lr + rr,
    }
}

/// Sends each reference to the side(s) of the split it touches.
fn partition(scene: &Scene, refs: &[Ref], split: &Split, left_box: &Aabb, right_box: &Aabb) -> (Vec<Ref>, Vec<Ref>) {
    let (mut left, mut right) = (
        Vec::with_capacity(refs.len() / 2 + 1),
        Vec::with_capacity(refs.len() / 2 + 1),
    );
    for &r in refs {
        let (lo, hi) = (r.bounds.lo[split.axis], r.bounds.hi[split.axis]);
        if lo == split.pos && hi == split.pos {
            // A triangle lying in the split plane goes where the SAH counted it
            // (above). Rays in the plane visit both children, and rays crossing
            // it near the plane visit both within the traversal's slack.
            right.push(r);
        } else if hi <= split.pos {
            left.push(r);
        } else if lo >= split.pos {
            right.push(r);
        } else {
            // Straddling: clip the triangle itself to each child ("perfect
            // splits"), so it only goes where it really is.
            let v = scene.vertices(r.tri as usize);
            if let Some(b) = clip_triangle(v, &r.bounds.clip(left_box)) {
                left.push(Ref { tri: r.tri, bounds: b });
            }
            if let Some(b) = clip_triangle(v, &r.bounds.clip(right_box)) {
                right.push(Ref { tri: r.tri, bounds: b });
            }
        }
    }
    (left, right)
}

fn leaf(refs: Vec<Ref>) -> BuildNode {
    BuildNode::Leaf(refs.into_iter().map(|r| r.tri).collect())
}

/// Most bins per axis.
const MAX_BINS: usize = 64;

/// Counts of references starting and ending in each bin, per axis, and the
/// bounds of their content.
#[derive(Clone)]
struct Bins {
    starts: [[u32; MAX_BINS]; 3],
    ends: [[u32; MAX_BINS]; 3],
    content: Aabb,
}

impl Bins {
    fn empty() -> Bins {
        Bins {
            starts: [[0; MAX_BINS]; 3],
            ends: [[0; MAX_BINS]; 3],
            content: Aabb::EMPTY,
        }
    }

    /// One pass over the references for all three axes.
    fn add(mut self, refs: &[Ref], lo: glam::Vec3, scale: glam::Vec3, bins: usize) -> Bins {
        let last = (bins - 1) as f32;
        // Plain comparisons, not `f32::min`: its NaN rule costs a blend per
        // operation, and bounds are never NaN (a NaN would land in the last bin).
        let bin = |x: f32, axis: usize| {
            let b = (x - lo[axis]) * scale[axis];
            let b = if b < last { b } else { last };
            (if b > 0.0 { b } else { 0.0 }) as usize
        };
        for r in refs {
            self.content.include(&r.bounds);
            for axis in 0..3 {
                self.starts[axis][bin(r.bounds.lo[axis], axis).min(MAX_BINS - 1)] += 1;
                self.ends[axis][bin(r.bounds.hi[axis], axis).min(MAX_BINS - 1)] += 1;
            }
        }
        self
    }

    fn merge(mut self, o: Bins) -> Bins {
        for axis in 0..3 {
            for b in 0..MAX_BINS {
                self.starts[axis][b] += o.starts[axis][b];
                self.ends[axis][b] += o.ends[axis][b];
            }
        }
        self.content = self.content.union(&o.content);
        self
    }
}

/// The cheapest binned SAH split, in units of one triangle test.
fn best_split(refs: &[Ref], bounds: &Aabb, o: &BuildOptions) -> Option<Split> {
    let area = bounds.area();
    if area <= 0.0 {
        return None;
    }
    let bins = o.bins.clamp(2, MAX_BINS);
    let extent = bounds.hi - bounds.lo;
    let scale = glam::Vec3::new(
        if extent.x > 0.0 { bins as f32 / extent.x } else { 0.0 },
        if extent.y > 0.0 { bins as f32 / extent.y } else { 0.0 },
        if extent.z > 0.0 { bins as f32 / extent.z } else { 0.0 },
    );
    let counts = if refs.len() > o.parallel_above * 16 {
        refs.par_chunks(1 << 14)
            .fold(Bins::empty, |acc, chunk| acc.add(chunk, bounds.lo, scale, bins))
            .reduce(Bins::empty, Bins::merge)
    } else {
        Bins::empty().add(refs, bounds.lo, scale, bins)
    };
    let n = refs.len() as f32;
    let mut best: Option<Split> = None;
    let mut consider = |axis: usize, pos: f32, left: f32, right: f32| {
        let (mut lb, mut rb) = (*bounds, *bounds);
        lb.hi[axis] = pos;
        rb.lo[axis] = pos;
        let bonus = if left == 0.0 || right == 0.0 {
            o.empty_bonus
        } else {
            1.0
        };
        let cost = o.traversal_cost + bonus * (lb.area() * left + rb.area() * right) / area;
        if best.as_ref().is_none_or(|s| cost < s.cost) {
            best = Some(Split { axis, pos, cost });
        }
    };
    for axis in 0..3 {
        if extent[axis] <= 0.0 {
            continue;
        }
        // Candidate planes at bin boundaries: left holds refs starting below,
        // right holds refs ending above.
        let (mut left, mut right) = (0u32, refs.len() as u32);
        for b in 1..bins {
            left += counts.starts[axis][b - 1];
            right -= counts.ends[axis][b - 1];
            let pos = bounds.lo[axis] + extent[axis] * b as f32 / bins as f32;
            consider(axis, pos, left as f32, right as f32);
        }
        // Cut off empty space exactly at the content boundary.
        let content = &counts.content;
        // Content flat in this axis (all triangles in one plane): a cut there
        // would send everything to both sides.
        let flat = content.lo[axis] >= content.hi[axis];
        if !flat && (content.lo[axis] - bounds.lo[axis]) > 0.1 * extent[axis] {
            consider(axis, content.lo[axis], 0.0, n);
        }
        if !flat && (bounds.hi[axis] - content.hi[axis]) > 0.1 * extent[axis] {
            consider(axis, content.hi[axis], n, 0.0);
        }
    }
    best.filter(|s| s.pos.is_finite() && s.pos > bounds.lo[s.axis] && s.pos < bounds.hi[s.axis])
}

/// Bounds of the part of triangle `v` inside `b`, or `None` if it misses the box.
fn clip_triangle(v: [glam::Vec3; 3], b: &Aabb) -> Option<Aabb> {
    if b.is_empty() {
        return None;
    }
    // Sutherland-Hodgman against the six planes; a triangle clipped by six
    // planes has at most nine vertices. Points are arrays: a `Vec3` indexed
    // by a run-time axis is a branch per access.
    let mut poly = [[0f32; 3]; 12];
    let mut len = 3;
    for (p, q) in poly.iter_mut().zip(v) {
        *p = q.to_array();
    }
    let (lo, hi) = (b.lo.to_array(), b.hi.to_array());
    for axis in 0..3 {
        for (bound, keep_above) in [(lo[axis], true), (hi[axis], false)] {
            let inside = |p: &[f32; 3]| if keep_above { p[axis] >= bound } else { p[axis] <= bound };
            if poly[..len].iter().all(inside) {
                continue;
            }
            let mut out = [[0f32; 3]; 12];
            let mut n = 0;
            for i in 0..len {
                let (p, q) = (poly[i], poly[(i + 1) % len]);
                let (pin, qin) = (inside(&p), inside(&q));
                if pin {
                    out[n] = p;
                    n += 1;
                }
                if pin != qin && n < out.len() {
                    let t = (bound - p[axis]) / (q[axis] - p[axis]);
                    let mut x = [0f32; 3];
                    for c in 0..3 {
                        x[c] = p[c] + (q[c] - p[c]) * t;
                    }
                    x[axis] = bound;
                    out[n] = x;
                    n += 1;
                }
            }
            if n == 0 {
                return None;
            }
            poly = out;
            len = n;
        }
    }
    let mut r = Aabb::EMPTY;
    for p in &poly[..len] {
        r.grow(glam::Vec3::from_array(*p));
    }
    // Rounding must never shrink the box below what the triangle covers.
    Some(r.clip(b))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::accel::testing::heightfield_and_rays;
    use crate::accel::WideBvh;

    /// A tree big enough to be flattened in parallel (over 32,768 leaf
    /// references): children come after their parents in pairs, each leaf
    /// list follows the previous one in depth-first order with none
    /// skipped, every triangle is in some leaf, and rays find what the wide
    /// BVH finds.
    #[test]
    fn a_parallel_flatten_lays_the_tree_out_depth_first() {
        let (scene, rays) = heightfield_and_rays(136, 3000, 6);
        let tree = KdTree::build(&scene, &BuildOptions::default());
        let (nodes, tris) = (tree.nodes(), tree.leaf_tris());
        assert!(tris.len() > FLATTEN_IN_PARALLEL, "{}", tris.len());
        // Depth first from the root: leaf lists in order, children in range.
        let mut next_leaf = 0;
        let mut stack = vec![0usize];
        let mut reached = vec![false; nodes.len()];
        while let Some(i) = stack.pop() {
            assert!(!reached[i], "node {i} reached twice");
            reached[i] = true;
            let n = nodes[i];
            if n.is_leaf() {
                assert_eq!(n.first(), next_leaf, "leaf {i}");
                next_leaf += n.count();
            } else {
                assert!(n.left() > i && n.left() + 1 < nodes.len(), "node {i}");
                stack.push(n.left() + 1);
                stack.push(n.left());
            }
        }
        assert_eq!(next_leaf, tris.len());
        assert!(reached.iter().all(|&r| r), "a node no walk reaches");
        let mut seen = vec![false; scene.triangles.len()];
        for &t in tris {
            seen[t as usize] = true;
        }
        assert!(seen.iter().all(|&s| s), "a triangle in no leaf");
        // The rays aim at shared edges and vertices, where each triangle's
        // own arithmetic gives a distance a rounding apart. (On a field this
        // wide, a few graze past its far edge: both structures must agree.)
        let bvh = WideBvh::build(&scene).unwrap();
        let mut hits = 0;
        for ray in &rays {
            match (tree.intersect(ray), bvh.intersect(ray)) {
                (Some(a), Some(b)) => {
                    assert!((a.t - b.t).abs() <= 1e-6 * b.t, "{ray:?}: {a:?} against {b:?}");
                    hits += 1;
                }
                (None, None) => {}
                (a, b) => panic!("{ray:?}: kd-tree {a:?}, BVH {b:?}"),
            }
        }
        assert!(hits > 2900, "{hits}");
    }
}
