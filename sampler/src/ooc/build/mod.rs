//! Building a scene file out of core (Áfra 2012, 4.1 and 7; Wald 2004, 4):
//! the source is streamed once to find its bounds, emitters and size, and
//! once more to sort its triangles into chunk files at spatial medians (a
//! triangle goes to every chunk its bounds touch); chunks still too big for
//! the memory budget are split again. Each chunk is then built in core (the
//! binned-SAH kd-tree, in parallel), given voxels, cut into treelets, packed
//! into blocks and compressed in parallel. The median splits above the chunks,
//! with empty-space cuts, become the top of the tree. The file is written
//! beside its final name and renamed when complete; its work folder is
//! cleared on start, so a killed build simply runs again.

mod chunk;
pub mod source;
mod spill;
mod top;

use std::fs::{self, File};
use std::io::{BufWriter, Read, Seek, SeekFrom, Write};
use std::path::{Path, PathBuf};
use std::time::Instant;

use glam::Vec3;
use rayon::prelude::*;

use super::block::MAX_BLOCK_ITEMS;
use super::codec::Codec;
use super::format::{Emitter, Header, HeaderLink, HeaderTexture, IndexEntry, UV_RECORD};
use super::treelet::{decompose, split_box, Decomposed};
use super::writer::FileWriter;
use super::OocError;
use crate::geom::Aabb;
use crate::scene::Scene;
pub use chunk::shade_color;
use chunk::Chunk;
pub use source::{LandscapeSource, MandelbulbSource, RawTri, SceneMeta, SceneSource, StreamHash, TriangleSource};
use spill::Spill;
use top::{TopNode, TopTree};

/// Memory the in-core build needs per triangle (scene, references, nodes and
/// partitions at their peak), measured on the landscape.
pub const BUILD_BYTES_PER_TRIANGLE: u64 = 400;
/// Most chunk files written at once in the partition pass.
const MAX_FIRST_CHUNKS: usize = 256;

/// How to build.
#[derive(Clone, Copy, Debug)]
pub struct BuildSettings {
    /// Memory the build may use, bytes.
    pub memory: u64,
    /// Block codec.
    pub codec: Codec,
    /// Target decompressed block size, bytes.
    pub block_bytes: usize,
}

impl Default for BuildSettings {
    fn default() -> Self {
        BuildSettings {
            memory: 2 << 30,
            codec: Codec::Lz4,
            block_bytes: 64 << 10,
        }
    }
}

/// What a build made.
#[derive(Clone, Debug, Default)]
pub struct BuildReport {
    /// Triangles.
    pub triangles: u64,
    /// Triangle references in leaves.
    pub references: u64,
    /// Chunks built in core.
    pub chunks: usize,
    /// Most triangles in one chunk.
    pub largest_chunk: u64,
    /// Blocks.
    pub blocks: u32,
    /// LOD levels.
    pub levels: u32,
    /// Decompressed bytes of all blocks.
    pub decompressed_bytes: u64,
    /// Compressed bytes of all blocks.
    pub compressed_bytes: u64,
    /// Size of the file.
    pub file_bytes: u64,
    /// Seconds spent streaming and partitioning.
    pub partition_seconds: f64,
    /// Seconds spent building chunks (trees, voxels, blocks, compression).
    pub chunk_seconds: f64,
    /// Seconds in all.
    pub seconds: f64,
}

/// Progress of a build: phase name, done, total.
pub type Progress<'a> = &'a (dyn Fn(&str, u64, u64) + Sync);

struct Blocks {
    file: BufWriter<File>,
    path: PathBuf,
    at: u64,
    entries: Vec<IndexEntry>,
    codec: Codec,
    raw: u64,
    references: u64,
    /// One more than the deepest treelet level so far.
    levels: u16,
}

