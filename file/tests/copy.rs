//! `copy`: rays merged beam for beam into equal sections, and resampled into
//! other sections with their hits kept to within the new grid's precision.

use std::collections::HashMap;
use std::path::Path;

use glam::DVec3;
use holodeck_file::settings::Settings;
use holodeck_file::storage::{self, HoloFile, OpenOptions};
use holodeck_file::testing::{all_keys, pattern_rays, two_sections};
use holodeck_protocol::{BeamKey, Hit, RayRecord, Section, SectionKind};
use rand::{Rng, SeedableRng};

fn contents(path: &Path) -> (Settings, HashMap<BeamKey, Vec<RayRecord>>) {
    let mut f = HoloFile::open(path, &OpenOptions::read_only()).unwrap();
    let keys = all_keys(&f);
    let mut rays = HashMap::new();
    f.read_beams(&keys, |k, r| {
        if !r.is_empty() {
            rays.insert(k, r.to_vec());
        }
    })
    .unwrap();
    (f.settings().clone(), rays)
}

fn fill(path: &Path, settings: &Settings, from: u64, step: usize) -> HashMap<BeamKey, Vec<RayRecord>> {
    HoloFile::create(path, settings).unwrap();
    let mut f = HoloFile::open(path, &OpenOptions::default()).unwrap();
    let mut want = HashMap::new();
    for (s, section) in settings.sections.iter().enumerate() {
        for beam in (0..section.beam_count()).step_by(step) {
            let key = BeamKey::new(s as u32, beam);
            let rays = pattern_rays(key, from, 1 + u64::from(beam % 3));
            f.append(key, &rays).unwrap();
            want.insert(key, rays);
        }
    }
    f.close().unwrap();
    want
}

#[test]
fn equal_sections_merge_beam_for_beam_and_a_missing_destination_is_a_copy() {
    let dir = tempfile::tempdir().unwrap();
    let settings = two_sections([5, 4, 3], [3, 3, 3], 1 << 20);
    let (a, b, c) = (
        dir.path().join("a.hdk"),
        dir.path().join("b.hdk"),
        dir.path().join("c.hdk"),
    );
    let from_a = fill(&a, &settings, 100, 7);
    let from_b = fill(&b, &settings, 0, 11);
    let r = storage::copy(&a, &b, |_, _| {}).unwrap();
    let n: usize = from_a.values().map(Vec::len).sum();
    assert_eq!((r.created, r.merged_sections, r.resampled_sections), (false, 2, 0));
    assert_eq!((r.rays_read, r.rays_written, r.rays_dropped), (n as u64, n as u64, 0));
    let (_, got) = contents(&b);
    for key in from_a.keys().chain(from_b.keys()) {
        let mut want = from_b.get(key).cloned().unwrap_or_default();
        want.extend(from_a.get(key).cloned().unwrap_or_default());
        assert_eq!(got[key], want, "{key:?}");
    }
    let r = storage::copy(&a, &c, |_, _| {}).unwrap();
    assert!(r.created);
    assert_eq!(contents(&c), contents(&a));
    assert!(storage::copy(&a, &a, |_, _| {}).is_err());
}

/// Rays of a room section whose lines cross it and hit the walls of a box
/// around it, as a sampler would store them.
fn room_rays(path: &Path, room: &Section) -> Vec<(BeamKey, RayRecord)> {
    let settings = Settings {
        sections: vec![room.clone()],
        ..Settings::default()
    };
    HoloFile::create(path, &settings).unwrap();
    let mut f = HoloFile::open(path, &OpenOptions::default()).unwrap();
    let (lo, hi) = (DVec3::new(-5.0, -5.0, -5.0), DVec3::new(9.0, 8.0, 7.5));
    let mut rng = rand::rngs::StdRng::seed_from_u64(5);
    let mut stored = Vec::new();
    for k in 0..3000 {
        let p = DVec3::new(
            rng.gen_range(0.1..3.9),
            rng.gen_range(0.1..2.9),
            rng.gen_range(0.1..2.4),
        );
        let d = DVec3::new(
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
            rng.gen_range(-1.0..1.0),
        )
        .normalize();
        // Where the line leaves the box: the nearest of the far planes.
        let t = (0..3)
            .map(|a| {
                if d[a] > 0.0 {
                    (hi[a] - p[a]) / d[a]
                } else {
                    (lo[a] - p[a]) / d[a]
                }
            })
            .fold(f64::INFINITY, f64::min);
        let hit = (k % 10 != 0).then_some(p + d * t);
        let (beam, rec) = room.encode_ray(p, d, [0.1 * (k % 7) as f32, 0.5, 2.0], hit).unwrap();
        let key = BeamKey::new(0, beam);
        f.append(key, &[rec]).unwrap();
        stored.push((key, rec));
    }
    f.close().unwrap();
    stored
}

