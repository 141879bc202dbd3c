//! The scene file (`.hds`) layout. A preamble (magic, version, header length),
//! the header as TOML (codec, content hash, materials, sky, sections, the
//! emitters, the root link and sizes, and where a textured scene's textures,
//! maps and texture coordinates are) with its CRC-32C, the compressed blocks
//! ordered by LOD level (coarsest first; texture blocks last), the block index (offset, sizes,
//! CRC-32C of the compressed bytes and level of every block), and a trailer
//! that locates the index and closes the file. A file without its trailer
//! is one whose writing did not finish.

use holodeck_protocol::Section;
use serde::{Deserialize, Serialize};

use super::block::Link;
use super::codec::Codec;
use super::voxel::Voxel;
use super::OocError;
use crate::scene::{Material, Sky};

/// First bytes of a scene file.
pub const MAGIC: [u8; 8] = *b"HDSCENE\0";
/// Last bytes of a complete scene file.
pub const END_MAGIC: [u8; 8] = *b"HDSEND\0\0";
/// The layout version this code reads and writes.
pub const VERSION: u32 = 2;
/// Preamble: magic, version, header length.
pub const PREAMBLE: usize = 16;
/// Trailer: index offset, block count, index CRC, reserved, end magic.
pub const TRAILER: usize = 32;
/// Bytes per index entry.
pub const INDEX_ENTRY: usize = 24;

/// Where one block is and how to check it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct IndexEntry {
    /// Offset of the compressed bytes in the file.
    pub offset: u64,
    /// Compressed length.
    pub packed: u32,
    /// Decompressed length.
    pub len: u32,
    /// CRC-32C of the compressed bytes.
    pub crc: u32,
    /// LOD level (treelet depth) of the block's first, coarsest treelet.
    pub level: u16,
}

impl IndexEntry {
    /// The stored bytes.
    pub fn encode(&self, out: &mut Vec<u8>) {
        out.extend(self.offset.to_le_bytes());
        out.extend(self.packed.to_le_bytes());
        out.extend(self.len.to_le_bytes());
        out.extend(self.crc.to_le_bytes());
        out.extend(u32::from(self.level).to_le_bytes());
    }
    /// Reads one entry of `INDEX_ENTRY` bytes.
    pub fn decode(b: &[u8]) -> IndexEntry {
        let u32_at = |i: usize| u32::from_le_bytes([b[i], b[i + 1], b[i + 2], b[i + 3]]);
        IndexEntry {
            offset: u64::from(u32_at(0)) | u64::from(u32_at(4)) << 32,
            packed: u32_at(8),
            len: u32_at(12),
            crc: u32_at(16),
            level: u32_at(20) as u16,
        }
    }
}

/// A link as the header stores it (TOML has no unsigned 64-bit integers).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderLink {
    /// Block of the root treelet.
    pub block: u32,
    /// Node of the root treelet within the block.
    pub node: u32,
    /// Radius of the sphere around the scene bounds.
    pub radius: f32,
    /// The root voxel, as twelve 32-bit words.
    pub voxel: Vec<u32>,
}

impl HeaderLink {
    /// The header form of a link.
    pub fn from_link(l: &Link) -> HeaderLink {
        HeaderLink {
            block: l.block,
            node: l.node,
            radius: l.radius(),
            voxel: l.voxel.0.iter().flat_map(|w| [*w as u32, (*w >> 32) as u32]).collect(),
        }
    }
    /// The link, if the voxel has its twelve words.
    pub fn to_link(&self) -> Option<Link> {
        (self.voxel.len() == 12).then(|| Link {
            block: self.block,
            node: self.node,
            radius_bits: self.radius.to_bits(),
            voxel: Voxel(std::array::from_fn(|f| {
                u64::from(self.voxel[2 * f]) | u64::from(self.voxel[2 * f + 1]) << 32
            })),
        })
    }
}

/// An emissive triangle, kept whole in the header so that lights can be
/// sampled without loading any block.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Emitter {
    /// Scene-wide triangle id.
    pub id: u32,
    /// Its vertices.
    pub vertices: [[f32; 3]; 3],
    /// Its material.
    pub material: u32,
}

