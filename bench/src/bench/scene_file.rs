//! `holodeck bench scene-file`: the out-of-core scene file against the
//! in-core tracer on the same landscape, in one run: build time and size
//! with both codecs, decompression speed, rays per second on primary and
//! one-bounce diffuse rays with cache budgets of 100%, 30% and 10% of the
//! decompressed scene (cold and warm), and LOD's frame time and error for
//! 0.5 to 8 pixels of error; and the file assembled in memory, as samplers
//! trace it when every block fits.

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_protocol::View;
use holodeck_sampler::geom::{offset_origin, Ray};
use holodeck_sampler::ooc::build::{build_scene_file, BuildSettings, SceneSource, BUILD_BYTES_PER_TRIANGLE};
use holodeck_sampler::ooc::{Codec, Fetch, OocScene, OocSurface};
use holodeck_sampler::render::{render, Picture, RenderOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::shade::sampling::{cosine_hemisphere, Frame};
use holodeck_sampler::{KdTree, Rng, Scene, TraceOptions, Tracer};

use super::report::median;
use holodeck_cli::chart::{Panel, Series, SeriesLabelPosition};
use holodeck_cli::human::{bytes, count};
use holodeck_display::compare::relative_rmse;

/// Arguments of `holodeck bench scene-file`.
#[derive(clap::Args)]
#[command(after_help = "\
Builds an out-of-core scene file of a generated landscape within a memory budget and traces
it against the in-core tracer: build, size, rays/s by cache budget, and LOD.

Examples:
  holodeck bench scene-file --triangles 1M --pixels 256
  holodeck bench scene-file --triangles 10M --charts docs    (ooc-budget, ooc-lod charts)")]
pub struct Args {
    /// Landscape size (triangles).
    #[arg(long, value_parser = holodeck_cli::human::count_in(1, holodeck_cli::args::MAX_TRIANGLES), default_value = "1M")]
    pub triangles: u64,
    /// Rays per measurement: a square of this many pixels per side.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(4..=8192))]
    pub pixels: u32,
    /// Write charts (SVG and PNG) of the results into this folder.
    #[arg(long, value_name = "DIR")]
    pub charts: Option<std::path::PathBuf>,
    #[command(flatten)]
    pub files: super::Files,
}

/// Runs `holodeck bench scene-file`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    run(a.triangles, a.pixels, &a.files.dir, a.files.keep, a.charts.as_deref())?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// Over the room and across the terrain and forest from 40 m up.
const VIEW: &str = "-vtv -vp -20 2 40 -vd 1 0 -0.45 -vu 0 0 1 -vh 70 -vv 50";

fn primary(view: &View, n: usize) -> Vec<Ray> {
    (0..n * n)
        .filter_map(|i| {
            let (x, y) = ((i % n) as f64 + 0.5, (i / n) as f64 + 0.5);
            view.ray(x / n as f64, 1.0 - y / n as f64)
                .map(|(o, d)| Ray::new(o.as_vec3(), d.as_vec3()))
        })
        .collect()
}

fn bounces(tree: &KdTree, scene: &Scene, rays: &[Ray]) -> Vec<Ray> {
    let mut rng = Rng::new(1, 0);
    rays.iter()
        .filter_map(|r| {
            let h = tree.intersect(r)?;
            let [a, b, c] = scene.vertices(h.tri as usize);
            let mut ng = (b - a).cross(c - a).normalize();
            if ng.dot(r.dir) > 0.0 {
                ng = -ng;
            }
            let d = Frame::new(ng).to_world(cosine_hemisphere(rng.f32x2()));
            Some(Ray::new(offset_origin(r.at(h.t), ng), d))
        })
        .collect()
}

/// Traces the rays as a sampler does (batches of 4096; rays that met missing
/// blocks are traced again once fetched, loaded on the spot after 3 rounds);
/// returns rays/s and how many hits differ from `want`.
fn trace_ooc(file: &OocScene, rays: &[Ray], want: &[Option<f32>]) -> (f64, usize) {
    let start = Instant::now();
    let mut wrong = 0;
    for (chunk, want) in rays.chunks(4096).zip(want.chunks(4096)) {
        let got = file.exact_batch(chunk.len(), |k, fetch| {
            file.intersect(&chunk[k], 0.0, fetch).map(|h| h.t)
        });
        wrong += got.iter().zip(want).filter(|(g, w)| g.as_ref() != Some(*w)).count();
    }
    (rays.len() as f64 / start.elapsed().as_secs_f64(), wrong)
}

/// Warm passes per budget, each beside an in-core pass.
const REPEATS: usize = 5;

/// Runs the benchmark on a landscape of `triangles` triangles, files in
/// `dir`; writes charts of the results into `charts` if given.
pub fn run(triangles: u64, pixels: u32, dir: &Path, keep: bool, charts: Option<&Path>) -> Result<()> {
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    out!(
        "holodeck bench scene-file: landscape of {} triangles, {pixels} x {pixels} rays, one tracing thread",
        count(triangles)
    );
    let scene = generate(
        "landscape",
        &GenParams {
            triangles: Some(triangles),
            ..GenParams::default()
        },
    )?;
    let t0 = Instant::now();
    let tree = KdTree::build(&scene, &Default::default());
    let in_core_build = t0.elapsed().as_secs_f64();
    let Some((path, decompressed)) = builds_table(&scene, &tree, in_core_build, dir, keep)? else {
        return Ok(());
    };
    let view = View::parse(VIEW)?;
    let prim = primary(&view, pixels as usize);
    let budget_series = budgets_table(&tree, &scene, &prim, &path, decompressed)?;
    let file = Arc::new(OocScene::open(&path, None, 2)?);
    let lod = lod_table(&file, &view, &prim, pixels)?;
    if let Some(dir) = charts {
        write_charts(dir, scene.triangles.len() as u64, budget_series, lod)?;
    }
    if !keep {
        drop(file);
        let _ = std::fs::remove_file(&path);
    }
    Ok(())
}

/// The table of builds: the in-core kd-tree, then a scene file with each
/// codec in a quarter of the scene's memory. The LZ4 file's path and its
/// decompressed bytes (the zstd file is removed unless `keep`).
fn builds_table(
    scene: &Scene,
    tree: &KdTree,
    in_core_build: f64,
    dir: &Path,
    keep: bool,
) -> Result<Option<(PathBuf, u64)>> {
    let n = scene.triangles.len() as u64;
    let tree_bytes = scene.positions.len() * 12 + scene.triangles.len() * 16 + tree.stats().bytes;
    out!();
    out!("| build | memory budget | chunks | time (2 cores) | decompressed | file | ratio | decompression (1 core) |");
    out!("|---|---|---|---|---|---|---|---|");
    out!(
        "| in-core kd-tree | all | 1 | {in_core_build:.2} s | {} (tree and mesh) | — | — | — |",
        bytes(tree_bytes as u64)
    );
    let memory = (n / 4).max(1) * BUILD_BYTES_PER_TRIANGLE;
    let mut lz4 = None;
    for codec in [Codec::Lz4, Codec::Zstd] {
        let path = dir.join(format!("landscape-{}.hds", codec.name()));
        let settings = BuildSettings {
            memory,
            codec,
            ..BuildSettings::default()
        };
        let r = build_scene_file(&SceneSource::new(scene.clone()), &path, &settings, &|_, _, _| {})?;
        let file = OocScene::open(&path, Some(1), 0)?;
        let t = Instant::now();
        for id in 0..file.header().blocks {
            file.cache().read(id)?;
        }
        let speed = r.decompressed_bytes as f64 / t.elapsed().as_secs_f64() / 1e6;
        out!(
            "| {} | {} (a quarter of the scene) | {} | {:.2} s | {} ({:.1} B/tri) | {} | {:.1}% | {speed:.0} MB/s |",
            codec.name(),
            bytes(memory),
            r.chunks,
            r.seconds,
            bytes(r.decompressed_bytes),
            r.decompressed_bytes as f64 / n as f64,
            bytes(r.file_bytes),
            100.0 * r.compressed_bytes as f64 / r.decompressed_bytes as f64,
        );
        if codec == Codec::Lz4 {
            lz4 = Some((path, r.decompressed_bytes));
        } else if !keep {
            let _ = std::fs::remove_file(&path);
        }
    }
    Ok(lz4)
}

/// The table of rays/s out of core at cache budgets of the whole, 30% and
/// 10% of the scene, cold and warm, beside the in-core tree on the same
/// rays (primary, diffuse bounces, bounces sorted by hit point), then the
/// file assembled in memory. The warm and cold curves, for the chart.
fn budgets_table(tree: &KdTree, scene: &Scene, prim: &[Ray], path: &Path, decompressed: u64) -> Result<Vec<Series>> {
    let bounce = bounces(tree, scene, prim);
    out!();
    out!("| rays | in core (baseline, median) | budget | cold | warm (median of {REPEATS}) | warm / in core (median of pairs) | hits differing |");
    out!("|---|---|---|---|---|---|---|");
    let mut budget_series = Vec::new();
    // The file assembled in memory, as samplers do when every block fits.
    let (mesh, assembled, report) = OocScene::open(path, None, 0)?.in_core()?;
    let mut assembled_rows = Vec::new();
    // The bounce rays again, sorted by estimated hit point (Moon 2010; the
    // in-core tree's coarse grid stands in for the coarse level).
    let sorted: Vec<Ray> = tree
        .hit_point_order(&bounce)
        .into_iter()
        .map(|i| bounce[i as usize])
        .collect();
    for (label, rays) in [
        ("primary", prim),
        ("diffuse bounce", &bounce),
        ("diffuse bounce, sorted by hit point", &sorted),
    ] {
        let (mut cold_curve, mut warm_curve) = (Vec::new(), Vec::new());
        let in_core = || {
            let t = Instant::now();
            let hits: Vec<Option<f32>> = rays.iter().map(|r| tree.intersect(r).map(|h| h.t)).collect();
            (rays.len() as f64 / t.elapsed().as_secs_f64(), hits)
        };
        let want = in_core().1;
        for share in [1.0, 0.3, 0.1] {
            let budget = ((decompressed as f64 * share) as usize).max(1 << 16);
            let file = OocScene::open(path, Some(budget), 2)?;
            let (cold, mut wrong) = trace_ooc(&file, rays, &want);
            // Warm: passes alternating with the in-core baseline, so that both
            // see the same machine; the medians of each and of their ratio.
            let (mut base, mut warm, mut ratio) = (Vec::new(), Vec::new(), Vec::new());
            for _ in 0..REPEATS {
                let (b, _) = in_core();
                let (w, e) = trace_ooc(&file, rays, &want);
                wrong += e;
                base.push(b);
                warm.push(w);
                ratio.push(w / b);
            }
            let (base, warm, ratio) = (median(&base), median(&warm), median(&ratio));
            let st = file.cache().stats();
            out!(
                "| {label}, {} | {:.2} M/s | {:.0}% ({}; {} resident) | {:.2} M/s | {:.2} M/s | {:.2} | {} |",
                count(rays.len() as u64),
                base / 1e6,
                share * 100.0,
                bytes(budget as u64),
                bytes(st.resident_bytes as u64),
                cold / 1e6,
                warm / 1e6,
                ratio,
                wrong
            );
            cold_curve.push((share * 100.0, cold / base));
            warm_curve.push((share * 100.0, ratio));
        }
        let (mut ratio, mut wrong) = (Vec::new(), 0);
        for _ in 0..REPEATS {
            let (b, _) = in_core();
            let t = Instant::now();
            let hits: Vec<Option<f32>> = rays.iter().map(|r| assembled.intersect(r).map(|h| h.t)).collect();
            let a = rays.len() as f64 / t.elapsed().as_secs_f64();
            wrong += hits.iter().zip(&want).filter(|(g, w)| g != w).count();
            ratio.push(a / b);
        }
        assembled_rows.push(format!(
            "| {label}, {} | {:.2} | {wrong} |",
            count(rays.len() as u64),
            median(&ratio)
        ));
        budget_series.push(Series {
            name: format!("{label}, warm"),
            points: warm_curve,
        });
        budget_series.push(Series {
            name: format!("{label}, cold"),
            points: cold_curve,
        });
    }

    out!();
    out!(
        "Assembled in memory (every block read and linked into the in-core tree in {:.2} s, {} nodes):",
        report.seconds,
        count(report.nodes as u64)
    );
    out!();
    out!("| rays | assembled / in core (median of {REPEATS} pairs) | hits differing |");
    out!("|---|---|---|");
    for row in &assembled_rows {
        out!("{row}");
    }
    drop((mesh, assembled));
    Ok(budget_series)
}

/// What the LOD table measured, per pixels of error: frame time against
/// LOD off, relative RMSE against LOD off, and the share of primary rays
/// ending at a voxel; with the frame size.
struct LodCurves {
    size: (u32, u32),
    time: Vec<(f64, f64)>,
    error: Vec<(f64, f64)>,
    voxels: Vec<(f64, f64)>,
}

/// The LOD table: frame time and error against LOD off, all blocks resident.
fn lod_table(file: &Arc<OocScene>, view: &View, prim: &[Ray], pixels: u32) -> Result<LodCurves> {
    let (w, h) = (pixels, pixels * 5 / 7);
    let opts = RenderOptions {
        width: w,
        height: h,
        spp: 4,
        seed: 5,
    };
    let frame = |poe: f64| -> Result<(Picture, f64, u64)> {
        let tracer = Tracer::out_of_core(
            Arc::clone(file),
            TraceOptions {
                max_bounces: 1,
                lod_primary: holodeck::truth::lod_ratio(poe, view, w),
                lod_secondary: holodeck::truth::lod_ratio(poe, view, w),
                ..TraceOptions::default()
            },
        );
        // Once to load every block, once to time.
        render(&tracer, view, &opts, &|_, _| {})?;
        let t = Instant::now();
        let p = render(&tracer, view, &opts, &|_, _| {})?;
        Ok((p, t.elapsed().as_secs_f64(), file.cache().stats().resident_bytes as u64))
    };
    let (exact, exact_time, _) = frame(0.0)?;
    let voxel_hits = |poe: f64| {
        let c = holodeck::truth::lod_ratio(poe, view, w);
        prim.iter()
            .filter(|r| {
                matches!(
                    file.intersect(r, c, &mut Fetch::load()),
                    Some(holodeck_sampler::ooc::OocHit {
                        surface: OocSurface::Voxel { .. },
                        ..
                    })
                )
            })
            .count() as f64
            / prim.len() as f64
    };
    out!();
    out!("| pixels of error | frame ({w} x {h}, 4 spp, 1 bounce, 2 threads) | frame / LOD off | relative RMSE against LOD off | primary rays ending at a voxel |");
    out!("|---|---|---|---|---|");
    out!("| off | {exact_time:.3} s | 1.00 | 0 | 0% |");
    let (mut time_curve, mut error_curve, mut voxel_curve) = (Vec::new(), Vec::new(), Vec::new());
    for poe in [0.5, 1.0, 2.0, 4.0, 8.0] {
        let (p, t, _) = frame(poe)?;
        let (error, voxels) = (relative_rmse(&p, &exact)?, voxel_hits(poe));
        out!(
            "| {poe} | {t:.3} s | {:.2} | {error:.4} | {:.1}% |",
            t / exact_time,
            100.0 * voxels
        );
        time_curve.push((poe, t / exact_time));
        error_curve.push((poe, error));
        voxel_curve.push((poe, voxels));
    }
    Ok(LodCurves {
        size: (w, h),
        time: time_curve,
        error: error_curve,
        voxels: voxel_curve,
    })
}

/// Charts of the budget and LOD tables into `dir`.
fn write_charts(dir: &Path, n: u64, budget_series: Vec<Series>, lod: LodCurves) -> Result<()> {
    let (w, h) = lod.size;
    let (time_curve, error_curve, voxel_curve) = (lod.time, lod.error, lod.voxels);
    let scene_name = format!("landscape, {} triangles", count(n));
    let budget = Panel {
        title: format!("Scene-memory budget: rays/s against in core ({scene_name})"),
        x_label: "cache budget, % of the decompressed scene".into(),
        y_label: "rays/s, out of core / in core".into(),
        legend: SeriesLabelPosition::LowerRight,
        series: budget_series,
    };
    let lod = [
        Panel {
            title: format!("LOD: frame time ({scene_name})"),
            x_label: "pixels of error".into(),
            y_label: "frame time / LOD off".into(),
            legend: SeriesLabelPosition::LowerLeft,
            series: vec![Series {
                name: format!("{w} x {h}, 4 spp, 1 bounce"),
                points: time_curve,
            }],
        },
        Panel {
            title: "LOD: image error and voxel hits".into(),
            x_label: "pixels of error".into(),
            y_label: "share".into(),
            legend: SeriesLabelPosition::UpperLeft,
            series: vec![
                Series {
                    name: "relative RMSE against LOD off".into(),
                    points: error_curve,
                },
                Series {
                    name: "primary rays ending at a voxel".into(),
                    points: voxel_curve,
                },
            ],
        },
    ];
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    for (stem, panels) in [("ooc-budget", std::slice::from_ref(&budget)), ("ooc-lod", &lod[..])] {
        let [svg, png] = holodeck_cli::chart::write(&dir.join(stem), panels)?;
        eprintln!("wrote {} and {}", svg.display(), png.display());
    }
    Ok(())
}

/// The fast version for `bench all`: a landscape of 300,000 triangles built
/// into an LZ4 scene file, traced out of core with a cache of a tenth of it
/// (warm) beside the in-core kd-tree on the same rays, 128 x 128 primary
/// and diffuse bounce rays on one core.
pub fn fast(ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    std::fs::create_dir_all(&ctx.dir).with_context(|| format!("creating {}", ctx.dir.display()))?;
    let scene = generate(
        "landscape",
        &GenParams {
            triangles: Some(300_000),
            ..GenParams::default()
        },
    )?;
    let tree = KdTree::build(&scene, &Default::default());
    let path = ctx.dir.join("all-landscape.hds");
    let settings = BuildSettings {
        memory: (scene.triangles.len() as u64 / 4).max(1) * BUILD_BYTES_PER_TRIANGLE,
        codec: Codec::Lz4,
        ..BuildSettings::default()
    };
    let r = build_scene_file(&SceneSource::new(scene.clone()), &path, &settings, &|_, _, _| {})?;
    let view = View::parse(VIEW)?;
    let prim = primary(&view, 128);
    let bounce = bounces(&tree, &scene, &prim);
    let file = OocScene::open(&path, Some(((r.decompressed_bytes / 10) as usize).max(1 << 16)), 2)?;
    let mut out = Vec::new();
    for (label, rays) in [("primary", &prim), ("diffuse bounce", &bounce)] {
        let want: Vec<Option<f32>> = rays.iter().map(|r| tree.intersect(r).map(|h| h.t)).collect();
        // Once to warm the cache.
        let (_, mut wrong) = trace_ooc(&file, rays, &want);
        let (mut ooc, mut core) = (Vec::new(), Vec::new());
        for _ in 0..ctx.repeats {
            let t = Instant::now();
            std::hint::black_box(rays.iter().filter(|r| tree.intersect(r).is_some()).count());
            core.push(rays.len() as f64 / t.elapsed().as_secs_f64() / 1e6);
            let (w, e) = trace_ooc(&file, rays, &want);
            wrong += e;
            ooc.push(w / 1e6);
        }
        anyhow::ensure!(
            wrong == 0,
            "{wrong} {label} rays found other hits out of core than in core"
        );
        out.push(
            Figure::new(
                "out-of-core",
                &format!("{label} rays, cache a tenth of the scene, warm"),
                "Mrays/s",
                true,
                ooc,
            )
            .against("in-core kd-tree", core),
        );
    }
    drop(file);
    let _ = std::fs::remove_file(&path);
    Ok(out)
}
