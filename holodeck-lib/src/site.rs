//! A holodeck file as the data of a static web site (`holodeck export web`):
//! its rays in chunk files of whole beams, in key order, and the index a
//! page reads to fetch exactly the beams its view sees, by byte range (see
//! [`holodeck_protocol::site`]). The page's own files are the caller's.

use std::io::Write;
use std::path::{Path, PathBuf};

use holodeck_file::HoloFile;
use holodeck_protocol::site::{chunk_name, SiteBeam, SiteHeader, SiteIndex, MAX_SITE_CHUNK};
use holodeck_protocol::{BeamKey, RayRecord, RAY_RECORD_BYTES};

/// A chunk file's size the export aims at: small enough that a host which
/// ignores byte ranges costs a page little, large enough that files are few.
pub const SITE_CHUNK_BYTES: u64 = 4 << 20;

/// The index's file name in the site.
pub const SITE_INDEX: &str = "holodeck.idx";

/// Why an export failed.
#[derive(Debug, thiserror::Error)]
pub enum SiteExportError {
    /// Reading the holodeck failed.
    #[error(transparent)]
    Storage(#[from] holodeck_file::StorageError),
    /// Writing a site file failed.
    #[error("writing {}: {source}", path.display())]
    Write {
        /// The file.
        path: PathBuf,
        /// Why.
        source: std::io::Error,
    },
    /// The index could not be encoded.
    #[error(transparent)]
    Index(#[from] holodeck_protocol::site::SiteError),
}

/// What an export wrote.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct SiteSummary {
    /// Beams holding rays.
    pub beams: usize,
    /// Rays written.
    pub rays: u64,
    /// Chunk files.
    pub chunks: usize,
    /// Bytes of the chunk files and the index.
    pub bytes: u64,
}

/// Beams read from the file at once.
const READ_BEAMS: usize = 4096;

/// Writes `file`'s rays into `dir` (which must exist) as chunk files of
/// about `chunk_bytes` and the index [`SITE_INDEX`]; `progress` is told the
/// rays written so far.
pub fn export_site(
    file: &mut HoloFile,
    dir: &Path,
    chunk_bytes: u64,
    progress: &mut dyn FnMut(u64),
) -> Result<SiteSummary, SiteExportError> {
    let chunk_bytes = chunk_bytes.clamp(RAY_RECORD_BYTES as u64, MAX_SITE_CHUNK);
    let sections = file.sections().to_vec();
    let mut keys = Vec::new();
    for (s, section) in sections.iter().enumerate() {
        for beam in 0..section.beam_count() {
            let key = BeamKey::new(s as u32, beam);
            if file.beam_len(key)? > 0 {
                keys.push(key);
            }
        }
    }
    let mut writer = ChunkWriter::new(dir, chunk_bytes);
    let mut rows = Vec::with_capacity(keys.len());
    let mut summary = SiteSummary::default();
    for batch in keys.chunks(READ_BEAMS) {
        // The file visits cache hits first and misses in disk order: kept
        // in key order here.
        let mut read: Vec<(BeamKey, Vec<RayRecord>)> = Vec::with_capacity(batch.len());
        file.read_beams(batch, |k, rays| read.push((k, rays.to_vec())))?;
        read.sort_unstable_by_key(|(k, _)| *k);
        for (key, rays) in read {
            if rays.is_empty() {
                continue;
            }
            // A beam larger than a chunk file can hold is cut to what fits.
            let most = (MAX_SITE_CHUNK / RAY_RECORD_BYTES as u64) as usize;
            let rays = &rays[..rays.len().min(most)];
            let (chunk, offset) = writer.write(RayRecord::slice_as_bytes(rays))?;
            rows.push(SiteBeam {
                key,
                chunk,
                offset,
                rays: rays.len() as u32,
            });
            summary.rays += rays.len() as u64;
        }
        progress(summary.rays);
    }
    let chunks = writer.finish()?;
    let index = SiteIndex {
        header: SiteHeader { sections, chunks },
        beams: rows,
    };
    let bytes = index.encode()?;
    let path = dir.join(SITE_INDEX);
    std::fs::write(&path, &bytes).map_err(|source| SiteExportError::Write { path, source })?;
    summary.beams = index.beams.len();
    summary.chunks = index.header.chunks.len();
    summary.bytes = index.header.chunks.iter().sum::<u64>() + bytes.len() as u64;
    Ok(summary)
}

/// Chunk files written one after another.
struct ChunkWriter {
    dir: PathBuf,
    target: u64,
    sizes: Vec<u64>,
    current: Option<(PathBuf, std::io::BufWriter<std::fs::File>)>,
}

impl ChunkWriter {
    fn new(dir: &Path, target: u64) -> ChunkWriter {
        ChunkWriter {
            dir: dir.to_path_buf(),
            target,
            sizes: Vec::new(),
            current: None,
        }
    }

