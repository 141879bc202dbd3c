//! `holodeck fill`: trace rays of a scene into a holodeck file, in this process.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use holodeck_protocol::wire::MAX_PACKET_RAYS;
use holodeck_sampler::TraceOptions;

use holodeck_file::settings::parse_duration;
use holodeck_file::{HoloFile, OpenOptions};

use holodeck::fill::{fill, FillOptions, ViewFill};
use holodeck_cli::args::MAX_TRIANGLES;
use holodeck_cli::human::{bytes, count, count_in};
use holodeck_cli::progress::{Progress, Unit};

/// Arguments of `holodeck fill`.
#[derive(clap::Args)]
#[command(after_help = "\
Fills the holodeck in batch mode: every beam gets rays in proportion to its volume, and
every beam gets its first rays before any gets more, so the file is usable whenever the
fill stops. A new FILE takes its sections from the scene; an existing one must belong to
the same scene (its content hash is checked) and is filled further.

Examples:
  holodeck fill builtin:room room.hdk --rays 2M
  holodeck fill scenes/room.toml room.hdk --time 10m --samples 4
  holodeck fill builtin:room room.hdk --rays 1M --views walk.vf   # only what a walk sees
  holodeck info room.hdk")]
pub struct Args {
    /// Scene file, or builtin:NAME.
    scene: String,
    /// The holodeck file (created if missing).
    file: PathBuf,
    /// Stop after this many rays (K, M, G suffixes).
    #[arg(long, value_parser = count_in(1, u64::MAX))]
    rays: Option<u64>,
    /// Stop after this long (e.g. 90s, 10m, 2h).
    #[arg(long)]
    time: Option<String>,
    /// Rays per beam per visit.
    #[arg(long, default_value_t = 4, value_parser = clap::value_parser!(u32).range(1..=i64::from(MAX_PACKET_RAYS)))]
    packet: u32,
    /// Path samples averaged per ray.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    /// Largest number of bounces.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    #[command(flatten)]
    reorder: holodeck_cli::args::ReorderArgs,
    /// Seed of this run (use another to add independent rays).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// Fill only the beams these views see (a file of Radiance views, one per line).
    #[arg(long)]
    views: Option<PathBuf>,
    /// With --views: new rays pass this near the eyes of the views that see their beam
    /// (each in turn, by its share of the beam), as a fraction of the section diagonal
    /// (0: anywhere in the beam).
    #[arg(long, default_value_t = holodeck_display::request::RequestOptions::default().eye_radius, requires = "views", value_parser = holodeck_cli::args::non_negative)]
    eye_radius: f64,
    /// For a .hds scene file: decompressed blocks kept in memory (K, M, G; default: all of them).
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    scene_memory: Option<u64>,
    /// Write on top of a file whose newest commit is damaged, keeping what can
    /// still be read and losing the rest for good (see `holodeck check`).
    #[arg(long)]
    accept_loss: bool,
    /// For a new FILE: record virtual distances through windows and mirrors
    /// (VDISTANCE), so that what a window shows reprojects as the view beyond
    /// it does when the eye moves (as `holodeck demo` fills).
    #[arg(long)]
    vdistance: bool,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    if a.rays.is_none() && a.time.is_none() {
        bail!("give --rays or --time (or both) so the fill knows when to stop");
    }
    let time = a
        .time
        .as_deref()
        .map(|t| parse_duration(t, 1.0))
        .transpose()
        .context("--time")?;
    let (scene, mut file) = holodeck_cli::prepare::prepare(
        &a.scene,
        &a.file,
        a.triangles,
        a.scene_memory,
        a.accept_loss,
        a.vdistance,
    )?;
    let options = TraceOptions {
        max_bounces: a.bounces,
        samples: a.samples,
        vdistance: file.settings().vdistance,
        reorder: a.reorder.reorder,
        ..TraceOptions::default()
    };
    let tracer = scene.tracer(options);
    // Filling toward a ray count shows the rays; filling for a time shows the time.
    let bar = match (a.rays, time) {
        (None, Some(limit)) => Progress::timed("filling", Some(Unit::Rays), limit),
        (rays, _) => Progress::counting("filling", Unit::Rays, rays),
    };
    let fill_options = FillOptions {
        rays: a.rays,
        time,
        packet: a.packet,
        batch: 4096,
        seed: a.seed,
        views: match &a.views {
            Some(path) => Some(ViewFill::new(
                file.sections(),
                &holodeck_cli::view_arg::read_views(path)?,
                a.eye_radius,
            )),
            None => None,
        },
    };
    let report = fill(&tracer, &mut file, &fill_options, &|n| bar.set(n))
        .with_context(|| format!("filling {}", a.file.display()))?;
    bar.finish();
    let non_finite = tracer.non_finite_count();
    // Closing compacts the file: its size is what it is after that.
    file.close()?;
    let summary = HoloFile::open(&a.file, &OpenOptions::read_only())?.summary();
    summary!(
        "{}: {} rays in {:.1} s ({} rays/s, {:.1}% of the time storing); {} of {} beams hold rays ({:.1}%); file {} ({:.2} bytes/ray)",
        a.file.display(),
        count(report.rays),
        report.secs,
        count((report.rays as f64 / report.secs.max(1e-9)).round() as u64),
        100.0 * report.store_secs / report.secs.max(1e-9),
        count(report.beams_filled),
        count(report.beams),
        100.0 * report.beams_filled as f64 / report.beams.max(1) as f64,
        bytes(summary.file_bytes),
        summary.bytes_per_ray()
    );
    if non_finite > 0 {
        summary!("warning: {non_finite} non-finite estimates were replaced by black");
    }
    Ok(ExitCode::SUCCESS)
}
