//! Wavefront OBJ import through `tobj`, with MTL materials converted to ours:
//! `Ke` > 0 gives an emitter; `d` < 1 or `illum` 4, 6, 7 glass (`Ni`, `Tf`);
//! `illum` 3 with black `Kd` metal; `Ks` > 0 plastic with roughness
//! sqrt(2 / (Ns + 2)); anything else lambertian with `Kd`. Textures are ignored.

use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::{Mat4, Vec3};

use super::{file_material, parse_error, unit_color, ImportOptions};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::material::Material;

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
    import_reader(b, &mut BufReader::new(file), path, load_mtl, transform, options)
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
    import_reader(b, &mut &bytes[..], name, no_library, transform, options)
}

/// Adds every object of the OBJ text `reader` gives; `path` names it in
/// messages and `load_mtl` finds its material libraries.
fn import_reader(
    b: &mut SceneBuilder,
    reader: &mut impl BufRead,
    path: &Path,
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
                    let id = file_material(b, options, &m.name, convert(m))?;
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
        b.add_mesh(&what, &positions, &triangles, &[material], transform)?;
    }
    Ok(())
}

/// Our material for an MTL material.
pub(super) fn convert(m: &tobj::Material) -> Material {
    let kd = m.diffuse.map(unit_color);
    let ks = m.specular.map(unit_color).unwrap_or([0.0; 3]);
    let ke = m
        .emissive
        .unwrap_or([0.0; 3])
        .map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 });
    let illum = m.illumination_model.unwrap_or(2);
    let roughness = match m.shininess {
        Some(ns) if ns.is_finite() && ns >= 0.0 => (2.0 / (ns + 2.0)).sqrt().clamp(0.0, 1.0),
        _ => 1.0,
    };
    let max = |c: [f32; 3]| c[0].max(c[1]).max(c[2]);
    if max(ke) > 0.0 {
        return Material::Emitter { radiance: ke };
    }
    let dissolve = m.dissolve.filter(|d| d.is_finite()).unwrap_or(1.0);
    if dissolve < 1.0 || matches!(illum, 4 | 6 | 7) {
        let ior = m.optical_density.filter(|n| n.is_finite() && *n >= 1.0).unwrap_or(1.5);
        let color = m
            .unknown_param
            .get("Tf")
            .and_then(|tf| parse_rgb(tf))
            .map(unit_color)
            .unwrap_or([1.0; 3]);
        return Material::Glass {
            ior,
            color,
            thin: false,
        };
    }
    if illum == 3 && kd.is_none_or(|c| max(c) < 0.01) {
        let color = if max(ks) > 0.0 { ks } else { [0.9; 3] };
        return Material::Metal { color, roughness };
    }
    let albedo = kd.unwrap_or([0.8; 3]);
    if max(ks) > 0.0 {
        return Material::Plastic {
            albedo,
            roughness,
            ior: 1.5,
        };
    }
    Material::lambertian(albedo)
}

/// Three numbers, or one repeated (as MTL allows for `Tf`).
fn parse_rgb(s: &str) -> Option<[f32; 3]> {
    let v: Vec<f32> = s.split_whitespace().map(str::parse).collect::<Result<_, _>>().ok()?;
    match v[..] {
        [g] => Some([g; 3]),
        [r, g, b] => Some([r, g, b]),
        _ => None,
    }
}
