//! Assembling a [`Scene`] from meshes, with the validation every importer and
//! generator shares: non-finite vertices and degenerate triangles are skipped
//! and counted; out-of-range indices and bad materials are errors.

use std::collections::HashMap;

use glam::{Mat4, Vec2, Vec3, Vec4};
use holodeck_protocol::Section;

use super::maps::MaterialMaps;
use super::material::{Material, Sky};
use super::texture::TextureSet;
use super::{ImportNote, Scene, Triangle};
use crate::error::SceneError;

/// Most triangles one in-core scene may hold: keeps kd-tree node and
/// reference indices (30 and 32 bits) far from overflow.
pub const MAX_TRIANGLES: usize = 1 << 28;

/// What import skipped and kept, for reports.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ImportStats {
    /// Meshes added.
    pub meshes: u64,
    /// Triangles kept.
    pub triangles: u64,
    /// Triangles skipped for zero area.
    pub degenerate: u64,
    /// Triangles skipped for a NaN or infinite vertex.
    pub non_finite: u64,
    /// Meshes with no triangles.
    pub empty_meshes: u64,
}

/// Builds a scene mesh by mesh.
#[derive(Default)]
pub struct SceneBuilder {
    scene: Scene,
    by_name: HashMap<String, u32>,
}

impl SceneBuilder {
    /// An empty scene.
    pub fn new() -> SceneBuilder {
        SceneBuilder::default()
    }

    /// Adds a named material (validated) and returns its index; a name added
    /// again returns the existing index if the parameters agree, else an error.
    pub fn material(&mut self, name: &str, m: Material) -> Result<u32, SceneError> {
        self.material_with_maps(name, m, MaterialMaps::default())
    }

    /// [`SceneBuilder::material`] with textures; a name added again must
    /// agree on them too.
    pub fn material_with_maps(&mut self, name: &str, m: Material, maps: MaterialMaps) -> Result<u32, SceneError> {
        m.validate().map_err(|source| SceneError::BadMaterial {
            name: name.to_string(),
            source,
        })?;
        if let Some(&id) = self.by_name.get(name) {
            if self.scene.materials[id as usize] != m || self.scene.maps[id as usize] != maps {
                return Err(SceneError::MaterialRedefined(name.to_string()));
            }
            return Ok(id);
        }
        let id = self.scene.materials.len() as u32;
        self.scene.materials.push(m);
        self.scene.maps.push(maps);
        self.scene.material_names.push(name.to_string());
        self.by_name.insert(name.to_string(), id);
        Ok(id)
    }

    /// The index of a material added earlier.
    pub fn material_id(&self, name: &str) -> Option<u32> {
        self.by_name.get(name).copied()
    }

    /// Gives material `id` (added earlier) the textures `maps`.
    pub fn set_maps(&mut self, id: u32, maps: MaterialMaps) {
        if let Some(m) = self.scene.maps.get_mut(id as usize) {
            *m = maps;
        }
    }

    /// The textures of material `id` (default for one without).
    pub fn material_maps(&self, id: u32) -> Option<&MaterialMaps> {
        self.scene.maps.get(id as usize)
    }

    /// The scene's textures, to load into.
    pub fn textures(&mut self) -> &mut TextureSet {
        &mut self.scene.textures
    }

    /// Notes that `file` (and `material`, if given) had something dropped
    /// or approximated, as `what` says.
    pub fn note(&mut self, file: &str, material: Option<&str>, what: impl Into<String>) {
        let note = ImportNote {
            file: file.to_string(),
            material: material.map(str::to_string),
            what: what.into(),
        };
        if !self.scene.notes.contains(&note) {
            tracing::debug!("{note}");
            self.scene.notes.push(note);
        }
    }

    /// Adds a mesh: `positions` transformed by `transform`, `triangles` indexing
    /// them, `materials` one per triangle (or a single entry for all). `source`
    /// names the mesh in errors and logs.
    pub fn add_mesh(
        &mut self,
        source: &str,
        positions: &[Vec3],
        triangles: &[[u32; 3]],
        materials: &[u32],
        transform: Mat4,
    ) -> Result<(), SceneError> {
        self.add_mesh_uv(source, positions, None, triangles, materials, transform)
    }

