//! `holodeck bench accuracy`: is a holodeck picture worth its rays? Every
//! measure of the yardstick (FLIP, SSIM, relative errors raw and clamped,
//! light kept per region) against a converged reference of the same view,
//! made of two halves that state its own noise, for the holodeck and for a
//! direct render given the same compute, on its own and cleaned by Open
//! Image Denoise:
//!
//! 1. one view: holodeck pictures (a fill for the view, then `pict`, raw and
//!    denoised; and a display session that asks for rays where its pixels
//!    need them) against direct renders with the same number of paths;
//! 2. light kept: on every scene used for accuracy (the room, the room with
//!    terrain, the arcade and the blind room, the last two lit mostly
//!    indirectly), each region's light in the default picture;
//! 3. a walkthrough: the time until every view of a path is within a target
//!    error, the holodeck (fill for the first view, then more rays only where
//!    a view needs them, reusing every ray and every pixel estimate so far)
//!    against rendering each view from scratch.
//!
//! The walk at equal total time, with every method beside direct + OIDN,
//! is `holodeck demo`'s. References are rendered once and kept under `--dir`.

use std::collections::HashMap;
use std::path::PathBuf;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_display::denoise::{AtrousOptions, Denoiser};
use holodeck_display::image_io::{read_picture, write_hdr};
use holodeck_display::request::{BeamRequest, RequestOptions};
use holodeck_display::{new_driver_with, Driver, EstimatorOptions, SampleDecoder, Viewport};
use holodeck_file::HoloFile;
use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::{BeamKey, Picture, View};
use holodeck_sampler::render::{render, RenderOptions};
use holodeck_sampler::{TraceOptions, Tracer};

use holodeck::fill::{fill, FillOptions, ViewFill};
use holodeck::truth::Truth;
use holodeck_cli::human::count;
use holodeck_display::compare::Metrics;

use super::kept::{mean, KeptOver};
use holodeck_sampler::beam::trace_batch;

/// Arguments of `holodeck bench accuracy`.
#[derive(clap::Args)]
#[command(after_help = "\
Holodeck pictures against direct renders given the same compute (raw, and cleaned by Intel Open
Image Denoise in a build with --features oidn), every measure (FLIP, SSIM, relative errors raw and
clamped, light kept in the dark, middle and bright quarters and the silhouette band) against a
converged reference made of two halves that state its own noise: one view (against paths), the
light kept per region on every scene used for accuracy (the room, the room with terrain, and
two lit mostly indirectly: builtin:arcade and builtin:blind), and a walkthrough (time until
every view is within a target error). The walk at equal total time is `holodeck demo`'s.
References are rendered once and kept under --dir.

Examples:
  holodeck bench accuracy                                  (one view, light kept, a 10-view walk)
  holodeck bench accuracy --paths 250K --paths 1M --repeats 3 --walk-views 0 --light-scenes none
  holodeck bench accuracy --paths 1M --walk-views 0 --reference-spp 4096 -x 160 -y 120
  holodeck bench accuracy --paths 250K --walk-views 0 --light-scenes blind --reference-time 30")]
