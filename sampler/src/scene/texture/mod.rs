//! Image textures as the path tracer reads them: decoded once, kept as a
//! mip pyramid (8-bit texels where the file has 8 bits, floats for HDR),
//! looked up with bilinear filtering between two levels chosen by the
//! ray's footprint, with repeat, clamp or mirror wrapping.
//!
//! Texture coordinates follow glTF: (0, 0) is the image's top-left corner,
//! v grows downward. Importers of formats whose v grows upward (OBJ, PLY)
//! flip v when they read it. Loading files, the limits and the sharing of
//! one image among many materials are in [`set`].

pub mod set;

use std::sync::LazyLock;

use glam::{Vec2, Vec4};

pub use set::{TextureError, TextureSet, MAX_TEXTURE_PIXELS};

/// How a texture's 8-bit values become linear numbers.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Encoding {
    /// Colour (base colour, emission): sRGB-encoded, decoded to linear.
    Srgb,
    /// Data (alpha masks, roughness, normals, heights): used as stored.
    Linear,
}

/// What a coordinate outside [0, 1] reads.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
pub enum Wrap {
    /// The image tiles (the default of OBJ and glTF).
    #[default]
    Repeat,
    /// The edge texel continues.
    Clamp,
    /// The image tiles, every other copy mirrored.
    Mirror,
}

/// The texels of one level, row by row from the top.
#[derive(Clone, Debug)]
enum Texels {
    /// Four 8-bit channels (RGBA), encoded as the texture's [`Encoding`] says.
    Byte(Vec<[u8; 4]>),
    /// Four linear float channels (RGBA), for high-dynamic-range images.
    Float(Vec<[f32; 4]>),
}

/// One level of the pyramid.
#[derive(Clone, Debug)]
struct Level {
    width: u32,
    height: u32,
    texels: Texels,
}

impl Level {
    /// The linear value of texel (x, y), both in range.
    #[inline]
    fn texel(&self, x: u32, y: u32, encoding: Encoding) -> Vec4 {
        let i = (y * self.width + x) as usize;
        match &self.texels {
            Texels::Byte(t) => {
                let [r, g, b, a] = t[i];
                match encoding {
                    Encoding::Srgb => {
                        let lut = &*SRGB_TO_LINEAR;
                        Vec4::new(lut[r as usize], lut[g as usize], lut[b as usize], f32::from(a) / 255.0)
                    }
                    Encoding::Linear => Vec4::new(
                        f32::from(r) / 255.0,
                        f32::from(g) / 255.0,
                        f32::from(b) / 255.0,
                        f32::from(a) / 255.0,
                    ),
                }
            }
            Texels::Float(t) => Vec4::from_array(t[i]),
        }
    }

    /// Bilinear lookup at texture coordinates `uv`, wrapped as `wrap` says.
    fn bilinear(&self, uv: Vec2, wrap: [Wrap; 2], encoding: Encoding) -> Vec4 {
        let x = uv.x * self.width as f32 - 0.5;
        let y = uv.y * self.height as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let xs = [
            wrap_index(x0, self.width, wrap[0]),
            wrap_index(x0 + 1.0, self.width, wrap[0]),
        ];
        let ys = [
            wrap_index(y0, self.height, wrap[1]),
            wrap_index(y0 + 1.0, self.height, wrap[1]),
        ];
        let top = self.texel(xs[0], ys[0], encoding) * (1.0 - fx) + self.texel(xs[1], ys[0], encoding) * fx;
        let bottom = self.texel(xs[0], ys[1], encoding) * (1.0 - fx) + self.texel(xs[1], ys[1], encoding) * fx;
        top * (1.0 - fy) + bottom * fy
    }

    /// Bytes its texels take.
    fn bytes(&self) -> usize {
        match &self.texels {
            Texels::Byte(t) => t.len() * 4,
            Texels::Float(t) => t.len() * 16,
        }
    }
}

/// Texel index `i` (possibly outside the image) of an axis `n` texels long.
#[inline]
fn wrap_index(i: f32, n: u32, wrap: Wrap) -> u32 {
    let n_f = n as f32;
    // Non-finite coordinates (NaN UVs) read texel 0.
    if !i.is_finite() {
        return 0;
    }
    let k = match wrap {
        Wrap::Repeat => i.rem_euclid(n_f),
        Wrap::Clamp => i.clamp(0.0, n_f - 1.0),
        Wrap::Mirror => {
            let period = i.rem_euclid(2.0 * n_f);
            if period >= n_f {
                2.0 * n_f - 1.0 - period
            } else {
                period
            }
        }
    };
    (k as u32).min(n - 1)
}

