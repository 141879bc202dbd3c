//! Writing a scene file: the header, the blocks in the order given, the
//! index and the trailer, into a file beside the final name that is synced
//! and renamed only when complete, so a reader never sees half a file and an
//! interrupted writer leaves the old file (if any) as it was.

use std::fs::{self, File};
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use super::format::{encode_trailer, Header, IndexEntry, INDEX_ENTRY};
use super::OocError;

/// A scene file being written.
pub struct FileWriter {
    out: BufWriter<File>,
    partial: PathBuf,
    at: u64,
    index: Vec<Option<IndexEntry>>,
}

impl FileWriter {
    /// Starts `partial` with `header`, for `blocks` blocks.
    pub fn create(partial: &Path, header: &Header) -> Result<FileWriter, OocError> {
        let head = header.encode()?;
        let file = File::create(partial).map_err(|e| OocError::io(partial, e))?;
        let mut out = BufWriter::with_capacity(1 << 20, file);
        out.write_all(&head).map_err(|e| OocError::io(partial, e))?;
        Ok(FileWriter {
            out,
            partial: partial.to_path_buf(),
            at: head.len() as u64,
            index: vec![None; header.blocks as usize],
        })
    }

    /// Appends block `id`: its compressed bytes, decompressed length and level.
    pub fn block(&mut self, id: u32, packed: &[u8], len: u32, level: u16) -> Result<(), OocError> {
        let slot = self
            .index
            .get_mut(id as usize)
            .ok_or_else(|| OocError::Build(format!("block {id} is past the header's count")))?;
        *slot = Some(IndexEntry {
            offset: self.at,
            packed: packed.len() as u32,
            len,
            crc: crc32c::crc32c(packed),
            level,
        });
        self.out.write_all(packed).map_err(|e| OocError::io(&self.partial, e))?;
        self.at += packed.len() as u64;
        Ok(())
    }

    /// Writes the index and trailer, syncs, and renames the file to `out`.
    /// Returns the index.
    pub fn finish(self, out: &Path) -> Result<Vec<IndexEntry>, OocError> {
        let io = |e| OocError::io(&self.partial, e);
        let index = self
            .index
            .iter()
            .enumerate()
            .map(|(i, e)| e.ok_or_else(|| OocError::Build(format!("block {i} was never written"))))
            .collect::<Result<Vec<_>, _>>()?;
        let mut raw = Vec::with_capacity(index.len() * INDEX_ENTRY);
        for e in &index {
            e.encode(&mut raw);
        }
        let mut w = self.out;
        w.write_all(&raw).map_err(io)?;
        w.write_all(&encode_trailer(self.at, index.len() as u64, crc32c::crc32c(&raw)))
            .map_err(io)?;
        let file = w.into_inner().map_err(|e| io(e.into_error()))?;
        file.sync_all().map_err(io)?;
        drop(file);
        fs::rename(&self.partial, out).map_err(|e| OocError::io(out, e))?;
        if let Some(parent) = out.parent().filter(|p| !p.as_os_str().is_empty()) {
            if let Ok(d) = File::open(parent) {
                let _ = d.sync_all();
            }
        }
        Ok(index)
    }
}
