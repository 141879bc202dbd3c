//! PLY import through `ply-rs-bw`: ASCII, binary little- and big-endian.
//! Reads `vertex` x, y, z (any numeric type), texture coordinates u, v (or
//! s, t; texture_u, texture_v), v flipped to grow downward, and `face` `vertex_indices` (or
//! `vertex_index`) lists, fan-triangulating polygons, with an optional integer
//! per-face `material_index` into the caller's material list. Elements are read
//! one at a time straight into the scene's arrays, so memory stays at the size
//! of the result however large the file.

use std::io::{BufRead, BufReader};
use std::path::Path;

use glam::{Mat4, Vec2, Vec3};
use ply_rs_bw::parser::Parser;
use ply_rs_bw::ply::{ElementDef, Encoding, Header, Property, PropertyAccess, PropertyType};
use rayon::prelude::*;

use super::{parse_error, ImportOptions};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::Triangle;

/// A vertex as read: its position and texture coordinates.
struct Vertex([f64; 3], [f64; 2]);

impl PropertyAccess for Vertex {
    fn new() -> Self {
        Vertex([f64::NAN; 3], [0.0; 2])
    }
    fn set_property(&mut self, name: String, property: Property) {
        let Some(v) = scalar(&property) else { return };
        match name.as_str() {
            "x" => self.0[0] = v,
            "y" => self.0[1] = v,
            "z" => self.0[2] = v,
            "u" | "s" | "texture_u" | "texture_s" => self.1[0] = v,
            "v" | "t" | "texture_v" | "texture_t" => self.1[1] = v,
            _ => {}
        }
    }
}

/// Whether the vertex element of `header` has texture coordinates.
fn has_uvs(header: &Header) -> bool {
    header.elements.get("vertex").is_some_and(|e| {
        let has = |names: [&str; 4]| names.iter().any(|n| e.properties.contains_key(*n));
        has(["u", "s", "texture_u", "texture_s"]) && has(["v", "t", "texture_v", "texture_t"])
    })
}

/// A face as read: its vertex list (negative entries marked) and material index.
#[derive(Default)]
struct Face {
    indices: Vec<u32>,
    negative: bool,
    material: Option<f64>,
}

impl PropertyAccess for Face {
    fn new() -> Self {
        Face::default()
    }
    fn set_property(&mut self, name: String, property: Property) {
        match name.as_str() {
            "vertex_indices" | "vertex_index" => {
                let signed = |v: Vec<i64>| {
                    let negative = v.iter().any(|&i| !(0..=i64::from(u32::MAX)).contains(&i));
                    (
                        v.into_iter().map(|i| i.clamp(0, i64::from(u32::MAX)) as u32).collect(),
                        negative,
                    )
                };
                (self.indices, self.negative) = match property {
                    Property::ListUInt(v) => (v, false),
                    Property::ListUChar(v) => (v.into_iter().map(u32::from).collect(), false),
                    Property::ListUShort(v) => (v.into_iter().map(u32::from).collect(), false),
                    Property::ListInt(v) => signed(v.into_iter().map(i64::from).collect()),
                    Property::ListShort(v) => signed(v.into_iter().map(i64::from).collect()),
                    Property::ListChar(v) => signed(v.into_iter().map(i64::from).collect()),
                    _ => (Vec::new(), true),
                };
            }
            "material_index" => self.material = scalar(&property),
            _ => {}
        }
    }
}

/// An element of no interest; its bytes are read and dropped.
struct Skip;

impl PropertyAccess for Skip {
    fn new() -> Self {
        Skip
    }
}

/// A scalar property as f64.
fn scalar(p: &Property) -> Option<f64> {
    Some(match *p {
        Property::Char(v) => v.into(),
        Property::UChar(v) => v.into(),
        Property::Short(v) => v.into(),
        Property::UShort(v) => v.into(),
        Property::Int(v) => v.into(),
        Property::UInt(v) => v.into(),
        Property::Float(v) => v.into(),
        Property::Double(v) => v,
        _ => return None,
    })
}

/// Reads the next element of `def` in the header's encoding.
fn read_element<E: PropertyAccess, R: BufRead>(
    reader: &mut R,
    header: &Header,
    def: &ElementDef,
    line: &mut String,
) -> std::io::Result<E> {
    let parser = Parser::<E>::new();
    match header.encoding {
        Encoding::Ascii => {
            line.clear();
            if reader.read_line(line)? == 0 {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "unexpected end of file",
                ));
            }
            parser.read_ascii_element(line, def)
        }
        Encoding::BinaryLittleEndian => parser.read_little_endian_element(reader, def),
        Encoding::BinaryBigEndian => parser.read_big_endian_element(reader, def),
    }
}

