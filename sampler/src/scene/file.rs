//! The TOML scene file: named materials, a sky, geometry files with
//! transforms, built-in generated scenes, and holodeck sections. Paths in it
//! are relative to the file. Every table refuses unknown keys, and every error
//! names the file and what in it is wrong.
//!
//! Materials are added in the order they are written, before anything else, so
//! they override same-named materials of OBJ/MTL and glTF files and of
//! built-in scenes. The sky is the file's `[sky]`, else one a geometry file
//! brings (the distant sources of a Radiance file), else the first builtin's;
//! the sections are the file's `[[section]]` tables, else the builtins'.

pub use crate::error::TransformError;
use std::collections::HashMap;
use std::fmt;
use std::path::{Path, PathBuf};

use glam::{EulerRot, Mat4, Quat, Vec3};
use serde::de::{MapAccess, Visitor};
use serde::{Deserialize, Deserializer, Serialize};

use super::builder::SceneBuilder;
use super::gen::{self, GenParams};
use super::import::{import_file_with, ImportOptions, UpAxis};
use super::material::{Material, Sky};
use super::Scene;
pub use textures::{write_textures, TextureEntry, WrapMode};

mod textures;
use crate::error::SceneError;
use holodeck_protocol::SectionSpec;

/// A whole scene file.
#[derive(Clone, Debug, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SceneFile {
    /// What escaping rays see (default: the first builtin's, else none).
    #[serde(default)]
    pub sky: Option<Sky>,
    /// Named materials, in file order.
    #[serde(default)]
    pub materials: NamedMaterials,
    /// Textures of named materials, in file order.
    #[serde(default)]
    pub textures: Named<TextureEntry>,
    /// Geometry files.
    #[serde(default)]
    pub geometry: Vec<GeometryEntry>,
    /// Built-in generated scenes merged in.
    #[serde(default)]
    pub builtin: Vec<BuiltinEntry>,
    /// Holodeck sections.
    #[serde(default)]
    pub section: Vec<SectionSpec>,
}

/// `[materials.NAME]` or `[textures.NAME]` tables in the order written
/// (so material and texture ids are stable).
#[derive(Clone, Debug, PartialEq)]
pub struct Named<T>(pub Vec<(String, T)>);

impl<T> Default for Named<T> {
    fn default() -> Self {
        Named(Vec::new())
    }
}

/// `[materials.NAME]` tables in the order written.
pub type NamedMaterials = Named<Material>;

impl<'de, T: Deserialize<'de>> Deserialize<'de> for Named<T> {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct Ordered<T>(std::marker::PhantomData<T>);
        impl<'de, T: Deserialize<'de>> Visitor<'de> for Ordered<T> {
            type Value = Named<T>;
            fn expecting(&self, f: &mut fmt::Formatter) -> fmt::Result {
                f.write_str("a table of named tables")
            }
            fn visit_map<A: MapAccess<'de>>(self, mut map: A) -> Result<Named<T>, A::Error> {
                let mut out = Vec::new();
                while let Some((name, m)) = map.next_entry::<String, T>()? {
                    out.push((name, m));
                }
                Ok(Named(out))
            }
        }
        d.deserialize_map(Ordered(std::marker::PhantomData))
    }
}

/// A `[[geometry]]` table: one file placed in the scene.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GeometryEntry {
    /// The file (.obj, .ply, .gltf, .glb, .rad), relative to the scene file.
    pub file: PathBuf,
    /// Material for faces the file gives none.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub material: Option<String>,
    /// Materials that a PLY file's per-face `material_index` values index.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub materials: Vec<String>,
    /// Translation, meters (applied last).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub translate: Option<[f32; 3]>,
    /// Rotation in degrees about x, then y, then z.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rotate: Option<[f32; 3]>,
    /// Scale (applied first): one factor or one per axis.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<Scale>,
    /// The file's up axis, `"y"` or `"z"`: the file is turned +z up before
    /// scale, rotate and translate apply. Default: y for glTF/GLB, z for the rest.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub up: Option<UpAxis>,
    /// A 4×4 affine matrix, row-major (translation in the last column), as
    /// converters write an object's placement: applied after the up axis,
    /// before scale, rotate and translate.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub matrix: Option<[[f32; 4]; 4]>,
}

/// A uniform or per-axis scale.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Scale {
    /// The same factor on every axis.
    Uniform(f32),
    /// One factor per axis.
    Axes([f32; 3]),
}

