//! The out-of-core scene (`.hds` files): a kd-tree over any number of
//! triangles, decomposed into treelets with LOD voxels, packed into compressed
//! blocks ordered by level (Áfra 2012, sections 4–6), built out of core within
//! a memory budget (`build`), and traced through a cache of decompressed
//! blocks of fixed budget that fetcher threads fill (`cache`, `traverse`).
//! Voxels stand in for subtrees that are small enough as seen from the ray
//! (LOD) or not loaded yet; callers learn which, so that nothing traced from a
//! proxy for missing data is ever stored as a holodeck ray.

pub mod block;
pub mod build;
pub mod cache;
pub mod codec;
pub mod format;
pub mod in_core;
pub mod node;
pub mod recode;
pub mod traverse;
pub mod treelet;
pub mod voxel;
pub mod writer;

#[cfg(test)]
mod tests;

use std::fs::File;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use glam::Vec3;

pub use block::{Block, Link};
pub use build::{build_scene_file, BuildReport, BuildSettings};
pub use cache::{Cache, CacheStats};
pub use codec::Codec;
pub use format::Header;
pub use in_core::InCoreReport;
pub use recode::{recode, RecodeReport};
pub use traverse::{Fetch, OnMissing, OocHit, OocSurface};

use crate::geom::Aabb;
use crate::scene::Scene;

/// Rounds a batch waits for the fetchers before loading blocks itself.
pub const PROXY_ROUNDS: usize = 3;
/// How long one round waits for the fetchers.
const ROUND_WAIT: std::time::Duration = std::time::Duration::from_secs(2);

/// File name extension of scene files.
pub const EXTENSION: &str = "hds";

/// Why a scene file cannot be built, opened or read.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum OocError {
    /// The file does not start like a scene file.
    #[error("not a holodeck scene file (no HDSCENE magic)")]
    NotASceneFile,
    /// Written by another version of the layout.
    #[error(
        "scene file version {0}; this holodeck reads version {version}: build it again from its scene with `holodeck scene build`",
        version = format::VERSION
    )]
    Version(u32),
    /// The file ends early.
    #[error("the file is truncated: {0} is missing or cut short")]
    Truncated(&'static str),
    /// A checksum does not match.
    #[error("checksum mismatch in {0}: the file is corrupt")]
    Checksum(String),
    /// The header does not parse or is inconsistent.
    #[error("bad header: {0}")]
    Header(String),
    /// A block fails its checks.
    #[error("block {block}: {message}")]
    Block {
        /// The block.
        block: u32,
        /// What is wrong.
        message: String,
    },
    /// Reading or writing failed.
    #[error("{path}: {message}")]
    Io {
        /// The file.
        path: PathBuf,
        /// The system's message.
        message: String,
    },
    /// The scene cannot be built.
    #[error("{0}")]
    Build(String),
    /// The blocks do not make one tree (found when assembling it in memory).
    #[error("the scene file is corrupt: {0}")]
    Corrupt(String),
}

impl OocError {
    /// An I/O error on `path`.
    pub fn io(path: &Path, e: std::io::Error) -> OocError {
        OocError::Io {
            path: path.to_path_buf(),
            message: e.to_string(),
        }
    }
}

/// True if `path` names a scene file (by its extension).
pub fn is_scene_file(path: &Path) -> bool {
    path.extension().is_some_and(|e| e.eq_ignore_ascii_case(EXTENSION))
}

/// An open scene file: header, root, and the block cache with its fetchers.
pub struct OocScene {
    header: Header,
    root: Link,
    bounds: Aabb,
    fetchers: cache::Fetchers,
    corrupt: AtomicU64,
    /// The textures, every material's maps, and the textured triangles'
    /// texture coordinates by id (ascending), read whole on opening.
    pub(crate) texturing: Texturing,
}

/// What a scene file keeps of its scene's textures.
#[derive(Default)]
pub(crate) struct Texturing {
    pub(crate) textures: crate::scene::TextureSet,
    pub(crate) maps: Vec<crate::scene::MaterialMaps>,
    pub(crate) uvs: Vec<(u32, [glam::Vec2; 3])>,
    /// The textured triangles' tangents, in the order of `uvs`, where the file keeps them.
    pub(crate) tangents: Vec<[glam::Vec4; 3]>,
}

