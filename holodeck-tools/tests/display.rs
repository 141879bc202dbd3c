//! Pictures from a holodeck, measured: every driver's reconstruction of the
//! built-in room against the direct reference renderer, as the holodeck
//! fills; and the cases where display methods fail.

mod common;
use common::{holodeck, text};

use holodeck_display::compare::{relative_rmse, ssim};
use holodeck_display::image_io::read_picture;
use holodeck_display::tonemap::{DisplayRange, Histogram, ToneMap, ToneMode};

const VIEW: &str = "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56";

fn ok(args: &[&str]) -> String {
    let o = holodeck(args);
    assert!(o.status.success(), "holodeck {args:?}: {}", text(&o));
    text(&o)
}

/// The quadtree picture of a view-driven fill converges: every ray a pixel
/// gets joins its estimate, so quadrupling the rays about halves the error
/// (slope -1/2 in log-log) until the reference's own noise is reached, and
/// the picture ends far below the noise of a one-sample-per-pixel render,
/// which is where keeping one ray per pixel left it.
#[test]
fn pictures_of_every_driver_converge_to_the_reference_as_the_holodeck_fills() {
    let dir = tempfile::tempdir().unwrap();
    let p = |name: &str| dir.path().join(name).to_str().unwrap().to_string();
    let (hdk, reference, direct, views) = (p("room.hdk"), p("ref.hdr"), p("direct.hdr"), p("v.vf"));
    std::fs::write(&views, format!("{VIEW}\n")).unwrap();
    let size = ["-x", "64", "-y", "48"];
    let render = |spp: &str, seed: &str, out: &str| {
        // Direct lighting only (no interreflections): the reference converges fast.
        ok(&[
            &[
                "render",
                "builtin:room",
                "--view",
                VIEW,
                "--bounces",
                "0",
                "--spp",
                spp,
                "--seed",
                seed,
                "-o",
                out,
            ][..],
            &size,
        ]
        .concat());
    };
    render("1024", "1", &reference);
    render("1", "9", &direct);
    let r = read_picture(std::path::Path::new(&reference)).unwrap();
    let tone = ToneMap::new(&Histogram::from_picture(&r), ToneMode::Camera, DisplayRange::default());
    let floor = relative_rmse(&read_picture(std::path::Path::new(&direct)).unwrap(), &r).unwrap();

    // Every driver draws the same holodeck after each fill; the GPU drivers
    // on Mesa's software Vulkan where there is no GPU.
    let drivers: [(&str, &[&str]); 4] = [
        ("quadtree", &[]),
        ("voronoi", &[]),
        ("voronoi+geometry", &["--geometry", "builtin:room"]),
        ("mesh", &[]),
    ];
    let mut table: Vec<Vec<(f64, f64)>> = vec![Vec::new(); drivers.len()];
    for (add, seed) in [("12K", "1"), ("36K", "2"), ("144K", "3")] {
        ok(&[
            "fill",
            "builtin:room",
            &hdk,
            "--rays",
            add,
            "--bounces",
            "0",
            "--views",
            &views,
            "--seed",
            seed,
        ]);
        for (i, (name, extra)) in drivers.iter().enumerate() {
            let driver = name.split('+').next().unwrap_or(name);
            let pict = p(&format!("pict-{name}-{add}.hdr"));
            let out = ok(&[
                // The drivers' own reconstruction: the denoiser after them is measured elsewhere.
                &[
                    "pict",
                    &hdk,
                    "--view",
                    VIEW,
                    "--driver",
                    driver,
                    "--denoise",
                    "off",
                    "-o",
                    &pict,
                ][..],
                extra,
                &size,
            ]
            .concat());
            let q = read_picture(std::path::Path::new(&pict)).unwrap();
            let e = relative_rmse(&q, &r).unwrap();
            let s = ssim(&q, &r, &tone);
            println!("{name} after +{add}: {out} relative rmse {e:.4} (1-spp render {floor:.3}), ssim {s:.3}");
            table[i].push((e, s));
        }
    }
    println!("| rays | 1-spp render | {} |", drivers.map(|d| d.0).join(" | "));
    for (row, rays) in ["12K", "48K", "192K"].iter().enumerate() {
        let cells: Vec<String> = table.iter().map(|t| format!("{:.4}", t[row].0)).collect();
        println!("| {rays} | {floor:.4} | {} |", cells.join(" | "));
    }
    for ((name, _), errors) in drivers.iter().zip(&table) {
        assert!(errors[2].0 < 0.75 * errors[0].0, "{name}: {errors:?}");
        assert!(
            errors[2].0 < 0.5 * floor,
            "{name}: {errors:?} vs the 1-spp render's {floor}"
        );
    }
    let errors = &table[0];
    // 12K, 48K and 192K rays: each step four times the rays, and the error
    // falls at each. Over the two steps (sixteen times the rays) it falls
    // with a slope below -0.3 in log-log; one step's slope alone swings
    // between -0.2 and -0.6 with the random sequences.
    let slopes: Vec<f64> = errors.windows(2).map(|w| (w[1].0 / w[0].0).ln() / 4f64.ln()).collect();
    assert!(slopes.iter().all(|s| *s < 0.0), "slopes {slopes:?}: {errors:?}");
    let overall = (errors[2].0 / errors[0].0).ln() / 16f64.ln();
    assert!(
        overall < -0.3,
        "slope {overall} over sixteen times the rays: {errors:?}"
    );
    assert!(errors[0].1 < errors[2].1, "{errors:?}");
    assert!(errors[2].0 < 0.25 * floor, "{errors:?} vs the 1-spp render's {floor}");
    assert!(errors[2].1 >= 0.9, "{errors:?}");
}

