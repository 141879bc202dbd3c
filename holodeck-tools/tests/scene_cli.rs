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

#[test]
fn the_built_in_bunny_needs_no_files_from_anywhere() {
    // An installed holodeck runs from any directory: nothing of the
    // development tree is next to it.
    let dir = tempfile::tempdir().unwrap();
    let run = |args: &[&str]| {
        let o = common::process::run(
            std::process::Command::new(env!("CARGO_BIN_EXE_holodeck"))
                .args(args)
                .current_dir(dir.path()),
        );
        assert!(o.status.success(), "{args:?}: {}", text(&o));
        text(&o)
    };
    let t = run(&["scene", "gen", "bunny", "-o", "bunny.toml"]);
    let bunny = holodeck_sampler::scene::generate("bunny", &Default::default()).unwrap();
    let hash = holodeck_sampler::scene::content_hash(&bunny);
    assert!(t.contains(&hash), "{t}");
    // The Stanford bunny's 3,674 triangles, the room and the table.
    assert!(
        t.contains(&format!("{} triangles", count(bunny.triangles.len()))),
        "{t}"
    );
    assert!(bunny.triangles.len() > 3_674, "{}", bunny.triangles.len());
    let loaded = holodeck_sampler::scene::load_scene(&dir.path().join("bunny.toml")).unwrap();
    assert_eq!(holodeck_sampler::scene::content_hash(&loaded), hash);
    run(&[
        "render",
        "builtin:bunny",
        "-x",
        "16",
        "-y",
        "12",
        "--spp",
        "1",
        "-o",
        "bunny.png",
    ]);
    assert!(dir.path().join("bunny.png").is_file());
}

