//! Writing a complete holodeck file front to back: both header copies, beam
//! runs in the order given, directories, root, one commit. Used to create files
//! and by the optimizer and the repair tool. The file is built under a
//! temporary name of its own and put in place only when complete and synced,
//! so a crash never leaves a half-written file under the real name. A new file
//! is linked into place, which fails if the name exists: of two processes
//! creating the same file at once, exactly one wins.

use std::fs::File;
use std::io::{BufWriter, Write};
use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, RayRecord};

use super::disk::chunks_of;
use super::error::{Result, StorageError};
use super::format::{self, BeamEntry, ChunkRef, Slot, COPIES};
use super::io;
use crate::settings::Settings;

/// Builds a holodeck file sequentially.
pub struct SequentialWriter {
    out: Option<BufWriter<File>>,
    tmp: PathBuf,
    dest: PathBuf,
    pos: u64,
    dirs: Vec<Vec<BeamEntry>>,
    sections: Vec<holodeck_protocol::Section>,
    text_len: u32,
    replace: bool,
    finished: bool,
}

/// A temporary name to build a file under: beside the destination, and of
/// this process and call alone, so that two builders never share one.
pub fn temp_path(dest: &Path, purpose: &str) -> PathBuf {
    remove_stale_temps(dest);
    static NEXT: std::sync::atomic::AtomicU64 = std::sync::atomic::AtomicU64::new(0);
    let n = NEXT.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
    let mut name = dest.file_name().unwrap_or_default().to_os_string();
    name.push(format!(".{purpose}.{}.{n}.tmp", std::process::id()));
    dest.with_file_name(name)
}

/// Removes the temporary files that builders of `dest` left when they were
/// killed: names `DEST.PURPOSE.PID.N.tmp` whose process no longer runs.
/// Those of running processes (another builder at work) are left alone.
pub fn remove_stale_temps(dest: &Path) {
    let Some(base) = dest.file_name().and_then(|n| n.to_str()) else {
        return;
    };
    let dir = match dest.parent() {
        Some(d) if !d.as_os_str().is_empty() => d,
        _ => Path::new("."),
    };
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let name = entry.file_name();
        let Some(name) = name.to_str() else { continue };
        let Some(rest) = name.strip_prefix(base).and_then(|r| r.strip_prefix('.')) else {
            continue;
        };
        let Some(rest) = rest.strip_suffix(".tmp") else {
            continue;
        };
        // PURPOSE.PID.N
        let parts: Vec<&str> = rest.rsplitn(3, '.').collect();
        let [n, pid, _purpose] = parts[..] else { continue };
        let (Ok(_), Ok(pid)) = (n.parse::<u64>(), pid.parse::<i32>()) else {
            continue;
        };
        // SAFETY: kill with signal 0 only checks that the process exists.
        let gone = pid > 0
            && unsafe { libc::kill(pid, 0) } != 0
            && std::io::Error::last_os_error().raw_os_error() == Some(libc::ESRCH);
        if gone {
            let path = entry.path();
            if std::fs::remove_file(&path).is_ok() {
                tracing::info!("removed {}, left by a killed process {pid}", path.display());
            }
        }
    }
}

impl SequentialWriter {
    /// Starts a new file that will appear at `dest` on
    /// [`SequentialWriter::finish`], which fails with
    /// [`StorageError::Exists`] if something took the name meanwhile.
    pub fn create(dest: &Path, settings: &Settings) -> Result<SequentialWriter> {
        Self::start(dest, settings, false)
    }

    /// Starts a file that replaces `dest` atomically on [`SequentialWriter::finish`].
    pub fn replacing(dest: &Path, settings: &Settings) -> Result<SequentialWriter> {
        Self::start(dest, settings, true)
    }

