//! Tracing rays through the out-of-core tree: Áfra 2012, Algorithm 1. The
//! walk is the in-core kd-tree walk (same slack at split planes, so hits are
//! bit-for-bit the in-core tracer's), extended with LOD nodes: at each one the
//! ray remembers the voxel, stops there if the voxel looks small enough from
//! the ray's origin, and, when the block behind it is not resident, either
//! asks for it and returns the voxel as a proxy hit, or loads it on the spot.

use std::mem::MaybeUninit;

use crossbeam_epoch::Guard;
use glam::Vec3;

use super::block::{Block, Link};
use super::node::{NodeKind, TNode};
use super::voxel::{entry_face, FaceSample};
use super::OocScene;
use crate::geom::{intersect_triangle, Ray, RayPrep};

const STACK: usize = 128;
const SLACK_UP: f32 = 1.0 + 1e-5;
const SLACK_DOWN: f32 = 1.0 - 1e-5;

/// What to do when a ray needs a block that is not resident.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum OnMissing {
    /// Ask the fetchers for it and return the last voxel (a proxy hit).
    Proxy,
    /// Load it now and go on: exact, at the price of waiting.
    Load,
}

/// Per-ray (or per-batch) fetch state: the blocks asked for, and whether any
/// result came from a proxy because data was missing.
#[derive(Clone, Debug)]
pub struct Fetch {
    /// Behaviour on a missing block.
    pub on_missing: OnMissing,
    /// Blocks asked for (not yet handed to the cache).
    pub requests: Vec<u32>,
    /// True once a proxy stood in for missing data.
    pub missed: bool,
}

impl Fetch {
    /// A fetch state that loads what it needs on the spot.
    pub fn load() -> Fetch {
        Fetch {
            on_missing: OnMissing::Load,
            requests: Vec::new(),
            missed: false,
        }
    }
    /// A fetch state that returns proxies for missing data.
    pub fn proxy() -> Fetch {
        Fetch {
            on_missing: OnMissing::Proxy,
            requests: Vec::new(),
            missed: false,
        }
    }
}

/// What a ray hit in the out-of-core scene.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum OocSurface {
    /// A triangle.
    Triangle {
        /// Scene-wide triangle id.
        id: u32,
        /// Material index.
        material: u32,
        /// The triangle's vertices.
        vertices: [Vec3; 3],
        /// Barycentric weight of vertex 1.
        u: f32,
        /// Barycentric weight of vertex 2.
        v: f32,
    },
    /// A voxel: the face sample the ray entered through.
    Voxel {
        /// The face's shading sample.
        sample: FaceSample,
        /// Radius of the voxel's bounding sphere (for the offset of the next ray).
        radius: f32,
        /// True if the voxel stood in for data that was not resident.
        missing: bool,
    },
}

/// The nearest hit of a ray.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct OocHit {
    /// Ray parameter.
    pub t: f32,
    /// What was hit.
    pub surface: OocSurface,
}

/// How a walk ended early.
enum Stop<'g> {
    /// At a voxel (LOD or missing data), at parameter `t`, entered through `face`.
    Voxel {
        t: f32,
        link: &'g Link,
        face: usize,
        missing: bool,
    },
    /// The leaf visitor said so.
    Visitor,
}

/// A walk position: block, node, ray range, entry axis, and how many links
/// into other blocks led here (24 bytes: pushed and popped at every split).
#[derive(Clone, Copy)]
struct State<'g> {
    block: &'g Block,
    node: u32,
    t_min: f32,
    t_max: f32,
    axis: u8,
    depth: u16,
}

