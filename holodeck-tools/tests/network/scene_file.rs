//! Samplers tracing a built scene file (`.hds`) out of core, with a block
//! cache far smaller than the scene: every ray they store must be the exact
//! in-core result, never one traced through a stand-in for missing data.

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_sampler::ooc::OocScene;
use holodeck_sampler::scene::gen::{generate, GenParams};

use crate::common::process::Proc;
use crate::common::{check_rays_against_room, holodeck, text};
use crate::harness::*;

#[test]
fn samplers_on_a_tenth_of_a_scene_file_store_only_exact_rays() {
    let dir = tempfile::tempdir().unwrap();
    let hds = dir.path().join("room.hds");
    let o = holodeck(&[
        "scene",
        "build",
        "builtin:room",
        "-o",
        hds.to_str().unwrap(),
        "--block-size",
        "4K",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let header = OocScene::open(&hds, None, 0).unwrap().header().clone();
    assert!(header.blocks >= 10, "{header:?}");
    // The scene file is the scene: same content hash.
    let room = generate("room", &GenParams::default()).unwrap();
    assert_eq!(header.content_hash, holodeck_sampler::scene::content_hash(&room));
    let budget = (header.decompressed_bytes / 10).to_string();
    let file = dir.path().join("room.hdk");
    let run = Proc::start(bin().args([
        "run",
        hds.to_str().unwrap(),
        file.to_str().unwrap(),
        "-n",
        "2",
        "--time",
        "10m",
        "--bounces",
        "0",
        "--scene-memory",
        &budget,
    ]));
    // Enough rays that some beams see the lamp, whichever the samplers took.
    run_stores_then_quit(&run, &file, 20_000, "samplers tracing the scene file");
    let o = run.finish();
    assert!(o.status.success(), "{}", text(&o));
    let mut hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    let rays = hdk.summary().rays();
    assert!(rays >= 20_000, "{rays}");
    // Each stored depth is where the ray really hits, each color what it sees.
    let (checked, lights) = check_rays_against_room(&mut hdk);
    assert_eq!(checked, rays);
    assert!(lights > 0);
}
