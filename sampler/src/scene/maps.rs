//! What textures do to a material: base colour multiplying its colour,
//! glTF's metallic-roughness texture choosing its model per texel, alpha
//! coverage (cut-outs and partial coverage), and normal or height maps
//! bending its shading normal. A material without maps shades as written.

use glam::{Vec2, Vec3, Vec4};
use serde::{Deserialize, Serialize};

use super::material::Material;
use super::texture::{TextureSet, Wrap};

/// A placement of 2D texture coordinates: scale, then rotate
/// (counter-clockwise, radians), then offset, as glTF's
/// `KHR_texture_transform` and MTL's `-s`/`-o` options give it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct UvTransform {
    /// Added after scaling and rotating.
    pub offset: [f32; 2],
    /// Multiplies the coordinates first.
    pub scale: [f32; 2],
    /// Rotation, radians.
    pub rotation: f32,
}

impl Default for UvTransform {
    fn default() -> Self {
        UvTransform {
            offset: [0.0; 2],
            scale: [1.0; 2],
            rotation: 0.0,
        }
    }
}

impl UvTransform {
    /// The coordinates `uv` placed.
    #[inline]
    pub fn apply(&self, uv: Vec2) -> Vec2 {
        let s = uv * Vec2::from_array(self.scale);
        let (sin, cos) = self.rotation.sin_cos();
        // glTF's matrix: [cos, sin; -sin, cos] applied to (u, v).
        let r = Vec2::new(cos * s.x + sin * s.y, -sin * s.x + cos * s.y);
        r + Vec2::from_array(self.offset)
    }

    /// Whether it changes nothing.
    pub fn is_identity(&self) -> bool {
        *self == UvTransform::default()
    }
}

/// One texture as a material uses it.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TexRef {
    /// Index into the scene's [`TextureSet`].
    pub texture: u32,
    /// Wrapping along u and v.
    pub wrap: [Wrap; 2],
    /// Placement of the coordinates.
    pub transform: UvTransform,
}

impl TexRef {
    /// A repeating, unplaced use of `texture`.
    pub fn new(texture: u32) -> TexRef {
        TexRef {
            texture,
            wrap: [Wrap::Repeat; 2],
            transform: UvTransform::default(),
        }
    }

    /// The linear RGBA value at surface coordinates `uv` for a footprint
    /// `width` wide in coordinate units; white where the texture is missing.
    #[inline]
    pub fn sample(&self, textures: &TextureSet, uv: Vec2, width: f32) -> Vec4 {
        let Some(t) = textures.get(self.texture) else {
            return Vec4::ONE;
        };
        let scale = Vec2::from_array(self.transform.scale).abs().max_element();
        let texels = width * scale * t.width().max(t.height()) as f32;
        t.sample(
            self.transform.apply(uv),
            self.wrap,
            super::texture::Texture::lod_for(texels),
        )
    }
}

/// Which channel of a coverage texture holds coverage.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Channel {
    /// The alpha channel (glTF; MTL `map_d` images that have one).
    Alpha,
    /// The red channel (MTL `map_d` greyscale images).
    Red,
}

/// How much of a surface is there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Coverage {
    /// Alpha below `cutoff` is a hole, above it solid (glTF MASK, MTL `map_d`).
    Mask {
        /// The threshold (0.5 by default).
        cutoff: f32,
    },
    /// Alpha is the fraction of rays the surface stops; the rest pass
    /// (glTF BLEND, MTL `d` below 1 on an opaque model).
    Blend,
}

/// How a normal map encodes the surface.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub enum Relief {
    /// Tangent-space normals in RGB (glTF `normalTexture`, MTL `norm`),
    /// scaled in x and y by `scale`.
    Normal {
        /// glTF's `normalTexture.scale`.
        scale: f32,
    },
    /// Heights in the red channel (MTL `bump`/`map_Bump`): a change of
    /// 1/`scale` (`-bm`) from one texel to the next tilts the surface 45 degrees.
    Height {
        /// The bump multiplier.
        scale: f32,
    },
}