pub struct Args {
    /// Paths per budget (repeat for several).
    #[arg(long, value_parser = holodeck_cli::human::count_in(1, u64::from(u32::MAX)), default_values = ["62.5K", "250K", "1M", "4M"])]
    pub paths: Vec<u64>,
    /// Scene.
    #[arg(long, default_value = "builtin:room")]
    pub scene: String,
    /// View (the walk starts there).
    #[arg(long, default_value = holodeck::ROOM_VIEW, allow_hyphen_values = true)]
    pub view: String,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 128, value_parser = clap::value_parser!(u32).range(holodeck_cli::args::SIDE))]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 96, value_parser = clap::value_parser!(u32).range(holodeck_cli::args::SIDE))]
    pub height: u32,
    /// Samples per pixel of the references (rendered once, kept in --dir).
    #[arg(long, default_value_t = 1024, value_parser = clap::value_parser!(u32).range(1..))]
    pub reference_spp: u32,
    /// Instead of --reference-spp: the seconds each reference may take (its samples per
    /// pixel found by timing a pass of its view; a reference kept in --dir is used again
    /// only where the count comes out the same).
    #[arg(long, conflicts_with = "reference_spp", value_parser = holodeck_cli::args::non_negative)]
    pub reference_time: Option<f64>,
    /// Independent runs averaged per budget.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    pub repeats: u32,
    /// Views in the walkthrough (0: none; each keeps a reference picture).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u16).range(0..=1000))]
    pub walk_views: u16,
    /// Scenes whose light kept per region is measured (builtin:NAME, each at its own
    /// view; none to skip): the room, the room with terrain, and two lit mostly indirectly.
    #[arg(long, value_delimiter = ',', default_value = "room,landscape,arcade,blind")]
    pub light_scenes: Vec<String>,
    /// Rays filled for each scene's view in the light-kept part.
    #[arg(long, default_value = "1M", value_parser = holodeck_cli::human::count_in(1000, u64::from(u32::MAX)))]
    pub light_rays: u64,
    /// Independent fills of each scene in the light-kept part: the ratios are
    /// their means, each with its standard error.
    #[arg(long, default_value_t = 16, value_parser = clap::value_parser!(u32).range(1..=64))]
    pub light_repeats: u32,
    /// Relative RMSE every walkthrough view must reach.
    #[arg(long, default_value_t = 0.2, value_parser = holodeck_cli::args::positive)]
    pub target: f64,
    /// Eye radius of the holodeck's fills (fraction of the section diagonal).
    #[arg(long, default_value_t = holodeck_display::request::RequestOptions::default().eye_radius, value_parser = holodeck_cli::args::non_negative)]
    pub eye_radius: f64,
    #[command(flatten)]
    pub estimator: holodeck_cli::args::EstimatorArgs,
    #[command(flatten)]
    pub files: super::Files,
    #[command(flatten)]
    pub markdown: holodeck_cli::generated::MarkdownArgs,
}

/// Runs `holodeck bench accuracy`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    holodeck_cli::args::frame_size(a.width, a.height)?;
    a.markdown.start();
    AccuracyBench {
        scene: a.scene.clone(),
        view: View::parse(&a.view).context("--view")?,
        width: a.width,
        height: a.height,
        paths: a.paths.clone(),
        reference_spp: a.reference_spp,
        reference_time: a.reference_time,
        repeats: a.repeats,
        walk_views: usize::from(a.walk_views),
        light_scenes: a
            .light_scenes
            .iter()
            .filter(|s| s.as_str() != "none")
            .cloned()
            .collect(),
        light_rays: a.light_rays,
        light_repeats: a.light_repeats,
        target: a.target,
        estimator: a.estimator.options()?,
        eye_radius: a.eye_radius,
        dir: a.files.dir.clone(),
        keep: a.files.keep,
    }
    .run()?;
    a.markdown.finish("accuracy", &[])?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// What to measure.
pub struct AccuracyBench {
    /// Scene (file or builtin:NAME).
    pub scene: String,
    /// The single view.
    pub view: View,
    /// Frame size.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Paths per budget of the single-view comparison.
    pub paths: Vec<u64>,
    /// Samples per pixel of the references.
    pub reference_spp: u32,
    /// Instead: the seconds each reference may take.
    pub reference_time: Option<f64>,
    /// Independent runs averaged per budget.
    pub repeats: u32,
    /// Views in the walkthrough (0: skip it).
    pub walk_views: usize,
    /// Built-in scenes of the light-kept part (empty: skip it).
    pub light_scenes: Vec<String>,
    /// Rays filled for each of their views.
    pub light_rays: u64,
    /// Independent fills of each (their ratios averaged).
    pub light_repeats: u32,
    /// Relative RMSE every view of the walk must reach.
    pub target: f64,
    /// How the display combines rays.
    pub estimator: EstimatorOptions,
    /// Eye radius of the fill (fraction of the smallest section diagonal).
    pub eye_radius: f64,
    /// Where references and holodeck files go.
    pub dir: PathBuf,
    /// Keep the holodeck files.
    pub keep: bool,
}

impl AccuracyBench {
    fn truth(&self, tracer: &Tracer, view: &View, name: &str) -> Result<Truth> {
        self.truth_of(&self.scene, tracer, view, name)
    }