impl GeometryEntry {
    /// Scale, then rotate about x, y, z, then translate; an error names the bad key.
    pub fn transform(&self) -> Result<Mat4, TransformError> {
        let scale = match self.scale {
            None => Vec3::ONE,
            Some(Scale::Uniform(s)) => Vec3::splat(s),
            Some(Scale::Axes(a)) => Vec3::from(a),
        };
        if !scale.is_finite() || scale.x * scale.y * scale.z == 0.0 {
            return Err(TransformError::Scale(scale));
        }
        let rotate = Vec3::from(self.rotate.unwrap_or([0.0; 3]));
        let translate = Vec3::from(self.translate.unwrap_or([0.0; 3]));
        if !rotate.is_finite() {
            return Err(TransformError::Rotate(rotate));
        }
        if !translate.is_finite() {
            return Err(TransformError::Translate(translate));
        }
        let r = rotate * (std::f32::consts::PI / 180.0);
        // Extrinsic x, then y, then z is the intrinsic z-y-x rotation.
        let q = Quat::from_euler(EulerRot::ZYX, r.z, r.y, r.x);
        let placed = Mat4::from_scale_rotation_translation(scale, q, translate);
        Ok(match &self.matrix {
            Some(rows) => placed * matrix(rows)?,
            None => placed,
        })
    }
}

/// The transform a row-major 4×4 `matrix` gives, refused where it is not
/// finite, not affine or not invertible.
fn matrix(rows: &[[f32; 4]; 4]) -> Result<Mat4, TransformError> {
    if rows.iter().flatten().any(|v| !v.is_finite()) {
        return Err(TransformError::Matrix("must hold finite numbers"));
    }
    if rows[3] != [0.0, 0.0, 0.0, 1.0] {
        let column_major = rows[0][3] == 0.0 && rows[1][3] == 0.0 && rows[2][3] == 0.0 && rows[3][3] == 1.0;
        return Err(TransformError::Matrix(if column_major {
            "has its translation in the last row: it is written column-major; give it row-major (transposed)"
        } else {
            "must be affine: its last row must be [0, 0, 0, 1]"
        }));
    }
    // glam's matrices are column-major: the rows given are its transpose's columns.
    let m = Mat4::from_cols_array_2d(rows).transpose();
    let det = m.determinant();
    if !(det.is_finite() && det.abs() > 1e-12) {
        return Err(TransformError::Matrix("is singular: it flattens the geometry"));
    }
    Ok(m)
}

/// A `[[builtin]]` table: a generated scene merged in.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct BuiltinEntry {
    /// room, landscape, mandelbulb or bunny.
    pub name: String,
    /// Target triangle count (landscape).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub triangles: Option<u64>,
    /// Grid resolution (mandelbulb).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub resolution: Option<u32>,
    /// Random seed (default 0).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seed: Option<u64>,
    /// A bunny OBJ, relative to the scene file, instead of the built-in one.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bunny: Option<PathBuf>,
}

/// Parses scene file text; `path` is only for error messages.
pub fn parse_scene_file(text: &str, path: &Path) -> Result<SceneFile, SceneError> {
    toml::from_str(text).map_err(|e| SceneError::Parse {
        path: path.to_path_buf(),
        message: e.to_string(),
    })
}