impl Blocks {
    /// Adds a block of `raw` bytes that is no treelet (textures, their
    /// coordinates), after every level; returns its index.
    fn add_raw(&mut self, raw: &[u8]) -> Result<u32, OocError> {
        let bytes = self.codec.compress(raw);
        self.file.write_all(&bytes).map_err(|e| OocError::io(&self.path, e))?;
        self.entries.push(IndexEntry {
            offset: self.at,
            packed: bytes.len() as u32,
            len: raw.len() as u32,
            crc: crc32c::crc32c(&bytes),
            level: u16::MAX,
        });
        self.at += bytes.len() as u64;
        self.raw += raw.len() as u64;
        Ok(self.entries.len() as u32 - 1)
    }

    /// Adds the textures, maps and texture coordinates of `scene` (the
    /// scene the stream came from, triangle ids its indices).
    fn add_textures(&mut self, scene: &Scene) -> Result<Texturing, OocError> {
        let mut textures = Vec::with_capacity(scene.textures.len());
        for t in scene.textures.iter() {
            let (width, height) = (t.width(), t.height());
            let (float, bytes) = match t.level0_rgba8() {
                Some((_, _, texels)) => (false, texels.as_flattened().to_vec()),
                None => (
                    true,
                    t.level0_rgba32f().map_or_else(Vec::new, |(_, _, texels)| {
                        texels.iter().flatten().flat_map(|c| c.to_le_bytes()).collect()
                    }),
                ),
            };
            let block = self.add_raw(&bytes)?;
            textures.push(HeaderTexture {
                name: t.name.clone(),
                encoding: t.encoding(),
                width,
                height,
                float,
                block,
            });
        }
        let maps = postcard::to_allocvec(&scene.maps).map_err(|e| OocError::Build(format!("material maps: {e}")))?;
        let maps_block = Some(self.add_raw(&maps)?);
        let mut uv_blocks = Vec::new();
        let mut records = Vec::new();
        let uv_tangents = !scene.tangents.is_empty();
        for (i, t) in scene.triangles.iter().enumerate() {
            if scene.maps_of(t.material).is_none() {
                continue;
            }
            records.extend((i as u32).to_le_bytes());
            for uv in scene.triangle_uvs(i) {
                records.extend(uv.x.to_le_bytes());
                records.extend(uv.y.to_le_bytes());
            }
            if uv_tangents {
                let v =
                    t.v.map(|v| scene.tangents.get(v as usize).copied().unwrap_or(glam::Vec4::ZERO));
                for c in v.iter().flat_map(|t| t.to_array()) {
                    records.extend(c.to_le_bytes());
                }
            }
            if records.len() >= UV_RECORD << 16 {
                uv_blocks.push(self.add_raw(&records)?);
                records.clear();
            }
        }
        if !records.is_empty() {
            uv_blocks.push(self.add_raw(&records)?);
        }
        Ok(Texturing {
            textures,
            maps_block,
            uv_blocks,
            uv_tangents,
        })
    }

    fn add(&mut self, d: Decomposed) -> Result<super::Link, OocError> {
        self.levels = self.levels.max(d.levels);
        let blocks = d.blocks;
        for (_, b) in &blocks {
            if b.verts.len() > MAX_BLOCK_ITEMS || b.tris.len() > MAX_BLOCK_ITEMS {
                return Err(OocError::Build(format!(
                    "a leaf holds too many triangles for one block ({} vertices)",
                    b.verts.len()
                )));
            }
            self.references += b.list.len() as u64;
        }
        let codec = self.codec;
        let packed: Vec<(u16, u32, Vec<u8>)> = blocks
            .into_par_iter()
            .map(|(level, b)| {
                let raw = b.encode();
                (level, raw.len() as u32, codec.compress(&raw))
            })
            .collect();
        for (level, len, bytes) in packed {
            self.file.write_all(&bytes).map_err(|e| OocError::io(&self.path, e))?;
            self.entries.push(IndexEntry {
                offset: self.at,
                packed: bytes.len() as u32,
                len,
                crc: crc32c::crc32c(&bytes),
                level,
            });
            self.at += bytes.len() as u64;
            self.raw += u64::from(len);
        }
        Ok(d.root)
    }
}

