//! Radiance holodecks: files built here byte by byte as rholo lays them out
//! (both byte orders, all offset sizes, two sections, empty beams, rays
//! anywhere in the file) import with every ray in its beam; export, import
//! and export again gives the same bytes; cut and damaged files are refused
//! with messages naming what is wrong.

use std::collections::HashMap;
use std::path::Path;

use holodeck_file::radiance::{self, ImportOptions, Layout, RadianceFile};
use holodeck_file::settings::Settings;
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use holodeck_file::testing::{pattern_rays, two_sections};
use holodeck_protocol::{BeamKey, CellPair, DepthCoding, RayRecord, Rgbe, Section, SectionKind, Wall, WallCell};

/// Radiance's beams of a grid in its own order, enumerated as holo.c
/// documents it: lower entry wall first, by (walls, entry cell, exit cell),
/// a cell numbered u + grid_u * v; then the same pairs reversed.
fn radiance_order(grid: [u16; 3]) -> Vec<CellPair> {
    let axes = |w: u8| [(usize::from(w / 2) + 1) % 3, (usize::from(w / 2) + 2) % 3];
    let cells = |w: u8| {
        let [u, v] = axes(w);
        let (gu, gv) = (grid[u], grid[v]);
        (0..gu * gv)
            .map(|c| WallCell {
                wall: Wall(w),
                cell: [c % gu, c / gu],
            })
            .collect::<Vec<_>>()
    };
    let mut forward = Vec::new();
    for w0 in 0..6u8 {
        for w1 in w0 + 1..6 {
            for a in cells(w0) {
                for b in cells(w1) {
                    forward.push(CellPair { entry: a, exit: b });
                }
            }
        }
    }
    let reverse: Vec<CellPair> = forward
        .iter()
        .map(|p| CellPair {
            entry: p.exit,
            exit: p.entry,
        })
        .collect();
    forward.extend(reverse);
    forward
}

struct HandSection {
    origin: [f64; 3],
    axes: [[f64; 3]; 3],
    grid: [u16; 3],
    /// (Radiance beam number, rays as stored: 10 bytes each, depth in the file's order).
    beams: Vec<(usize, Vec<[u8; 10]>)>,
}

