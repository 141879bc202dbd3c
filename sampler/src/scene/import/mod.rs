//! Geometry importers: OBJ (with MTL materials), PLY (ASCII and binary),
//! glTF/GLB and Radiance scene files, each adding its triangles and materials
//! to a [`SceneBuilder`].
//! They only read files; they never decide where a scene's files live (the
//! scene file does that) and never panic on what a file contains.
//!
//! Scenes are +z up. glTF files are +y up by specification, so they are
//! turned to +z up on import, (x, y, z) -> (x, -z, y), a rotation that keeps
//! handedness and face orientation; OBJ, PLY and Radiance files are taken as
//! +z up.
//! [`UpAxis`] overrides either for files whose authors used the other.

mod gltf;
mod gltf_material;
mod mtl;
mod obj;
mod ply;
pub mod rad;

use std::collections::HashMap;
use std::path::Path;

use glam::Mat4;
use serde::{Deserialize, Serialize};

use super::builder::SceneBuilder;
use super::maps::MaterialMaps;
use super::material::Material;
use crate::error::SceneError;

/// Which axis of a geometry file points up.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum UpAxis {
    /// +y up (glTF's convention, and many OBJ exporters').
    Y,
    /// +z up (the scene's convention).
    Z,
}

impl UpAxis {
    /// The convention of the format of `path`: y for glTF and GLB, z for the rest.
    pub fn default_for(path: &Path) -> UpAxis {
        let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
        match ext.as_deref() {
            Some("gltf" | "glb") => UpAxis::Y,
            _ => UpAxis::Z,
        }
    }

    /// The rotation that turns a file with this up axis +z up: for y, +90
    /// degrees about x, taking (x, y, z) to (x, -z, y).
    pub fn to_z_up(self) -> Mat4 {
        match self {
            UpAxis::Y => Mat4::from_cols_array(&[
                1.0, 0.0, 0.0, 0.0, //
                0.0, 0.0, 1.0, 0.0, //
                0.0, -1.0, 0.0, 0.0, //
                0.0, 0.0, 0.0, 1.0,
            ]),
            UpAxis::Z => Mat4::IDENTITY,
        }
    }
}

/// How one file is imported besides its transform.
#[derive(Clone, Copy, Debug, Default)]
pub struct ImportOptions<'a> {
    /// Material for faces the file gives none (OBJ faces without `usemtl`, PLY
    /// without `material_index`, glTF primitives without a material).
    pub default_material: Option<u32>,
    /// Scene materials by name that replace a file's material of the same name
    /// (OBJ/MTL and glTF material names).
    pub overrides: Option<&'a HashMap<String, u32>>,
    /// Material ids that a PLY file's per-face `material_index` indexes.
    pub face_materials: &'a [u32],
    /// The file's up axis; `None` takes its format's ([`UpAxis::default_for`]).
    pub up: Option<UpAxis>,
}

/// Imports `path` (`.obj`, `.ply`, `.gltf`, `.glb` or `.rad`, by extension) into `b`,
/// transformed by `transform`. `default_material` is used for faces without a
/// material; `overrides` maps file material names to scene materials that
/// replace them.
pub fn import_file(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    default_material: Option<u32>,
    overrides: &HashMap<String, u32>,
) -> Result<(), SceneError> {
    let options = ImportOptions {
        default_material,
        overrides: Some(overrides),
        ..ImportOptions::default()
    };
    import_file_with(b, path, transform, &options)
}

