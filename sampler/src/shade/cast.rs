//! What a tracer casts its rays against: one of the sibling casters of
//! [`crate::accel`] (the wide BVH, the kd-tree, or another library's
//! hierarchy such as Embree through [`RayCaster`]), or a scene file walked
//! out of core. Each query is one `match` that hands the ray to the
//! caster's own walk, inlined where the caster is ours (as pbrt-v4
//! dispatches over its tagged pointers rather than virtual calls); the path
//! estimator never asks which caster it has, only whether it casts packets
//! and whether it is a scene file.
//!
//! A scene file is the one caster with more to say than a triangle hit: its
//! walk stands voxels in for far or missing data and fetches blocks, so the
//! tracer walks it through [`OocScene`] itself, and the in-core queries here
//! answer nothing for it.

use std::sync::Arc;

use crate::accel::{BuildOptions, Hit, KdTree, RayCaster, RayOrder, WideBvh, PACKET};
use crate::geom::Ray;
use crate::ooc::OocScene;
use crate::scene::Scene;

/// The one ray caster of a [`Tracer`](super::Tracer).
pub enum Caster {
    /// In memory: the wide BVH casts single rays and packets; the kd-tree
    /// `tree` sorts the rays of wavefront batches by its coarse grid.
    Bvh {
        /// Casts every ray.
        bvh: WideBvh,
        /// Sorts batches (`crate::accel::RayOrder`).
        tree: KdTree,
    },
    /// In memory: the kd-tree casts and sorts (scenes beyond the BVH's size).
    KdTree(KdTree),
    /// Another library's hierarchy (Embree) casting single rays, no
    /// packets; it must hold the scene's triangles with their indices. The
    /// kd-tree `tree` sorts.
    Outside {
        /// Casts every ray.
        caster: Arc<dyn RayCaster>,
        /// Sorts batches.
        tree: KdTree,
    },
    /// A scene file: materials, sky and lights from its header, triangles
    /// from its blocks as rays need them.
    OutOfCore(Arc<OocScene>),
}

impl Caster {
    /// The in-core caster of a scene: the wide BVH where the scene fits it
    /// ([`crate::accel::MAX_TRIANGLES`]), else the kd-tree.
    pub fn in_core(scene: &Scene) -> Caster {
        Caster::around_tree(scene, KdTree::build(scene, &BuildOptions::default()))
    }

    /// [`Caster::in_core`] around a kd-tree already built over `scene`.
    pub fn around_tree(scene: &Scene, tree: KdTree) -> Caster {
        match WideBvh::build(scene) {
            Some(bvh) => Caster::Bvh { bvh, tree },
            None => Caster::KdTree(tree),
        }
    }

    /// Another library's caster over `scene` (its triangles with their
    /// indices), with a kd-tree to sort batches: for comparing whole path
    /// tracing over another hierarchy (`holodeck bench tracer --embree`).
    pub fn outside(scene: &Scene, caster: Arc<dyn RayCaster>) -> Caster {
        Caster::Outside {
            caster,
            tree: KdTree::build(scene, &BuildOptions::default()),
        }
    }

