//! Damaged files: every bit of metadata flipped one at a time, both copies of
//! a directory block destroyed, and truncation. Damage is always reported,
//! never taken for a crash, and costs at most the beams the damaged block
//! described; writing on top of a damaged newest commit needs consent.

use std::collections::HashMap;
use std::fs;
use std::path::{Path, PathBuf};

use holodeck_file::settings::Settings;
use holodeck_file::storage::{self, HoloFile, OpenOptions, StorageError};
use holodeck_file::testing::{assert_pattern_contents, metadata_map, pattern_rays, two_sections, zero_every_page};
use holodeck_protocol::BeamKey;

fn writable() -> OpenOptions {
    OpenOptions {
        writable: true,
        cache_bytes: Some(1 << 20),
        flush_interval: None,
        accept_loss: false,
    }
}

/// A file with `settings`, filled over three commits; returns its path and contents.
fn filled(dir: &Path, settings: &Settings, beams: u32, step: u32) -> (PathBuf, HashMap<BeamKey, u64>) {
    let path = dir.join("filled.hdk");
    HoloFile::create(&path, settings).unwrap();
    let mut expected = HashMap::new();
    let mut f = HoloFile::open(&path, &writable()).unwrap();
    for round in 0..3u64 {
        for i in 0..beams {
            let s = i % 2;
            let count = settings.sections[s as usize].beam_count();
            let k = BeamKey::new(s, (i * step) % count);
            let have = expected.get(&k).copied().unwrap_or(0);
            f.append(k, &pattern_rays(k, have, 1 + round)).unwrap();
            expected.insert(k, have + 1 + round);
        }
        f.flush().unwrap();
    }
    f.close().unwrap();
    (path, expected)
}

#[test]
fn every_single_bit_flip_in_metadata_is_detected_and_loses_nothing() {
    let dir = tempfile::tempdir().unwrap();
    // A small file: 208 + 30 beams, so every bit of its metadata can be tried.
    let (path, expected) = filled(dir.path(), &two_sections([2, 2, 1], [1, 1, 1], 1 << 20), 60, 7);
    let total: u64 = expected.values().sum();
    let good = fs::read(&path).unwrap();
    let map = metadata_map(&path);
    let bits: u64 = map.iter().map(|m| m.extent.len * 8).sum();
    assert!(map.len() >= 14, "{map:?}");
    let bad = dir.path().join("flipped.hdk");
    let mut flips = 0u64;
    for block in &map {
        for at in block.extent.offset..block.extent.end() {
            for bit in 0..8 {
                let mut bytes = good.clone();
                bytes[at as usize] ^= 1 << bit;
                fs::write(&bad, &bytes).unwrap();
                let where_ = format!("{} byte {at} bit {bit}", block.what);
                let report = storage::check(&bad, |_, _| {}).unwrap_or_else(|e| panic!("{where_}: {e}"));
                assert!(!report.is_clean(), "{where_}: not detected");
                assert!(report.damage.is_none(), "{where_}: {:?}", report.damage);
                assert!(report.corrupt.is_empty(), "{where_}");
                assert_eq!(report.rays_ok, total, "{where_}: rays lost");
                // Every eighth flip: a writable open needs no consent, and
                // restores the damaged copy so the file checks clean again.
                if flips.is_multiple_of(8) {
                    HoloFile::open(&bad, &writable())
                        .unwrap_or_else(|e| panic!("{where_}: {e}"))
                        .close()
                        .unwrap();
                    let again = storage::check(&bad, |_, _| {}).unwrap();
                    assert!(again.is_clean(), "{where_}: not restored: {again:?}");
                    assert_pattern_contents(&bad, &expected);
                }
                flips += 1;
            }
        }
    }
    assert_eq!(flips, bits);
}

