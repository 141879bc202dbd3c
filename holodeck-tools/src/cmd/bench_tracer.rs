//! `holodeck bench tracer`: kd-tree build time and memory per triangle, and
//! single-core ray throughput (primary and diffuse-bounce rays), on the bunny
//! room and a generated landscape; then path-traced samples per second.

use std::time::Instant;

use anyhow::Result;
use holodeck_protocol::View;
use holodeck_sampler::accel::BuildOptions;
use holodeck_sampler::geom::{offset_origin, Ray};
use holodeck_sampler::render::{render, RenderOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::shade::sampling::{cosine_hemisphere, Frame};
use holodeck_sampler::{KdTree, Rng, Scene, TraceOptions, Tracer};

use crate::human::count;

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

fn throughput(tree: &KdTree, scene: &Scene, rays: &[Ray]) -> (f64, Vec<Option<RayHit>>) {
    let start = Instant::now();
    let hits: Vec<_> = rays
        .iter()
        .map(|r| tree.intersect(scene, r).map(|h| (*r, h.t, h.tri)))
        .collect();
    (rays.len() as f64 / start.elapsed().as_secs_f64(), hits)
}

/// Runs the tracer measurements and prints a table.
pub fn run(triangles: &[u64], pixels: u32) -> Result<()> {
    println!("holodeck bench tracer: {pixels} x {pixels} rays per measurement, ray casting on one core");
    println!();
    println!("| scene | triangles | build (2 cores) | bytes/triangle | primary Mrays/s | diffuse bounce Mrays/s |");
    println!("|---|---|---|---|---|---|");
    for case in cases(triangles)? {
        let scene = &case.scene;
        let start = Instant::now();
        let tree = KdTree::build(scene, &BuildOptions::default());
        let build = start.elapsed().as_secs_f64();
        let st = tree.stats();
        let bytes = scene.positions.len() * 12 + scene.triangles.len() * 16 + st.bytes;
        let n = pixels as usize;
        let primary: Vec<Ray> = (0..n * n)
            .filter_map(|i| {
                let (x, y) = ((i % n) as f64 + 0.5, (i / n) as f64 + 0.5);
                case.view
                    .ray(x / n as f64, 1.0 - y / n as f64)
                    .map(|(o, d)| Ray::new(o.as_vec3(), d.as_vec3()))
            })
            .collect();
        let (primary_rate, hits) = throughput(&tree, scene, &primary);
        let mut rng = Rng::new(1, 0);
        let bounce: Vec<Ray> = hits
            .iter()
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
            .collect();
        let (bounce_rate, _) = throughput(&tree, scene, &bounce);
        println!(
            "| {} | {} | {:.2} s | {:.1} | {:.2} | {:.2} |",
            case.label,
            count(scene.triangles.len() as u64),
            build,
            bytes as f64 / scene.triangles.len().max(1) as f64,
            primary_rate / 1e6,
            bounce_rate / 1e6
        );
    }
    // Path tracing with one diffuse bounce in the furnished room, on one core.
    let room = generate("room", &GenParams::default())?;
    let tracer = Tracer::new(
        room,
        TraceOptions {
            max_bounces: 1,
            ..TraceOptions::default()
        },
    );
    let view = View::parse(super::render::ROOM_VIEW)?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let opts = RenderOptions {
        width: 128,
        height: 96,
        spp: 16,
        seed: 1,
    };
    let start = Instant::now();
    pool.install(|| render(&tracer, &view, &opts, &|_, _| {}));
    let secs = start.elapsed().as_secs_f64();
    println!();
    println!(
        "path tracing, furnished room, one bounce, one core: {:.2} M samples/s ({} samples in {secs:.2} s)",
        (128 * 96 * 16) as f64 / secs / 1e6,
        count(128 * 96 * 16)
    );
    Ok(())
}