/// sRGB to linear for every 8-bit value.
static SRGB_TO_LINEAR: LazyLock<[f32; 256]> = LazyLock::new(|| {
    let mut lut = [0.0; 256];
    for (i, v) in lut.iter_mut().enumerate() {
        *v = srgb_to_linear(i as f32 / 255.0);
    }
    lut
});

/// The sRGB transfer function's inverse.
pub fn srgb_to_linear(c: f32) -> f32 {
    if c <= 0.04045 {
        c / 12.92
    } else {
        ((c + 0.055) / 1.055).powf(2.4)
    }
}

/// The sRGB transfer function.
pub fn linear_to_srgb(c: f32) -> f32 {
    if c <= 0.003_130_8 {
        c * 12.92
    } else {
        1.055 * c.powf(1.0 / 2.4) - 0.055
    }
}

/// An image texture: a mip pyramid with the name it was loaded under.
#[derive(Clone, Debug)]
pub struct Texture {
    /// Where it came from (a path, or a name for generated images), for reports.
    pub name: String,
    encoding: Encoding,
    levels: Vec<Level>,
    /// Whether any texel's alpha is below 1 (an alpha mask can cut it).
    pub has_alpha: bool,
    /// BLAKE3 of the full-size texels, for the scene's content hash.
    pub digest: [u8; 32],
}

impl Texture {
    /// A texture from 8-bit RGBA texels, `width` × `height`, rows from the top.
    pub fn from_rgba8(
        name: &str,
        width: u32,
        height: u32,
        texels: Vec<[u8; 4]>,
        encoding: Encoding,
    ) -> Result<Texture, TextureError> {
        check_size(name, width, height, texels.len())?;
        let has_alpha = texels.iter().any(|t| t[3] < 255);
        let digest = *blake3::hash(bytemuck_bytes(&texels)).as_bytes();
        let mut levels = vec![Level {
            width,
            height,
            texels: Texels::Byte(texels),
        }];
        while let Some(next) = levels.last().and_then(|l| halve(l, encoding)) {
            levels.push(next);
        }
        Ok(Texture {
            name: name.to_string(),
            encoding,
            levels,
            has_alpha,
            digest,
        })
    }

    /// A texture from linear float RGBA texels (a high-dynamic-range image).
    pub fn from_rgba32f(name: &str, width: u32, height: u32, texels: Vec<[f32; 4]>) -> Result<Texture, TextureError> {
        check_size(name, width, height, texels.len())?;
        // Non-finite or negative texels would poison every estimate that reads them.
        let texels: Vec<[f32; 4]> = texels
            .into_iter()
            .map(|t| t.map(|c| if c.is_finite() { c.max(0.0) } else { 0.0 }))
            .collect();
        let has_alpha = texels.iter().any(|t| t[3] < 1.0);
        let mut hasher = blake3::Hasher::new();
        for t in &texels {
            for c in t {
                hasher.update(&c.to_bits().to_le_bytes());
            }
        }
        let digest = *hasher.finalize().as_bytes();
        let mut levels = vec![Level {
            width,
            height,
            texels: Texels::Float(texels),
        }];
        while let Some(next) = levels.last().and_then(|l| halve(l, Encoding::Linear)) {
            levels.push(next);
        }
        Ok(Texture {
            name: name.to_string(),
            encoding: Encoding::Linear,
            levels,
            has_alpha,
            digest,
        })
    }

    /// Width of the full-size image, texels.
    pub fn width(&self) -> u32 {
        self.levels[0].width
    }

    /// Height of the full-size image, texels.
    pub fn height(&self) -> u32 {
        self.levels[0].height
    }

    /// How its 8-bit texels are decoded.
    pub fn encoding(&self) -> Encoding {
        self.encoding
    }

    /// Levels in the pyramid (1 for a 1×1 image).
    pub fn levels(&self) -> usize {
        self.levels.len()
    }

    /// The full-size image as 8-bit RGBA texels, as stored (width, height,
    /// texels); `None` for a float texture.
    pub fn level0_rgba8(&self) -> Option<(u32, u32, &[[u8; 4]])> {
        let l = &self.levels[0];
        match &l.texels {
            Texels::Byte(t) => Some((l.width, l.height, t)),
            Texels::Float(_) => None,
        }
    }

