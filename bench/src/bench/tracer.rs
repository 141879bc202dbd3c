//! `holodeck bench tracer`: kd-tree build time and memory per triangle, and
//! single-core ray throughput (primary and diffuse-bounce rays), on the bunny
//! room and a generated landscape; then path-traced samples per second.

use std::time::Instant;

use anyhow::Result;
use holodeck_protocol::RayRecord;
use holodeck_protocol::View;
use holodeck_sampler::accel::{BuildOptions, Hit, RayOrder, WideBvh, PACKET};
use holodeck_sampler::beam::{trace_samples, traced_ray, uniform_rays, BeamSample, FileRules};
use holodeck_sampler::geom::{offset_origin, Ray};
use holodeck_sampler::render::{render, Picture, RenderOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::shade::sampling::{cosine_hemisphere, Frame};
use holodeck_sampler::{FirstHits, KdTree, Rng, Scene, TraceOptions, Tracer};

use holodeck_cli::human::count;

/// Arguments of `holodeck bench tracer`.
#[derive(clap::Args)]
#[command(after_help = "\
Builds the kd-tree and the wide BVH of the bunny room and of generated landscapes, and casts
primary and diffuse bounce rays on one core, singly and in packets of 8; then incoherent rays
sorted and not, whole paths in each order, beam packets in the room, and path tracing against
a converged reference. With --embree the same rays go through Embree 3 in the same process, and so
do the one-bounce path tracer's rays, every one cast by Embree instead.

Examples:
  holodeck bench tracer --triangles 1M --triangles 10M
  holodeck bench tracer --triangles 10M --embree      (needs a build with --features embree)")]
pub struct Args {
    /// Landscape sizes (triangles; repeat for several).
    #[arg(long, value_parser = holodeck_cli::human::count_in(1, holodeck_cli::args::MAX_TRIANGLES), default_values = ["1M"])]
    pub triangles: Vec<u64>,
    /// Rays per measurement: a square of this many pixels per side.
    #[arg(long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(4..=8192))]
    pub pixels: u32,
    /// Trace the same rays through Embree in the same process (a holodeck
    /// built with `--features embree`, which needs libembree-dev).
    #[arg(long)]
    pub embree: bool,
}

/// Runs `holodeck bench tracer`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    run(&a.triangles, a.pixels, a.embree)?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// One scene to measure: name, generator parameters and a view of its geometry.
struct Case {
    label: String,
    scene: Scene,
    view: View,
}

fn cases(triangles: &[u64]) -> Result<Vec<Case>> {
    let mut out = vec![Case {
        label: "bunny room".into(),
        scene: generate("bunny", &GenParams::default())?,
        view: View::parse("-vtv -vp 2 1.35 1.0 -vd 0 1 -0.35 -vu 0 0 1 -vh 28 -vv 28")?,
    }];
    for &n in triangles {
        out.push(Case {
            label: format!("landscape {}", count(n)),
            scene: generate(
                "landscape",
                &GenParams {
                    triangles: Some(n),
                    ..GenParams::default()
                },
            )?,
            view: View::parse("-vtv -vp 8 2 4 -vd 1 0 -0.12 -vu 0 0 1 -vh 90 -vv 60")?,
        });
    }
    Ok(out)
}

/// Rays per second on this thread, and the hits, for a batch of rays.
/// A ray that hit: the ray, its parameter at the hit, the triangle.
type RayHit = (Ray, f32, u32);

fn throughput(tree: &KdTree, rays: &[Ray]) -> (f64, Vec<Option<RayHit>>) {
    let start = Instant::now();
    let hits: Vec<_> = rays
        .iter()
        .map(|r| tree.intersect(r).map(|h| (*r, h.t, h.tri)))
        .collect();
    (rays.len() as f64 / start.elapsed().as_secs_f64(), hits)
}

/// `n` x `n` primary rays of `view` in 4 x 2 pixel tiles, so that each run
/// of 8 is a coherent packet.
fn tiled_primary(view: &View, n: usize) -> Vec<Ray> {
    (0..n * n)
        .filter_map(|i| {
            let (tile, k) = (i / 8, i % 8);
            let (tx, ty) = (tile % (n / 4), tile / (n / 4));
            let (x, y) = ((tx * 4 + k % 4) as f64 + 0.5, (ty * 2 + k / 4) as f64 + 0.5);
            view.ray(x / n as f64, 1.0 - y / n as f64)
                .map(|(o, d)| Ray::new(o.as_vec3(), d.as_vec3()))
        })
        .collect()
}

/// One cosine-distributed diffuse bounce ray from each hit.
fn bounces_from(scene: &Scene, hits: &[Option<RayHit>]) -> Vec<Ray> {
    let mut rng = Rng::new(1, 0);
    hits.iter()
        .flatten()
        .map(|(r, t, tri)| {
            let [a, b, c] = scene.vertices(*tri as usize);
            let mut ng = (b - a).cross(c - a).normalize();
            if ng.dot(r.dir) > 0.0 {
                ng = -ng;
            }
            let d = Frame::new(ng).to_world(cosine_hemisphere(rng.f32x2()));
            Ray::new(offset_origin(r.at(*t), ng), d)
        })
        .collect()
}

/// Rays per second on this thread with `intersect`, best of three, and the
/// distances of the hits.
fn best_of_three(intersect: impl Fn(&Ray) -> Option<Hit>, rays: &[Ray]) -> (f64, Vec<Option<f32>>) {
    let mut best = 0f64;
    let mut hits = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        hits = rays.iter().map(|r| intersect(r).map(|h| h.t)).collect();
        best = best.max(rays.len() as f64 / start.elapsed().as_secs_f64());
    }
    (best, hits)
}