/// A Radiance holodeck as rholo creates it: all section records back to back,
/// then the beams, here in reverse order. Written with plain integer
/// conversions, not the exporter's code.
fn hand_file(big: bool, offset_bytes: usize, entry_bytes: usize, sections: &[HandSection]) -> Vec<u8> {
    let u16b = |v: u16| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let u32b = |v: u32| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let u64b = |v: u64| if big { v.to_be_bytes() } else { v.to_le_bytes() };
    let off = |v: u64| -> Vec<u8> {
        if offset_bytes == 4 {
            u32b(v as u32).to_vec()
        } else {
            u64b(v).to_vec()
        }
    };
    let mut text = String::from(
        "#?RADIANCE\nSOFTWARE= RADIANCE 5.4a hand\nCACHE= 20\nGRID= 0.5\nOBSTRUCTIONS= True\nOCTREE= hand.oct\n",
    );
    for s in sections {
        let mut w: Vec<String> = s
            .origin
            .iter()
            .chain(s.axes.iter().flatten())
            .map(|v| v.to_string())
            .collect();
        w.extend(s.grid.iter().map(|g| g.to_string()));
        text += &format!("section= {}\n", w.join(" "));
    }
    text += &format!("VDISTANCE= F\nBigEndian={}\nFORMAT=Holodeck\n\n", u8::from(big));
    let mut out = text.into_bytes();
    out.extend_from_slice(&u32b(324 + entry_bytes as u32));
    let beams_of = |s: &HandSection| radiance_order(s.grid).len();
    let record = |n: usize| offset_bytes + 104 + n * entry_bytes;
    let records_end = out.len() + sections.iter().map(|s| record(beams_of(s))).sum::<usize>();
    // Ray positions: beams written after every record, last section's last beam first.
    let mut positions = HashMap::new();
    let mut at = records_end;
    for (si, s) in sections.iter().enumerate().rev() {
        for (number, rays) in s.beams.iter().rev() {
            positions.insert((si, *number), at);
            at += rays.len() * 10;
        }
    }
    for (si, s) in sections.iter().enumerate() {
        let start = out.len();
        let next = if si + 1 < sections.len() {
            start + record(beams_of(s))
        } else {
            0
        };
        out.extend(off(next as u64));
        for v in s.origin.iter().chain(s.axes.iter().flatten()) {
            out.extend_from_slice(&u64b(v.to_bits()));
        }
        for g in s.grid {
            out.extend_from_slice(&u16b(g));
        }
        out.extend_from_slice(&[0, 0]);
        let rays: HashMap<usize, &Vec<[u8; 10]>> = s.beams.iter().map(|(n, r)| (*n, r)).collect();
        for number in 1..=beams_of(s) {
            let (count, fo) = match rays.get(&number) {
                Some(r) => (r.len(), positions[&(si, number)]),
                // rholo's mark of a directory being rewritten: no rays, position -1.
                None if number == 2 => (0, u64::MAX as usize),
                None => (0, 0),
            };
            let mut e = u32b(count as u32).to_vec();
            e.resize(entry_bytes - offset_bytes, 0);
            e.extend(off(fo as u64));
            out.extend(e);
        }
    }
    assert_eq!(out.len(), records_end);
    for (si, s) in sections.iter().enumerate().rev() {
        for (number, rays) in s.beams.iter().rev() {
            assert_eq!(out.len(), positions[&(si, *number)]);
            rays.iter().for_each(|r| out.extend_from_slice(r));
        }
    }
    out
}

fn ray_bytes(seed: usize) -> [u8; 10] {
    let mut r = [0u8; 10];
    for (k, b) in r.iter_mut().enumerate() {
        *b = (seed * 31 + k * 7 + (seed >> 3)) as u8;
    }
    r
}

fn hand_sections() -> Vec<HandSection> {
    let room_beams = [1usize, 5, 193, 3650, 7298];
    let room = HandSection {
        origin: [0.0; 3],
        axes: [[5.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 3.0]],
        grid: [5, 4, 3],
        beams: room_beams
            .iter()
            .enumerate()
            .map(|(k, &n)| (n, (0..k * 3 + 1).map(|j| ray_bytes(n * 100 + j)).collect()))
            .collect(),
    };
    let object = HandSection {
        origin: [10.0, 0.5, 0.0],
        axes: [[1.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 2.0]],
        grid: [2, 3, 1],
        // Beam 7 is listed with no rays: an empty beam.
        beams: vec![
            (3, vec![ray_bytes(1), ray_bytes(2)]),
            (7, vec![]),
            (386, vec![ray_bytes(3)]),
        ],
    };
    vec![room, object]
}

fn imported(path: &Path) -> (Settings, HashMap<BeamKey, Vec<RayRecord>>) {
    let mut f = HoloFile::open(path, &OpenOptions::read_only()).unwrap();
    let mut rays = HashMap::new();
    let keys = holodeck_file::testing::all_keys(&f);
    f.read_beams(&keys, |k, r| {
        if !r.is_empty() {
            rays.insert(k, r.to_vec());
        }
    })
    .unwrap();
    (f.settings().clone(), rays)
}

