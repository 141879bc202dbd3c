//! `holodeck fill` end to end: a real process traces the built-in room into a
//! holodeck file; the test then checks every stored ray against the scene.

mod common;
use common::holodeck;

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};

#[test]
fn filled_rays_agree_with_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    // No bounces: every stored color is then exact. A ray that sees the light
    // carries its radiance; any other opaque surface is black. 600,000 rays of
    // 4 visit every one of the section's 129,438 beams at least once.
    let o = holodeck(&["fill", "builtin:room", f, "--rays", "600K", "--bounces", "0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("600,000 rays"));

    let scene = generate("room", &GenParams::default()).unwrap();
    let mut hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    assert_eq!(
        hdk.sections(),
        scene.sections.as_slice(),
        "the file takes the scene's sections"
    );
    let summary = hdk.summary();
    assert_eq!(summary.rays(), 600_000);
    assert_eq!(summary.sections[0].1, summary.sections[0].0, "every beam holds rays");
    // First runs are exact: the only free space is the empty directory and
    // root written at creation (two copies of each: one byte per beam and 20
    // per chunk of 8,192 beams, and the root), freed by the first commit, and
    // at most one gap kept between the metadata's copies.
    let beams = u64::from(section_beams(&summary));
    let chunks = beams.div_ceil(8192);
    assert!(summary.fragments as u64 <= chunks + 2, "{summary:?}");
    let root = holodeck_file::storage::format::root_len(chunks as usize);
    let created = 2 * (beams + 20 * chunks + root);
    let gap = holodeck_file::storage::format::COPY_GAP;
    assert!(
        summary.free_bytes >= created && summary.free_bytes <= created + gap,
        "{summary:?}"
    );

    let (checked, lights) = common::check_rays_against_room(&mut hdk);
    assert_eq!(checked, 600_000);
    assert!(lights > 100, "some rays see the ceiling light ({lights})");

    drop(hdk);
    // Another scene may not be filled into this file.
    let o = holodeck(&["fill", "builtin:landscape", f, "--triangles", "2000", "--rays", "10"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("another scene"), "{err}");
}

fn section_beams(s: &holodeck_file::storage::FileSummary) -> u32 {
    s.sections.iter().map(|x| x.0).sum()
}