    /// The reference of `view` of `scene`, rendered once in two halves and
    /// kept under `--dir`.
    fn truth_of(&self, scene: &str, tracer: &Tracer, view: &View, name: &str) -> Result<Truth> {
        let spp = match self.reference_time {
            Some(secs) => holodeck::truth::spp_for_time(tracer, view, (self.width, self.height), secs)?,
            None => self.reference_spp,
        };
        let key =
            blake3::hash(format!("{} {} {}x{} {}", scene, view.to_spec(), self.width, self.height, spp).as_bytes())
                .to_hex();
        let paths = ["a", "b"].map(|h| self.dir.join(format!("reference-{}-{h}.hdr", &key[..16])));
        let halves = match (read_picture(&paths[0]), read_picture(&paths[1])) {
            (Ok(a), Ok(b)) => (a, b),
            _ => {
                eprintln!(
                    "rendering the reference of {name} ({} spp in two halves, kept as {} and -b)...",
                    spp,
                    paths[0].display()
                );
                let size = (self.width, self.height);
                let halves = holodeck::truth::reference_halves(tracer, view, size, spp, 0x005e_ed0f_7e57)?;
                for (p, path) in [&halves.0, &halves.1].into_iter().zip(&paths) {
                    write_hdr(p, path).with_context(|| format!("writing {}", path.display()))?;
                }
                halves
            }
        };
        Ok(Truth::new(tracer, view, halves)?)
    }

    /// How the references are sized, in words ("1024-spp", "20 s").
    fn reference_words(&self) -> String {
        match self.reference_time {
            Some(secs) => format!("{secs} s"),
            None => format!("{}-spp", self.reference_spp),
        }
    }

    fn viewport(&self, view: &View) -> Result<Viewport> {
        Ok(Viewport::new(view.clone(), self.width, self.height)?)
    }

    /// A direct render of `paths` paths (rounded to whole samples per pixel).
    fn direct(&self, tracer: &Tracer, view: &View, paths: u64, seed: u64) -> Result<(Picture, f64, u64)> {
        Ok(holodeck::truth::direct_render(
            tracer,
            view,
            (self.width, self.height),
            paths,
            seed,
        )?)
    }

    /// A fresh holodeck of `scene` filled with `paths` rays for `view`, then
    /// its quadtree picture raw and through the default denoiser, with the
    /// seconds each took in all (fill, recall, drawing, denoising).
    fn holodeck(&self, scene: &str, tracer: &Tracer, view: &View, paths: u64, seed: u64) -> Result<Filled> {
        let path = self.dir.join(format!("accuracy-{seed}.hdk"));
        let _ = std::fs::remove_file(&path);
        let (_, mut file) = holodeck_cli::prepare::prepare(scene, &path, None, None, false, true)?;
        let start = Instant::now();
        let o = FillOptions {
            rays: Some(paths),
            time: None,
            packet: 16,
            batch: 4096,
            seed,
            views: Some(ViewFill::new(
                file.sections(),
                std::slice::from_ref(view),
                self.eye_radius,
            )),
        };
        fill(tracer, &mut file, &o, &|_| {})?;
        let choice = holodeck_cli::args::DriverChoice::plain("quadtree", self.estimator);
        let (mut driver, _) = holodeck::recall(&mut file, self.viewport(view)?, &choice, 2, seed)?;
        let raw = driver.render();
        let raw_secs = start.elapsed().as_secs_f64();
        let start = Instant::now();
        let denoised = Denoiser::Atrous(AtrousOptions::default()).apply(&raw, &driver.guide())?;
        let denoised_secs = raw_secs + start.elapsed().as_secs_f64();
        file.close()?;
        if !self.keep {
            let _ = std::fs::remove_file(&path);
        }
        Ok(Filled {
            raw,
            raw_secs,
            denoised,
            denoised_secs,
        })
    }

    /// A display session on a fresh holodeck: the view's rays requested
    /// where its pixels need them, 4 rays per pixel at a time, until
    /// `paths` rays are traced. Returns the picture, the seconds and the
    /// rays traced.
    fn session(&self, tracer: &Tracer, view: &View, paths: u64, seed: u64) -> Result<(Picture, f64, u64)> {
        let path = self.dir.join(format!("accuracy-session-{seed}.hdk"));
        let _ = std::fs::remove_file(&path);
        let (_, file) = holodeck_cli::prepare::prepare(&self.scene, &path, None, None, false, true)?;
        let start = Instant::now();
        let mut walker = Walker::new(file, self.viewport(view)?, self.estimator)?;
        let (mut rays, mut density, mut step) = (0u64, 0.0f32, 0u64);
        while rays < paths {
            density += 4.0;
            let got = walker.refine(tracer, density, self.eye_radius, seed << 20 | step)?;
            rays += got;
            step += 1;
            if got == 0 && step > 1000 {
                break;
            }
        }
        let picture = walker.driver.render();
        let secs = start.elapsed().as_secs_f64();
        walker.file.close()?;
        if !self.keep {
            let _ = std::fs::remove_file(&path);
        }
        Ok((picture, secs, rays))
    }

