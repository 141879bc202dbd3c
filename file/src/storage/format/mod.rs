//! Byte layout of a holodeck file, and the codecs for each of its parts.
//!
//! ```text
//! header copy 1, at 0                      header copy 2, at span = HEADER_ALIGN multiple
//! 0     prefix (64 B)                      span + 0     the same prefix
//! 64    commit slot A (64 B)               span + 64    slot A again
//! 128   commit slot B (64 B)               span + 128   slot B again
//! 192   settings text + CRC32C             span + 192   the same text
//! ...   zero padding to `span`             ...          padding to 2 * span
//! 2*span  allocatable space: beam runs (10-byte records), directory blocks, roots
//! ```
//!
//! Every piece of metadata is stored twice, each copy checked by its own
//! CRC32C, so that one damaged block never costs a ray: the prefix and settings
//! text in two header copies a page apart, each commit slot in both header
//! copies, and each root and directory block at two places in the data area.
//! A *root* lists the directory blocks of one commit. Sections are cut into
//! *chunks* of at most [`DIR_CHUNK_BEAMS`] beams, each with its own directory
//! block, so a commit rewrites only the chunks that changed and damage to both
//! copies of a block costs at most the beams it describes. A *directory block*
//! holds, per beam, the ray count, the run's offset (delta-coded against the
//! end of the previous run, so a collated file spends one byte on it) and the
//! run's CRC32C. All integers are little-endian. Every decoder here takes
//! untrusted bytes: it returns a [`FormatError`] naming what failed and where,
//! and never panics.

mod directory;
mod header;
mod root;
pub mod v1;

pub use directory::{decode_directory, directory_len_bound, encode_directory, max_directory_len, BeamEntry};
pub use header::{
    data_start, decode_prefix, decode_slot, decode_text, encode_prefix, encode_slot, encode_text, header_span,
    header_stride, slot_offset, text_offset, Prefix, Slot, HEADER_ALIGN, MAGIC, PREFIX_LEN, SLOT_LEN, TEXT_IN_HEADER,
};
pub use root::{decode_root, encode_root, root_len, ChunkRef};

use holodeck_protocol::RAY_RECORD_BYTES;

/// The format version this code writes and reads. Format 3 puts the second
/// header copy at least [`COPY_GAP`] from the first; format 2 files (the
/// copies side by side) are read and written in their own layout.
pub const FORMAT_VERSION: u32 = 3;
/// The oldest format version this code reads (read only: see [`v1`]).
pub const OLDEST_READ: u32 = 1;
/// Longest settings text accepted (sections are a line each; this is generous).
pub const MAX_TEXT_LEN: u32 = 1 << 24;
/// How many copies of each piece of metadata a file holds.
pub const COPIES: usize = 2;
/// Least distance between the two copies of a directory block or root:
/// a damaged stretch of the disk shorter than this never takes both.
pub const COPY_GAP: u64 = 64 << 10;
/// Most beams one directory block describes.
pub const DIR_CHUNK_BEAMS: u32 = 8192;
/// Largest generation accepted: far beyond any real count of commits, and far
/// from overflow.
pub const MAX_GENERATION: u64 = 1 << 62;

const RECORD: u64 = RAY_RECORD_BYTES as u64;

/// What is wrong with some bytes of a holodeck file, and where.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FormatError {
    /// The file does not start with the holodeck magic.
    #[error("not a holodeck file: it starts with {found:?}, not \"HOLODECK\"{hint}")]
    NotHolodeck {
        /// The first bytes found, lossily as text.
        found: String,
        /// Extra advice (e.g. for Radiance holodeck files).
        hint: &'static str,
    },
    /// The file is written in a newer format than this program reads.
    #[error(
        "file format version {found} is newer than this program reads (version {supported}); use a newer holodeck"
    )]
    FutureVersion {
        /// Version in the file.
        found: u32,
        /// Version supported here.
        supported: u32,
    },
    /// The file is written in an older format: either one this program does
    /// not read at all, or one it reads but does not write.
    #[error(
        "file format version {found} is older than this program writes (version {supported}): it can be read, \
         but `holodeck optimize` must convert it before anything is written to it"
    )]
    OldVersion {
        /// Version in the file.
        found: u32,
        /// Version supported here.
        supported: u32,
    },
    /// A part ends before its declared size.
    #[error("{what} at bytes {start}..{end} is truncated: only {have} bytes are there")]
    Truncated {
        /// Which part.
        what: String,
        /// Its first byte.
        start: u64,
        /// One past its last byte.
        end: u64,
        /// Bytes present.
        have: u64,
    },
    /// A checksum does not match.
    #[error("{what} at bytes {start}..{end} fails its checksum (stored {stored:08x}, computed {computed:08x})")]
    Checksum {
        /// Which part.
        what: String,
        /// Its first byte.
        start: u64,
        /// One past its last byte.
        end: u64,
        /// Stored CRC.
        stored: u32,
        /// CRC of the bytes present.
        computed: u32,
    },
    /// A value is impossible.
    #[error("{what} at byte {at}: {detail}")]
    Invalid {
        /// Which part.
        what: String,
        /// File offset of the bad value.
        at: u64,
        /// What is wrong.
        detail: String,
    },
}

