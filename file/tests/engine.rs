//! The storage engine through its public API: round trips, eviction, crash
//! recovery, damaged files, the fragment list and the optimizer.

use std::fs;
use std::os::unix::fs::FileExt;
use std::path::{Path, PathBuf};

use holodeck_file::settings::Settings;
use holodeck_file::storage::{self, format, HoloFile, OpenOptions, StorageError};
use holodeck_protocol::{BeamKey, RayRecord};

use holodeck_file::testing::{assert_pattern_contents as assert_contents, pattern_rays as rays, two_sections};

fn settings() -> Settings {
    two_sections([4, 3, 2], [2, 2, 2], 1 << 20)
}

fn new_file(dir: &Path) -> PathBuf {
    let path = dir.join("test.hdk");
    HoloFile::create(&path, &settings()).unwrap();
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

#[test]
fn appended_rays_read_back_before_and_after_reopen() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let mut expected = std::collections::HashMap::new();
    {
        let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
        for round in 0..5u64 {
            for b in [0u32, 7, 100, 575] {
                let k = BeamKey::new(0, b);
                let have = expected.get(&k).copied().unwrap_or(0);
                f.append(k, &rays(k, have, 3 + round)).unwrap();
                expected.insert(k, have + 3 + round);
            }
            let k = BeamKey::new(1, round as u32);
            f.append(k, &rays(k, 0, 1)).unwrap();
            expected.insert(k, 1);
            if round == 2 {
                f.flush().unwrap();
            }
        }
        assert_eq!(f.beam_len(BeamKey::new(0, 7)).unwrap(), 3 + 4 + 5 + 6 + 7);
        assert_eq!(
            f.read_beam(BeamKey::new(0, 7)).unwrap(),
            rays(BeamKey::new(0, 7), 0, 25)
        );
        f.close().unwrap();
    }
    assert_contents(&path, &expected);
    let f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    let s = f.summary();
    assert_eq!(s.rays(), expected.values().sum::<u64>());
    assert_eq!(s.sections[0].1, 4);
    assert_eq!(s.sections[1], (f.sections()[1].beam_count(), 5, 5));
}

#[test]
fn a_tiny_cache_evicts_relocates_and_stays_within_budget() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let budget = 8 << 10;
    let mut expected = std::collections::HashMap::new();
    let mut f = HoloFile::open(&path, &writable(budget)).unwrap();
    let mut state = 12345u64;
    for step in 0..4000u64 {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        let k = BeamKey::new(0, ((state >> 33) % 60) as u32 * 7);
        let n = 1 + (state >> 50) % 20;
        let have = expected.get(&k).copied().unwrap_or(0);
        f.append(k, &rays(k, have, n)).unwrap();
        expected.insert(k, have + n);
        assert!(
            f.cache_usage().0 <= budget as usize,
            "cache {} over budget",
            f.cache_usage().0
        );
        if step % 500 == 499 {
            f.flush().unwrap();
        }
        if step % 97 == 0 {
            // Reads mixed with writes see every appended ray, flushed or not.
            assert_eq!(f.read_beam(k).unwrap(), rays(k, 0, have + n));
        }
    }
    let stats = f.io_stats();
    assert!(stats.relocations > 0, "beams should have had to move: {stats:?}");
    f.close().unwrap();
    assert_contents(&path, &expected);
    // Freed runs are reused: the file holds little beyond the live rays.
    let s = HoloFile::open(&path, &OpenOptions::read_only()).unwrap().summary();
    assert!(
        s.file_bytes < 2 * s.ray_bytes + 64 * 1024,
        "file {} bytes for {} ray bytes",
        s.file_bytes,
        s.ray_bytes
    );
}

#[test]
fn unflushed_rays_are_lost_but_flushed_ones_survive_a_crash() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let k = BeamKey::new(0, 42);
    let mut f = HoloFile::open(&path, &writable(4096)).unwrap();
    f.append(k, &rays(k, 0, 10)).unwrap();
    f.flush().unwrap();
    // Enough to force eviction writes, but no commit.
    for b in 0..50 {
        let kb = BeamKey::new(0, 1000 + b);
        f.append(kb, &rays(kb, 0, 30)).unwrap();
    }
    f.append(k, &rays(k, 10, 5)).unwrap();
    f.abandon();
    let mut expected = std::collections::HashMap::new();
    expected.insert(k, 10);
    assert_contents(&path, &expected);
}