/// Everything about the scene that is not in blocks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// How blocks are compressed.
    pub codec: Codec,
    /// The scene's content hash (the same as the source scene file's).
    pub content_hash: String,
    /// Triangles in the scene.
    pub triangles: u64,
    /// Triangle references in leaves.
    pub references: u64,
    /// Triangles skipped on the way in (degenerate or not finite).
    pub skipped: u64,
    /// Blocks in the file.
    pub blocks: u32,
    /// LOD levels (treelet depths).
    pub levels: u32,
    /// Sum of decompressed block sizes, bytes.
    pub decompressed_bytes: u64,
    /// Scene bounds, min and max corner.
    pub bounds: [[f32; 3]; 2],
    /// The root treelet.
    pub root: HeaderLink,
    /// Materials by index.
    pub materials: Vec<Material>,
    /// Material names by index.
    pub material_names: Vec<String>,
    /// What rays that escape see.
    pub sky: Sky,
    /// Holodeck sections defined with the scene.
    pub sections: Vec<Section>,
    /// The emissive triangles.
    pub emitters: Vec<Emitter>,
    /// The images textured materials use, one block each (full size; the
    /// mip levels are made again on opening).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub textures: Vec<HeaderTexture>,
    /// The block holding every material's maps (postcard), where any
    /// material is textured.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub maps_block: Option<u32>,
    /// Blocks of the textured triangles' texture coordinates: records of a
    /// triangle id (u32) and its vertices' (u, v) (six f32), little-endian.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub uv_blocks: Vec<u32>,
    /// Whether each texture coordinate record goes on with the vertices'
    /// tangents (four f32 each, zero for none).
    #[serde(default, skip_serializing_if = "std::ops::Not::not")]
    pub uv_tangents: bool,
}

/// Bytes of one texture coordinate record of a `uv_blocks` block.
pub const UV_RECORD: usize = 28;
/// Bytes of the tangents that follow a record where the file keeps them.
pub const TANGENT_RECORD: usize = 48;

/// One texture of a scene file.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct HeaderTexture {
    /// Where it came from, for reports.
    pub name: String,
    /// How its 8-bit texels decode.
    pub encoding: crate::scene::texture::Encoding,
    /// Width, texels.
    pub width: u32,
    /// Height, texels.
    pub height: u32,
    /// Float texels (4 f32 each) rather than 8-bit (4 bytes each).
    pub float: bool,
    /// The block that holds its texels, rows from the top.
    pub block: u32,
}

impl Header {
    /// The preamble and header bytes with the header's CRC.
    pub fn encode(&self) -> Result<Vec<u8>, OocError> {
        let text = toml::to_string(self).map_err(|e| OocError::Header(e.to_string()))?;
        let mut out = Vec::with_capacity(PREAMBLE + text.len() + 4);
        out.extend(MAGIC);
        out.extend(VERSION.to_le_bytes());
        out.extend((text.len() as u32).to_le_bytes());
        out.extend(text.as_bytes());
        out.extend(crc32c::crc32c(text.as_bytes()).to_le_bytes());
        Ok(out)
    }

