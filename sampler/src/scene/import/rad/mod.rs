//! Radiance scene files (`.rad`): surfaces become triangles, materials become
//! ours, distant sources become the sky, and `!xform` / `!genbox` lines are
//! read in-process. It never runs a command and never panics on what a file
//! holds; what it cannot show faithfully it approximates and reports
//! ([`RadReport`]), what it cannot show at all it refuses with an error that
//! names the file and line.
//!
//! * Surfaces: `polygon` (ear-clipped), `sphere`, `bubble`, `cone`, `cup`,
//!   `cylinder`, `tube`, `ring`, tessellated as `shapes.rs` says; `source`
//!   as the sun or sky (`sky.rs`). `instance` and `mesh` are refused.
//! * Materials, patterns, mixtures and aliases: see `materials.rs`. A surface
//!   whose modifier chain reaches no material (`void`) is invisible in
//!   Radiance, and left out.
//! * Commands: `xform` options `-t -rx -ry -rz -s -mx -my -mz -i -I -m -n`
//!   with files found relative to the including file, `genbox` with `-i`,
//!   each piped through further `xform`s; anything else is refused.
//!
//! Coordinates are taken as they are (Radiance is +z up, as the scene is).
//! The whole file is read before anything is added to the scene, so a refused
//! file adds nothing.

mod command;
pub mod error;
mod functions;
mod lexer;
mod loader;
mod materials;
mod parse;
pub mod report;
mod shapes;
mod sky;

use std::path::Path;

use glam::Mat4;

pub use error::{Location, RadError, RadErrorKind};
pub use report::{NoteKind, RadNote, RadReport};
pub use shapes::{SEGMENTS, SPHERE_BANDS};

use super::ImportOptions;
use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::maps::{MaterialMaps, TexRef, UvTransform};
use crate::scene::material::Sky;
use crate::scene::texture::Encoding;

/// Adds the Radiance file at `path` (and what it includes) to `b`, placed by
/// `transform`; returns what was approximated. Materials are named as in the
/// file; a scene material of the same name (`options.overrides`) replaces
/// one. Sources set the builder's sky, which must not be set already.
pub fn read_rad(
    b: &mut SceneBuilder,
    path: &Path,
    transform: Mat4,
    options: &ImportOptions,
) -> Result<RadReport, SceneError> {
    let bytes = std::fs::read(path).map_err(|source| SceneError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    let mut loader = loader::Loader::default();
    loader.read_root(&bytes, path)?;
    drop(bytes);
    let sky = sky::sky(&loader.sources, &loader.modifiers.slots, transform, &mut loader.report)?;
    if let (Some(_), Some(first)) = (&sky, loader.sources.first()) {
        if *b.current_sky() != Sky::None {
            let kind = RadErrorKind::Source {
                what: first.what.clone(),
                message: "the scene already has a sky from another file".to_string(),
            };
            return Err(RadError::new(&first.at, kind).into());
        }
    }
    let mut ids: Vec<Option<u32>> = vec![None; loader.modifiers.slots.len()];
    let mut materials = Vec::with_capacity(loader.slots.len());
    for &slot in &loader.slots {
        let id = match ids[slot] {
            Some(id) => id,
            None => {
                let s = &loader.modifiers.slots[slot];
                let mut maps = picture_maps(b, s, path);
                maps.patterns = s.patterns.clone();
                let id = super::textured_material(b, options, &s.name, s.material.clone(), maps)?;
                ids[slot] = Some(id);
                id
            }
        };
        materials.push(id);
    }
    if loader.triangles.is_empty() {
        tracing::info!("{}: no visible surfaces", path.display());
    } else {
        let source = path.display().to_string();
        let uvs = (!loader.uvs.is_empty()).then(|| {
            let mut uvs = loader.uvs;
            uvs.resize(loader.positions.len(), glam::Vec2::ZERO);
            uvs
        });
        b.add_mesh_uv(
            &source,
            &loader.positions,
            uvs.as_deref(),
            &loader.triangles,
            &materials,
            transform,
        )?;
    }
    if let Some(sky) = sky {
        b.sky(sky)?;
    }
    Ok(loader.report)
}

/// The maps of material slot `s`: its `colorpict` picture as base colour,
/// placed as picture.cal places it (lower left at the origin, the smaller
/// side 1 long); none without one, or where the picture cannot be read
/// (noted).
fn picture_maps(b: &mut SceneBuilder, s: &materials::Slot, path: &Path) -> MaterialMaps {
    let Some(picture) = &s.picture else {
        return MaterialMaps::default();
    };
    let file = path.display().to_string();
    let image = picture.dir.join(&picture.file);
    match b.textures().load(&image, Encoding::Srgb) {
        Ok(texture) => {
            let (w, h) = b
                .textures()
                .get(texture)
                .map_or((1.0, 1.0), |t| (t.width() as f32, t.height() as f32));
            let side = w.min(h);
            let (u_max, v_max) = (w / side, h / side);
            MaterialMaps {
                base_color: Some(TexRef {
                    texture,
                    wrap: [picture.wrap; 2],
                    // Radiance's v grows upward, the scene's downward.
                    transform: UvTransform {
                        offset: [0.0, 1.0],
                        scale: [1.0 / u_max, -1.0 / v_max],
                        rotation: 0.0,
                    },
                }),
                ..MaterialMaps::default()
            }
        }
        Err(e) => {
            tracing::warn!("{file}: material {:?}: colorpict: {e}; the picture is dropped", s.name);
            b.note(&file, Some(&s.name), format!("colorpict: {e}; dropped"));
            MaterialMaps::default()
        }
    }
}

impl From<RadError> for SceneError {
    fn from(e: RadError) -> SceneError {
        SceneError::Rad(Box::new(e))
    }
}

#[cfg(test)]
mod tests;