/// Rays per second on this thread in packets of eight consecutive rays with
/// `packet`, best of three, and the distances of the hits.
fn packets_best_of_three(packet: impl Fn(&[Ray]) -> [Option<Hit>; PACKET], rays: &[Ray]) -> (f64, Vec<Option<f32>>) {
    let mut best = 0f64;
    let mut hits = Vec::new();
    for _ in 0..3 {
        let start = Instant::now();
        hits.clear();
        for chunk in rays.chunks(PACKET) {
            hits.extend(packet(chunk)[..chunk.len()].iter().map(|h| h.map(|h| h.t)));
        }
        best = best.max(rays.len() as f64 / start.elapsed().as_secs_f64());
    }
    (best, hits)
}

/// The kd-tree beside the wide BVH on the same rays: a table row of build
/// times, sizes, single-ray rates (best of three each, alternated) and the
/// BVH's packet rates, and how many rays found their nearest hit at another
/// distance.
fn wide_row(
    label: &str,
    scene: &Scene,
    bvh: &WideBvh,
    tree: &KdTree,
    build: Builds,
    primary: &[Ray],
    bounce: &[Ray],
) -> String {
    let tris = scene.triangles.len().max(1) as f64;
    let mut cells = Vec::new();
    let mut differ = 0;
    let mut rates = [0.0; 4];
    for (i, rays) in [primary, bounce].into_iter().enumerate() {
        let (kd, kd_hits) = best_of_three(|r| tree.intersect(r), rays);
        let (wide, wide_hits) = best_of_three(|r| bvh.intersect(r), rays);
        let (packets, packet_hits) = packets_best_of_three(|p| bvh.intersect_packet(p), rays);
        differ += kd_hits.iter().zip(&wide_hits).filter(|(a, b)| a != b).count();
        differ += packet_hits.iter().zip(&wide_hits).filter(|(a, b)| a != b).count();
        cells.push(format!("{:.2} / {:.2} = {:.2}", wide / 1e6, kd / 1e6, wide / kd));
        rates[i] = wide;
        rates[i + 2] = packets;
    }
    let st = bvh.stats();
    format!(
        "| {label} | {:.2} s / {:.2} s | {:.1} / {:.1} | {} nodes, {} leaves of {:.2} triangles, depth {} | {} | {} | {:.2} ({:.2}x single) | {:.2} ({:.2}x single) | {differ} of {} |",
        build.bvh,
        build.kd,
        st.bytes as f64 / tris,
        tree.stats().bytes as f64 / tris,
        count(st.nodes as u64),
        count(st.leaves as u64),
        st.fill,
        st.depth,
        cells[0],
        cells[1],
        rates[2] / 1e6,
        rates[2] / rates[0],
        rates[3] / 1e6,
        rates[3] / rates[1],
        2 * (primary.len() + bounce.len())
    )
}

/// Build seconds of the kd-tree, the wide BVH and Embree (infinite when
/// not built), each the best of two.
#[derive(Clone, Copy)]
struct Builds {
    kd: f64,
    bvh: f64,
    #[cfg_attr(not(feature = "embree"), allow(dead_code))]
    embree: f64,
}

/// Times the other builds beside a kd-tree built in `kd` seconds: the
/// wide BVH, then Embree's (with `embree`), then all three again, best of
/// two each. Taking turns puts a busy moment of a shared machine on all
/// of them alike. Returns the times and the wide BVH.
#[cfg_attr(not(feature = "embree"), allow(unused_variables))]
fn builds(label: &str, scene: &Scene, kd: f64, embree: bool) -> Result<(Builds, WideBvh)> {
    // Embree's device may refuse to start; our builds cannot fail.
    let embree_build = || -> Result<f64> {
        #[cfg(feature = "embree")]
        if embree {
            let (e, t) = timed(|| {
                holodeck_sampler::accel::embree::Embree::new(&scene.positions, scene.triangles.iter().map(|t| t.v))
            });
            drop(e?);
            return Ok(t);
        }
        Ok(f64::INFINITY)
    };
    // The first round: the kd-tree was built by the caller, the BVH is kept.
    let (bvh, bvh_first) = timed(|| WideBvh::build(scene));
    let bvh = bvh.ok_or_else(|| anyhow::anyhow!("{label}: too many triangles for the wide BVH"))?;
    let embree_first = embree_build()?;
    // The second round.
    let b = Builds {
        kd: kd.min(timed(|| drop(KdTree::build(scene, &BuildOptions::default()))).1),
        bvh: bvh_first.min(timed(|| drop(WideBvh::build(scene))).1),
        embree: embree_first.min(embree_build()?),
    };
    Ok((b, bvh))
}