/// glTF's metallic-roughness model with its factors, for materials whose
/// metalness or roughness comes from a texture: the model is chosen per texel.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Pbr {
    /// Base colour factor (linear RGB).
    pub base: [f32; 3],
    /// Metallic factor.
    pub metallic: f32,
    /// Roughness factor.
    pub roughness: f32,
    /// The metallic-roughness texture (roughness in green, metalness in blue).
    pub texture: Option<TexRef>,
    /// Transmission factor (`KHR_materials_transmission`).
    pub transmission: f32,
    /// Index of refraction (`KHR_materials_ior`).
    pub ior: f32,
    /// The roughness of a clear coat over a dielectric base, where
    /// `KHR_materials_clearcoat` covers it (factor at least 0.5).
    pub clearcoat: Option<f32>,
}

/// The textures of one material; all empty for an untextured one.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialMaps {
    /// Multiplies the material's colour (albedo, metal or glass colour).
    pub base_color: Option<TexRef>,
    /// Alpha coverage: the texture and channel it reads, and what it means.
    /// Without a texture, `alpha` below is the coverage everywhere.
    pub coverage: Option<(Option<(TexRef, Channel)>, Coverage)>,
    /// Constant alpha that multiplies the texture's (glTF base colour factor's alpha).
    pub alpha: f32,
    /// A normal or height map.
    pub relief: Option<(TexRef, Relief)>,
    /// Metalness and roughness from a texture (glTF).
    pub pbr: Option<Pbr>,
    /// Roughness from a texture's red channel, multiplying the material's (MTL `map_Pr`).
    pub roughness: Option<TexRef>,
    /// Emission from a texture (sRGB) times `emission`, added to what the
    /// material emits (MTL `map_Ke` with `Ke`, glTF `emissiveTexture` with
    /// its factor and strength).
    pub emissive: Option<TexRef>,
    /// The radiance an emission texture's white stands for.
    pub emission: [f32; 3],
    /// Radiance function and data patterns, applied in order at every hit.
    pub patterns: Vec<crate::scene::pattern::Pattern>,
}

impl Default for MaterialMaps {
    fn default() -> Self {
        MaterialMaps {
            base_color: None,
            coverage: None,
            alpha: 1.0,
            relief: None,
            pbr: None,
            roughness: None,
            emissive: None,
            emission: [0.0; 3],
            patterns: Vec::new(),
        }
    }
}

impl MaterialMaps {
    /// The textures it uses, in a fixed order (base colour, roughness,
    /// relief, coverage, metallic-roughness), with a mutable handle on each.
    pub fn refs_mut(&mut self) -> Vec<&mut TexRef> {
        let mut out: Vec<&mut TexRef> = Vec::new();
        out.extend(self.base_color.as_mut());
        out.extend(self.roughness.as_mut());
        out.extend(self.relief.as_mut().map(|r| &mut r.0));
        out.extend(self.coverage.as_mut().and_then(|c| c.0.as_mut()).map(|c| &mut c.0));
        out.extend(self.pbr.as_mut().and_then(|p| p.texture.as_mut()));
        out.extend(self.emissive.as_mut());
        out
    }

    /// The emission factor and the emission texture's mean colour, where
    /// the material glows through a texture.
    pub fn emissive_parts(&self, textures: &TextureSet) -> Option<(Vec3, Vec3)> {
        let tex = self.emissive?;
        let factor = Vec3::from_array(self.emission);
        if factor.max_element() <= 0.0 {
            return None;
        }
        Some((factor, tex.sample(textures, Vec2::splat(0.5), f32::MAX).truncate()))
    }

    /// Radiance emitted at `uv` through the emission texture (zero without one).
    pub fn emission_at(&self, textures: &TextureSet, uv: Vec2, width: f32) -> Vec3 {
        match &self.emissive {
            Some(t) => Vec3::from_array(self.emission) * t.sample(textures, uv, width).truncate(),
            None => Vec3::ZERO,
        }
    }

