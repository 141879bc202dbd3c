//! `holodeck chart grid`: how a section's grid resolution (its beam count)
//! trades recall speed against picture error for one budget of rays. The
//! paper advises 50,000 to 500,000 beams: with fewer, a beam's rays spread
//! over more of the view and each view reads rays it does not need; with
//! more, a view's request names more beams, each holding fewer rays.

use std::path::{Path, PathBuf};

use anyhow::{Context, Result};
use holodeck_display::EstimatorOptions;
use holodeck_file::settings::Settings;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::{grid_for_beam_count, Section};
use holodeck_sampler::{TraceOptions, Tracer};

use holodeck::fill::{fill, FillOptions, ViewFill};
use holodeck::truth::Truth;
use holodeck_cli::args::DriverChoice;
use holodeck_cli::chart::{Panel, Series, SeriesLabelPosition};
use holodeck_cli::human::count;

/// Arguments of `holodeck chart grid`.
#[derive(clap::Args)]
#[command(after_help = "\
For each target beam count, makes a holodeck of the scene's first section with the grid that
gives it, fills it with --rays rays for the view, and draws the view with the quadtree driver:
the recall rate (samples read, decoded and inserted per second, best of three) and the error
against a direct reference. Writes grid.png and grid.svg into -o and prints the table.

Examples:
  holodeck chart grid -o charts
  holodeck chart grid --beams 20K --beams 200K --beams 2M --rays 4M -o charts")]
pub struct Args {
    /// Where to write the chart.
    #[arg(short, long, default_value = "charts")]
    pub output: PathBuf,
    /// Scene (file or builtin:NAME); its first section is regridded.
    #[arg(long, default_value = "builtin:room")]
    pub scene: String,
    /// The view.
    #[arg(long, default_value = holodeck::ROOM_VIEW, allow_hyphen_values = true)]
    pub view: String,
    /// Target beam counts (repeat for several).
    #[arg(long, value_parser = holodeck_cli::human::count_in(100, 50_000_000), default_values = ["10K", "30K", "100K", "300K", "1M", "3M"])]
    pub beams: Vec<u64>,
    /// Rays traced into each holodeck.
    #[arg(long, default_value = "1M", value_parser = holodeck_cli::human::count_in(1000, 1_000_000_000))]
    pub rays: u64,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 96, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pub height: u32,
    /// Samples per pixel of the reference.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(1..=65536))]
    pub reference_spp: u32,
    #[command(flatten)]
    pub markdown: holodeck_cli::generated::MarkdownArgs,
}

/// One grid's measurement.
pub struct Point {
    /// Beams of the section.
    pub beams: u64,
    /// Its grid.
    pub grid: [u16; 3],
    /// Samples read, decoded and inserted per second (best of three).
    pub recall: f64,
    /// Every measure of the picture against the reference.
    pub error: holodeck_display::compare::Metrics,
    /// Beams the view's request named.
    pub requested: usize,
    /// Rays per second of the fill.
    pub fill_rate: f64,
}