fn flip_byte(path: &Path, at: u64) {
    let f = fs::OpenOptions::new().read(true).write(true).open(path).unwrap();
    let mut b = [0u8];
    f.read_exact_at(&mut b, at).unwrap();
    f.write_all_at(&[b[0] ^ 0x5a], at).unwrap();
}

fn text_len() -> u32 {
    settings().to_text().len() as u32
}

/// The prefix of a new file of [`settings`].
fn prefix() -> format::Prefix {
    format::Prefix::new(text_len())
}

#[test]
fn a_torn_last_commit_falls_back_to_the_previous_one() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let (a, b) = (BeamKey::new(0, 1), BeamKey::new(0, 2));
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    f.append(a, &rays(a, 0, 4)).unwrap();
    f.flush().unwrap();
    // Copy 2 of the slot the next commit goes to, as it is before that commit.
    let side = 1 - f.open_info().slot;
    let copy2 = format::slot_offset(prefix(), 1, side);
    let old = fs::read(&path).unwrap()[copy2 as usize..copy2 as usize + 64].to_vec();
    f.append(b, &rays(b, 0, 6)).unwrap();
    f.flush().unwrap();
    assert_eq!(f.open_info().slot, side);
    // Dropped, not closed: closing would compact, with commits of its own.
    drop(f);
    // A crash tearing copy 1 of the new slot leaves copy 2 as it was.
    let file = fs::OpenOptions::new().write(true).open(&path).unwrap();
    file.write_all_at(&old, copy2).unwrap();
    drop(file);
    flip_byte(&path, format::slot_offset(prefix(), 0, side) + 20);
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let info = f.open_info();
    assert!(
        info.damage.is_none(),
        "a torn commit loses nothing that completed: {info:?}"
    );
    assert_eq!(info.repaired.len(), 1, "{info:?}");
    assert!(info.repaired[0].contains("cut short by a crash"), "{info:?}");
    assert_eq!(f.read_beam(a).unwrap().len(), 4);
    assert_eq!(f.beam_len(b).unwrap(), 0);
    // Writing goes on from the surviving commit, and the next commit wins.
    f.append(b, &rays(b, 0, 2)).unwrap();
    f.close().unwrap();
    let mut expected = std::collections::HashMap::new();
    expected.insert(a, 4);
    expected.insert(b, 2);
    assert_contents(&path, &expected);
    let f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert!(f.open_info().skipped.is_empty(), "{:?}", f.open_info());
    assert!(f.open_info().repaired.is_empty(), "{:?}", f.open_info());
}

#[test]
fn a_damaged_slot_copy_is_not_taken_for_a_torn_commit() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let (a, b) = (BeamKey::new(0, 1), BeamKey::new(0, 2));
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    f.append(a, &rays(a, 0, 4)).unwrap();
    f.flush().unwrap();
    f.append(b, &rays(b, 0, 6)).unwrap();
    // Dropped, not closed: the commit before must be the one with beam a alone.
    drop(f);
    let side = HoloFile::open(&path, &OpenOptions::read_only())
        .unwrap()
        .open_info()
        .slot;
    let mut expected = std::collections::HashMap::new();
    expected.insert(a, 4);
    expected.insert(b, 6);
    // One copy of the newest slot damaged: its twin holds the commit, nothing is lost.
    flip_byte(&path, format::slot_offset(prefix(), 0, side) + 20);
    let f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert!(f.open_info().skipped.is_empty(), "{:?}", f.open_info());
    assert_eq!(f.open_info().repaired.len(), 1, "{:?}", f.open_info());
    drop(f);
    assert_contents(&path, &expected);
    // Both copies damaged: the newest commit may be lost, so writing is refused.
    flip_byte(&path, format::slot_offset(prefix(), 1, side) + 20);
    let e = HoloFile::open(&path, &writable(1 << 20)).err().unwrap();
    assert!(matches!(&e, StorageError::Damaged { .. }), "{e}");
    assert!(e.to_string().contains("both copies of commit slot"), "{e}");
    let report = storage::check(&path, |_, _| {}).unwrap();
    assert!(report.loses_rays());
    // The older commit still holds beam a, and only it.
    assert_eq!(report.rays_ok, 4);
    let accepted = OpenOptions {
        accept_loss: true,
        ..writable(1 << 20)
    };
    HoloFile::open(&path, &accepted).unwrap().close().unwrap();
    expected.insert(b, 0);
    assert_contents(&path, &expected);
    assert!(storage::check(&path, |_, _| {}).unwrap().is_clean());
}

