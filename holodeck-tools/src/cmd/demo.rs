//! `holodeck demo`: the whole system on the built-in scene, in one command.

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use anyhow::{Context, Result};

use crate::demo::Demo;
use crate::human::count_in;

/// Arguments of `holodeck demo`.
#[derive(clap::Args)]
#[command(after_help = "\
Builds the furnished room with terrain and a forest outside its window, renders the views of a
scripted walk directly as references, fills a holodeck for the walk (all cores, with a
progress bar), draws every view with every display driver (quadtree on the CPU; Voronoi cones
and the spherical Delaunay mesh on the GPU, or on Mesa's software Vulkan where there is none),
and writes into OUT:
  frames/viewNN-DRIVER.png    every frame, and each view's reference and direct render
                              (and .hdr beside each, linear, for `holodeck compare`)
  compare-viewNN.png          reference | quadtree | voronoi | mesh | direct render in the
                              same time, each with its relative RMSE
  chart-error-vs-paths-and-time.{png,svg}   the first view's error as the holodeck fills,
                              per driver, against a direct render with the same paths
  chart-walkthrough.{png,svg} each view's error against time along the walk, the holodeck
                              reusing its rays against tracing every view from scratch
  summary.md                  rays, rays/s, recall rate and error per driver (also printed)
  demo.hdk, walk.vf           the holodeck file and the walk (see `holodeck pict`, `holodeck view`)
A driver that cannot run here (no Vulkan at all) is reported and left out.
With --window it then opens the walkthrough window on the holodeck (`holodeck run`), which
goes on filling while you walk.

Examples:
  holodeck demo
  holodeck demo -o /tmp/demo --rays 8M --views 8
  holodeck demo --window")]
pub struct Args {
    /// Where to write.
    #[arg(short, long, default_value = "demo-out")]
    output: PathBuf,
    /// Rays to trace into the holodeck (K, M suffixes).
    #[arg(long, default_value = "4M", value_parser = count_in(1000, 1_000_000_000))]
    rays: u64,
    /// Views of the walk.
    #[arg(long, default_value_t = 5, value_parser = clap::value_parser!(u32).range(1..=100))]
    views: u32,
    /// Triangles of the scenery outside the window (K, M suffixes).
    #[arg(long, default_value = "200K", value_parser = count_in(1000, super::args::MAX_TRIANGLES))]
    triangles: u64,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 192, value_parser = clap::value_parser!(u32).range(16..=4096))]
    width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 144, value_parser = clap::value_parser!(u32).range(16..=4096))]
    height: u32,
    /// Samples per pixel of the reference renders.
    #[arg(long, default_value_t = 256, value_parser = clap::value_parser!(u32).range(1..=65536))]
    reference_spp: u32,
    /// Seed of the fill.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Then open the walkthrough window on the holodeck (needs a screen).
    #[arg(long)]
    window: bool,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let demo = Demo {
        out: a.output.clone(),
        triangles: a.triangles,
        rays: a.rays,
        views: a.views as usize,
        width: a.width,
        height: a.height,
        reference_spp: a.reference_spp,
        seed: a.seed,
    };
    let summary = demo.run()?;
    print!("{summary}");
    if a.window {
        let hdk = a.output.join("demo.hdk");
        let status = Command::new(std::env::current_exe().context("finding the holodeck executable")?)
            .args(["run", crate::demo::SCENE])
            .arg(&hdk)
            .args(["--triangles", &a.triangles.to_string(), "-o", "quadtree", "--views"])
            .arg(a.output.join("walk.vf"))
            .status()
            .context("starting `holodeck run` for the window")?;
        if !status.success() {
            anyhow::bail!("`holodeck run` for the window ended with {status}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
