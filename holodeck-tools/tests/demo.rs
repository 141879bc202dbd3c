//! `holodeck demo` end to end, small: every file it promises, a summary
//! row per driver with numbers, comparison sheets of the promised layout,
//! and the holodeck file it leaves behind readable by the other commands.

mod common;
use common::{holodeck, text};

#[test]
fn the_demo_writes_frames_sheets_charts_and_a_summary() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("demo-out");
    let out_s = out.to_str().unwrap();
    let o = holodeck(&[
        "demo",
        "-o",
        out_s,
        "--rays",
        "60K",
        "--views",
        "2",
        "--triangles",
        "20K",
        "-x",
        "48",
        "-y",
        "36",
        "--reference-spp",
        "16",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let summary = std::fs::read_to_string(out.join("summary.md")).unwrap();
    assert!(t.contains(&summary), "the summary is printed: {t}");
    // One row per method with its measures; the GPU drivers run on Mesa's
    // software Vulkan where there is no GPU.
    let row = |name: &str| -> Vec<String> {
        let line = summary
            .lines()
            .find(|l| l.starts_with(&format!("| {name} |")))
            .unwrap_or_else(|| panic!("no row for {name}: {summary}"));
        line.split('|').map(|c| c.trim().to_string()).collect()
    };
    for driver in ["quadtree", "voronoi", "mesh"] {
        for name in [driver.to_string(), format!("{driver} + atrous")] {
            let cells = row(&name);
            assert_eq!(cells[2], "60,000", "{cells:?}");
            let flip: f64 = cells[4].parse().unwrap_or_else(|_| panic!("{cells:?}"));
            let ssim: f64 = cells[6].parse().unwrap_or_else(|_| panic!("{cells:?}"));
            let clamped: f64 = cells[7].parse().unwrap_or_else(|_| panic!("{cells:?}"));
            let dark: f64 = cells[11].parse().unwrap_or_else(|_| panic!("{cells:?}"));
            assert!(flip > 0.0 && flip < 1.0, "{cells:?}");
            assert!(ssim > 0.0 && ssim <= 1.0, "{cells:?}");
            assert!(clamped > 0.0 && clamped.is_finite(), "{cells:?}");
            assert!(dark > 0.2 && dark < 5.0, "{cells:?}");
        }
    }
    let direct = row("direct, same time");
    assert!(direct[4].parse::<f64>().is_ok(), "{direct:?}");
    // Without Open Image Denoise in this build, its row says so; with it, it has numbers.
    let oidn = row("direct + oidn, same time");
    if cfg!(feature = "oidn") {
        assert!(oidn[4].parse::<f64>().is_ok(), "{oidn:?}");
    } else {
        assert!(oidn[2].starts_with("not drawn here"), "{oidn:?}");
        assert!(summary.contains("--features oidn"), "{summary}");
    }
    assert!(summary.contains("The references' own noise"), "{summary}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    assert_eq!(json["rays"], 60_000);
    assert!(json["methods"].as_array().unwrap().len() >= 8);
    for v in ["view01", "view02"] {
        for what in [
            "reference",
            "quadtree",
            "quadtree-atrous",
            "voronoi",
            "mesh-atrous",
            "direct",
        ] {
            for ext in ["png", "hdr"] {
                let f = out.join("frames").join(format!("{v}-{what}.{ext}"));
                assert!(f.exists(), "{} missing", f.display());
            }
        }
        let sheet = image::open(out.join(format!("compare-{v}.png"))).unwrap();
        // Seven panels of 48 x 36 with gaps, captions under them.
        assert_eq!((sheet.width(), sheet.height()), (7 * 48 + 8 * 6, 36 + 30 + 12));
    }
    for chart in ["chart-error-vs-paths-and-time", "chart-walkthrough"] {
        for ext in ["png", "svg"] {
            assert!(out.join(format!("{chart}.{ext}")).exists(), "{chart}.{ext}");
        }
    }
    let walk = std::fs::read_to_string(out.join("walk.vf")).unwrap();
    assert_eq!(walk.lines().count(), 2, "{walk}");
    // The holodeck is a real file the other commands read.
    let info = holodeck(&["info", out.join("demo.hdk").to_str().unwrap()]);
    assert!(info.status.success(), "{}", text(&info));
    assert!(
        text(&info).contains("60,000") || text(&info).contains("60000"),
        "{}",
        text(&info)
    );
    // Run again into the same folder: it starts over rather than failing.
    let again = holodeck(&[
        "demo",
        "-o",
        out_s,
        "--rays",
        "20K",
        "--views",
        "1",
        "--triangles",
        "20K",
        "-x",
        "32",
        "-y",
        "24",
        "--reference-spp",
        "4",
    ]);
    assert!(again.status.success(), "{}", text(&again));
    assert!(
        !out.join("compare-view02.png").exists(),
        "the earlier run's second view is gone"
    );
    assert!(!out.join("frames").join("view02-mesh.png").exists());
}
