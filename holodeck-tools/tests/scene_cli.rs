//! `holodeck scene gen` and `holodeck scene info` as real processes.

mod common;
use common::{holodeck, text};

#[test]
fn gen_room_then_info_prints_the_loaded_scene_and_its_hash() {
    let dir = tempfile::tempdir().unwrap();
    let toml = dir.path().join("scenes/room.toml");
    let o = holodeck(&["scene", "gen", "room", "-o", toml.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(dir.path().join("scenes/room.ply").is_file());
    let generated = holodeck_sampler::scene::generate("room", &Default::default()).unwrap();
    let gen_hash = holodeck_sampler::scene::content_hash(&generated);
    assert!(text(&o).contains(&gen_hash), "{}", text(&o));

    let o = holodeck(&["scene", "info", toml.to_str().unwrap()]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    let loaded = holodeck_sampler::scene::load_scene(&toml).unwrap();
    let hash = holodeck_sampler::scene::content_hash(&loaded);
    let printed = out.lines().find_map(|l| l.strip_prefix("content hash")).map(str::trim);
    assert_eq!(printed, Some(hash.as_str()), "{out}");
    assert_eq!(hash, gen_hash, "the written scene loads back identical");
    let tris = format!("{}", loaded.triangles.len());
    let line = out.lines().find(|l| l.starts_with("triangles")).unwrap();
    assert_eq!(line.split_whitespace().nth(1).unwrap().replace(',', ""), tris, "{out}");
    for want in [
        "materials    10:",
        "window (glass)",
        "light (emitter)",
        "section 0    interior",
        "sky          sun",
        "0 degenerate",
    ] {
        assert!(out.contains(want), "missing {want:?} in\n{out}");
    }
}

#[test]
fn scene_errors_name_the_file_and_fail() {
    let dir = tempfile::tempdir().unwrap();
    let bad = dir.path().join("bad.toml");
    std::fs::write(&bad, "[[geometry]]\nfile = \"x.obj\"\nmaterial = \"nope\"\n").unwrap();
    let o = holodeck(&["scene", "info", bad.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("bad.toml") && text(&o).contains("nope"),
        "{}",
        text(&o)
    );

    let out = dir.path().join("b.toml");
    let o = holodeck(&[
        "scene",
        "gen",
        "bunny",
        "--bunny",
        "/nonexistent/bunny.obj",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("/nonexistent/bunny.obj"), "{}", text(&o));

    let o = holodeck(&["scene", "gen", "castle", "-o", out.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("mandelbulb"), "{}", text(&o));

    let o = holodeck(&["scene", "gen", "--help"]);
    assert!(o.status.success() && text(&o).contains("Examples:"), "{}", text(&o));
}