#[test]
fn corrupt_beams_are_detected_checked_and_salvaged() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let mut expected = std::collections::HashMap::new();
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    for b in 0..20 {
        let k = BeamKey::new(0, b * 11);
        f.append(k, &rays(k, 0, 8)).unwrap();
        expected.insert(k, 8);
    }
    f.close().unwrap();
    let victim = BeamKey::new(0, 77);
    damage_run(&path, victim, 13);
    let before = fs::read(&path).unwrap();

    let mut f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    let err = f.read_beam(victim).unwrap_err();
    assert!(
        matches!(err, StorageError::BeamCorrupt { key, .. } if key == victim),
        "{err}"
    );
    assert!(err.to_string().contains("beam 77 of section 0"), "{err}");
    drop(f);

    let report = storage::check(&path, |_, _| {}).unwrap();
    assert_eq!(report.corrupt, vec![victim]);
    assert_eq!(report.beams_ok, 19);
    assert!(
        storage::optimize(&path, |_, _| {}).is_err(),
        "optimize must refuse a corrupt file"
    );

    let fixed = dir.path().join("fixed.hdk");
    let r = storage::repair(&path, &fixed).unwrap();
    assert_eq!((r.beams, r.rays, r.beams_lost), (19, 152, 1));
    assert_eq!(
        fs::read(&path).unwrap(),
        before,
        "the damaged original must be untouched"
    );
    expected.remove(&victim);
    assert_contents(&fixed, &expected);
    assert!(storage::check(&fixed, |_, _| {}).unwrap().is_clean());
}

#[test]
fn damaged_files_give_errors_that_say_what_and_where() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    {
        let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
        let k = BeamKey::new(0, 3);
        f.append(k, &rays(k, 0, 100)).unwrap();
        f.close().unwrap();
    }
    let good = fs::read(&path).unwrap();
    let p = dir.path().join("bad.hdk");
    let open = |bytes: &[u8]| {
        fs::write(&p, bytes).unwrap();
        HoloFile::open(&p, &OpenOptions::read_only())
            .err()
            .map(|e| e.to_string())
            .unwrap_or_default()
    };
    assert!(open(b"").contains("not a holodeck file"));
    assert!(open(b"#?RADIANCE\nFORMAT=holodeck\n").contains("holodeck import radiance"));
    assert!(open(&good[..40]).contains("truncated"));
    assert!(open(&good[..300]).contains("truncated"), "{}", open(&good[..300]));
    // A later format says so in both header copies; one copy saying so is damage.
    let mut future = good.clone();
    future[8] = 4;
    assert_eq!(open(&future), "", "copy 2 still reads");
    future[format::header_stride(prefix()) as usize + 8] = 4;
    assert!(open(&future).contains("version 4 is newer"), "{}", open(&future));
    // One copy of the settings text damaged: the other is read, and reported.
    let text = format::text_offset(prefix(), 0) as usize + 5;
    let mut one = good.clone();
    one[text] ^= 1;
    assert_eq!(open(&one), "");
    let f = HoloFile::open(&p, &OpenOptions::read_only()).unwrap();
    assert!(
        f.open_info().repaired[0].contains("settings text, copy 1"),
        "{:?}",
        f.open_info()
    );
    drop(f);
    let mut both = one.clone();
    both[format::text_offset(prefix(), 1) as usize + 5] ^= 1;
    assert!(open(&both).contains("settings text"), "{}", open(&both));
    // A writable open restores the damaged copy from the other.
    fs::write(&p, &one).unwrap();
    HoloFile::open(&p, &writable(1 << 20)).unwrap().close().unwrap();
    assert!(storage::check(&p, |_, _| {}).unwrap().is_clean());
    // A directory whose checksum is fine but which points outside the file.
    let lying = dir.path().join("lying.hdk");
    fs::write(&lying, &good).unwrap();
    point_a_beam_outside_the_file(&lying);
    let f = HoloFile::open(&lying, &OpenOptions::read_only()).unwrap();
    let damage = f.open_info().damage.clone().expect("the newest commit is damaged");
    assert_eq!((damage.claimed_rays, damage.readable_rays), (Some(100), 0));
    assert!(
        damage.describe().contains("1 beams (100 rays) lie past the end"),
        "{}",
        damage.describe()
    );
    drop(f);
    let e = HoloFile::open(&lying, &writable(1 << 20)).err().unwrap();
    assert!(matches!(e, StorageError::Damaged { .. }), "{e}");
    // Zero every slot.
    let mut noslots = good.clone();
    for copy in 0..2 {
        let at = format::slot_offset(prefix(), copy, 0) as usize;
        noslots[at..at + 128].fill(0);
    }
    assert!(open(&noslots).contains("neither commit slot"));
}

