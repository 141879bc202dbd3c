//! `holodeck chart`, small: each chart's measurement runs, prints its
//! table and writes the chart as PNG and SVG.

mod common;
use common::{holodeck, text};

#[test]
fn the_grid_chart_measures_every_beam_count() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().to_str().unwrap();
    let o = holodeck(&[
        "chart",
        "grid",
        "-o",
        out,
        "--beams",
        "2K",
        "--beams",
        "20K",
        "--rays",
        "20K",
        "-x",
        "32",
        "-y",
        "24",
        "--reference-spp",
        "4",
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    let rows: Vec<&str> = t
        .lines()
        .filter(|l| l.starts_with("| ") && !l.starts_with("| beams"))
        .collect();
    assert_eq!(rows.len(), 2, "{t}");
    for row in rows {
        let cells: Vec<&str> = row.split('|').map(str::trim).collect();
        let beams: u64 = cells[1].replace(',', "").parse().unwrap();
        let recall: f64 = cells[4].parse().unwrap();
        let error: f64 = cells[5].parse().unwrap();
        assert!(beams > 500 && recall > 0.0 && error > 0.0 && error.is_finite(), "{row}");
    }
    for ext in ["png", "svg"] {
        assert!(dir.path().join(format!("grid.{ext}")).exists());
    }
    assert!(!dir.path().join("grid-2000.hdk").exists(), "the holodecks are removed");
}

#[test]
fn the_lod_and_memory_charts_come_from_the_scene_file_bench() {
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("charts");
    let files = dir.path().join("files");
    let o = holodeck(&[
        "chart",
        "lod",
        "--triangles",
        "20K",
        "--pixels",
        "32",
        "-o",
        out.to_str().unwrap(),
        "--dir",
        files.to_str().unwrap(),
    ]);
    let t = text(&o);
    assert!(o.status.success(), "{t}");
    assert!(t.contains("diffuse bounce, sorted by hit point"), "{t}");
    for stem in ["ooc-lod", "ooc-budget"] {
        for ext in ["png", "svg"] {
            assert!(out.join(format!("{stem}.{ext}")).exists(), "{stem}.{ext}");
        }
    }
}
