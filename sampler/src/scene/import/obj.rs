//! Wavefront OBJ import through `tobj`: positions, texture coordinates
//! (`vt`, v flipped to grow downward as the scene's do) and MTL materials
//! with their maps, converted as `mtl.rs` says.

use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::{Mat4, Vec2, Vec3};

use super::{parse_error, textured_material, ImportOptions};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;

/// Adds every object of the OBJ file at `path`.
pub(super) fn import(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let file = super::open(path)?;
    let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
    let load_mtl = |mtl: &Path| {
        let full = dir.join(mtl);
        let result = match super::check_regular_file(&full) {
            // tobj panics on some malformed lines (one number where three
            // belong); such a library is as broken as an unreadable one.
            Ok(()) => std::panic::catch_unwind(|| tobj::load_mtl(&full)).unwrap_or(Err(tobj::LoadError::ReadError)),
            Err(_) => Err(tobj::LoadError::OpenFileFailed),
        };
        if let Err(e) = &result {
            tracing::warn!(
                "{}: material library {}: {e}; faces using it get the default material",
                path.display(),
                full.display()
            );
        }
        result
    };
    import_reader(b, &mut BufReader::new(file), path, &dir, load_mtl, transform, options)
}

/// Adds every object of OBJ text held in memory (a built-in model), named
/// `name` in messages. It has no material libraries: its faces take the
/// default material.
pub(super) fn import_bytes(
    b: &mut SceneBuilder,
    bytes: &[u8],
    name: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let no_library = |_: &Path| Err(tobj::LoadError::OpenFileFailed);
    import_reader(b, &mut &bytes[..], name, Path::new(""), no_library, transform, options)
}

/// Adds every object of the OBJ text `reader` gives; `path` names it in
/// messages, `load_mtl` finds its material libraries and textures are
/// found relative to `dir`.
fn import_reader(
    b: &mut SceneBuilder,
    reader: &mut impl BufRead,
    path: &Path,
    dir: &Path,
    load_mtl: impl Fn(&Path) -> tobj::MTLLoadResult,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let load = tobj::LoadOptions {
        triangulate: true,
        single_index: true,
        ignore_points: true,
        ignore_lines: true,
    };
    let (models, materials) =
        tobj::load_obj_buf(reader, &load, load_mtl).map_err(|e| parse_error(path, format!("OBJ: {e}")))?;
    let materials = materials.unwrap_or_default();
    let mut ids: Vec<Option<u32>> = vec![None; materials.len()];
    for model in &models {
        let mesh = &model.mesh;
        let what = format!("{}: object {:?}", path.display(), model.name);
        let material = match mesh.material_id {
            Some(k) if k < materials.len() => match ids[k] {
                Some(id) => id,
                None => {
                    let m = &materials[k];
                    let file = path.display().to_string();
                    let (material, maps) = super::mtl::convert(b, m, dir, &file);
                    let id = textured_material(b, options, &m.name, material, maps)?;
                    ids[k] = Some(id);
                    id
                }
            },
            _ => options.default_material.ok_or_else(|| SceneError::MissingMaterial {
                path: path.to_path_buf(),
                what: format!("object {:?}", model.name),
            })?,
        };
        if mesh.positions.len() % 3 != 0 || mesh.indices.len() % 3 != 0 {
            return Err(parse_error(
                path,
                format!("object {:?}: incomplete vertex or triangle list", model.name),
            ));
        }
        let positions: Vec<Vec3> = mesh
            .positions
            .chunks_exact(3)
            .map(|p| Vec3::new(p[0], p[1], p[2]))
            .collect();
        let triangles: Vec<[u32; 3]> = mesh.indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
        // OBJ's v grows upward; the scene's, like glTF's, downward.
        let uvs: Option<Vec<Vec2>> =
            (mesh.texcoords.len() == 2 * positions.len() && !positions.is_empty()).then(|| {
                mesh.texcoords
                    .chunks_exact(2)
                    .map(|t| Vec2::new(t[0], 1.0 - t[1]))
                    .collect()
            });
        b.add_mesh_uv(&what, &positions, uvs.as_deref(), &triangles, &[material], transform)?;
    }
    Ok(())
}