/// Rewrites the newest commit so that beam 3 of section 0 points past the end
/// of the file, with every checksum valid, and blanks the other slot.
fn point_a_beam_outside_the_file(path: &Path) {
    let f = fs::OpenOptions::new().read(true).write(true).open(path).unwrap();
    let len = f.metadata().unwrap().len();
    let n = prefix();
    let read = |at: u64, len: u64| {
        let mut b = vec![0u8; len as usize];
        f.read_exact_at(&mut b, at).unwrap();
        b
    };
    let (side, slot) = (0..2)
        .filter_map(|side| {
            let at = format::slot_offset(n, 0, side);
            format::decode_slot(&read(at, 64), at).unwrap().map(|s| (side, s))
        })
        .max_by_key(|(_, s)| s.generation)
        .unwrap();
    let beams: Vec<u32> = settings().sections.iter().map(|s| s.beam_count()).collect();
    let root_at = slot.roots[0];
    let mut chunks = format::decode_root(&read(root_at, slot.root_len), root_at, slot.generation, &beams).unwrap();
    let c = chunks[0];
    let mut dir = format::decode_directory(&read(c.copies[0], c.len), c.copies[0], 0, 0, c.beams, 0).unwrap();
    dir[3].offset = len + 4096;
    let block = format::encode_directory(0, 0, &dir);
    chunks[0].copies = [len, len];
    chunks[0].len = block.len() as u64;
    f.write_all_at(&block, len).unwrap();
    let root = format::encode_root(slot.generation, &chunks);
    let root_at = len + block.len() as u64;
    f.write_all_at(&root, root_at).unwrap();
    let new_slot = format::Slot {
        roots: [root_at, root_at],
        root_len: root.len() as u64,
        root_crc: crc32c(&root),
        ..slot
    };
    for copy in 0..2 {
        f.write_all_at(&format::encode_slot(&new_slot), format::slot_offset(n, copy, side))
            .unwrap();
        f.write_all_at(&[0u8; 64], format::slot_offset(n, copy, 1 - side))
            .unwrap();
    }
}

fn crc32c(bytes: &[u8]) -> u32 {
    // CRC-32C (Castagnoli), bitwise: the test's own check on the engine's checksums.
    let mut crc = !0u32;
    for &b in bytes {
        crc ^= u32::from(b);
        for _ in 0..8 {
            crc = if crc & 1 != 0 {
                (crc >> 1) ^ 0x82F6_3B78
            } else {
                crc >> 1
            };
        }
    }
    !crc
}

/// Rays appended a few at a time to many beams, flushed after each round, as
/// samplers fill a holodeck: runs outgrow their places and move, leaving holes.
fn fragmented_fill(path: &Path, rounds: u64) -> (HoloFile, std::collections::HashMap<BeamKey, u64>) {
    let mut expected = std::collections::HashMap::new();
    let mut f = HoloFile::open(path, &writable(1 << 16)).unwrap();
    for round in 0..rounds {
        for s in 0..2u32 {
            let beams = f.sections()[s as usize].beam_count();
            for b in (round as u32 % 3..beams).step_by(2) {
                let k = BeamKey::new(s, b);
                let have = expected.get(&k).copied().unwrap_or(0);
                let n = 1 + (u64::from(b) * 7 + round) % 4;
                f.append(k, &rays(k, have, n)).unwrap();
                expected.insert(k, have + n);
            }
        }
        f.flush().unwrap();
    }
    (f, expected)
}

