//! Writing a scene out as a scene file plus one binary PLY mesh, so that a
//! generated scene can be inspected, shared and loaded back bit for bit: the
//! loaded scene has the same content hash. The PLY carries a per-face
//! `material_index` into the geometry entry's `materials` list.

pub use crate::error::ExportError;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use serde::Serialize;

use super::file::{write_textures, GeometryEntry};
use super::hash::content_hash;
use super::Scene;
use crate::error::SceneError;

/// Writes `scene` as the scene file `toml_path` and its mesh as a PLY file of
/// the same name next to it (with texture coordinates where it has them,
/// and its textures as PNG files `NAME-K.png` beside); returns the PLY path.
pub fn write_scene(scene: &Scene, toml_path: &Path) -> Result<PathBuf, SceneError> {
    let ply_path = toml_path.with_extension("ply");
    let ply_name = ply_path
        .file_name()
        .map(PathBuf::from)
        .unwrap_or_else(|| ply_path.clone());
    write_ply(scene, &ply_path)?;
    let dir = toml_path.parent().unwrap_or(Path::new(""));
    let stem = toml_path.file_stem().and_then(|s| s.to_str()).unwrap_or("scene");
    let textures = write_textures(scene, dir, stem)?;
    let mut text = scene_text(scene, &ply_name).map_err(|source| SceneError::Export {
        path: toml_path.to_path_buf(),
        source,
    })?;
    for (name, entry) in &textures {
        text += &format!("\n[textures.{}]\n", key(name));
        text += &to_toml("[textures]", entry).map_err(|source| SceneError::Export {
            path: toml_path.to_path_buf(),
            source,
        })?;
    }
    std::fs::write(toml_path, text).map_err(|source| SceneError::Io {
        path: toml_path.to_path_buf(),
        source,
    })?;
    Ok(ply_path)
}

/// The scene file text for `scene` with its mesh in the file `ply`.
pub fn scene_text(scene: &Scene, ply: &Path) -> Result<String, ExportError> {
    let mut out = format!(
        "# Holodeck scene: {} triangles, {} materials.\n# Content hash {}\n\n",
        scene.triangles.len(),
        scene.materials.len(),
        content_hash(scene)
    );
    out += "[sky]\n";
    out += &to_toml("[sky]", &scene.sky)?;
    for (name, m) in scene.material_names.iter().zip(&scene.materials) {
        out += &format!("\n[materials.{}]\n", key(name));
        out += &to_toml("[materials]", m)?;
    }
    let geometry = GeometryEntry {
        file: ply.to_path_buf(),
        materials: scene.material_names.clone(),
        ..Default::default()
    };
    out += "\n[[geometry]]\n";
    out += &to_toml("[[geometry]]", &geometry)?;
    for s in &scene.sections {
        out += "\n[[section]]\n";
        out += &to_toml("[[section]]", &s.spec())?;
    }
    Ok(out)
}

/// A TOML key: bare when it can be, else quoted.
fn key(name: &str) -> String {
    let bare = !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_' || c == '-');
    if bare {
        name.to_string()
    } else {
        toml::Value::String(name.to_string()).to_string()
    }
}

/// One table's body as TOML, `type` first, with f32 values in their shortest exact form.
fn to_toml<T: Serialize>(table: &'static str, v: &T) -> Result<String, ExportError> {
    let err = |source| ExportError::Toml { table, source };
    let value = toml::Value::try_from(v).map_err(err)?;
    let text = toml::to_string(&shortest(value)).map_err(err)?;
    let (first, rest): (Vec<&str>, Vec<&str>) = text.lines().partition(|l| l.starts_with("type = "));
    Ok(first.into_iter().chain(rest).map(|l| format!("{l}\n")).collect())
}

/// Rewrites floats that came from f32 (like 0.800000011920929) as the shortest
/// decimal that reads back as the same f32 (0.8).
fn shortest(v: toml::Value) -> toml::Value {
    match v {
        toml::Value::Float(f) => {
            let x = f as f32;
            if f64::from(x) == f {
                if let Ok(p) = x.to_string().parse::<f64>() {
                    if p as f32 == x {
                        return toml::Value::Float(p);
                    }
                }
            }
            toml::Value::Float(f)
        }
        toml::Value::Array(a) => toml::Value::Array(a.into_iter().map(shortest).collect()),
        toml::Value::Table(t) => toml::Value::Table(t.into_iter().map(|(k, v)| (k, shortest(v))).collect()),
        other => other,
    }
}

/// Writes the scene's positions and triangles as binary little-endian PLY with
/// a per-face `material_index` (the scene's material index).
pub fn write_ply(scene: &Scene, path: &Path) -> Result<(), SceneError> {
    let io = |source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    };
    let mut w = BufWriter::with_capacity(1 << 22, File::create(path).map_err(io)?);
    let with_uvs = !scene.uvs.is_empty();
    let header = format!(
        "ply\nformat binary_little_endian 1.0\ncomment holodeck scene\nelement vertex {}\n\
         property float x\nproperty float y\nproperty float z\n{}element face {}\n\
         property list uchar uint vertex_indices\nproperty uint material_index\nend_header\n",
        scene.positions.len(),
        if with_uvs {
            "property float u\nproperty float v\n"
        } else {
            ""
        },
        scene.triangles.len()
    );
    w.write_all(header.as_bytes()).map_err(io)?;
    let mut buf = Vec::with_capacity(1 << 20);
    for (k, chunk) in scene.positions.chunks(1 << 16).enumerate() {
        buf.clear();
        for (i, p) in chunk.iter().enumerate() {
            for c in p.to_array() {
                buf.extend_from_slice(&c.to_le_bytes());
            }
            if with_uvs {
                // PLY's v grows upward.
                let uv = scene.uvs[(k << 16) + i];
                buf.extend_from_slice(&uv.x.to_le_bytes());
                buf.extend_from_slice(&(1.0 - uv.y).to_le_bytes());
            }
        }
        w.write_all(&buf).map_err(io)?;
    }
    for chunk in scene.triangles.chunks(1 << 16) {
        buf.clear();
        for t in chunk {
            buf.push(3);
            for v in t.v {
                buf.extend_from_slice(&v.to_le_bytes());
            }
            buf.extend_from_slice(&t.material.to_le_bytes());
        }
        w.write_all(&buf).map_err(io)?;
    }
    w.flush().map_err(io)
}