/// What `f` returns, and the seconds it took.
fn timed<T>(f: impl FnOnce() -> T) -> (T, f64) {
    let start = Instant::now();
    let out = f();
    (out, start.elapsed().as_secs_f64())
}

/// Rays per second on this thread, tracing in packets of eight consecutive
/// rays, and the hits (parameter, triangle).
fn packet_throughput(tree: &KdTree, rays: &[Ray]) -> (f64, Vec<Option<(f32, u32)>>) {
    let start = Instant::now();
    let mut hits = Vec::with_capacity(rays.len());
    for chunk in rays.chunks(PACKET) {
        let found = tree.intersect_packet(chunk);
        hits.extend(found[..chunk.len()].iter().map(|h| h.map(|h| (h.t, h.tri))));
    }
    (rays.len() as f64 / start.elapsed().as_secs_f64(), hits)
}

/// Rays whose packet hit differs from the single-ray hit.
fn differing(packets: &[Option<(f32, u32)>], single: &[Option<RayHit>]) -> usize {
    packets
        .iter()
        .zip(single)
        .filter(|(p, s)| **p != s.map(|(_, t, tri)| (t, tri)))
        .count()
}

/// Seconds of rendering per estimator in the equal-time comparison.
const EQUAL_TIME: f64 = 3.0;

/// Renders passes of one sample per pixel until [`EQUAL_TIME`] has passed;
/// returns the average, the passes made and the seconds taken.
fn equal_time(tracer: &Tracer, view: &View, w: u32, h: u32) -> Result<(Picture, u32, f64)> {
    let start = Instant::now();
    let mut sum: Option<Picture> = None;
    let mut passes = 0u32;
    while passes == 0 || start.elapsed().as_secs_f64() < EQUAL_TIME {
        let options = RenderOptions {
            width: w,
            height: h,
            spp: 1,
            seed: 1000 + u64::from(passes),
        };
        let p = render(tracer, view, &options, &|_, _| {})?;
        match &mut sum {
            None => sum = Some(p),
            Some(acc) => acc.pixels.iter_mut().zip(&p.pixels).for_each(|(a, b)| *a += *b),
        }
        passes += 1;
    }
    let secs = start.elapsed().as_secs_f64();
    let mut picture = sum.unwrap_or(Picture {
        width: 0,
        height: 0,
        pixels: Vec::new(),
    });
    picture.pixels.iter_mut().for_each(|p| *p /= passes as f32);
    Ok((picture, passes, secs))
}

/// Runs the tracer measurements and prints a table (and, with `embree`, the
/// same rays through Embree beside ours).
pub fn run(triangles: &[u64], pixels: u32, embree: bool) -> Result<()> {
    if embree && !cfg!(feature = "embree") {
        anyhow::bail!(
            "this holodeck was built without Embree: build it with \
             `cargo build --release -p holodeck-tools --features embree` (needs libembree-dev)"
        );
    }
    let mut rows = Rows::default();
    println!("holodeck bench tracer: {pixels} x {pixels} rays per measurement, ray casting on one core");
    println!();
    println!(
        "| scene | triangles | build (2 cores, best of two) | kd-tree bytes/tri | mesh bytes/tri | primary, single | primary, packets of 8 | diffuse bounce, single | diffuse bounce, packets of 8 | packet hits differing from single |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for case in cases(triangles)? {
        case_rows(&case, pixels, embree, &mut rows)?;
    }
    print_tables(rows, embree);
    beam_table()?;
    room_paths_table(embree)
}

/// The rows of the tables printed after the first, gathered case by case.
#[derive(Default)]
struct Rows {
    /// Embree's rows.
    beside: Vec<String>,
    /// The reordering table.
    reordered: Vec<String>,
    /// The build-memory table.
    memory: Vec<String>,
    /// The wide BVH's table.
    wide: Vec<String>,
    /// Rays spread over the whole scene.
    scattered: Vec<String>,
    /// Whole paths in each order.
    paths: Vec<String>,
}