    /// Part 1: one view, every method against paths traced.
    fn one_view(&self, tracer: &Tracer) -> Result<()> {
        let truth = self.truth(tracer, &self.view, "the view")?;
        out!(
            "\nOne view ({}x{}, {}) against a {} reference (its own clamped relative RMSE {:.4}), mean of {} \
             run(s). Holodeck: `fill --views` then `pict` (fill), raw and denoised, and a display session that \
             asks for rays where its pixels need them (session); direct renders with the same paths, raw and \
             cleaned by OIDN with albedo and normals:",
            self.width,
            self.height,
            self.view.to_spec(),
            self.reference_words(),
            truth.yardstick.noise().map_or(f64::NAN, |n| n.clamped_relative_rmse),
            self.repeats
        );
        for &paths in &self.paths {
            let mut m: [Means; 5] = Default::default();
            let mut oidn_missing = None;
            let mut traced = 0;
            for r in 0..self.repeats {
                let seed = 1 + u64::from(r);
                let keep = |p: &Picture, what: &str| -> Result<()> {
                    if self.keep && r == 0 {
                        write_hdr(p, &self.dir.join(format!("one-view-{paths}-{what}.hdr")))?;
                    }
                    Ok(())
                };
                let (p, secs, n) = self.direct(tracer, &self.view, paths, seed)?;
                m[0].add(truth.measure(&p)?, secs);
                keep(&p, "direct")?;
                traced = n;
                match direct_oidn(tracer, &self.view, (self.width, self.height), paths, seed) {
                    Ok((p, secs)) => {
                        m[1].add(truth.measure(&p)?, secs);
                        keep(&p, "direct-oidn")?;
                    }
                    Err(e) => oidn_missing = Some(format!("{e:#}")),
                }
                let f = self.holodeck(&self.scene, tracer, &self.view, paths, seed)?;
                m[2].add(truth.measure(&f.raw)?, f.raw_secs);
                m[3].add(truth.measure(&f.denoised)?, f.denoised_secs);
                keep(&f.raw, "fill")?;
                keep(&f.denoised, "fill-atrous")?;
                let (p, secs, _) = self.session(tracer, &self.view, paths, seed)?;
                m[4].add(truth.measure(&p)?, secs);
                keep(&p, "session")?;
            }
            out!(
                "\n{} paths (direct: {} in whole samples per pixel):\n",
                count(paths),
                count(traced)
            );
            out!("{MEASURES}");
            for (means, name) in m
                .iter()
                .zip(["direct", "direct + oidn", "fill", "fill + atrous", "session"])
            {
                if means.runs.is_empty() {
                    let why = oidn_missing.as_deref().unwrap_or("not run");
                    out!("| {name} | not here: {} |||||||||||", why.lines().next().unwrap_or(why));
                } else {
                    out!("{}", means.row(name));
                }
            }
        }
        Ok(())
    }