/// Where a scene file's textures went.
#[derive(Default)]
struct Texturing {
    textures: Vec<HeaderTexture>,
    maps_block: Option<u32>,
    uv_blocks: Vec<u32>,
    uv_tangents: bool,
}

fn midpoint(b: &Aabb) -> (usize, f32) {
    let d = b.hi - b.lo;
    let axis = if d.x >= d.y && d.x >= d.z {
        0
    } else if d.y >= d.z {
        1
    } else {
        2
    };
    (axis, 0.5 * (b.lo[axis] + b.hi[axis]))
}

/// Splits node `node` (box `b`) of the top tree into `2^levels` chunk files.
fn make_chunks(
    top: &mut TopTree,
    node: usize,
    b: Aabb,
    depth: usize,
    levels: usize,
    dir: &Path,
    out: &mut Vec<Spill>,
) -> Result<(), OocError> {
    if levels == 0 {
        // Named by node, as re-split halves are: no two live chunk files share a name.
        let path = dir.join(format!("chunk-{node}.tri"));
        out.push(Spill::create(path, b, depth, node)?);
        return Ok(());
    }
    let (axis, split) = midpoint(&b);
    let l = top.push(TopNode::Empty);
    let r = top.push(TopNode::Empty);
    top.nodes[node] = TopNode::Inner {
        axis,
        split,
        children: [l, r],
    };
    let (lb, rb) = split_box(&b, axis, split);
    make_chunks(top, l, lb, depth + 1, levels - 1, dir, out)?;
    make_chunks(top, r, rb, depth + 1, levels - 1, dir, out)
}

/// Sends a triangle to every chunk whose box its bounds touch.
fn route(
    top: &TopTree,
    spills: &mut [Spill],
    slot_of: &[usize],
    t: &RawTri,
    root: usize,
    root_box: &Aabb,
) -> Result<(), OocError> {
    let tb = t.bounds();
    let mut stack = vec![(root, *root_box)];
    while let Some((i, b)) = stack.pop() {
        match &top.nodes[i] {
            TopNode::Inner { axis, split, children } => {
                let (lb, rb) = split_box(&b, *axis, *split);
                if tb.lo[*axis] <= *split {
                    stack.push((children[0], lb));
                }
                if tb.hi[*axis] >= *split {
                    stack.push((children[1], rb));
                }
            }
            _ => {
                let s = slot_of[i];
                if s != usize::MAX {
                    spills[s].push(t, &tb)?;
                }
            }
        }
    }
    Ok(())
}

/// Builds `out` from `source` within `settings.memory`.
pub fn build_scene_file(
    source: &dyn TriangleSource,
    out: &Path,
    settings: &BuildSettings,
    progress: Progress<'_>,
) -> Result<BuildReport, OocError> {
    let start = Instant::now();
    let meta = source.meta().clone();
    if meta.materials.len() > usize::from(u16::MAX) {
        return Err(OocError::Build(
            "too many materials for a scene file (65,535 at most)".into(),
        ));
    }
    let work = PathBuf::from(format!("{}.build", out.display()));
    let partial = PathBuf::from(format!("{}.partial", out.display()));
    // A build that was killed left these: start over.
    let _ = fs::remove_dir_all(&work);
    let _ = fs::remove_file(&partial);
    fs::create_dir_all(&work).map_err(|e| OocError::io(&work, e))?;
    let result = build_in(source, &meta, out, &work, &partial, settings, progress, start);
    let _ = fs::remove_dir_all(&work);
    if result.is_err() {
        let _ = fs::remove_file(&partial);
    }
    result
}

/// What the first pass over a source finds.
struct Scan {
    /// Triangles.
    count: u64,
    /// Their bounds (a point at the origin for none).
    bounds: Aabb,
    /// The triangles that emit light.
    emitters: Vec<Emitter>,
    /// The scene's identity.
    content_hash: String,
}