/// Measures one case: prints its row of the first table and gathers its
/// rows of the others.
#[cfg_attr(not(feature = "embree"), allow(unused_variables))]
fn case_rows(case: &Case, pixels: u32, embree: bool, rows: &mut Rows) -> Result<()> {
    let scene = &case.scene;
    let peak_known = super::reset_peak_rss();
    let before = super::rss().1;
    let start = Instant::now();
    let tree = KdTree::build(scene, &BuildOptions::default());
    let kd_build = start.elapsed().as_secs_f64();
    // The first build gives the peak memory; the rest take turns.
    let peak = super::rss().0;
    let (build, bvh) = builds(&case.label, scene, kd_build, embree)?;
    let st = tree.stats();
    let bytes = scene.positions.len() * 12 + scene.triangles.len() * 16 + st.bytes;
    let mib = |b: u64| b as f64 / f64::from(1 << 20);
    let mesh = (bytes - st.bytes) as u64;
    // The target's measure: the build's peak with the mesh beside it,
    // against what remains (the tree and the mesh).
    let grown = peak.saturating_sub(before);
    rows.memory.push(if peak_known {
        format!(
            "| {} | {:.0} MiB | {:.0} MiB | {:.0} MiB | {:.2} |",
            case.label,
            mib(mesh),
            mib(st.bytes as u64),
            mib(grown),
            (grown + mesh) as f64 / bytes.max(1) as f64
        )
    } else {
        format!(
            "| {} | {:.0} MiB | {:.0} MiB | unknown (this system cannot reset the peak) | |",
            case.label,
            mib(mesh),
            mib(st.bytes as u64)
        )
    });
    let primary = tiled_primary(&case.view, pixels as usize);
    let (primary_packets, primary_packet_hits) = packet_throughput(&tree, &primary);
    let (primary_rate, hits) = throughput(&tree, &primary);
    let mut wrong = differing(&primary_packet_hits, &hits);
    let bounce = bounces_from(scene, &hits);
    let (bounce_rate, bounce_hits) = throughput(&tree, &bounce);
    let (bounce_packets, bounce_packet_hits) = packet_throughput(&tree, &bounce);
    wrong += differing(&bounce_packet_hits, &bounce_hits);
    rows.reordered
        .push(reordering_row(&case.label, &tree, &bounce, &bounce_hits));
    rows.wide
        .push(wide_row(&case.label, scene, &bvh, &tree, build, &primary, &bounce));
    rows.scattered.push(scattered_row(&case.label, scene, &tree, &bvh));
    let tris = scene.triangles.len().max(1) as f64;
    println!(
        "| {} | {} | {:.2} s | {:.1} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {wrong} |",
        case.label,
        count(scene.triangles.len() as u64),
        build.kd,
        st.bytes as f64 / tris,
        (bytes - st.bytes) as f64 / tris,
        primary_rate / 1e6,
        primary_packets / 1e6,
        bounce_rate / 1e6,
        bounce_packets / 1e6
    );
    rows.paths.extend(super::paths::rows(&case.label, scene, &case.view)?);
    #[cfg(feature = "embree")]
    if embree {
        rows.beside.push(side_by_side(
            &case.label,
            scene,
            build,
            [primary_rate, primary_packets, bounce_rate, bounce_packets],
            &bvh,
            &primary,
            &hits,
            &bounce,
            &bounce_hits,
        )?);
    }
    drop(bvh);
    Ok(())
}

/// Prints the tables gathered case by case.
fn print_tables(rows: Rows, embree: bool) {
    println!();
    println!(
        "Memory while building (resident memory of this process above what it held just before the build, at its peak):"
    );
    println!();
    println!("| scene | mesh | kd-tree | build's peak | (build's peak + mesh) / (kd-tree + mesh) |");
    println!("|---|---|---|---|---|");
    for row in rows.memory {
        println!("{row}");
    }
    println!();
    println!(
        "The wide BVH (8 children per node, leaves of up to 8 triangles) beside the kd-tree on the same rays, one core, best of three; single rays wide BVH / kd-tree, and the BVH's packets of 8 (Mrays/s):"
    );
    println!();
    println!("| scene | build (2 cores, best of two) | bytes/tri | shape | primary, single | diffuse bounce, single | primary, packets of 8, wide BVH | diffuse bounce, packets of 8, wide BVH | rays with another nearest distance (kd-tree and packets against single BVH rays) |");
    println!("|---|---|---|---|---|---|---|---|---|");
    for row in rows.wide {
        println!("{row}");
    }
    if embree {
        println!();
        println!(
            "The same rays through Embree 3 in this process (high build quality, default threads; builds best of two, taking turns with ours; rays best of three, the wide BVH's runs taking turns with Embree's, the kd-tree's from the first table); ours / Embree:"
        );
        println!();
        println!(
            "| scene | build, kd-tree / wide BVH / Embree | primary, single | primary, packets of 8 | diffuse bounce, single | diffuse bounce, packets of 8 | primary, single, wide BVH | diffuse bounce, single, wide BVH | primary, packets of 8, wide BVH | diffuse bounce, packets of 8, wide BVH | rays hitting another triangle |"
        );
        println!("|---|---|---|---|---|---|---|---|---|---|---|");
        for row in rows.beside {
            println!("{row}");
        }
    }
    println!();
    println!(
        "Incoherent rays: the diffuse bounce rays above in random order, traced as given and reordered, in one batch and in smaller ones (the sort's time included):"
    );
    println!();
    println!(
        "| scene | rays | as given | by hit point, batches of 4,096 (/ as given) | by hit point, batches of 32,768 | by hit point (Moon 2010), one batch | by origin, one batch | hit point / as given | origin / as given | hits differing |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for row in rows.reordered {
        println!("{row}");
    }
    println!();
    println!(
        "Incoherent rays over the whole scene: {SCATTERED} diffuse bounce rays from points spread evenly over all triangles, in random order (a batch from many beams whose views see all of the scene), traced as given and sorted in one batch (the sort's time included), by the kd-tree and by the wide BVH; single rays on one core, best of three:"
    );
    println!();
    println!(
        "| scene | rays | kd-tree, as given | kd-tree, by hit point (/ as given) | kd-tree, by origin (/ as given) | wide BVH, as given | wide BVH, by hit point (/ as given) | wide BVH, by origin (/ as given) | hits differing from as given |"
    );
    println!("|---|---|---|---|---|---|---|---|---|");
    for row in rows.scattered {
        println!("{row}");
    }
    println!();
    println!("{}", super::paths::heading());
    for row in rows.paths {
        println!("{row}");
    }
}

