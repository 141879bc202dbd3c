//! Scenes: triangles in world space with materials, a sky, and the holodeck
//! sections that look at them. Import (`import`), generation (`gen`), the TOML
//! scene file (`file`, `section`), writing scenes out (`export`) and the
//! content hash live here; nothing here traces rays.

pub mod builder;
pub mod calc;
pub mod export;
pub mod file;
pub mod gen;
pub mod hash;
pub mod import;
pub mod maps;
pub mod material;
pub mod pattern;
pub mod section;
pub mod section_fit;
pub mod sky_distribution;
pub mod texture;

use glam::{Vec2, Vec3, Vec4};
use holodeck_protocol::Section;

pub use builder::{ImportStats, SceneBuilder};
pub use export::write_scene;
pub use file::load_scene;
pub use gen::{generate, GenParams};
pub use hash::content_hash;
pub use import::{import_file, import_file_with, ImportOptions, UpAxis};
pub use maps::MaterialMaps;
pub use material::{Material, Sky};
pub use texture::{Texture, TextureSet};

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
    /// Texture coordinates by vertex (parallel to [`Scene::positions`]), or
    /// empty when no mesh has any. glTF's convention: v grows downward.
    pub uvs: Vec<Vec2>,
    /// Tangents by vertex (xyz, and w: +1 or -1, the bitangent's side, as
    /// glTF gives them), or empty; a zero tangent means none (generated from
    /// the texture coordinates where a normal map needs one).
    pub tangents: Vec<Vec4>,
    /// The images materials use, each once.
    pub textures: TextureSet,
    /// Each material's textures, by material index (missing entries: none).
    pub maps: Vec<MaterialMaps>,
    /// What import dropped or approximated, per file and material.
    pub notes: Vec<ImportNote>,
}

/// One thing an importer dropped or approximated.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ImportNote {
    /// The file.
    pub file: String,
    /// The material concerned, if one.
    pub material: Option<String>,
    /// What was dropped or approximated, and what was used instead.
    pub what: String,
}

impl std::fmt::Display for ImportNote {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match &self.material {
            Some(m) => write!(f, "{}: material {m:?}: {}", self.file, self.what),
            None => write!(f, "{}: {}", self.file, self.what),
        }
    }
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

    /// The textures of material `m` (`None` when it has none).
    #[inline]
    pub fn maps_of(&self, m: u32) -> Option<&MaterialMaps> {
        self.maps.get(m as usize).filter(|maps| !maps.is_empty())
    }

    /// Tangents of triangle `t`'s vertices, where it has them all.
    #[inline]
    pub fn triangle_tangents(&self, t: usize) -> Option<[Vec4; 3]> {
        let v = self.triangles[t].v;
        let tangents = v.map(|i| self.tangents.get(i as usize).copied().unwrap_or(Vec4::ZERO));
        tangents.iter().all(|t| t.w != 0.0).then_some(tangents)
    }

    /// Texture coordinates of triangle `t`'s vertices (zero without UVs).
    #[inline]
    pub fn triangle_uvs(&self, t: usize) -> [Vec2; 3] {
        let v = self.triangles[t].v;
        if self.uvs.is_empty() {
            return [Vec2::ZERO; 3];
        }
        v.map(|i| self.uvs.get(i as usize).copied().unwrap_or(Vec2::ZERO))
    }

    /// Replaces every textured material by its texture's mean (colour,
    /// roughness) and drops texture coordinates, maps and images, for
    /// stores that keep no textures; alpha-masked surfaces become solid.
    /// Returns whether there was anything to drop.
    pub fn bake_textures(&mut self) -> bool {
        if self.maps.iter().all(|m| m.is_empty()) && self.uvs.is_empty() {
            return false;
        }
        for (m, maps) in self.materials.iter_mut().zip(&self.maps) {
            if !maps.is_empty() && maps.pbr.is_none() {
                *m = maps.material_at(m, &self.textures, Vec2::splat(0.5), f32::MAX);
            }
            // A diffuse surface keeps the mean of what it glows with.
            if let (Some((factor, mean)), Material::Lambertian { emission, .. }) =
                (maps.emissive_parts(&self.textures), &mut *m)
            {
                *emission = (Vec3::from_array(*emission) + factor * mean).to_array();
            }
        }
        self.maps.clear();
        self.uvs = Vec::new();
        self.tangents = Vec::new();
        self.textures = TextureSet::new();
        true
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
