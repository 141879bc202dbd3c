//! A hit as shading needs it: where, which triangle (or voxel), its
//! material and the numbers texture lookups need.

use glam::{Vec2, Vec3};

/// A hit as shading needs it.
#[derive(Clone, Copy)]
pub(super) struct SurfaceHit {
    pub(super) t: f32,
    /// Unit geometric normal.
    pub(super) ng: Vec3,
    /// Triangle id (for light pdfs); `u32::MAX` for a voxel.
    pub(super) tri: u32,
    /// Barycentric weights of the triangle's vertices 1 and 2 (texture lookups).
    pub(super) bary: Vec2,
    /// The triangle's vertices (texture footprints and tangents; zero for a voxel).
    pub(super) verts: [Vec3; 3],
    /// Material index, or `None` for a voxel (a diffuse proxy of `color`).
    pub(super) material: Option<u32>,
    pub(super) color: Vec3,
    /// Voxel radius (0 for triangles): later rays start beyond the voxel.
    pub(super) radius: f32,
}