    /// The caster's name, for reports.
    pub fn name(&self) -> &'static str {
        match self {
            Caster::Bvh { .. } => "wide BVH",
            Caster::KdTree(_) => "kd-tree",
            Caster::Outside { .. } => "outside caster",
            Caster::OutOfCore(_) => "scene file",
        }
    }

    /// The kd-tree, where the caster keeps one (in core).
    pub fn tree(&self) -> Option<&KdTree> {
        match self {
            Caster::Bvh { tree, .. } | Caster::Outside { tree, .. } | Caster::KdTree(tree) => Some(tree),
            Caster::OutOfCore(_) => None,
        }
    }

    /// The wide BVH, where it casts the rays.
    pub fn bvh(&self) -> Option<&WideBvh> {
        match self {
            Caster::Bvh { bvh, .. } => Some(bvh),
            _ => None,
        }
    }

    /// The scene file, where one is walked out of core.
    pub fn file(&self) -> Option<&Arc<OocScene>> {
        match self {
            Caster::OutOfCore(ooc) => Some(ooc),
            _ => None,
        }
    }

    /// Bytes of the structure single rays walk through in core (for an
    /// outside caster, whose own size is unknown, its kd-tree's); 0 for a
    /// scene file.
    pub fn bytes(&self) -> usize {
        match self {
            Caster::Bvh { bvh, .. } => bvh.stats().bytes,
            Caster::KdTree(tree) | Caster::Outside { tree, .. } => tree.stats().bytes,
            Caster::OutOfCore(_) => 0,
        }
    }

    /// Whether first hits are found [`PACKET`] rays at a time.
    #[inline]
    pub(super) fn packets(&self) -> bool {
        matches!(self, Caster::Bvh { .. } | Caster::KdTree(_))
    }

    /// The nearest in-core hit of a single ray (`None` for a scene file).
    #[inline]
    pub(super) fn intersect(&self, ray: &Ray) -> Option<Hit> {
        match self {
            Caster::Bvh { bvh, .. } => bvh.intersect(ray),
            Caster::KdTree(tree) => tree.intersect(ray),
            Caster::Outside { caster, .. } => cast_outside(caster.as_ref(), ray),
            Caster::OutOfCore(_) => None,
        }
    }

    /// The nearest hits of up to [`PACKET`] rays, found together where the
    /// caster casts packets and one by one otherwise.
    #[inline]
    pub(super) fn intersect_packet(&self, rays: &[Ray]) -> [Option<Hit>; PACKET] {
        match self {
            Caster::Bvh { bvh, .. } => bvh.intersect_packet(rays),
            Caster::KdTree(tree) => tree.intersect_packet(rays),
            _ => {
                let mut out = [None; PACKET];
                for (o, r) in out.iter_mut().zip(rays) {
                    *o = self.intersect(r);
                }
                out
            }
        }
    }

    /// Whether anything lies within `(0, ray.t_max)` in core (false for a
    /// scene file).
    #[inline]
    pub(super) fn occluded(&self, ray: &Ray) -> bool {
        self.occluded_by(ray, |_| true)
    }

    /// True if a triangle for which `blocks(triangle)` is true lies within
    /// `(0, ray.t_max)` in core; the others are looked past (false for a
    /// scene file).
    #[inline(always)]
    pub(super) fn occluded_by(&self, ray: &Ray, mut blocks: impl FnMut(u32) -> bool) -> bool {
        match self {
            Caster::Bvh { bvh, .. } => bvh.occluded_by(ray, blocks),
            Caster::KdTree(tree) => tree.occluded_by(ray, blocks),
            Caster::Outside { caster, .. } => occluded_outside(caster.as_ref(), ray, &mut blocks),
            Caster::OutOfCore(_) => false,
        }
    }

    /// `f` of every ray, called in `order` (by the kd-tree's coarse grid;
    /// as given for a scene file), returned in the rays' order.
    pub(super) fn in_order<T: Default + Clone>(
        &self,
        rays: &[Ray],
        order: RayOrder,
        f: impl FnMut(&Ray) -> T,
    ) -> Vec<T> {
        match self.tree() {
            Some(tree) => tree.in_order(rays, order, f),
            None => rays.iter().map(f).collect(),
        }
    }
}

/// An outside caster's nearest hit: out of line and cold, so that the
/// casters of our own keep their walks inlined in the match.
#[cold]
#[inline(never)]
fn cast_outside(caster: &dyn RayCaster, ray: &Ray) -> Option<Hit> {
    caster.intersect(ray)
}

/// An outside caster's filtered occlusion query, out of line and cold.
#[cold]
#[inline(never)]
fn occluded_outside(caster: &dyn RayCaster, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool {
    caster.occluded_by(ray, blocks)
}
