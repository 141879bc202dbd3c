//! Block compression: LZ4 (lz4_flex, pure Rust; the default, since blocks are
//! decompressed on the tracing path) or Zstandard (smaller files, slower to
//! decompress). Both are measured by `holodeck bench scene-file`.

use serde::{Deserialize, Serialize};

use super::block::MAX_BLOCK_BYTES;

/// The block codec of a scene file.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, Default)]
#[serde(rename_all = "lowercase")]
pub enum Codec {
    /// LZ4 block format.
    #[default]
    Lz4,
    /// Zstandard at level 3.
    Zstd,
}

/// A block that does not decompress.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("block does not decompress ({0})")]
pub struct CodecError(String);

impl Codec {
    /// Compresses one block.
    pub fn compress(self, raw: &[u8]) -> Vec<u8> {
        match self {
            Codec::Lz4 => lz4_flex::block::compress(raw),
            // Level 3 is zstd's default; compressing from memory cannot fail.
            Codec::Zstd => zstd::bulk::compress(raw, 3).unwrap_or_else(|_| raw.to_vec()),
        }
    }

    /// Decompresses a block that must come out at exactly `len` bytes.
    pub fn decompress(self, packed: &[u8], len: usize) -> Result<Vec<u8>, CodecError> {
        let mut out = Vec::new();
        self.decompress_into(packed, len, &mut out)?;
        Ok(out)
    }

    /// Decompresses a block that must come out at exactly `len` bytes into
    /// `buf`, which keeps its allocation from block to block (the cache
    /// decodes thousands of blocks a second; a fresh buffer each time costs
    /// more in page faults than LZ4 takes to decompress it). Returns the
    /// `len` bytes.
    pub fn decompress_into<'b>(self, packed: &[u8], len: usize, buf: &'b mut Vec<u8>) -> Result<&'b [u8], CodecError> {
        if len > MAX_BLOCK_BYTES {
            return Err(CodecError(format!("{len} bytes is more than a block may hold")));
        }
        if buf.len() < len {
            buf.resize(len, 0);
        }
        let out = &mut buf[..len];
        let got = match self {
            Codec::Lz4 => lz4_flex::block::decompress_into(packed, out).map_err(|e| CodecError(e.to_string()))?,
            Codec::Zstd => zstd::bulk::decompress_to_buffer(packed, out).map_err(|e| CodecError(e.to_string()))?,
        };
        if got != len {
            return Err(CodecError(format!("{got} bytes where the index says {len}")));
        }
        Ok(&buf[..len])
    }

    /// The codec's name, as written on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Codec::Lz4 => "lz4",
            Codec::Zstd => "zstd",
        }
    }
}

impl std::str::FromStr for Codec {
    type Err = String;
    fn from_str(s: &str) -> Result<Codec, String> {
        match s {
            "lz4" => Ok(Codec::Lz4),
            "zstd" => Ok(Codec::Zstd),
            _ => Err(format!("unknown codec {s:?} (lz4 or zstd)")),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn both_codecs_round_trip_and_refuse_garbage() {
        let raw: Vec<u8> = (0..10_000u32).flat_map(|i| (i / 7).to_le_bytes()).collect();
        for c in [Codec::Lz4, Codec::Zstd] {
            let packed = c.compress(&raw);
            assert!(packed.len() < raw.len() / 2, "{c:?} {}", packed.len());
            assert_eq!(c.decompress(&packed, raw.len()).unwrap(), raw);
            assert!(c.decompress(&packed, raw.len() + 1).is_err());
            assert!(c.decompress(&packed[..packed.len() / 2], raw.len()).is_err());
            assert!(c.decompress(&packed, MAX_BLOCK_BYTES + 1).is_err());
            // A buffer left longer by a bigger block gives back exactly this one.
            let small = c.compress(&raw[..400]);
            let mut buf = vec![0xAA; raw.len() * 2];
            assert_eq!(c.decompress_into(&small, 400, &mut buf).unwrap(), &raw[..400]);
            assert_eq!(c.decompress_into(&packed, raw.len(), &mut buf).unwrap(), &raw[..]);
            assert!(c.decompress_into(&small, 401, &mut buf).is_err());
        }
    }
}
