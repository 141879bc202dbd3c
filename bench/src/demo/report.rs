//! What the demo writes about its measurements: a comparison sheet per
//! view, the charts, the summary table (markdown, also printed) and the
//! same numbers as JSON for scripts.

use std::path::Path;

use anyhow::Result;
use holodeck_display::compare::Metrics;

use super::{sheet, Demo, Fill};
use holodeck::demo::methods::{Column, Kind};
use holodeck::truth::Truth;
use holodeck_cli::chart::{Panel, Series, SeriesLabelPosition};
use holodeck_cli::human::count;

/// The methods a sheet shows after the reference: by name, and the label
/// under each.
const SHEET: [(&str, &str); 6] = [
    ("quadtree", "quadtree"),
    ("quadtree + atrous", "quadtree + atrous"),
    ("voronoi + atrous", "voronoi + atrous"),
    ("mesh + atrous", "mesh + atrous"),
    ("direct, same time", "direct, same time"),
    ("direct + oidn, same time", "direct + oidn"),
];

/// Writes the comparison sheet of view `i`: the reference and the methods
/// of [`SHEET`], each with its FLIP (the reference with its own noise).
pub fn sheet(out: &Path, i: usize, truth: &Truth, columns: &[Column], reference_spp: u32) -> Result<()> {
    let noise = truth
        .yardstick
        .noise()
        .map_or(String::new(), |n| format!("noise {:.3}", n.clamped_relative_rmse));
    let mut panels = vec![sheet::Panel {
        picture: Some(&truth.picture),
        caption: format!("reference {reference_spp} spp\n{noise}"),
    }];
    for (name, label) in SHEET {
        let column = columns.iter().find(|c| c.kind.name() == name);
        let shot = column.and_then(|c| c.shots[i].as_ref());
        panels.push(sheet::Panel {
            picture: shot.map(|s| &s.picture),
            caption: match shot {
                Some(s) => format!("{label}\nFLIP {:.3}", s.metrics.flip),
                None => format!("{label}\nnot drawn here"),
            },
        });
    }
    sheet::write(&out.join(format!("compare-view{:02}.png", i + 1)), &panels, &truth.tone)
}

/// The charts: the first view's FLIP as the holodeck fills against the same
/// paths and time traced directly, and every view's FLIP and clamped error
/// along the walk against each method's time so far.
pub fn charts(out: &Path, filled: &Fill, columns: &[Column], views: usize) -> Result<()> {
    let curve = |name: &str, points: &[super::Point], x: fn(&super::Point) -> f64| Series {
        name: name.to_string(),
        points: points.iter().map(|p| (x(p), p.2)).collect(),
    };
    let by_paths: Vec<Series> = filled
        .convergence
        .iter()
        .filter(|(_, c)| !c.is_empty())
        .map(|(n, c)| curve(n, c, |p| p.0 / 1e6))
        .collect();
    let by_time: Vec<Series> = filled
        .convergence
        .iter()
        .filter(|(_, c)| !c.is_empty())
        .map(|(n, c)| curve(n, c, |p| p.1))
        .collect();
    holodeck_cli::chart::write(
        &out.join("chart-error-vs-paths-and-time"),
        &[
            Panel {
                title: match views {
                    1 => "One view: FLIP against paths".to_string(),
                    n => format!("First view: FLIP against paths (the holodeck's rays serve all {n} views)"),
                },
                x_label: "million paths (holodeck: rays in the file)".into(),
                y_label: "FLIP (mean)".into(),
                series: by_paths,
                legend: SeriesLabelPosition::UpperRight,
            },
            Panel {
                title: "First view: FLIP against seconds".into(),
                x_label: "seconds (holodeck: fill and drawing)".into(),
                y_label: "FLIP (mean)".into(),
                series: by_time,
                legend: SeriesLabelPosition::UpperRight,
            },
        ],
    )?;
    let along = |f: fn(&Metrics) -> f64| -> Vec<Series> {
        columns
            .iter()
            .filter(|c| c.failed.is_none())
            .map(|c| {
                let mut clock = match c.kind {
                    Kind::Holodeck { .. } => filled.secs,
                    Kind::Direct { .. } => 0.0,
                };
                Series {
                    name: c.kind.name(),
                    points: c
                        .shots
                        .iter()
                        .flatten()
                        .map(|s| {
                            clock += s.secs;
                            (clock, f(&s.metrics))
                        })
                        .collect(),
                }
            })
            .collect()
    };
    holodeck_cli::chart::write(
        &out.join("chart-walkthrough"),
        &[
            Panel {
                title: "The walk: each view's FLIP against time so far".into(),
                x_label: "seconds since the start (holodeck: from its fill)".into(),
                y_label: "FLIP (mean)".into(),
                series: along(|m| m.flip),
                legend: SeriesLabelPosition::UpperRight,
            },
            Panel {
                title: "The walk: relative RMSE of values clamped at 2".into(),
                x_label: "seconds since the start (holodeck: from its fill)".into(),
                y_label: "clamped relative RMSE".into(),
                series: along(|m| m.clamped_relative_rmse),
                legend: SeriesLabelPosition::UpperRight,
            },
        ],
    )?;
    Ok(())
}