fn section(origin: [f64; 3], size: [f64; 3], grid: [u16; 3]) -> Section {
    let axes = [[size[0], 0.0, 0.0], [0.0, size[1], 0.0], [0.0, 0.0, size[2]]];
    Section::new(origin, axes, grid, SectionKind::Interior).unwrap()
}

#[test]
fn resampled_rays_keep_their_hits_to_within_the_new_grids_precision() {
    let dir = tempfile::tempdir().unwrap();
    let room = section([0.0; 3], [4.0, 3.0, 2.5], [8, 6, 5]);
    let src = dir.path().join("room.hdk");
    let stored = room_rays(&src, &room);
    // The same box on a finer grid, a section inside the room, one around it.
    let fine = section([0.0; 3], [4.0, 3.0, 2.5], [20, 15, 12]);
    let inner = section([1.0, 1.0, 0.5], [2.0, 1.0, 1.5], [6, 3, 4]);
    let around = section([-1.0; 3], [6.0, 5.0, 4.5], [6, 5, 4]);
    let dest = dir.path().join("resampled.hdk");
    HoloFile::create(
        &dest,
        &Settings {
            sections: vec![fine.clone(), inner.clone(), around],
            // Sections that may hold geometry: a line counts only from where
            // its ray began (an unobstructed destination is tested below).
            obstructions: true,
            ..Settings::default()
        },
    )
    .unwrap();
    let r = storage::copy(&src, &dest, |_, _| {}).unwrap();
    assert_eq!((r.merged_sections, r.resampled_sections), (0, 1));
    // Every ray is valid in the finer grid; in the inner section when its line
    // crosses it; never in the section around the room, which its lines enter
    // before the room, where nothing was traced and geometry may lie.
    let crossing = stored
        .iter()
        .filter(|(k, rec)| {
            let d = room.decode_record(k.beam, rec).unwrap();
            inner.locate(d.ray.origin, d.ray.direction).is_some()
        })
        .count();
    assert!(crossing > 300 && crossing < 2900, "{crossing}");
    assert_eq!(r.rays_read, 3000);
    assert_eq!(r.rays_written, 3000 + crossing as u64);
    assert_eq!(r.rays_dropped, 0);
    let (_, got) = contents(&dest);
    assert!(got.keys().all(|k| k.section < 2), "nothing lands in the outer section");
    let placed: usize = got.iter().filter(|(k, _)| k.section == 0).map(|(_, r)| r.len()).sum();
    assert_eq!(placed, 3000);
    // Each source ray's hit is found again in the finer section.
    let sub = 4.0 / (20.0 * 256.0);
    let decoded: Vec<_> = got
        .iter()
        .filter(|(k, _)| k.section == 0)
        .flat_map(|(k, rs)| {
            rs.iter()
                .map(|r| fine.decode_record(k.beam, r).unwrap())
                .collect::<Vec<_>>()
        })
        .collect();
    for (key, rec) in &stored {
        let want = room.decode_record(key.beam, rec).unwrap();
        let found = decoded.iter().any(|d| {
            if d.color != want.color || d.ray.direction.dot(want.ray.direction) < 0.99 {
                return false;
            }
            match (d.hit, want.hit) {
                (Hit::Infinite, Hit::Infinite) => {
                    d.ray.direction.angle_between(want.ray.direction) < 4.0 * sub / d.ray.length
                }
                (Hit::Point(a), Hit::Point(b)) => {
                    let far = (b - want.ray.origin).length();
                    let tol = 2.0 * sub * (1.0 + 2.0 * far / d.ray.length) + 5e-4 * far.max(fine.diagonal());
                    (a - b).length() <= tol
                }
                _ => false,
            }
        });
        assert!(found, "{key:?} {want:?} has no match in the finer grid");
    }
}