/// The table of one beam packet's rays in the furnished room.
fn beam_table() -> Result<()> {
    println!();
    println!(
        "Beam packets in the furnished room: the rays of one beam packet (from one sampled pair of grid cells), first hits one ray at a time and in packets of 8, and the whole sample (path tracing, 8 bounces, one estimate) with each and with the choice timed as it runs (the samplers' way):"
    );
    println!();
    println!(
        "| rays per beam | beams | first hits, single | first hits, packets | packets / single | samples/s, single first hits | samples/s, packets | packets / single | samples/s, measured (its choice) | records differing |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|");
    for per_beam in [4, 32] {
        println!("{}", beam_row(per_beam)?);
    }
    Ok(())
}

/// Path tracing with one diffuse bounce in the furnished room, on one core:
/// samples per second, and the error against a converged reference after
/// equal wall time, with and without light sampling (and through Embree).
#[cfg_attr(not(feature = "embree"), allow(unused_variables))]
fn room_paths_table(embree: bool) -> Result<()> {
    let room = generate("room", &GenParams::default())?;
    let view = View::parse(holodeck::ROOM_VIEW)?;
    let (w, h) = (96u32, 72u32);
    let one_bounce = |light_sampling| TraceOptions {
        max_bounces: 1,
        light_sampling,
        ..TraceOptions::default()
    };
    let reference_tracer = Tracer::new(room.clone(), one_bounce(true));
    let start = Instant::now();
    let reference = render(
        &reference_tracer,
        &view,
        &RenderOptions {
            width: w,
            height: h,
            spp: 4096,
            seed: 7,
        },
        &|_, _| {},
    )?;
    let reference_secs = start.elapsed().as_secs_f64();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    println!();
    println!(
        "Furnished room, one bounce, {w} x {h}, one core, {EQUAL_TIME} s each; reference: 4,096 spp with light sampling ({reference_secs:.1} s on all cores)"
    );
    println!();
    println!("| estimator | samples/s | spp reached | relative RMS error vs reference |");
    println!("|---|---|---|---|");
    // Samples per second, samples per pixel reached and relative RMS error
    // of one equal-time render.
    let measure = |tracer: &Tracer| -> Result<(f64, u32, f64)> {
        let (picture, spp, secs) = pool.install(|| equal_time(tracer, &view, w, h))?;
        let rmse = picture.mse(&reference).unwrap_or(f64::NAN).sqrt() / reference.mean_luminance().max(1e-9);
        Ok((f64::from(w * h) * f64::from(spp) / secs / 1e6, spp, rmse))
    };
    let row =
        |label: &str, (rate, spp, rmse): (f64, u32, f64)| println!("| {label} | {rate:.2} M | {spp} | {rmse:.3} |");
    for (label, light_sampling) in [("NEE + MIS (sun, area light)", true), ("BSDF sampling only", false)] {
        row(label, measure(&Tracer::new(room.clone(), one_bounce(light_sampling)))?);
    }
    #[cfg(feature = "embree")]
    if embree {
        // The same paths with every ray cast by Embree instead, taking
        // turns with ours, best of two each.
        let e = holodeck_sampler::accel::embree::Embree::new(&room.positions, room.triangles.iter().map(|t| t.v))?;
        let ours = Tracer::new(room.clone(), one_bounce(true));
        let theirs = Tracer::with_caster(
            room.clone(),
            holodeck_sampler::Caster::outside(&room, std::sync::Arc::new(e)),
            one_bounce(true),
        );
        let mut best = [(0f64, 0u32, f64::NAN); 2];
        for _ in 0..2 {
            for (b, tracer) in best.iter_mut().zip([&ours, &theirs]) {
                let m = measure(tracer)?;
                if m.0 > b.0 {
                    *b = m;
                }
            }
        }
        row(
            "NEE + MIS, our wide BVH, taking turns with Embree (best of two)",
            best[0],
        );
        row("NEE + MIS, every ray through Embree (best of two)", best[1]);
        println!();
        println!(
            "Path tracing, one bounce, ours / Embree: {:.2} M / {:.2} M samples/s = {:.2}",
            best[0].0,
            best[1].0,
            best[0].0 / best[1].0
        );
    }
    Ok(())
}

