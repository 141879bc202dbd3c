//! DISKSPACE is a hard limit: the file never grows past it, appends that might
//! not fit are refused before anything is stored, and everything accepted
//! survives.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use holodeck_file::settings::Settings;
use holodeck_file::storage::{HoloFile, OpenOptions, StorageError};
use holodeck_file::testing::{
    all_keys, assert_pattern_contents as assert_contents, pattern_rays as rays, two_sections,
};
use holodeck_protocol::BeamKey;
use rand::{Rng, SeedableRng};

/// Large enough that the gap a commit keeps between metadata copies
/// (64 KiB) is a small part of it.
const LIMIT: u64 = 1200 << 10;

fn settings(diskspace: u64) -> Settings {
    Settings {
        diskspace_bytes: diskspace,
        ..two_sections([4, 3, 2], [2, 2, 2], 1 << 20)
    }
}

fn new_file(dir: &Path, diskspace: u64) -> PathBuf {
    let path = dir.join("limited.hdk");
    HoloFile::create(&path, &settings(diskspace)).unwrap();
    path
}

fn writable(cache: u64) -> OpenOptions {
    OpenOptions {
        writable: true,
        cache_bytes: Some(cache),
        flush_interval: None,
        accept_loss: false,
    }
}

fn disk_len(path: &Path) -> u64 {
    fs::metadata(path).unwrap().len()
}

/// Asserts `e` is the DISKSPACE refusal for `path` and `limit`.
fn assert_disk_space(e: &StorageError, path: &Path, limit: u64) {
    match e {
        StorageError::DiskSpace {
            path: p,
            limit: l,
            needed,
        } => {
            assert_eq!(p, path);
            assert_eq!(*l, limit);
            assert!(*needed > limit, "needed {needed} is within the limit {limit}");
        }
        other => panic!("expected a DISKSPACE refusal, got {other}"),
    }
    let message = e.to_string();
    assert!(message.contains("DISKSPACE"), "{message}");
    assert!(message.contains(&limit.to_string()), "{message}");
    assert!(message.contains(&path.display().to_string()), "{message}");
}

/// Appends packets of 1-21 rays to random beams of a file limited to `limit`
/// bytes until the first refusal,
/// flushing every `flush_every` appends, checking the file length after every
/// append. Returns (file length / limit, ray bytes / limit) after closing.
fn fill(limit: u64, cache: u64, flush_every: u64, seed: u64) -> (f64, f64) {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path(), limit);
    let mut f = HoloFile::open(&path, &writable(cache)).unwrap();
    assert_eq!(f.size_limit(), Some(limit));
    let keys = all_keys(&f);
    let mut rng = rand::rngs::StdRng::seed_from_u64(seed);
    let mut expected: HashMap<BeamKey, u64> = HashMap::new();
    let mut appends = 0u64;
    let refusal = loop {
        let key = keys[rng.gen_range(0..keys.len())];
        let n = rng.gen_range(1..=21u64);
        let have = expected.get(&key).copied().unwrap_or(0);
        match f.append(key, &rays(key, have, n)) {
            Ok(()) => {
                expected.insert(key, have + n);
            }
            Err(e) => {
                // Refused before anything was stored (not by the guard mid-eviction).
                assert_eq!(f.beam_len(key).unwrap(), have);
                break e;
            }
        }
        appends += 1;
        assert!(
            disk_len(&path) <= limit,
            "file grew to {} after append {appends}",
            disk_len(&path)
        );
        // The bound is never below what is on disk.
        let bound = limit - f.headroom().unwrap();
        assert!(
            disk_len(&path) <= bound,
            "{} bytes on disk, bound {bound}",
            disk_len(&path)
        );
        if appends.is_multiple_of(flush_every) {
            f.flush().unwrap();
            assert!(disk_len(&path) <= limit);
        }
        assert!(appends < 1_000_000, "never refused");
    };
    assert_disk_space(&refusal, &path, limit);
    // A refusal stores nothing and spoils nothing: the file flushes and
    // closes within the limit, holding exactly what was accepted.
    let stats = f.io_stats();
    f.flush().unwrap();
    assert!(disk_len(&path) <= limit);
    f.close().unwrap();
    let len = disk_len(&path);
    assert!(len <= limit, "closed at {len} bytes");
    assert_contents(&path, &expected);
    let ray_bytes: u64 = expected.values().sum::<u64>() * 10;
    let fill = (len as f64 / limit as f64, ray_bytes as f64 / limit as f64);
    eprintln!(
        "DISKSPACE {limit}, cache {cache}, flush every {flush_every}: {appends} appends, {} commits, {} relocations, file {len} bytes = {:.1}% of DISKSPACE, rays {:.1}%",
        stats.commits,
        stats.relocations,
        100.0 * fill.0,
        100.0 * fill.1
    );
    assert!(
        fill.0 >= 0.85,
        "the file reached only {:.1}% of DISKSPACE",
        100.0 * fill.0
    );
    fill
}

