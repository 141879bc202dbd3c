//! `holodeck bench display`: the quadtree driver against plain point
//! splatting on the same samples, and `holodeck pict`'s recall rate against
//! reading the same beams without drawing them, all in one run.
//!
//! Samples are real: rays traced in the built-in room from points near the
//! eye (as proximity sampling makes them), so depth discontinuities and
//! multidepth collisions are those of a real view.

use std::path::Path;
use std::time::Instant;

use anyhow::Result;
use glam::DVec3;
use holodeck_display::{new_driver, Driver, Sample, Viewport};
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::{BeamKey, View};
use holodeck_sampler::shade::Rng;
use holodeck_sampler::{TraceOptions, Tracer};
use rayon::prelude::*;

use super::row;
use holodeck::fill::{fill, FillOptions, ViewFill};
use holodeck::ROOM_VIEW;
use holodeck_cli::human::count;

/// Most driver samples `bench display` traces and holds at once.
const MAX_DISPLAY_SAMPLES: u64 = 100_000_000;

/// Arguments of `holodeck bench display`.
#[derive(clap::Args)]
#[command(after_help = "\
Inserts traced samples of the room into every driver and draws frames: samples inserted per
second, frame times, and pictures from a holodeck file (`pict`) with its recall rate.

Example:
  holodeck bench display --samples 1M --rays 4M")]
pub struct Args {
    /// Driver samples (at most 100M: about 10 GB of samples).
    #[arg(long, default_value = "1M", value_parser = holodeck_cli::human::count_in(1, MAX_DISPLAY_SAMPLES))]
    pub samples: u64,
    /// Rays in the holodeck file drawn from.
    #[arg(long, default_value = "4M", value_parser = holodeck_cli::human::count_in(1, u64::MAX))]
    pub rays: u64,
    #[command(flatten)]
    pub files: super::Files,
}

/// Runs `holodeck bench display`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    run(a.samples as usize, a.rays, &a.files.dir, a.files.keep)?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// Samples through random pixels of `view`, traced from points within
/// `radius` of the eye: the kind a display receives.
fn room_samples(tracer: &Tracer, view: &View, n: usize, radius: f64) -> Vec<Sample> {
    let rays = view.rays();
    (0..n)
        .into_par_iter()
        .map(|i| {
            let mut rng = Rng::new(7, i as u64);
            let (x, y) = rng.f32x2();
            let (eye, dir) = rays.ray(f64::from(x), f64::from(y))?;
            let (a, b) = rng.f32x2();
            let off = DVec3::new(f64::from(a) - 0.5, f64::from(b) - 0.5, f64::from(rng.f32()) - 0.5) * (2.0 * radius);
            let origin = eye + off;
            let t = tracer.trace(origin.as_vec3(), dir.as_vec3(), &mut rng);
            Some(Sample {
                origin,
                direction: dir,
                hit: t.distance.is_finite().then(|| origin + dir * f64::from(t.distance)),
                color: t.radiance.to_array(),
            })
        })
        .flatten()
        .collect()
}

/// Insertion rate (samples/s) into a warm driver in batches of `batch`, and
/// the best of three frame times (ms).
fn time_driver(name: &str, viewport: &Viewport, samples: &[Sample], batch: usize) -> Result<(f64, f64, u64, u64)> {
    let mut d = new_driver(name, viewport.clone())?;
    // A display keeps its driver from frame to frame: time a warm one (the
    // first pass pays the kernel for fresh pages).
    for chunk in samples.chunks(batch.max(1)) {
        d.add(chunk);
    }
    d.clear();
    let before = d.stats();
    let start = Instant::now();
    for chunk in samples.chunks(batch.max(1)) {
        d.add(chunk);
    }
    let add = samples.len() as f64 / start.elapsed().as_secs_f64();
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        let p = d.render();
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
        std::hint::black_box(p);
    }
    let after = d.stats();
    Ok((
        add,
        best,
        after.kept,
        (after.discarded + after.replaced) - (before.discarded + before.replaced),
    ))
}