    /// Whether the material shades as written.
    pub fn is_empty(&self) -> bool {
        self.base_color.is_none()
            && self.coverage.is_none()
            && self.relief.is_none()
            && self.pbr.is_none()
            && self.roughness.is_none()
            && self.emissive.is_none()
            && self.patterns.is_empty()
    }

    /// Whether rays may pass through parts of the surface.
    pub fn cuts(&self) -> bool {
        self.coverage.is_some()
    }

    /// The fraction of the surface present at `uv`, and how to read it.
    pub fn coverage_at(&self, textures: &TextureSet, uv: Vec2) -> Option<(f32, Coverage)> {
        let (source, kind) = self.coverage?;
        let alpha = match source {
            Some((tex, channel)) => {
                let c = tex.sample(textures, uv, 0.0);
                match channel {
                    Channel::Alpha => c.w,
                    Channel::Red => c.x,
                }
            }
            None => 1.0,
        };
        Some((alpha * self.alpha, kind))
    }

    /// Whether a ray passes the surface at `uv`; `u` is a uniform number in
    /// [0, 1) for partial coverage.
    pub fn passes(&self, textures: &TextureSet, uv: Vec2, u: f32) -> bool {
        match self.coverage_at(textures, uv) {
            None => false,
            Some((alpha, Coverage::Mask { cutoff })) => alpha < cutoff,
            Some((alpha, Coverage::Blend)) => u >= alpha,
        }
    }

    /// `m` as it is at surface coordinates `uv`, for a footprint `width`
    /// coordinate units wide.
    pub fn material_at(&self, m: &Material, textures: &TextureSet, uv: Vec2, width: f32) -> Material {
        let tint = self
            .base_color
            .map(|t| t.sample(textures, uv, width).truncate())
            .unwrap_or(Vec3::ONE);
        if let Some(p) = &self.pbr {
            let (mut metallic, mut roughness) = (p.metallic, p.roughness);
            if let Some(t) = &p.texture {
                let mr = t.sample(textures, uv, width);
                roughness *= mr.y;
                metallic *= mr.z;
            }
            let base = (Vec3::from_array(p.base) * tint).to_array();
            return pbr_material(base, metallic, roughness, p.transmission, p.ior, p.clearcoat);
        }
        if matches!(m, Material::Emitter { .. }) {
            return m.clone();
        }
        let mut out = tinted(m, tint);
        if let (Some(t), Material::Plastic { roughness, .. } | Material::Metal { roughness, .. }) =
            (&self.roughness, &mut out)
        {
            *roughness = (*roughness * t.sample(textures, uv, width).x).clamp(0.0, 1.0);
        }
        out
    }

    /// The shading normal at `uv` from the relief map, given the unit
    /// geometric normal `n` and the surface's tangent `t` and bitangent `b`
    /// (the directions in which u and v grow, world units per coordinate
    /// unit); `None` without a relief map or with a degenerate frame.
    pub fn normal_at(&self, textures: &TextureSet, uv: Vec2, n: Vec3, t: Vec3, b: Vec3) -> Option<Vec3> {
        let (tex, relief) = self.relief?;
        let shading = match relief {
            Relief::Normal { scale } => {
                let c = tex.sample(textures, uv, 0.0);
                let x = (c.x * 2.0 - 1.0) * scale;
                let y = (c.y * 2.0 - 1.0) * scale;
                let z = (c.z * 2.0 - 1.0).max(0.0);
                // Gram-Schmidt: a tangent frame orthonormal around n.
                let tu = (t - n * n.dot(t)).try_normalize()?;
                let handed = if n.cross(tu).dot(b) < 0.0 { -1.0 } else { 1.0 };
                // glTF's green channel points toward +v of OpenGL's texture space,
                // which is -v in ours (v grows downward).
                let tv = n.cross(tu) * handed;
                tu * x - tv * y + n * z
            }
            Relief::Height { scale } => {
                let texture = textures.get(tex.texture)?;
                let du = 1.0 / texture.width() as f32;
                let dv = 1.0 / texture.height() as f32;
                let h = |o: Vec2| tex.sample(textures, uv + o, 0.0).x;
                let h0 = h(Vec2::ZERO);
                // One texel's step along u and along v on the surface, lifted
                // by the change of height over it: a height step of `scale`
                // over one texel tilts the surface 45 degrees, whatever the
                // scene's units.
                let (su, sv) = (t * du, b * dv);
                let pu = su + n * ((h(Vec2::new(du, 0.0)) - h0) * scale * su.length());
                let pv = sv + n * ((h(Vec2::new(0.0, dv)) - h0) * scale * sv.length());
                let m = pu.cross(pv);
                if m.dot(n) < 0.0 {
                    -m
                } else {
                    m
                }
            }
        };
        let s = shading.try_normalize()?;
        s.is_finite().then_some(s)
    }
}

