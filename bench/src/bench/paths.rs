//! The path tracer's batches in each order (`holodeck bench tracer`, its
//! table of whole paths): the same paths traced each to its end, and a
//! segment at a time with each segment's rays sorted by estimated hit point
//! and by origin, on one core; and whether any sample differs.

use std::time::Instant;

use anyhow::Result;
use holodeck_protocol::View;
use holodeck_sampler::geom::{offset_origin, Ray};
use holodeck_sampler::shade::last_level_cache_bytes;
use holodeck_sampler::shade::sampling::{cosine_hemisphere, Frame};
use holodeck_sampler::{FirstHits, Reorder, Rng, Sample, Scene, TraceOptions, Tracer};

/// Paths per batch in the table.
pub const PATHS: usize = 1 << 20;

/// One ray set's rate each way (paths/s, best of two) and how many samples
/// differ from those of paths traced each to its end.
fn rates(tracer: &mut Tracer, rays: &[(glam::Vec3, glam::Vec3)]) -> (Vec<f64>, usize) {
    let mut out = Vec::new();
    let mut want: Option<Vec<Option<Sample>>> = None;
    let mut differ = 0;
    for reorder in [Reorder::Off, Reorder::HitPoint, Reorder::Origin] {
        tracer.options.reorder = reorder;
        let mut best = 0f64;
        for _ in 0..2 {
            let start = Instant::now();
            let got = tracer.trace_rays(rays, false, FirstHits::Single, &mut Rng::new(1, 1));
            best = best.max(rays.len() as f64 / start.elapsed().as_secs_f64());
            match &want {
                None => want = Some(got),
                Some(w) => differ += w.iter().zip(&got).filter(|(a, b)| a != b).count(),
            }
        }
        out.push(best);
    }
    (out, differ)
}

/// Table rows for one scene: paths from the view's pixels, and paths from
/// points spread over the whole scene (a batch from many beams), with
/// eight bounces and light sampling.
pub fn rows(label: &str, scene: &Scene, view: &View) -> Result<Vec<String>> {
    let side = (PATHS as f64).sqrt() as usize;
    let from_view: Vec<(glam::Vec3, glam::Vec3)> = (0..side * side)
        .filter_map(|i| {
            let (x, y) = ((i % side) as f64 + 0.5, (i / side) as f64 + 0.5);
            view.ray(x / side as f64, 1.0 - y / side as f64)
                .map(|(o, d)| (o.as_vec3(), d.as_vec3()))
        })
        .collect();
    let scattered: Vec<(glam::Vec3, glam::Vec3)> = scattered_rays(scene, PATHS)
        .into_iter()
        .map(|r| (r.origin, r.dir))
        .collect();
    let mut tracer = Tracer::new(scene.clone(), TraceOptions::default());
    let mib = tracer.in_core_bytes() as f64 / f64::from(1 << 20);
    let pool = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    let mut out = Vec::new();
    for (what, rays) in [("from the view", &from_view), ("over the whole scene", &scattered)] {
        let (r, differ) = pool.install(|| rates(&mut tracer, rays));
        out.push(format!(
            "| {label} ({mib:.0} MiB) | {what} | {} | {:.3} | {:.3} ({:.2}) | {:.3} ({:.2}) | {differ} |",
            rays.len(),
            r[0] / 1e6,
            r[1] / 1e6,
            r[1] / r[0],
            r[2] / 1e6,
            r[2] / r[0],
        ));
    }
    Ok(out)
}

/// The table's heading.
pub fn heading() -> String {
    format!(
        "Whole paths (eight bounces, light sampling) in batches of {PATHS}, one core, M paths/s best of two: each path to its end, and a segment at a time with each segment's rays sorted (the samplers' `--reorder`); this CPU's largest cache is {:.0} MiB:\n\n| scene (in-core structure and mesh) | paths | paths | each to its end | sorted by hit point (/ to its end) | sorted by origin | samples differing |\n|---|---|---|---|---|---|---|",
        last_level_cache_bytes() as f64 / f64::from(1 << 20)
    )
}

/// `n` diffuse bounce rays from points spread over the whole scene, on
/// triangles drawn evenly by index (so by area on an even mesh), in random
/// order: a batch from many beams whose views see all of the scene.
pub(super) fn scattered_rays(scene: &Scene, n: usize) -> Vec<Ray> {
    let mut rng = Rng::new(7, 0);
    let tris = scene.triangles.len();
    (0..if tris == 0 { 0 } else { n })
        .map(|_| {
            let tri = ((u64::from(rng.next_u32()) * tris as u64) >> 32) as usize;
            let [a, b, c] = scene.vertices(tri);
            let (mut u, mut v) = rng.f32x2();
            if u + v > 1.0 {
                (u, v) = (1.0 - u, 1.0 - v);
            }
            let ng = (b - a).cross(c - a).normalize_or_zero();
            let d = Frame::new(ng).to_world(cosine_hemisphere(rng.f32x2()));
            Ray::new(offset_origin(a + u * (b - a) + v * (c - a), ng), d)
        })
        .filter(|r| r.dir.is_finite() && r.dir != glam::Vec3::ZERO)
        .collect()
}