    /// The full-size image as float RGBA texels (width, height, texels);
    /// `None` for an 8-bit texture.
    pub fn level0_rgba32f(&self) -> Option<(u32, u32, &[[f32; 4]])> {
        let l = &self.levels[0];
        match &l.texels {
            Texels::Float(t) => Some((l.width, l.height, t)),
            Texels::Byte(_) => None,
        }
    }

    /// Bytes the pyramid's texels take in memory.
    pub fn bytes(&self) -> usize {
        self.levels.iter().map(Level::bytes).sum()
    }

    /// The linear RGBA value at `uv`, filtered for a footprint `lod` levels
    /// above full size (0: full size; fractions blend two levels).
    pub fn sample(&self, uv: Vec2, wrap: [Wrap; 2], lod: f32) -> Vec4 {
        let top = (self.levels.len() - 1) as f32;
        let lod = if lod.is_nan() { 0.0 } else { lod.clamp(0.0, top) };
        let k = lod.floor();
        let f = lod - k;
        let k = k as usize;
        let a = self.levels[k].bilinear(uv, wrap, self.encoding);
        if f <= 0.0 || k + 1 >= self.levels.len() {
            return a;
        }
        let b = self.levels[k + 1].bilinear(uv, wrap, self.encoding);
        a * (1.0 - f) + b * f
    }

    /// The level of detail for a footprint of `texels` full-size texels
    /// across (log2; 0 below one texel or for NaN; the top level for an
    /// infinite footprint).
    pub fn lod_for(texels: f32) -> f32 {
        if texels > 1.0 {
            texels.log2().min(f32::MAX)
        } else {
            0.0
        }
    }
}

/// Refuses sizes that are zero, beyond [`MAX_TEXTURE_PIXELS`], or that do
/// not match the texels given.
fn check_size(name: &str, width: u32, height: u32, len: usize) -> Result<(), TextureError> {
    let pixels = u64::from(width) * u64::from(height);
    if width == 0 || height == 0 {
        return Err(TextureError::Empty { name: name.to_string() });
    }
    if pixels > MAX_TEXTURE_PIXELS {
        return Err(TextureError::TooLarge {
            name: name.to_string(),
            width,
            height,
        });
    }
    if pixels != len as u64 {
        return Err(TextureError::Decode {
            name: name.to_string(),
            message: format!("{len} texels for {width}x{height}"),
        });
    }
    Ok(())
}

/// The bytes of RGBA texels, in order.
fn bytemuck_bytes(texels: &[[u8; 4]]) -> &[u8] {
    texels.as_flattened()
}

/// The next pyramid level: each texel the mean of up to 2×2 texels of
/// `level`, averaged in linear light; `None` once the level is 1×1.
fn halve(level: &Level, encoding: Encoding) -> Option<Level> {
    if level.width == 1 && level.height == 1 {
        return None;
    }
    let (w, h) = ((level.width / 2).max(1), (level.height / 2).max(1));
    let mut sums: Vec<Vec4> = Vec::with_capacity((w * h) as usize);
    for y in 0..h {
        for x in 0..w {
            let mut sum = Vec4::ZERO;
            let mut n = 0.0;
            for dy in 0..2 {
                for dx in 0..2 {
                    let (sx, sy) = (2 * x + dx, 2 * y + dy);
                    if sx < level.width && sy < level.height {
                        sum += level.texel(sx, sy, encoding);
                        n += 1.0;
                    }
                }
            }
            sums.push(sum / n);
        }
    }
    let texels = match &level.texels {
        Texels::Byte(_) => Texels::Byte(
            sums.iter()
                .map(|s| {
                    let encode = |c: f32| match encoding {
                        Encoding::Srgb => linear_to_srgb(c),
                        Encoding::Linear => c,
                    };
                    let byte = |c: f32| (c.clamp(0.0, 1.0) * 255.0).round() as u8;
                    [byte(encode(s.x)), byte(encode(s.y)), byte(encode(s.z)), byte(s.w)]
                })
                .collect(),
        ),
        Texels::Float(_) => Texels::Float(sums.iter().map(|s| s.to_array()).collect()),
    };
    Some(Level {
        width: w,
        height: h,
        texels,
    })
}

#[cfg(test)]
mod tests;