/// Pass 1: size, bounds, emitters, and the hash of a stream with no other
/// identity; every triangle's material and vertices checked.
fn scan(source: &dyn TriangleSource, meta: &SceneMeta, progress: Progress<'_>) -> Result<Scan, OocError> {
    let mut count = 0u64;
    let mut bounds = Aabb::EMPTY;
    let mut emitters = Vec::new();
    let mut hash = source.content_hash().is_none().then(StreamHash::default);
    // Emitters: materials that emit, or glow through an emission texture.
    let emissive: Vec<bool> = (0..meta.materials.len())
        .map(|m| {
            meta.materials[m].emission().iter().any(|&e| e > 0.0)
                || source.textured().is_some_and(|scene| {
                    scene
                        .maps_of(m as u32)
                        .and_then(|maps| maps.emissive_parts(&scene.textures))
                        .is_some()
                })
        })
        .collect();
    source.stream(&mut |batch| {
        for t in batch {
            if t.material as usize >= meta.materials.len() {
                return Err(OocError::Build(format!(
                    "triangle {} names material {} of {}",
                    t.id,
                    t.material,
                    meta.materials.len()
                )));
            }
            if !t.v.iter().all(|p| p.is_finite()) {
                return Err(OocError::Build(format!(
                    "triangle {} has a vertex that is not finite",
                    t.id
                )));
            }
            for p in t.v {
                bounds.grow(p);
            }
            if emissive[t.material as usize] {
                emitters.push(Emitter {
                    id: t.id,
                    vertices: t.v.map(|p| p.to_array()),
                    material: t.material,
                });
            }
        }
        if let Some(h) = hash.as_mut() {
            h.update(batch);
        }
        count += batch.len() as u64;
        progress("scanning", count, 0);
        Ok(())
    })?;
    let content_hash = match hash {
        Some(h) => h.finish(meta),
        None => source.content_hash().unwrap_or_default(),
    };
    if count == 0 {
        bounds = Aabb {
            lo: Vec3::ZERO,
            hi: Vec3::ZERO,
        };
    }
    Ok(Scan {
        count,
        bounds,
        emitters,
        content_hash,
    })
}

/// Builds one chunk's triangles (within `b`, `depth` median splits down)
/// in core and adds its blocks.
fn build_chunk(
    tris: Vec<RawTri>,
    b: Aabb,
    depth: usize,
    blocks: &mut Blocks,
    meta: &SceneMeta,
    settings: &BuildSettings,
) -> Result<super::Link, OocError> {
    let chunk = Chunk::build(&tris, b, &meta.materials);
    drop(tris);
    let first = blocks.entries.len() as u32;
    let d = decompose(&chunk, 0, b, first, (depth / 3 + 1) as u16, settings.block_bytes);
    drop(chunk);
    blocks.add(d)
}