#[test]
fn closing_compacts_holes_and_reserves_away_and_keeps_every_ray() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let (f, expected) = fragmented_fill(&path, 40);
    let open = f.summary();
    assert!(
        open.free_bytes * 5 > open.file_bytes,
        "a fill that leaves little free: {open:?}"
    );
    f.close().unwrap();
    assert_contents(&path, &expected);
    let check = storage::check(&path, |_, _| {}).unwrap();
    assert!(check.is_clean(), "{check:?}");
    let after = HoloFile::open(&path, &OpenOptions::read_only()).unwrap().summary();
    assert_eq!(after.rays(), open.rays());
    // Packed to within 1% of free space (plus one leftover hole's rounding),
    // but for the gap kept between the metadata's two copies.
    assert!(
        after.free_bytes.saturating_sub(format::COPY_GAP) * 100 <= after.file_bytes + 200,
        "{after:?}"
    );
    let header = format::data_start(prefix());
    assert_eq!(
        after.file_bytes,
        header + after.ray_bytes + after.metadata_bytes + after.free_bytes
    );
    assert!(
        after.file_bytes * 10 < open.file_bytes * 8,
        "{} -> {}",
        open.file_bytes,
        after.file_bytes
    );
    // A file with little free space is closed as it is.
    let mut f = HoloFile::open(&path, &writable(1 << 16)).unwrap();
    f.append(
        BeamKey::new(0, 1),
        &rays(BeamKey::new(0, 1), expected[&BeamKey::new(0, 1)], 1),
    )
    .unwrap();
    f.close().unwrap();
    let again = HoloFile::open(&path, &OpenOptions::read_only()).unwrap().summary();
    assert!(
        again.generation <= after.generation + 2,
        "{} -> {}",
        after.generation,
        again.generation
    );
}

#[test]
fn compacting_in_small_windows_packs_the_same_and_a_read_only_file_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let (mut f, expected) = fragmented_fill(&path, 25);
    let moved = f.compact().unwrap();
    assert!(moved > 0);
    drop(f);
    assert_contents(&path, &expected);
    let after = HoloFile::open(&path, &OpenOptions::read_only()).unwrap().summary();
    assert!(
        after.free_bytes.saturating_sub(format::COPY_GAP) * 100 <= after.file_bytes + 200,
        "{after:?}"
    );
    let mut ro = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert!(matches!(ro.compact(), Err(StorageError::ReadOnly { .. })));
}

#[test]
fn optimize_collates_beams_and_removes_fragments() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let mut expected = std::collections::HashMap::new();
    let mut f = HoloFile::open(&path, &writable(2048)).unwrap();
    for round in 0..30u64 {
        for b in (0..200u32).rev().step_by(3) {
            let k = BeamKey::new(0, b);
            let have = expected.get(&k).copied().unwrap_or(0);
            f.append(k, &rays(k, have, 1 + (b as u64 + round) % 4)).unwrap();
            expected.insert(k, have + 1 + (b as u64 + round) % 4);
        }
        f.flush().unwrap();
    }
    // Dropped, not closed: closing would compact the fragments away.
    drop(f);
    let before = HoloFile::open(&path, &OpenOptions::read_only()).unwrap().summary();
    assert!(before.fragments > 0);
    let r = storage::optimize(&path, |_, _| {}).unwrap();
    assert_eq!(r.rays, before.rays());
    assert_contents(&path, &expected);
    let f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    let after = f.summary();
    // No free space but the gap between the metadata's two copies: together
    // with one copy of the directories and root, COPY_GAP.
    assert_eq!(
        after.free_bytes,
        format::COPY_GAP.saturating_sub(after.metadata_bytes / 2)
    );
    assert!(after.fragments <= 1, "{after:?}");
    // Smaller but for that gap (this file is small beside 64 KiB).
    assert!(r.bytes_after - after.free_bytes < r.bytes_before);
    // Nothing but the two header copies, rays and two copies of one compact
    // directory per section (one chunk each here): one byte per empty beam,
    // six per filled one, 20 bytes of framing and the first run's absolute
    // offset per block; and two copies of the root (20 + 44 per chunk + 4).
    let header = format::data_start(prefix());
    assert_eq!(
        after.file_bytes,
        header + after.ray_bytes + after.metadata_bytes + after.free_bytes
    );
    let (beams, filled): (u64, u64) = after
        .sections
        .iter()
        .map(|s| (u64::from(s.0), u64::from(s.1)))
        .fold((0, 0), |a, b| (a.0 + b.0, a.1 + b.1));
    assert!(
        after.metadata_bytes <= 2 * (beams + 6 * filled + 2 * (20 + 8)) + 2 * format::root_len(2),
        "{} metadata bytes",
        after.metadata_bytes
    );
    let offsets: Vec<u64> = f
        .directory(0)
        .unwrap()
        .iter()
        .filter(|e| e.count > 0)
        .map(|e| e.offset)
        .collect();
    assert!(offsets.windows(2).all(|w| w[0] < w[1]), "beams collated in beam order");
}

