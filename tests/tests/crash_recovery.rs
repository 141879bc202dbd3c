//! Crash safety with real processes and real signals: a child process fills a
//! holodeck file (appending, evicting, relocating, committing, optimizing) and
//! is killed with SIGKILL at random instants. After every kill the file must
//! open without error, every beam must hold exactly a prefix of the rays
//! written to it, and no flushed ray may be missing.

use std::io::{BufRead, BufReader};
use std::path::Path;
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use holodeck_protocol::{BeamKey, RayRecord};
use holodeck_server::settings::Settings;
use holodeck_server::storage::{self, HoloFile, OpenOptions};
use holodeck_server::testing::{pattern_ray as ray, two_sections};
use rand::{Rng, SeedableRng};

const FILE_VAR: &str = "HOLODECK_CRASH_FILE";
const SEED_VAR: &str = "HOLODECK_CRASH_SEED";
const MODE_VAR: &str = "HOLODECK_CRASH_MODE";

fn settings() -> Settings {
    two_sections([3, 2, 2], [1, 1, 2], holodeck_server::settings::DEFAULT_CACHE_BYTES)
}

/// The writer run in the child process. Prints `flushed N` after each flush that
/// made N rays durable in total. Runs until killed.
#[test]
#[ignore = "helper process: started by the crash tests, never on its own"]
fn child_writer() {
    let (Ok(path), Ok(seed)) = (std::env::var(FILE_VAR), std::env::var(SEED_VAR)) else {
        panic!("child_writer runs only as a child of the crash tests");
    };
    let optimize_too = std::env::var(MODE_VAR).is_ok_and(|m| m == "optimize");
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
        println!("flushed {total}");
        if optimize_too && rng.gen_bool(0.2) {
            drop(f);
            storage::optimize(path, |_, _| {}).unwrap();
            println!("optimized {total}");
            f = HoloFile::open(path, &options).unwrap();
        }
    }
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

/// Runs `rounds` child writers, killing each after a random delay.
fn kill_repeatedly(mode: &str, rounds: u32, max_delay_ms: u64) -> (u64, u32) {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("crash.hdk");
    HoloFile::create(&path, &settings()).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    let exe = std::env::current_exe().unwrap();
    let mut stored = 0;
    let mut mid_run_kills = 0;
    for round in 0..rounds {
        let mut child = Command::new(&exe)
            .args([
                "child_writer",
                "--exact",
                "--ignored",
                "--nocapture",
                "--test-threads=1",
            ])
            .env(FILE_VAR, &path)
            .env(SEED_VAR, (1000 + round).to_string())
            .env(MODE_VAR, mode)
            .stdout(Stdio::piped())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        let flushed = Arc::new(AtomicU64::new(0));
        let lines = BufReader::new(child.stdout.take().unwrap());
        let seen = Arc::clone(&flushed);
        let reader = std::thread::spawn(move || {
            for line in lines.lines().map_while(Result::ok) {
                if let Some(n) = line.split_whitespace().nth(1).and_then(|n| n.parse().ok()) {
                    seen.store(n, Ordering::SeqCst);
                }
            }
        });
        // Let it get going, then kill it at a random instant.
        let started = Instant::now();
        while flushed.load(Ordering::SeqCst) <= stored && started.elapsed() < Duration::from_secs(20) {
            std::thread::sleep(Duration::from_millis(1));
        }
        std::thread::sleep(Duration::from_micros(rng.gen_range(0..max_delay_ms * 1000)));
        child.kill().unwrap(); // SIGKILL
        let status = child.wait().unwrap();
        reader.join().unwrap();
        assert!(!status.success(), "the writer must have been killed, not have exited");
        let durable = flushed.load(Ordering::SeqCst);
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
fn sigkill_while_optimizing() {
    let (stored, _) = kill_repeatedly("optimize", 15, 120);
    assert!(stored > 500, "{stored}");
}