#[test]
fn filling_with_a_large_cache_stops_at_the_limit() {
    for seed in 0..3 {
        fill(LIMIT, 1 << 20, 200, seed);
    }
}

#[test]
fn filling_with_a_large_cache_and_no_flushes_stops_at_the_limit() {
    fill(LIMIT, 1 << 20, u64::MAX, 7);
}

#[test]
fn filling_through_a_small_cache_evicts_and_stops_at_the_limit() {
    for seed in 0..3 {
        fill(LIMIT, 16 << 10, 500, seed);
    }
}

#[test]
fn filling_a_few_megabytes_stops_at_the_limit() {
    fill(4 << 20, 256 << 10, 2000, 11);
}

#[test]
fn a_refused_append_does_not_stop_smaller_ones() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path(), 0);
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    assert_eq!(f.size_limit(), None, "DISKSPACE=0 means no limit");
    assert_eq!(f.headroom(), None);
    // Room for 8,000 bytes of rays beyond the gap a commit keeps between
    // metadata copies.
    let limit = disk_len(&path) + 8000 + holodeck_file::storage::format::COPY_GAP;
    f.set_size_limit(Some(limit));
    assert_eq!(f.size_limit(), Some(limit));
    let key = BeamKey::new(0, 5);
    let e = f.append(key, &rays(key, 0, 500)).unwrap_err();
    assert_disk_space(&e, &path, limit);
    assert_eq!(f.beam_len(key).unwrap(), 0, "nothing of a refused append is stored");
    f.append(key, &rays(key, 0, 20)).unwrap();
    let other = BeamKey::new(1, 3);
    f.append(other, &rays(other, 0, 10)).unwrap();
    assert!(f.headroom().is_some_and(|h| h < 8000));
    f.close().unwrap();
    assert!(disk_len(&path) <= limit);
    assert_contents(&path, &HashMap::from([(key, 20), (other, 10)]));
}

#[test]
fn a_file_already_past_its_limit_refuses_appends_and_reads_fine() {
    let dir = tempfile::tempdir().unwrap();
    let limit = 64 << 10;
    let path = new_file(dir.path(), limit);
    let mut expected = HashMap::new();
    {
        // Filled past DISKSPACE with the limit lifted.
        let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
        f.set_size_limit(None);
        for b in 0..200u32 {
            let key = BeamKey::new(0, b);
            f.append(key, &rays(key, 0, 50)).unwrap();
            expected.insert(key, 50);
        }
        f.close().unwrap();
    }
    let before = disk_len(&path);
    assert!(before > limit);
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    assert_eq!(f.size_limit(), Some(limit));
    assert_eq!(f.headroom(), Some(0));
    for key in [BeamKey::new(0, 0), BeamKey::new(0, 300), BeamKey::new(1, 0)] {
        let e = f.append(key, &rays(key, 50, 1)).unwrap_err();
        assert_disk_space(&e, &path, limit);
    }
    assert_eq!(
        f.read_beam(BeamKey::new(0, 7)).unwrap(),
        rays(BeamKey::new(0, 7), 0, 50)
    );
    f.close().unwrap();
    assert_eq!(disk_len(&path), before);
    assert_contents(&path, &expected);
    // Read-only opens apply no limit at all.
    let r = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert_eq!(r.size_limit(), None);
}

#[test]
fn the_hard_limit_holds_even_when_the_bound_is_bypassed() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path(), 0);
    let mut expected = HashMap::new();
    let mut f = HoloFile::open(&path, &writable(4 << 20)).unwrap();
    for b in 0..100u32 {
        let key = BeamKey::new(0, b);
        f.append(key, &rays(key, 0, 30)).unwrap();
        expected.insert(key, 30);
    }
    f.flush().unwrap();
    let committed = expected.clone();
    // Rays accepted while there was no limit, then a limit they cannot fit:
    // writing them is refused, nothing is written past the limit, and the
    // file is not poisoned.
    for b in 0..400u32 {
        let key = BeamKey::new(0, b);
        let have = expected.get(&key).copied().unwrap_or(0);
        f.append(key, &rays(key, have, 40)).unwrap();
        expected.insert(key, have + 40);
    }
    let limit = disk_len(&path) + 20_000;
    f.set_size_limit(Some(limit));
    let e = f.flush().unwrap_err();
    assert_disk_space(&e, &path, limit);
    assert!(disk_len(&path) <= limit, "{} > {limit}", disk_len(&path));
    // What a crash now would leave: the previous commit, intact.
    let copy = dir.path().join("copy.hdk");
    fs::copy(&path, &copy).unwrap();
    assert_contents(&copy, &committed);
    // The unwritten rays are still cached; with room they are written.
    assert_eq!(
        f.read_beam(BeamKey::new(0, 350)).unwrap(),
        rays(BeamKey::new(0, 350), 0, 40)
    );
    f.set_size_limit(None);
    f.close().unwrap();
    assert_contents(&path, &expected);
}