#[test]
fn a_copy_stopped_by_diskspace_commits_what_it_stored_and_a_larger_limit_adds_the_rest() {
    let dir = tempfile::tempdir().unwrap();
    let settings = two_sections([12, 10, 8], [6, 6, 6], 1 << 20);
    let (a, b) = (dir.path().join("a.hdk"), dir.path().join("b.hdk"));
    let from_a = fill(&a, &settings, 100, 1);
    let total: u64 = from_a.values().map(|r| r.len() as u64).sum();
    HoloFile::create(&b, &settings).unwrap();
    let empty = std::fs::metadata(&b).unwrap().len();
    let limit = empty + 200_000;
    let options = storage::CopyOptions { diskspace: Some(limit) };
    let r = storage::copy_with(&a, &b, &options, |_, _| {}).unwrap();
    let why = r.stopped.clone().expect("the limit stops the copy");
    assert!(why.contains("DISKSPACE limit of"), "{why}");
    assert!(r.rays_written > 0 && r.rays_written < total, "{r:?} of {total}");
    // What it says it stored is committed, and the file kept to the limit.
    assert!(std::fs::metadata(&b).unwrap().len() <= limit);
    let stored: u64 = contents(&b).1.values().map(|r| r.len() as u64).sum();
    assert_eq!(stored, r.rays_written);
    assert!(storage::check(&b, |_, _| {}).unwrap().is_clean());
    // No limit: everything comes in (beams copied before get their rays twice).
    let options = storage::CopyOptions { diskspace: Some(0) };
    let again = storage::copy_with(&a, &b, &options, |_, _| {}).unwrap();
    assert_eq!((again.stopped, again.rays_written), (None, total));
    let stored: u64 = contents(&b).1.values().map(|r| r.len() as u64).sum();
    assert_eq!(stored, r.rays_written + total);
}

#[test]
fn rays_crossing_a_shared_wall_go_into_the_unobstructed_neighbour_as_rhcopy_keeps_them() {
    let dir = tempfile::tempdir().unwrap();
    // Two rooms side by side, sharing the wall x = 2.
    let a = section([0.0, 0.0, 0.0], [2.0, 3.0, 2.5], [4, 6, 5]);
    let b = section([2.0, 0.0, 0.0], [2.0, 3.0, 2.5], [4, 6, 5]);
    let settings = |s: &Section, obstructions: bool| Settings {
        sections: vec![s.clone()],
        obstructions,
        ..Settings::default()
    };
    // Rays of `a` leaving through x = 0 after starting on the shared wall
    // (traced toward -x): their lines crossed `b` before they began.
    let src = dir.path().join("a.hdk");
    HoloFile::create(&src, &settings(&a, false)).unwrap();
    let mut f = HoloFile::open(&src, &OpenOptions::default()).unwrap();
    let mut n = 0u64;
    for i in 0..12 {
        for j in 0..10 {
            let (y, z) = (0.2 + 0.2 * f64::from(i), 0.2 + 0.2 * f64::from(j));
            let dir = DVec3::new(-1.0, 0.03 * f64::from(i % 3), -0.02 * f64::from(j % 4)).normalize();
            let origin = DVec3::new(2.0, y, z);
            let hit = origin + dir * 5.0;
            let (beam, rec) = a.encode_ray(origin, dir, [0.5, 0.25, 1.0], Some(hit)).unwrap();
            f.append(BeamKey::new(0, beam), &[rec]).unwrap();
            n += 1;
        }
    }
    f.close().unwrap();
    for (obstructions, kept) in [(false, n), (true, 0)] {
        let dest = dir.path().join(format!("b-{obstructions}.hdk"));
        HoloFile::create(&dest, &settings(&b, obstructions)).unwrap();
        let r = storage::copy(&src, &dest, |_, _| {}).unwrap();
        assert_eq!((r.rays_read, r.rays_written), (n, kept), "obstructions {obstructions}");
        // Each kept ray's hit is where it was: its depth now counts from b's far wall.
        let (_, rays) = contents(&dest);
        for (key, recs) in &rays {
            for rec in recs {
                let d = b.decode_record(key.beam, rec).unwrap();
                let Hit::Point(p) = d.hit else { panic!("a finite hit") };
                assert!(
                    p.x < 0.0 && (p.x - (2.0 - 5.0 * d.ray.direction.x.abs())).abs() < 0.3,
                    "{p}"
                );
            }
        }
    }
}
