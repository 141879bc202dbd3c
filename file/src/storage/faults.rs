//! Fault injection for tests of the storage path: writes or syncs of one
//! file fail with EIO from a chosen call on, as a failing disk's would; and
//! a recorder of every write, sync and length change of one file, in order,
//! from which a test rebuilds what a power cut could leave on disk (the
//! writes a sync has not yet made durable may land in any order, or not at
//! all). Built only with the `fault-injection` feature, which no product
//! build enables.

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Mutex;

/// Which operation a plan makes fail.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Op {
    /// Positioned writes of the file's bytes.
    Write,
    /// `fdatasync` of the file.
    Sync,
}

struct Plan {
    path: PathBuf,
    op: Op,
    /// Calls of `op` that still succeed.
    left: u64,
    /// A call has failed.
    failed: bool,
}

/// One operation on a recorded file, as the engine issued it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Event {
    /// `bytes` written at `offset`.
    Write {
        /// Where.
        offset: u64,
        /// What.
        bytes: Vec<u8>,
    },
    /// The file's data made durable (`fdatasync`): every event before it is on disk.
    Sync,
    /// The file's length set (a trim after a commit).
    SetLen(u64),
}

static RECORDING: AtomicBool = AtomicBool::new(false);
static RECORD: Mutex<Option<(PathBuf, Vec<Event>)>> = Mutex::new(None);

/// From now on, every write, sync and length change of the file at `path`
/// is recorded, in order.
pub fn record(path: &Path) {
    if let Ok(mut r) = RECORD.lock() {
        *r = Some((path.to_path_buf(), Vec::new()));
        RECORDING.store(true, Ordering::SeqCst);
    }
}

/// Events recorded so far (recording goes on).
pub fn recorded_len() -> usize {
    RECORD.lock().map_or(0, |r| r.as_ref().map_or(0, |(_, e)| e.len()))
}

/// Stops recording and returns what was recorded.
pub fn recorded() -> Vec<Event> {
    RECORDING.store(false, Ordering::SeqCst);
    RECORD
        .lock()
        .map_or_else(|_| Vec::new(), |mut r| r.take().map(|(_, e)| e).unwrap_or_default())
}

/// Records `event` if `path` is the file being recorded.
pub(super) fn note(path: &Path, event: impl FnOnce() -> Event) {
    if !RECORDING.load(Ordering::Relaxed) {
        return;
    }
    if let Ok(mut guard) = RECORD.lock() {
        if let Some((_, events)) = guard.as_mut().filter(|(p, _)| p == path) {
            events.push(event());
        }
    }
}

static ARMED: AtomicBool = AtomicBool::new(false);
static PLAN: Mutex<Option<Plan>> = Mutex::new(None);

/// From now on, the `after + 1`-th `op` on the file at `path` and every one
/// after it fail with EIO.
pub fn arm(path: &Path, op: Op, after: u64) {
    if let Ok(mut p) = PLAN.lock() {
        *p = Some(Plan {
            path: path.to_path_buf(),
            op,
            left: after,
            failed: false,
        });
        ARMED.store(true, Ordering::SeqCst);
    }
}

/// Ends the failures.
pub fn disarm() {
    ARMED.store(false, Ordering::SeqCst);
    if let Ok(mut p) = PLAN.lock() {
        *p = None;
    }
}

/// True once the armed plan has made a call fail.
pub fn tripped() -> bool {
    PLAN.lock()
        .is_ok_and(|p| p.as_ref().is_some_and(|p| p.left == 0) && ARMED.load(Ordering::SeqCst))
}

/// Fails the call if the plan says so.
pub(super) fn check(path: &Path, op: Op) -> std::io::Result<()> {
    if !ARMED.load(Ordering::Relaxed) {
        return Ok(());
    }
    let Ok(mut guard) = PLAN.lock() else { return Ok(()) };
    match guard.as_mut() {
        Some(p) if p.op == op && p.path == path => {
            if p.left == 0 {
                p.failed = true;
                return Err(std::io::Error::from_raw_os_error(libc::EIO));
            }
            p.left -= 1;
            Ok(())
        }
        _ => Ok(()),
    }
}