    /// Part 2: the light kept per region by the default picture (quadtree
    /// and the default denoiser) and by the raw quadtree, on every scene of
    /// `light_scenes` at its own view, against converged references.
    fn light_kept(&self) -> Result<()> {
        let n = self.light_repeats;
        out!(
            "\nLight kept: each scene's view filled with {} rays and drawn by the quadtree (raw, and with the \
             default denoiser), against a {} reference of two halves (its regions chosen on one half and \
             measured against the other); a direct render with the same paths beside them. Each figure is \
             the mean over {n} independent fills and direct renders (other random sequences), and each \
             ratio is followed by its standard error over them: one fill's ratio in a band of a few hundred \
             pixels moves by several percent with the few bright rays that land in it, and what is asked \
             of an estimate is that its expected value keep the light. The direct render is unbiased by \
             construction: where it departs from 1, the reference (one finite render of heavy-tailed \
             paths) is short of its own expectation:\n",
            count(self.light_rays),
            self.reference_words()
        );
        out!("| scene | method | FLIP | clamped rel. RMSE | dark | middle | bright | band | peak | reference noise |");
        out!("|---|---|---|---|---|---|---|---|---|---|");
        let mut outside = Vec::new();
        for name in &self.light_scenes {
            let scene = if name.contains(':') {
                name.clone()
            } else {
                format!("builtin:{name}")
            };
            let view = View::parse(scene_view(&scene))?;
            let tracer = Tracer::new(holodeck::load(&scene, None)?, TraceOptions::default());
            let truth = self.truth_of(&scene, &tracer, &view, &scene)?;
            let noise = truth.yardstick.noise().map_or(f64::NAN, |n| n.clamped_relative_rmse);
            let mut rows: [Vec<Metrics>; 3] = Default::default();
            for seed in 1..=u64::from(n) {
                let f = self.holodeck(&scene, &tracer, &view, self.light_rays, seed)?;
                let (direct, _, _) = self.direct(&tracer, &view, self.light_rays, seed)?;
                for (row, p) in rows.iter_mut().zip([&f.raw, &f.denoised, &direct]) {
                    row.push(truth.measure(p)?);
                }
            }
            let direct = KeptOver::of(&rows[2]);
            for (method, runs) in ["quadtree", "quadtree + atrous", "direct, same paths"]
                .iter()
                .zip(&rows)
            {
                let kept = KeptOver::of(runs);
                if *method != "direct, same paths" {
                    outside.extend(
                        kept.outside(0.02, &direct)
                            .into_iter()
                            .map(|r| format!("{scene} {method} {r}")),
                    );
                }
                out!(
                    "| {scene} | {method} | {:.4} | {:.4} | {} | {} | {} | {} | {:.3} | {noise:.4} |",
                    mean(runs.iter().map(|m| m.flip)),
                    mean(runs.iter().map(|m| m.clamped_relative_rmse)),
                    kept.dark,
                    kept.middle,
                    kept.bright,
                    kept.band,
                    mean(runs.iter().map(|m| m.peak)),
                );
            }
        }
        if outside.is_empty() {
            out!("\nEvery region of the holodeck's pictures keeps its light within 2% (the mean over the fills).");
        } else {
            out!(
                "\nOutside 0.98-1.02 (the mean over the fills, and how many standard errors from the bound): {}.",
                outside.join("; ")
            );
        }
        Ok(())
    }

    /// The walk: `n` views from the single view's eye, 10 cm a step
    /// along its direction, turning 1.5 degrees a step.
    fn walk(&self, n: usize) -> Vec<View> {
        holodeck::truth::walk(&self.view, n, 0.1, 1.5)
    }

    /// Part 2: the walkthrough, time to the target error per view, over
    /// `repeats` runs with other random sequences.
    fn walkthrough(&self, tracer: &Tracer) -> Result<()> {
        let views = self.walk(self.walk_views);
        let truths: Vec<Truth> = views
            .iter()
            .enumerate()
            .map(|(i, v)| self.truth(tracer, v, &format!("walk view {}", i + 1)))
            .collect::<Result<_>>()?;
        out!(
            "\nWalkthrough of {} views (10 cm and 1.5 degrees a step), time until each is within relative RMSE {}:\n",
            views.len(),
            self.target
        );
        out!("| view | direct: paths | direct: s | holodeck: new rays | holodeck: s | error direct / holodeck |");
        out!("|---|---|---|---|---|---|");
        let (mut direct, mut holodeck) = (0.0, 0.0);
        for run in 0..self.repeats.max(1) {
            let (d, h) = self.walk_once(tracer, &views, &truths, u64::from(run), run == 0)?;
            direct += d;
            holodeck += h;
        }
        out!(
            "\nAll runs: direct {direct:.2} s, holodeck {holodeck:.2} s: the holodeck {:.2}x faster.",
            direct / holodeck.max(1e-9)
        );
        Ok(())
    }

