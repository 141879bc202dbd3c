//! Crash safety with real processes and real signals: a child process fills a
//! holodeck file (appending, evicting, relocating, committing, compacting,
//! optimizing) and is killed with SIGKILL at random instants. After every kill the file must
//! open without error, every beam must hold exactly a prefix of the rays
//! written to it, and no flushed ray may be missing. The writer reports each
//! flush on a pipe of its own, in lines of one strict form; every report is
//! checked. It dies with the test, by the same guard as every other child.

use std::fs::File;
use std::io::{BufRead, BufReader, Write};
use std::os::fd::{AsRawFd, FromRawFd, OwnedFd, RawFd};
use std::os::unix::process::{CommandExt, ExitStatusExt};
use std::path::Path;
use std::process::Command;
use std::sync::mpsc;

use holodeck_file::settings::Settings;
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use holodeck_file::testing::{pattern_ray as ray, two_sections};
use holodeck_protocol::{BeamKey, RayRecord};
use rand::{Rng, SeedableRng};

#[path = "../../holodeck-tools/tests/common/process.rs"]
mod process;
use process::{Proc, DEADLINE};

const FILE_VAR: &str = "HOLODECK_CRASH_FILE";
const SEED_VAR: &str = "HOLODECK_CRASH_SEED";
const MODE_VAR: &str = "HOLODECK_CRASH_MODE";
/// The descriptor of the pipe the writer reports on (its stdout belongs to
/// the test harness it runs under).
const REPORT_FD_VAR: &str = "HOLODECK_CRASH_REPORT_FD";

fn settings() -> Settings {
    two_sections([3, 2, 2], [1, 1, 2], holodeck_file::settings::DEFAULT_CACHE_BYTES)
}

/// What the writer reports, one line each, nothing else.
#[derive(Clone, Copy, Debug, PartialEq)]
enum Report {
    /// `flushed N`: a flush returned with N rays in the file, all durable.
    Flushed(u64),
    /// `optimized N`: the file was rewritten whole, holding N rays.
    Optimized(u64),
    /// `compacted N`: the runs were packed in place, N rays kept.
    Compacted(u64),
}

impl Report {
    fn line(self) -> String {
        match self {
            Report::Flushed(n) => format!("flushed {n}\n"),
            Report::Optimized(n) => format!("optimized {n}\n"),
            Report::Compacted(n) => format!("compacted {n}\n"),
        }
    }

    /// Parses one line, newline included; anything else is refused.
    fn parse(line: &[u8]) -> Result<Report, String> {
        let bad = || format!("not a report: {:?}", String::from_utf8_lossy(line));
        let text = std::str::from_utf8(line).map_err(|_| bad())?;
        let text = text.strip_suffix('\n').ok_or_else(bad)?;
        let (word, n) = text.split_once(' ').ok_or_else(bad)?;
        if n.is_empty() || !n.bytes().all(|b| b.is_ascii_digit()) {
            return Err(bad());
        }
        let n = n.parse().map_err(|_| bad())?;
        match word {
            "flushed" => Ok(Report::Flushed(n)),
            "optimized" => Ok(Report::Optimized(n)),
            "compacted" => Ok(Report::Compacted(n)),
            _ => Err(bad()),
        }
    }
}