/// Smaller batches the reordering table also sorts and traces one by one.
const REORDER_BATCHES: [usize; 2] = [4096, 32768];

/// The bounce rays shuffled, traced as one batch in each [`RayOrder`]: a
/// table row of rates (rays/s, best of three) and how many hits differ from
/// the single-ray hits.
fn reordering_row(label: &str, tree: &KdTree, bounce: &[Ray], hits: &[Option<RayHit>]) -> String {
    use rand::seq::SliceRandom;
    use rand::SeedableRng;
    let mut order: Vec<usize> = (0..bounce.len()).collect();
    order.shuffle(&mut rand::rngs::StdRng::seed_from_u64(9));
    let rays: Vec<Ray> = order.iter().map(|&i| bounce[i]).collect();
    let want: Vec<Option<(f32, u32)>> = order.iter().map(|&i| hits[i].map(|(_, t, tri)| (t, tri))).collect();
    let mut differ = 0;
    // Rays traced in batches of `batch` (each reordered on its own), as a
    // sampler with that many rays in hand would.
    let mut rate = |o: RayOrder, batch: usize| {
        let mut best = 0f64;
        for repeat in 0..3 {
            let start = Instant::now();
            let got: Vec<_> = rays.chunks(batch).flat_map(|b| tree.intersect_batch(b, o)).collect();
            best = best.max(rays.len() as f64 / start.elapsed().as_secs_f64());
            if repeat == 0 {
                differ += got
                    .iter()
                    .zip(&want)
                    .filter(|(g, w)| g.map(|h| (h.t, h.tri)) != **w)
                    .count();
            }
        }
        best
    };
    let all = rays.len().max(1);
    let given = rate(RayOrder::AsGiven, all);
    let small = REORDER_BATCHES.map(|b| rate(RayOrder::HitPoint, b));
    let (hit_point, origin) = (rate(RayOrder::HitPoint, all), rate(RayOrder::Origin, all));
    format!(
        "| {label} | {} | {:.2} | {} | {:.2} | {:.2} | {:.2} | {:.2} | {differ} |",
        rays.len(),
        given / 1e6,
        small.map(|r| format!("{:.2} ({:.2})", r / 1e6, r / given)).join(" | "),
        hit_point / 1e6,
        origin / 1e6,
        hit_point / given,
        origin / given
    )
}

/// Rays in the table of rays spread over the whole scene.
const SCATTERED: usize = 1_048_576;

/// A row of the table of rays spread over the whole scene: diffuse bounces
/// from points on triangles drawn evenly by index (so by area on an even
/// mesh), each structure's rate as given and reordered (best of three), and
/// how many hits differ from those traced as given.
fn scattered_row(label: &str, scene: &Scene, tree: &KdTree, bvh: &WideBvh) -> String {
    let rays = super::paths::scattered_rays(scene, SCATTERED);
    let mut differ = 0;
    let mut cells = Vec::new();
    for intersect in [
        &(|r: &Ray| tree.intersect(r)) as &dyn Fn(&Ray) -> Option<Hit>,
        &|r: &Ray| bvh.intersect(r),
    ] {
        let (given, want) = best_of_three(intersect, &rays);
        cells.push(format!("{:.2}", given / 1e6));
        for o in [RayOrder::HitPoint, RayOrder::Origin] {
            let mut best = 0f64;
            let mut got = vec![None; rays.len()];
            for _ in 0..3 {
                let start = Instant::now();
                let order = match o {
                    RayOrder::Origin => tree.origin_order(&rays),
                    _ => tree.hit_point_order(&rays),
                };
                for i in order {
                    got[i as usize] = intersect(&rays[i as usize]).map(|h| h.t);
                }
                best = best.max(rays.len() as f64 / start.elapsed().as_secs_f64());
            }
            differ += got.iter().zip(&want).filter(|(g, w)| g != w).count();
            cells.push(format!("{:.2} ({:.2})", best / 1e6, best / given));
        }
    }
    format!("| {label} | {} | {} | {differ} |", rays.len(), cells.join(" | "))
}

