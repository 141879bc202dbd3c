//! Scenes: triangles in world space with materials, a sky, and the holodeck
//! sections that look at them. Import (`import`), generation (`gen`), the TOML
//! scene file (`file`, `section`), writing scenes out (`export`) and the
//! content hash live here; nothing here traces rays.

pub mod builder;
pub mod export;
pub mod file;
pub mod gen;
pub mod hash;
pub mod import;
pub mod material;
pub mod section;

use glam::Vec3;
use holodeck_protocol::Section;

pub use builder::{ImportStats, SceneBuilder};
pub use export::write_scene;
pub use file::load_scene;
pub use gen::{generate, GenParams};
pub use hash::content_hash;
pub use import::{import_file, import_file_with, ImportOptions, UpAxis};
pub use material::{Material, Sky};

/// One triangle: three indices into [`Scene::positions`] and a material index.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Triangle {
    /// Vertex indices, counter-clockwise seen from the front.
    pub v: [u32; 3],
    /// Index into [`Scene::materials`].
    pub material: u32,
}

/// A scene ready to trace: world-space triangles (f32), materials, sky, sections.
#[derive(Clone, Debug, Default)]
pub struct Scene {
    /// Vertex positions, world space.
    pub positions: Vec<Vec3>,
    /// Triangles; every index is valid and no triangle is degenerate or NaN.
    pub triangles: Vec<Triangle>,
    /// Materials by index.
    pub materials: Vec<Material>,
    /// Material names by index (for reports and errors).
    pub material_names: Vec<String>,
    /// What rays that escape see.
    pub sky: Sky,
    /// Holodeck sections defined with the scene (may be empty).
    pub sections: Vec<Section>,
    /// What import skipped, and why.
    pub stats: ImportStats,
}

impl Scene {
    /// The three vertex positions of triangle `t`.
    #[inline]
    pub fn vertices(&self, t: usize) -> [Vec3; 3] {
        let v = self.triangles[t].v;
        [
            self.positions[v[0] as usize],
            self.positions[v[1] as usize],
            self.positions[v[2] as usize],
        ]
    }

    /// Axis-aligned bounds of all triangles (min, max); zero-size for an empty scene.
    pub fn bounds(&self) -> (Vec3, Vec3) {
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for t in &self.triangles {
            for &i in &t.v {
                let p = self.positions[i as usize];
                lo = lo.min(p);
                hi = hi.max(p);
            }
        }
        if self.triangles.is_empty() {
            (Vec3::ZERO, Vec3::ZERO)
        } else {
            (lo, hi)
        }
    }
}