    /// [`SceneBuilder::add_mesh`] with texture coordinates by vertex
    /// (glTF's convention, v downward), as many as `positions`; non-finite
    /// ones read as 0.
    pub fn add_mesh_uv(
        &mut self,
        source: &str,
        positions: &[Vec3],
        uvs: Option<&[Vec2]>,
        triangles: &[[u32; 3]],
        materials: &[u32],
        transform: Mat4,
    ) -> Result<(), SceneError> {
        if let Some(uvs) = uvs {
            if uvs.len() != positions.len() {
                return Err(SceneError::Invalid {
                    what: source.to_string(),
                    message: format!("{} texture coordinates for {} vertices", uvs.len(), positions.len()),
                });
            }
        }
        if triangles.is_empty() {
            self.scene.stats.empty_meshes += 1;
            tracing::warn!("{source}: mesh has no triangles; skipped");
            return Ok(());
        }
        self.check_room(source, triangles.len())?;
        if materials.len() != 1 && materials.len() != triangles.len() {
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message: format!("{} material indices for {} triangles", materials.len(), triangles.len()),
            });
        }
        for &m in materials {
            if m as usize >= self.scene.materials.len() {
                return Err(SceneError::Invalid {
                    what: source.to_string(),
                    message: format!(
                        "material index {m} but only {} materials exist",
                        self.scene.materials.len()
                    ),
                });
            }
        }
        let base = self.scene.positions.len();
        let count = u32::try_from(base + positions.len()).map_err(|_| SceneError::Invalid {
            what: source.to_string(),
            message: "more than 4 billion vertices".to_string(),
        })?;
        let _ = count;
        self.extend_uvs(base, positions.len(), uvs.map(|u| u.iter().copied()));
        if transform == Mat4::IDENTITY {
            // Bit-exact: a written-out scene reads back with the same content hash.
            self.scene.positions.extend_from_slice(positions);
        } else {
            self.scene
                .positions
                .extend(positions.iter().map(|p| transform.transform_point3(*p)));
        }
        let world = &self.scene.positions[base..];
        let (mut degenerate, mut non_finite) = (0u64, 0u64);
        for (k, t) in triangles.iter().enumerate() {
            if let Some(&bad) = t.iter().find(|&&i| i as usize >= positions.len()) {
                self.scene.positions.truncate(base);
                self.scene.uvs.truncate(base.min(self.scene.uvs.len()));
                return Err(SceneError::Invalid {
                    what: source.to_string(),
                    message: format!(
                        "triangle {k} uses vertex {bad}, but the mesh has {} vertices",
                        positions.len()
                    ),
                });
            }
            let [a, b, c] = t.map(|i| world[i as usize]);
            if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                non_finite += 1;
                continue;
            }
            let area2 = (b - a).cross(c - a).length();
            if !(area2.is_finite() && area2 > 0.0) {
                degenerate += 1;
                continue;
            }
            let material = if materials.len() == 1 {
                materials[0]
            } else {
                materials[k]
            };
            self.scene.triangles.push(Triangle {
                v: t.map(|i| i + base as u32),
                material,
            });
        }
        if degenerate + non_finite > 0 {
            tracing::warn!("{source}: skipped {degenerate} degenerate and {non_finite} non-finite triangles");
        }
        let stats = &mut self.scene.stats;
        stats.meshes += 1;
        stats.degenerate += degenerate;
        stats.non_finite += non_finite;
        stats.triangles += triangles.len() as u64 - degenerate - non_finite;
        Ok(())
    }

    /// The parameters of material `id`, if it exists.
    pub fn material_params(&self, id: u32) -> Option<&Material> {
        self.scene.materials.get(id as usize)
    }

    /// Vertices added so far.
    pub fn vertex_count(&self) -> usize {
        self.scene.positions.len()
    }

    /// Triangles kept so far.
    pub fn triangle_count(&self) -> usize {
        self.scene.triangles.len()
    }

    /// Names of all materials so far, in index order, comma-separated (for errors).
    pub fn material_list(&self) -> String {
        self.scene.material_names.join(", ")
    }

    /// Adds a mesh already in world space, taking ownership so that very large
    /// generated meshes are not copied when the scene is still empty. Triangle
    /// indices are local to `positions`; materials must already exist. Validation
    /// (the same as [`SceneBuilder::add_mesh`]) runs in parallel.
    pub fn add_world_mesh(
        &mut self,
        source: &str,
        positions: Vec<Vec3>,
        triangles: Vec<Triangle>,
    ) -> Result<(), SceneError> {
        self.add_world_mesh_uv(source, positions, None, triangles)
    }

    /// [`SceneBuilder::add_world_mesh`] with texture coordinates by vertex
    /// (as many as `positions`).
    pub fn add_world_mesh_uv(
        &mut self,
        source: &str,
        positions: Vec<Vec3>,
        uvs: Option<Vec<Vec2>>,
        mut triangles: Vec<Triangle>,
    ) -> Result<(), SceneError> {
        use rayon::prelude::*;
        if uvs.as_ref().is_some_and(|uvs| uvs.len() != positions.len()) {
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message: "texture coordinates and vertices differ in number".to_string(),
            });
        }
        if triangles.is_empty() {
            self.scene.stats.empty_meshes += 1;
            tracing::warn!("{source}: mesh has no triangles; skipped");
            return Ok(());
        }
        self.check_room(source, triangles.len())?;
        let base = self.scene.positions.len();
        if u32::try_from(base + positions.len()).is_err() {
            let message = "more than 4 billion vertices".to_string();
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message,
            });
        }
        let materials = self.scene.materials.len();
        let n = positions.len();
        let bad = triangles
            .par_iter()
            .position_first(|t| t.v.iter().any(|&i| i as usize >= n));
        if let Some(k) = bad {
            let message = format!(
                "triangle {k} uses vertex {:?}, but the mesh has {n} vertices",
                triangles[k].v
            );
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message,
            });
        }
        if let Some(t) = triangles.par_iter().find_any(|t| t.material as usize >= materials) {
            let message = format!("material index {} but only {materials} materials exist", t.material);
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message,
            });
        }
        // 0 = keep, 1 = degenerate, 2 = non-finite.
        let verdict: Vec<u8> = triangles
            .par_iter()
            .map(|t| {
                let [a, b, c] = t.v.map(|i| positions[i as usize]);
                if !(a.is_finite() && b.is_finite() && c.is_finite()) {
                    return 2;
                }
                let area2 = (b - a).cross(c - a).length();
                u8::from(!(area2.is_finite() && area2 > 0.0))
            })
            .collect();
        let non_finite = verdict.par_iter().filter(|&&v| v == 2).count() as u64;
        let degenerate = verdict.par_iter().filter(|&&v| v == 1).count() as u64;
        if degenerate + non_finite > 0 {
            let mut k = 0;
            triangles.retain(|_| {
                k += 1;
                verdict[k - 1] == 0
            });
            tracing::warn!("{source}: skipped {degenerate} degenerate and {non_finite} non-finite triangles");
        }
        drop(verdict);
        let offset = base as u32;
        if offset > 0 {
            triangles.par_iter_mut().for_each(|t| t.v = t.v.map(|i| i + offset));
        }
        let kept = triangles.len() as u64;
        self.extend_uvs(base, positions.len(), uvs.map(Vec::into_iter));
        if self.scene.positions.is_empty() {
            self.scene.positions = positions;
        } else {
            self.scene.positions.extend_from_slice(&positions);
        }
        if self.scene.triangles.is_empty() {
            self.scene.triangles = triangles;
        } else {
            self.scene.triangles.extend_from_slice(&triangles);
        }
        let stats = &mut self.scene.stats;
        stats.meshes += 1;
        stats.degenerate += degenerate;
        stats.non_finite += non_finite;
        stats.triangles += kept;
        Ok(())
    }

    /// Gives the `n` vertices from `base` on the texture coordinates `uvs`
    /// (non-finite ones read as 0), or zeros where the scene has some and
    /// the mesh none.
    fn extend_uvs(&mut self, base: usize, n: usize, uvs: Option<impl Iterator<Item = Vec2>>) {
        if uvs.is_none() && self.scene.uvs.is_empty() {
            return;
        }
        self.scene.uvs.resize(base, Vec2::ZERO);
        match uvs {
            Some(uvs) => self
                .scene
                .uvs
                .extend(uvs.map(|uv| if uv.is_finite() { uv } else { Vec2::ZERO })),
            None => self.scene.uvs.resize(base + n, Vec2::ZERO),
        }
    }

    /// Refuses meshes that would take the scene past [`MAX_TRIANGLES`].
    fn check_room(&self, source: &str, more: usize) -> Result<(), SceneError> {
        if self.scene.triangles.len().saturating_add(more) > MAX_TRIANGLES {
            return Err(SceneError::Invalid {
                what: source.to_string(),
                message: format!(
                    "the scene would exceed {MAX_TRIANGLES} triangles, the most an in-core scene may hold"
                ),
            });
        }
        Ok(())
    }

    /// Sets the sky, once it is checked.
    pub fn sky(&mut self, sky: Sky) -> Result<(), SceneError> {
        sky.validate().map_err(|source| SceneError::BadSky {
            what: "sky".to_string(),
            source,
        })?;
        self.scene.sky = sky;
        Ok(())
    }

    /// The sky set so far ([`Sky::None`] until one is set).
    pub fn current_sky(&self) -> &Sky {
        &self.scene.sky
    }

    /// Adds a holodeck section.
    pub fn section(&mut self, s: Section) {
        self.scene.sections.push(s);
    }

    /// Gives the vertices from `first` on (those of the mesh just added,
    /// before `transform`) the tangents `tangents` (xyz, w the bitangent's
    /// side), turned into the scene's frame; non-finite or zero ones are left out.
    pub fn set_tangents(&mut self, first: usize, tangents: &[Vec4], transform: Mat4) {
        let mirror = transform.determinant() < 0.0;
        if first + tangents.len() > self.scene.positions.len() {
            return;
        }
        self.scene.tangents.resize(first, Vec4::ZERO);
        self.scene.tangents.extend(tangents.iter().map(|t| {
            let xyz = transform.transform_vector3(t.truncate());
            match xyz.try_normalize() {
                Some(d) if t.w.is_finite() && t.w != 0.0 => {
                    let w = if (t.w < 0.0) != mirror { -1.0 } else { 1.0 };
                    d.extend(w)
                }
                _ => Vec4::ZERO,
            }
        }));
    }

    /// The finished scene.
    pub fn finish(mut self) -> Scene {
        if !self.scene.tangents.is_empty() {
            let n = self.scene.positions.len();
            self.scene.tangents.resize(n, Vec4::ZERO);
        }
        if !self.scene.uvs.is_empty() {
            let n = self.scene.positions.len();
            self.scene.uvs.resize(n, Vec2::ZERO);
        }
        self.scene
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::material::MaterialError;

    #[test]
    fn skips_bad_triangles_and_refuses_bad_indices() {
        let mut b = SceneBuilder::new();
        let m = b.material("white", Material::lambertian([0.8; 3])).unwrap();
        assert_eq!(b.material("white", Material::lambertian([0.8; 3])).unwrap(), m);
        assert!(matches!(
            b.material("white", Material::lambertian([0.5; 3])),
            Err(SceneError::MaterialRedefined(name)) if name == "white"
        ));
        assert!(matches!(
            b.material("hot", Material::lambertian([2.0; 3])),
            Err(SceneError::BadMaterial {
                source: MaterialError::NotUnit { key: "albedo", .. },
                ..
            })
        ));
        let p = [
            Vec3::ZERO,
            Vec3::X,
            Vec3::Y,
            Vec3::new(f32::NAN, 0.0, 0.0),
            Vec3::X * 2.0,
        ];
        let tris = [[0, 1, 2], [0, 1, 4], [0, 1, 3], [2, 1, 0]];
        b.add_mesh("test", &p, &tris, &[m], Mat4::from_translation(Vec3::Z))
            .unwrap();
        let err = b
            .add_mesh("broken", &p, &[[0, 1, 9]], &[m], Mat4::IDENTITY)
            .unwrap_err();
        assert!(err.to_string().contains("triangle 0 uses vertex 9"), "{err}");
        b.add_mesh("empty", &p, &[], &[m], Mat4::IDENTITY).unwrap();
        let s = b.finish();
        assert_eq!(s.triangles.len(), 2);
        assert_eq!(
            (s.stats.degenerate, s.stats.non_finite, s.stats.empty_meshes),
            (1, 1, 1)
        );
        assert_eq!(s.positions.len(), 5, "the broken mesh's vertices are not kept");
        assert_eq!(s.vertices(0)[0], Vec3::Z);
    }
}
