//! `[textures.NAME]` tables of a scene file: the images that texture the
//! scene material `NAME` (for geometry whose own format carries no
//! materials, such as PLY with texture coordinates), and writing them back
//! out for a scene made in memory.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::error::SceneError;
use crate::scene::builder::SceneBuilder;
use crate::scene::maps::{Channel, Coverage, MaterialMaps, Relief, TexRef, UvTransform};
use crate::scene::texture::{Encoding, Wrap};
use crate::scene::Scene;

/// How coordinates outside [0, 1] read, as written in a scene file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum WrapMode {
    /// Tile (the default).
    #[default]
    Repeat,
    /// Continue the edge texel.
    Clamp,
    /// Tile, mirroring every other copy.
    Mirror,
}

impl From<WrapMode> for Wrap {
    fn from(w: WrapMode) -> Wrap {
        match w {
            WrapMode::Repeat => Wrap::Repeat,
            WrapMode::Clamp => Wrap::Clamp,
            WrapMode::Mirror => Wrap::Mirror,
        }
    }
}

/// A `[textures.NAME]` table; image paths are relative to the scene file.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TextureEntry {
    /// Colour image (sRGB) multiplying the material's colour.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub base_color: Option<PathBuf>,
    /// Coverage image: its alpha (or red, for images without alpha) below
    /// `alpha_cutoff` is a hole every ray passes.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha: Option<PathBuf>,
    /// Where coverage becomes a hole (0.5 by default).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub alpha_cutoff: Option<f32>,
    /// Tangent-space normal map.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub normal: Option<PathBuf>,
    /// Height map (red channel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bump: Option<PathBuf>,
    /// Height map strength: a change of 1/scale over one texel tilts 45 degrees.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub bump_scale: Option<f32>,
    /// Roughness image (red channel) multiplying the material's roughness.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub roughness: Option<PathBuf>,
    /// Emission image (sRGB): the surface glows with it times `emission`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emissive: Option<PathBuf>,
    /// Radiance the emission image's white stands for (W/sr/m²).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub emission: Option<[f32; 3]>,
    /// Texture coordinates multiplied by this first.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub scale: Option<[f32; 2]>,
    /// Then this added.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub offset: Option<[f32; 2]>,
    /// How coordinates outside [0, 1] read.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub wrap: Option<WrapMode>,
}

impl TextureEntry {
    /// The maps this table gives, loading its images (relative to `base`)
    /// into `b`; `what` names the table in errors.
    pub fn maps(&self, b: &mut SceneBuilder, base: &Path, what: &str) -> Result<MaterialMaps, SceneError> {
        let transform = UvTransform {
            offset: self.offset.unwrap_or([0.0; 2]),
            scale: self.scale.unwrap_or([1.0; 2]),
            rotation: 0.0,
        };
        if !transform.offset.iter().chain(&transform.scale).all(|v| v.is_finite()) {
            return Err(SceneError::Invalid {
                what: what.to_string(),
                message: "scale and offset must be finite".to_string(),
            });
        }
        let wrap: Wrap = self.wrap.unwrap_or_default().into();
        let load = |b: &mut SceneBuilder,
                    key: &str,
                    file: &Option<PathBuf>,
                    encoding: Encoding|
         -> Result<Option<TexRef>, SceneError> {
            let Some(file) = file else { return Ok(None) };
            let texture = b
                .textures()
                .load(&base.join(file), encoding)
                .map_err(|e| SceneError::Invalid {
                    what: format!("{what} {key}"),
                    message: e.to_string(),
                })?;
            Ok(Some(TexRef {
                texture,
                wrap: [wrap; 2],
                transform,
            }))
        };
        let mut maps = MaterialMaps {
            alpha: 1.0,
            ..MaterialMaps::default()
        };
        maps.base_color = load(b, "base_color", &self.base_color, Encoding::Srgb)?;
        // The colour image's own alpha (the same file): one texture serves
        // both, as alpha is stored linear whatever the colour's encoding.
        let own_alpha = maps.base_color.filter(|t| {
            self.alpha.is_some()
                && self.alpha == self.base_color
                && b.textures().get(t.texture).is_some_and(|t| t.has_alpha)
        });
        if let Some(tex) = own_alpha {
            let cutoff = self.alpha_cutoff.unwrap_or(0.5);
            maps.coverage = Some((Some((tex, Channel::Alpha)), Coverage::Mask { cutoff }));
        } else if let Some(tex) = load(b, "alpha", &self.alpha, Encoding::Linear)? {
            let channel = match b.textures().get(tex.texture) {
                Some(t) if t.has_alpha => Channel::Alpha,
                _ => Channel::Red,
            };
            let cutoff = self.alpha_cutoff.unwrap_or(0.5);
            maps.coverage = Some((Some((tex, channel)), Coverage::Mask { cutoff }));
        }
        if let Some(tex) = load(b, "bump", &self.bump, Encoding::Linear)? {
            let scale = self.bump_scale.unwrap_or(1.0);
            maps.relief = Some((tex, Relief::Height { scale }));
        }
        if let Some(tex) = load(b, "normal", &self.normal, Encoding::Linear)? {
            maps.relief = Some((tex, Relief::Normal { scale: 1.0 }));
        }
        maps.roughness = load(b, "roughness", &self.roughness, Encoding::Linear)?;
        maps.emissive = load(b, "emissive", &self.emissive, Encoding::Srgb)?;
        let emission = self.emission.unwrap_or([1.0; 3]);
        if !emission.iter().all(|v| v.is_finite() && *v >= 0.0) {
            return Err(SceneError::Invalid {
                what: what.to_string(),
                message: format!("emission {emission:?} must be finite and non-negative"),
            });
        }
        maps.emission = if maps.emissive.is_some() { emission } else { [0.0; 3] };
        Ok(maps)
    }
}