/// A driver holding `samples`, its best frame time (ms) of three, and the
/// time (ms) from a 5-degree turn to the complete frame.
fn frame_and_turn(name: &str, viewport: &Viewport, samples: &[Sample]) -> Result<(Box<dyn Driver>, f64, f64)> {
    let mut d = new_driver(name, viewport.clone())?;
    d.add(samples);
    // The first frame pays for pipelines and buffers.
    std::hint::black_box(d.render());
    let mut best = f64::INFINITY;
    for _ in 0..3 {
        let start = Instant::now();
        std::hint::black_box(d.render());
        best = best.min(start.elapsed().as_secs_f64() * 1e3);
    }
    let mut turned = viewport.view.clone();
    let (right, _) = turned.basis();
    turned.direction = (turned.direction.normalize() + right * 5f64.to_radians().tan()).normalize();
    let start = Instant::now();
    d.set_view(Viewport::new(turned, viewport.width, viewport.height)?);
    std::hint::black_box(d.render());
    let turn = start.elapsed().as_secs_f64() * 1e3;
    Ok((d, best, turn))
}

/// The display's denoisers on a 1024 x 768 quadtree frame of `samples`:
/// the best of three times against the frame's own drawing time.
fn denoise_rows(viewport: &Viewport, samples: &[Sample]) -> Result<()> {
    use holodeck_display::denoise::{AtrousOptions, Denoiser};
    let mut d = new_driver("quadtree", viewport.clone())?;
    d.add(samples);
    let mut frame = f64::INFINITY;
    let mut picture = d.render();
    for _ in 0..3 {
        let start = Instant::now();
        picture = d.render();
        frame = frame.min(start.elapsed().as_secs_f64() * 1e3);
    }
    let guide = d.guide();
    let mut denoisers = vec![Denoiser::Atrous(AtrousOptions::default())];
    if cfg!(feature = "oidn") {
        denoisers.push(Denoiser::Oidn);
    }
    let cpu = Denoiser::Atrous(AtrousOptions::default()).apply(&picture, &guide)?;
    let gpu = holodeck_display::denoise::gpu::GpuAtrous::shared();
    if let Ok(g) = &gpu {
        // Compiled and warmed before it is timed.
        g.filter(&picture, &guide, &AtrousOptions::default())?;
        denoisers.push(Denoiser::AtrousGpu(AtrousOptions::default()));
    }
    for dn in denoisers {
        let mut best = f64::INFINITY;
        let mut out = picture.clone();
        for _ in 0..3 {
            let start = Instant::now();
            out = std::hint::black_box(dn.apply(&picture, &guide)?);
            best = best.min(start.elapsed().as_secs_f64() * 1e3);
        }
        let on = match (&dn, &gpu) {
            (Denoiser::AtrousGpu(_), Ok(g)) => {
                // The GPU's frame against the CPU's: rounding apart, the same.
                let worst = cpu
                    .pixels
                    .iter()
                    .zip(&out.pixels)
                    .map(|(a, b)| ((*a - *b).abs() / (a.abs() + glam::Vec3::splat(1e-3))).max_element())
                    .fold(0.0f32, f32::max);
                format!(
                    "{} (largest relative difference from the CPU's frame {worst:.1e})",
                    g.describe()
                )
            }
            _ => format!("the CPU ({} threads)", rayon::current_num_threads()),
        };
        row(
            &format!("denoiser {}: a 1024x768 frame on {on}", dn.name()),
            format!("{best:.1} ms"),
            format!("the quadtree frame {frame:.1} ms"),
            best / frame,
        );
    }
    Ok(())
}

