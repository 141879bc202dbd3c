//! `holodeck bench all --json` and `holodeck bench compare`, end to end on
//! the storage benchmark (the quickest): the JSON holds every figure with
//! its repeats and baseline; a run compared with itself changes nothing;
//! a figure made worse beyond its noise is flagged, and fails the command
//! with --fail-on-regression.

mod common;
use common::{holodeck, text};

#[test]
fn a_run_compared_with_itself_and_with_a_regression() {
    let dir = tempfile::tempdir().unwrap();
    let json = dir.path().join("before.json");
    let files = dir.path().join("files");
    let o = holodeck(&[
        "bench",
        "all",
        "--only",
        "storage",
        "--repeats",
        "2",
        "--json",
        json.to_str().unwrap(),
        "--dir",
        files.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", text(&o));
    assert!(text(&o).contains("| storage | append 1M rays"), "{}", text(&o));
    let report: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let figures = report["figures"].as_array().unwrap();
    assert_eq!(figures.len(), 4, "{report}");
    for f in figures {
        assert_eq!(f["bench"], "storage");
        assert_eq!(f["repeats"].as_array().unwrap().len(), 2, "{f}");
        assert!(f["value"].as_f64().unwrap() > 0.0, "{f}");
        assert!(f["baseline"]["value"].as_f64().unwrap() > 0.0, "{f}");
    }
    assert!(!files.join("all-storage.hdk").exists(), "the bench's file is removed");

    // The measured noise of a loaded machine can exceed any change: the
    // comparisons below are made on the measured values with their repeats
    // made equal (no noise), so their verdicts do not depend on the load.
    let mut report = report;
    for f in report["figures"].as_array_mut().unwrap() {
        let v = f["value"].clone();
        f["repeats"] = serde_json::json!([v, v]);
        let b = f["baseline"]["value"].clone();
        f["baseline"]["repeats"] = serde_json::json!([b, b]);
    }
    let json = dir.path().join("quiet.json");
    std::fs::write(&json, serde_json::to_string(&report).unwrap()).unwrap();
    let same = holodeck(&[
        "bench",
        "compare",
        json.to_str().unwrap(),
        json.to_str().unwrap(),
        "--fail-on-regression",
    ]);
    assert!(same.status.success(), "{}", text(&same));
    assert!(
        text(&same).contains("0 worse, 0 better, 4 within the noise."),
        "{}",
        text(&same)
    );

    // Twice the bytes per ray (less is better) and half the append rate:
    // both far beyond any noise.
    let mut worse = report.clone();
    for f in worse["figures"].as_array_mut().unwrap() {
        let factor = match f["name"].as_str().unwrap() {
            n if n.starts_with("append") => 0.5,
            n if n.starts_with("whole-file bytes") => 2.0,
            _ => continue,
        };
        f["value"] = (f["value"].as_f64().unwrap() * factor).into();
        for r in f["repeats"].as_array_mut().unwrap() {
            *r = (r.as_f64().unwrap() * factor).into();
        }
    }
    let after = dir.path().join("after.json");
    std::fs::write(&after, serde_json::to_string(&worse).unwrap()).unwrap();
    let o = holodeck(&["bench", "compare", json.to_str().unwrap(), after.to_str().unwrap()]);
    assert!(
        o.status.success(),
        "without --fail-on-regression it only reports: {}",
        text(&o)
    );
    assert!(
        text(&o).contains("2 worse, 0 better, 2 within the noise."),
        "{}",
        text(&o)
    );
    let o = holodeck(&[
        "bench",
        "compare",
        json.to_str().unwrap(),
        after.to_str().unwrap(),
        "--fail-on-regression",
    ]);
    assert_eq!(o.status.code(), Some(1), "{}", text(&o));
    // A file that is not a report is refused, naming it.
    std::fs::write(&after, "not json").unwrap();
    let o = holodeck(&["bench", "compare", json.to_str().unwrap(), after.to_str().unwrap()]);
    assert!(!o.status.success());
    assert!(text(&o).contains("after.json"), "{}", text(&o));
}