    /// One walk; returns the seconds of the direct renders and of the
    /// holodeck, printing each view's row when `rows`.
    fn walk_once(&self, tracer: &Tracer, views: &[View], truths: &[Truth], run: u64, rows: bool) -> Result<(f64, f64)> {
        let pixels = u64::from(self.width) * u64::from(self.height);
        // Both methods add work in steps of 4 paths per pixel.
        let step_spp = 4u32;
        let max_steps = 64u32;
        let path = self.dir.join("accuracy-walk.hdk");
        let _ = std::fs::remove_file(&path);
        let (_, file) = holodeck_cli::prepare::prepare(&self.scene, &path, None, None, false, true)?;
        let mut walker = Walker::new(file, self.viewport(&views[0])?, self.estimator)?;
        let (mut direct_total, mut holo_total) = (0.0, 0.0);
        let (mut direct_paths, mut holo_rays) = (0u64, 0u64);
        for (i, (view, truth)) in views.iter().zip(truths).enumerate() {
            let seed = (run << 40) | ((i as u64) << 20);
            // Direct: passes of `step_spp` until the target is met.
            let o = RenderOptions {
                width: self.width,
                height: self.height,
                spp: step_spp,
                seed: 0,
            };
            let (mut sum, mut secs, mut passes, mut d_err) = (None::<Picture>, 0.0, 0u32, f64::INFINITY);
            while passes < max_steps {
                let start = Instant::now();
                let p = render(
                    tracer,
                    view,
                    &RenderOptions {
                        seed: seed | u64::from(passes),
                        ..o.clone()
                    },
                    &|_, _| {},
                )?;
                let acc = match sum.take() {
                    None => p,
                    Some(mut s) => {
                        for (a, b) in s.pixels.iter_mut().zip(&p.pixels) {
                            *a += *b;
                        }
                        s
                    }
                };
                passes += 1;
                let mean = Picture {
                    pixels: acc.pixels.iter().map(|c| *c / passes as f32).collect(),
                    ..acc.clone()
                };
                secs += start.elapsed().as_secs_f64();
                sum = Some(acc);
                d_err = truth.rmse(&mean)?;
                if d_err <= self.target {
                    break;
                }
            }
            let d_paths = u64::from(passes * step_spp) * pixels;
            // Holodeck: what is there already, then more rays where this
            // view's pixels need them.
            let start = Instant::now();
            walker.set_view(self.viewport(view)?)?;
            let mut h_secs = start.elapsed().as_secs_f64();
            let (mut rays, mut h_err, mut density) = (0u64, f64::INFINITY, 0.0f32);
            for step in 0..=max_steps {
                let start = Instant::now();
                let p = walker.driver.render();
                h_secs += start.elapsed().as_secs_f64();
                h_err = truth.rmse(&p)?;
                if h_err <= self.target || step == max_steps {
                    if self.keep && rows {
                        write_hdr(&p, &self.dir.join(format!("walk-{:02}-holodeck.hdr", i + 1)))?;
                        write_hdr(
                            &truth.picture,
                            &self.dir.join(format!("walk-{:02}-reference.hdr", i + 1)),
                        )?;
                    }
                    break;
                }
                let start = Instant::now();
                density += step_spp as f32;
                rays += walker.refine(tracer, density, self.eye_radius, seed | u64::from(step))?;
                h_secs += start.elapsed().as_secs_f64();
            }
            if rows {
                out!(
                    "| {} | {} | {:.2} | {} | {:.2} | {:.3} / {:.3} |",
                    i + 1,
                    count(d_paths),
                    secs,
                    count(rays),
                    h_secs,
                    d_err,
                    h_err
                );
            }
            direct_total += secs;
            holo_total += h_secs;
            direct_paths += d_paths;
            holo_rays += rays;
        }
        out!(
            "| all (run {}) | {} | {:.2} | {} | {:.2} | holodeck {:.2}x faster |",
            run + 1,
            count(direct_paths),
            direct_total,
            count(holo_rays),
            holo_total,
            direct_total / holo_total.max(1e-9)
        );
        walker.file.close()?;
        if !self.keep {
            let _ = std::fs::remove_file(&path);
        }
        Ok((direct_total, holo_total))
    }

    /// Runs both parts.
    pub fn run(&self) -> Result<()> {
        std::fs::create_dir_all(&self.dir).with_context(|| format!("creating {}", self.dir.display()))?;
        let scene = holodeck::load(&self.scene, None)?;
        let tracer = Tracer::new(scene, TraceOptions::default());
        if !self.paths.is_empty() {
            self.one_view(&tracer)?;
        }
        if !self.light_scenes.is_empty() {
            self.light_kept()?;
        }
        if self.walk_views > 0 {
            self.walkthrough(&tracer)?;
        }
        Ok(())
    }
}

/// A holodeck filled for one view and drawn: raw and denoised.
struct Filled {
    raw: Picture,
    raw_secs: f64,
    denoised: Picture,
    denoised_secs: f64,
}

/// The view each built-in scene of the light-kept part is measured at (the
/// room and the room with terrain: out of the window).
fn scene_view(scene: &str) -> &'static str {
    use holodeck_sampler::scene::gen::{arcade::ARCADE_VIEW, blind::BLIND_VIEW};
    match scene {
        "builtin:arcade" => ARCADE_VIEW,
        "builtin:blind" => BLIND_VIEW,
        _ => holodeck::ROOM_VIEW,
    }
}