/// The writer run in the child process. Reports `flushed N` after each flush
/// that made N rays durable in total, on the pipe named by [`REPORT_FD_VAR`],
/// each line in one write (a kill cannot tear it). Runs until killed, or
/// until its parent is gone (its stdin ends).
#[test]
#[ignore = "helper process: started by the crash tests, never on its own"]
fn child_writer() {
    let (Ok(path), Ok(seed), Ok(fd)) = (
        std::env::var(FILE_VAR),
        std::env::var(SEED_VAR),
        std::env::var(REPORT_FD_VAR),
    ) else {
        panic!("child_writer runs only as a child of the crash tests");
    };
    let fd: RawFd = fd.parse().unwrap();
    // SAFETY: the parent opened this descriptor for us alone and nothing
    // else in this process uses it.
    let mut reports = unsafe { File::from_raw_fd(fd) };
    let mut report = |r: Report| reports.write_all(r.line().as_bytes()).unwrap();
    // The test that started us is gone when our stdin ends: so are we.
    std::thread::spawn(|| {
        let _ = std::io::copy(&mut std::io::stdin(), &mut std::io::sink());
        std::process::exit(0);
    });
    let mode = std::env::var(MODE_VAR).unwrap_or_default();
    let (optimize_too, compact_too) = (mode == "optimize", mode == "compact");
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed.parse().unwrap());
    let path = Path::new(&path);
    let options = OpenOptions {
        writable: true,
        cache_bytes: Some(6 << 10),
        flush_interval: None,
        accept_loss: false,
    };
    let mut f = HoloFile::open(path, &options).unwrap();
    let sections: Vec<u32> = f.sections().iter().map(|s| s.beam_count()).collect();
    let mut total = f.summary().rays();
    loop {
        for _ in 0..rng.gen_range(1..60) {
            let s = rng.gen_range(0..sections.len());
            let key = BeamKey::new(s as u32, rng.gen_range(0..sections[s]));
            let have = f.beam_len(key).unwrap();
            let n = rng.gen_range(1..=25);
            let rays: Vec<RayRecord> = (have..have + n).map(|j| ray(key, j)).collect();
            f.append(key, &rays).unwrap();
            total += n;
        }
        f.flush().unwrap();
        report(Report::Flushed(total));
        if optimize_too && rng.gen_bool(0.2) {
            drop(f);
            storage::optimize(path, |_, _| {}).unwrap();
            report(Report::Optimized(total));
            f = HoloFile::open(path, &options).unwrap();
        }
        if compact_too && rng.gen_bool(0.3) {
            f.compact().unwrap();
            report(Report::Compacted(total));
        }
    }
}

/// A pipe whose ends are both closed on exec: (read, write).
fn pipe() -> (OwnedFd, OwnedFd) {
    let mut fds = [0; 2];
    // SAFETY: pipe2 writes two descriptors into `fds`, which we then own.
    let rc = unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC) };
    assert_eq!(rc, 0, "pipe2: {}", std::io::Error::last_os_error());
    unsafe { (OwnedFd::from_raw_fd(fds[0]), OwnedFd::from_raw_fd(fds[1])) }
}

/// Starts a writer on `path` that reports on a pipe of its own; returns it
/// and the reports as they come (a line that is not a report comes as Err).
fn start_writer(path: &Path, seed: u32, mode: &str) -> (Proc, mpsc::Receiver<Result<Report, String>>) {
    let (read, write) = pipe();
    let fd = write.as_raw_fd();
    let mut cmd = Command::new(std::env::current_exe().unwrap());
    cmd.args(["child_writer", "--exact", "--ignored", "--test-threads=1"])
        .env(FILE_VAR, path)
        .env(SEED_VAR, seed.to_string())
        .env(MODE_VAR, mode)
        .env(REPORT_FD_VAR, fd.to_string());
    // SAFETY: runs in the forked child before exec; fcntl is async-signal-safe.
    unsafe {
        cmd.pre_exec(move || {
            // This child alone keeps the write end across exec.
            if libc::fcntl(fd, libc::F_SETFD, 0) == -1 {
                return Err(std::io::Error::last_os_error());
            }
            Ok(())
        });
    }
    let child = Proc::start(&mut cmd);
    // Only the child writes now: its death ends the reader's input.
    drop(write);
    let (tx, rx) = mpsc::channel();
    std::thread::spawn(move || {
        let mut lines = BufReader::new(File::from(read));
        let mut line = Vec::new();
        loop {
            line.clear();
            match lines.read_until(b'\n', &mut line) {
                Ok(0) => return,
                Ok(_) => {
                    if tx.send(Report::parse(&line)).is_err() {
                        return;
                    }
                }
                Err(e) => {
                    let _ = tx.send(Err(format!("reading the reports: {e}")));
                    return;
                }
            }
        }
    });
    (child, rx)
}

