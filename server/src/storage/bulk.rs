//! Writing a complete holodeck file front to back: header, beam runs in the
//! order given, directories, root, one commit. Used to create files and by the
//! optimizer and the repair tool. The file is built under a temporary name and
//! renamed into place only when complete and synced, so a crash never leaves a
//! half-written file under the real name.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, RayRecord};

use super::error::{Result, StorageError};
use super::format::{self, BeamEntry, DirRef, Extent, Slot, SLOT_OFFSETS};
use super::io;
use crate::settings::Settings;

/// Builds a holodeck file sequentially.
pub struct SequentialWriter {
    out: Option<BufWriter<File>>,
    tmp: PathBuf,
    dest: PathBuf,
    pos: u64,
    dirs: Vec<Vec<BeamEntry>>,
    finished: bool,
}

/// The temporary name a file is built under: beside the destination.
pub fn temp_path(dest: &Path, purpose: &str) -> PathBuf {
    let mut name = dest.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{purpose}.tmp"));
    dest.with_file_name(name)
}

impl SequentialWriter {
    /// Starts a file that will appear at `dest` on [`SequentialWriter::finish`].
    pub fn create(dest: &Path, settings: &Settings) -> Result<SequentialWriter> {
        settings.validate().map_err(|source| StorageError::Settings {
            path: dest.to_path_buf(),
            source,
        })?;
        let text = settings.to_text();
        let text_len = u32::try_from(text.len())
            .ok()
            .filter(|&n| n <= format::MAX_TEXT_LEN)
            .ok_or_else(|| {
                let message = format!(
                    "settings text of {} bytes exceeds the {} allowed",
                    text.len(),
                    format::MAX_TEXT_LEN
                );
                StorageError::Settings {
                    path: dest.to_path_buf(),
                    source: crate::settings::SettingsError::Toml(message),
                }
            })?;
        let tmp = temp_path(dest, "building");
        let file = File::create(&tmp).map_err(|source| StorageError::Io {
            path: tmp.clone(),
            op: "creating",
            source,
        })?;
        let mut w = SequentialWriter {
            out: Some(BufWriter::with_capacity(4 << 20, file)),
            tmp,
            dest: dest.to_path_buf(),
            pos: 0,
            dirs: settings
                .sections
                .iter()
                .map(|s| vec![BeamEntry::default(); s.beam_count() as usize])
                .collect(),
            finished: false,
        };
        w.write(&format::encode_prefix(text_len))?;
        w.write(&[0u8; 2 * format::SLOT_LEN as usize])?;
        w.write(&format::encode_text(&text))?;
        debug_assert_eq!(w.pos, format::data_start(text_len));
        Ok(w)
    }

    fn write(&mut self, bytes: &[u8]) -> Result<()> {
        let out = self.out.as_mut().ok_or_else(|| StorageError::Io {
            path: self.tmp.clone(),
            op: "writing",
            source: std::io::Error::other("writer already finished"),
        })?;
        out.write_all(bytes).map_err(|source| StorageError::Io {
            path: self.tmp.clone(),
            op: "writing",
            source,
        })?;
        self.pos += bytes.len() as u64;
        Ok(())
    }

    /// Writes a beam's whole run. Each beam may be written once; out-of-range keys are refused.
    pub fn push_beam(&mut self, key: BeamKey, rays: &[RayRecord]) -> Result<()> {
        let count = self.dirs.len();
        let dir = self.dirs.get(key.section as usize).ok_or(StorageError::NoSuchSection {
            section: key.section,
            count,
        })?;
        let beams = dir.len() as u32;
        if key.beam >= beams {
            let source = holodeck_protocol::SectionError::BeamOutOfRange {
                beam: key.beam,
                count: beams,
            };
            return Err(StorageError::Beam {
                section: key.section,
                source,
            });
        }
        if rays.is_empty() || dir[key.beam as usize].count > 0 {
            return Ok(());
        }
        let bytes = RayRecord::slice_as_bytes(rays);
        let entry = BeamEntry {
            offset: self.pos,
            count: u32::try_from(rays.len()).map_err(|_| StorageError::BeamFull { key })?,
            crc: crc32c::crc32c(bytes),
        };
        self.write(bytes)?;
        self.dirs[key.section as usize][key.beam as usize] = entry;
        Ok(())
    }

    /// Writes directories, root and the first commit, syncs, and renames into place.
    pub fn finish(mut self) -> Result<()> {
        let mut refs = Vec::with_capacity(self.dirs.len());
        let dirs = std::mem::take(&mut self.dirs);
        for (s, d) in dirs.iter().enumerate() {
            let bytes = format::encode_directory(s as u32, d);
            refs.push(DirRef {
                block: Extent {
                    offset: self.pos,
                    len: bytes.len() as u64,
                },
                beams: d.len() as u32,
                rays: d.iter().map(|e| u64::from(e.count)).sum(),
            });
            self.write(&bytes)?;
        }
        let root_bytes = format::encode_root(1, &refs);
        let root = Extent {
            offset: self.pos,
            len: root_bytes.len() as u64,
        };
        self.write(&root_bytes)?;
        let writer = self.out.take().ok_or_else(|| StorageError::Io {
            path: self.tmp.clone(),
            op: "writing",
            source: std::io::Error::other("writer already finished"),
        })?;
        let file = writer.into_inner().map_err(|e| StorageError::Io {
            path: self.tmp.clone(),
            op: "writing",
            source: e.into_error(),
        })?;
        let slot = Slot {
            generation: 1,
            root,
            root_crc: crc32c::crc32c(&root_bytes),
        };
        io::write_at(&file, &self.tmp, SLOT_OFFSETS[0], &format::encode_slot(&slot))?;
        file.sync_all().map_err(|source| StorageError::Io {
            path: self.tmp.clone(),
            op: "syncing",
            source,
        })?;
        drop(file);
        io::durable_rename(&self.tmp, &self.dest)?;
        self.finished = true;
        Ok(())
    }
}

impl Drop for SequentialWriter {
    fn drop(&mut self) {
        if !self.finished {
            // Unfinished: remove the partial temporary file.
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}