#[test]
fn hand_built_files_of_every_layout_import_ray_for_ray() {
    let dir = tempfile::tempdir().unwrap();
    let sections = hand_sections();
    for (big, offset_bytes, entry_bytes) in [
        (false, 8, 16),
        (true, 8, 16),
        (false, 8, 12),
        (true, 4, 8),
        (false, 4, 8),
    ] {
        let bytes = hand_file(big, offset_bytes, entry_bytes, &sections);
        let name = format!("hand-{big}-{entry_bytes}");
        let src = dir.path().join(format!("{name}.rad.hdk"));
        std::fs::write(&src, &bytes).unwrap();
        let dest = dir.path().join(format!("{name}.hdk"));
        let report = radiance::import(&src, &dest, &ImportOptions::default(), |_, _| {}).unwrap();
        assert_eq!(report.layout.offset_bytes as usize, offset_bytes);
        assert_eq!(
            (report.sections, report.beams, report.rays),
            (2, 7, 1 + 4 + 7 + 10 + 13 + 2 + 1)
        );
        assert_eq!(report.unused, ["SOFTWARE= RADIANCE 5.4a hand", "OCTREE= hand.oct"]);
        let (settings, rays) = imported(&dest);
        assert_eq!(settings.grid, Some(0.5));
        assert!(settings.obstructions && !settings.vdistance);
        assert_eq!(settings.cache_bytes, 20 << 20);
        let mut expected = 0;
        for (si, (hand, section)) in sections.iter().zip(&settings.sections).enumerate() {
            assert_eq!(section.grid(), hand.grid);
            assert_eq!(section.origin().to_array(), hand.origin);
            assert_eq!(section.depth_coding(), DepthCoding::Radiance);
            assert_eq!(section.kind(), SectionKind::Interior);
            let order = radiance_order(hand.grid);
            for (number, raw) in &hand.beams {
                let beam = section.beam_index(order[number - 1]).unwrap();
                let got = rays.get(&BeamKey::new(si as u32, beam)).cloned().unwrap_or_default();
                let want: Vec<RayRecord> = raw
                    .iter()
                    .map(|r| RayRecord {
                        entry: [r[0], r[1]],
                        exit: [r[2], r[3]],
                        color: Rgbe([r[4], r[5], r[6], r[7]]),
                        depth: if big { [r[9], r[8]] } else { [r[8], r[9]] },
                    })
                    .collect();
                assert_eq!(got, want, "{name}: section {si} Radiance beam {number} (ours {beam})");
                expected += usize::from(!want.is_empty());
            }
        }
        assert_eq!(rays.len(), expected, "{name}: no ray may land anywhere else");
        let check = storage::check(&dest, |_, _| {}).unwrap();
        assert!(check.is_clean(), "{name}: {check:?}");
    }
}

fn filled_holodeck(path: &Path) -> HashMap<BeamKey, Vec<RayRecord>> {
    let mut settings = two_sections([6, 5, 4], [3, 3, 3], 1 << 20);
    settings.scene = Some("blake3:00ff".into());
    settings.vdistance = true;
    HoloFile::create(path, &settings).unwrap();
    let mut f = HoloFile::open(path, &OpenOptions::default()).unwrap();
    let mut want = HashMap::new();
    for (s, section) in settings.sections.iter().enumerate() {
        for beam in (0..section.beam_count()).step_by(37 + s) {
            let key = BeamKey::new(s as u32, beam);
            let mut rays = pattern_rays(key, 0, u64::from(beam % 5));
            // Escaped rays, zero depth and the largest finite code too.
            for (r, code) in rays.iter_mut().zip([u16::MAX, 0, u16::MAX - 1]) {
                r.depth = code.to_le_bytes();
            }
            f.append(key, &rays).unwrap();
            if !rays.is_empty() {
                want.insert(key, rays);
            }
        }
    }
    f.close().unwrap();
    want
}

