//! The interface every in-core ray caster offers: the kd-tree, the wide
//! BVH and Embree (feature `embree`) are siblings behind it. The path
//! tracer dispatches over them by `shade::Caster`, so that our own walks
//! stay inlined; another library's hierarchy enters through this trait
//! alone (`holodeck bench tracer --embree` traces the same paths through
//! Embree to compare whole path tracing, not just ray casts).

use super::{Hit, KdTree, WideBvh};
use crate::geom::Ray;

/// Single-ray queries a tracer needs of its scene's triangles (indices as
/// in the scene), from any thread.
pub trait RayCaster: Send + Sync {
    /// The nearest hit within `(0, ray.t_max]`.
    fn intersect(&self, ray: &Ray) -> Option<Hit>;

    /// True if a triangle for which `blocks(triangle)` is true lies within
    /// `(0, ray.t_max)`; triangles that do not block are passed to
    /// `blocks` and looked past.
    fn occluded_by(&self, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool;
}

impl RayCaster for WideBvh {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        WideBvh::intersect(self, ray)
    }

    fn occluded_by(&self, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool {
        WideBvh::occluded_by(self, ray, blocks)
    }
}

impl RayCaster for KdTree {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        KdTree::intersect(self, ray)
    }

    fn occluded_by(&self, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool {
        KdTree::occluded_by(self, ray, blocks)
    }
}
