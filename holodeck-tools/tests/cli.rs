//! The `holodeck` binary end to end: real processes, real files, exit codes.

use std::path::Path;

use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::{BeamKey, DepthCode, RayRecord, Rgbe};

mod common;
use common::{fill_room, holodeck, text};

const ROOM: &str = "interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5";

fn fill(path: &Path, beams: u32, rays_each: u64) {
    let mut f = HoloFile::open(path, &OpenOptions::default()).unwrap();
    for b in 0..beams {
        let rays: Vec<RayRecord> = (0..rays_each)
            .map(|j| RayRecord::new([j as u8, 1], [2, 3], Rgbe([200, 100, 50, 128]), DepthCode(j as u16)))
            .collect();
        f.append(BeamKey::new(0, b * 3), &rays).unwrap();
    }
    f.close().unwrap();
}

#[test]
fn create_info_grid_check_optimize() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    let o = holodeck(&["create", f, "--section", ROOM, "--grid", "0.5", "--cache", "8M"]);
    assert!(o.status.success(), "{}", text(&o));
    // Grid 12 x 8 x 5 from cell length 0.5.
    assert_eq!(holodeck_protocol::beam_count_for_grid([12, 8, 5]), 124_832);
    assert!(text(&o).contains("1 section(s), 124,832 beams"), "{}", text(&o));
    fill(&file, 500, 20);

    let o = holodeck(&["info", f]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    assert!(out.contains("grid 12 x 8 x 5"), "{out}");
    assert!(out.contains("500 holding rays"), "{out}");
    assert!(out.contains("10,000 rays"), "{out}");
    assert!(out.contains("CACHE=8.0 MiB"), "{out}");

    let obj = dir.path().join("grid.obj");
    let o = holodeck(&["grid", f, "-o", obj.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let obj = std::fs::read_to_string(obj).unwrap();
    let lines = obj.lines().filter(|l| l.starts_with("l ")).count();
    let verts = obj.lines().filter(|l| l.starts_with("v ")).count();
    // Boundary points of each wall-pair grid: (gb+1)(gc+1) - (gb-1)(gc-1) per axis.
    let ring = |b: usize, c: usize| (b + 1) * (c + 1) - (b - 1) * (c - 1);
    assert_eq!(lines, ring(8, 5) + ring(5, 12) + ring(12, 8));
    assert_eq!(verts, 2 * lines);

    let o = holodeck(&["check", f]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("all checksums verify"));

    let o = holodeck(&["optimize", f]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("10,000 rays"), "{}", text(&o));
    let o = holodeck(&["info", f]);
    assert!(text(&o).contains("0 B free in 0 fragments"), "{}", text(&o));
}

#[test]
fn create_from_a_control_file() {
    let dir = tempfile::tempdir().unwrap();
    let toml = dir.path().join("room.toml");
    std::fs::write(
        &toml,
        "cache = \"16M\"\nobstructions = true\n[[section]]\norigin = [0, 0, 0]\naxes = [[6, 0, 0], [0, 4, 0], [0, 0, 2.5]]\ngrid = [10, 6, 4]\n",
    )
    .unwrap();
    let file = dir.path().join("room.hdk");
    let o = holodeck(&["create", file.to_str().unwrap(), "--control", toml.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let f = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    assert_eq!(f.sections()[0].grid(), [10, 6, 4]);
    assert!(f.settings().obstructions);
    assert_eq!(f.settings().cache_bytes, 16 << 20);
}

#[test]
fn damage_is_reported_and_salvaged_into_a_new_file() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    assert!(holodeck(&["create", f, "--section", &format!("{ROOM} grid=6,4,3")])
        .status
        .success());
    fill(&file, 50, 10);
    let offset = HoloFile::open(&file, &OpenOptions::read_only())
        .unwrap()
        .directory(0)
        .unwrap()[30]
        .offset;
    let mut bytes = std::fs::read(&file).unwrap();
    bytes[offset as usize + 4] ^= 0xff;
    std::fs::write(&file, &bytes).unwrap();

    let o = holodeck(&["check", f]);
    assert_eq!(o.status.code(), Some(2), "{}", text(&o));
    assert!(text(&o).contains("section 0 beam 30"), "{}", text(&o));

    let salvaged = dir.path().join("salvaged.hdk");
    let o = holodeck(&["check", f, "--repair", salvaged.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("salvaged 49 beams (490 rays)"), "{}", text(&o));
    assert!(holodeck(&["check", salvaged.to_str().unwrap()]).status.success());
    assert_eq!(
        std::fs::read(&file).unwrap(),
        bytes,
        "the damaged file is never written"
    );
}

#[test]
fn bad_input_gets_a_clear_error_and_a_failing_exit() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("x.hdk");
    let f = file.to_str().unwrap();
    let o = holodeck(&["create", f, "--section", "interior origin=0,0,0 x=1,0,0 y=0,1,0"]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("--section number 1") && text(&o).contains("no z= axis"),
        "{}",
        text(&o)
    );
    let o = holodeck(&["create", f]);
    assert!(
        !o.status.success() && text(&o).contains("at least one --section"),
        "{}",
        text(&o)
    );
    let o = holodeck(&["create", f, "--section", &format!("{ROOM} grid=300,1,1")]);
    assert!(
        !o.status.success() && text(&o).contains("outside 1..=255"),
        "{}",
        text(&o)
    );
    assert!(!file.exists(), "a refused create leaves no file");

    std::fs::write(&file, b"hello").unwrap();
    let o = holodeck(&["info", f]);
    assert!(
        !o.status.success() && text(&o).contains("not a holodeck file"),
        "{}",
        text(&o)
    );
    let o = holodeck(&["create", f, "--section", ROOM]);
    assert!(
        !o.status.success() && text(&o).contains("already exists"),
        "{}",
        text(&o)
    );
    assert_eq!(
        std::fs::read(&file).unwrap(),
        b"hello",
        "an existing file is never overwritten"
    );
    // Without grid= or --grid, the grid aims at 150,000 beams.
    let auto = dir.path().join("auto.hdk");
    let o = holodeck(&["create", auto.to_str().unwrap(), "--section", ROOM]);
    assert!(o.status.success(), "{}", text(&o));
    let beams = HoloFile::open(&auto, &OpenOptions::read_only()).unwrap().sections()[0].beam_count();
    assert!((75_000..300_000).contains(&beams), "{beams}");
    let o = holodeck(&["info", dir.path().join("missing.hdk").to_str().unwrap()]);
    assert!(
        !o.status.success() && text(&o).contains("missing.hdk: opening"),
        "{}",
        text(&o)
    );
}

#[test]
fn every_command_has_help_with_examples() {
    for cmd in [
        "create", "info", "check", "optimize", "grid", "bench", "scene", "render", "fill", "run", "serve", "sample",
        "pict", "view", "compare", "copy", "import", "export",
    ] {
        let o = holodeck(&[cmd, "--help"]);
        assert!(o.status.success());
        assert!(text(&o).contains("Example"), "{cmd} --help has no examples");
    }
    assert!(text(&holodeck(&["--help"])).contains("Examples:"));
}

#[test]
fn sections_beyond_sane_sizes_and_zero_directions_are_refused_by_key() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("x.hdk");
    let f = file.to_str().unwrap();
    let refused = |args: &[&str], wants: &[&str]| {
        let o = holodeck(args);
        assert!(!o.status.success(), "{args:?} was accepted: {}", text(&o));
        for w in wants {
            assert!(text(&o).contains(w), "{args:?}: no {w:?} in {}", text(&o));
        }
        assert!(!file.exists(), "{args:?} left a file behind");
    };
    let section = |s: &str| ["create", f, "--section", s].map(str::to_string);
    let run = |s: &str, wants: &[&str]| {
        let args = section(s);
        refused(&args.iter().map(String::as_str).collect::<Vec<_>>(), wants)
    };
    // Too small and too large to hold a grid; the key is named as written.
    run(
        "interior origin=0,0,0 x=1e-30,0,0 y=0,1,0 z=0,0,1",
        &[
            "x=: section axis 0 is 1e-30 long",
            "between 0.001 and 10000000 scene units",
        ],
    );
    run(
        "interior origin=0,0,0 x=1,0,0 y=0,1e30,0 z=0,0,1",
        &["y=: section axis 1 is 1e30 long"],
    );
    run("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=nan,0,1", &["z=", "not finite"]);
    run(
        "interior origin=0,2e7,0 x=1,0,0 y=0,1,0 z=0,0,1",
        &["origin=: section origin [0.0, 20000000.0, 0.0]"],
    );
    // Axes nearly in one plane: no volume worth a grid.
    run("interior origin=0,0,0 x=1,0,0 y=0,1,0 z=1,1,1e-6", &["degenerate"]);
    // Cells finer than single precision resolves that far from the origin.
    run(
        "interior origin=5e6,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=200,2,2",
        &["x=: section cells along axis 0", "single precision"],
    );

    let toml = dir.path().join("c.toml");
    std::fs::write(
        &toml,
        "[[section]]\norigin = [0, 0, 0]\naxes = [[1, 0, 0], [0, 1, 0], [0, 0, 1e-9]]\n",
    )
    .unwrap();
    refused(
        &["create", f, "--control", toml.to_str().unwrap()],
        &["c.toml", "section 0 axes[2]: section axis 2 is 1e-9 long"],
    );

    let scene = dir.path().join("s.toml");
    std::fs::write(
        &scene,
        "[[section]]\norigin = [0, 0, 0]\naxes = [[1e30, 0, 0], [0, 1, 0], [0, 0, 1]]\n",
    )
    .unwrap();
    refused(
        &["scene", "info", scene.to_str().unwrap()],
        &["s.toml", "[[section]] 1: axes[0]"],
    );
    std::fs::write(
        &scene,
        "[sky]\ntype = \"sun\"\ndirection = [0, 0, 0]\nsun_radiance = [1, 1, 1]\nzenith = [1, 1, 1]\nhorizon = [1, 1, 1]\nground = [0, 0, 0]\n",
    )
    .unwrap();
    refused(
        &["scene", "info", scene.to_str().unwrap()],
        &["s.toml", "[sky]", "direction"],
    );
}

#[test]
fn numbers_that_size_an_allocation_are_refused_by_their_flag() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("out.png");
    let (png, hdk, toml) = (
        out.to_str().unwrap(),
        dir.path().join("x.hdk"),
        dir.path().join("s.toml"),
    );
    let (hdk, toml) = (hdk.to_str().unwrap(), toml.to_str().unwrap());
    let views = dir.path().join("v.vf");
    std::fs::write(
        &views,
        format!("{}\n", "-vtv -vp 1 1 1 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45"),
    )
    .unwrap();
    let views = views.to_str().unwrap();
    let refused = |args: &[&str], flag: &str| {
        let o = holodeck(args);
        assert!(!o.status.success(), "{args:?} was accepted: {}", text(&o));
        assert!(
            text(&o).contains(flag),
            "{args:?}: {flag:?} is not named in {}",
            text(&o)
        );
        assert!(!text(&o).contains("memory allocation"), "{}", text(&o));
        for made in [png, hdk, toml] {
            assert!(!Path::new(made).exists(), "{args:?} wrote {made}");
        }
    };
    let both = "-x/--width and -y/--height";
    refused(
        &["render", "builtin:room", "-x", "4000000000", "-y", "1", "-o", png],
        "--width",
    );
    refused(&["render", "builtin:room", "-x", "0", "-o", png], "--width");
    refused(&["render", "builtin:room", "--spp", "0", "-o", png], "--spp");
    refused(
        &["render", "builtin:room", "-x", "65536", "-y", "65536", "-o", png],
        both,
    );
    refused(
        &["render", "builtin:landscape", "--triangles", "1G", "-o", png],
        "--triangles",
    );
    refused(&["pict", hdk, "-y", "0", "-o", png], "--height");
    refused(&["pict", hdk, "-x", "16384", "-y", "16384", "-o", png], both);
    let view = [
        "view",
        "--connect",
        "127.0.0.1:1",
        "--token",
        "t",
        "--headless",
        "--views",
        views,
    ];
    refused(&[&view[..], &["-o", png, "-x", "0"]].concat(), "--width");
    refused(&[&view[..], &["-o", png, "-x", "65536", "-y", "1025"]].concat(), both);
    let run = ["run", "builtin:room", hdk, "--time", "1s"];
    refused(&[&run[..], &["-x", "100000"]].concat(), "--width");
    refused(&[&run[..], &["-x", "60000", "-y", "60000"]].concat(), both);
    refused(&[&run[..], &["-n", "0"]].concat(), "--workers");
    refused(&["bench", "accuracy", "-x", "0"], "--width");
    refused(&["bench", "accuracy", "-x", "9000", "-y", "9000"], both);
    refused(&["bench", "tracer", "--pixels", "100000"], "--pixels");
    refused(&["bench", "display", "--samples", "1e12"], "--samples");
    refused(&["bench", "storage", "--request", "0"], "--request");
    refused(&["bench", "network", "--seconds=-1"], "--seconds");
    refused(
        &["scene", "gen", "landscape", "--triangles", "1G", "-o", toml],
        "--triangles",
    );
    refused(
        &["scene", "gen", "landscape", "--triangles", "0", "-o", toml],
        "--triangles",
    );
    refused(
        &["scene", "gen", "mandelbulb", "--resolution", "100000", "-o", toml],
        "--resolution",
    );
    refused(&["fill", "builtin:room", hdk, "--rays", "0"], "--rays");
    refused(
        &["fill", "builtin:room", hdk, "--rays", "1K", "--packet", "4000000000"],
        "--packet",
    );
    refused(
        &[
            "sample",
            "builtin:room",
            "--connect",
            "127.0.0.1:1",
            "--token",
            "t",
            "-j",
            "100000",
        ],
        "--jobs",
    );
    refused(&["serve", hdk, "--packet", "0"], "--packet");
    refused(&["create", hdk, "--section", ROOM, "--beams", "0"], "--beams");
}

#[test]
fn radiance_holodecks_export_import_and_copy_through_the_command_line() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    let section = format!("{ROOM} grid=6,4,3");
    assert!(holodeck(&["create", f, "--section", &section]).status.success());
    fill(&file, 200, 3);
    let rad = dir.path().join("room.rad.hdk");
    let r = rad.to_str().unwrap();
    let o = holodeck(&["export", "radiance", f, "-o", r]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("200 beams holding 600 rays"), "{}", text(&o));
    assert!(std::fs::read(&rad).unwrap().starts_with(b"#?RADIANCE\n"));
    // Our own commands on a Radiance file say how to convert it.
    let o = holodeck(&["info", r]);
    assert!(!o.status.success());
    assert!(text(&o).contains("holodeck import radiance"), "{}", text(&o));
    let back = dir.path().join("back.hdk");
    let b = back.to_str().unwrap();
    let o = holodeck(&["import", "radiance", r, "-o", b]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("200 beams holding 600 rays (little-endian, 8-byte offsets)"),
        "{}",
        text(&o)
    );
    let o = holodeck(&["info", b]);
    assert!(text(&o).contains("depth=radiance"), "{}", text(&o));
    assert!(holodeck(&["check", b]).status.success());
    // A second import onto the same name is refused; the first survives.
    let o = holodeck(&["import", "radiance", r, "-o", b]);
    assert!(!o.status.success());
    assert!(holodeck(&["check", b]).status.success());
    // Copy into the imported file: its section differs in depth coding only, so rays are resampled.
    let o = holodeck(&["copy", f, b]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(
        text(&o).contains("600 rays read, 600 stored (0 section(s) merged beam for beam, 1 resampled)"),
        "{}",
        text(&o)
    );
    let o = holodeck(&["info", b]);
    assert!(text(&o).contains("1,200 rays"), "{}", text(&o));
    // A truncated Radiance file is refused with the beam that lost its rays.
    let bytes = std::fs::read(&rad).unwrap();
    let cut = dir.path().join("cut.rad.hdk");
    std::fs::write(&cut, &bytes[..bytes.len() - 5]).unwrap();
    let o = holodeck(&[
        "import",
        "radiance",
        cut.to_str().unwrap(),
        "-o",
        dir.path().join("x.hdk").to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("cut off"), "{}", text(&o));
}

#[test]
fn outputs_never_destroy_inputs_devices_are_refused_and_closed_stdout_is_quiet() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    let o = holodeck(&["create", f, "--section", ROOM, "--grid", "0.5"]);
    assert!(o.status.success(), "{}", text(&o));
    fill(&file, 4, 3);
    let before = std::fs::read(&file).unwrap();
    // `grid FILE -o FILE` would replace the holodeck with OBJ text.
    let o = holodeck(&["grid", f, "-o", f]);
    assert!(
        !o.status.success() && text(&o).contains("would destroy it"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read(&file).unwrap(), before, "the holodeck is intact");
    // A scene from a device is refused at once, not read for ever.
    let o = holodeck(&["scene", "info", "/dev/zero"]);
    assert!(
        !o.status.success() && text(&o).contains("not a regular file"),
        "{}",
        text(&o)
    );
    // Standard output on a full device: a message and status 1, no panic.
    let o = common::process::run(std::process::Command::new("sh").args([
        "-c",
        "\"$0\" info \"$1\" > /dev/full",
        env!("CARGO_BIN_EXE_holodeck"),
        f,
    ]));
    let err = String::from_utf8_lossy(&o.stderr);
    assert_eq!(o.status.code(), Some(1), "{err}");
    assert!(
        err.contains("writing to standard output") && !err.contains("panicked"),
        "{err}"
    );
    // Durations that are not numbers, or too long, say so.
    let o = holodeck(&["serve", f, "--time", "nans"]);
    assert!(
        text(&o).contains("not a number") || text(&o).contains("nans"),
        "{}",
        text(&o)
    );
    assert!(!text(&o).contains("non-negative"), "{}", text(&o));
    // scene gen does not replace files silently.
    let toml = dir.path().join("room.toml");
    let t = toml.to_str().unwrap();
    assert!(holodeck(&["scene", "gen", "room", "-o", t]).status.success());
    let o = holodeck(&["scene", "gen", "room", "-o", t]);
    assert!(!o.status.success() && text(&o).contains("--force"), "{}", text(&o));
    assert!(holodeck(&["scene", "gen", "room", "-o", t, "--force"]).status.success());
}

#[test]
fn run_without_a_window_needs_time_and_time_bounds_a_headless_display() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    let o = holodeck(&["run", "builtin:room", f, "--headless", "--driver", "quadtree"]);
    assert!(!o.status.success() && text(&o).contains("give --time"), "{}", text(&o));
    let frames = dir.path().join("frames");
    let o = holodeck(&[
        "run",
        "builtin:room",
        f,
        "--time",
        "4s",
        "--headless",
        "-o",
        "quadtree",
        "--bounces",
        "1",
        "--frames",
        frames.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    // The old spelling of the driver still works, and says what it is now.
    assert!(text(&o).contains("it is --driver quadtree now"), "{}", text(&o));
    // The run's own account of how long it filled: TIME and the display's
    // two seconds of grace, not the walk of every view at its own pace.
    let out = text(&o);
    let secs: f64 = out
        .split(" rays added in ")
        .nth(1)
        .and_then(|r| r.split(' ').next())
        .and_then(|v| v.parse().ok())
        .unwrap_or_else(|| panic!("no summary in {out}"));
    assert!(secs < 4.0 + 2.0 + 1.0, "filled for {secs} s: {out}");
}

/// A holodeck file of the room's section with a few rays, in a new folder.
fn filled_room() -> (tempfile::TempDir, std::path::PathBuf) {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let o = holodeck(&["create", file.to_str().unwrap(), "--section", ROOM, "--grid", "0.5"]);
    assert!(o.status.success(), "{}", text(&o));
    fill(&file, 4, 3);
    (dir, file)
}

#[test]
fn pictures_make_their_folders_and_a_view_that_sees_nothing_says_so() {
    let (dir, file) = filled_room();
    let f = file.to_str().unwrap();
    let out = dir.path().join("frames/far/away.png");
    let o = holodeck(&[
        "pict",
        f,
        "--view",
        "-vtv -vp 100 100 100 -vd 1 0 0 -vu 0 0 1",
        "-x",
        "32",
        "-y",
        "24",
        "-o",
        out.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(out.is_file(), "the folders were made");
    assert!(text(&o).contains("is black: the view sees no rays"), "{}", text(&o));
    let o = holodeck(&["info", f]);
    assert!(text(&o).contains("TIME=unlimited REPORT=off"), "{}", text(&o));
    let o = holodeck(&["render", "builtin:room", "-vp", "1", "2", "1.5", "-o", "x.png"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(text(&o).contains("give the view in --view"), "{}", text(&o));
}

#[test]
fn quiet_reaches_runs_children() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let o = holodeck(&[
        "-q",
        "run",
        "builtin:room",
        file.to_str().unwrap(),
        "--time",
        "2s",
        "--bounces",
        "1",
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(!err.contains("access token"), "-q silences the children too: {err}");
    assert_eq!(text(&o), "", "-q: errors only, the run's summary left out too");
    assert!(file.is_file());
    // The same for the commands' own summaries.
    let png = dir.path().join("q.png");
    let rad = dir.path().join("rholo.hdk");
    for args in [
        vec![
            "-q",
            "render",
            "builtin:room",
            "-x",
            "16",
            "-y",
            "12",
            "--spp",
            "1",
            "-o",
            png.to_str().unwrap(),
        ],
        vec![
            "-q",
            "export",
            "radiance",
            file.to_str().unwrap(),
            "-o",
            rad.to_str().unwrap(),
        ],
        vec![
            "-q",
            "pict",
            file.to_str().unwrap(),
            "-x",
            "16",
            "-y",
            "12",
            "-o",
            png.to_str().unwrap(),
        ],
    ] {
        let o = holodeck(&args);
        assert!(o.status.success(), "{args:?}: {}", text(&o));
        assert_eq!(text(&o), "", "{args:?} printed more than errors");
    }
}

#[test]
fn a_gpu_driver_without_a_runtime_directory_prints_no_complaint() {
    let (dir, file) = filled_room();
    let f = file.to_str().unwrap();
    let out = dir.path().join("mesh.png");
    let o = common::process::run(
        std::process::Command::new(env!("CARGO_BIN_EXE_holodeck"))
            .args(["pict", f, "--driver", "mesh", "-x", "32", "-y", "24", "-o"])
            .arg(&out)
            .env_remove("XDG_RUNTIME_DIR"),
    );
    assert!(o.status.success(), "{}", text(&o));
    assert!(!text(&o).contains("XDG_RUNTIME_DIR"), "{}", text(&o));
}

#[test]
fn a_coarse_picture_says_how_to_fill_for_the_view() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    let o = holodeck(&["fill", "builtin:room", f, "--rays", "20K", "--bounces", "1"]);
    assert!(o.status.success(), "{}", text(&o));
    let png = dir.path().join("room.png");
    let o = holodeck(&["pict", f, "-x", "64", "-y", "48", "-o", png.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
    let out = text(&o);
    assert!(out.contains("is coarse: the view sees 0."), "{out}");
    assert!(out.contains("--views VIEWS"), "{out}");
}

#[test]
fn progress_is_not_drawn_off_a_terminal() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let png = dir.path().join("room.png");
    for args in [
        vec![
            "fill",
            "builtin:room",
            file.to_str().unwrap(),
            "--rays",
            "50K",
            "--bounces",
            "1",
        ],
        vec![
            "render",
            "builtin:room",
            "-x",
            "32",
            "-y",
            "24",
            "--spp",
            "2",
            "-o",
            png.to_str().unwrap(),
        ],
    ] {
        let o = holodeck(&args);
        assert!(o.status.success(), "{}", text(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            !err.contains('\r') && !err.contains('\u{1b}') && !err.contains("[="),
            "{args:?} drew progress into a pipe: {err:?}"
        );
    }
}

#[test]
fn old_spellings_of_frames_and_driver_say_what_they_are_now() {
    let dir = tempfile::tempdir().unwrap();
    let views = dir.path().join("v.vf");
    std::fs::write(&views, "-vp 1 1 1\n").unwrap();
    let frames = dir.path().join("frames");
    // Nothing listens on port 1: the note comes before the connection fails.
    let o = holodeck(&[
        "view",
        "--connect",
        "127.0.0.1:1",
        "--token",
        "t",
        "--headless",
        "--views",
        views.to_str().unwrap(),
        "-o",
        frames.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("it is --frames"), "{}", text(&o));
    let o = holodeck(&["run", "builtin:room", "x.hdk", "--driver", "crayon", "--time", "1s"]);
    assert_eq!(o.status.code(), Some(2));
    assert!(
        text(&o).contains("[possible values: none, quadtree, splat, voronoi, mesh]"),
        "{}",
        text(&o)
    );
}

/// `holodeck run` of the room into `file` until its DISKSPACE of `size` is
/// full (TIME is long enough never to end it first); fails unless it succeeds.
fn run_until_full(file: &Path, size: &str, bounces: &str) -> std::process::Output {
    let f = file.to_str().unwrap();
    let o = holodeck(&[
        "run",
        "builtin:room",
        f,
        "--time",
        "10m",
        "--diskspace",
        size,
        "--bounces",
        bounces,
    ]);
    assert!(o.status.success(), "{}", text(&o));
    o
}

#[test]
fn a_run_stopped_by_diskspace_says_so_and_keeps_to_the_limit() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let o = run_until_full(&file, "6M", "1");
    assert!(text(&o).contains("before --time: its DISKSPACE"), "{}", text(&o));
    assert!(std::fs::metadata(&file).unwrap().len() <= 6 << 20);
    let o = holodeck(&["check", file.to_str().unwrap()]);
    assert!(o.status.success(), "{}", text(&o));
}

#[test]
fn a_file_that_records_no_scene_is_continued_with_the_scene_given() {
    // As an imported Radiance holodeck: sections and rays, no scene.
    let (_dir, file) = filled_room();
    let f = file.to_str().unwrap();
    assert!(
        !text(&holodeck(&["info", f])).contains("SCENE="),
        "{}",
        text(&holodeck(&["info", f]))
    );
    let o = holodeck(&["run", "builtin:room", f, "--time", "3s", "--bounces", "1"]);
    assert!(o.status.success(), "{}", text(&o));
    let out = text(&o);
    assert!(
        out.contains("recorded no scene") && out.contains("12 rays are taken as traced in it"),
        "{out}"
    );
    let added: u64 = out
        .split(" rays added in ")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|n| n.replace(',', "").parse().ok())
        .unwrap_or_else(|| panic!("no summary in {out}"));
    assert!(added > 0, "{out}");
    assert!(
        text(&holodeck(&["info", f])).contains("SCENE=blake3:"),
        "{}",
        text(&holodeck(&["info", f]))
    );
}

#[test]
fn zeroing_any_one_page_of_a_run_made_file_loses_at_most_its_beams() {
    // Written by the server of `holodeck run` (and closed by it), kept small
    // by DISKSPACE so that every page can be tried.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    run_until_full(&file, "3M", "0");
    let (pages, worst) = holodeck_file::testing::zero_every_page(&file);
    eprintln!("run-made file: {pages} pages zeroed in turn, at most {worst} beams lost to one");
    assert!(pages > 300, "{pages} pages");
}

#[test]
fn a_scripts_tables_are_published_as_a_generated_document() {
    let dir = tempfile::tempdir().unwrap();
    let results = dir.path().join("results");
    let doc = dir.path().join("RESULTS.md");
    std::fs::write(
        &doc,
        "# R\n<!-- begin results/t.md -->\nold\n<!-- end results/t.md -->\n",
    )
    .unwrap();
    let input = dir.path().join("in.md");
    std::fs::write(&input, "| a | b |\n|---|---|\n| 1 | 2 |\n").unwrap();
    let publish = |input: &Path| {
        let line = format!(
            "exec {} bench publish t --command ./measure.sh --markdown {} < {}",
            env!("CARGO_BIN_EXE_holodeck"),
            results.display(),
            input.display()
        );
        common::process::run(std::process::Command::new("sh").arg("-c").arg(line))
    };
    let o = publish(&input);
    assert!(o.status.success(), "{}", text(&o));
    let written = std::fs::read_to_string(results.join("t.md")).unwrap();
    assert!(
        written.starts_with("Generated by `./measure.sh` (holodeck "),
        "{written}"
    );
    assert!(written.ends_with("| 1 | 2 |\n"), "{written}");
    let quoting = std::fs::read_to_string(&doc).unwrap();
    assert!(
        quoting.contains("| 1 | 2 |\n<!-- end results/t.md -->") && !quoting.contains("old"),
        "{quoting}"
    );
    // Nothing to publish is an error, and the document stays.
    let empty = dir.path().join("empty.md");
    std::fs::write(&empty, "").unwrap();
    let o = publish(&empty);
    assert!(
        !o.status.success() && text(&o).contains("standard input is empty"),
        "{}",
        text(&o)
    );
    assert_eq!(std::fs::read_to_string(results.join("t.md")).unwrap(), written);
}

#[test]
fn bench_replay_draws_the_walk_from_the_file_on_one_core_and_on_all() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    fill_room(&file, "300K", "0");
    let o = holodeck(&[
        "bench",
        "replay",
        &file.to_string_lossy(),
        "--views",
        "3",
        "-x",
        "64",
        "-y",
        "36",
    ]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    for driver in ["quadtree", "splat"] {
        let samples = out
            .lines()
            .find(|l| l.starts_with(&format!("| {driver}: samples recalled")))
            .and_then(|l| l.split('(').nth(1))
            .and_then(|l| l.split(' ').next())
            .map(|n| n.replace(',', "").parse::<u64>().unwrap())
            .unwrap_or_else(|| panic!("no samples row for {driver}: {out}"));
        assert!(samples > 0, "{driver} recalled nothing: {out}");
        let fps = out
            .lines()
            .find(|l| l.starts_with(&format!("| {driver}: frames per second")))
            .unwrap_or_else(|| panic!("no frame rate for {driver}: {out}"));
        let cells: Vec<f64> = fps.split('|').filter_map(|c| c.trim().parse().ok()).collect();
        assert!(cells.len() == 3 && cells[0] > 0.0 && cells[1] > 0.0, "{fps}");
    }
}
