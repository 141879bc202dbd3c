//! The scene's textures: image files decoded through the `image` crate
//! (PNG, JPEG, TGA, BMP, Radiance HDR), each kept once however many
//! materials use it, within a stated size limit.

use std::collections::HashMap;
use std::io::Cursor;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use image::{DynamicImage, ImageReader, Limits};

use super::{Encoding, Texture};

/// Most pixels one texture may have (8192 × 8192): a larger image, or a
/// corrupt header that claims one, is refused before it is decoded.
pub const MAX_TEXTURE_PIXELS: u64 = 1 << 26;

/// Why a texture could not be used, naming it.
#[derive(Debug, thiserror::Error)]
pub enum TextureError {
    /// The file is missing or unreadable.
    #[error("texture {}: {source}", path.display())]
    Io {
        /// The path tried.
        path: PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
    /// The bytes are not an image the decoder reads.
    #[error("texture {name}: {message}")]
    Decode {
        /// The file or image.
        name: String,
        /// What the decoder said.
        message: String,
    },
    /// Beyond [`MAX_TEXTURE_PIXELS`].
    #[error("texture {name}: {width}x{height} is more than the {MAX_TEXTURE_PIXELS} pixels a texture may have")]
    TooLarge {
        /// The file or image.
        name: String,
        /// Its width.
        width: u32,
        /// Its height.
        height: u32,
    },
    /// No pixels at all.
    #[error("texture {name}: the image has no pixels")]
    Empty {
        /// The file or image.
        name: String,
    },
}

/// Every texture of a scene, each once, by index.
#[derive(Clone, Debug, Default)]
pub struct TextureSet {
    textures: Vec<Arc<Texture>>,
    by_key: HashMap<(String, Encoding), u32>,
}

impl TextureSet {
    /// An empty set.
    pub fn new() -> TextureSet {
        TextureSet::default()
    }

    /// The texture at `index`.
    #[inline]
    pub fn get(&self, index: u32) -> Option<&Texture> {
        self.textures.get(index as usize).map(|t| &**t)
    }

    /// All textures, by index.
    pub fn iter(&self) -> impl Iterator<Item = &Texture> {
        self.textures.iter().map(|t| &**t)
    }

    /// Number of textures.
    pub fn len(&self) -> usize {
        self.textures.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.textures.is_empty()
    }

    /// Bytes all textures' pyramids take.
    pub fn bytes(&self) -> usize {
        self.textures.iter().map(|t| t.bytes()).sum()
    }

    /// Adds a texture made in memory (a generator's); its name keys it.
    pub fn add(&mut self, texture: Texture) -> u32 {
        let key = (texture.name.clone(), texture.encoding());
        if let Some(&i) = self.by_key.get(&key) {
            return i;
        }
        let i = self.textures.len() as u32;
        self.textures.push(Arc::new(texture));
        self.by_key.insert(key, i);
        i
    }

    /// The texture of the image file at `path`, decoded as `encoding` says;
    /// loaded once, whatever path spelling leads to the same file.
    pub fn load(&mut self, path: &Path, encoding: Encoding) -> Result<u32, TextureError> {
        let canonical = std::fs::canonicalize(path).map_err(|source| TextureError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        let key = (canonical.to_string_lossy().into_owned(), encoding);
        if let Some(&i) = self.by_key.get(&key) {
            return Ok(i);
        }
        let meta = std::fs::metadata(&canonical).map_err(|source| TextureError::Io {
            path: path.to_path_buf(),
            source,
        })?;
        if !meta.is_file() {
            return Err(TextureError::Decode {
                name: path.display().to_string(),
                message: "not a regular file".to_string(),
            });
        }
        let name = path.display().to_string();
        let reader = ImageReader::open(&canonical)
            .and_then(|r| r.with_guessed_format())
            .map_err(|source| TextureError::Io {
                path: path.to_path_buf(),
                source,
            })?;
        let texture = decode(&name, reader, encoding)?;
        Ok(self.insert(key, texture))
    }

    /// The texture of an image held in memory (a glTF buffer view or data
    /// URI), known as `name`.
    pub fn load_bytes(&mut self, name: &str, bytes: &[u8], encoding: Encoding) -> Result<u32, TextureError> {
        let key = (name.to_string(), encoding);
        if let Some(&i) = self.by_key.get(&key) {
            return Ok(i);
        }
        let reader = ImageReader::new(Cursor::new(bytes))
            .with_guessed_format()
            .map_err(|e| TextureError::Decode {
                name: name.to_string(),
                message: e.to_string(),
            })?;
        let texture = decode(name, reader, encoding)?;
        Ok(self.insert(key, texture))
    }

    fn insert(&mut self, key: (String, Encoding), texture: Texture) -> u32 {
        let i = self.textures.len() as u32;
        self.textures.push(Arc::new(texture));
        self.by_key.insert(key, i);
        i
    }
}

/// Decodes what `reader` holds, within the size limit.
fn decode<R: std::io::BufRead + std::io::Seek>(
    name: &str,
    mut reader: ImageReader<R>,
    encoding: Encoding,
) -> Result<Texture, TextureError> {
    let mut limits = Limits::default();
    // Room for the largest texture as float RGBA, the most a decoder makes of it.
    limits.max_alloc = Some(MAX_TEXTURE_PIXELS * 16);
    reader.limits(limits);
    let decode_error = |e: image::ImageError| match e {
        image::ImageError::Limits(_) => TextureError::Decode {
            name: name.to_string(),
            message: format!("the image is larger than the {MAX_TEXTURE_PIXELS} pixels a texture may have"),
        },
        e => TextureError::Decode {
            name: name.to_string(),
            message: e.to_string(),
        },
    };
    if reader.format().is_none() {
        return Err(TextureError::Decode {
            name: name.to_string(),
            message: "not an image format this program reads (PNG, JPEG, TGA, BMP, HDR)".to_string(),
        });
    }
    let image = reader.decode().map_err(decode_error)?;
    from_image(name, image, encoding)
}

/// A texture from a decoded image: floats stay floats, the rest becomes
/// 8-bit RGBA.
fn from_image(name: &str, image: DynamicImage, encoding: Encoding) -> Result<Texture, TextureError> {
    let (width, height) = (image.width(), image.height());
    match image {
        DynamicImage::ImageRgb32F(_) | DynamicImage::ImageRgba32F(_) => {
            let texels: Vec<[f32; 4]> = image.into_rgba32f().pixels().map(|p| p.0).collect();
            Texture::from_rgba32f(name, width, height, texels)
        }
        other => {
            let texels: Vec<[u8; 4]> = other.into_rgba8().pixels().map(|p| p.0).collect();
            Texture::from_rgba8(name, width, height, texels, encoding)
        }
    }
}
