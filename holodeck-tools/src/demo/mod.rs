//! `holodeck demo`: the whole system on the built-in room with scenery
//! outside its window, in one command. It fills a holodeck for a scripted
//! walk, draws every view with every display driver, renders each view
//! directly as the reference, and writes what a user needs to judge the
//! result: frames, a comparison sheet per view with each picture's error,
//! charts of error against paths and time, and a summary table.
//!
//! Every number is measured here, in this run: the holodeck's pictures
//! against converged direct renders, and against direct renders given the
//! same paths (the first view, as the holodeck fills) and the same time
//! (every view of the walk).

mod sheet;

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_display::tonemap::ToneMap;
use holodeck_display::{EstimatorOptions, Viewport};
use holodeck_protocol::{Picture, View};
use holodeck_sampler::render::{render, RenderOptions};
use holodeck_sampler::{TraceOptions, Tracer};

use crate::chart::{Panel, Series, SeriesLabelPosition};
use crate::cmd::args::DriverChoice;
use crate::fill::{fill, FillOptions, ViewFill};
use crate::human::count;
use crate::truth::{Error, Truth};

/// The display drivers shown, in the order of the sheets.
pub const DRIVERS: [&str; 3] = ["quadtree", "voronoi", "mesh"];

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
    /// Samples per pixel of the reference renders.
    pub reference_spp: u32,
    /// Seed of the fill.
    pub seed: u64,
}

/// The scene: the furnished room, with terrain and a forest outside its window.
pub const SCENE: &str = "builtin:landscape";

/// The first view of the walk: from inside the room, out of its window.
pub const FIRST_VIEW: &str = "-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56";

/// One driver's picture of one view, and what it took.
struct Drawn {
    picture: Picture,
    error: Error,
    /// Samples read from the file and given to the driver.
    samples: u64,
    /// Seconds reading, decoding and inserting them, and drawing.
    recall_secs: f64,
    draw_secs: f64,
}

/// A driver's totals over the walk.
#[derive(Default)]
struct Totals {
    error: f64,
    band: f64,
    ssim: f64,
    samples: u64,
    recall_secs: f64,
    draw_secs: f64,
    views: usize,
    /// Why the driver could not draw here, if it could not.
    failed: Option<String>,
}

/// A point of the convergence chart: paths (holodeck rays or direct
/// samples), seconds, error.
type Point = (f64, f64, f64);

impl Demo {
    /// The walk: from the first view, 12 cm a step along the view's
    /// direction, turning 3 degrees a step.
    pub fn walk(&self) -> Result<Vec<View>> {
        Ok(crate::truth::walk(
            &View::parse(FIRST_VIEW)?,
            self.views.max(1),
            0.12,
            3.0,
        ))
    }

    fn viewport(&self, view: &View) -> Result<Viewport> {
        Ok(Viewport::new(view.clone(), self.width, self.height)?)
    }

    /// Draws `view` from the file with `driver`.
    fn draw(&self, file: &mut holodeck_server::HoloFile, view: &View, driver: &str, truth: &Truth) -> Result<Drawn> {
        let choice = DriverChoice::plain(driver, EstimatorOptions::default());
        let (picture, _, stats) = crate::cmd::pict::draw(file, self.viewport(view)?, &choice, 2, self.seed)?;
        Ok(Drawn {
            error: truth.error(&picture)?,
            picture,
            samples: stats.samples,
            recall_secs: stats.recall.as_secs_f64(),
            draw_secs: stats.render.as_secs_f64(),
        })
    }