/// Means of every measure over repeated runs of one method.
#[derive(Default)]
struct Means {
    runs: Vec<holodeck_display::compare::Metrics>,
    secs: f64,
}

impl Means {
    fn add(&mut self, m: holodeck_display::compare::Metrics, secs: f64) {
        self.runs.push(m);
        self.secs += secs;
    }

    fn mean(&self, f: impl Fn(&holodeck_display::compare::Metrics) -> f64) -> f64 {
        let v: Vec<f64> = self.runs.iter().map(f).filter(|x| !x.is_nan()).collect();
        if v.is_empty() {
            f64::NAN
        } else {
            v.iter().sum::<f64>() / v.len() as f64
        }
    }

    /// A table row: the method, then every measure.
    fn row(&self, method: &str) -> String {
        let n = self.runs.len().max(1) as f64;
        format!(
            "| {method} | {:.4} | {:.4} | {:.3} | {:.4} | {:.5} | {:.4} | {:.3} | {:.3} | {:.3} | {:.3} | {:.2} |",
            self.mean(|m| m.flip),
            self.mean(|m| m.hdr_flip),
            self.mean(|m| m.ssim),
            self.mean(|m| m.clamped_relative_rmse),
            self.mean(|m| m.clamped_relative_mse),
            self.mean(|m| m.relative_rmse),
            self.mean(|m| m.light.dark),
            self.mean(|m| m.light.middle),
            self.mean(|m| m.light.bright),
            self.mean(|m| m.light.band.unwrap_or(f64::NAN)),
            self.secs / n
        )
    }
}

/// The header of [`Means::row`] tables.
const MEASURES: &str = "| method | FLIP | HDR-FLIP | SSIM | clamped rel. RMSE | clamped rel. MSE | rel. RMSE | dark | middle | bright | band | s |\n|---|---|---|---|---|---|---|---|---|---|---|---|";

/// A direct render of `paths` paths cleaned by OIDN with its albedo and
/// normals, and the seconds in all; an error without OIDN in the build.
fn direct_oidn(tracer: &Tracer, view: &View, size: (u32, u32), paths: u64, seed: u64) -> Result<(Picture, f64)> {
    let start = Instant::now();
    let (noisy, _, _) = holodeck::truth::direct_render(tracer, view, size, paths, seed)?;
    let o = RenderOptions {
        width: size.0,
        height: size.1,
        spp: 4,
        seed,
    };
    let (albedo, normal) = holodeck_sampler::render::render_aovs(tracer, view, &o)?;
    let p = holodeck::truth::denoise_oidn(&noisy, &albedo, &normal)?;
    Ok((p, start.elapsed().as_secs_f64()))
}

/// A display walking through views with a holodeck beside it, as an
/// interactive session does: its driver keeps every pixel estimate across
/// views, and it is given each stored ray once.
struct Walker {
    file: HoloFile,
    decoder: SampleDecoder,
    driver: Box<dyn Driver>,
    /// Rays of each beam given to the driver so far.
    fed: HashMap<BeamKey, usize>,
}

impl Walker {
    fn new(file: HoloFile, viewport: Viewport, estimator: EstimatorOptions) -> Result<Walker> {
        Ok(Walker {
            decoder: SampleDecoder::new(file.sections().to_vec()),
            driver: new_driver_with("quadtree", viewport, estimator)?,
            file,
            fed: HashMap::new(),
        })
    }

    /// Moves to a view and takes the stored rays of its beams not taken yet.
    fn set_view(&mut self, viewport: Viewport) -> Result<()> {
        let drops = self.driver.stats().cache_drops;
        self.driver.set_view(viewport);
        if self.driver.stats().cache_drops > drops {
            self.fed.clear();
        }
        self.feed()
    }

    fn feed(&mut self) -> Result<()> {
        let request = BeamRequest::for_viewport(
            self.decoder.sections(),
            self.driver.viewport(),
            &RequestOptions {
                stride: 2,
                ..RequestOptions::default()
            },
            0,
        );
        let mut keys: Vec<BeamKey> = request.beams.iter().map(|b| b.0).collect();
        keys.sort_unstable();
        let (decoder, driver, fed) = (&self.decoder, &mut self.driver, &mut self.fed);
        let mut samples = Vec::new();
        self.file.read_beams(&keys, |k, rays| {
            let done = fed.entry(k).or_insert(0);
            if rays.len() > *done {
                decoder.decode(k.section, k.beam, &rays[*done..], &mut samples);
                *done = rays.len();
            }
        })?;
        driver.add(&samples);
        Ok(())
    }