    /// Reads the preamble and header at the start of `bytes`; returns the
    /// header and where the blocks begin.
    pub fn decode(bytes: &[u8]) -> Result<(Header, usize), OocError> {
        if bytes.len() < PREAMBLE || bytes[..8] != MAGIC {
            return Err(OocError::NotASceneFile);
        }
        let version = u32::from_le_bytes([bytes[8], bytes[9], bytes[10], bytes[11]]);
        if version != VERSION {
            return Err(OocError::Version(version));
        }
        let len = u32::from_le_bytes([bytes[12], bytes[13], bytes[14], bytes[15]]) as usize;
        let end = PREAMBLE + len;
        if bytes.len() < end + 4 {
            return Err(OocError::Truncated("the header"));
        }
        let text = &bytes[PREAMBLE..end];
        let crc = u32::from_le_bytes([bytes[end], bytes[end + 1], bytes[end + 2], bytes[end + 3]]);
        if crc32c::crc32c(text) != crc {
            return Err(OocError::Checksum("the header".into()));
        }
        let text = std::str::from_utf8(text).map_err(|e| OocError::Header(e.to_string()))?;
        let header: Header = toml::from_str(text).map_err(|e| OocError::Header(e.to_string()))?;
        for (i, m) in header.materials.iter().enumerate() {
            m.validate()
                .map_err(|e| OocError::Header(format!("material {i}: {e}")))?;
        }
        header
            .sky
            .validate()
            .map_err(|e| OocError::Header(format!("sky: {e}")))?;
        if header.material_names.len() != header.materials.len() || header.materials.len() > usize::from(u16::MAX) {
            return Err(OocError::Header("material names do not match the materials".into()));
        }
        if header
            .emitters
            .iter()
            .any(|e| e.material as usize >= header.materials.len())
        {
            return Err(OocError::Header(
                "an emitter names a material that does not exist".into(),
            ));
        }
        let blocks = header.blocks;
        let beyond = header
            .textures
            .iter()
            .map(|t| t.block)
            .chain(header.maps_block)
            .chain(header.uv_blocks.iter().copied())
            .any(|b| b >= blocks);
        if beyond {
            return Err(OocError::Header("a texture block is out of range".into()));
        }
        if header.blocks == 0 || header.root.block >= header.blocks || header.root.to_link().is_none() {
            return Err(OocError::Header("the root link is out of range".into()));
        }
        Ok((header, end + 4))
    }
}

/// The trailer's bytes.
pub fn encode_trailer(index_offset: u64, blocks: u64, index_crc: u32) -> Vec<u8> {
    let mut out = Vec::with_capacity(TRAILER);
    out.extend(index_offset.to_le_bytes());
    out.extend(blocks.to_le_bytes());
    out.extend(index_crc.to_le_bytes());
    out.extend(0u32.to_le_bytes());
    out.extend(END_MAGIC);
    out
}

/// Reads the trailer and index of a whole file whose blocks start at
/// `blocks_start`; checks that every block lies inside the block region.
pub fn decode_index(bytes: &[u8], blocks_start: usize, expected: u32) -> Result<Vec<IndexEntry>, OocError> {
    if bytes.len() < blocks_start + TRAILER || bytes[bytes.len() - 8..] != END_MAGIC {
        return Err(OocError::Truncated("the trailer (the file did not finish writing)"));
    }
    let t = &bytes[bytes.len() - TRAILER..];
    let u64_at = |i: usize| u64::from_le_bytes(t[i..i + 8].try_into().unwrap_or([0; 8]));
    let (index_offset, blocks) = (u64_at(0), u64_at(8));
    let index_crc = u32::from_le_bytes([t[16], t[17], t[18], t[19]]);
    if blocks != u64::from(expected) {
        return Err(OocError::Header(format!(
            "the header says {expected} blocks, the index {blocks}"
        )));
    }
    let index_len = blocks as usize * INDEX_ENTRY;
    let index_end = bytes.len() - TRAILER;
    let index_start = usize::try_from(index_offset).unwrap_or(usize::MAX);
    if index_start < blocks_start || index_start.checked_add(index_len) != Some(index_end) {
        return Err(OocError::Truncated("the block index"));
    }
    let raw = &bytes[index_start..index_end];
    if crc32c::crc32c(raw) != index_crc {
        return Err(OocError::Checksum("the block index".into()));
    }
    let index: Vec<IndexEntry> = raw.chunks_exact(INDEX_ENTRY).map(IndexEntry::decode).collect();
    for (i, e) in index.iter().enumerate() {
        let inside = e.offset >= blocks_start as u64 && e.offset + u64::from(e.packed) <= index_offset;
        if !inside {
            return Err(OocError::Block {
                block: i as u32,
                message: format!("lies outside the block region ({}+{})", e.offset, e.packed),
            });
        }
    }
    Ok(index)
}