/// What the summary says of the run beside the table.
pub struct Run<'a> {
    /// The demo's settings.
    pub demo: &'a Demo,
    /// The holodeck file.
    pub hdk: &'a Path,
    /// The fill.
    pub filled: &'a Fill,
    /// The holodeck's time: the fill and every frame of the default method.
    pub holodeck_secs: f64,
    /// Seconds rendering the references.
    pub reference_secs: f64,
    /// The references.
    pub truths: &'a [Truth],
    /// Where the frames are.
    pub frames: &'a Path,
    /// Seconds in all.
    pub total_secs: f64,
}

/// What the summary's measures and names mean, printed above its table.
const MEASURES: &str = "What the columns mean. FLIP: NVIDIA's perceptual difference of the pictures as \
shown (0 is identical, lower is better); HDR-FLIP: the same over the reference's range of exposures. \
SSIM: structural similarity (1 is identical). Relative RMSE: the root of the mean, over pixels, of the \
squared difference divided by the reference's squared value (plus 0.01); a few bright pixels can \
dominate it, so the clamped columns first clamp every value at 2. Same time: a direct render of \
each view given the holodeck's time (its fill and its frames) divided among the views; \
direct + oidn is that render cleaned by Intel Open Image Denoise, what a user would otherwise do.\n\n";

/// How to read the charts the demo writes, printed under its table.
const CHARTS: &str = "\nThe charts: chart-error-vs-paths-and-time shows the first view alone. A direct \
render spends every path on that view while the holodeck's rays serve every view of the walk, so \
on one view the direct render catches up as paths grow and wins from some count on; the \
holodeck's gain is that the next views cost only their frames (chart-walkthrough, each view's \
error against the time spent so far).\n";

fn cell(x: f64, digits: usize) -> String {
    if x.is_nan() {
        String::new()
    } else {
        format!("{x:.digits$}")
    }
}

/// The summary: a line on the run, the table of every measure per method
/// (means over the walk's views), the references' noise, and where the
/// default holodeck picture beats a denoised direct render and where not.
pub fn summary(r: &Run<'_>, columns: &[Column]) -> String {
    let d = r.demo;
    let n = r.truths.len();
    let mut s = format!(
        "holodeck demo: {} rays traced into {} in {:.1} s ({} rays/s), {n} views of {}x{} along a walk through the room and out, references at {} spp in two halves ({:.1} s)\n\n",
        count(r.filled.rays),
        r.hdk.display(),
        r.filled.secs,
        count((r.filled.rays as f64 / r.filled.secs.max(1e-9)).round() as u64),
        d.width,
        d.height,
        d.reference_spp,
        r.reference_secs
    );
    s += MEASURES;
    s += "Means over the views. Seconds: the holodeck's fill and every frame of the method; a direct render's every view, each given the holodeck's time (fill and quadtree + atrous frames) over the views. Light kept: the method's luminance over the reference's in the darkest quarter, the middle half and the brightest quarter of the reference's pixels, and in the silhouette band; peak: the brightest spot kept.\n\n";
    s += &method_table(r, columns);
    let default = columns
        .iter()
        .find(|c| c.kind == holodeck::demo::methods::default_method());
    s += &reference_noise(r, default);
    s += &against_oidn(columns, default, n);
    s += CHARTS;
    s += &format!(
        "\nThe walk: the holodeck's quadtree + atrous pictures after {:.1} s (fill and every frame). Frames in {}, comparison sheets, charts and summary.json in {}; {:.0} s in all.\n",
        r.holodeck_secs,
        r.frames.display(),
        d.out.display(),
        r.total_secs
    );
    s
}

/// The table of every method's means over the views.
fn method_table(r: &Run<'_>, columns: &[Column]) -> String {
    let mut s = String::new();
    s += "| method | rays or paths | seconds | FLIP | HDR-FLIP | SSIM | clamped rel. RMSE | clamped rel. MSE | rel. RMSE | rel. MSE | dark | middle | bright | band | peak |\n";
    s += "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|\n";
    for c in columns {
        let name = c.kind.name();
        if let Some(why) = &c.failed {
            s += &format!(
                "| {name} | not drawn here: {} | | | | | | | | | | | | | |\n",
                why.lines().next().unwrap_or(why)
            );
            continue;
        }
        let (rays, secs) = match c.kind {
            Kind::Holodeck { .. } => (r.filled.rays, r.filled.secs + c.secs()),
            Kind::Direct { .. } => (c.shots.iter().flatten().map(|s| s.samples).sum(), c.secs()),
        };
        s += &format!(
            "| {name} | {} | {:.1} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n",
            count(rays),
            secs,
            cell(c.mean(|m| m.flip), 4),
            cell(c.mean(|m| m.hdr_flip), 4),
            cell(c.mean(|m| m.ssim), 3),
            cell(c.mean(|m| m.clamped_relative_rmse), 4),
            cell(c.mean(|m| m.clamped_relative_mse), 5),
            cell(c.mean(|m| m.relative_rmse), 4),
            cell(c.mean(|m| m.relative_mse), 5),
            cell(c.mean(|m| m.light.dark), 3),
            cell(c.mean(|m| m.light.middle), 3),
            cell(c.mean(|m| m.light.bright), 3),
            cell(c.mean(|m| m.light.band.unwrap_or(f64::NAN)), 3),
            cell(c.mean(|m| m.peak), 3),
        );
    }
    s
}