#[test]
fn export_import_export_gives_the_same_bytes_and_every_ray_back() {
    let dir = tempfile::tempdir().unwrap();
    let ours = dir.path().join("ours.hdk");
    let want = filled_holodeck(&ours);
    let a = dir.path().join("a.rad.hdk");
    let r = radiance::export(&ours, &a, Layout::LP64, |_, _| {}).unwrap();
    let n: usize = want.values().map(Vec::len).sum();
    assert_eq!((r.rays, r.converted), (n as u64, n as u64));
    let b = dir.path().join("b.hdk");
    radiance::import(&a, &b, &ImportOptions::default(), |_, _| {}).unwrap();
    let (settings, got) = imported(&b);
    let (original, _) = imported(&ours);
    // Kinds and scene come back from the lines Radiance ignores.
    assert_eq!(settings.scene, original.scene);
    assert!(settings.vdistance);
    for (s, o) in settings.sections.iter().zip(&original.sections) {
        assert_eq!(s.kind(), o.kind());
        assert_eq!(s.spec().grid, o.spec().grid);
    }
    assert_eq!(got.len(), want.len());
    for (key, rays) in &want {
        let back = &got[key];
        let (s, o) = (
            &settings.sections[key.section as usize],
            &original.sections[key.section as usize],
        );
        for (g, w) in back.iter().zip(rays) {
            assert_eq!((g.entry, g.exit, g.color), (w.entry, w.exit, w.color), "{key:?}");
            match (o.decode_depth(w.depth_code()), s.decode_depth(g.depth_code())) {
                (None, None) => {}
                // Radiance's farthest distance is 1e10: beyond, a ray escaped.
                (Some(d0), None) if d0 >= 0.99e10 => {}
                (Some(d0), Some(d1)) => {
                    // Within one of Radiance's steps (a 2^-11 share of its scale, or 0.05%).
                    let step = (s.depth_scale() / 2048.0).max(d0 * 5e-4);
                    assert!((d0 - d1).abs() <= step, "{key:?}: {d0} -> {d1}");
                }
                other => panic!("{key:?}: depth {other:?}"),
            }
        }
    }
    let c = dir.path().join("c.rad.hdk");
    let r2 = radiance::export(&b, &c, Layout::LP64, |_, _| {}).unwrap();
    assert_eq!(r2.converted, 0);
    assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&c).unwrap());
    // Every other layout imports to the same rays.
    for layout in Layout::ALL {
        let other = dir
            .path()
            .join(format!("{}-{}.rad.hdk", layout.order.name(), layout.entry_bytes));
        radiance::export(&b, &other, layout, |_, _| {}).unwrap();
        let again = dir
            .path()
            .join(format!("{}-{}.hdk", layout.order.name(), layout.entry_bytes));
        radiance::import(&other, &again, &ImportOptions::default(), |_, _| {}).unwrap();
        assert_eq!(imported(&again).1, got, "{layout:?}");
    }
    // Neither command replaces a file.
    assert!(radiance::export(&b, &c, Layout::LP64, |_, _| {}).is_err());
    assert!(radiance::import(&a, &b, &ImportOptions::default(), |_, _| {}).is_err());
    assert_eq!(imported(&b).1, got);
}

