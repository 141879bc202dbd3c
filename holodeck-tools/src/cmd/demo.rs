//! `holodeck demo`: the whole system on the built-in scene, in one command.

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use anyhow::{Context, Result};

use crate::demo::Demo;
use crate::human::count_in;

/// Arguments of `holodeck demo`.
#[derive(clap::Args)]
#[command(after_help = "\
Builds the furnished room (with a textured rug, painting, brick wall and plant) with terrain and
a forest outside its window, renders the views of a walk through the room and out across the terrain directly as references (two independent
halves each, which state the reference's own noise), fills a holodeck for the walk (all cores,
with a progress bar), draws every view with every display driver (quadtree on the CPU; Voronoi
cones and the spherical Delaunay mesh on the GPU, or on Mesa's software Vulkan where there is
none), each on its own and through the display's denoiser, renders each view directly in its
share of the holodeck's time, on its own and cleaned by Intel Open Image Denoise with albedo and
normals (a build with --features oidn; without it that row says so), and writes into OUT:
  frames/viewNN-METHOD.png    every frame, and each view's reference (and .hdr beside each,
                              linear, for `holodeck compare`)
  compare-viewNN.png          reference | quadtree | quadtree + atrous | voronoi + atrous |
                              mesh + atrous | direct | direct + oidn, each with its FLIP
  chart-error-vs-paths-and-time.{png,svg}   the first view's FLIP as the holodeck fills,
                              per driver, against direct renders with the same paths
  chart-walkthrough.{png,svg} each view's FLIP and clamped error against each method's time
                              so far along the walk
  summary.md, summary.json    every measure per method (FLIP, HDR-FLIP, SSIM, relative errors
                              raw and clamped, light kept per region), the references' noise,
                              and where the holodeck beats a denoised direct render (printed)
  demo.hdk, walk.vf           the holodeck file and the walk (see `holodeck pict`, `holodeck view`)
A driver that cannot run here (no Vulkan at all) is reported and left out.
With --window it then opens the walkthrough window on the holodeck (`holodeck run`), which
goes on filling while you walk.

Examples:
  holodeck demo
  holodeck demo -o /tmp/demo --rays 8M --views 40 --reference-spp 1024
  holodeck demo --window")]
pub struct Args {
    /// Where to write.
    #[arg(short, long, default_value = "demo-out")]
    output: PathBuf,
    /// Rays to trace into the holodeck (K, M suffixes).
    #[arg(long, default_value = "4M", value_parser = count_in(1000, 1_000_000_000))]
    rays: u64,
    /// Views of the walk.
    #[arg(long, default_value_t = 32, value_parser = clap::value_parser!(u32).range(1..=1000))]
    views: u32,
    /// Triangles of the scenery outside the window (K, M suffixes).
    #[arg(long, default_value = "200K", value_parser = count_in(1000, super::args::MAX_TRIANGLES))]
    triangles: u64,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(16..=4096))]
    width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 96, value_parser = clap::value_parser!(u32).range(16..=4096))]
    height: u32,
    /// Samples per pixel of the reference renders (two independent halves of half each).
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
            .args(crate::verbosity_args())
            .args(["run", crate::demo::SCENE])
            .arg(&hdk)
            .args([
                "--triangles",
                &a.triangles.to_string(),
                "-o",
                "quadtree",
                "--vdistance",
                "--views",
            ])
            .arg(a.output.join("walk.vf"))
            .status()
            .context("starting `holodeck run` for the window")?;
        if !status.success() {
            anyhow::bail!("`holodeck run` for the window ended with {status}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