/// `n` with thousands separators, as the command prints counts.
fn count(n: usize) -> String {
    let s = n.to_string();
    let mut out = String::new();
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

#[test]
fn the_mandelbulb_streams_into_a_scene_file_that_recodes_to_zstd() {
    let dir = tempfile::tempdir().unwrap();
    let hds = dir.path().join("bulb.hds");
    let zstd = dir.path().join("bulb-zstd.hds");
    let o = holodeck(&[
        "scene",
        "build",
        "builtin:mandelbulb",
        "--resolution",
        "20",
        "--memory",
        "1M",
        "-o",
        hds.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let generated = holodeck_sampler::scene::generate(
        "mandelbulb",
        &holodeck_sampler::scene::gen::GenParams {
            resolution: Some(20),
            ..Default::default()
        },
    )
    .unwrap();
    assert!(
        text(&o).contains(&count(generated.triangles.len())),
        "every generated triangle streamed: {}",
        text(&o)
    );
    let o = holodeck(&[
        "scene",
        "recode",
        hds.to_str().unwrap(),
        "--codec",
        "zstd",
        "-o",
        zstd.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    let o = holodeck(&["scene", "info", zstd.to_str().unwrap()]);
    assert!(text(&o).contains("zstd codec"), "{}", text(&o));
    assert!(text(&o).contains(&count(generated.triangles.len())), "{}", text(&o));
    // Rendered from the file assembled in memory, and through the block
    // cache: the same hits, so the same picture.
    let view = "-vtv -vp 0 -3.5 0.3 -vd 0 1 -0.08 -vu 0 0 1 -vh 50 -vv 40";
    let mut pictures = Vec::new();
    for (name, extra) in [("assembled.png", None), ("streamed.png", Some("--out-of-core"))] {
        let out = dir.path().join(name);
        let mut args = vec![
            "render",
            zstd.to_str().unwrap(),
            "--view",
            view,
            "-x",
            "32",
            "-y",
            "24",
            "--spp",
            "2",
            "-o",
            out.to_str().unwrap(),
        ];
        args.extend(extra);
        let o = holodeck(&args);
        assert!(o.status.success(), "{}", text(&o));
        let said = if extra.is_some() {
            "blocks loaded"
        } else {
            "assembled in memory"
        };
        assert!(text(&o).contains(said), "{}", text(&o));
        pictures.push(std::fs::read(&out).unwrap());
    }
    assert_eq!(pictures[0], pictures[1], "the two renders differ");
    // Past what triangle ids can number: refused before any work.
    let o = holodeck(&[
        "scene",
        "build",
        "builtin:mandelbulb",
        "--resolution",
        "9000",
        "-o",
        hds.to_str().unwrap(),
    ]);
    assert!(!o.status.success());
    assert!(text(&o).contains("9000"), "{}", text(&o));
}

#[test]
fn scene_info_lists_textures_import_notes_and_the_radiance_sky() {
    let dir = tempfile::tempdir().unwrap();
    let p = dir.path();
    image::RgbaImage::from_pixel(8, 8, image::Rgba([200, 100, 50, 255]))
        .save(p.join("wood.png"))
        .unwrap();
    std::fs::write(
        p.join("t.mtl"),
        "newmtl wood\nillum 2\nd 0\nKd 1 1 1\nmap_Kd wood.png\nmap_Ks gloss.png\n",
    )
    .unwrap();
    std::fs::write(
        p.join("t.obj"),
        "mtllib t.mtl\nv 0 0 0\nv 1 0 0\nv 1 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nusemtl wood\nf 1/1 2/2 3/3\n",
    )
    .unwrap();
    std::fs::write(
        p.join("gensky.rad"),
        "void light solar 0 0 3 6.38e+06 6.38e+06 6.38e+06\nsolar source sun 0 0 4 0 -0.644212 0.764848 0.5\n\
         void brightfunc skyfunc 2 skybr skybright.cal 0 7 1 3.56e+01 4.38e+01 2.41e-01 0 -0.644212 0.764848\n\
         skyfunc glow sky_mat 0 0 4 0.9 0.9 1.15 0\nsky_mat source sky 0 0 4 0 0 1 180\n",
    )
    .unwrap();
    std::fs::write(
        p.join("scene.toml"),
        "[[geometry]]\nfile = \"t.obj\"\n\n[[geometry]]\nfile = \"gensky.rad\"\n",
    )
    .unwrap();
    let o = holodeck(&["scene", "info", p.join("scene.toml").to_str().unwrap()]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    for want in [
        "textures     1 images,",
        "import note",
        "d 0 ignored: illum 2 is an opaque model",
        "map_Ks is not used",
        "CIE clear sky (skybright.cal)",
    ] {
        assert!(out.contains(want), "missing {want:?} in\n{out}");
    }
    // At the default verbosity the notes come as one summary line.
    let stderr = String::from_utf8_lossy(&o.stderr);
    assert!(stderr.contains("dropped or approximated on import"), "{stderr}");
    assert!(!stderr.contains("map_Ks"), "details only with -v: {stderr}");
}

#[test]
fn sections_that_cut_geometry_are_reported_and_a_proposed_one_fits() {
    let dir = tempfile::tempdir().unwrap();
    let o = holodeck(&["scene", "section", "builtin:room", "--eye", "3", "2", "1.6"]);
    let out = text(&o);
    assert!(o.status.success(), "{out}");
    let table = &out[out.find("[[section]]").expect("a [[section]] table")..];
    // The room with the proposed section, and with one through the table.
    let write = |name: &str, section: &str| {
        let path = dir.path().join(name);
        std::fs::write(&path, format!("[[builtin]]\nname = \"room\"\n\n{section}\n")).unwrap();
        path
    };
    let fits = write("fits.toml", table);
    let o = holodeck(&["scene", "info", fits.to_str().unwrap()]);
    assert!(o.status.success() && !text(&o).contains("warning"), "{}", text(&o));
    assert!(text(&o).contains("section 0    interior"), "{}", text(&o));
    let cuts = write(
        "cuts.toml",
        "[[section]]\nkind = \"interior\"\norigin = [2, 1, 0.5]\naxes = [[2, 0, 0], [0, 2, 0], [0, 0, 1]]",
    );
    let o = holodeck(&["scene", "info", cuts.to_str().unwrap()]);
    let out = text(&o);
    assert!(out.contains("reach into interior section 0"), "{out}");
    // A fill warns too, naming the file.
    let hdk = dir.path().join("cuts.hdk");
    let o = holodeck(&["fill", cuts.to_str().unwrap(), hdk.to_str().unwrap(), "--rays", "1000"]);
    assert!(text(&o).contains("reach into interior section 0"), "{}", text(&o));
    let o = holodeck(&["scene", "section", "builtin:room", "--eye", "3", "2", "0.02"]);
    assert!(
        !o.status.success() && text(&o).contains("within --margin"),
        "{}",
        text(&o)
    );
}
