//! Positioned file I/O for the engine: a write batch that merges adjacent
//! writes into few large ones, advisory locking, and durable renames.

use std::fs::File;
use std::os::unix::fs::FileExt;
use std::os::unix::io::AsRawFd;
use std::path::Path;

use super::error::{Result, StorageError};

/// Largest batch held before it is written.
const BATCH_LIMIT: usize = 2 << 20;

/// Longest gap of free space a write batch fills with zeros to join the next
/// write: writing a few KiB more costs less than one more system call.
const MAX_PAD: u64 = 8 << 10;

/// Adjacent writes gathered into one buffer.
#[derive(Default)]
pub struct WriteBatch {
    start: u64,
    buf: Vec<u8>,
    /// The bytes from the batch's end up to here are free space that no
    /// commit refers to and nothing else will be written to (the growth
    /// reserve of the run just queued): a write starting within them joins
    /// the batch, the gap written as zeros.
    pad_to: u64,
}

impl WriteBatch {
    /// Queues `bytes` for `offset`, writing out what was queued first if it is
    /// not adjacent (or joined to it by a short stretch declared with
    /// [`WriteBatch::pad_to`]).
    pub fn push(&mut self, file: &File, path: &Path, offset: u64, bytes: &[u8]) -> Result<()> {
        let end = self.start + self.buf.len() as u64;
        let pad = if !self.buf.is_empty() && offset > end && offset <= self.pad_to && offset - end <= MAX_PAD {
            (offset - end) as usize
        } else {
            0
        };
        self.pad_to = 0;
        let adjacent = !self.buf.is_empty() && offset == end + pad as u64;
        if !adjacent || self.buf.len() + pad + bytes.len() > BATCH_LIMIT {
            self.flush(file, path)?;
        } else if pad > 0 {
            self.buf.resize(self.buf.len() + pad, 0);
        }
        if self.buf.is_empty() {
            if bytes.len() >= BATCH_LIMIT {
                return write_at(file, path, offset, bytes);
            }
            self.start = offset;
        }
        self.buf.extend_from_slice(bytes);
        Ok(())
    }

    /// Declares the bytes from the batch's end up to `end` free space that
    /// only zeros may be written to, until the next push: a write starting
    /// within them then joins the batch.
    pub fn pad_to(&mut self, end: u64) {
        self.pad_to = end;
    }

    /// Whether any queued byte lies in `offset..offset + len`: a read there
    /// must flush the batch first.
    pub fn overlaps(&self, offset: u64, len: u64) -> bool {
        !self.buf.is_empty() && offset < self.start + self.buf.len() as u64 && self.start < offset + len
    }

    /// Where the queued bytes go and how many there are.
    #[cfg(test)]
    pub fn queued(&self) -> (u64, usize) {
        (self.start, self.buf.len())
    }

    /// Writes out whatever is queued.
    pub fn flush(&mut self, file: &File, path: &Path) -> Result<()> {
        self.pad_to = 0;
        if !self.buf.is_empty() {
            write_at(file, path, self.start, &self.buf)?;
            self.buf.clear();
            if self.buf.capacity() > BATCH_LIMIT {
                self.buf.shrink_to(BATCH_LIMIT);
            }
        }
        Ok(())
    }
}

fn io_err<'a>(path: &'a Path, op: &'static str) -> impl FnOnce(std::io::Error) -> StorageError + 'a {
    move |source| StorageError::Io {
        path: path.to_path_buf(),
        op,
        source,
    }
}

/// Writes all of `bytes` at `offset`.
pub fn write_at(file: &File, path: &Path, offset: u64, bytes: &[u8]) -> Result<()> {
    #[cfg(feature = "fault-injection")]
    super::faults::check(path, super::faults::Op::Write).map_err(io_err(path, "writing"))?;
    file.write_all_at(bytes, offset).map_err(io_err(path, "writing"))?;
    #[cfg(feature = "fault-injection")]
    super::faults::note(path, || super::faults::Event::Write {
        offset,
        bytes: bytes.to_vec(),
    });
    Ok(())
}

/// Sets the file's length (trimming space no commit refers to).
pub fn set_len(file: &File, path: &Path, len: u64) -> Result<()> {
    file.set_len(len).map_err(io_err(path, "trimming"))?;
    #[cfg(feature = "fault-injection")]
    super::faults::note(path, || super::faults::Event::SetLen(len));
    Ok(())
}

/// Reads exactly `len` bytes at `offset` into `buf` (resized).
pub fn read_at(file: &File, path: &Path, offset: u64, len: usize, buf: &mut Vec<u8>) -> Result<()> {
    buf.resize(len, 0);
    file.read_exact_at(buf, offset).map_err(io_err(path, "reading"))
}