/// Adds the mesh of the PLY file at `path`.
pub(super) fn import(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let file = super::open(path)?;
    let file_len = file.metadata().map(|m| m.len()).unwrap_or(0);
    let mut reader = BufReader::with_capacity(1 << 20, file);
    let header = Parser::<Skip>::new()
        .read_header(&mut reader)
        .map_err(|e| parse_error(path, format!("PLY header: {e}")))?;
    check_header(path, &header)?;
    // Every element takes at least one byte, which bounds what a lying header can reserve.
    let bound = |n: usize| n.min(usize::try_from(file_len).unwrap_or(usize::MAX));
    let mut positions: Vec<Vec3> = Vec::new();
    let with_uvs = has_uvs(&header);
    let mut uvs: Vec<Vec2> = Vec::new();
    let mut triangles: Vec<Triangle> = Vec::new();
    let (mut skipped_faces, mut line) = (0u64, String::new());
    for (name, def) in &header.elements {
        if def.properties.is_empty() && def.count > 0 {
            // It would take no bytes to read, so a huge count would loop for ever.
            return Err(parse_error(path, format!("PLY element {name} has no properties")));
        }
        let fail = |k: usize, e: std::io::Error| {
            parse_error(
                path,
                format!("{name} {k} of {}: {e} (file truncated or malformed?)", def.count),
            )
        };
        match name.as_str() {
            "vertex" => {
                positions.reserve_exact(bound(def.count));
                for k in 0..def.count {
                    let Vertex(p, uv) = read_element(&mut reader, &header, def, &mut line).map_err(|e| fail(k, e))?;
                    positions.push(Vec3::new(p[0] as f32, p[1] as f32, p[2] as f32));
                    if with_uvs {
                        // PLY's v grows upward, as OBJ's does.
                        uvs.push(Vec2::new(uv[0] as f32, (1.0 - uv[1]) as f32));
                    }
                }
            }
            "face" => {
                triangles.reserve_exact(bound(def.count));
                for k in 0..def.count {
                    let face: Face = read_element(&mut reader, &header, def, &mut line).map_err(|e| fail(k, e))?;
                    if face.negative {
                        return Err(parse_error(
                            path,
                            format!("face {k}: negative or non-integer vertex index"),
                        ));
                    }
                    if face.indices.len() < 3 {
                        skipped_faces += 1;
                        continue;
                    }
                    let material = face_material(path, options, k, face.material)?;
                    let v = &face.indices;
                    triangles.extend((1..v.len() - 1).map(|i| Triangle {
                        v: [v[0], v[i], v[i + 1]],
                        material,
                    }));
                }
            }
            _ => {
                for k in 0..def.count {
                    read_element::<Skip, _>(&mut reader, &header, def, &mut line).map_err(|e| fail(k, e))?;
                }
            }
        }
    }
    if skipped_faces > 0 {
        tracing::warn!(
            "{}: skipped {skipped_faces} faces with fewer than 3 vertices",
            path.display()
        );
    }
    if transform != Mat4::IDENTITY {
        positions
            .par_iter_mut()
            .for_each(|p| *p = transform.transform_point3(*p));
    }
    let uvs = (with_uvs && uvs.len() == positions.len()).then_some(uvs);
    b.add_world_mesh_uv(&path.display().to_string(), positions, uvs, triangles)
}

/// Requires a vertex element with x, y, z and a face element with an index list.
fn check_header(path: &Path, header: &Header) -> Result<(), SceneError> {
    let vertex = header
        .elements
        .get("vertex")
        .ok_or_else(|| parse_error(path, "PLY has no vertex element"))?;
    for axis in ["x", "y", "z"] {
        match vertex.properties.get(axis).map(|p| &p.data_type) {
            Some(PropertyType::Scalar(_)) => {}
            _ => {
                return Err(parse_error(
                    path,
                    format!("PLY vertex element has no scalar property {axis}"),
                ))
            }
        }
    }
    let face = header
        .elements
        .get("face")
        .ok_or_else(|| parse_error(path, "PLY has no face element"))?;
    let list = ["vertex_indices", "vertex_index"]
        .iter()
        .find_map(|n| face.properties.get(*n));
    if !matches!(list.map(|p| &p.data_type), Some(PropertyType::List(..))) {
        return Err(parse_error(path, "PLY face element has no vertex_indices list"));
    }
    if let Some(m) = face.properties.get("material_index") {
        if !matches!(m.data_type, PropertyType::Scalar(_)) {
            return Err(parse_error(
                path,
                "PLY face material_index must be a number, not a list",
            ));
        }
    }
    Ok(())
}

/// The scene material of face `k` with file material index `index`.
fn face_material(path: &Path, options: &ImportOptions, k: usize, index: Option<f64>) -> Result<u32, SceneError> {
    match index {
        Some(i) if !options.face_materials.is_empty() => {
            let list = options.face_materials;
            if i.fract() == 0.0 && i >= 0.0 && (i as usize) < list.len() {
                Ok(list[i as usize])
            } else {
                let message = format!(
                    "face {k}: material_index {i} is not an index into the {} listed materials",
                    list.len()
                );
                Err(parse_error(path, message))
            }
        }
        _ => options.default_material.ok_or_else(|| SceneError::MissingMaterial {
            path: path.to_path_buf(),
            what: if index.is_some() {
                format!("face {k} (its material_index needs a `materials` list)")
            } else {
                format!("face {k}")
            },
        }),
    }
}