fn parse_error(bytes: &[u8]) -> String {
    match RadianceFile::parse(bytes) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn cut_and_damaged_files_are_refused_naming_what_is_wrong() {
    let bytes = hand_file(false, 8, 16, &hand_sections());
    let whole = RadianceFile::parse(&bytes[..]).unwrap();
    assert_eq!(whole.rays(), 38);
    // Cut anywhere: the last beam's rays end the file, so every cut loses something.
    for cut in (0..bytes.len()).step_by(97).chain([bytes.len() - 1]) {
        let e = parse_error(&bytes[..cut]);
        assert!(
            e.contains("cut off") || e.contains("not a Radiance holodeck") || e.contains("magic"),
            "cut at {cut}: {e}"
        );
    }
    let header_len = whole.header.len as usize;
    let mut bad = bytes.clone();
    bad[header_len] = 0x55;
    assert!(parse_error(&bad).contains("magic number"), "{}", parse_error(&bad));
    // The first section's pointer aims back into its own record.
    let mut back = bytes.clone();
    back[header_len + 4..header_len + 12].copy_from_slice(&(header_len as u64).to_le_bytes());
    assert!(
        parse_error(&back).contains("pointer to the next section"),
        "{}",
        parse_error(&back)
    );
    // A grid of zero cells.
    let mut zero = bytes.clone();
    let grid_at = header_len + 4 + 8 + 96;
    zero[grid_at..grid_at + 2].copy_from_slice(&0i16.to_le_bytes());
    let e = parse_error(&zero);
    assert!(e.starts_with("section 0 (at byte") && e.contains("grid size 0"), "{e}");
    // A beam claiming more rays than the file holds.
    let mut many = bytes.clone();
    let entry_at = header_len + 4 + 8 + 104;
    many[entry_at..entry_at + 4].copy_from_slice(&1_000_000u32.to_le_bytes());
    let e = parse_error(&many);
    assert!(e.contains("section 0 beam 1") && e.contains("cut off"), "{e}");
    // The header's byte order contradicts the magic number.
    let text = String::from_utf8_lossy(&bytes[..header_len]).replace("BigEndian=0", "BigEndian=1");
    let mut liar = text.into_bytes();
    liar.extend_from_slice(&bytes[header_len..]);
    assert!(parse_error(&liar).contains("BigEndian=1"), "{}", parse_error(&liar));
    // A Radiance picture is not a holodeck.
    assert!(parse_error(b"#?RADIANCE\nFORMAT=32-bit_rle_rgbe\n\n-Y 1 +X 1\n").contains("FORMAT=32-bit_rle_rgbe"));
}

#[test]
fn overlapping_or_cut_beams_are_refused_and_salvaged_with_loss_accepted() {
    let bytes = hand_file(false, 8, 16, &hand_sections());
    let whole = RadianceFile::parse(&bytes[..]).unwrap();
    let header_len = whole.header.len as usize;
    let dir_at = header_len + 4 + 8 + 104;
    // Beam 1 (its one ray) pointed into beam 5's four: a flipped position.
    let (one, _) = whole.sections[0].beams[0];
    let (five, p5) = whole.sections[0].beams[4];
    assert_eq!((one, five), (1, 4));
    let mut flipped = bytes.clone();
    let at = dir_at + 8;
    flipped[at..at + 8].copy_from_slice(&(p5 + 10).to_le_bytes());
    let e = parse_error(&flipped);
    assert!(
        e.contains("overlap") && e.contains("section 0 beam 1 ") && e.contains("section 0 beam 5 "),
        "{e}"
    );
    // With loss accepted both beams of the overlap are left out (which one
    // is right cannot be told), and nothing else.
    let salvaged = RadianceFile::parse_salvaging(&flipped[..], true).unwrap();
    assert_eq!(salvaged.lost_rays, 5, "{:?}", salvaged.lost);
    assert_eq!(salvaged.lost.len(), 2, "{:?}", salvaged.lost);
    assert_eq!(salvaged.rays(), whole.rays() - 5);
    // Cut by one byte: only the beam whose rays end the file is lost.
    let cut = &bytes[..bytes.len() - 1];
    assert!(parse_error(cut).contains("cut off"));
    let salvaged = RadianceFile::parse_salvaging(cut, true).unwrap();
    assert_eq!(salvaged.lost.len(), 1, "{:?}", salvaged.lost);
    assert!(salvaged.lost[0].contains("cut off"), "{:?}", salvaged.lost);
    assert!(salvaged.lost_rays > 0);
    assert_eq!(salvaged.rays() + salvaged.lost_rays, whole.rays());
    // The import keeps every other ray exactly.
    let dir = tempfile::tempdir().unwrap();
    let (src, cut_src) = (dir.path().join("whole.rad.hdk"), dir.path().join("cut.rad.hdk"));
    std::fs::write(&src, &bytes).unwrap();
    std::fs::write(&cut_src, cut).unwrap();
    let (a, b) = (dir.path().join("whole.hdk"), dir.path().join("cut.hdk"));
    radiance::import(&src, &a, &ImportOptions::default(), |_, _| {}).unwrap();
    assert!(radiance::import(&cut_src, &b, &ImportOptions::default(), |_, _| {}).is_err());
    let options = ImportOptions {
        accept_loss: true,
        ..ImportOptions::default()
    };
    let report = radiance::import(&cut_src, &b, &options, |_, _| {}).unwrap();
    assert_eq!(report.rays, whole.rays() - report.lost_rays);
    let (all, kept) = (imported(&a).1, imported(&b).1);
    assert_eq!(kept.len(), all.len() - 1, "one beam lost");
    for (key, rays) in &kept {
        assert_eq!(&all[key], rays, "{key:?}");
    }
}

#[test]
fn an_import_keeps_radiance_depth_codes_when_new_rays_are_added() {
    let dir = tempfile::tempdir().unwrap();
    let src = dir.path().join("hand.rad.hdk");
    std::fs::write(&src, hand_file(false, 8, 16, &hand_sections())).unwrap();
    let dest = dir.path().join("hand.hdk");
    radiance::import(
        &src,
        &dest,
        &ImportOptions {
            kind: Some(SectionKind::Exterior),
            accept_loss: false,
        },
        |_, _| {},
    )
    .unwrap();
    let f = HoloFile::open(&dest, &OpenOptions::default()).unwrap();
    let s: &Section = &f.sections()[0];
    assert_eq!(s.kind(), SectionKind::Exterior);
    // Radiance's scale is the sum of the axis lengths (12 here), codes truncate.
    assert_eq!(s.depth_scale(), 12.0);
    assert_eq!(s.encode_depth(3.0).0, 512);
    let origin = glam::DVec3::new(-1.0, 2.0, 1.5);
    let (_, rec) = s
        .encode_ray(
            origin,
            glam::DVec3::X,
            [1.0, 0.5, 0.25],
            Some(glam::DVec3::new(2.5, 2.0, 1.5)),
        )
        .unwrap();
    assert_eq!(rec.depth_code().0, (2.5 * 2048.0 / 12.0) as u16);
}

/// Radiance's own writer: `data/exported.rad.hdk.zst` is this program's
/// export of a 300-ray fill of two sections (7,680 and 7,298 beams);
/// `data/rhcopy.rad.hdk.zst` is a copy of it to which Radiance's rhcopy
/// added the same file's rays (`rhcopy dest -h src`), rewriting beams
/// elsewhere in the file through Radiance's own holofile.c. rhinfo counts 600
/// and 2 samples in its sections.
#[test]
fn a_file_written_by_radiances_rhcopy_imports_with_every_ray() {
    let dir = tempfile::tempdir().unwrap();
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data");
    let unpack = |name: &str| {
        let bytes = zstd::decode_all(std::fs::File::open(data.join(format!("{name}.rad.hdk.zst"))).unwrap()).unwrap();
        let path = dir.path().join(format!("{name}.rad.hdk"));
        std::fs::write(&path, bytes).unwrap();
        let out = dir.path().join(format!("{name}.hdk"));
        radiance::import(&path, &out, &ImportOptions::default(), |_, _| {}).unwrap();
        imported(&out)
    };
    let (_, before) = unpack("exported");
    let (settings, after) = unpack("rhcopy");
    let count = |m: &HashMap<BeamKey, Vec<RayRecord>>, s: u32| -> usize {
        m.iter().filter(|(k, _)| k.section == s).map(|(_, r)| r.len()).sum()
    };
    assert_eq!((count(&before, 0), count(&before, 1)), (300, 0));
    assert_eq!((count(&after, 0), count(&after, 1)), (600, 2));
    assert_eq!(settings.sections[1].kind(), SectionKind::Exterior);
    // rhcopy appends: every beam keeps its rays first, byte for byte, and the
    // same section's rays land in the same beams again.
    for (key, rays) in &before {
        let got = &after[key];
        assert_eq!(&got[..rays.len()], &rays[..], "{key:?}");
        assert_eq!(got.len(), 2 * rays.len(), "{key:?}");
    }
}