#[test]
fn locks_read_only_and_bad_keys() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let _writer = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let e = HoloFile::open(&path, &writable(1 << 20)).err().unwrap();
    assert!(matches!(e, StorageError::Locked { .. }), "{e}");
    drop(_writer);
    let mut r = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert!(matches!(
        r.append(BeamKey::new(0, 0), &[RayRecord::default()]),
        Err(StorageError::ReadOnly { .. })
    ));
    assert!(matches!(
        r.read_beam(BeamKey::new(5, 0)),
        Err(StorageError::NoSuchSection { section: 5, count: 2 })
    ));
    let e = r.read_beam(BeamKey::new(1, 1_000_000)).unwrap_err();
    assert!(e.to_string().contains("out of range"), "{e}");
    assert!(matches!(
        HoloFile::create(&path, &settings()),
        Err(StorageError::Exists { .. })
    ));
}

#[test]
fn random_damage_never_panics_and_never_yields_unwritten_rays() {
    use rand::{Rng, SeedableRng};
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let mut expected = std::collections::HashMap::new();
    {
        let mut f = HoloFile::open(&path, &writable(4096)).unwrap();
        for round in 0..6u64 {
            for b in 0..40u32 {
                let k = BeamKey::new(b % 2, b * 5 + round as u32 % 3);
                let have = expected.get(&k).copied().unwrap_or(0);
                f.append(k, &rays(k, have, 2 + round)).unwrap();
                expected.insert(k, have + 2 + round);
            }
            f.flush().unwrap();
        }
        f.close().unwrap();
    }
    let good = fs::read(&path).unwrap();
    let mut rng = rand::rngs::StdRng::seed_from_u64(99);
    let bad = dir.path().join("damaged.hdk");
    let total: u64 = expected.values().sum();
    let (mut opened, mut clean, mut flagged, mut unreadable) = (0, 0, 0, 0);
    for trial in 0..300 {
        let mut bytes = good.clone();
        match trial % 3 {
            0 => bytes.truncate(rng.gen_range(0..good.len())),
            1 => {
                for _ in 0..rng.gen_range(1..8) {
                    let at = rng.gen_range(0..bytes.len());
                    bytes[at] ^= 1 << rng.gen_range(0..8);
                }
            }
            _ => {
                let at = rng.gen_range(0..bytes.len() - 8);
                let v: u64 = rng.gen();
                bytes[at..at + 8].copy_from_slice(&v.to_le_bytes());
            }
        }
        fs::write(&bad, &bytes).unwrap();
        // Whatever opens must only ever deliver rays that were really written.
        if let Ok(mut f) = HoloFile::open(&bad, &OpenOptions::read_only()) {
            opened += 1;
            let keys: Vec<BeamKey> = expected.keys().copied().collect();
            f.read_beams(&keys, |k, got| {
                assert!(got.len() as u64 <= expected[&k]);
                assert_eq!(got, rays(k, 0, got.len() as u64).as_slice(), "trial {trial}: {k:?}");
            })
            .unwrap();
        }
        // No silent loss: a check that finds nothing wrong means every ray is there.
        match storage::check(&bad, |_, _| {}) {
            Ok(r) if r.is_clean() => {
                clean += 1;
                assert_eq!(r.rays_ok, total, "trial {trial}: check passed a file that lost rays");
            }
            Ok(r) => {
                flagged += 1;
                assert!(r.rays_ok <= total);
            }
            Err(_) => unreadable += 1,
        }
        let out = dir.path().join(format!("salvage{trial}.hdk"));
        if storage::repair(&bad, &out).is_ok() {
            assert!(storage::check(&out, |_, _| {}).unwrap().is_clean());
            fs::remove_file(&out).unwrap();
        }
    }
    // Damage lands in rays, free space and metadata alike: every outcome occurs.
    assert!(opened >= 100, "only {opened} of 300 damaged files opened");
    assert!(flagged >= 100, "only {flagged} of 300 damaged files were flagged");
    // Metadata copies 64 KiB apart make a file that cannot be opened rare.
    assert!(clean > 0, "clean {clean}, unreadable {unreadable}");
}