    /// Asks for rays as a display refining its view does (each pixel wants
    /// its share of `density` rays per pixel, by how much its rays
    /// disagree, less what it holds), traces what the holodeck lacks near
    /// the eye, stores it and takes it. Returns the rays traced.
    fn refine(&mut self, tracer: &Tracer, density: f32, eye_radius: f64, seed: u64) -> Result<u64> {
        let sections = self.decoder.sections().to_vec();
        let viewport = self.driver.viewport().clone();
        let want = self.driver.needs(density);
        let o = RequestOptions {
            stride: 2,
            eye_radius,
            ..RequestOptions::default()
        };
        let fed = &self.fed;
        let request = BeamRequest::refining(&sections, &viewport, &o, seed, &want, &|k| {
            fed.get(&k).copied().unwrap_or(0) as u64
        });
        let mut batch = Vec::new();
        for &(k, desired) in &request.beams {
            let stored = self.file.beam_len(k)?;
            if u64::from(desired) > stored {
                batch.push((k, (u64::from(desired) - stored) as u32));
            }
        }
        let mode = match request.eye {
            Some(e) => SamplingMode::NearEye {
                eye: e.position,
                radius: e.radius,
                frustum: e.frustum,
            },
            None => SamplingMode::Uniform,
        };
        let rules = holodeck_sampler::beam::FileRules {
            obstructions: self.file.settings().obstructions,
            vdistance: self.file.settings().vdistance,
        };
        let traced = trace_batch(tracer, &sections, rules, &batch, &|_| mode, seed);
        let mut rays = 0u64;
        let mut samples = Vec::new();
        for (k, records) in &traced {
            // Rays of a beam not taken yet would come before these in the
            // file: take them in order, then the new ones straight away.
            if self.fed.get(k).copied().unwrap_or(0) as u64 == self.file.beam_len(*k)? {
                self.decoder.decode(k.section, k.beam, records, &mut samples);
                *self.fed.entry(*k).or_insert(0) += records.len();
            }
            self.file.append(*k, records)?;
            rays += records.len() as u64;
        }
        self.driver.add(&samples);
        Ok(rays)
    }
}

/// The fast version for `bench all`: the room's view at 96 x 72, a fill of
/// 250,000 rays for it drawn by the quadtree and the default denoiser,
/// beside a direct render with the same paths, both measured by FLIP
/// against a 256-spp reference kept in the folder.
pub fn fast(ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    let bench = AccuracyBench {
        scene: "builtin:room".into(),
        view: View::parse(holodeck::ROOM_VIEW)?,
        width: 96,
        height: 72,
        paths: vec![250_000],
        reference_spp: 256,
        reference_time: None,
        repeats: 1,
        walk_views: 0,
        light_scenes: Vec::new(),
        light_rays: 0,
        light_repeats: 1,
        target: 0.2,
        estimator: Default::default(),
        eye_radius: holodeck_display::request::RequestOptions::default().eye_radius,
        dir: ctx.dir.clone(),
        keep: false,
    };
    std::fs::create_dir_all(&bench.dir).with_context(|| format!("creating {}", bench.dir.display()))?;
    let scene = holodeck::load(&bench.scene, None)?;
    let tracer = Tracer::new(scene, TraceOptions::default());
    let truth = bench.truth(&tracer, &bench.view, "the room's view")?;
    let (mut holodeck, mut direct, mut h_secs, mut d_secs) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for r in 0..ctx.repeats {
        let seed = 1 + r as u64;
        let (p, secs, _) = bench.direct(&tracer, &bench.view, 250_000, seed)?;
        direct.push(truth.measure(&p)?.flip);
        d_secs.push(secs);
        let f = bench.holodeck(&bench.scene, &tracer, &bench.view, 250_000, seed)?;
        holodeck.push(truth.measure(&f.denoised)?.flip);
        h_secs.push(f.denoised_secs);
    }
    Ok(vec![
        Figure::new(
            "accuracy",
            "room view, 250K paths: holodeck (fill, quadtree + atrous) error",
            "FLIP",
            false,
            holodeck,
        )
        .against("direct render, same paths", direct),
        Figure::new(
            "accuracy",
            "room view, 250K paths: holodeck time (fill, picture, denoiser)",
            "s",
            false,
            h_secs,
        )
        .against("direct render, same paths", d_secs),
    ])
}
