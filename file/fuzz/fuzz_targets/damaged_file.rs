//! A real holodeck file damaged the way disks and copies damage files: bits
//! flipped anywhere (mostly near the end, where the newest metadata lies),
//! bytes overwritten, the file cut short. Whatever the damage, opening,
//! checking, salvaging and writing with consent must never panic, never
//! deliver a ray that was not written, never pass a file that lost rays as
//! clean, and leave a file that checks clean once written with consent.
#![no_main]

use std::collections::HashMap;
use std::sync::OnceLock;

use holodeck_protocol::BeamKey;
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use holodeck_file::testing::{pattern_rays, two_sections};
use libfuzzer_sys::fuzz_target;

/// The undamaged file's bytes and what it holds.
fn original() -> &'static (Vec<u8>, HashMap<BeamKey, u64>) {
    static FILE: OnceLock<(Vec<u8>, HashMap<BeamKey, u64>)> = OnceLock::new();
    FILE.get_or_init(|| {
        let dir = tempfile::tempdir().expect("temporary directory");
        let path = dir.path().join("seed.hdk");
        HoloFile::create(&path, &two_sections([3, 2, 2], [1, 1, 1], 1 << 20)).expect("create");
        let options = OpenOptions {
            flush_interval: None,
            ..OpenOptions::default()
        };
        let mut f = HoloFile::open(&path, &options).expect("open");
        let mut expected = HashMap::new();
        for round in 0..3u64 {
            for i in 0..40u32 {
                let k = BeamKey::new(i % 2, (i * 37) % if i % 2 == 0 { 500 } else { 30 });
                let have = expected.get(&k).copied().unwrap_or(0);
                f.append(k, &pattern_rays(k, have, 1 + round)).expect("append");
                expected.insert(k, have + 1 + round);
            }
            f.flush().expect("flush");
        }
        f.close().expect("close");
        (std::fs::read(&path).expect("read"), expected)
    })
}

fuzz_target!(|data: &[u8]| {
    let (good, expected) = original();
    let total: u64 = expected.values().sum();
    let mut bytes = good.clone();
    // Each 4-byte group of the input is one mutation.
    for m in data.chunks_exact(4) {
        let back = usize::from(u16::from_le_bytes([m[1], m[2]]));
        let at = bytes.len().saturating_sub(1 + back % bytes.len().max(1));
        match m[0] % 4 {
            0 | 1 => bytes[at] ^= 1 << (m[3] % 8),
            2 => bytes[at] = m[3],
            _ => bytes.truncate(at),
        }
        if bytes.is_empty() {
            break;
        }
    }
    let Ok(dir) = tempfile::tempdir() else { return };
    let path = dir.path().join("damaged.hdk");
    if std::fs::write(&path, &bytes).is_err() {
        return;
    }
    if let Ok(mut f) = HoloFile::open(&path, &OpenOptions::read_only()) {
        let keys: Vec<BeamKey> = expected.keys().copied().collect();
        let _ = f.read_beams(&keys, |k, got| {
            assert!(got.len() as u64 <= expected[&k]);
            assert_eq!(got, pattern_rays(k, 0, got.len() as u64).as_slice());
        });
    }
    if let Ok(r) = storage::check(&path, |_, _| {}) {
        if r.is_clean() {
            assert_eq!(r.rays_ok, total, "a file that lost rays checked clean");
        }
    }
    let _ = storage::repair(&path, &dir.path().join("salvaged.hdk"));
    let consent = OpenOptions {
        accept_loss: true,
        flush_interval: None,
        ..OpenOptions::default()
    };
    if let Ok(f) = HoloFile::open(&path, &consent) {
        if f.close().is_ok() {
            let r = storage::check(&path, |_, _| {}).expect("a file just written checks");
            assert!(r.damage.is_none(), "written with consent, yet damaged: {r:?}");
            assert!(r.repaired.is_empty(), "written, yet copies are still damaged: {r:?}");
        }
    }
});