    /// Writes one beam's bytes whole into a chunk; its chunk and offset.
    fn write(&mut self, bytes: &[u8]) -> Result<(u32, u32), SiteExportError> {
        let full = self
            .sizes
            .last()
            .is_some_and(|&s| s > 0 && s + bytes.len() as u64 > self.target.max(bytes.len() as u64));
        if self.current.is_none() || full {
            self.close()?;
            let path = self.dir.join(chunk_name(self.sizes.len() as u32));
            let f = std::fs::File::create(&path).map_err(|source| SiteExportError::Write {
                path: path.clone(),
                source,
            })?;
            self.current = Some((path, std::io::BufWriter::new(f)));
            self.sizes.push(0);
        }
        let Some((path, w)) = &mut self.current else {
            unreachable!("a chunk file was opened above")
        };
        w.write_all(bytes).map_err(|source| SiteExportError::Write {
            path: path.clone(),
            source,
        })?;
        let chunk = self.sizes.len() - 1;
        let offset = self.sizes[chunk];
        self.sizes[chunk] += bytes.len() as u64;
        Ok((chunk as u32, offset as u32))
    }

    fn close(&mut self) -> Result<(), SiteExportError> {
        if let Some((path, mut w)) = self.current.take() {
            w.flush().map_err(|source| SiteExportError::Write { path, source })?;
        }
        Ok(())
    }

    /// The chunk files' sizes, all written.
    fn finish(mut self) -> Result<Vec<u64>, SiteExportError> {
        self.close()?;
        Ok(self.sizes)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_ray_is_where_the_index_says_in_key_order() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("t.hdk");
        let section = holodeck_protocol::Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.0]],
            [4, 4, 2],
            holodeck_protocol::SectionKind::Interior,
        )
        .unwrap();
        let settings = holodeck_file::settings::Settings {
            sections: vec![section],
            ..holodeck_file::settings::Settings::default()
        };
        HoloFile::create(&path, &settings).unwrap();
        let mut file = HoloFile::open(&path, &holodeck_file::OpenOptions::default()).unwrap();
        let ray = |i: u32| {
            RayRecord::new(
                [i as u8, 1],
                [2, i as u8],
                holodeck_protocol::Rgbe::from_rgb([i as f32, 1.0, 0.5]),
                holodeck_protocol::DepthCode(i as u16),
            )
        };
        // Appended out of key order, one beam twice.
        let wrote: Vec<(u32, Vec<RayRecord>)> = vec![
            (90, (0..30).map(ray).collect()),
            (5, (0..7).map(ray).collect()),
            (90, (30..40).map(ray).collect()),
            (12, (0..100).map(ray).collect()),
        ];
        for (beam, rays) in &wrote {
            file.append(BeamKey::new(0, *beam), rays).unwrap();
        }
        file.flush().unwrap();
        let site = dir.path().join("site");
        std::fs::create_dir(&site).unwrap();
        let mut told = 0;
        // Chunks of about 500 bytes: 50 rays.
        let s = export_site(&mut file, &site, 500, &mut |n| told = n).unwrap();
        assert_eq!((s.beams, s.rays, told), (3, 147, 147));
        let index = SiteIndex::decode(&std::fs::read(site.join(SITE_INDEX)).unwrap()).unwrap();
        let keys: Vec<u32> = index.beams.iter().map(|b| b.key.beam).collect();
        assert_eq!(keys, [5, 12, 90]);
        // Beam 12's 100 rays do not fit 500 bytes: a chunk of its own.
        assert_eq!(index.header.chunks, [70, 1000, 400]);
        assert_eq!(s.chunks, 3);
        for b in &index.beams {
            let chunk = std::fs::read(site.join(chunk_name(b.chunk))).unwrap();
            let bytes = &chunk[b.offset as usize..b.end() as usize];
            let want = file.read_beam(b.key).unwrap();
            assert_eq!(RayRecord::slice_from_bytes(bytes).unwrap(), &want[..], "{:?}", b.key);
        }
    }
}
