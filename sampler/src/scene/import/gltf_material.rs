//! glTF materials as the specification defines them, mapped onto ours.
//!
//! Metallic-roughness with its defaults (metallic and roughness factors 1,
//! multiplied by the texture's blue and green channels): where a
//! metallic-roughness texture is given, the model is chosen per texel
//! ([`pbr_material`]), so a textured material is metal only where its
//! texture says so. `baseColorTexture` (sRGB, with its sampler's wrap modes
//! and `KHR_texture_transform`) multiplies the base colour; `normalTexture`
//! bends the shading normal (tangents are generated from the texture
//! coordinates); alpha modes MASK (with `alphaCutoff`) and BLEND (partial
//! coverage) cut holes every ray passes; `KHR_materials_transmission`
//! (factor), `_ior`, `_emissive_strength` and `_clearcoat` (factor and
//! roughness: a dielectric under a coat becomes plastic with the coat's
//! roughness) are read. Emission glows only
//! through `emissiveTexture` (times its factor and strength) on a surface
//! that keeps its model, or as an emitter where the factor alone glows.
//! Dropped (noted): occlusion textures (the path tracer finds occlusion itself), transmission
//! and clear-coat textures, a clear coat over metal, texture coordinate sets other
//! than 0, and other extensions.

use std::path::Path;

use glam::Vec2;

use super::unit_color;
use crate::scene::builder::SceneBuilder;
use crate::scene::maps::{pbr_material, Channel, Coverage, MaterialMaps, Pbr, Relief, TexRef, UvTransform};
use crate::scene::material::Material;
use crate::scene::texture::{Encoding, Wrap};

/// What converting materials needs from the file.
pub(super) struct Source<'a> {
    /// The glTF or GLB file, for messages and relative image paths.
    pub path: &'a Path,
    /// Its buffers' bytes, for images stored in buffer views.
    pub buffers: &'a [gltf::buffer::Data],
}