/// [`import_file`] with every option, including the material list that PLY
/// per-face `material_index` values index and the file's up axis. The file is
/// turned +z up first; `transform` then places it in the scene. What a
/// file dropped or approximated becomes the scene's import notes (a
/// Radiance file's once per kind).
pub fn import_file_with(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let up = options.up.unwrap_or_else(|| UpAxis::default_for(path));
    let transform = transform * up.to_z_up();
    let ext = path.extension().and_then(|e| e.to_str()).map(str::to_ascii_lowercase);
    let before = b.triangle_count();
    check_regular_file(path)?;
    // The parsers are third-party code reading untrusted bytes; a panic inside
    // one becomes an error naming the file instead of ending the process.
    let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| match ext.as_deref() {
        Some("obj") => obj::import(b, path, transform, options),
        Some("ply") => ply::import(b, path, transform, options),
        Some("gltf") | Some("glb") => gltf::import(b, path, transform, options),
        Some("rad") => rad::read_rad(b, path, transform, options).map(|report| report.note_into(b, path)),
        _ => Err(SceneError::UnsupportedFormat {
            path: path.to_path_buf(),
        }),
    }));
    match result {
        Ok(r) => r?,
        Err(panic) => {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| s.to_string())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_default();
            let message = format!("the file is malformed: its parser failed ({what})");
            return Err(SceneError::Parse {
                path: path.to_path_buf(),
                message,
            });
        }
    }
    tracing::info!("{}: {} triangles", path.display(), b.triangle_count() - before);
    Ok(())
}

/// Imports OBJ text held in memory (a model built into the program), named
/// `name` in messages and logs; its faces take `default_material`, and its
/// coordinates are used as they are.
pub(crate) fn import_obj_bytes(
    b: &mut SceneBuilder,
    bytes: &[u8],
    name: &Path,
    transform: Mat4,
    default_material: Option<u32>,
) -> Result<(), SceneError> {
    let options = ImportOptions {
        default_material,
        ..ImportOptions::default()
    };
    obj::import_bytes(b, bytes, name, transform, &options)
}

/// Opens a file to import, naming it in the error.
pub(crate) fn open(path: &Path) -> Result<std::fs::File, SceneError> {
    std::fs::File::open(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })
}

/// Largest file an importer reads (glTF buffers, MTL libraries).
pub(crate) const MAX_FILE_BYTES: u64 = 64 << 30;

/// Refuses what is not a regular file of sane size (devices, pipes, directories),
/// which a scene file could otherwise name to make a reader run forever.
pub(crate) fn check_regular_file(path: &Path) -> Result<(), SceneError> {
    let meta = std::fs::metadata(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    if !meta.is_file() {
        let message = "not a regular file".to_string();
        return Err(SceneError::Parse {
            path: path.to_path_buf(),
            message,
        });
    }
    if meta.len() > MAX_FILE_BYTES {
        let message = format!(
            "{} bytes is more than the {MAX_FILE_BYTES} an importer reads",
            meta.len()
        );
        return Err(SceneError::Parse {
            path: path.to_path_buf(),
            message,
        });
    }
    Ok(())
}

/// The material (and textures) for a file's material named `name`: the scene's override if
/// there is one, else `m` added under `name` (or `name#2`, `name#3`, ... when
/// another file already used the name for different parameters).
fn textured_material(
    b: &mut SceneBuilder,
    options: &ImportOptions,
    name: &str,
    m: Material,
    maps: MaterialMaps,
) -> Result<u32, SceneError> {
    if let Some(&id) = options.overrides.and_then(|o| o.get(name)) {
        return Ok(id);
    }
    let mut candidate = name.to_string();
    for k in 2u32.. {
        match b.material_id(&candidate) {
            Some(id) if b.material_params(id) == Some(&m) && b.material_maps(id) == Some(&maps) => return Ok(id),
            Some(_) => candidate = format!("{name}#{k}"),
            None => break,
        }
    }
    b.material_with_maps(&candidate, m, maps)
}

/// Clamps a color into [0, 1], mapping NaN to 0.
fn unit_color(c: [f32; 3]) -> [f32; 3] {
    c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
}

/// Parse error for `path`.
fn parse_error(path: &Path, message: impl Into<String>) -> SceneError {
    SceneError::Parse {
        path: path.to_path_buf(),
        message: message.into(),
    }
}

#[cfg(test)]
pub(crate) mod tests;
