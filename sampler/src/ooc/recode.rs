//! Rewriting a scene file with another block codec, without building it
//! again: every block is read, checked against its CRC, decompressed and
//! compressed anew (in parallel, a batch at a time); the tree, the blocks'
//! order and the header carry over.

use std::path::{Path, PathBuf};
use std::time::Instant;

use rayon::prelude::*;

use super::codec::Codec;
use super::format::{decode_index, Header};
use super::writer::FileWriter;
use super::OocError;

/// Blocks recompressed at once.
const BATCH: usize = 512;

/// What a recode did.
#[derive(Clone, Copy, Debug, Default)]
pub struct RecodeReport {
    /// Blocks.
    pub blocks: u32,
    /// Decompressed bytes of all blocks.
    pub decompressed_bytes: u64,
    /// Compressed bytes of all blocks before.
    pub before_bytes: u64,
    /// Compressed bytes of all blocks after.
    pub after_bytes: u64,
    /// Size of the new file.
    pub file_bytes: u64,
    /// Seconds in all.
    pub seconds: f64,
}

/// Writes `out`, a copy of the scene file `src` whose blocks use `codec`.
/// `out` may be `src`: the new file replaces it only once complete.
pub fn recode(
    src: &Path,
    out: &Path,
    codec: Codec,
    progress: &(dyn Fn(u64, u64) + Sync),
) -> Result<RecodeReport, OocError> {
    let start = Instant::now();
    let file = std::fs::File::open(src).map_err(|e| OocError::io(src, e))?;
    // SAFETY: read-only; scene files are replaced by rename, never changed in place.
    let mmap = unsafe { memmap2::Mmap::map(&file) }.map_err(|e| OocError::io(src, e))?;
    let (mut header, blocks_start) = Header::decode(&mmap)?;
    let index = decode_index(&mmap, blocks_start, header.blocks)?;
    let from = header.codec;
    header.codec = codec;
    let partial = PathBuf::from(format!("{}.partial", out.display()));
    let mut writer = FileWriter::create(&partial, &header)?;
    let result = (|| {
        let mut order: Vec<u32> = (0..index.len() as u32).collect();
        order.sort_by_key(|&i| index[i as usize].offset);
        let mut report = RecodeReport {
            blocks: header.blocks,
            ..RecodeReport::default()
        };
        for (k, ids) in order.chunks(BATCH).enumerate() {
            let packed: Vec<Vec<u8>> = ids
                .par_iter()
                .map(|&id| {
                    let e = index[id as usize];
                    let bytes = &mmap[e.offset as usize..(e.offset + u64::from(e.packed)) as usize];
                    if crc32c::crc32c(bytes) != e.crc {
                        return Err(OocError::Checksum(format!("block {id}")));
                    }
                    let raw = from.decompress(bytes, e.len as usize).map_err(|c| OocError::Block {
                        block: id,
                        message: c.to_string(),
                    })?;
                    Ok(codec.compress(&raw))
                })
                .collect::<Result<_, _>>()?;
            for (&id, bytes) in ids.iter().zip(&packed) {
                let e = index[id as usize];
                writer.block(id, bytes, e.len, e.level)?;
                report.decompressed_bytes += u64::from(e.len);
                report.before_bytes += u64::from(e.packed);
                report.after_bytes += bytes.len() as u64;
            }
            progress(((k + 1) * BATCH).min(order.len()) as u64, order.len() as u64);
        }
        writer.finish(out)?;
        report.file_bytes = std::fs::metadata(out).map(|m| m.len()).unwrap_or(0);
        report.seconds = start.elapsed().as_secs_f64();
        Ok(report)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&partial);
    }
    result
}