#[test]
fn flush_if_due_makes_rays_durable_after_a_quiet_spell() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let hour = Some(std::time::Duration::from_secs(3600));
    let mut f = HoloFile::open(
        &path,
        &OpenOptions {
            writable: true,
            cache_bytes: Some(1 << 20),
            flush_interval: hour,
            accept_loss: false,
        },
    )
    .unwrap();
    let k = BeamKey::new(0, 9);
    f.append(k, &rays(k, 0, 7)).unwrap();
    assert!(!f.flush_if_due().unwrap(), "not due for an hour");
    f.set_flush_interval(Some(std::time::Duration::ZERO));
    assert!(f.flush_if_due().unwrap(), "due, with rays to write");
    assert!(!f.flush_if_due().unwrap(), "nothing left to flush");
    f.abandon();
    let mut expected = std::collections::HashMap::new();
    expected.insert(k, 7);
    assert_contents(&path, &expected);
}

#[test]
fn reading_beams_with_unwritten_tails_through_a_tiny_cache() {
    // Beams with rays on disk *and* unwritten tails in the cache: reading them
    // all must join both parts and must not move runs the read is still using.
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let keys: Vec<BeamKey> = (0..60).map(|b| BeamKey::new(0, b * 9)).collect();
    {
        let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
        for &k in &keys {
            f.append(k, &rays(k, 0, 40)).unwrap();
        }
        f.close().unwrap();
    }
    let mut f = HoloFile::open(&path, &writable(6 << 10)).unwrap();
    for &k in &keys {
        f.append(k, &rays(k, 40, 3)).unwrap();
    }
    for _ in 0..3 {
        let mut seen = 0;
        let report = f
            .read_beams(&keys, |k, got| {
                assert_eq!(got, rays(k, 0, 43).as_slice(), "{k:?}");
                seen += 1;
            })
            .unwrap();
        assert!(report.corrupt.is_empty(), "{:?}", report.corrupt);
        assert_eq!(seen, keys.len());
        assert!(f.cache_usage().0 <= f.cache_usage().1);
    }
    f.close().unwrap();
    let expected = keys.iter().map(|&k| (k, 43)).collect();
    assert_contents(&path, &expected);
}

/// Writes a file in format version 1, as earlier builds did: one header, one
/// root, one directory block per section. Returns what it holds.
fn write_format_1(path: &Path) -> std::collections::HashMap<BeamKey, u64> {
    let push_crc = |mut b: Vec<u8>| {
        let crc = crc32c(&b);
        b.extend_from_slice(&crc.to_le_bytes());
        b
    };
    let text = settings().to_text();
    let mut out = Vec::new();
    out.extend_from_slice(b"HOLODECK");
    out.extend_from_slice(&1u32.to_le_bytes());
    out.extend_from_slice(&(text.len() as u32).to_le_bytes());
    out.resize(60, 0);
    out = push_crc(out);
    out.resize(192, 0); // both slots, written below
    out.extend_from_slice(&push_crc(text.as_bytes().to_vec()));
    let mut expected = std::collections::HashMap::new();
    let mut dirs = Vec::new();
    for (s, section) in settings().sections.iter().enumerate() {
        let mut entries = vec![format::BeamEntry::default(); section.beam_count() as usize];
        for b in (0..section.beam_count()).step_by(37) {
            let k = BeamKey::new(s as u32, b);
            let n = 1 + u64::from(b % 5);
            let bytes = RayRecord::slice_as_bytes(&rays(k, 0, n)).to_vec();
            entries[b as usize] = format::BeamEntry {
                offset: out.len() as u64,
                count: n as u32,
                crc: crc32c(&bytes),
            };
            out.extend_from_slice(&bytes);
            expected.insert(k, n);
        }
        dirs.push(entries);
    }
    let mut refs = Vec::new();
    for (s, entries) in dirs.iter().enumerate() {
        // The entries are coded as in format 2; only the block's header differs.
        let v2 = format::encode_directory(s as u32, 0, entries);
        let mut block = b"HDKD".to_vec();
        block.extend_from_slice(&(s as u32).to_le_bytes());
        block.extend_from_slice(&(entries.len() as u32).to_le_bytes());
        block.extend_from_slice(&v2[16..v2.len() - 4]);
        let block = push_crc(block);
        let rays: u64 = entries.iter().map(|e| u64::from(e.count)).sum();
        refs.push((out.len() as u64, block.len() as u64, entries.len() as u32, rays));
        out.extend_from_slice(&block);
    }
    let mut root = b"HDKR".to_vec();
    root.extend_from_slice(&1u64.to_le_bytes());
    root.extend_from_slice(&(refs.len() as u32).to_le_bytes());
    for (offset, len, beams, rays) in &refs {
        root.extend_from_slice(&offset.to_le_bytes());
        root.extend_from_slice(&len.to_le_bytes());
        root.extend_from_slice(&beams.to_le_bytes());
        root.extend_from_slice(&rays.to_le_bytes());
    }
    let root = push_crc(root);
    let root_at = out.len() as u64;
    out.extend_from_slice(&root);
    let mut slot = b"HDKC".to_vec();
    slot.extend_from_slice(&1u64.to_le_bytes());
    slot.extend_from_slice(&root_at.to_le_bytes());
    slot.extend_from_slice(&(root.len() as u64).to_le_bytes());
    slot.extend_from_slice(&crc32c(&root).to_le_bytes());
    slot.resize(60, 0);
    let slot = push_crc(slot);
    out[64..128].copy_from_slice(&slot);
    fs::write(path, &out).unwrap();
    expected
}