/// Opens the file after a crash and checks every beam; returns the rays stored.
fn verify(path: &Path) -> u64 {
    let mut f = HoloFile::open(path, &OpenOptions::read_only()).unwrap_or_else(|e| panic!("reopen after kill: {e}"));
    let mut keys = Vec::new();
    for (s, section) in f.sections().iter().enumerate() {
        keys.extend((0..section.beam_count()).map(|b| BeamKey::new(s as u32, b)));
    }
    let mut total = 0;
    let report = f
        .read_beams(&keys, |key, rays| {
            for (j, r) in rays.iter().enumerate() {
                assert_eq!(*r, ray(key, j as u64), "ray {j} of {key:?} is not the one written");
            }
            total += rays.len() as u64;
        })
        .unwrap();
    assert!(
        report.corrupt.is_empty(),
        "corrupt beams after a kill: {:?}",
        report.corrupt
    );
    total
}

/// Runs `rounds` child writers, killing each after a random delay. Every
/// report a writer made before it died is checked against the file.
fn kill_repeatedly(mode: &str, rounds: u32, max_delay_ms: u64) -> (u64, u32) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("crash.hdk");
    HoloFile::create(&path, &settings()).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let mut stored = 0;
    let mut mid_run_kills = 0;
    for round in 0..rounds {
        let (mut child, reports) = start_writer(&path, 1000 + round, mode);
        // Let it get going (its first flush), then kill it at a random instant.
        let first = reports
            .recv_timeout(DEADLINE)
            .unwrap_or_else(|_| panic!("round {round}: no report from the writer:\n{}", child.text()));
        std::thread::sleep(std::time::Duration::from_micros(rng.gen_range(0..max_delay_ms * 1000)));
        let status = child.kill();
        assert_eq!(
            status.signal(),
            Some(libc::SIGKILL),
            "round {round}: the writer must have been killed, not have exited ({status}):\n{}",
            child.text()
        );
        // The pipe ends with the writer: these are all its reports.
        let said: Vec<Report> = std::iter::once(first)
            .chain(reports.iter())
            .collect::<Result<_, _>>()
            .unwrap_or_else(|e| panic!("round {round}: {e}"));
        let mut durable = stored;
        for (i, r) in said.iter().enumerate() {
            match *r {
                Report::Flushed(n) => {
                    assert!(
                        n > durable,
                        "round {round}: report {i} ({r:?}) adds nothing to {durable}"
                    );
                    durable = n;
                }
                Report::Optimized(n) | Report::Compacted(n) => {
                    assert_eq!(n, durable, "round {round}: report {i}: {r:?} changed the rays");
                }
            }
        }
        let now = verify(&path);
        assert!(
            now >= durable,
            "round {round}: {now} rays on disk, but {durable} were reported flushed"
        );
        assert!(now >= stored, "round {round}: rays went missing ({stored} -> {now})");
        mid_run_kills += u32::from(now > stored);
        stored = now;
    }
    let report = storage::check(&path, |_, _| {}).unwrap();
    assert!(report.is_clean());
    assert_eq!(report.rays_ok, stored);
    (stored, mid_run_kills)
}

#[test]
fn sigkill_while_appending_and_committing() {
    let (stored, progressed) = kill_repeatedly("append", 40, 60);
    assert!(
        stored > 1000,
        "the writers made too little progress to test anything: {stored}"
    );
    assert!(progressed >= 30, "only {progressed} of 40 rounds stored new rays");
}

#[test]
fn sigkill_while_compacting() {
    let (stored, _) = kill_repeatedly("compact", 15, 120);
    assert!(stored > 500, "{stored}");
}

#[test]
fn sigkill_while_optimizing() {
    let (stored, _) = kill_repeatedly("optimize", 15, 120);
    assert!(stored > 500, "{stored}");
}
