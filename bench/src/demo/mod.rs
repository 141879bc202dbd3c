//! `holodeck demo`: the whole system on the built-in room (with textured
//! things in it) and scenery outside its window, in one command. It fills a holodeck for a walk
//! through the room and out across the terrain, draws every view with every
//! display driver (on its own and denoised), renders each view directly as
//! its reference and as what a user would otherwise do (a direct render in
//! the same time, on its own and cleaned by Open Image Denoise), and writes
//! what a user needs to judge the result: frames, a comparison sheet per
//! view, charts of error against paths and time and along the walk, and a
//! summary table of every measure per method.
//!
//! Every number is measured here, in this run, against references whose own
//! noise is stated beside them. The stages (the walk, the ways of drawing a
//! view) are the library's (`holodeck::demo`); this module runs them in
//! order and writes what they give.
//!
//! * `report` — the sheets, charts, summary table and JSON of a run.
//! * `sheet` — a comparison sheet of pictures side by side.

mod report;
mod sheet;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_display::tonemap::ToneMap;
use holodeck_display::Viewport;
use holodeck_protocol::{Picture, View};
use holodeck_sampler::TraceOptions;

pub use holodeck::demo::methods::DRIVERS;
use holodeck::demo::methods::{self, Column, Kind, Shot};
use holodeck::demo::walk;
use holodeck::fill::{fill, FillOptions, ViewFill};
use holodeck::truth::Truth;
use holodeck_cli::human::count;

/// What the demo does and where it writes.
#[derive(Clone, Debug)]
pub struct Demo {
    /// The output folder.
    pub out: PathBuf,
    /// Triangles of the scenery outside the window (terrain and forest).
    pub triangles: u64,
    /// Rays traced into the holodeck.
    pub rays: u64,
    /// Views of the walk.
    pub views: usize,
    /// Frame width.
    pub width: u32,
    /// Frame height.
    pub height: u32,
    /// Samples per pixel of the reference renders (two halves of half each).
    pub reference_spp: u32,
    /// Seconds all the references may take together, where given: it
    /// sets `reference_spp` when the demo runs.
    pub reference_time: Option<f64>,
    /// Seed of the fill.
    pub seed: u64,
}

/// The scene: the furnished room with its textured rug, painting, brick
/// wall and alpha-masked plant, and terrain and a forest outside its window.
pub const SCENE: &str = "builtin:gallery";

/// A point of the convergence chart: paths (holodeck rays or direct
/// samples), seconds, FLIP.
pub type Point = (f64, f64, f64);

/// What the fill and the first view's convergence measured.
pub struct Fill {
    /// Rays in the file.
    pub rays: u64,
    /// Seconds tracing and storing them.
    pub secs: f64,
    /// Per method of the convergence chart (its name): the first view's
    /// FLIP after each stage of the fill, or after the same paths traced
    /// directly.
    pub convergence: Vec<(String, Vec<Point>)>,
}

impl Demo {
    /// The walk (see [`walk::path`]).
    pub fn walk(&self) -> Vec<View> {
        walk::path(self.views)
    }

    fn viewport(&self, view: &View) -> Result<Viewport> {
        Ok(Viewport::new(view.clone(), self.width, self.height)?)
    }

    fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Removes what an earlier demo wrote into the output folder (its own
    /// file names only), so that no stale frame or sheet is left beside
    /// this run's.
    fn clear_earlier_run(&self, frames: &Path) -> Result<()> {
        if frames.is_dir() {
            std::fs::remove_dir_all(frames).with_context(|| format!("removing {}", frames.display()))?;
        }
        let Ok(entries) = std::fs::read_dir(&self.out) else {
            return Ok(());
        };
        for entry in entries.flatten() {
            let name = entry.file_name().to_string_lossy().into_owned();
            let ours = (name.starts_with("compare-view") && name.ends_with(".png"))
                || name.starts_with("chart-")
                || [
                    "demo.hdk",
                    "demo.hdk.token",
                    "demo.hdk.writer.token",
                    "demo.hdk.viewer.token",
                    "summary.md",
                    "summary.json",
                    "walk.vf",
                ]
                .contains(&name.as_str());
            if ours {
                let path = entry.path();
                std::fs::remove_file(&path).with_context(|| format!("removing {}", path.display()))?;
            }
        }
        Ok(())
    }

    /// Runs the demo; returns the summary it printed.
    pub fn run(&mut self) -> Result<String> {
        let start = Instant::now();
        let frames = self.out.join("frames");
        self.clear_earlier_run(&frames)?;
        std::fs::create_dir_all(&frames).with_context(|| format!("creating {}", frames.display()))?;
        let views = self.walk();
        let walk_file = self.out.join("walk.vf");
        let walk_text: String = views.iter().map(|v| v.to_spec() + "\n").collect();
        std::fs::write(&walk_file, walk_text).with_context(|| format!("writing {}", walk_file.display()))?;

        eprintln!(
            "holodeck demo: the furnished room (a textured rug, painting, brick wall and plant) with {} triangles of terrain and forest outside its window, a walk of {} views",
            count(self.triangles),
            views.len()
        );
        let hdk = self.out.join("demo.hdk");
        // Virtual distances: the walk looks out of the window, and what a
        // window shows must move with the eye as the view beyond it does.
        let (input, mut file) = holodeck_cli::prepare::prepare(SCENE, &hdk, Some(self.triangles), None, false, true)?;
        let tracer = input.tracer(TraceOptions::default());

        // References first: every picture below is measured against them.
        let truths = self.references(&tracer, &views)?;
        let reference_secs = start.elapsed().as_secs_f64();

        let kinds = methods::methods();
        let filled = self.fill(&tracer, &mut file, &views, &truths[0], &kinds)?;
        let mut columns = self.draw_walk(&tracer, &mut file, &views, &truths, &kinds)?;
        file.close()?;

        // Each view traced directly from scratch in its share of the
        // holodeck's time (the fill and every frame of the default method).
        let default = kinds
            .iter()
            .position(|&k| k == methods::default_method())
            .context("the default method is measured")?;
        let holodeck_secs = filled.secs + columns[default].secs();
        let share = holodeck_secs / views.len() as f64;
        self.direct_walk(&tracer, &views, &truths, &kinds, share, &mut columns)?;

        let run = report::Run {
            demo: self,
            hdk: &hdk,
            filled: &filled,
            holodeck_secs,
            reference_secs,
            truths: &truths,
            frames: &frames,
            total_secs: 0.0,
        };
        self.write_results(run, start, &columns)
    }

    /// The converged reference of every view of the walk.
    fn references(&mut self, tracer: &holodeck_sampler::Tracer, views: &[View]) -> Result<Vec<Truth>> {
        let bar = holodeck_cli::progress::Progress::counting(
            "rendering the reference views",
            holodeck_cli::progress::Unit::Views,
            Some(views.len() as u64),
        );
        if let (Some(secs), Some(first)) = (self.reference_time, views.first()) {
            let each = secs / views.len() as f64;
            self.reference_spp = holodeck::truth::spp_for_time(tracer, first, self.size(), each)?;
        }
        let mut truths = Vec::with_capacity(views.len());
        for (i, v) in views.iter().enumerate() {
            let seed = 0x005e_ed0f_7e57 + 2 * i as u64;
            let halves = holodeck::truth::reference_halves(tracer, v, self.size(), self.reference_spp, seed)?;
            truths.push(Truth::new(tracer, v, halves)?);
            bar.inc(1);
        }
        bar.finish();
        Ok(truths)
    }

    /// Every view drawn by every holodeck method; a driver that fails is
    /// not asked again, its columns saying why.
    fn draw_walk(
        &self,
        tracer: &holodeck_sampler::Tracer,
        file: &mut holodeck_file::HoloFile,
        views: &[View],
        truths: &[Truth],
        kinds: &[Kind],
    ) -> Result<Vec<Column>> {
        let mut columns: Vec<Column> = kinds.iter().map(|&k| Column::new(k)).collect();
        let bar = holodeck_cli::progress::Progress::counting(
            "drawing every view from the holodeck",
            holodeck_cli::progress::Unit::Views,
            Some(views.len() as u64),
        );
        for (i, (view, truth)) in views.iter().zip(truths).enumerate() {
            for driver in DRIVERS {
                let mine: Vec<usize> = (0..kinds.len())
                    .filter(|&k| matches!(kinds[k], Kind::Holodeck { driver: d, .. } if d == driver))
                    .collect();
                if mine.iter().all(|&k| columns[k].failed.is_some()) {
                    continue;
                }
                match methods::draw_holodeck(
                    file,
                    self.viewport(view)?,
                    driver,
                    kinds,
                    truth,
                    self.seed,
                    Some(tracer),
                ) {
                    Ok(shots) => {
                        for (k, shot) in shots {
                            columns[k].shots.resize_with(i, || None);
                            columns[k].shots.push(Some(shot));
                        }
                    }
                    Err(e) => {
                        for &k in &mine {
                            columns[k].failed = Some(format!("{e:#}"));
                        }
                    }
                }
            }
            bar.inc(1);
        }
        bar.finish();
        for c in &mut columns {
            c.shots.resize_with(views.len(), || None);
        }
        Ok(columns)
    }

    /// Each view traced directly in `share` seconds, raw and cleaned by
    /// OIDN, into the direct methods' columns.
    fn direct_walk(
        &self,
        tracer: &holodeck_sampler::Tracer,
        views: &[View],
        truths: &[Truth],
        kinds: &[Kind],
        share: f64,
        columns: &mut [Column],
    ) -> Result<()> {
        let bar = holodeck_cli::progress::Progress::counting(
            "rendering each view directly in the same time",
            holodeck_cli::progress::Unit::Views,
            Some(views.len() as u64),
        );
        let mut overhead = 0.0;
        for (i, (view, truth)) in views.iter().zip(truths).enumerate() {
            for (k, kind) in kinds.iter().enumerate() {
                let Kind::Direct { oidn } = kind else { continue };
                if columns[k].failed.is_some() {
                    continue;
                }
                let seed = 1000 + i as u64;
                let shot = if *oidn {
                    methods::direct_oidn_for(tracer, view, self.size(), share, seed, &mut overhead)
                } else {
                    methods::direct_for(tracer, view, self.size(), share, seed)
                };
                match shot {
                    Ok((picture, secs, paths)) => {
                        columns[k].shots[i] = Some(Shot {
                            metrics: truth.measure(&picture)?,
                            picture,
                            secs,
                            samples: paths,
                        })
                    }
                    Err(e) => columns[k].failed = Some(format!("{e:#}")),
                }
            }
            bar.inc(1);
        }
        bar.finish();
        Ok(())
    }

    /// Frames, sheets, charts, the summary (Markdown, returned) and its JSON.
    fn write_results(&self, mut run: report::Run<'_>, start: Instant, columns: &[Column]) -> Result<String> {
        let (frames, truths, filled) = (run.frames, run.truths, run.filled);
        // Frames and sheets.
        for (i, truth) in truths.iter().enumerate() {
            let name = |what: &str| frames.join(format!("view{:02}-{what}.png", i + 1));
            save(&truth.picture, &truth.tone, &name("reference"))?;
            for c in columns {
                if let Some(s) = &c.shots[i] {
                    save(&s.picture, &truth.tone, &name(&c.kind.file_name()))?;
                }
            }
            report::sheet(&self.out, i, truth, columns, self.reference_spp)?;
        }
        report::charts(&self.out, filled, columns, truths.len())?;
        run.total_secs = start.elapsed().as_secs_f64();
        let summary = report::summary(&run, columns);
        let path = self.out.join("summary.md");
        std::fs::write(&path, &summary).with_context(|| format!("writing {}", path.display()))?;
        let json = report::json(columns, truths, run.holodeck_secs, filled);
        let path = self.out.join("summary.json");
        std::fs::write(&path, serde_json::to_string_pretty(&json)?)
            .with_context(|| format!("writing {}", path.display()))?;
        Ok(summary)
    }

    /// Fills the holodeck for the walk in stages; after each, the first
    /// view is drawn by the default method and by every driver raw (the
    /// convergence chart), and traced directly with the same paths.
    fn fill(
        &self,
        tracer: &holodeck_sampler::Tracer,
        file: &mut holodeck_file::HoloFile,
        views: &[View],
        first: &Truth,
        kinds: &[Kind],
    ) -> Result<Fill> {
        let eye_radius = holodeck_display::request::RequestOptions::default().eye_radius;
        let mut o = FillOptions {
            rays: None,
            time: None,
            packet: 16,
            batch: 4096,
            seed: self.seed,
            views: Some(ViewFill::new(file.sections(), views, eye_radius)),
        };
        let stages = [self.rays / 16, self.rays / 4, self.rays];
        let bar = holodeck_cli::progress::Progress::counting(
            "filling the holodeck for the walk",
            holodeck_cli::progress::Unit::Rays,
            Some(self.rays),
        );
        let (mut secs, mut filled) = (0.0, 0u64);
        let charted: Vec<Kind> = kinds
            .iter()
            .copied()
            .filter(|k| matches!(k, Kind::Holodeck { .. }))
            .filter(|k| {
                *k == methods::default_method()
                    || matches!(
                        k,
                        Kind::Holodeck {
                            denoise: holodeck_display::denoise::Denoiser::Off,
                            ..
                        }
                    )
            })
            .collect();
        let mut convergence: Vec<(String, Vec<Point>)> = charted.iter().map(|k| (k.name(), Vec::new())).collect();
        let mut failed = vec![false; charted.len()];
        for (k, &stage) in stages.iter().enumerate() {
            o.rays = Some(stage.saturating_sub(filled).max(1));
            o.seed = self.seed + k as u64;
            let base = filled;
            let report = fill(tracer, file, &o, &|n| bar.set(base + n))?;
            filled += report.rays;
            secs += report.secs;
            for driver in DRIVERS {
                let mine: Vec<usize> = (0..charted.len())
                    .filter(|&c| matches!(charted[c], Kind::Holodeck { driver: d, .. } if d == driver))
                    .collect();
                if mine.iter().all(|&c| failed[c]) {
                    continue;
                }
                match methods::draw_holodeck(
                    file,
                    self.viewport(&views[0])?,
                    driver,
                    &charted,
                    first,
                    self.seed,
                    Some(tracer),
                ) {
                    Ok(shots) => {
                        for (c, shot) in shots {
                            convergence[c]
                                .1
                                .push((filled as f64, secs + shot.secs, shot.metrics.flip));
                        }
                    }
                    Err(_) => mine.iter().for_each(|&c| failed[c] = true),
                }
            }
        }
        bar.finish();
        // Direct renders of the first view with the paths of each stage, on
        // their own and cleaned by OIDN.
        let mut direct = Vec::new();
        let mut cleaned = Vec::new();
        for (k, &stage) in stages.iter().enumerate() {
            let (p, t, paths) = holodeck::truth::direct_render(tracer, &views[0], self.size(), stage, 77 + k as u64)?;
            direct.push((paths as f64, t, first.measure(&p)?.flip));
            let start = Instant::now();
            let o = holodeck_sampler::render::RenderOptions {
                width: self.width,
                height: self.height,
                spp: 4,
                seed: 77,
            };
            let (albedo, normal) = holodeck_sampler::render::render_aovs(tracer, &views[0], &o)?;
            if let Ok(q) = holodeck::truth::denoise_oidn(&p, &albedo, &normal) {
                cleaned.push((paths as f64, t + start.elapsed().as_secs_f64(), first.measure(&q)?.flip));
            }
        }
        convergence.push(("direct".into(), direct));
        if !cleaned.is_empty() {
            convergence.push(("direct + oidn".into(), cleaned));
        }
        Ok(Fill {
            rays: filled,
            secs,
            convergence,
        })
    }
}

/// Writes `p` tone mapped by `tone` as the PNG `path`, and in linear
/// radiance beside it as .hdr (for `holodeck compare`).
fn save(p: &Picture, tone: &ToneMap, path: &Path) -> Result<()> {
    holodeck_display::image_io::write_rgb8(path, p.width, p.height, &tone.apply(p))
        .with_context(|| format!("writing {}", path.display()))?;
    let hdr = path.with_extension("hdr");
    holodeck_display::image_io::write_hdr(p, &hdr).with_context(|| format!("writing {}", hdr.display()))
}