#[test]
fn losing_both_copies_of_a_directory_block_costs_at_most_its_beams() {
    let dir = tempfile::tempdir().unwrap();
    // 22,738 beams in section 0: three directory chunks.
    let settings = two_sections([7, 5, 4], [1, 1, 1], 1 << 20);
    let (path, expected) = filled(dir.path(), &settings, 400, 113);
    let good = fs::read(&path).unwrap();
    let map = metadata_map(&path);
    let chunks: Vec<(u32, u32, u32)> = {
        let mut c: Vec<_> = map.iter().filter_map(|m| m.beams).collect();
        c.dedup();
        c
    };
    assert_eq!(chunks.len(), 4, "{chunks:?}");
    let bad = dir.path().join("lost-chunk.hdk");
    for &(section, first, beams) in &chunks {
        let inside = |k: &BeamKey| k.section == section && (first..first + beams).contains(&k.beam);
        let described: u64 = expected.iter().filter(|(k, _)| inside(k)).map(|(_, n)| n).sum();
        let mut bytes = good.clone();
        for m in map.iter().filter(|m| m.beams == Some((section, first, beams))) {
            bytes[m.extent.offset as usize + 7] ^= 0x40;
        }
        fs::write(&bad, &bytes).unwrap();
        let report = storage::check(&bad, |_, _| {}).unwrap();
        let damage = report.damage.clone().expect("both copies lost is damage");
        assert!(
            damage
                .describe()
                .contains(&format!("section {section} beams {first}..{}", first + beams)),
            "{}",
            damage.describe()
        );
        assert!(damage.rays_lost().unwrap() <= described, "{}", damage.describe());
        assert!(report.rays_ok >= expected.values().sum::<u64>() - described);
        // Writing on top needs consent.
        let e = HoloFile::open(&bad, &writable()).err().unwrap();
        assert!(matches!(e, StorageError::Damaged { .. }), "{e}");
        assert!(e.to_string().contains("--accept-loss"), "{e}");
        // Every beam the block did not describe reads back whole; those it did
        // are either gone or (from the commit before) a true prefix.
        let mut f = HoloFile::open(&bad, &OpenOptions::read_only()).unwrap();
        let keys: Vec<BeamKey> = expected.keys().copied().collect();
        f.read_beams(&keys, |k, got| {
            if inside(&k) {
                assert!(got.len() as u64 <= expected[&k]);
                assert_eq!(got, pattern_rays(k, 0, got.len() as u64).as_slice());
            } else {
                assert_eq!(got, pattern_rays(k, 0, expected[&k]).as_slice(), "{k:?}");
            }
        })
        .unwrap();
        drop(f);
        // Repair copies everything that verifies.
        let fixed = dir.path().join(format!("fixed-{section}-{first}.hdk"));
        let r = storage::repair(&bad, &fixed).unwrap();
        assert_eq!(r.rays, report.rays_ok);
        assert!(storage::check(&fixed, |_, _| {}).unwrap().is_clean());
        // With consent, what can be read becomes the new, whole state.
        let accepted = OpenOptions {
            accept_loss: true,
            ..writable()
        };
        HoloFile::open(&bad, &accepted).unwrap().close().unwrap();
        let after = storage::check(&bad, |_, _| {}).unwrap();
        assert!(after.is_clean(), "{after:?}");
        assert_eq!(after.rays_ok, report.rays_ok);
    }
}

#[test]
fn a_truncated_file_is_damage_and_optimize_refuses_it() {
    let dir = tempfile::tempdir().unwrap();
    let (path, expected) = filled(dir.path(), &two_sections([4, 3, 2], [2, 2, 2], 1 << 20), 300, 7);
    let total: u64 = expected.values().sum();
    let good = fs::read(&path).unwrap();
    let cut = dir.path().join("cut.hdk");
    // Into the rays and past the first copies of the metadata (the second
    // copies lie COPY_GAP further on, also cut off).
    fs::write(&cut, &good[..good.len() / 4]).unwrap();
    let report = storage::check(&cut, |_, _| {}).unwrap();
    assert!(report.loses_rays(), "{report:?}");
    let damage = report.damage.clone().unwrap();
    let text = damage.describe();
    assert!(
        text.contains("truncated") && text.contains(&format!("commit {}", damage.generation)),
        "{text}"
    );
    assert!(report.rays_ok < total);
    let before = fs::read(&cut).unwrap();
    let e = storage::optimize(&cut, |_, _| {}).unwrap_err();
    assert!(matches!(e, StorageError::Damaged { .. }), "{e}");
    assert_eq!(
        fs::read(&cut).unwrap(),
        before,
        "optimize must leave a damaged file alone"
    );
    // Repair keeps every beam that still verifies, each a true prefix.
    let fixed = dir.path().join("fixed.hdk");
    let r = storage::repair(&cut, &fixed).unwrap();
    assert_eq!(r.rays, report.rays_ok);
    let mut f = HoloFile::open(&fixed, &OpenOptions::read_only()).unwrap();
    let keys: Vec<BeamKey> = expected.keys().copied().collect();
    let mut saved = 0;
    f.read_beams(&keys, |k, got| {
        assert_eq!(got, pattern_rays(k, 0, got.len() as u64).as_slice());
        saved += got.len() as u64;
    })
    .unwrap();
    assert_eq!(saved, r.rays);
}

