//! `holodeck chart`: speed against accuracy, drawn (PNG and SVG, with the
//! bundled font). Each chart runs its own measurement on this machine:
//!
//! 1. `error`: one view's error against paths and against time, one curve
//!    per display driver and one for the direct render (the demo's
//!    measurement, one view);
//! 2. `walk`: a walkthrough, each view's error against the time so far,
//!    the holodeck reusing its rays against rendering each view from
//!    scratch (the demo's measurement);
//! 3. `lod`: out-of-core LOD, pixels of error against frame time and error;
//! 4. `grid`: beam count against recall speed and picture error for one
//!    budget of rays;
//! 5. `memory`: scene-memory budget against rays/s, rays as given and
//!    sorted by estimated hit point (with 3, from the scene-file bench).

pub mod grid;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;

use crate::demo::Demo;

/// Arguments of `holodeck chart`.
#[derive(clap::Args)]
#[command(after_help = "\
Examples:
  holodeck chart error -o charts
  holodeck chart walk --views 8 -o charts
  holodeck chart lod --triangles 1M -o charts
  holodeck chart grid --rays 2M -o charts
  holodeck chart memory --triangles 10M -o charts")]
pub struct Args {
    #[command(subcommand)]
    chart: Chart,
}

#[derive(clap::Subcommand)]
enum Chart {
    /// One view's error against paths and time, per driver, against a direct render.
    Error(DemoArgs),
    /// A walkthrough: each view's error against time, rays reused against each view from scratch.
    Walk(DemoArgs),
    /// Out-of-core LOD: pixels of error against frame time and picture error.
    Lod(SceneFileArgs),
    /// Beam count against recall speed and picture error for one budget of rays.
    Grid(grid::Args),
    /// Scene-memory budget against rays/s, rays as given and sorted by hit point.
    Memory(SceneFileArgs),
}

/// The demo's measurement for charts 1 and 2.
#[derive(clap::Args)]
#[command(after_help = "\
Runs the measurement of `holodeck demo` (the furnished room with terrain and a forest outside its
window) and writes its charts, frames and comparison sheets into -o: chart-error-vs-paths-and-time
and chart-walkthrough (PNG and SVG).")]
struct DemoArgs {
    /// Where to write.
    #[arg(short, long, default_value = "charts")]
    output: PathBuf,
    /// Rays traced into the holodeck.
    #[arg(long, default_value = "4M", value_parser = holodeck_cli::human::count_in(1000, 1_000_000_000))]
    rays: u64,
    /// Views of the walk (`error` uses the first).
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    views: u32,
    /// Triangles of the scenery outside the window.
    #[arg(long, default_value = "200K", value_parser = holodeck_cli::human::count_in(1000, holodeck_cli::args::MAX_TRIANGLES))]
    triangles: u64,
    /// Samples per pixel of the references.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    reference_spp: u32,
}

/// The scene-file bench's measurement for charts 3 and 5.
#[derive(clap::Args)]
#[command(after_help = "\
Runs `holodeck bench scene-file` on a generated landscape (its tables are printed) and writes
ooc-lod and ooc-budget (PNG and SVG) into -o.")]
struct SceneFileArgs {
    /// Where to write.
    #[arg(short, long, default_value = "charts")]
    output: PathBuf,
    /// Landscape size (triangles).
    #[arg(long, default_value = "1M", value_parser = holodeck_cli::human::count_in(1000, holodeck_cli::args::MAX_TRIANGLES))]
    triangles: u64,
    /// Rays per measurement: a square of this many pixels per side.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(16..=4096))]
    pixels: u32,
    #[command(flatten)]
    files: super::bench::Files,
    #[command(flatten)]
    markdown: holodeck_cli::generated::MarkdownArgs,
}

fn demo(a: &DemoArgs, views: u32) -> Result<ExitCode> {
    let summary = Demo {
        out: a.output.clone(),
        triangles: a.triangles,
        rays: a.rays,
        views: views as usize,
        width: 192,
        height: 144,
        reference_spp: a.reference_spp,
        reference_time: None,
        seed: 1,
    }
    .run()?;
    print!("{summary}");
    Ok(ExitCode::SUCCESS)
}

fn scene_file(a: &SceneFileArgs) -> Result<ExitCode> {
    a.markdown.start();
    super::bench::scene_file::run(a.triangles, a.pixels, &a.files.dir, a.files.keep, Some(&a.output))?;
    a.markdown.finish(
        "memory",
        &[
            (
                a.output.join("ooc-budget.png"),
                "Rays/s out of core against in core by cache budget".to_string(),
            ),
            (
                a.output.join("ooc-lod.png"),
                "LOD: frame time and error against pixels of error".to_string(),
            ),
        ],
    )?;
    Ok(ExitCode::SUCCESS)
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    match a.chart {
        Chart::Error(a) => demo(&a, 1),
        Chart::Walk(a) => demo(&a, a.views.max(2)),
        Chart::Lod(a) | Chart::Memory(a) => scene_file(&a),
        Chart::Grid(a) => {
            grid::run(&a)?;
            Ok(ExitCode::SUCCESS)
        }
    }
}