#[test]
fn format_1_files_are_read_refused_for_writing_and_converted_by_optimize() {
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("old.hdk");
    let expected = write_format_1(&path);
    assert!(expected.len() > 50);
    assert_contents(&path, &expected);
    let report = storage::check(&path, |_, _| {}).unwrap();
    assert!(report.is_clean(), "{report:?}");
    assert_eq!(report.rays_ok, expected.values().sum::<u64>());
    let e = HoloFile::open(&path, &writable(1 << 20)).err().unwrap();
    assert!(e.to_string().contains("holodeck optimize"), "{e}");
    let r = storage::optimize(&path, |_, _| {}).unwrap();
    assert_eq!(r.rays, report.rays_ok);
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let k = BeamKey::new(0, 1);
    f.append(k, &rays(k, 0, 3)).unwrap();
    f.close().unwrap();
    let mut expected = expected;
    expected.insert(k, 3);
    assert_contents(&path, &expected);
    assert!(storage::check(&path, |_, _| {}).unwrap().is_clean());
}

/// Flips a byte `at` bytes into the run of beam `key` of the file at `path`.
fn damage_run(path: &Path, key: BeamKey, at: u64) {
    let offset = HoloFile::open(path, &OpenOptions::read_only())
        .unwrap()
        .directory(key.section)
        .unwrap()[key.beam as usize]
        .offset;
    flip_byte(path, offset + at);
}

#[test]
fn a_damaged_beam_loses_its_old_rays_and_writing_goes_on() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let mut expected = std::collections::HashMap::new();
    for b in 0..20 {
        let k = BeamKey::new(0, b * 11);
        f.append(k, &rays(k, 0, 8)).unwrap();
        expected.insert(k, 8);
    }
    f.close().unwrap();
    let victim = BeamKey::new(0, 77);
    damage_run(&path, victim, 13);
    // A writer adds rays to the damaged beam (beyond its run: it must move,
    // reading the old rays) and to others: the flush succeeds.
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let fresh: Vec<RayRecord> = rays(victim, 8, 40);
    f.append(victim, &fresh).unwrap();
    let other = BeamKey::new(0, 11);
    f.append(other, &rays(other, 8, 5)).unwrap();
    f.flush().expect("a damaged beam does not stop the writer");
    let stats = f.io_stats();
    assert_eq!((stats.damaged_beams, stats.damaged_rays), (1, 8));
    f.close().unwrap();
    // The victim holds only its new rays, every other beam all of its own.
    let mut f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert_eq!(f.read_beam(victim).unwrap(), fresh);
    assert_eq!(f.read_beam(other).unwrap().len(), 13);
    drop(f);
    assert!(
        storage::check(&path, |_, _| {}).unwrap().is_clean(),
        "nothing damaged is left"
    );
}

#[test]
fn rays_appended_in_place_to_a_damaged_beam_are_not_lost_with_it() {
    let dir = tempfile::tempdir().unwrap();
    let path = new_file(dir.path());
    let victim = BeamKey::new(0, 5);
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    f.append(victim, &rays(victim, 0, 8)).unwrap();
    f.close().unwrap();
    damage_run(&path, victim, 3);
    // Two rays: little enough to grow the run where it lies.
    let mut f = HoloFile::open(&path, &writable(1 << 20)).unwrap();
    let fresh = rays(victim, 8, 2);
    f.append(victim, &fresh).unwrap();
    f.flush().unwrap();
    assert_eq!(f.io_stats().damaged_rays, 8);
    f.close().unwrap();
    let mut f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    assert_eq!(f.read_beam(victim).unwrap(), fresh, "the new rays stand alone");
    drop(f);
    assert!(storage::check(&path, |_, _| {}).unwrap().is_clean());
}