/// Reads the scene file at `path` and builds its scene: geometry files are
/// found relative to it. A Radiance scene file (`.rad`) is a scene of its
/// own: its surfaces, materials and sources, with no sections.
pub fn load_scene(path: &Path) -> Result<Scene, SceneError> {
    let is_rad = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("rad"));
    let file = if is_rad {
        SceneFile {
            geometry: vec![GeometryEntry {
                file: path.file_name().map(PathBuf::from).unwrap_or_default(),
                ..GeometryEntry::default()
            }],
            ..SceneFile::default()
        }
    } else {
        check_scene_file(path)?;
        let text = std::fs::read_to_string(path).map_err(|source| SceneError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        parse_scene_file(&text, path)?
    };
    let base = path.parent().unwrap_or(Path::new(""));
    let at = |what: String, e: SceneError| SceneError::Invalid {
        what: format!("{}: {what}", path.display()),
        message: e.to_string(),
    };

    let mut b = SceneBuilder::new();
    let mut overrides = HashMap::new();
    for (name, m) in &file.materials.0 {
        let id = b
            .material(name, m.clone())
            .map_err(|e| at(format!("[materials.{name}]"), e))?;
        overrides.insert(name.clone(), id);
    }
    for (name, entry) in &file.textures.0 {
        let what = format!("{}: [textures.{name}]", path.display());
        let Some(&id) = overrides.get(name) else {
            return Err(SceneError::UnknownMaterial {
                what,
                name: name.clone(),
                known: b.material_list(),
            });
        };
        let maps = entry.maps(&mut b, base, &what)?;
        b.set_maps(id, maps);
    }
    let mut settings = Vec::new();
    for entry in &file.builtin {
        if !gen::NAMES.contains(&entry.name.as_str()) {
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                message: format!(
                    "[[builtin]] name {:?} is not one of {}",
                    entry.name,
                    gen::NAMES.join(", ")
                ),
            });
        }
        let params = GenParams {
            triangles: entry.triangles,
            resolution: entry.resolution,
            seed: entry.seed.unwrap_or(0),
            bunny_path: entry.bunny.as_ref().map(|p| base.join(p)),
        };
        let setting =
            gen::add(&entry.name, &params, &mut b).map_err(|e| at(format!("[[builtin]] {:?}", entry.name), e))?;
        settings.push(setting);
    }
    for (k, g) in file.geometry.iter().enumerate() {
        let what = format!("{}: [[geometry]] {} ({})", path.display(), k + 1, g.file.display());
        let id = |name: &String| {
            b.material_id(name).ok_or_else(|| SceneError::UnknownMaterial {
                what: what.clone(),
                name: name.clone(),
                known: b.material_list(),
            })
        };
        let default_material = g.material.as_ref().map(id).transpose()?;
        let face_materials = g.materials.iter().map(id).collect::<Result<Vec<u32>, _>>()?;
        let transform = g.transform().map_err(|source| SceneError::Transform {
            what: what.clone(),
            source,
        })?;
        let options = ImportOptions {
            default_material,
            overrides: Some(&overrides),
            face_materials: &face_materials,
            up: g.up,
        };
        import_file_with(&mut b, &base.join(&g.file), transform, &options)?;
    }
    // A geometry file's own sky (Radiance sources) comes after `[sky]` and
    // before a builtin's.
    let imported = b.current_sky().clone();
    let sky = match (&file.sky, settings.first()) {
        (Some(sky), _) => sky.clone(),
        _ if imported != Sky::None => imported,
        (None, Some(s)) => s.sky.clone(),
        (None, None) => Sky::None,
    };
    sky.validate().map_err(|source| SceneError::BadSky {
        what: format!("{}: [sky]", path.display()),
        source,
    })?;
    b.sky(sky)?;
    if file.section.is_empty() {
        for s in settings.into_iter().flat_map(|s| s.sections) {
            b.section(s);
        }
    } else {
        for (k, t) in file.section.iter().enumerate() {
            let s = t.resolve(None, None).map_err(|source| SceneError::Section {
                what: format!("{}: [[section]] {}", path.display(), k + 1),
                source,
            })?;
            b.section(s);
        }
    }
    let scene = b.finish();
    log_notes(path, &scene);
    Ok(scene)
}

/// Largest scene file (TOML) read: scene files name their geometry, they
/// do not hold it.
pub const MAX_SCENE_FILE_BYTES: u64 = 16 << 20;

/// Refuses a scene file that is not a regular file (a device or a pipe
/// could be read for ever) or is larger than [`MAX_SCENE_FILE_BYTES`].
fn check_scene_file(path: &Path) -> Result<(), SceneError> {
    let meta = std::fs::metadata(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let refuse = |message: String| SceneError::Parse {
        path: path.to_path_buf(),
        message,
    };
    if !meta.is_file() {
        return Err(refuse(
            "not a regular file: a scene file is TOML text (or a .rad file)".into(),
        ));
    }
    if meta.len() > MAX_SCENE_FILE_BYTES {
        return Err(refuse(format!(
            "{} bytes is more than the {MAX_SCENE_FILE_BYTES} a scene file may have (geometry belongs in the files it names)",
            meta.len()
        )));
    }
    Ok(())
}

/// Says once what import dropped or approximated: a summary line at the
/// default verbosity, each note with `-v`.
fn log_notes(path: &Path, scene: &Scene) {
    if scene.notes.is_empty() {
        return;
    }
    let mut materials: Vec<&str> = scene.notes.iter().filter_map(|n| n.material.as_deref()).collect();
    materials.sort_unstable();
    materials.dedup();
    tracing::warn!(
        "{}: {} things dropped or approximated on import ({} materials); `holodeck scene info` or -v lists them",
        path.display(),
        scene.notes.len(),
        materials.len()
    );
    for note in &scene.notes {
        tracing::info!("{note}");
    }
}

#[cfg(test)]
mod tests;