/// Measures every target beam count of `a`, files under `dir`.
pub fn measure(a: &Args, dir: &Path) -> Result<Vec<Point>> {
    let scene = holodeck::load(&a.scene, None)?;
    let Some(first) = scene.sections.first().cloned() else {
        anyhow::bail!("scene {} defines no holodeck section", a.scene);
    };
    let hash = holodeck_sampler::scene::hash::content_hash(&scene);
    let view = holodeck_cli::view_arg::parse(&a.view).context("--view")?;
    let tracer = Tracer::new(scene, TraceOptions::default());
    let halves = holodeck::truth::reference_halves(&tracer, &view, (a.width, a.height), a.reference_spp, 0x5eed)?;
    let truth = Truth::new(&tracer, &view, halves)?;
    let axes = first.axes().map(|v| v.to_array());
    let eye_radius = holodeck_display::request::RequestOptions::default().eye_radius;
    let mut out = Vec::new();
    for &target in &a.beams {
        let grid = grid_for_beam_count(axes, target)?;
        let section = Section::new(first.origin().to_array(), axes, grid, first.kind())?;
        let path = dir.join(format!("grid-{target}.hdk"));
        let _ = std::fs::remove_file(&path);
        let settings = Settings {
            sections: vec![section.clone()],
            scene: Some(hash.clone()),
            ..Settings::default()
        };
        HoloFile::create(&path, &settings)?;
        let mut file = HoloFile::open(&path, &OpenOptions::default())?;
        let fo = FillOptions {
            rays: Some(a.rays),
            time: None,
            packet: 16,
            batch: 4096,
            seed: 1,
            views: Some(ViewFill::new(file.sections(), std::slice::from_ref(&view), eye_radius)),
        };
        let report = fill(&tracer, &mut file, &fo, &|_| {})?;
        let viewport = holodeck_display::Viewport::new(view.clone(), a.width, a.height)?;
        let choice = DriverChoice::plain("quadtree", EstimatorOptions::default());
        // The same picture each time; the recall rate is the best of three.
        let (picture, _, stats) = holodeck::recall::draw(&mut file, viewport.clone(), &choice, 2, 1)?;
        let (error, requested) = (truth.measure(&picture)?, stats.beams);
        let rate = |s: &holodeck::recall::FrameStats| s.samples as f64 / s.recall.as_secs_f64().max(1e-9);
        let mut recall = rate(&stats);
        for _ in 1..3 {
            let (_, _, stats) = holodeck::recall::draw(&mut file, viewport.clone(), &choice, 2, 1)?;
            recall = recall.max(rate(&stats));
        }
        file.close()?;
        let _ = std::fs::remove_file(&path);
        eprintln!(
            "grid {:?}: {} beams, recall {:.2} M samples/s, FLIP {:.4}",
            grid,
            count(section.beam_count().into()),
            recall / 1e6,
            error.flip
        );
        out.push(Point {
            beams: section.beam_count().into(),
            grid,
            recall,
            error,
            requested,
            fill_rate: report.rays as f64 / report.secs.max(1e-9),
        });
    }
    Ok(out)
}

/// Runs the command.
pub fn run(a: &Args) -> Result<()> {
    std::fs::create_dir_all(&a.output).with_context(|| format!("creating {}", a.output.display()))?;
    let points = measure(a, &a.output)?;
    a.markdown.start();
    out!(
        "Grid resolution against recall and error, {} rays per holodeck, {} x {}, quadtree:\n",
        count(a.rays),
        a.width,
        a.height
    );
    out!("| beams | grid | beams the view asks for | recall (M samples/s) | FLIP | clamped rel. RMSE | relative RMSE | darkest quarter's light | fill (rays/s) |");
    out!("|---|---|---|---|---|---|---|---|---|");
    for p in &points {
        out!(
            "| {} | {}x{}x{} | {} | {:.2} | {:.4} | {:.4} | {:.4} | {:.3} | {:.0} |",
            count(p.beams),
            p.grid[0],
            p.grid[1],
            p.grid[2],
            count(p.requested as u64),
            p.recall / 1e6,
            p.error.flip,
            p.error.clamped_relative_rmse,
            p.error.relative_rmse,
            p.error.light.dark,
            p.fill_rate
        );
    }
    let x = |p: &Point| (p.beams as f64).log10();
    let [svg, png] = holodeck_cli::chart::write(
        &a.output.join("grid"),
        &[
            Panel {
                title: format!("Recall speed by beam count ({} rays)", count(a.rays)),
                x_label: "log10 beams (the paper advises 4.7 to 5.7)".into(),
                y_label: "M samples/s read, decoded, inserted".into(),
                series: vec![Series {
                    name: "quadtree, one view".into(),
                    points: points.iter().map(|p| (x(p), p.recall / 1e6)).collect(),
                }],
                legend: SeriesLabelPosition::UpperRight,
            },
            Panel {
                title: "Picture error by beam count".into(),
                x_label: "log10 beams".into(),
                y_label: "FLIP (mean)".into(),
                series: vec![Series {
                    name: "against a direct reference".into(),
                    points: points.iter().map(|p| (x(p), p.error.flip)).collect(),
                }],
                legend: SeriesLabelPosition::UpperRight,
            },
        ],
    )?;
    eprintln!("wrote {} and {}", svg.display(), png.display());
    a.markdown
        .finish("grid", &[(png, "Recall speed and FLIP against beam count".to_string())])
}
