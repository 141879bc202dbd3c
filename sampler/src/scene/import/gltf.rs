//! glTF 2.0 (`.gltf` with embedded or external buffers, and `.glb`) import
//! through the `gltf` crate: every node of the default scene (else the first)
//! with its world transform, primitives in triangle mode only (points, lines,
//! strips and fans are skipped and counted), with TEXCOORD_0 and TANGENT
//! (for normal maps; generated from the texture coordinates where missing).
//! Materials are converted as `gltf_material.rs` says. Vertex colours and
//! normals are not read (shading uses the geometric normal, or a normal
//! map's). Positions are
//! read in glTF's +y-up frame; the transform the caller passes turns them
//! +z up (see [`super::UpAxis`]).

use std::path::Path;

use glam::{Mat4, Vec2, Vec3};

use super::gltf_material::Source;
use super::{parse_error, textured_material, ImportOptions};
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;

/// Deepest node hierarchy followed (a guard against cyclic files).
const MAX_DEPTH: usize = 256;

/// Adds every triangle primitive of the glTF or GLB file at `path`.
pub(super) fn import(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<(), SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let gltf = gltf::Gltf::from_slice(&bytes).map_err(|e| parse_error(path, format!("glTF: {e}")))?;
    drop(bytes);
    let gltf::Gltf { document, blob } = gltf;
    let base = path.parent().unwrap_or(Path::new("."));
    for buffer in document.buffers() {
        if let gltf::buffer::Source::Uri(uri) = buffer.source() {
            if uri.starts_with("data:") {
                continue;
            }
            // Only plain relative paths next to the file: no schemes, no
            // absolute paths, no escapes into parent directories.
            let plain = !uri.contains(':') && !uri.starts_with('/') && !uri.split(['/', '\\']).any(|c| c == "..");
            let decoded_ok = !uri.contains('%');
            if !plain || !decoded_ok {
                return Err(parse_error(
                    path,
                    format!("glTF buffer URI {uri:?} is not a relative file path"),
                ));
            }
            super::check_regular_file(&base.join(uri))?;
        }
    }
    let buffers = gltf::import_buffers(&document, Some(base), blob)
        .map_err(|e| parse_error(path, format!("glTF buffers: {e}")))?;
    let Some(scene) = document.default_scene().or_else(|| document.scenes().next()) else {
        tracing::warn!("{}: glTF has no scene; nothing imported", path.display());
        return Ok(());
    };
    const READ: [&str; 5] = [
        "KHR_texture_transform",
        "KHR_materials_transmission",
        "KHR_materials_ior",
        "KHR_materials_emissive_strength",
        "KHR_materials_clearcoat",
    ];
    for ext in document.extensions_used() {
        if !READ.contains(&ext) {
            b.note(
                &path.display().to_string(),
                None,
                format!("extension {ext} is not read"),
            );
        }
    }
    let mut ctx = Context {
        b,
        path,
        options,
        buffers: &buffers,
        skipped: 0,
        no_uvs: 0,
    };
    let mut stack: Vec<(gltf::Node, Mat4, usize)> = scene.nodes().map(|n| (n, transform, 0)).collect();
    // glTF requires a tree; a node reached twice (shared or cyclic) is refused
    // rather than copied exponentially.
    let mut seen = std::collections::HashSet::new();
    while let Some((node, parent, depth)) = stack.pop() {
        if !seen.insert(node.index()) {
            return Err(parse_error(
                path,
                format!(
                    "glTF node {} is reached twice: the node graph is not a tree",
                    node.index()
                ),
            ));
        }
        if depth > MAX_DEPTH {
            return Err(parse_error(
                path,
                format!("glTF node hierarchy deeper than {MAX_DEPTH} (a cycle?)"),
            ));
        }
        let world = parent * Mat4::from_cols_array_2d(&node.transform().matrix());
        if let Some(mesh) = node.mesh() {
            ctx.mesh(&mesh, world)?;
        }
        stack.extend(node.children().map(|c| (c, world, depth + 1)));
    }
    if ctx.no_uvs > 0 {
        let what = format!(
            "{} textured primitives have no TEXCOORD_0; their textures read one texel",
            ctx.no_uvs
        );
        ctx.b.note(&path.display().to_string(), None, what);
    }
    if ctx.skipped > 0 {
        tracing::warn!(
            "{}: skipped {} primitives that are not triangle lists",
            path.display(),
            ctx.skipped
        );
    }
    Ok(())
}