/// Reads exactly `buf.len()` bytes at `offset`.
pub fn read_exact_at(file: &File, path: &Path, offset: u64, buf: &mut [u8]) -> Result<()> {
    file.read_exact_at(buf, offset).map_err(io_err(path, "reading"))
}

/// Flushes file data (and the size needed to read it) to stable storage.
pub fn sync(file: &File, path: &Path) -> Result<()> {
    #[cfg(feature = "fault-injection")]
    super::faults::check(path, super::faults::Op::Sync).map_err(io_err(path, "syncing"))?;
    file.sync_data().map_err(io_err(path, "syncing"))?;
    #[cfg(feature = "fault-injection")]
    super::faults::note(path, || super::faults::Event::Sync);
    Ok(())
}

/// Length of the file.
pub fn file_len(file: &File, path: &Path) -> Result<u64> {
    Ok(file.metadata().map_err(io_err(path, "reading metadata"))?.len())
}

/// How long to keep trying a lock that is held: a process that just closed the
/// file can still hold the lock for a moment through a child it forked, until
/// that child's exec closes the inherited descriptor.
const LOCK_PATIENCE: std::time::Duration = std::time::Duration::from_millis(250);

/// Takes an advisory lock: exclusive for writers, shared for readers.
pub fn lock(file: &File, path: &Path, exclusive: bool) -> Result<()> {
    let op = if exclusive { libc::LOCK_EX } else { libc::LOCK_SH } | libc::LOCK_NB;
    let start = std::time::Instant::now();
    loop {
        // SAFETY: flock on a valid open descriptor has no memory effects.
        let rc = unsafe { libc::flock(file.as_raw_fd(), op) };
        if rc == 0 {
            return Ok(());
        }
        let err = std::io::Error::last_os_error();
        if err.raw_os_error() != Some(libc::EWOULDBLOCK) {
            return Err(StorageError::Io {
                path: path.to_path_buf(),
                op: "locking",
                source: err,
            });
        }
        if start.elapsed() >= LOCK_PATIENCE {
            return Err(StorageError::Locked {
                path: path.to_path_buf(),
            });
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
}

/// Renames `from` over `to` and makes the rename durable.
pub fn durable_rename(from: &Path, to: &Path) -> Result<()> {
    std::fs::rename(from, to).map_err(io_err(to, "renaming into place"))?;
    sync_dir(to);
    Ok(())
}

/// Puts the finished file `from` in place at `to`, which must not exist:
/// hard-links it (which fails if `to` exists, so of two creators exactly one
/// wins), removes `from`, and makes both durable. Where the file system has no
/// hard links, falls back to a rename after checking that `to` is free.
pub fn durable_link_new(from: &Path, to: &Path) -> Result<()> {
    let linked = std::fs::hard_link(from, to);
    let result = match linked {
        Ok(()) => Ok(()),
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => Err(StorageError::Exists { path: to.to_path_buf() }),
        Err(e)
            if matches!(
                e.raw_os_error(),
                Some(libc::EPERM) | Some(libc::EOPNOTSUPP) | Some(libc::EXDEV)
            ) =>
        {
            if to.exists() {
                Err(StorageError::Exists { path: to.to_path_buf() })
            } else {
                return durable_rename(from, to);
            }
        }
        Err(e) => Err(io_err(to, "linking into place")(e)),
    };
    let _ = std::fs::remove_file(from);
    result?;
    sync_dir(to);
    Ok(())
}

fn sync_dir(path: &Path) {
    let dir = path
        .parent()
        .filter(|p| !p.as_os_str().is_empty())
        .unwrap_or(Path::new("."));
    if let Ok(d) = File::open(dir) {
        // Directory fsync is best effort: some filesystems refuse it.
        let _ = d.sync_all();
    }
}

/// Tells the kernel these bytes will be read soon, so it can fetch many runs
/// concurrently instead of one read at a time.
pub fn will_need(file: &File, offset: u64, len: u64) {
    // SAFETY: advisory call on a valid descriptor.
    unsafe {
        libc::posix_fadvise(
            file.as_raw_fd(),
            offset as libc::off_t,
            len as libc::off_t,
            libc::POSIX_FADV_WILLNEED,
        );
    }
}

/// Asks the kernel to drop its cached pages of the file (for cold-read measurements).
pub fn drop_page_cache(file: &File) {
    // SAFETY: advisory call on a valid descriptor.
    unsafe {
        libc::posix_fadvise(file.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_short_declared_gap_joins_two_writes_with_zeros_and_an_undeclared_one_does_not() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("batch");
        let file = File::options()
            .read(true)
            .write(true)
            .create(true)
            .truncate(true)
            .open(&path)
            .unwrap();
        let mut batch = WriteBatch::default();
        batch.push(&file, &path, 100, &[1; 10]).unwrap();
        batch.pad_to(130);
        batch.push(&file, &path, 125, &[2; 5]).unwrap();
        assert_eq!(batch.queued(), (100, 30), "joined across the declared gap");
        assert!(batch.overlaps(129, 5) && batch.overlaps(90, 11) && !batch.overlaps(130, 5) && !batch.overlaps(90, 10));
        // Nothing was declared after the last push: a gap ends the batch.
        batch.push(&file, &path, 140, &[3; 4]).unwrap();
        assert_eq!(batch.queued(), (140, 4));
        // A gap past what was declared, or longer than MAX_PAD, is never filled.
        batch.pad_to(150);
        batch.push(&file, &path, 151, &[4; 1]).unwrap();
        assert_eq!(batch.queued(), (151, 1));
        batch.pad_to(u64::MAX);
        batch.push(&file, &path, 152 + MAX_PAD + 1, &[5; 1]).unwrap();
        assert_eq!(batch.queued(), (152 + MAX_PAD + 1, 1));
        batch.flush(&file, &path).unwrap();
        let bytes = std::fs::read(&path).unwrap();
        assert_eq!(&bytes[100..110], &[1; 10]);
        assert_eq!(&bytes[110..125], &[0; 15]);
        assert_eq!(&bytes[125..130], &[2; 5]);
        assert_eq!(&bytes[140..144], &[3; 4]);
        assert_eq!(bytes[151], 4);
        assert_eq!(bytes[(152 + MAX_PAD + 1) as usize], 5);
    }

    /// One step of a batch's life: a write past everything written so far
    /// (`gap` bytes on, then `pad` bytes declared free after it), or a write
    /// over bytes already written (`back` bytes before the end).
    #[derive(Debug, Clone)]
    enum Step {
        Ahead { gap: u64, len: usize, pad: Option<u64> },
        Over { back: u64, len: usize },
    }

    fn step() -> impl proptest::strategy::Strategy<Value = Step> {
        use proptest::prelude::*;
        prop_oneof![
            3 => (0u64..2 * MAX_PAD, 1usize..3000, proptest::option::of(0u64..2 * MAX_PAD))
                .prop_map(|(gap, len, pad)| Step::Ahead { gap, len, pad }),
            1 => (1u64..5000, 1usize..300).prop_map(|(back, len)| Step::Over { back, len }),
        ]
    }

    proptest::proptest! {
        #![proptest_config(proptest::prelude::ProptestConfig::with_cases(64))]
        /// Whatever the batch joins, the file ends up holding each byte's
        /// last write, and zeros where nothing was written.
        #[test]
        fn the_file_holds_every_last_write_and_zeros_elsewhere(steps in proptest::collection::vec(step(), 1..40)) {
            let dir = tempfile::tempdir().unwrap();
            let path = dir.path().join("batch");
            let file = File::options().read(true).write(true).create(true).truncate(true).open(&path).unwrap();
            let mut batch = WriteBatch::default();
            let mut model: Vec<u8> = Vec::new();
            let mut end = 0u64;
            for (i, s) in steps.iter().enumerate() {
                let byte = (i % 250) as u8 + 1;
                let (offset, len, pad) = match *s {
                    Step::Ahead { gap, len, pad } => (end + gap, len, pad),
                    Step::Over { back, len } => (end.saturating_sub(back), len.min(back as usize).max(1), None),
                };
                batch.push(&file, &path, offset, &vec![byte; len]).unwrap();
                let (start, queued) = batch.queued();
                proptest::prop_assert_eq!(start + queued as u64, offset + len as u64);
                let stop = offset as usize + len;
                if model.len() < stop {
                    model.resize(stop, 0);
                }
                model[offset as usize..stop].fill(byte);
                end = end.max(stop as u64);
                // Only the space past everything written is free to declare.
                if let (Some(pad), true) = (pad, stop as u64 == end) {
                    batch.pad_to(end + pad);
                }
            }
            batch.flush(&file, &path).unwrap();
            let bytes = std::fs::read(&path).unwrap();
            proptest::prop_assert_eq!(bytes.len(), model.len());
            proptest::prop_assert!(bytes == model, "the file differs from the last writes");
        }
    }
}
