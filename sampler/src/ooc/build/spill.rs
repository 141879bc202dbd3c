//! Chunk files: the triangles of one box of the scene, written while the
//! source streams and read back whole when the chunk is built (or split
//! again at its spatial median when it turned out too big).

use std::fs::File;
use std::io::{BufReader, BufWriter, Read, Write};
use std::path::{Path, PathBuf};

use super::super::OocError;
use super::source::{RawTri, RAW_BYTES};
use crate::geom::Aabb;

/// A chunk file being written or waiting to be built.
pub struct Spill {
    /// Its path.
    pub path: PathBuf,
    /// The chunk's box.
    pub bounds: Aabb,
    /// Union of its triangles' bounds clipped to the box.
    pub content: Aabb,
    /// Triangles in it.
    pub count: u64,
    /// Its depth in the top tree.
    pub depth: usize,
    /// Its node in the top tree.
    pub node: usize,
    out: Option<BufWriter<File>>,
    buf: Vec<u8>,
}

impl Spill {
    /// A new, empty chunk file.
    pub fn create(path: PathBuf, bounds: Aabb, depth: usize, node: usize) -> Result<Spill, OocError> {
        let f = File::create(&path).map_err(|e| OocError::io(&path, e))?;
        Ok(Spill {
            path,
            bounds,
            content: Aabb::EMPTY,
            count: 0,
            depth,
            node,
            out: Some(BufWriter::with_capacity(1 << 16, f)),
            buf: Vec::with_capacity(1 << 16),
        })
    }

    /// Appends a triangle whose bounds are `b`.
    pub fn push(&mut self, t: &RawTri, b: &Aabb) -> Result<(), OocError> {
        t.write(&mut self.buf);
        self.content = self.content.union(&b.clip(&self.bounds));
        self.count += 1;
        if self.buf.len() >= 1 << 16 {
            self.flush_buf()?;
        }
        Ok(())
    }

    fn flush_buf(&mut self) -> Result<(), OocError> {
        if let Some(out) = self.out.as_mut() {
            out.write_all(&self.buf).map_err(|e| OocError::io(&self.path, e))?;
        }
        self.buf.clear();
        Ok(())
    }

    /// Finishes writing.
    pub fn close(&mut self) -> Result<(), OocError> {
        self.flush_buf()?;
        if let Some(mut out) = self.out.take() {
            out.flush().map_err(|e| OocError::io(&self.path, e))?;
        }
        Ok(())
    }

    /// Reads every triangle back.
    pub fn read_all(&self) -> Result<Vec<RawTri>, OocError> {
        let mut tris = Vec::with_capacity(self.count as usize);
        for_each(&self.path, |t| {
            tris.push(t);
            Ok(())
        })?;
        Ok(tris)
    }

    /// Deletes the file.
    pub fn remove(&self) {
        let _ = std::fs::remove_file(&self.path);
    }
}

/// Calls `f` on each triangle of a chunk file, in order.
pub fn for_each(path: &Path, mut f: impl FnMut(RawTri) -> Result<(), OocError>) -> Result<(), OocError> {
    let file = File::open(path).map_err(|e| OocError::io(path, e))?;
    let mut r = BufReader::with_capacity(1 << 20, file);
    let mut rec = [0u8; RAW_BYTES];
    loop {
        match r.read_exact(&mut rec) {
            Ok(()) => f(RawTri::read(&rec))?,
            Err(e) if e.kind() == std::io::ErrorKind::UnexpectedEof => return Ok(()),
            Err(e) => return Err(OocError::io(path, e)),
        }
    }
}