/// A row of the beam-packet table: `per_beam` rays in each of a spread of
/// the room's beams, first hits (Mrays/s) and whole samples (M/s) with
/// single rays and with packets, best of three, on this thread.
fn beam_row(per_beam: usize) -> Result<String> {
    let room = generate("room", &GenParams::default())?;
    let sections = room.sections.clone();
    let tracer = Tracer::new(room, TraceOptions::default());
    let rules = FileRules::default();
    let mut rng = Rng::new(3, per_beam as u64);
    let target = 256 * 1024 / per_beam;
    let mut beams: Vec<(usize, Vec<BeamSample>)> = Vec::new();
    for (i, section) in sections.iter().enumerate() {
        let step = (u64::from(section.beam_count()) * sections.len() as u64 / target as u64).max(1);
        for beam in (0..section.beam_count()).step_by(step as usize) {
            beams.push((i, uniform_rays(section, beam, per_beam, &mut rng)?));
        }
    }
    let rays: Vec<Vec<Ray>> = beams
        .iter()
        .map(|(i, samples)| {
            samples
                .iter()
                .map(|s| {
                    let (_, origin, dir) = traced_ray(&sections[*i], rules, s);
                    Ray::new(origin, dir.normalize())
                })
                .collect()
        })
        .collect();
    let total: usize = rays.iter().map(Vec::len).sum();
    let best = |f: &mut dyn FnMut()| {
        (0..3)
            .map(|_| {
                let start = Instant::now();
                f();
                total as f64 / start.elapsed().as_secs_f64()
            })
            .fold(0f64, f64::max)
    };
    // First hits as the tracer finds them: through the wide BVH when it has one.
    let (Some(tree), bvh) = (tracer.caster().tree(), tracer.caster().bvh()) else {
        anyhow::bail!("the room's tracer has no kd-tree");
    };
    let single_hits = best(&mut || {
        for beam in &rays {
            for r in beam {
                std::hint::black_box(bvh.map_or_else(|| tree.intersect(r), |b| b.intersect(r)));
            }
        }
    });
    let packet_hits = best(&mut || {
        for beam in &rays {
            for chunk in beam.chunks(PACKET) {
                std::hint::black_box(bvh.map_or_else(|| tree.intersect_packet(chunk), |b| b.intersect_packet(chunk)));
            }
        }
    });
    let mut records: [Vec<Vec<RayRecord>>; 3] = [Vec::new(), Vec::new(), Vec::new()];
    let mut rates = [0f64; 3];
    for (k, first) in [FirstHits::Single, FirstHits::Packets, FirstHits::Measured]
        .into_iter()
        .enumerate()
    {
        rates[k] = best(&mut || {
            records[k] = beams
                .iter()
                .enumerate()
                .map(|(b, (i, samples))| {
                    let mut rng = Rng::new(4, b as u64);
                    trace_samples(&tracer, &sections[*i], rules, samples, first, &mut rng)
                })
                .collect();
        });
    }
    let differ: usize = records[1..]
        .iter()
        .flat_map(|other| records[0].iter().zip(other))
        .map(|(a, b)| a.iter().zip(b).filter(|(x, y)| x != y).count() + a.len().abs_diff(b.len()))
        .sum();
    Ok(format!(
        "| {per_beam} | {} | {:.2} | {:.2} | {:.2} | {:.3} | {:.3} | {:.2} | {:.3} ({:?}) | {differ} |",
        beams.len(),
        single_hits / 1e6,
        packet_hits / 1e6,
        packet_hits / single_hits,
        rates[0] / 1e6,
        rates[1] / 1e6,
        rates[1] / rates[0],
        rates[2] / 1e6,
        tracer.first_hits_preferred()
    ))
}