/// What importing one file needs at every mesh.
struct Context<'a, 'b> {
    b: &'a mut SceneBuilder,
    path: &'a Path,
    options: &'a ImportOptions<'b>,
    buffers: &'a [gltf::buffer::Data],
    skipped: u64,
    /// Textured primitives without texture coordinates.
    no_uvs: u64,
}

impl Context<'_, '_> {
    /// Adds the triangle primitives of `mesh` placed by `world`.
    fn mesh(&mut self, mesh: &gltf::Mesh, world: Mat4) -> Result<(), SceneError> {
        for prim in mesh.primitives() {
            let what = format!(
                "mesh {} primitive {}",
                mesh.name().unwrap_or(&mesh.index().to_string()),
                prim.index()
            );
            if prim.mode() != gltf::mesh::Mode::Triangles {
                self.skipped += 1;
                continue;
            }
            let buffers = self.buffers;
            let reader = prim.reader(|buf| buffers.get(buf.index()).map(|d| &d.0[..]));
            let positions: Vec<Vec3> = reader
                .read_positions()
                .ok_or_else(|| parse_error(self.path, format!("{what}: no readable POSITION accessor")))?
                .map(Vec3::from)
                .collect();
            let indices: Vec<u32> = match reader.read_indices() {
                Some(ix) => ix.into_u32().collect(),
                None if prim.indices().is_some() => {
                    return Err(parse_error(
                        self.path,
                        format!("{what}: index accessor out of its buffer"),
                    ))
                }
                None => (0..positions.len() as u32).collect(),
            };
            if !indices.len().is_multiple_of(3) {
                return Err(parse_error(
                    self.path,
                    format!("{what}: {} indices is not a triangle list", indices.len()),
                ));
            }
            let triangles: Vec<[u32; 3]> = indices.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect();
            let material = self.material(&prim.material())?;
            let uvs: Option<Vec<Vec2>> = reader
                .read_tex_coords(0)
                .map(|tc| tc.into_f32().map(Vec2::from).collect::<Vec<Vec2>>())
                .filter(|uvs| uvs.len() == positions.len());
            if uvs.is_none() && self.b.material_maps(material).is_some_and(|m| !m.is_empty()) {
                self.no_uvs += 1;
            }
            let source = format!("{}: {what}", self.path.display());
            let first = self.b.vertex_count();
            self.b
                .add_mesh_uv(&source, &positions, uvs.as_deref(), &triangles, &[material], world)?;
            let tangents: Option<Vec<glam::Vec4>> = reader
                .read_tangents()
                .map(|t| t.map(glam::Vec4::from).collect::<Vec<_>>())
                .filter(|t| t.len() == positions.len());
            if let Some(tangents) = tangents {
                self.b.set_tangents(first, &tangents, world);
            }
        }
        Ok(())
    }

    /// The scene material for a glTF material (the caller's default for none).
    fn material(&mut self, m: &gltf::Material) -> Result<u32, SceneError> {
        let source = Source {
            path: self.path,
            buffers: self.buffers,
        };
        let Some(index) = m.index() else {
            if let Some(id) = self.options.default_material {
                return Ok(id);
            }
            let (material, maps) = source.convert(self.b, m, "gltf:default");
            return textured_material(self.b, self.options, "gltf:default", material, maps);
        };
        let name = m.name().map_or_else(|| format!("gltf:{index}"), str::to_string);
        if let Some(&id) = self.options.overrides.and_then(|o| o.get(&name)) {
            return Ok(id);
        }
        let (material, maps) = source.convert(self.b, m, &name);
        textured_material(self.b, self.options, &name, material, maps)
    }
}
