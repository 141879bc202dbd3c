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

/// One copy of a piece of metadata in a file, for tests that damage files.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct MetaBlock {
    /// What it is ("prefix copy 1", "root copy 2", ...).
    pub what: String,
    /// Where it lies.
    pub extent: crate::storage::format::Extent,
    /// For a directory block: (section, first beam, beams) it describes.
    pub beams: Option<(u32, u32, u32)>,
}

/// Every copy of every piece of metadata of the newest commit of the
/// (undamaged) file at `path`: both header copies' prefix, slots and settings
/// text, and both copies of the root and of every directory block. Panics on
/// a damaged file: for tests.
pub fn metadata_map(path: &std::path::Path) -> Vec<MetaBlock> {
    use crate::storage::format::{self, Extent};
    let bytes = std::fs::read(path).expect("read the file");
    let prefix = format::decode_prefix(&bytes, 0).expect("prefix");
    let text_len = prefix.text_len;
    let text_at = format::text_offset(prefix, 0) as usize;
    let text = format::decode_text(&bytes[text_at..text_at + text_len as usize + 4], text_at as u64).expect("text");
    let settings = Settings::from_text(&text).expect("settings");
    let beams: Vec<u32> = settings.sections.iter().map(|s| s.beam_count()).collect();
    let mut out = Vec::new();
    let mut push = |what: String, offset: u64, len: u64, beams: Option<(u32, u32, u32)>| {
        out.push(MetaBlock {
            what,
            extent: Extent { offset, len },
            beams,
        })
    };
    let mut newest: Option<format::Slot> = None;
    for copy in 0..2 {
        let base = format::header_stride(prefix) * copy as u64;
        push(format!("prefix copy {}", copy + 1), base, format::PREFIX_LEN, None);
        for side in 0..2 {
            let at = format::slot_offset(prefix, copy, side);
            push(format!("slot {side} copy {}", copy + 1), at, format::SLOT_LEN, None);
            let slot = format::decode_slot(&bytes[at as usize..at as usize + 64], at).expect("slot");
            if let Some(s) = slot {
                if newest.is_none_or(|n| s.generation > n.generation) {
                    newest = Some(s);
                }
            }
        }
        push(
            format!("settings text copy {}", copy + 1),
            format::text_offset(prefix, copy),
            u64::from(text_len) + 4,
            None,
        );
    }
    let slot = newest.expect("a commit");
    let root = slot.root_copies()[0];
    let chunks = format::decode_root(
        &bytes[root.offset as usize..root.end() as usize],
        root.offset,
        slot.generation,
        &beams,
    )
    .expect("root");
    for (copy, e) in slot.root_copies().iter().enumerate() {
        push(format!("root copy {}", copy + 1), e.offset, e.len, None);
    }
    for c in &chunks {
        for (copy, e) in c.extents().iter().enumerate() {
            push(
                format!(
                    "directory of section {} beams {}.. copy {}",
                    c.section,
                    c.first,
                    copy + 1
                ),
                e.offset,
                e.len,
                Some((c.section, c.first, c.beams)),
            );
        }
    }
    out
}

/// Zeroes every 4 KiB page of the (undamaged) file at `path` in turn: each
/// time the file must open at its newest commit with no metadata damage and
/// lose at most the beams whose records lay in that page, every other ray
/// readable. Returns the pages tried and the most beams one page cost.
/// Panics on the first page that costs more: for tests.
pub fn zero_every_page(path: &std::path::Path) -> (usize, usize) {
    use crate::storage;
    const PAGE: usize = 4096;
    let good = std::fs::read(path).expect("read the file");
    let generation = storage::check(path, |_, _| {}).expect("check").generation;
    // Where every beam's records lie, and how many it holds.
    let f = crate::HoloFile::open(path, &crate::OpenOptions::read_only()).expect("open");
    let mut runs: Vec<(BeamKey, u64, u64, u64)> = Vec::new();
    for (s, section) in f.sections().iter().enumerate() {
        let dir = f.directory(s as u32).expect("a directory");
        for b in 0..section.beam_count() {
            let e = dir[b as usize];
            if e.count > 0 {
                let start = e.offset;
                runs.push((
                    BeamKey::new(s as u32, b),
                    start,
                    start + u64::from(e.count) * 10,
                    u64::from(e.count),
                ));
            }
        }
    }
    drop(f);
    let total: u64 = runs.iter().map(|r| r.3).sum();
    let damaged = path.with_extension("zeroed.hdk");
    let (mut pages, mut worst) = (0, 0);
    for start in (0..good.len()).step_by(PAGE) {
        let end = (start + PAGE).min(good.len());
        let mut bytes = good.clone();
        bytes[start..end].fill(0);
        std::fs::write(&damaged, &bytes).expect("write the damaged copy");
        let report = storage::check(&damaged, |_, _| {})
            .unwrap_or_else(|e| panic!("page at {start}: the file no longer opens: {e}"));
        assert_eq!(report.generation, generation, "page at {start}: {report:?}");
        assert!(report.damage.is_none(), "page at {start}: {report:?}");
        let mut lost = 0;
        for k in &report.corrupt {
            let run = runs.iter().find(|r| r.0 == *k).expect("a beam of the file");
            assert!(
                run.1 < end as u64 && run.2 > start as u64,
                "page at {start}: beam {k:?} lost, but none of its records lay there"
            );
            lost += run.3;
        }
        assert_eq!(report.rays_ok, total - lost, "page at {start}");
        pages += 1;
        worst = worst.max(report.corrupt.len());
    }
    let _ = std::fs::remove_file(&damaged);
    (pages, worst)
}