/// Reads the textures, maps and texture coordinates the header points at.
fn read_texturing(header: &Header, cache: &Cache) -> Result<Texturing, OocError> {
    use crate::scene::texture::Texture;
    let mut out = Texturing::default();
    for (k, t) in header.textures.iter().enumerate() {
        let bytes = cache.read_raw(t.block)?;
        let bad = |e: crate::scene::texture::TextureError| OocError::Header(format!("texture {k}: {e}"));
        let texture = if t.float {
            let texels: Vec<[f32; 4]> = bytes
                .chunks_exact(16)
                .map(|c| {
                    std::array::from_fn(|i| f32::from_le_bytes([c[4 * i], c[4 * i + 1], c[4 * i + 2], c[4 * i + 3]]))
                })
                .collect();
            Texture::from_rgba32f(&t.name, t.width, t.height, texels).map_err(bad)?
        } else {
            let texels: Vec<[u8; 4]> = bytes.chunks_exact(4).map(|c| [c[0], c[1], c[2], c[3]]).collect();
            Texture::from_rgba8(&t.name, t.width, t.height, texels, t.encoding).map_err(bad)?
        };
        out.textures.add(texture);
    }
    if let Some(block) = header.maps_block {
        let bytes = cache.read_raw(block)?;
        out.maps = postcard::from_bytes(&bytes).map_err(|e| OocError::Header(format!("material maps: {e}")))?;
        let textures = out.textures.len() as u32;
        let mut maps = out.maps.clone();
        if maps.len() != header.materials.len()
            || maps
                .iter_mut()
                .any(|m| m.refs_mut().iter().any(|r| r.texture >= textures))
        {
            return Err(OocError::Header(
                "material maps do not match the materials and textures".into(),
            ));
        }
    }
    let record = format::UV_RECORD + if header.uv_tangents { format::TANGENT_RECORD } else { 0 };
    for &block in &header.uv_blocks {
        let bytes = cache.read_raw(block)?;
        if bytes.len() % record != 0 {
            return Err(OocError::Block {
                block,
                message: "texture coordinates: not whole records".into(),
            });
        }
        for r in bytes.chunks_exact(record) {
            let f = |i: usize| f32::from_le_bytes([r[i], r[i + 1], r[i + 2], r[i + 3]]);
            let id = u32::from_le_bytes([r[0], r[1], r[2], r[3]]);
            let uv = [0, 1, 2].map(|k| glam::Vec2::new(f(4 + 8 * k), f(8 + 8 * k)));
            out.uvs.push((id, uv));
            if header.uv_tangents {
                let at = format::UV_RECORD;
                let t = [0, 1, 2].map(|k| {
                    let o = at + 16 * k;
                    glam::Vec4::new(f(o), f(o + 4), f(o + 8), f(o + 12))
                });
                out.tangents.push(t);
            }
        }
    }
    if !out.uvs.windows(2).all(|w| w[0].0 < w[1].0)
        || out.uvs.last().is_some_and(|u| u64::from(u.0) >= header.triangles)
    {
        return Err(OocError::Header(
            "texture coordinates: ids out of order or out of range".into(),
        ));
    }
    Ok(out)
}

