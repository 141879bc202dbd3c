//! A whole file of arbitrary bytes opened, verified and salvaged: errors are
//! fine, panics are not.
#![no_main]

use holodeck_protocol::BeamKey;
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let Ok(dir) = tempfile::tempdir() else { return };
    let path = dir.path().join("fuzz.hdk");
    if std::fs::write(&path, data).is_err() {
        return;
    }
    if let Ok(mut f) = HoloFile::open(&path, &OpenOptions::read_only()) {
        let _ = f.summary();
        let _ = f.read_beam(BeamKey::new(0, 0));
    }
    let _ = storage::check(&path, |_, _| {});
    let _ = storage::repair(&path, &dir.path().join("out.hdk"));
});