#[test]
fn a_flip_near_the_end_of_a_filled_file_is_reported_and_costs_at_most_a_beam() {
    let dir = tempfile::tempdir().unwrap();
    let (path, expected) = filled(dir.path(), &two_sections([4, 3, 2], [2, 2, 2], 1 << 20), 300, 7);
    let good = fs::read(&path).unwrap();
    // What the file uses: every copy of its metadata and every beam's run.
    let mut used: Vec<(u64, u64)> = metadata_map(&path)
        .iter()
        .map(|m| (m.extent.offset, m.extent.end()))
        .collect();
    let f = HoloFile::open(&path, &OpenOptions::read_only()).unwrap();
    for s in 0..2 {
        used.extend(
            f.directory(s)
                .unwrap()
                .iter()
                .filter(|e| e.count > 0)
                .map(|e| (e.offset, e.extent().end())),
        );
    }
    drop(f);
    let most = expected.values().copied().max().unwrap();
    let total: u64 = expected.values().sum();
    let mut detected = 0;
    for back in (100..=3000).step_by(100) {
        let mut bytes = good.clone();
        let at = bytes.len() - back;
        bytes[at] ^= 16;
        fs::write(&path, &bytes).unwrap();
        let report = storage::check(&path, |_, _| {}).unwrap();
        let in_use = used.iter().any(|&(a, b)| (a..b).contains(&(at as u64)));
        // A flip in free space harms nothing; anywhere else it is reported.
        assert_eq!(!report.is_clean(), in_use, "{back} bytes from the end: {report:?}");
        detected += usize::from(in_use);
        assert!(report.damage.is_none(), "{report:?}");
        assert!(
            report.corrupt.len() <= 1 && report.rays_ok + most >= total,
            "{report:?}"
        );
    }
    assert!(detected >= 20, "only {detected} of 30 flips landed in use");
}

#[test]
fn zeroing_any_one_page_loses_at_most_the_beams_recorded_in_it() {
    let dir = tempfile::tempdir().unwrap();
    let (path, expected) = filled(dir.path(), &two_sections([4, 3, 2], [2, 2, 2], 1 << 20), 300, 7);
    let (pages, worst) = zero_every_page(&path);
    assert_eq!(
        expected.values().sum::<u64>(),
        storage::check(&path, |_, _| {}).unwrap().rays_ok
    );
    eprintln!("filled file: {pages} pages zeroed in turn, at most {worst} beams lost to one");
    // An optimized file keeps its metadata at the end, its copies apart too.
    storage::optimize(&path, |_, _| {}).unwrap();
    let (pages, worst) = zero_every_page(&path);
    eprintln!("optimized file: {pages} pages zeroed in turn, at most {worst} beams lost to one");
    assert!(pages > 16);
}

/// A file of format 2 (header copies side by side), as an earlier build
/// wrote it: `data/format2.hdk.zst`, 300 rays of a fill of the room in a
/// 3 x 3 x 3 section. It reads, takes new rays in its own layout, survives
/// either header copy zeroed, and `optimize` turns it into format 3.
#[test]
fn a_format_2_file_is_read_written_and_optimized_into_format_3() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/format2.hdk.zst");
    let bytes = zstd::decode_all(fs::File::open(data).unwrap()).unwrap();
    assert_eq!(&bytes[8..12], &2u32.to_le_bytes(), "a format 2 file");
    let path = dir.path().join("old.hdk");
    fs::write(&path, &bytes).unwrap();
    let report = storage::check(&path, |_, _| {}).unwrap();
    assert!(report.is_clean(), "{report:?}");
    assert_eq!(report.rays_ok, 300);
    // New rays go in, the layout stays format 2.
    let mut f = HoloFile::open(&path, &writable()).unwrap();
    let key = BeamKey::new(0, 7);
    f.append(key, &pattern_rays(key, 0, 20)).unwrap();
    f.close().unwrap();
    let after = fs::read(&path).unwrap();
    assert_eq!(&after[8..12], &2u32.to_le_bytes());
    assert_eq!(storage::check(&path, |_, _| {}).unwrap().rays_ok, 320);
    // Either header copy may go: the other holds.
    for block in metadata_map(&path).iter().filter(|m| m.what.starts_with("prefix copy")) {
        let mut damaged = after.clone();
        let at = block.extent.offset as usize;
        damaged[at..at + 4096].fill(0);
        let copy = dir.path().join("damaged.hdk");
        fs::write(&copy, &damaged).unwrap();
        let r = storage::check(&copy, |_, _| {}).unwrap();
        assert_eq!(r.rays_ok, 320, "{}: {r:?}", block.what);
    }
    // Optimized, it is format 3: its header copies 64 KiB apart.
    storage::optimize(&path, |_, _| {}).unwrap();
    let new = fs::read(&path).unwrap();
    assert_eq!(&new[8..12], &3u32.to_le_bytes());
    let prefixes: Vec<u64> = metadata_map(&path)
        .iter()
        .filter(|m| m.what.starts_with("prefix copy"))
        .map(|m| m.extent.offset)
        .collect();
    assert_eq!(prefixes, vec![0, 64 << 10]);
    assert_eq!(storage::check(&path, |_, _| {}).unwrap().rays_ok, 320);
}