#[allow(clippy::too_many_arguments)]
fn build_in(
    source: &dyn TriangleSource,
    meta: &SceneMeta,
    out: &Path,
    work: &Path,
    partial: &Path,
    settings: &BuildSettings,
    progress: Progress<'_>,
    start: Instant,
) -> Result<BuildReport, OocError> {
    let found = scan(source, meta, progress)?;
    let (count, bounds) = (found.count, found.bounds);
    let limit = (settings.memory / BUILD_BYTES_PER_TRIANGLE).max(1024);
    let mut top = TopTree::default();
    let root = top.push(TopNode::Empty);
    let mut blocks = Blocks {
        file: BufWriter::new(File::create(work.join("blocks")).map_err(|e| OocError::io(work, e))?),
        path: work.join("blocks"),
        at: 0,
        entries: Vec::new(),
        codec: settings.codec,
        raw: 0,
        references: 0,
        levels: 0,
    };
    let mut report = BuildReport {
        triangles: count,
        ..BuildReport::default()
    };
    let partition_start = Instant::now();
    if count <= limit {
        let mut tris = Vec::with_capacity(count as usize);
        source.stream(&mut |batch| {
            tris.extend_from_slice(batch);
            Ok(())
        })?;
        report.partition_seconds = partition_start.elapsed().as_secs_f64();
        progress("building", 0, count);
        let t0 = Instant::now();
        let link = build_chunk(tris, bounds, 0, &mut blocks, meta, settings)?;
        top.nodes[root] = TopNode::Chunk(link);
        report.chunks = 1;
        report.largest_chunk = count;
        report.chunk_seconds = t0.elapsed().as_secs_f64();
        progress("building", count, count);
    } else {
        let mut chunks = Chunking {
            source,
            meta,
            settings,
            progress,
            work,
            limit,
            top: &mut top,
            blocks: &mut blocks,
            report: &mut report,
        };
        chunks.partition(root, bounds, count, partition_start)?;
    }

    // The top of the tree, over the chunks.
    top.compute_voxels(root, &bounds);
    let first = blocks.entries.len() as u32;
    let d = decompose(&top, root, bounds, first, 0, settings.block_bytes);
    let root_link = blocks.add(d)?;
    let texturing = match source.textured() {
        Some(scene) => blocks.add_textures(scene)?,
        None => Texturing::default(),
    };
    blocks.file.flush().map_err(|e| OocError::io(&blocks.path, e))?;
    let header = Header {
        codec: settings.codec,
        content_hash: found.content_hash,
        triangles: count,
        references: blocks.references,
        skipped: source.skipped(),
        blocks: blocks.entries.len() as u32,
        levels: u32::from(blocks.levels.max(1)),
        decompressed_bytes: blocks.raw,
        bounds: [bounds.lo.to_array(), bounds.hi.to_array()],
        root: HeaderLink::from_link(&root_link),
        materials: meta.materials.clone(),
        material_names: meta.material_names.clone(),
        sky: meta.sky.clone(),
        sections: source.sections()?,
        emitters: found.emitters,
        textures: texturing.textures,
        maps_block: texturing.maps_block,
        uv_blocks: texturing.uv_blocks,
        uv_tangents: texturing.uv_tangents,
    };
    write_file(&blocks, header, partial, out, progress, &mut report)?;
    report.seconds = start.elapsed().as_secs_f64();
    Ok(report)
}

/// A source too large for the memory budget, sorted into chunk files at
/// spatial medians and built chunk by chunk.
struct Chunking<'a> {
    source: &'a dyn TriangleSource,
    meta: &'a SceneMeta,
    settings: &'a BuildSettings,
    progress: Progress<'a>,
    /// The build's work folder, where chunk files go.
    work: &'a Path,
    /// Triangles a chunk may hold to be built in core.
    limit: u64,
    top: &'a mut TopTree,
    blocks: &'a mut Blocks,
    report: &'a mut BuildReport,
}

