//! Synthetic scenes and helpers shared by the driver and store tests.

use glam::DVec3;
use holodeck_protocol::{Picture, View};

use crate::driver::{Driver, Viewport};
use crate::sample::Sample;

/// The perspective view of the tests: looking along +y, z up.
pub(crate) const EYE_VIEW: &str = "-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45";

/// A viewport from a view spec.
pub(crate) fn viewport(spec: &str, width: u32, height: u32) -> Viewport {
    Viewport::new(View::parse(spec).unwrap(), width, height).unwrap()
}

/// A tiny deterministic generator (xorshift64*), so tests need no rand.
pub(crate) struct Rng(pub(crate) u64);

impl Rng {
    /// Uniform in [0, 1).
    pub(crate) fn next(&mut self) -> f64 {
        self.0 ^= self.0 >> 12;
        self.0 ^= self.0 << 25;
        self.0 ^= self.0 >> 27;
        (self.0.wrapping_mul(0x2545_f491_4f6c_dd1d) >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// The scene: the plane y - 0.3 x = 4, in front of the test eye.
pub(crate) fn hit_plane(origin: DVec3, dir: DVec3) -> Option<DVec3> {
    let n = DVec3::new(-0.3, 1.0, 0.0);
    let denom = n.dot(dir);
    if denom <= 1e-9 {
        return None;
    }
    let t = (4.0 - n.dot(origin)) / denom;
    (t > 0.0).then(|| origin + dir * t)
}

/// The plane's radiance: smooth, strictly positive.
pub(crate) fn plane_color(p: DVec3) -> [f32; 3] {
    [
        (0.5 + 0.4 * (2.0 * p.x).sin()) as f32,
        (0.5 + 0.4 * (1.5 * p.z).cos()) as f32,
        (0.3 + 0.2 * (p.x + p.z).sin()) as f32,
    ]
}

/// A sample of the plane seen through image point (x, y) of `view`, whose
/// ray starts `offset` away from the eye (sideways) and passes through the
/// same hit point: it reprojects to that image point and misses the eye
/// by about `offset`.
pub(crate) fn plane_sample(view: &View, x: f64, y: f64, offset: DVec3) -> Option<Sample> {
    let (eye, dir) = view.ray(x, y)?;
    let hit = hit_plane(eye, dir)?;
    let origin = eye + offset + dir;
    Some(Sample {
        origin,
        direction: (hit - origin).normalize(),
        hit: Some(hit),
        color: plane_color(hit),
    })
}

/// `n` samples of the plane at random image points with random small
/// origin offsets (so miss distances differ).
pub(crate) fn random_plane_samples(view: &View, n: usize, seed: u64) -> Vec<Sample> {
    let mut rng = Rng(seed | 1);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let (x, y) = (rng.next(), rng.next());
        let offset = DVec3::new(rng.next() - 0.5, 0.0, rng.next() - 0.5) * 0.2;
        if let Some(s) = plane_sample(view, x, y, offset) {
            out.push(s);
        }
    }
    out
}

/// The analytic picture: the plane's color through each pixel center.
pub(crate) fn analytic(vp: &Viewport) -> Picture {
    truth(vp, |o, d| hit_plane(o, d).map(|p| (p, plane_color(p))))
}

/// What `scene` (nearest hit and its radiance of a ray) shows through each
/// pixel center of `vp`, black where nothing.
pub(crate) fn truth(vp: &Viewport, scene: impl Fn(DVec3, DVec3) -> Option<(DVec3, [f32; 3])>) -> Picture {
    let (w, h) = (vp.width as usize, vp.height as usize);
    let mut pixels = Vec::with_capacity(w * h);
    for row in 0..h {
        for col in 0..w {
            let (x, y) = ((col as f64 + 0.5) / w as f64, 1.0 - (row as f64 + 0.5) / h as f64);
            let c = vp
                .view
                .ray(x, y)
                .and_then(|(o, d)| scene(o, d))
                .map_or([0.0; 3], |h| h.1);
            pixels.push(glam::Vec3::from_array(c));
        }
    }
    Picture {
        width: w,
        height: h,
        pixels,
    }
}

/// A sample on the exact image grid of a parallel view "-vtl -vp 0 0 0
/// -vd 0 1 0 -vu 0 0 1 -vh W -vv H" drawn on W x H pixels: pixel column c
/// starts at world x = c - W/2 and row r at world z = H/2 - r, so
/// (`px`, `py`) in pixel units lands exactly where asked.
pub(crate) fn grid_sample(w: u32, h: u32, px: f64, py: f64, depth: f64, miss: f64, color: [f32; 3]) -> Sample {
    let hit = DVec3::new(px - f64::from(w) / 2.0, depth, f64::from(h) / 2.0 - py);
    Sample {
        origin: DVec3::new(miss, 0.0, 0.0),
        direction: DVec3::Y,
        hit: Some(hit),
        color,
    }
}

/// The parallel view that [`grid_sample`] is exact for.
pub(crate) fn grid_viewport(w: u32, h: u32) -> Viewport {
    viewport(&format!("-vtl -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh {w} -vv {h}"), w, h)
}

/// Times a driver on 1M plane samples at 1024x768: one batch, batches of
/// 10,000, rendering (best of three) and a 5-degree turn; prints the
/// numbers and the RMSE against the analytic image.
pub(crate) fn time_driver(make: impl Fn(Viewport) -> Box<dyn Driver>) {
    use std::time::Instant;
    let vp = viewport(EYE_VIEW, 1024, 768);
    let samples = random_plane_samples(&vp.view, 1_000_000, 42);
    let truth = analytic(&vp);
    let n = samples.len() as f64;
    for round in 0..3 {
        let mut d = make(vp.clone());
        let t = Instant::now();
        d.add(&samples);
        let one = t.elapsed().as_secs_f64();
        let mut d = make(vp.clone());
        let t = Instant::now();
        for batch in samples.chunks(10_000) {
            d.add(batch);
        }
        let many = t.elapsed().as_secs_f64();
        let mut render = f64::INFINITY;
        let mut pic = None;
        for _ in 0..3 {
            let t = Instant::now();
            pic = Some(d.render());
            render = render.min(t.elapsed().as_secs_f64());
        }
        let kept = d.stats().kept;
        let t = Instant::now();
        d.set_view(viewport(&format!("{EYE_VIEW} -vd 0.0875 1 0"), 1024, 768));
        let turn = t.elapsed().as_secs_f64();
        println!(
            "{} round {round}: add {:.2} M/s in one batch, {:.2} M/s in batches of 10k; \
             render {:.1} ms; {kept} kept; 5-degree reprojection {:.1} ms; RMSE {:.4}",
            d.name(),
            1e-6 * n / one,
            1e-6 * n / many,
            render * 1e3,
            turn * 1e3,
            pic.map_or(f64::NAN, |p| rmse(&p, &truth)),
        );
    }
}

/// Root-mean-square difference per channel.
pub(crate) fn rmse(a: &Picture, b: &Picture) -> f64 {
    a.mse(b).unwrap().sqrt()
}

/// The process's GPU (a real one or Mesa's lavapipe). Without one the
/// GPU tests fail, saying what to install: they never pass silently.
pub(crate) fn gpu() -> std::sync::Arc<crate::gpu::GpuContext> {
    match crate::gpu::GpuContext::shared() {
        Ok(g) => g,
        Err(e) => panic!("the GPU tests need a GPU or Mesa's software Vulkan: {e}"),
    }
}

/// The radiance of the occluder of [`occluded_scene`].
pub(crate) const OCCLUDER_COLOR: [f32; 3] = [1.5, 0.1, 0.05];

/// The test plane with a square occluder in front of it, 2 m from the
/// eye (x in -0.6..0.6, z in -0.45..0.45 at y = 2): the nearest hit of a ray.
pub(crate) fn occluded_hit(origin: DVec3, dir: DVec3) -> Option<(DVec3, [f32; 3])> {
    if dir.y > 1e-9 {
        let t = (2.0 - origin.y) / dir.y;
        let p = origin + dir * t;
        if t > 0.0 && p.x.abs() <= 0.6 && p.z.abs() <= 0.45 {
            return Some((p, OCCLUDER_COLOR));
        }
    }
    hit_plane(origin, dir).map(|p| (p, plane_color(p)))
}

/// The occluded scene's triangles (occluder and a large piece of plane).
pub(crate) fn occluded_triangles() -> Vec<[glam::Vec3; 3]> {
    use glam::Vec3;
    let quad = |a: Vec3, b: Vec3, c: Vec3, d: Vec3| [[a, b, c], [a, c, d]];
    let mut t = Vec::new();
    t.extend(quad(
        Vec3::new(-0.6, 2.0, -0.45),
        Vec3::new(0.6, 2.0, -0.45),
        Vec3::new(0.6, 2.0, 0.45),
        Vec3::new(-0.6, 2.0, 0.45),
    ));
    let p = |x: f32, z: f32| Vec3::new(x, 4.0 + 0.3 * x, z);
    t.extend(quad(p(-20.0, -20.0), p(20.0, -20.0), p(20.0, 20.0), p(-20.0, 20.0)));
    t
}

/// The occluded scene as the eye sees it through each pixel center.
pub(crate) fn occluded_truth(vp: &Viewport) -> Picture {
    truth(vp, occluded_hit)
}

/// `n` samples of the occluded scene: rays from points up to `spread`
/// beside the eye through random image points, so some of them hit the
/// plane behind the occluder's edge (the paper's multidepth samples).
pub(crate) fn occluded_samples(view: &View, n: usize, spread: f64, seed: u64) -> Vec<Sample> {
    let mut rng = Rng(seed | 1);
    let mut out = Vec::with_capacity(n);
    while out.len() < n {
        let (x, y) = (rng.next(), rng.next());
        let Some((eye, dir)) = view.ray(x, y) else { continue };
        let origin = eye + DVec3::new(rng.next() - 0.5, 0.0, rng.next() - 0.5) * spread;
        // Aim at what the eye's ray would hit on the plane, from beside it.
        let Some(target) = hit_plane(eye, dir) else { continue };
        let d = (target - origin).normalize();
        if let Some((hit, color)) = occluded_hit(origin, d) {
            out.push(Sample {
                origin,
                direction: d,
                hit: Some(hit),
                color,
            });
        }
    }
    out
}

/// Pixels within `radius` of a place where the truth changes by more than
/// `step` in luminance: the band around silhouettes.
pub(crate) fn edge_band(truth: &Picture, radius: usize, step: f32) -> Vec<bool> {
    let (w, h) = (truth.width, truth.height);
    let lum = |i: usize| {
        let c = truth.pixels[i];
        0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
    };
    let mut edge = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let right = x + 1 < w && (lum(i) - lum(i + 1)).abs() > step;
            let down = y + 1 < h && (lum(i) - lum(i + w)).abs() > step;
            edge[i] = right || down;
        }
    }
    let mut band = vec![false; w * h];
    for y in 0..h {
        for x in 0..w {
            if edge[y * w + x] {
                for yy in y.saturating_sub(radius)..=(y + radius).min(h - 1) {
                    for xx in x.saturating_sub(radius)..=(x + radius).min(w - 1) {
                        band[yy * w + xx] = true;
                    }
                }
            }
        }
    }
    band
}

/// Root-mean-square difference per channel over the pixels in `mask`
/// (non-finite values as zero), as `compare::rmse_masked` gives it; here
/// so that the drivers' tests need no comparison module.
pub(crate) fn masked_rmse(a: &Picture, b: &Picture, mask: &[bool]) -> f64 {
    assert_eq!((a.width, a.height, a.pixels.len()), (b.width, b.height, b.pixels.len()));
    let channels = |v: glam::Vec3| {
        if v.is_finite() {
            v.as_dvec3().to_array()
        } else {
            [0.0; 3]
        }
    };
    let (mut sum, mut n) = (0.0f64, 0usize);
    for ((&pa, &pb), _) in a.pixels.iter().zip(&b.pixels).zip(mask).filter(|(_, &m)| m) {
        let (x, y) = (channels(pa), channels(pb));
        sum += (0..3).map(|k| (x[k] - y[k]) * (x[k] - y[k])).sum::<f64>();
        n += 1;
    }
    (sum / (3 * n.max(1)) as f64).sqrt()
}
