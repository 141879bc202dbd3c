//! `holodeck demo`: the whole system on the built-in scene, in one command.

use std::path::PathBuf;
use std::process::{Command, ExitCode};

use anyhow::{Context, Result};

use holodeck_bench::demo::Demo;
use holodeck_cli::human::count_in;

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
goes on filling while you walk; with --web ADDR it serves the web display there instead (or
as well) and prints the link to open, until Ctrl-C.

Examples:
  holodeck demo
  holodeck demo -o /tmp/demo --rays 8M --views 40 --reference-spp 1024
  holodeck demo --window
  holodeck demo --web 127.0.0.1:8080        # then open the link it prints in a browser
  holodeck demo --markdown docs/results     # what docs/RESULTS.md quotes")]
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
    #[arg(long, default_value = "200K", value_parser = count_in(1000, holodeck_cli::args::MAX_TRIANGLES))]
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
    /// Instead of --reference-spp: the seconds all the references may take together
    /// (the samples per pixel that fit are found by timing a pass of the first view).
    #[arg(long, conflicts_with = "reference_spp", value_parser = holodeck_cli::args::non_negative)]
    reference_time: Option<f64>,
    /// Seed of the fill.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Then open the walkthrough window on the holodeck (needs a screen).
    #[arg(long)]
    window: bool,
    /// Then serve the web display of the holodeck here (HOST:PORT) while it
    /// goes on filling, until Ctrl-C; the link to open is printed.
    #[arg(long, value_name = "ADDR")]
    web: Option<String>,
    /// Also write the summary, its charts and two comparison sheets into DIR
    /// (DIR/demo.md headed by this command, the commit and the date), and refresh
    /// the blocks quoting it in the Markdown files of DIR's parent
    /// (docs/RESULTS.md quotes docs/results/demo.md).
    #[arg(long, value_name = "DIR")]
    markdown: Option<PathBuf>,
}

/// Copies the charts and two comparison sheets (a quarter and three
/// quarters along the walk) into `dir` and writes `dir/demo.md`: the summary
/// with them.
fn publish(a: &Args, dir: &std::path::Path, summary: &str) -> Result<()> {
    let views = a.views as usize;
    let mut sheets: Vec<usize> = vec![(views / 4).max(1), (3 * views / 4).max(1)];
    sheets.dedup();
    let mut pictures = vec![
        (
            "chart-error-vs-paths-and-time.png".to_string(),
            "The first view: FLIP against paths and against time, per driver, against direct renders with the same paths".to_string(),
        ),
        (
            "chart-walkthrough.png".to_string(),
            "The walk: each view's FLIP and clamped error against each method's time so far".to_string(),
        ),
    ];
    for v in sheets {
        pictures.push((
            format!("compare-view{v:02}.png"),
            format!("View {v} of {views}: the reference, the holodeck's drivers, and direct renders in the same time, raw and cleaned by OIDN, each with its FLIP"),
        ));
    }
    let charts: Vec<(PathBuf, String)> = pictures
        .into_iter()
        .map(|(file, caption)| (a.output.join(file), caption))
        .collect();
    holodeck_cli::generated::publish_with_charts(
        dir,
        "demo",
        &holodeck_cli::generated::command_line(),
        format!("{summary}\n"),
        &charts,
    )?;
    Ok(())
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let mut demo = Demo {
        out: a.output.clone(),
        triangles: a.triangles,
        rays: a.rays,
        views: a.views as usize,
        width: a.width,
        height: a.height,
        reference_spp: a.reference_spp,
        reference_time: a.reference_time,
        seed: a.seed,
    };
    let summary = demo.run()?;
    print!("{summary}");
    if let Some(dir) = &a.markdown {
        publish(&a, dir, &summary)?;
    }
    if a.window || a.web.is_some() {
        let hdk = a.output.join("demo.hdk");
        let status = Command::new(std::env::current_exe().context("finding the holodeck executable")?)
            .args(holodeck_cli::verbosity::child_args())
            .args(["run", holodeck_bench::demo::SCENE])
            .arg(&hdk)
            .args([
                "--triangles",
                &a.triangles.to_string(),
                "--driver",
                if a.window { "quadtree" } else { "none" },
                "--vdistance",
                "--views",
            ])
            .arg(a.output.join("walk.vf"))
            .args(a.web.iter().flat_map(|w| ["--web", w.as_str()]))
            .status()
            .context("starting `holodeck run` for the walkthrough")?;
        // Ctrl-C ends a web session: that is its way to end, not a failure.
        // (`run` exits 130 or 143 after SIGINT or SIGTERM.)
        let ended_well = status.success() || (a.web.is_some() && matches!(status.code(), Some(130) | Some(143)));
        if !ended_well {
            anyhow::bail!("`holodeck run` for the walkthrough ended with {status}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