impl Source<'_> {
    /// Our material and maps for glTF material `m` (named `name` in notes).
    ///
    /// Long because it reads glTF's material properties one after another
    /// (emission, occlusion, base colour with metal and roughness,
    /// transmission and IOR, normals, alpha), each with the note that says
    /// what is approximated or ignored next to the property it concerns, and
    /// then fixes the material those factors and textures make.
    pub(super) fn convert(&self, b: &mut SceneBuilder, m: &gltf::Material, name: &str) -> (Material, MaterialMaps) {
        let file = self.path.display().to_string();
        let note = |b: &mut SceneBuilder, what: String| b.note(&file, Some(name), what);
        let strength = m
            .emissive_strength()
            .filter(|s| s.is_finite() && *s >= 0.0)
            .unwrap_or(1.0);
        let emissive = m
            .emissive_factor()
            .map(|v| if v.is_finite() { (v * strength).max(0.0) } else { 0.0 });
        let glow = m
            .emissive_texture()
            .filter(|_| emissive.iter().any(|&v| v > 0.0))
            .and_then(|info| self.texture(b, &info, Encoding::Srgb, name, "emissiveTexture"));
        if glow.is_none() && m.emissive_texture().is_none() && emissive.iter().any(|&v| v > 0.0) {
            return (Material::Emitter { radiance: emissive }, MaterialMaps::default());
        }
        if m.occlusion_texture().is_some() {
            note(
                b,
                "occlusionTexture is not used (the path tracer finds occlusion)".to_string(),
            );
        }
        let pbr = m.pbr_metallic_roughness();
        let [r, g, bl, a] = pbr.base_color_factor();
        let base = unit_color([r, g, bl]);
        let mut maps = MaterialMaps {
            alpha: if a.is_finite() { a.clamp(0.0, 1.0) } else { 1.0 },
            emissive: glow,
            emission: if glow.is_some() { emissive } else { [0.0; 3] },
            ..MaterialMaps::default()
        };
        maps.base_color = pbr
            .base_color_texture()
            .and_then(|info| self.texture(b, &info, Encoding::Srgb, name, "baseColorTexture"));
        let mr = pbr
            .metallic_roughness_texture()
            .and_then(|info| self.texture(b, &info, Encoding::Linear, name, "metallicRoughnessTexture"));
        let (transmission, ior) = (
            m.transmission().map_or(0.0, |t| t.transmission_factor()),
            m.ior().unwrap_or(1.5),
        );
        if m.transmission().is_some_and(|t| t.transmission_texture().is_some()) {
            note(b, "transmissionTexture is not used; the factor is".to_string());
        }
        if let Some(normal) = m.normal_texture() {
            if normal.tex_coord() != 0 {
                note(
                    b,
                    format!("normalTexture uses TEXCOORD_{}; only set 0 is read", normal.tex_coord()),
                );
            }
            let scale = if normal.scale().is_finite() {
                normal.scale()
            } else {
                1.0
            };
            maps.relief = self
                .image(b, &normal.texture(), Encoding::Linear, name, "normalTexture")
                .map(|t| (t, Relief::Normal { scale }));
        }
        let coverage_source = maps.base_color.map(|t| (t, Channel::Alpha));
        maps.coverage = match m.alpha_mode() {
            gltf::material::AlphaMode::Opaque => None,
            gltf::material::AlphaMode::Mask => {
                let cutoff = m.alpha_cutoff().filter(|c| c.is_finite()).unwrap_or(0.5);
                Some((coverage_source, Coverage::Mask { cutoff }))
            }
            gltf::material::AlphaMode::Blend => Some((coverage_source, Coverage::Blend)),
        };
        // The model out of core and for light sampling: the factors times
        // the textures' means.
        let textures = b.textures();
        let mean = |t: &TexRef| {
            textures
                .get(t.texture)
                .map(|tex| tex.sample(Vec2::splat(0.5), [Wrap::Repeat; 2], f32::MAX))
        };
        let tint = maps
            .base_color
            .as_ref()
            .and_then(mean)
            .map_or([1.0; 3], |c| c.truncate().to_array());
        let mr_mean = mr.as_ref().and_then(mean);
        let (metallic, roughness) = (pbr.metallic_factor(), pbr.roughness_factor());
        let clearcoat = self.clearcoat(b, m, name);
        if clearcoat.is_some() && metallic * mr_mean.map_or(1.0, |c| c.z) >= 0.5 {
            note(
                b,
                "KHR_materials_clearcoat over metal is not modelled; the metal shows alone".to_string(),
            );
        }
        let material = pbr_material(
            [base[0] * tint[0], base[1] * tint[1], base[2] * tint[2]],
            metallic * mr_mean.map_or(1.0, |c| c.z),
            roughness * mr_mean.map_or(1.0, |c| c.y),
            transmission,
            ior,
            clearcoat,
        );
        if mr.is_some() {
            maps.pbr = Some(Pbr {
                base,
                metallic,
                roughness,
                texture: mr,
                transmission,
                ior,
                clearcoat,
            });
        } else if maps.base_color.is_some() || maps.emissive.is_some() {
            // The model is fixed by the factors; the texture tints it.
            maps.pbr = Some(Pbr {
                base,
                metallic,
                roughness,
                texture: None,
                transmission,
                ior,
                clearcoat,
            });
        }
        (material, maps)
    }

    /// The roughness of `m`'s clear coat (`KHR_materials_clearcoat`) where
    /// it covers the surface (factor at least 0.5); the coat's textures are
    /// read as their factors (noted).
    fn clearcoat(&self, b: &mut SceneBuilder, m: &gltf::Material, name: &str) -> Option<f32> {
        let coat = m.extension_value("KHR_materials_clearcoat")?;
        let number = |key: &str| {
            coat.get(key)
                .and_then(gltf::json::Value::as_f64)
                .filter(|v| v.is_finite())
                .map(|v| v.clamp(0.0, 1.0) as f32)
        };
        let file = self.path.display().to_string();
        for key in [
            "clearcoatTexture",
            "clearcoatRoughnessTexture",
            "clearcoatNormalTexture",
        ] {
            if coat.get(key).is_some() {
                b.note(
                    &file,
                    Some(name),
                    format!("KHR_materials_clearcoat: {key} is not used; the factors are"),
                );
            }
        }
        let factor = number("clearcoatFactor").unwrap_or(0.0);
        if factor > 0.0 && factor < 1.0 {
            b.note(
                &file,
                Some(name),
                format!(
                    "KHR_materials_clearcoat: factor {factor} rounded to {}",
                    u8::from(factor >= 0.5)
                ),
            );
        }
        (factor >= 0.5).then(|| number("clearcoatRoughnessFactor").unwrap_or(0.0))
    }

    /// The texture a material's texture reference names, placed by its
    /// `KHR_texture_transform` and wrapped as its sampler says.
    fn texture(
        &self,
        b: &mut SceneBuilder,
        info: &gltf::texture::Info,
        encoding: Encoding,
        name: &str,
        key: &str,
    ) -> Option<TexRef> {
        let file = self.path.display().to_string();
        let mut tex = self.image(b, &info.texture(), encoding, name, key)?;
        let mut set = info.tex_coord();
        if let Some(t) = info.texture_transform() {
            tex.transform = UvTransform {
                offset: t.offset(),
                scale: t.scale(),
                rotation: t.rotation(),
            };
            if let Some(s) = t.tex_coord() {
                set = s;
            }
        }
        if set != 0 {
            b.note(
                &file,
                Some(name),
                format!("{key} uses TEXCOORD_{set}; only set 0 is read"),
            );
        }
        Some(tex)
    }

    /// The image of glTF texture `texture`, loaded once, with its wrap modes.
    fn image(
        &self,
        b: &mut SceneBuilder,
        texture: &gltf::Texture,
        encoding: Encoding,
        name: &str,
        key: &str,
    ) -> Option<TexRef> {
        let file = self.path.display().to_string();
        let image = texture.source();
        let loaded = match image.source() {
            gltf::image::Source::View { view, .. } => {
                let bytes = self.buffers.get(view.buffer().index()).and_then(|data| {
                    let end = view.offset().checked_add(view.length())?;
                    data.0.get(view.offset()..end)
                });
                match bytes {
                    Some(bytes) => {
                        let label = format!("{file}#image{}", image.index());
                        b.textures()
                            .load_bytes(&label, bytes, encoding)
                            .map_err(|e| e.to_string())
                    }
                    None => Err(format!("image {} lies outside its buffer", image.index())),
                }
            }
            gltf::image::Source::Uri { uri, .. } => match uri.strip_prefix("data:") {
                Some(data) => match data.split_once(";base64,") {
                    Some((_, encoded)) => match base64::decode(encoded) {
                        Ok(bytes) => {
                            let label = format!("{file}#image{}", image.index());
                            b.textures()
                                .load_bytes(&label, &bytes, encoding)
                                .map_err(|e| e.to_string())
                        }
                        Err(e) => Err(format!("image {}: data URI: {e}", image.index())),
                    },
                    None => Err(format!("image {}: data URI is not base64", image.index())),
                },
                None => {
                    let plain =
                        !uri.contains(':') && !uri.starts_with('/') && !uri.split(['/', '\\']).any(|c| c == "..");
                    if plain {
                        let path = self.path.parent().unwrap_or(Path::new(".")).join(percent_decoded(uri));
                        b.textures().load(&path, encoding).map_err(|e| e.to_string())
                    } else {
                        Err(format!("image URI {uri:?} is not a relative file path"))
                    }
                }
            },
        };
        match loaded {
            Ok(index) => {
                let sampler = texture.sampler();
                let wrap = |w: gltf::texture::WrappingMode| match w {
                    gltf::texture::WrappingMode::ClampToEdge => Wrap::Clamp,
                    gltf::texture::WrappingMode::MirroredRepeat => Wrap::Mirror,
                    gltf::texture::WrappingMode::Repeat => Wrap::Repeat,
                };
                Some(TexRef {
                    texture: index,
                    wrap: [wrap(sampler.wrap_s()), wrap(sampler.wrap_t())],
                    transform: UvTransform::default(),
                })
            }
            Err(e) => {
                tracing::warn!("{file}: material {name:?}: {key}: {e}; the map is dropped");
                b.note(&file, Some(name), format!("{key}: {e}; dropped"));
                None
            }
        }
    }
}

/// A URI's percent escapes decoded (`%20` to a space); malformed escapes
/// stay as written.
fn percent_decoded(uri: &str) -> String {
    let bytes = uri.as_bytes();
    let mut out = Vec::with_capacity(bytes.len());
    let mut i = 0;
    while i < bytes.len() {
        let hex = |c: u8| (c as char).to_digit(16);
        if bytes[i] == b'%' && i + 2 < bytes.len() {
            if let (Some(h), Some(l)) = (hex(bytes[i + 1]), hex(bytes[i + 2])) {
                out.push((h * 16 + l) as u8);
                i += 3;
                continue;
            }
        }
        out.push(bytes[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}