impl OocScene {
    /// Opens a scene file with a cache of `budget` decompressed bytes (by
    /// default room for every block) and `fetchers` fetcher threads. Checks
    /// the header, index and trailer; blocks are checked as they are loaded.
    pub fn open(path: &Path, budget: Option<usize>, fetchers: usize) -> Result<OocScene, OocError> {
        let file = File::open(path).map_err(|e| OocError::io(path, e))?;
        if !file.metadata().map_err(|e| OocError::io(path, e))?.is_file() {
            return Err(OocError::io(
                path,
                std::io::Error::new(std::io::ErrorKind::InvalidInput, "not a regular file"),
            ));
        }
        // SAFETY: the file is opened read-only; a scene file is never modified
        // in place (the builder writes a new file and renames it over the old).
        let mmap = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| OocError::io(path, e))?;
        let (header, blocks_start) = format::Header::decode(&mmap)?;
        let index = format::decode_index(&mmap, blocks_start, header.blocks)?;
        let root = header
            .root
            .to_link()
            .ok_or_else(|| OocError::Header("root link".into()))?;
        let [lo, hi] = header.bounds;
        let bounds = Aabb {
            lo: Vec3::from(lo),
            hi: Vec3::from(hi),
        };
        if !(bounds.lo.is_finite() && bounds.hi.is_finite()) {
            return Err(OocError::Header("scene bounds are not finite".into()));
        }
        let cache = Arc::new(Cache::new(
            mmap,
            index,
            header.codec,
            header.materials.len() as u32,
            budget
                .unwrap_or_else(|| {
                    usize::try_from(header.decompressed_bytes)
                        .unwrap_or(usize::MAX)
                        .saturating_add(16 << 20)
                })
                .max(1),
        ));
        let texturing = read_texturing(&header, &cache)?;
        Ok(OocScene {
            header,
            root,
            bounds,
            fetchers: cache::Fetchers::start(cache, fetchers),
            corrupt: AtomicU64::new(0),
            texturing,
        })
    }

    /// The tangents of triangle `id`'s vertices, where it is textured and
    /// its file gave them all.
    #[inline]
    pub fn triangle_tangents(&self, id: u32) -> Option<[glam::Vec4; 3]> {
        let t = &self.texturing;
        let k = t.uvs.binary_search_by_key(&id, |u| u.0).ok()?;
        t.tangents.get(k).copied().filter(|v| v.iter().all(|t| t.w != 0.0))
    }

    /// The texture coordinates of triangle `id`'s vertices, where it is textured.
    #[inline]
    pub fn triangle_uvs(&self, id: u32) -> Option<[glam::Vec2; 3]> {
        let uvs = &self.texturing.uvs;
        uvs.binary_search_by_key(&id, |u| u.0).ok().map(|k| uvs[k].1)
    }

    /// The header.
    pub fn header(&self) -> &Header {
        &self.header
    }
    /// The block cache.
    pub fn cache(&self) -> &Arc<Cache> {
        self.fetchers.cache()
    }
    /// The link to the root treelet.
    pub fn root(&self) -> &Link {
        &self.root
    }
    /// Scene bounds.
    pub fn bounds(&self) -> Aabb {
        self.bounds
    }
    /// Links that pointed past the end of a block or formed a cycle (corrupt files only).
    pub fn corrupt_links(&self) -> u64 {
        self.corrupt.load(Ordering::Relaxed)
    }
    fn note_corrupt(&self, what: impl FnOnce() -> String) {
        if self.corrupt.fetch_add(1, Ordering::Relaxed) == 0 {
            tracing::error!("scene file: {}; the file is corrupt", what());
        }
    }

    /// Runs `f` on items `0..n` as one batch, keeping no result that a proxy
    /// for missing data stood in for: items that missed are run again once the
    /// fetchers have what they asked for, and after [`PROXY_ROUNDS`] rounds
    /// (or at once when the blocks do not fit beside those in use) with blocks
    /// loaded on the spot. `None` only for items that met unreadable blocks.
    pub fn exact_batch<T>(&self, n: usize, mut f: impl FnMut(usize, &mut Fetch) -> T) -> Vec<Option<T>> {
        let cache = self.cache();
        let batch = cache.begin_batch();
        let mut out: Vec<Option<T>> = (0..n).map(|_| None).collect();
        let mut todo: Vec<usize> = (0..n).collect();
        let mut waiting = true;
        for round in 0..=PROXY_ROUNDS {
            let on_missing = if round < PROXY_ROUNDS && waiting {
                OnMissing::Proxy
            } else {
                OnMissing::Load
            };
            let mut requests = Vec::new();
            // Rays that missed, with the block each waits for.
            let mut again = Vec::new();
            for k in todo {
                let mut fetch = Fetch {
                    on_missing,
                    requests: Vec::new(),
                    missed: false,
                };
                let r = f(k, &mut fetch);
                if fetch.missed {
                    again.push((fetch.requests.first().copied().unwrap_or(u32::MAX), k));
                    requests.extend(fetch.requests);
                } else {
                    out[k] = Some(r);
                }
            }
            // Rays waiting for the same block go on together: they walk the same
            // subtree, so a cache too small for the whole batch still serves them.
            again.sort_unstable();
            if again.is_empty() {
                todo = Vec::new();
                break;
            }
            // Every request counts: a block many rays missed is fetched first.
            cache.request(&requests);
            requests.sort_unstable();
            requests.dedup();
            waiting = cache.wait_resident(&requests, ROUND_WAIT);
            if !waiting || round + 1 >= PROXY_ROUNDS {
                // The next round loads on the spot: the fetchers decode the
                // awaited blocks ahead, in the order the rays will want them.
                let mut awaited: Vec<u32> = again.iter().map(|&(b, _)| b).collect();
                awaited.dedup();
                cache.decode_ahead(&awaited);
            }
            todo = again.into_iter().map(|(_, k)| k).collect();
        }
        cache.end_batch(batch);
        if !todo.is_empty() {
            tracing::error!(
                "{} rays could not be traced: the scene file has unreadable blocks",
                todo.len()
            );
        }
        out
    }

    /// The scene without its triangles: materials, sky, sections and the
    /// emitters (so lights can be sampled with no block loaded).
    pub fn shell(&self) -> Scene {
        let h = &self.header;
        let mut s = Scene {
            materials: h.materials.clone(),
            material_names: h.material_names.clone(),
            sky: h.sky.clone(),
            sections: h.sections.clone(),
            textures: self.texturing.textures.clone(),
            maps: self.texturing.maps.clone(),
            ..Scene::default()
        };
        s.stats.triangles = h.triangles;
        s
    }
}