/// `m` with its colour multiplied by `c` (a texture's or a pattern's):
/// reflectances stay within [0, 1]; an emitter's radiance is multiplied
/// as it is.
pub fn tinted(m: &Material, c: Vec3) -> Material {
    if c == Vec3::ONE {
        return m.clone();
    }
    let mul = |x: &[f32; 3]| unit((Vec3::from_array(*x) * c).to_array());
    match m {
        Material::Lambertian { albedo, emission } => Material::Lambertian {
            albedo: mul(albedo),
            emission: *emission,
        },
        Material::Plastic { albedo, roughness, ior } => Material::Plastic {
            albedo: mul(albedo),
            roughness: *roughness,
            ior: *ior,
        },
        Material::Metal { color, roughness } => Material::Metal {
            color: mul(color),
            roughness: *roughness,
        },
        Material::Mirror { color } => Material::Mirror { color: mul(color) },
        Material::Glass { ior, color, thin } => Material::Glass {
            ior: *ior,
            color: mul(color),
            thin: *thin,
        },
        Material::Emitter { radiance } => Material::Emitter {
            radiance: (Vec3::from_array(*radiance) * c)
                .to_array()
                .map(|v| if v.is_finite() { v.max(0.0) } else { 0.0 }),
        },
    }
}

/// Clamps a colour into [0, 1].
fn unit(c: [f32; 3]) -> [f32; 3] {
    c.map(|v| if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) })
}

/// Our model for glTF's metallic-roughness parameters at one point:
/// mostly transmissive is glass; metallic at least 0.5 is metal; a
/// dielectric under a clear coat (`clearcoat`, the coat's roughness) is
/// plastic with the coat's roughness; roughness below 0.9 is plastic (a
/// dielectric coat over the base colour); else diffuse. What this
/// approximates: metalness between 0 and 1 is rounded to one model, the
/// dielectric's specular level is glTF's fixed 4%, a clear coat replaces
/// the base's own specular lobe, and a coat over metal is not modelled.
pub fn pbr_material(
    base: [f32; 3],
    metallic: f32,
    roughness: f32,
    transmission: f32,
    ior: f32,
    clearcoat: Option<f32>,
) -> Material {
    let finite01 = |v: f32, default: f32| if v.is_finite() { v.clamp(0.0, 1.0) } else { default };
    let color = unit(base);
    let (metallic, roughness) = (finite01(metallic, 1.0), finite01(roughness, 1.0));
    let ior = if ior.is_finite() && ior >= 1.0 { ior } else { 1.5 };
    if finite01(transmission, 0.0) >= 0.5 && metallic < 0.5 {
        return Material::Glass {
            ior,
            color,
            thin: false,
        };
    }
    if metallic >= 0.5 {
        Material::Metal { color, roughness }
    } else if let Some(coat) = clearcoat {
        Material::Plastic {
            albedo: color,
            roughness: finite01(coat, 0.0),
            ior: 1.5,
        }
    } else if roughness < 0.9 {
        Material::Plastic {
            albedo: color,
            roughness,
            ior,
        }
    } else {
        Material::lambertian(color)
    }
}
