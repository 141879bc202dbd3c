//! What the file's settings and scene mean for networked samplers: they
//! trace as the file says (VDISTANCE), and an admin may change the scene
//! under a running server (kill, edit, adopt).

use std::path::{Path, PathBuf};

use holodeck_protocol::{BeamKey, Hit};
use holodeck_sampler::scene::hash::content_hash;
use holodeck_sampler::scene::load_scene;
use holodeck_server::settings::Settings;
use holodeck_server::{HoloFile, OpenOptions};

use crate::common::text;
use crate::harness::*;

/// The x of the mirror plane, and of the wall its reflections land on.
const MIRROR_X: f64 = 6.0;
const WALL_X: f64 = -10.0;

/// A scene file: a 2 m interior section at the origin, a large flat mirror
/// at x = 6 facing it and a large diffuse wall at x = -10 behind it, under a
/// dark sky. `wall_albedo` tells edits apart.
fn mirror_scene(dir: &Path, wall_albedo: f32) -> PathBuf {
    let quad = |x: f64| format!("v {x} -100 -100\nv {x} 100 -100\nv {x} 100 100\nv {x} -100 100\nf 1 2 3\nf 1 3 4\n");
    std::fs::write(dir.join("mirror.obj"), quad(MIRROR_X)).unwrap();
    std::fs::write(dir.join("wall.obj"), quad(WALL_X)).unwrap();
    let scene = dir.join("mirror.toml");
    std::fs::write(
        &scene,
        format!(
            r#"
[materials.mirror]
type = "mirror"
color = [0.9, 0.9, 0.9]

[materials.wall]
type = "lambertian"
albedo = [{wall_albedo}, {wall_albedo}, {wall_albedo}]
emission = [1, 1, 1]

[[geometry]]
file = "mirror.obj"
material = "mirror"

[[geometry]]
file = "wall.obj"
material = "wall"

[[section]]
origin = [0, 0, 0]
axes = [[2, 0, 0], [0, 2, 0], [0, 0, 2]]
grid = [2, 2, 2]
"#
        ),
    )
    .unwrap();
    scene
}

/// Checks the rays of a closed file that head for the mirror: each stored
/// depth is the virtual one (through the mirror, on to the wall behind)
/// when `virtual_depth`, else the distance to the mirror. Returns the rays checked.
fn check_mirror_depths(file: &Path, virtual_depth: bool) -> u64 {
    let mut hdk = HoloFile::open(file, &OpenOptions::read_only()).unwrap();
    let section = hdk.sections()[0].clone();
    let keys: Vec<BeamKey> = (0..section.beam_count()).map(|b| BeamKey::new(0, b)).collect();
    let mut checked = 0;
    hdk.read_beams(&keys, |key, rays| {
        for r in rays {
            let d = section.decode_record(key.beam, r).unwrap();
            let dir = d.ray.direction;
            // Steep enough to hit the mirror well inside its edges, and the
            // wall after it.
            if dir.x < 0.3 {
                continue;
            }
            let exit = d.ray.origin + dir * d.ray.length;
            let to_mirror = (MIRROR_X - exit.x) / dir.x;
            let back_to_wall = (MIRROR_X - WALL_X) / dir.x;
            let want = d.ray.length + to_mirror + if virtual_depth { back_to_wall } else { 0.0 };
            let Hit::Point(p) = d.hit else {
                panic!("beam {}: a ray toward the mirror escaped", key.beam)
            };
            let stored = (p - d.ray.origin).length();
            assert!(
                (stored - want).abs() <= 1e-3 * want + 1e-3,
                "beam {}: stored depth {stored}, expected {want} (virtual: {virtual_depth})",
                key.beam
            );
            checked += 1;
        }
    })
    .unwrap();
    checked
}

#[test]
fn networked_samplers_record_virtual_distances_when_the_file_says_so() {
    let dir = tempfile::tempdir().unwrap();
    let scene = mirror_scene(dir.path(), 0.5);
    let file = dir.path().join("mirror.hdk");
    let loaded = load_scene(&scene).unwrap();
    HoloFile::create(
        &file,
        &Settings {
            sections: loaded.sections.clone(),
            scene: Some(content_hash(&loaded)),
            vdistance: true,
            ..Settings::default()
        },
    )
    .unwrap();
    let token = "t";
    let (mut server, addr) = start_server_with(file.to_str().unwrap(), "127.0.0.1:0", token, &["--report", "0.2s"]);
    // The sampler's own options know nothing of VDISTANCE: the server's welcome tells it.
    let worker = sampler(&addr, token, &[scene.to_str().unwrap()]);
    let mut log = 0;
    reported_above(&server, &mut log, 2_000, "the samplers' rays");
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let w = worker.finish();
    assert!(w.status.success(), "{}", text(&w));
    let checked = check_mirror_depths(&file, true);
    assert!(checked > 200, "rays toward the mirror were checked ({checked})");
}