    fn start(dest: &Path, settings: &Settings, replace: bool) -> Result<SequentialWriter> {
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
        let file = std::fs::OpenOptions::new()
            .write(true)
            .create_new(true)
            .open(&tmp)
            .map_err(|source| StorageError::Io {
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
            sections: settings.sections.clone(),
            text_len,
            replace,
            finished: false,
        };
        let prefix = format::Prefix::new(text_len);
        for copy in 0..COPIES as u64 {
            let start = copy * format::header_stride(prefix);
            w.write(&vec![0u8; (start - w.pos) as usize])?;
            w.write(&format::encode_prefix(prefix))?;
            w.write(&[0u8; 2 * format::SLOT_LEN as usize])?;
            w.write(&format::encode_text(&text))?;
            w.write(&vec![0u8; (start + format::header_span(text_len) - w.pos) as usize])?;
        }
        debug_assert_eq!(w.pos, format::data_start(prefix));
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

    /// Writes directories, root and the first commit, syncs, and puts the
    /// file in place.
    pub fn finish(mut self) -> Result<()> {
        let dirs = std::mem::take(&mut self.dirs);
        let chunks = chunks_of(&self.sections);
        let mut refs = Vec::with_capacity(chunks.len());
        // Both copies of every block, each set followed by its root, follow
        // the runs: a collated file keeps its metadata at the end, its two
        // copies at least COPY_GAP apart.
        let blocks: Vec<Vec<u8>> = chunks
            .iter()
            .map(|c| {
                let d = &dirs[c.section as usize][c.first as usize..(c.first + c.beams) as usize];
                format::encode_directory(c.section, c.first, d)
            })
            .collect();
        let mut offsets = vec![[0u64; COPIES]; chunks.len()];
        let mut roots = [0u64; COPIES];
        let root_len = format::root_len(chunks.len());
        let blocks_len: u64 = blocks.iter().map(|b| b.len() as u64).sum();
        for copy in 0..COPIES {
            if copy > 0 {
                // The second copies lie at least COPY_GAP past the first: the
                // stretch between is free space.
                let gap = format::COPY_GAP.saturating_sub(blocks_len + root_len);
                self.write(&vec![0u8; gap as usize])?;
            }
            for (at, bytes) in offsets.iter_mut().zip(&blocks) {
                at[copy] = self.pos;
                self.write(bytes)?;
            }
            // The root's copy follows its blocks' copies; it is written in
            // place once every block's offsets are known.
            roots[copy] = self.pos;
            self.write(&vec![0u8; root_len as usize])?;
        }
        for ((c, bytes), copies) in chunks.iter().zip(&blocks).zip(offsets) {
            let d = &dirs[c.section as usize][c.first as usize..(c.first + c.beams) as usize];
            refs.push(ChunkRef {
                section: c.section,
                first: c.first,
                beams: c.beams,
                rays: d.iter().map(|e| u64::from(e.count)).sum(),
                copies,
                len: bytes.len() as u64,
            });
        }
        let root_bytes = format::encode_root(1, &refs);
        debug_assert_eq!(root_bytes.len() as u64, root_len);
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
        for at in roots {
            io::write_at(&file, &self.tmp, at, &root_bytes)?;
        }
        let slot = Slot {
            generation: 1,
            roots,
            root_len: root_bytes.len() as u64,
            root_crc: crc32c::crc32c(&root_bytes),
        };
        for copy in 0..COPIES {
            let at = format::slot_offset(format::Prefix::new(self.text_len), copy, 0);
            io::write_at(&file, &self.tmp, at, &format::encode_slot(&slot))?;
        }
        file.sync_all().map_err(|source| StorageError::Io {
            path: self.tmp.clone(),
            op: "syncing",
            source,
        })?;
        drop(file);
        if self.replace {
            io::durable_rename(&self.tmp, &self.dest)?;
        } else {
            io::durable_link_new(&self.tmp, &self.dest)?;
        }
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

#[cfg(test)]
mod stale_tests {
    use super::*;

    #[test]
    fn temporary_files_of_killed_builders_are_removed_and_live_ones_kept() {
        let dir = tempfile::tempdir().unwrap();
        let dest = dir.path().join("room.hdk");
        // A process that has ended, and this one, still running.
        let mut child = std::process::Command::new("true").spawn().unwrap();
        let dead = child.id();
        child.wait().unwrap();
        let stale = dir.path().join(format!("room.hdk.building.{dead}.0.tmp"));
        let live = dir
            .path()
            .join(format!("room.hdk.building.{}.7.tmp", std::process::id()));
        let other = dir.path().join(format!("other.hdk.building.{dead}.0.tmp"));
        for p in [&stale, &live, &other] {
            std::fs::write(p, b"x").unwrap();
        }
        let fresh = temp_path(&dest, "building");
        assert!(!stale.exists(), "a killed builder's file is removed");
        assert!(live.exists(), "a running builder's file is kept");
        assert!(other.exists(), "another file's temporaries are not touched");
        assert!(!fresh.exists());
    }
}
