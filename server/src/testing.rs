//! Test patterns for holodeck files: rays whose content is fixed by where they
//! belong, so any misplaced, duplicated or invented record is detected. Used by
//! the engine's tests, the crash tests and the benchmarks; never by the engine.

use holodeck_protocol::{BeamKey, DepthCode, RayRecord, Rgbe, Section, SectionKind};

use crate::settings::Settings;

/// Ray number `j` of a beam: its bytes are a hash of (section, beam, j).
pub fn pattern_ray(key: BeamKey, j: u64) -> RayRecord {
    let h = (u64::from(key.section) << 40 ^ u64::from(key.beam) << 20 ^ j).wrapping_mul(0x9E37_79B9_7F4A_7C15);
    let b = h.to_le_bytes();
    RayRecord::new(
        [b[0], b[1]],
        [b[2], b[3]],
        Rgbe([b[4], b[5], b[6], 130]),
        DepthCode(u16::from_le_bytes([b[7], b[1]])),
    )
}

/// Rays `from..from + n` of a beam's pattern.
pub fn pattern_rays(key: BeamKey, from: u64, n: u64) -> Vec<RayRecord> {
    (from..from + n).map(|j| pattern_ray(key, j)).collect()
}

/// Two small sections: an interior room (`room_grid` cells) and an exterior
/// unit box beside it (`box_grid`), with the given cache budget.
pub fn two_sections(room_grid: [u16; 3], box_grid: [u16; 3], cache_bytes: u64) -> Settings {
    let room = Section::new(
        [0.0; 3],
        [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.5]],
        room_grid,
        SectionKind::Interior,
    );
    let object = Section::new(
        [10.0, 0.0, 0.0],
        [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        box_grid,
        SectionKind::Exterior,
    );
    let sections = [room, object].into_iter().filter_map(Result::ok).collect();
    Settings {
        sections,
        cache_bytes,
        ..Settings::default()
    }
}

/// Every beam of every section, in order.
pub fn all_keys(f: &crate::HoloFile) -> Vec<BeamKey> {
    let mut keys = Vec::new();
    for (s, sec) in f.sections().iter().enumerate() {
        keys.extend((0..sec.beam_count()).map(|b| BeamKey::new(s as u32, b)));
    }
    keys
}

/// Asserts (panics otherwise: for tests) that every beam of the file at
/// `path` holds exactly `expected[key]` pattern rays, in order, and nothing
/// reads back corrupt.
pub fn assert_pattern_contents(path: &std::path::Path, expected: &std::collections::HashMap<BeamKey, u64>) {
    let mut f = crate::HoloFile::open(path, &crate::OpenOptions::read_only()).expect("open for the check");
    let keys = all_keys(&f);
    let mut seen = 0;
    let report = f
        .read_beams(&keys, |k, got| {
            let n = expected.get(&k).copied().unwrap_or(0);
            assert_eq!(got.len() as u64, n, "beam {k:?}");
            assert_eq!(got, pattern_rays(k, 0, n).as_slice(), "contents of {k:?}");
            seen += 1;
        })
        .expect("read every beam");
    assert!(report.corrupt.is_empty());
    assert_eq!(seen, keys.len());
}