/// Writes the textures of `scene`'s materials as PNG files named
/// `stem-N.png` in `dir`, and returns a `[textures.NAME]` table per
/// textured material. Maps a table cannot say (glTF's per-texel model,
/// rotated or per-map placements, partial coverage) are an error.
pub fn write_textures(scene: &Scene, dir: &Path, stem: &str) -> Result<Vec<(String, TextureEntry)>, SceneError> {
    let mut written: Vec<Option<PathBuf>> = vec![None; scene.textures.len()];
    let mut out = Vec::new();
    for (name, maps) in scene.material_names.iter().zip(&scene.maps) {
        if maps.is_empty() {
            continue;
        }
        let unsupported = |why: &str| SceneError::Invalid {
            what: format!("material {name:?}"),
            message: format!("its textures cannot be written to a scene file: {why}"),
        };
        if maps.pbr.is_some() {
            return Err(unsupported("its model is chosen per texel (glTF)"));
        }
        let refs: Vec<&TexRef> = [
            maps.base_color.as_ref(),
            maps.roughness.as_ref(),
            maps.emissive.as_ref(),
        ]
        .into_iter()
        .flatten()
        .chain(maps.relief.as_ref().map(|r| &r.0))
        .chain(maps.coverage.as_ref().and_then(|c| c.0.as_ref()).map(|c| &c.0))
        .collect();
        let Some(first) = refs.first() else {
            return Err(unsupported("coverage without an image"));
        };
        if refs
            .iter()
            .any(|r| r.transform != first.transform || r.wrap != first.wrap)
            || first.transform.rotation != 0.0
        {
            return Err(unsupported("its maps are placed differently"));
        }
        let mut file = |r: Option<&TexRef>| -> Result<Option<PathBuf>, SceneError> {
            let Some(r) = r else { return Ok(None) };
            let i = r.texture as usize;
            if let Some(p) = &written[i] {
                return Ok(Some(p.clone()));
            }
            let texture = scene
                .textures
                .get(r.texture)
                .ok_or_else(|| unsupported("a missing texture"))?;
            let name = PathBuf::from(format!("{stem}-{i}.png"));
            let (w, h, texels) = texture.level0_rgba8().ok_or_else(|| unsupported("a float texture"))?;
            let path = dir.join(&name);
            image::save_buffer(&path, texels.as_flattened(), w, h, image::ColorType::Rgba8).map_err(|e| {
                SceneError::Io {
                    path: path.clone(),
                    source: std::io::Error::other(e.to_string()),
                }
            })?;
            written[i] = Some(name.clone());
            Ok(Some(name))
        };
        let (cutoff, alpha) = match &maps.coverage {
            Some((Some((tex, _)), Coverage::Mask { cutoff })) => (Some(*cutoff), file(Some(tex))?),
            Some(_) => return Err(unsupported("partial coverage")),
            None => (None, None),
        };
        let (normal, bump, bump_scale) = match &maps.relief {
            Some((tex, Relief::Normal { .. })) => (file(Some(tex))?, None, None),
            Some((tex, Relief::Height { scale })) => (None, file(Some(tex))?, Some(*scale)),
            None => (None, None, None),
        };
        let wrap = match first.wrap[0] {
            Wrap::Repeat => None,
            Wrap::Clamp => Some(WrapMode::Clamp),
            Wrap::Mirror => Some(WrapMode::Mirror),
        };
        let t = first.transform;
        out.push((
            name.clone(),
            TextureEntry {
                base_color: file(maps.base_color.as_ref())?,
                alpha,
                alpha_cutoff: cutoff,
                normal,
                bump,
                bump_scale,
                roughness: file(maps.roughness.as_ref())?,
                emissive: file(maps.emissive.as_ref())?,
                emission: maps.emissive.is_some().then_some(maps.emission),
                scale: (t.scale != [1.0; 2]).then_some(t.scale),
                offset: (t.offset != [0.0; 2]).then_some(t.offset),
                wrap,
            },
        ));
    }
    Ok(out)
}
