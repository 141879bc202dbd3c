//! What the file's settings and scene mean for networked samplers: they
//! trace as the file says (VDISTANCE), and an admin may change the scene
//! under a running server (kill, edit, adopt).

use std::path::{Path, PathBuf};

use holodeck_file::settings::Settings;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::Role;
use holodeck_protocol::{BeamKey, Hit};
use holodeck_sampler::scene::hash::content_hash;
use holodeck_sampler::scene::load_scene;

use crate::common::process::{wait_for, DEADLINE};
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

/// The content hash `holodeck sample` proves for the scene file at `path`.
fn hash_of(path: &Path) -> String {
    content_hash(&load_scene(path).unwrap())
}

/// The scene hash a closed holodeck file records, and whether it says its rays are stale.
fn recorded(file: &Path) -> (Option<String>, bool) {
    let f = HoloFile::open(file, &OpenOptions::read_only()).unwrap();
    (f.settings().scene.clone(), f.settings().stale)
}

/// `holodeck admin` against `addr` with the admin token.
fn admin(addr: &str, token: &str, args: &[&str]) -> std::process::Output {
    let mut all = vec!["admin", "--connect", addr, "--token", token];
    all.extend_from_slice(args);
    crate::common::holodeck(&all)
}

#[test]
fn an_admin_kills_the_samplers_the_scene_is_edited_and_adopted() {
    let dir = tempfile::tempdir().unwrap();
    let scene = mirror_scene(dir.path(), 0.5);
    let (s, file) = (scene.to_str().unwrap(), dir.path().join("mirror.hdk"));
    let f = file.to_str().unwrap();
    let o = crate::common::holodeck(&["fill", s, f, "--rays", "500", "--bounces", "0"]);
    assert!(o.status.success(), "{}", text(&o));
    let a = hash_of(&scene);
    assert_eq!(recorded(&file), (Some(a.clone()), false));
    let initial = rays_in(&file);
    let beams: Vec<(BeamKey, u32)> = {
        let n = HoloFile::open(&file, &OpenOptions::read_only()).unwrap().sections()[0].beam_count();
        (0..n).map(|b| (BeamKey::new(0, b), 0)).collect()
    };
    let token = "t";
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);
    let mut first = sampler(&addr, token, &[s]);
    let mut log = 0;
    reported_above(&server, &mut log, initial + 1_000, "scene A's rays");

    // Kill, then edit: a sampler of the edited scene is refused (and waits),
    // and so is the killed one, once it has reloaded the edit.
    let o = admin(&addr, token, &["kill"]);
    assert!(o.status.success(), "{}", text(&o));
    mirror_scene(dir.path(), 0.25);
    let b = hash_of(&scene);
    assert_ne!(a, b, "the edit changes the scene's hash");
    let mut second = sampler(&addr, token, &[s]);
    let refused = format!("scene {b} is not the holodeck's scene {a}");
    second.wait_line("the edited scene's sampler refused for now", &mut 0, |l| {
        l.contains(&refused).then_some(())
    });
    first.wait_line("the killed sampler reloading the edit", &mut 0, |l| {
        l.contains(&format!("the scene changed; now {b}")).then_some(())
    });
    assert!(second.try_wait().is_none() && first.try_wait().is_none(), "both wait");

    // Adopt B (paused first, to see the file empty before B's samplers refill it).
    let (mut display, _) = Client::connect(&addr, Role::Display, token);
    let o = admin(&addr, token, &["pause"]);
    assert!(o.status.success(), "{}", text(&o));
    let held = display.stored(&beams);
    assert!(held > initial, "scene A's rays are there before the adoption ({held})");
    let o = admin(&addr, token, &["adopt", s]);
    assert!(o.status.success() && text(&o).contains("done"), "{}", text(&o));
    assert_eq!(display.stored(&beams), 0, "scene A's rays are gone ({held} before)");
    let o = admin(&addr, token, &["resume"]);
    assert!(o.status.success(), "{}", text(&o));
    let after = stored_above(&mut display, &beams, 500, "scene B's samplers at work");
    // Both samplers of B are back (each retries within 2 s).
    wait_for("a status report of both samplers", DEADLINE, || {
        let status = admin(&addr, token, &["status"]);
        assert!(status.status.success(), "{}", text(&status));
        text(&status).contains("2 samplers").then_some(())
    });
    drop(display);
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    for w in [first, second] {
        let out = w.finish();
        assert!(out.status.success(), "{}", text(&out));
    }
    // Durably B's: the file records B, and holds only what B's samplers traced.
    assert_eq!(recorded(&file), (Some(b.clone()), false));
    let closed = rays_at_close(&server);
    assert!(closed >= after, "{closed} at close, {after} seen");
    assert!(
        check_mirror_depths(&file, false) > 50,
        "B's rays measure plain distances"
    );

    // A restarted server on the file takes B's samplers, and adopting a
    // third version with --keep-rays keeps the rays, marked stale.
    let (mut server, addr) = start_server_with(f, "127.0.0.1:0", token, &["--report", "0.2s"]);
    let third = sampler(&addr, token, &[s]);
    let mut log = 0;
    reported_above(&server, &mut log, closed, "scene B's sampler after the restart");
    let o = admin(&addr, token, &["kill"]);
    assert!(o.status.success(), "{}", text(&o));
    mirror_scene(dir.path(), 0.75);
    let c = hash_of(&scene);
    let o = admin(&addr, token, &["adopt", s, "--keep-rays"]);
    assert!(o.status.success(), "{}", text(&o));
    quit(&addr, token);
    assert!(server.wait().success(), "{}", server.text());
    let out = third.finish();
    assert!(out.status.success(), "{}", text(&out));
    assert_eq!(recorded(&file), (Some(c), true));
    assert!(rays_in(&file) >= closed, "the rays were kept");
    let info = crate::common::holodeck(&["info", f]);
    assert!(text(&info).contains("STALE"), "{}", text(&info));
    assert_clean(&file);
}