impl Chunking<'_> {
    /// Pass 2: sorts the `count` triangles into chunk files under `root`
    /// (within `bounds`), splits the chunks still too big, and builds each.
    fn partition(&mut self, root: usize, bounds: Aabb, count: u64, partition_start: Instant) -> Result<(), OocError> {
        let (limit, progress, work) = (self.limit, self.progress, self.work);
        // Pass 2: sort into chunk files at spatial medians.
        let levels = ((count as f64 / limit as f64).log2().ceil() as usize + 1).min(MAX_FIRST_CHUNKS.ilog2() as usize);
        let mut spills = Vec::new();
        make_chunks(self.top, root, bounds, 0, levels, work, &mut spills)?;
        let mut slot_of = vec![usize::MAX; self.top.nodes.len()];
        for (k, s) in spills.iter().enumerate() {
            slot_of[s.node] = k;
        }
        let mut routed = 0u64;
        self.source.stream(&mut |batch| {
            for t in batch {
                route(self.top, &mut spills, &slot_of, t, root, &bounds)?;
            }
            routed += batch.len() as u64;
            progress("partitioning", routed, count);
            Ok(())
        })?;
        for s in &mut spills {
            s.close()?;
        }
        self.report.partition_seconds = partition_start.elapsed().as_secs_f64();
        let t0 = Instant::now();
        let mut queue: Vec<Spill> = spills.into_iter().rev().collect();
        let mut built = 0u64;
        while let Some(s) = queue.pop() {
            if s.count > limit && s.depth < 40 {
                let [a, b] = self.split(s)?;
                queue.push(b);
                queue.push(a);
                continue;
            }
            let tris = s.read_all()?;
            s.remove();
            self.report.chunks += 1;
            self.report.largest_chunk = self.report.largest_chunk.max(s.count);
            let link = if tris.is_empty() {
                None
            } else {
                Some(build_chunk(
                    tris,
                    s.bounds,
                    s.depth,
                    self.blocks,
                    self.meta,
                    self.settings,
                )?)
            };
            self.top.nodes[s.node] = link.map_or(TopNode::Empty, TopNode::Chunk);
            built += s.count;
            progress("building", built.min(count), count);
            // Empty space around the chunk's triangles is cut off above it.
            if link.is_some() {
                self.top.cut_empty(s.node, &s.bounds, &s.content);
            }
        }
        self.report.chunk_seconds = t0.elapsed().as_secs_f64();
        Ok(())
    }

    /// A chunk too big for memory, split at its spatial median into two
    /// chunk files (unless that separates nothing: then both are built
    /// whole); its node in the top tree becomes their parent.
    fn split(&mut self, s: Spill) -> Result<[Spill; 2], OocError> {
        let work = self.work;
        let (axis, split) = midpoint(&s.bounds);
        let (lb, rb) = split_box(&s.bounds, axis, split);
        let l = self.top.push(TopNode::Empty);
        let r = self.top.push(TopNode::Empty);
        let mut halves = [
            Spill::create(work.join(format!("chunk-{l}.tri")), lb, s.depth + 1, l)?,
            Spill::create(work.join(format!("chunk-{r}.tri")), rb, s.depth + 1, r)?,
        ];
        spill::for_each(&s.path, |t| {
            let tb = t.bounds();
            if tb.lo[axis] <= split {
                halves[0].push(&t, &tb)?;
            }
            if tb.hi[axis] >= split {
                halves[1].push(&t, &tb)?;
            }
            Ok(())
        })?;
        s.remove();
        let [mut a, mut b] = halves;
        a.close()?;
        b.close()?;
        if a.count > s.count * 9 / 10 && b.count > s.count * 9 / 10 {
            tracing::warn!("a chunk of {} triangles does not split; building it whole", s.count);
            a.depth = 40;
            b.depth = 40;
        }
        self.top.nodes[s.node] = TopNode::Inner {
            axis,
            split,
            children: [l, r],
        };
        Ok([a, b])
    }
}

/// Writes the file beside `out` and renames it: the header, the blocks in
/// order of level, the index and the trailer.
fn write_file(
    blocks: &Blocks,
    header: Header,
    partial: &Path,
    out: &Path,
    progress: Progress<'_>,
    report: &mut BuildReport,
) -> Result<(), OocError> {
    let levels = header.levels;
    let mut order: Vec<usize> = (0..blocks.entries.len()).collect();
    order.sort_by_key(|&i| (blocks.entries[i].level, i));
    let mut src = File::open(&blocks.path).map_err(|e| OocError::io(&blocks.path, e))?;
    let mut file = FileWriter::create(partial, &header)?;
    let mut buf = Vec::new();
    for (k, &i) in order.iter().enumerate() {
        let e = blocks.entries[i];
        buf.resize(e.packed as usize, 0);
        src.seek(SeekFrom::Start(e.offset))
            .map_err(|e| OocError::io(&blocks.path, e))?;
        src.read_exact(&mut buf).map_err(|e| OocError::io(&blocks.path, e))?;
        file.block(i as u32, &buf, e.len, e.level)?;
        if k % 4096 == 0 {
            progress("writing", k as u64, order.len() as u64);
        }
    }
    let index = file.finish(out)?;
    report.references = blocks.references;
    report.blocks = index.len() as u32;
    report.levels = levels;
    report.decompressed_bytes = blocks.raw;
    report.compressed_bytes = blocks.at;
    report.file_bytes = fs::metadata(out).map(|m| m.len()).unwrap_or(0);
    Ok(())
}