/// Embree's rates on the same rays as a table row, each beside ours, with
/// the three builds' times (`ours`: primary single, primary packets, bounce
/// single, bounce packets, then the wide BVH's primary and bounce single and
/// primary and bounce packets, in rays/s), and how many rays hit a
/// different triangle.
#[cfg(feature = "embree")]
#[allow(clippy::too_many_arguments)]
fn side_by_side(
    label: &str,
    scene: &Scene,
    build: Builds,
    kd: [f64; 4],
    bvh: &WideBvh,
    primary: &[Ray],
    primary_hits: &[Option<RayHit>],
    bounce: &[Ray],
    bounce_hits: &[Option<RayHit>],
) -> Result<String> {
    use holodeck_sampler::accel::embree::Embree;
    let e = Embree::new(&scene.positions, scene.triangles.iter().map(|t| t.v))?;
    // Each side best of three, the wide BVH's runs taking turns with
    // Embree's: a slow spell of a shared machine then falls on both.
    let turns = |rays: &[Ray], ours: &dyn Fn(), theirs: &mut dyn FnMut()| {
        let rate = |start: Instant| rays.len() as f64 / start.elapsed().as_secs_f64();
        let (mut o, mut t) = (0f64, 0f64);
        for _ in 0..3 {
            let start = Instant::now();
            ours();
            o = o.max(rate(start));
            let start = Instant::now();
            theirs();
            t = t.max(rate(start));
        }
        (o, t)
    };
    let single = |rays: &[Ray]| {
        let mut hits = Vec::new();
        let ours = || {
            rays.iter().for_each(|r| {
                std::hint::black_box(bvh.intersect(r));
            })
        };
        let (o, t) = turns(rays, &ours, &mut || {
            hits = rays.iter().map(|r| e.intersect(r).map(|h| h.1)).collect();
        });
        (o, t, hits)
    };
    let packets = |rays: &[Ray]| {
        let mut hits: Vec<Option<u32>> = Vec::new();
        let ours = || {
            rays.chunks(PACKET).for_each(|c| {
                std::hint::black_box(bvh.intersect_packet(c));
            })
        };
        let (o, t) = turns(rays, &ours, &mut || {
            hits.clear();
            for chunk in rays.chunks(8) {
                let found = e.intersect8(chunk);
                hits.extend(found[..chunk.len()].iter().map(|h| h.map(|h| h.1)));
            }
        });
        (o, t, hits)
    };
    let (ops, ps, ph) = single(primary);
    let (opp, pp, pph) = packets(primary);
    let (obs, bs, bh) = single(bounce);
    let (obp, bp, bph) = packets(bounce);
    let other = |theirs: &[Option<u32>], ours: &[Option<RayHit>]| {
        theirs
            .iter()
            .zip(ours)
            .filter(|(t, o)| **t != o.map(|(_, _, tri)| tri))
            .count()
    };
    let differ = other(&ph, primary_hits) + other(&bh, bounce_hits);
    let packet_differ =
        ph.iter().zip(&pph).filter(|(a, b)| a != b).count() + bh.iter().zip(&bph).filter(|(a, b)| a != b).count();
    let cell = |o: f64, t: f64| format!("{:.2} / {:.2} = {:.2}", o / 1e6, t / 1e6, o / t);
    Ok(format!(
        "| {label} | {:.2} s / {:.2} s / {:.2} s | {} | {} | {} | {} | {} | {} | {} | {} | {differ} of {} ({packet_differ} between Embree's packets and its single rays) |",
        build.kd,
        build.bvh,
        build.embree,
        cell(kd[0], ps),
        cell(kd[1], pp),
        cell(kd[2], bs),
        cell(kd[3], bp),
        cell(ops, ps),
        cell(obs, bs),
        cell(opp, pp),
        cell(obp, bp),
        primary.len() + bounce.len(),
    ))
}

/// The fast version for `bench all`: the bunny room and a landscape of
/// 300,000 triangles, 256 x 256 rays on one core. The wide BVH's single
/// rays beside the kd-tree's on the same rays, its packets beside its own
/// single rays, and path tracing beside the primary ray rate (a path's cost
/// in rays). Each repeat takes its turn with its baseline.
pub fn fast(ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut out = Vec::new();
    for case in cases(&[300_000])? {
        let scene = &case.scene;
        let tree = KdTree::build(scene, &BuildOptions::default());
        let Some(bvh) = WideBvh::build(scene) else { continue };
        let primary = tiled_primary(&case.view, 256);
        let (_, hits) = throughput(&tree, &primary);
        let bounce = bounces_from(scene, &hits);
        for (what, rays) in [("primary", &primary), ("diffuse bounce", &bounce)] {
            let (mut b, mut k, mut p) = (Vec::new(), Vec::new(), Vec::new());
            pool.install(|| {
                for _ in 0..ctx.repeats {
                    k.push(best_of_three(|r| tree.intersect(r), rays).0 / 1e6);
                    b.push(best_of_three(|r| bvh.intersect(r), rays).0 / 1e6);
                    p.push(packets_best_of_three(|c| bvh.intersect_packet(c), rays).0 / 1e6);
                }
            });
            let name = |x: &str| format!("{}, {what}, {x}", case.label);
            out.push(
                Figure::new("tracer", &name("wide BVH single rays"), "Mrays/s", true, b.clone())
                    .against("kd-tree single rays", k),
            );
            out.push(
                Figure::new("tracer", &name("wide BVH packets of 8"), "Mrays/s", true, p)
                    .against("wide BVH single rays", b),
            );
        }
    }
    // Path tracing, one diffuse bounce with light sampling, in the room.
    let room = generate("room", &GenParams::default())?;
    let view = View::parse(holodeck::ROOM_VIEW)?;
    let tracer = Tracer::new(
        room,
        TraceOptions {
            max_bounces: 1,
            ..TraceOptions::default()
        },
    );
    let Some(bvh) = tracer.caster().bvh() else {
        return Ok(out);
    };
    let rays = tiled_primary(&view, 128);
    let (mut paths, mut cast) = (Vec::new(), Vec::new());
    pool.install(|| -> Result<()> {
        for r in 0..ctx.repeats {
            cast.push(best_of_three(|ray| bvh.intersect(ray), &rays).0 / 1e6);
            let o = RenderOptions {
                width: 96,
                height: 72,
                spp: 16,
                seed: r as u64,
            };
            let start = Instant::now();
            render(&tracer, &view, &o, &|_, _| {})?;
            paths.push(f64::from(96 * 72 * 16) / start.elapsed().as_secs_f64() / 1e6);
        }
        Ok(())
    })?;
    out.push(
        Figure::new(
            "tracer",
            "room, path tracing one bounce with light sampling",
            "M samples/s",
            true,
            paths,
        )
        .against("primary rays cast, wide BVH", cast),
    );
    Ok(out)
}