impl OocScene {
    fn block<'g>(&self, id: u32, fetch: &mut Fetch, guard: &'g Guard) -> Option<&'g Block> {
        let cache = self.cache();
        if let Some(b) = cache.get(id, guard) {
            return Some(b);
        }
        match fetch.on_missing {
            OnMissing::Proxy => {
                fetch.requests.push(id);
                fetch.missed = true;
                None
            }
            OnMissing::Load => match cache.load_now(id, guard) {
                Ok(b) => Some(b),
                Err(_) => {
                    // Unreadable: the error is noted by the cache; the proxy stands in.
                    fetch.missed = true;
                    None
                }
            },
        }
    }

    /// Walks the leaves along the ray front to back (see the in-core walk).
    /// `lod` is the voxel-size-to-distance ratio below which a voxel stands in
    /// for its subtree (0: never).
    ///
    /// Long because it is one traversal loop (Áfra 2012, Algorithm 1): the
    /// node stack, the ray's interval and the block in hand stay in locals
    /// across inner nodes, links, voxels and leaves; split, every step would
    /// hand them back and forth on the hottest path out of core.
    fn walk<'g>(
        &'g self,
        ray: &Ray,
        lod: f32,
        fetch: &mut Fetch,
        guard: &'g Guard,
        mut leaf: impl FnMut(&'g Block, &'g [u16], f32) -> Result<Option<f32>, ()>,
    ) -> Option<Stop<'g>> {
        let inv = ray.dir.recip();
        let bounds = self.bounds();
        let (t0, t1) = bounds.range(ray, inv)?;
        let root = self.root();
        let a = (bounds.lo - ray.origin) * inv;
        let b = (bounds.hi - ray.origin) * inv;
        let near = a.min(b);
        let axis0 = if near.x >= near.y && near.x >= near.z {
            0
        } else if near.y >= near.z {
            1
        } else {
            2
        };
        let missing_at = |t: f32, link: &'g Link, axis: usize| Stop::Voxel {
            t,
            link,
            face: entry_face(axis, ray.dir),
            missing: true,
        };
        if lod > 0.0 && root.radius() <= t0 * lod && solid(root, entry_face(axis0, ray.dir)) {
            return Some(Stop::Voxel {
                t: t0,
                link: root,
                face: entry_face(axis0, ray.dir),
                missing: false,
            });
        }
        let Some(root_block) = self.block(root.block, fetch, guard) else {
            return Some(missing_at(t0, root, axis0));
        };
        let (org, inv_a) = (ray.origin.to_array(), inv.to_array());
        let mut closest = ray.t_max;
        // Uninitialized: filling 128 entries would cost more than most rays.
        let mut stack: [MaybeUninit<State<'g>>; STACK] = [const { MaybeUninit::uninit() }; STACK];
        let mut sp = 0;
        let mut s = State {
            block: root_block,
            node: root.node,
            t_min: t0,
            t_max: t1,
            axis: axis0 as u8,
            depth: 0,
        };
        // Each link into another block leads a level deeper; more crossings
        // than levels means links that cycle (a corrupt file).
        let max_depth = self.header().levels.min(u32::from(u16::MAX)) as u16;
        // The current block's nodes, kept at hand: the block changes far less
        // often than the node.
        let mut nodes: &'g [TNode] = &s.block.nodes;
        loop {
            let Some(n) = nodes.get(s.node as usize) else {
                // A link into a block with fewer nodes: a corrupt file. Treat as empty.
                self.note_corrupt(|| format!("a link names node {} past the end of its block", s.node));
                if !pop(&stack, &mut sp, &mut s, &mut nodes, closest) {
                    return None;
                }
                continue;
            };
            match n.kind() {
                NodeKind::Inner { axis, split, left } => {
                    let o = org[axis];
                    let t_split = (split - o) * inv_a[axis];
                    let below_first = o < split || (o == split && inv_a[axis] <= 0.0);
                    let (first, second) = if below_first {
                        (left, left + 1)
                    } else {
                        (left + 1, left)
                    };
                    if t_split.is_nan() {
                        if sp < STACK {
                            stack[sp] = MaybeUninit::new(State { node: second, ..s });
                            sp += 1;
                        }
                        s.node = first;
                    } else if t_split > s.t_max * SLACK_UP || t_split <= 0.0 {
                        s.node = first;
                    } else if t_split < s.t_min * SLACK_DOWN {
                        s.node = second;
                    } else {
                        if sp < STACK {
                            stack[sp] = MaybeUninit::new(State {
                                node: second,
                                t_min: t_split,
                                axis: axis as u8,
                                ..s
                            });
                            sp += 1;
                        }
                        s.node = first;
                        s.t_max = t_split;
                    }
                    continue;
                }
                NodeKind::Link { link, local } => {
                    if local != 0 && lod <= 0.0 {
                        // Into this same block, and no voxel to look at.
                        s.node = local - 1;
                        continue;
                    }
                    let l = &s.block.links[link as usize];
                    if lod > 0.0 && l.radius() <= s.t_min * lod && solid(l, entry_face(s.axis as usize, ray.dir)) {
                        return Some(Stop::Voxel {
                            t: s.t_min,
                            link: l,
                            face: entry_face(s.axis as usize, ray.dir),
                            missing: false,
                        });
                    }
                    if local != 0 {
                        s.node = local - 1;
                        continue;
                    }
                    if s.depth >= max_depth {
                        self.note_corrupt(|| format!("links lead through more than {max_depth} blocks (a cycle)"));
                        if !pop(&stack, &mut sp, &mut s, &mut nodes, closest) {
                            return None;
                        }
                        continue;
                    }
                    match self.block(l.block, fetch, guard) {
                        Some(b) => {
                            s.block = b;
                            nodes = &b.nodes;
                            s.node = l.node;
                            s.depth += 1;
                        }
                        None => return Some(missing_at(s.t_min, l, s.axis as usize)),
                    }
                    continue;
                }
                NodeKind::Leaf { first, count } => {
                    let tris = &s.block.list[first as usize..(first + count) as usize];
                    match leaf(s.block, tris, s.t_max) {
                        Err(()) => return Some(Stop::Visitor),
                        Ok(Some(t)) => closest = closest.min(t),
                        Ok(None) => {}
                    }
                    if closest <= s.t_max {
                        return None;
                    }
                    if !pop(&stack, &mut sp, &mut s, &mut nodes, closest) {
                        return None;
                    }
                }
            }
        }
    }

    /// The nearest hit within `(0, ray.t_max]`, or a voxel: where LOD says
    /// (`lod` > 0) or where data was missing (`fetch` says which).
    pub fn intersect(&self, ray: &Ray, lod: f32, fetch: &mut Fetch) -> Option<OocHit> {
        let guard = crossbeam_epoch::pin();
        let prep = RayPrep::new(ray.origin, ray.dir);
        let mut best: Option<OocHit> = None;
        let mut closest = ray.t_max;
        let stop = self.walk(ray, lod, fetch, &guard, |block, tris, _| {
            for &t in tris {
                let t = t as usize;
                let [a, b, c] = block.triangle(t);
                if let Some(h) = intersect_triangle(&prep, a, b, c, closest) {
                    closest = h.t;
                    best = Some(OocHit {
                        t: h.t,
                        surface: OocSurface::Triangle {
                            id: block.ids[t],
                            material: u32::from(block.tris[t].material),
                            vertices: [a, b, c],
                            u: h.u,
                            v: h.v,
                        },
                    });
                }
            }
            Ok(best.map(|h| h.t))
        });
        match stop {
            Some(Stop::Voxel { t, link, face, missing }) if t <= closest => Some(OocHit {
                t,
                surface: OocSurface::Voxel {
                    sample: link.voxel_face(face),
                    radius: link.radius(),
                    missing,
                },
            }),
            _ => best,
        }
    }

    /// True if a triangle for which `blocks(id, material, vertices)` is true,
    /// or a voxel, lies within `(0, ray.t_max)`.
    pub fn occluded_by(
        &self,
        ray: &Ray,
        lod: f32,
        fetch: &mut Fetch,
        mut blocks: impl FnMut(u32, u32, [Vec3; 3]) -> bool,
    ) -> bool {
        let guard = crossbeam_epoch::pin();
        let prep = RayPrep::new(ray.origin, ray.dir);
        let stop = self.walk(ray, lod, fetch, &guard, |block, tris, _| {
            for &t in tris {
                let t = t as usize;
                let [a, b, c] = block.triangle(t);
                if intersect_triangle(&prep, a, b, c, ray.t_max).is_some_and(|h| h.t < ray.t_max)
                    && blocks(block.ids[t], u32::from(block.tris[t].material), [a, b, c])
                {
                    return Err(());
                }
            }
            Ok(None)
        });
        match stop {
            Some(Stop::Visitor) => true,
            Some(Stop::Voxel { t, .. }) => t < ray.t_max,
            None => false,
        }
    }
}

/// Coverage a voxel's face needs for LOD to stop there: a sparser voxel (a
/// few trees in a big box) is refined instead of drawn as a solid box.
pub const SOLID: f32 = 0.5;

fn solid(l: &Link, face: usize) -> bool {
    l.voxel.face(face).coverage >= SOLID
}

/// Pops the nearest pending node that starts before `closest`, with its
/// block's nodes. Entries below `sp` are initialized: only pushes write them,
/// and `sp` counts the pushes.
fn pop<'g>(
    stack: &[MaybeUninit<State<'g>>],
    sp: &mut usize,
    s: &mut State<'g>,
    nodes: &mut &'g [TNode],
    closest: f32,
) -> bool {
    while *sp > 0 {
        *sp -= 1;
        // SAFETY: index below the push count, written by a push (see above).
        let next = unsafe { stack[*sp].assume_init() };
        if next.t_min <= closest {
            *s = next;
            *nodes = &next.block.nodes;
            return true;
        }
    }
    false
}

impl Link {
    /// The voxel's sample for face `f`.
    pub fn voxel_face(&self, f: usize) -> FaceSample {
        self.voxel.face(f)
    }
}