/// The GPU drivers against the quadtree on the same samples: frame time,
/// cones per second, mesh insertions, and a view change to a full frame.
fn gpu_rows(viewport: &Viewport, samples: &[Sample]) -> Result<()> {
    let gpu = holodeck_display::gpu::GpuContext::shared()?;
    eprintln!("GPU drivers on {}", gpu.describe());
    let (_, q_frame, q_turn) = frame_and_turn("quadtree", viewport, samples)?;
    let n = count(samples.len() as u64);
    for name in ["voronoi", "mesh"] {
        let (d, frame, turn) = frame_and_turn(name, viewport, samples)?;
        let kept = d.stats().kept;
        row(
            &format!(
                "{name}: frame at 1024x768 with {n} samples ({} estimates), {}",
                count(kept),
                gpu.describe()
            ),
            format!("{frame:.1} ms"),
            format!("quadtree {q_frame:.1} ms"),
            frame / q_frame,
        );
        row(
            &format!("{name}: 5-degree turn to a complete frame from cached samples"),
            format!("{turn:.1} ms"),
            format!("quadtree {q_turn:.1} ms"),
            turn / q_turn,
        );
        if name == "voronoi" {
            row(
                "voronoi: cones drawn per second (one cone per estimate, frame above)",
                format!("{:.2} M/s", kept as f64 / frame * 1e-3),
                format!("quadtree estimates per second {:.2} M/s", kept as f64 / q_frame * 1e-3),
                q_frame / frame,
            );
        }
    }
    let (random, stats) = holodeck_display::sphere::bench_insertions(1_000_000, false, 1);
    let (coherent, _) = holodeck_display::sphere::bench_insertions(1_000_000, true, 1);
    let (sorted, _) = holodeck_display::sphere::bench_sorted_insertions(1_000_000, 1);
    row(
        "mesh: spherical Delaunay insertions per second, one core, 1M random directions inserted together (sorted along a Hilbert curve first, the sort timed)",
        format!("{:.2} M/s", 1.0 / sorted),
        format!("one at a time as they come {:.2} M/s", 1.0 / random),
        random / sorted,
    );
    row(
        &format!(
            "mesh: spherical Delaunay insertions per second, one core, 1M random directions ({:.2} flips each)",
            stats.flips_per_insertion()
        ),
        format!("{:.2} M/s", 1.0 / random),
        format!(
            "the same in frame order {:.2} M/s; the paper's O2 0.01 M/s",
            1.0 / coherent
        ),
        coherent / random,
    );
    Ok(())
}

/// Runs the benchmark: `samples` driver samples at 1024 x 768, and a
/// holodeck of `rays` rays filled for one view, recalled into 512 x 512.
pub fn run(samples: usize, rays: u64, dir: &Path, keep: bool) -> Result<()> {
    let scene = holodeck::load("builtin:room", None)?;
    let tracer = Tracer::new(
        scene,
        TraceOptions {
            max_bounces: 1,
            ..TraceOptions::default()
        },
    );
    let view = View::parse(ROOM_VIEW)?;
    let viewport = Viewport::new(view.clone(), 1024, 768)?;
    eprintln!("tracing {} samples in the room...", count(samples as u64));
    let s = room_samples(&tracer, &view, samples, 0.02);
    println!("| measurement | result | baseline (same run) | ratio |");
    println!("|---|---|---|---|");
    for batch in [10_000, s.len()] {
        let (q_add, q_frame, kept, behind) = time_driver("quadtree", &viewport, &s, batch)?;
        let (s_add, s_frame, _, _) = time_driver("splat", &viewport, &s, batch)?;
        let what = format!(
            "insert {} samples in batches of {}",
            count(s.len() as u64),
            count(batch as u64)
        );
        row(
            &format!("quadtree: {what}, samples/s (projection on all cores from 16k)"),
            format!("{:.2} M/s", q_add / 1e6),
            format!("point splatting {:.2} M/s", s_add / 1e6),
            q_add / s_add,
        );
        row(
            &format!(
                "quadtree: frame at 1024x768 after that ({} pixel estimates, {} rays behind a nearer surface)",
                count(kept),
                count(behind)
            ),
            format!("{q_frame:.1} ms"),
            format!("point splatting {s_frame:.1} ms"),
            q_frame / s_frame,
        );
    }

    denoise_rows(&viewport, &s)?;
    gpu_rows(&viewport, &s)?;

    // pict: a holodeck filled only for this view, so that the view's beams hold many rays.
    std::fs::create_dir_all(dir)?;
    let path = dir.join("pict-bench.hdk");
    let _ = std::fs::remove_file(&path);
    let (_, mut file) = holodeck_cli::prepare::prepare("builtin:room", &path, None, None, false, false)?;
    let seen = ViewFill::new(file.sections(), std::slice::from_ref(&view), 0.0);
    eprintln!("filling {} rays for one view...", count(rays));
    let o = FillOptions {
        rays: Some(rays),
        time: None,
        packet: 64,
        batch: 4096,
        seed: 1,
        views: Some(seen),
    };
    fill(&tracer, &mut file, &o, &|_| {})?;
    file.close()?;
    let vp = Viewport::new(view.clone(), 512, 512)?;
    for driver in ["quadtree", "splat"] {
        let mut file = HoloFile::open(&path, &OpenOptions::read_only())?;
        // Warm: the first call reads the file into the cache.
        holodeck::recall::draw(
            &mut file,
            vp.clone(),
            &holodeck_cli::args::DriverChoice::plain(driver, Default::default()),
            2,
            0,
        )?;
        let (_, _, st) = holodeck::recall::draw(
            &mut file,
            vp.clone(),
            &holodeck_cli::args::DriverChoice::plain(driver, Default::default()),
            2,
            0,
        )?;
        let drawn = st.samples as f64 / st.recall.as_secs_f64();
        // The same beams read and decoded, not drawn.
        let request = holodeck_display::request::BeamRequest::for_viewport(
            file.sections(),
            &vp,
            &holodeck_display::request::RequestOptions {
                stride: 2,
                ..Default::default()
            },
            0,
        );
        let mut keys: Vec<BeamKey> = request.beams.iter().map(|b| b.0).collect();
        keys.sort_unstable();
        let start = Instant::now();
        let mut n = 0u64;
        file.read_beams(&keys, |_, r| n += std::hint::black_box(r).len() as u64)?;
        let read = n as f64 / start.elapsed().as_secs_f64();
        row(
            &format!(
                "pict recall ({driver}): {} samples of {} beams, cached, read and drawn at 512x512",
                count(st.samples),
                count(st.beams as u64)
            ),
            format!("{:.1} M/s", drawn / 1e6),
            format!("reading them only {:.1} M/s; rhpict 2.7 M/s (DESIGN.md)", read / 1e6),
            drawn / read,
        );
    }
    if !keep {
        let _ = std::fs::remove_file(&path);
    }
    Ok(())
}