    /// A direct render of `view` in passes of one sample per pixel until
    /// `secs` have passed (at least one pass): the mean picture, the
    /// seconds taken and the paths traced.
    fn direct_for(&self, tracer: &Tracer, view: &View, secs: f64, seed: u64) -> Result<(Picture, f64, u64)> {
        let start = Instant::now();
        let mut sum: Option<Picture> = None;
        let mut passes = 0u64;
        while passes == 0 || start.elapsed().as_secs_f64() < secs {
            let o = RenderOptions {
                width: self.width,
                height: self.height,
                spp: 1,
                seed: seed << 20 | passes,
            };
            let p = render(tracer, view, &o, &|_, _| {})?;
            match &mut sum {
                None => sum = Some(p),
                Some(acc) => acc.pixels.iter_mut().zip(&p.pixels).for_each(|(a, b)| *a += *b),
            }
            passes += 1;
        }
        let mut picture = sum.context("no pass rendered")?;
        picture.pixels.iter_mut().for_each(|p| *p /= passes as f32);
        let paths = passes * u64::from(self.width) * u64::from(self.height);
        Ok((picture, start.elapsed().as_secs_f64(), paths))
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
    pub fn run(&self) -> Result<String> {
        let start = Instant::now();
        let frames = self.out.join("frames");
        self.clear_earlier_run(&frames)?;
        std::fs::create_dir_all(&frames).with_context(|| format!("creating {}", frames.display()))?;
        let views = self.walk()?;
        let walk_file = self.out.join("walk.vf");
        let walk_text: String = views.iter().map(|v| v.to_spec() + "\n").collect();
        std::fs::write(&walk_file, walk_text).with_context(|| format!("writing {}", walk_file.display()))?;

        eprintln!(
            "holodeck demo: the furnished room with {} triangles of terrain and forest outside its window",
            count(self.triangles)
        );
        let hdk = self.out.join("demo.hdk");
        let (input, mut file) = crate::cmd::fill::prepare(SCENE, &hdk, Some(self.triangles), None, false)?;
        let tracer = input.tracer(TraceOptions::default());

        // References first: every picture below is measured against them.
        let bar = crate::progress::count_bar("rendering the reference views", views.len() as u64);
        let mut truths = Vec::with_capacity(views.len());
        for (i, v) in views.iter().enumerate() {
            let size = (self.width, self.height);
            let seed = 0x005e_ed0f_7e57 + 2 * i as u64;
            let halves = crate::truth::reference_halves(&tracer, v, size, self.reference_spp, seed)?;
            truths.push(Truth::new(&tracer, v, halves)?);
            bar.inc(1);
        }
        bar.finish_and_clear();
        let reference_secs = start.elapsed().as_secs_f64();

        // The holodeck, filled for the walk in stages; after each, the
        // first view is drawn by every driver (the convergence chart).
        let eye_radius = holodeck_display::request::RequestOptions::default().eye_radius;
        let mut o = FillOptions {
            rays: None,
            time: None,
            packet: 16,
            batch: 4096,
            seed: self.seed,
            views: Some(ViewFill::new(file.sections(), &views, eye_radius)),
        };
        let stages = [self.rays / 16, self.rays / 4, self.rays];
        let bar = crate::progress::rays_bar("filling the holodeck for the walk");
        bar.set_length(self.rays);
        let mut fill_secs = 0.0;
        let mut filled = 0u64;
        let mut convergence: Vec<Vec<Point>> = vec![Vec::new(); DRIVERS.len()];
        let mut failures: Vec<Option<String>> = vec![None; DRIVERS.len()];
        // The last stage's pictures of the first view are also the walk's first frames.
        let mut first_frames: Vec<Option<Drawn>> = (0..DRIVERS.len()).map(|_| None).collect();
        for (k, &stage) in stages.iter().enumerate() {
            o.rays = Some(stage.saturating_sub(filled).max(1));
            o.seed = self.seed + k as u64;
            let base = filled;
            let report = fill(&tracer, &mut file, &o, &|n| bar.set_position(base + n))?;
            filled += report.rays;
            fill_secs += report.secs;
            for (d, driver) in DRIVERS.iter().enumerate() {
                if failures[d].is_some() {
                    continue;
                }
                match self.draw(&mut file, &views[0], driver, &truths[0]) {
                    Ok(drawn) => {
                        convergence[d].push((
                            filled as f64,
                            fill_secs + drawn.recall_secs + drawn.draw_secs,
                            drawn.error.all,
                        ));
                        first_frames[d] = (k + 1 == stages.len()).then_some(drawn);
                    }
                    Err(e) => failures[d] = Some(format!("{e:#}")),
                }
            }
        }
        bar.finish_and_clear();
        let rays_per_sec = filled as f64 / fill_secs.max(1e-9);

        // Direct renders of the first view with the paths of each stage.
        let mut direct_convergence: Vec<Point> = Vec::new();
        for (k, &stage) in stages.iter().enumerate() {
            let (p, secs, paths) =
                crate::truth::direct_render(&tracer, &views[0], (self.width, self.height), stage, 77 + k as u64)?;
            direct_convergence.push((paths as f64, secs, truths[0].rmse(&p)?));
        }

        // Every view, every driver: frames and totals.
        let mut totals: Vec<Totals> = (0..DRIVERS.len()).map(|_| Totals::default()).collect();
        for (t, f) in totals.iter_mut().zip(&failures) {
            t.failed = f.clone();
        }
        let mut walk_holodeck: Vec<(f64, f64)> = Vec::new();
        let mut holodeck_clock = fill_secs;
        let tones: Vec<&ToneMap> = truths.iter().map(|t| &t.tone).collect();
        let name = |i: usize, what: &str| frames.join(format!("view{:02}-{what}.png", i + 1));
        let mut drawn: Vec<Vec<Option<Drawn>>> = Vec::new();
        for (i, (view, truth)) in views.iter().zip(&truths).enumerate() {
            save(&truth.picture, tones[i], &name(i, "reference"))?;
            let mut row = Vec::new();
            for (d, driver) in DRIVERS.iter().enumerate() {
                if totals[d].failed.is_some() {
                    row.push(None);
                    continue;
                }
                let drawn = match first_frames[d].take() {
                    Some(x) => Ok(x),
                    None => self.draw(&mut file, view, driver, truth),
                };
                match drawn {
                    Ok(x) => {
                        save(&x.picture, tones[i], &name(i, driver))?;
                        let t = &mut totals[d];
                        t.error += x.error.all;
                        t.band += x.error.band;
                        t.ssim += x.error.ssim;
                        t.samples += x.samples;
                        t.recall_secs += x.recall_secs;
                        t.draw_secs += x.draw_secs;
                        t.views += 1;
                        if d == 0 {
                            holodeck_clock += x.recall_secs + x.draw_secs;
                            walk_holodeck.push((holodeck_clock, x.error.all));
                        }
                        row.push(Some(x));
                    }
                    Err(e) => {
                        totals[d].failed = Some(format!("{e:#}"));
                        row.push(None);
                    }
                }
            }
            drawn.push(row);
        }
        file.close()?;

        // Each view traced directly from scratch in its share of the
        // holodeck's time (the fill and every quadtree frame); the sheets.
        let share = holodeck_clock / views.len() as f64;
        let mut walk_direct: Vec<(f64, f64)> = Vec::new();
        let (mut direct_clock, mut direct_paths) = (0.0, 0u64);
        let (mut direct_error, mut direct_band, mut direct_ssim) = (0.0, 0.0, 0.0);
        let bar = crate::progress::count_bar("rendering each view directly in the same time", views.len() as u64);
        for (i, (view, truth)) in views.iter().zip(&truths).enumerate() {
            let (p, secs, paths) = self.direct_for(&tracer, view, share, 1000 + i as u64)?;
            let e = truth.error(&p)?;
            direct_clock += secs;
            direct_paths += paths;
            walk_direct.push((direct_clock, e.all));
            direct_error += e.all;
            direct_band += e.band;
            direct_ssim += e.ssim;
            save(&p, tones[i], &name(i, "direct"))?;
            let mut panels = vec![sheet::Panel {
                picture: Some(&truth.picture),
                caption: format!("reference ({} spp)", self.reference_spp),
            }];
            for (driver, x) in DRIVERS.iter().zip(&drawn[i]) {
                panels.push(sheet::Panel {
                    picture: x.as_ref().map(|x| &x.picture),
                    caption: match x {
                        Some(x) => format!("{driver}: {:.3}, SSIM {:.3}", x.error.all, x.error.ssim),
                        None => format!("{driver}: not drawn here"),
                    },
                });
            }
            panels.push(sheet::Panel {
                picture: Some(&p),
                caption: format!("direct, same time: {:.3}, SSIM {:.3}", e.all, e.ssim),
            });
            sheet::write(
                &self.out.join(format!("compare-view{:02}.png", i + 1)),
                &panels,
                tones[i],
            )?;
            bar.inc(1);
        }
        bar.finish_and_clear();

        self.charts(&convergence, &direct_convergence, &walk_holodeck, &walk_direct)?;

        let n = views.len() as f64;
        let mut summary = String::new();
        summary.push_str(&format!(
            "holodeck demo: {} rays traced into {} in {:.1} s ({:.0} rays/s), {} views of {}x{}, references at {} spp ({:.1} s)\n\n",
            count(filled),
            hdk.display(),
            fill_secs,
            rays_per_sec,
            views.len(),
            self.width,
            self.height,
            self.reference_spp,
            reference_secs
        ));
        summary.push_str("| driver | rays | rays/s (fill) | recall (samples/s) | frame (ms) | relative RMSE | in the silhouette band | SSIM |\n");
        summary.push_str("|---|---|---|---|---|---|---|---|\n");
        for (driver, t) in DRIVERS.iter().zip(&totals) {
            match &t.failed {
                Some(why) => summary.push_str(&format!(
                    "| {driver} | not drawn here: {} | | | | | | |\n",
                    first_line(why)
                )),
                None => summary.push_str(&format!(
                    "| {driver} | {} | {:.0} | {:.0} | {:.1} | {:.4} | {:.4} | {:.3} |\n",
                    count(filled),
                    rays_per_sec,
                    t.samples as f64 / t.recall_secs.max(1e-9),
                    1e3 * t.draw_secs / t.views.max(1) as f64,
                    t.error / t.views.max(1) as f64,
                    t.band / t.views.max(1) as f64,
                    t.ssim / t.views.max(1) as f64
                )),
            }
        }
        summary.push_str(&format!(
            "| direct render of each view, same time | {} paths | {:.0} | | {:.1} | {:.4} | {:.4} | {:.3} |\n",
            count(direct_paths),
            direct_paths as f64 / direct_clock.max(1e-9),
            1e3 * direct_clock / n,
            direct_error / n,
            direct_band / n,
            direct_ssim / n
        ));
        summary.push_str(&format!(
            "\nThe walk: the holodeck's quadtree pictures after {:.1} s (fill and every frame), direct renders of every view after {:.1} s. Frames in {}, comparison sheets and charts in {}; {:.0} s in all.\n",
            holodeck_clock,
            direct_clock,
            frames.display(),
            self.out.display(),
            start.elapsed().as_secs_f64()
        ));
        let path = self.out.join("summary.md");
        std::fs::write(&path, &summary).with_context(|| format!("writing {}", path.display()))?;
        Ok(summary)
    }

    /// The convergence chart (error against paths and against seconds,
    /// one curve per driver and the direct render) and the walk chart.
    fn charts(
        &self,
        convergence: &[Vec<Point>],
        direct: &[Point],
        walk_holodeck: &[(f64, f64)],
        walk_direct: &[(f64, f64)],
    ) -> Result<()> {
        let curve = |name: &str, points: &[Point], x: fn(&Point) -> f64| Series {
            name: name.to_string(),
            points: points.iter().map(|p| (x(p), p.2)).collect(),
        };
        let mut by_paths: Vec<Series> = DRIVERS
            .iter()
            .zip(convergence)
            .filter(|(_, c)| !c.is_empty())
            .map(|(d, c)| curve(d, c, |p| p.0 / 1e6))
            .collect();
        by_paths.push(curve("direct render", direct, |p| p.0 / 1e6));
        let mut by_time: Vec<Series> = DRIVERS
            .iter()
            .zip(convergence)
            .filter(|(_, c)| !c.is_empty())
            .map(|(d, c)| curve(d, c, |p| p.1))
            .collect();
        by_time.push(curve("direct render", direct, |p| p.1));
        crate::chart::write(
            &self.out.join("chart-error-vs-paths-and-time"),
            &[
                Panel {
                    title: match self.views {
                        1 => "One view: error against paths".to_string(),
                        n => format!("First view: error against paths (the holodeck's rays serve all {n} views)"),
                    },
                    x_label: "million paths (holodeck: rays in the file)".into(),
                    y_label: "relative RMSE".into(),
                    series: by_paths,
                    legend: SeriesLabelPosition::UpperRight,
                },
                Panel {
                    title: "First view: error against seconds".into(),
                    x_label: "seconds (holodeck: fill and drawing)".into(),
                    y_label: "relative RMSE".into(),
                    series: by_time,
                    legend: SeriesLabelPosition::UpperRight,
                },
            ],
        )?;
        crate::chart::write(
            &self.out.join("chart-walkthrough"),
            &[Panel {
                title: "The walk: each view's error against time so far".into(),
                x_label: "seconds since the start".into(),
                y_label: "relative RMSE".into(),
                series: vec![
                    Series {
                        name: "holodeck (quadtree), rays reused".into(),
                        points: walk_holodeck.to_vec(),
                    },
                    Series {
                        name: "direct render of each view, same time".into(),
                        points: walk_direct.to_vec(),
                    },
                ],
                // Neither curve starts near zero error: the legend goes there.
                legend: SeriesLabelPosition::LowerLeft,
            }],
        )?;
        Ok(())
    }
}

/// The first line of an error, for a table cell.
fn first_line(s: &str) -> &str {
    s.lines().next().unwrap_or(s)
}

/// Writes `p` tone mapped by `tone` as the PNG `path`, and in linear
/// radiance beside it as .hdr (for `holodeck compare`).
fn save(p: &Picture, tone: &ToneMap, path: &Path) -> Result<()> {
    holodeck_display::image_io::write_rgb8(path, p.width, p.height, &tone.apply(p))
        .with_context(|| format!("writing {}", path.display()))?;
    let hdr = path.with_extension("hdr");
    holodeck_display::image_io::write_hdr(p, &hdr).with_context(|| format!("writing {}", hdr.display()))
}