#[test]
fn pictures_where_the_method_fails_are_drawn_or_refused_clearly() {
    let dir = tempfile::tempdir().unwrap();
    let hdk = dir.path().join("room.hdk");
    let hdk = hdk.to_str().unwrap();
    // One bounce: lit walls, so a drawn frame is not black.
    ok(&["fill", "builtin:room", hdk, "--rays", "20K", "--bounces", "1"]);
    let out = |n: &str| dir.path().join(n).to_str().unwrap().to_string();
    // Outside every section, looking away: nothing to draw, a black frame, no error.
    let away = out("away.hdr");
    let t = ok(&[
        "pict",
        hdk,
        "--view",
        "-vtv -vp 50 50 50 -vd 0 0 1 -vu 0 1 0",
        "-x",
        "16",
        "-y",
        "16",
        "-o",
        &away,
    ]);
    assert!(t.contains(" 0 samples from 0 beams"), "{t}");
    assert_eq!(samples(&t), 0);
    let black = read_picture(std::path::Path::new(&away)).unwrap();
    assert!(black.pixels.iter().all(|p| *p == glam::Vec3::ZERO));
    // Outside the section looking in, and along a wall: drawn.
    let t = ok(&[
        "pict",
        hdk,
        "--view",
        "-vtv -vp -3 2 1.5 -vd 1 0 0 -vu 0 0 1",
        "-x",
        "32",
        "-y",
        "24",
        "-o",
        &out("in.hdr"),
    ]);
    let drawn = samples(&t);
    assert!(drawn > 0, "{t}");
    let inside = read_picture(std::path::Path::new(&out("in.hdr"))).unwrap();
    assert_eq!((inside.width, inside.height), (32, 24));
    let lit = inside.pixels.iter().filter(|p| p.max_element() > 0.0).count();
    assert!(
        lit > inside.pixels.len() / 2,
        "{drawn} samples lit only {lit} pixels: {t}"
    );
    // Along a wall, through a one-degree window: a frame of finite,
    // non-negative pixels, black exactly when no sample fell in it.
    let t = ok(&[
        "pict",
        hdk,
        "--view",
        "-vtv -vp 0.001 2 1.5 -vd 0 1 0 -vu 0 0 1 -vh 1 -vv 1",
        "-x",
        "8",
        "-y",
        "8",
        "-o",
        &out("wall.hdr"),
    ]);
    let wall = read_picture(std::path::Path::new(&out("wall.hdr"))).unwrap();
    assert_eq!((wall.width, wall.height), (8, 8));
    assert!(
        wall.pixels.iter().all(|p| p.is_finite() && p.min_element() >= 0.0),
        "{t}"
    );
    let black = wall.pixels.iter().all(|p| *p == glam::Vec3::ZERO);
    assert_eq!(black, samples(&t) == 0, "{t}");
    // One pixel works; a 16384 x 16384 frame is refused with a reason.
    ok(&["pict", hdk, "-x", "1", "-y", "1", "-o", &out("one.hdr")]);
    let o = holodeck(&["pict", hdk, "-x", "16384", "-y", "16384", "-o", &out("huge.hdr")]);
    assert!(!o.status.success());
    assert!(
        text(&o).contains("a 16384 x 16384 picture is too large"),
        "{}",
        text(&o)
    );
    // A scripted path gives numbered frames; a bad line names itself.
    let path = dir.path().join("walk.vf");
    std::fs::write(&path, format!("{VIEW}\n-vp 1 2 1.5\n-vp 1.3 2 1.5\n")).unwrap();
    let t = ok(&[
        "pict",
        hdk,
        "--views",
        path.to_str().unwrap(),
        "-x",
        "16",
        "-y",
        "12",
        "-o",
        &out("walk_%03d.png"),
    ]);
    for n in 1..=3 {
        assert!(dir.path().join(format!("walk_{n:03}.png")).exists(), "{t}");
    }
    std::fs::write(&path, format!("{VIEW}\n-vp 1 two 1.5\n")).unwrap();
    let o = holodeck(&["pict", hdk, "--views", path.to_str().unwrap(), "-o", &out("w_%d.png")]);
    assert!(!o.status.success() && text(&o).contains("walk.vf:2"), "{}", text(&o));
}

/// The samples `holodeck pict` reports drawing: "N samples from M beams".
fn samples(out: &str) -> u64 {
    let count = out
        .split(" samples from ")
        .next()
        .and_then(|head| head.rsplit(' ').next())
        .unwrap_or_else(|| panic!("no sample count in {out:?}"));
    count
        .replace(',', "")
        .parse()
        .unwrap_or_else(|e| panic!("sample count {count:?} in {out:?}: {e}"))
}