/// The fast version for `bench all`: 200,000 traced samples of the room
/// inserted into each driver and a frame drawn; the GPU drivers beside the
/// quadtree on the same samples, the quadtree beside a pass that only reads
/// the samples (memory speed).
pub fn fast(_ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    let scene = holodeck::load("builtin:room", None)?;
    let tracer = Tracer::new(scene, Default::default());
    let view = View::parse(ROOM_VIEW)?;
    let viewport = Viewport::new(view.clone(), 512, 384)?;
    let samples = room_samples(&tracer, &view, 200_000, 0.003);
    let repeats = _ctx.repeats;
    let mut rates: Vec<Vec<f64>> = vec![Vec::new(); 3];
    let mut frames: Vec<Vec<f64>> = vec![Vec::new(); 3];
    let mut read = Vec::new();
    let mut failed: Vec<bool> = vec![false; 3];
    for _ in 0..repeats {
        let start = Instant::now();
        let sum: f64 = samples.iter().map(|s| f64::from(s.color[0])).sum();
        std::hint::black_box(sum);
        read.push(samples.len() as f64 / start.elapsed().as_secs_f64() / 1e6);
        for (i, name) in ["quadtree", "voronoi", "mesh"].iter().enumerate() {
            if failed[i] {
                continue;
            }
            match time_driver(name, &viewport, &samples, 4096) {
                Ok((add, frame, _, _)) => {
                    rates[i].push(add / 1e6);
                    frames[i].push(frame);
                }
                Err(e) => {
                    tracing::warn!("{name}: {e:#}");
                    failed[i] = true;
                }
            }
        }
    }
    let mut out = vec![
        Figure::new("display", "quadtree: samples inserted", "M/s", true, rates[0].clone())
            .against("reading the samples", read),
    ];
    out.push(Figure::new(
        "display",
        "quadtree: frame, 512 x 384",
        "ms",
        false,
        frames[0].clone(),
    ));
    for (i, name) in [(1, "voronoi"), (2, "mesh")] {
        if failed[i] {
            continue;
        }
        out.push(
            Figure::new(
                "display",
                &format!("{name}: samples inserted"),
                "M/s",
                true,
                rates[i].clone(),
            )
            .against("quadtree", rates[0].clone()),
        );
        out.push(
            Figure::new(
                "display",
                &format!("{name}: frame, 512 x 384"),
                "ms",
                false,
                frames[i].clone(),
            )
            .against("quadtree", frames[0].clone()),
        );
    }
    Ok(out)
}