/// The references' own noise against the default method's errors.
fn reference_noise(r: &Run<'_>, default: Option<&Column>) -> String {
    let n = r.truths.len();
    let mut s = String::new();
    let noise: Vec<f64> = r
        .truths
        .iter()
        .filter_map(|t| t.yardstick.noise().map(|n| n.clamped_relative_rmse))
        .collect();
    let mean_noise = noise.iter().sum::<f64>() / noise.len().max(1) as f64;
    let too_noisy: Vec<String> = match default {
        Some(c) => r
            .truths
            .iter()
            .zip(&c.shots)
            .enumerate()
            .filter_map(|(i, (t, shot))| {
                let (n, shot) = (t.yardstick.noise()?, shot.as_ref()?);
                let bad = n.too_noisy_for(&shot.metrics);
                (!bad.is_empty()).then(|| format!("view {} ({})", i + 1, bad.join(", ")))
            })
            .collect(),
        None => Vec::new(),
    };
    s += &format!(
        "\nThe references' own noise (clamped relative RMSE against the truth, from their two halves): {mean_noise:.4} on average. "
    );
    if too_noisy.is_empty() {
        s += "It is under a quarter of every error of quadtree + atrous in every view.\n";
    } else {
        s += &format!(
            "It is not under a quarter of quadtree + atrous's error in {} of {n} views: {} (more --reference-spp states those errors better).\n",
            too_noisy.len(),
            too_noisy.join("; ")
        );
    }
    s
}

/// The holodeck's default picture against what a user would otherwise do:
/// a direct render cleaned by OIDN in the same time.
fn against_oidn(columns: &[Column], default: Option<&Column>, n: usize) -> String {
    let mut s = String::new();
    let oidn = columns.iter().find(|c| c.kind == Kind::Direct { oidn: true });
    match (default, oidn) {
        (Some(h), Some(o)) if o.failed.is_none() => {
            let wins: Vec<usize> = (0..n)
                .filter(|&i| match (&h.shots[i], &o.shots[i]) {
                    (Some(a), Some(b)) => a.metrics.flip < b.metrics.flip,
                    _ => false,
                })
                .map(|i| i + 1)
                .collect();
            s += &format!(
                "Quadtree + atrous against a direct render cleaned by OIDN in the same time: mean FLIP {:.4} against {:.4} ({:.2}x), clamped relative MSE {:.5} against {:.5} ({:.2}x), SSIM {:.3} against {:.3}; lower FLIP in {} of {n} views{}.\n",
                h.mean(|m| m.flip),
                o.mean(|m| m.flip),
                o.mean(|m| m.flip) / h.mean(|m| m.flip),
                h.mean(|m| m.clamped_relative_mse),
                o.mean(|m| m.clamped_relative_mse),
                o.mean(|m| m.clamped_relative_mse) / h.mean(|m| m.clamped_relative_mse),
                h.mean(|m| m.ssim),
                o.mean(|m| m.ssim),
                wins.len(),
                if wins.is_empty() {
                    String::new()
                } else {
                    format!(
                        " ({})",
                        wins.iter().map(|v| v.to_string()).collect::<Vec<_>>().join(", ")
                    )
                }
            );
        }
        _ => {
            s += "The direct render cleaned by OIDN is missing: this build has no Open Image Denoise (build with --features oidn, see the README).\n";
        }
    }
    s
}

/// Every method's measures per view, and the run's times, for scripts.
pub fn json(columns: &[Column], truths: &[Truth], holodeck_secs: f64, filled: &Fill) -> serde_json::Value {
    serde_json::json!({
        "rays": filled.rays,
        "fill_secs": filled.secs,
        "holodeck_secs": holodeck_secs,
        "reference_noise": truths.iter().map(|t| t.yardstick.noise().copied()).collect::<Vec<_>>(),
        "methods": columns.iter().map(|c| serde_json::json!({
            "name": c.kind.name(),
            "failed": c.failed,
            "views": c.shots.iter().map(|s| s.as_ref().map(|s| serde_json::json!({
                "secs": s.secs,
                "samples": s.samples,
                "metrics": s.metrics,
            }))).collect::<Vec<_>>(),
        })).collect::<Vec<_>>(),
    })
}