fn invalid(what: impl Into<String>, at: u64, detail: impl Into<String>) -> FormatError {
    FormatError::Invalid {
        what: what.into(),
        at,
        detail: detail.into(),
    }
}

/// A run of bytes in the file.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct Extent {
    /// First byte.
    pub offset: u64,
    /// Length in bytes.
    pub len: u64,
}

impl Extent {
    /// One past the last byte.
    pub fn end(&self) -> u64 {
        self.offset + self.len
    }
}

/// Reads little-endian values from a byte slice that lies at `base` in the file.
struct Reader<'a> {
    bytes: &'a [u8],
    pos: usize,
    base: u64,
    what: &'a str,
}

impl<'a> Reader<'a> {
    fn new(bytes: &'a [u8], base: u64, what: &'a str) -> Self {
        Reader {
            bytes,
            pos: 0,
            base,
            what,
        }
    }
    fn at(&self) -> u64 {
        self.base + self.pos as u64
    }
    fn take(&mut self, n: usize) -> Result<&'a [u8], FormatError> {
        if self.bytes.len() - self.pos < n {
            return Err(FormatError::Truncated {
                what: self.what.to_string(),
                start: self.base,
                end: self.at() + n as u64,
                have: self.bytes.len() as u64,
            });
        }
        let s = &self.bytes[self.pos..self.pos + n];
        self.pos += n;
        Ok(s)
    }
    fn u32(&mut self) -> Result<u32, FormatError> {
        let mut b = [0u8; 4];
        b.copy_from_slice(self.take(4)?);
        Ok(u32::from_le_bytes(b))
    }
    fn u64(&mut self) -> Result<u64, FormatError> {
        let mut b = [0u8; 8];
        b.copy_from_slice(self.take(8)?);
        Ok(u64::from_le_bytes(b))
    }
    fn varint(&mut self) -> Result<u64, FormatError> {
        let at = self.at();
        let mut value = 0u64;
        for shift in (0..64).step_by(7) {
            let byte = self.take(1)?[0];
            value |= u64::from(byte & 0x7f) << shift;
            if byte & 0x80 == 0 {
                if shift == 63 && byte > 1 {
                    break;
                }
                return Ok(value);
            }
        }
        Err(invalid(self.what, at, "variable-length integer is longer than 64 bits"))
    }
    fn magic(&mut self, expected: [u8; 4]) -> Result<(), FormatError> {
        let at = self.at();
        let found = self.take(4)?;
        if found != expected {
            return Err(invalid(
                self.what,
                at,
                format!(
                    "expected marker {:?}, found {:?}",
                    String::from_utf8_lossy(&expected),
                    String::from_utf8_lossy(found)
                ),
            ));
        }
        Ok(())
    }
}

fn put_varint(out: &mut Vec<u8>, mut v: u64) {
    while v >= 0x80 {
        out.push((v as u8) | 0x80);
        v >>= 7;
    }
    out.push(v as u8);
}

/// Bytes LEB128 takes for `v`.
pub fn varint_len(v: u64) -> u64 {
    u64::from((64 - v.leading_zeros()).max(1)).div_ceil(7)
}

/// Checks the trailing CRC32C of `bytes` (last four bytes cover the rest).
fn check_trailing_crc(bytes: &[u8], base: u64, what: &str) -> Result<(), FormatError> {
    if bytes.len() < 4 {
        return Err(FormatError::Truncated {
            what: what.into(),
            start: base,
            end: base + 4,
            have: bytes.len() as u64,
        });
    }
    let (body, tail) = bytes.split_at(bytes.len() - 4);
    let stored = u32::from_le_bytes([tail[0], tail[1], tail[2], tail[3]]);
    let computed = crc32c::crc32c(body);
    if stored != computed {
        return Err(FormatError::Checksum {
            what: what.into(),
            start: base,
            end: base + bytes.len() as u64,
            stored,
            computed,
        });
    }
    Ok(())
}

fn push_crc(mut out: Vec<u8>) -> Vec<u8> {
    let crc = crc32c::crc32c(&out);
    out.extend_from_slice(&crc.to_le_bytes());
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn varint_lengths_match_the_encoder() {
        for v in [0u64, 1, 127, 128, 16_383, 16_384, 1 << 35, u64::MAX] {
            let mut out = Vec::new();
            put_varint(&mut out, v);
            assert_eq!(varint_len(v), out.len() as u64, "{v}");
        }
    }
}
