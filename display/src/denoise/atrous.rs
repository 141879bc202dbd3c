//! The edge-avoiding à-trous wavelet filter (Dammertz et al., HPG 2010)
//! steered by each pixel's variance (Schied et al., "Spatiotemporal
//! Variance-Guided Filtering", HPG 2017): five passes of a 5 x 5 B3-spline
//! kernel whose taps spread 1, 2, 4, 8 and 16 pixels apart, each tap
//! weighed by how alike its pixel is to the centre in depth, normal and
//! luminance, the luminance measured in the centre's own standard
//! deviations, so noise is smoothed and edges are kept. The variance is
//! filtered along, so each pass knows how noisy its input still is.
//!
//! Two choices keep the light of every region (measured against converged
//! references on scenes lit mostly indirectly, docs/DISPLAY.md):
//! * the luminance compared is each pixel's own (the previous pass's), not
//!   a mean over its neighbours, which would carry a sunlit stripe's light
//!   into the shade beside it;
//! * the luminance difference is measured in the standard deviations of the
//!   quieter pixel of the two (its own, not smoothed over its neighbours,
//!   for the same reason), the same both ways: with the centre's own, a
//!   noisy bright pixel takes in its dark neighbours while a quiet dark one
//!   refuses the bright, and the bright regions lose light; with the noisier
//!   one's, light runs from sunlit stripes into the shade beside them.

use glam::Vec3;
use holodeck_protocol::Picture;
use rayon::prelude::*;

use super::guide::Guide;

/// How the filter weighs its taps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtrousOptions {
    /// Passes (each doubles the reach): 5 reaches 31 pixels each way.
    pub passes: u32,
    /// Luminance differences of this many standard deviations (of the
    /// quieter of the two pixels) weigh 1/e.
    pub sigma_luminance: f32,
    /// The exponent of the normals' cosine.
    pub sigma_normal: i32,
    /// Depth differences of this many times what the surface's slope
    /// explains weigh 1/e.
    pub sigma_depth: f32,
}

impl Default for AtrousOptions {
    fn default() -> Self {
        AtrousOptions {
            passes: 5,
            sigma_luminance: 3.0,
            sigma_normal: 128,
            sigma_depth: 1.0,
        }
    }
}

const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// Weights below e^-CUTOFF are left out (they change nothing).
const CUTOFF: f32 = 12.0;

/// What a pass reads of one pixel.
#[derive(Clone, Copy, Debug)]
struct Px {
    /// The luminance compared.
    l: f32,
    /// The standard deviation of the pixel's value.
    sd: f32,
    /// Its guide.
    tap: Tap,
}

/// One pixel's guide as the passes read it.
#[derive(Clone, Copy, Debug)]
pub(super) struct Tap {
    /// Distance to the surface (infinite for sky, NaN where unknown).
    pub(super) depth: f32,
    /// Depth change per pixel along the surface (its slope on screen).
    pub(super) slope: f32,
    /// Unit normal (zero where unknown).
    pub(super) normal: Vec3,
}

/// Filters `picture` (linear radiance) guided by `guide` (same size);
/// returns the filtered picture. A picture of another size than its guide
/// is returned as it is.
pub fn atrous(picture: &Picture, guide: &Guide, o: &AtrousOptions) -> Picture {
    let (w, h) = (picture.width, picture.height);
    let n = w * h;
    if n == 0 || guide.width != w || guide.height != h || picture.pixels.len() != n {
        return picture.clone();
    }
    let taps = taps(guide);
    let mut color: Vec<Vec3> = picture
        .pixels
        .iter()
        .map(|c| if c.is_finite() { c.max(Vec3::ZERO) } else { Vec3::ZERO })
        .collect();
    let mut variance = fill_variance(guide, &color);
    // The luminance the first pass compares: a 3 x 3 mean.
    let mut guide_l: Vec<f32> = color.iter().map(|&c| luminance(c)).collect();
    let mut next_color = vec![Vec3::ZERO; n];
    let mut next_var = vec![0.0f32; n];
    for pass in 0..o.passes {
        let step = 1usize << pass;
        // What a pass reads of each pixel, side by side.
        let px: Vec<Px> = (0..n)
            .map(|p| Px {
                l: guide_l[p],
                sd: variance[p].max(0.0).sqrt(),
                tap: taps[p],
            })
            .collect();
        let (px, color_in, var_in) = (&px, &color, &variance);
        next_color
            .par_chunks_mut(w)
            .zip(next_var.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, (out_c, out_v))| {
                for c in 0..w {
                    let p = r * w + c;
                    let a = px[p];
                    let (mut sum_c, mut sum_v, mut sum_w) = (Vec3::ZERO, 0.0f32, 0.0f32);
                    for (j, kj) in KERNEL.iter().enumerate() {
                        let rr = r as isize + (j as isize - 2) * step as isize;
                        if rr < 0 || rr >= h as isize {
                            continue;
                        }
                        for (i, ki) in KERNEL.iter().enumerate() {
                            let cc = c as isize + (i as isize - 2) * step as isize;
                            if cc < 0 || cc >= w as isize {
                                continue;
                            }
                            let q = rr as usize * w + cc as usize;
                            let k = ki * kj;
                            let wt = if q == p {
                                k
                            } else {
                                let b = px[q];
                                // Luminance first: most rejected taps stop here.
                                let scale_l = o.sigma_luminance * a.sd.min(b.sd) + 1e-6 + 1e-3 * a.l.min(b.l);
                                let mut e = (a.l - b.l).abs() / scale_l;
                                if e > CUTOFF {
                                    continue;
                                }
                                let dist = ((i as f32 - 2.0).abs() + (j as f32 - 2.0).abs()) * step as f32;
                                e += depth_term(a.tap, b.tap, dist, o.sigma_depth);
                                if e > CUTOFF {
                                    continue;
                                }
                                k * normal_weight(a.tap.normal, b.tap.normal, o.sigma_normal) * (-e).exp()
                            };
                            sum_c += color_in[q] * wt;
                            sum_v += var_in[q] * wt * wt;
                            sum_w += wt;
                        }
                    }
                    out_c[c] = sum_c / sum_w;
                    out_v[c] = sum_v / (sum_w * sum_w);
                }
            });
        std::mem::swap(&mut color, &mut next_color);
        std::mem::swap(&mut variance, &mut next_var);
        guide_l = color.iter().map(|&c| luminance(c)).collect();
    }
    Picture {
        width: w,
        height: h,
        pixels: color,
    }
}

/// Depth dissimilarity: 0 on the same plane, growing with the difference
/// beyond what the slope explains; sky matches only sky; unknown depths
/// match anything.
#[inline]
fn depth_term(p: Tap, q: Tap, dist: f32, sigma: f32) -> f32 {
    if p.depth.is_nan() || q.depth.is_nan() {
        return 0.0;
    }
    match (p.depth.is_finite(), q.depth.is_finite()) {
        (true, true) => {
            (p.depth - q.depth).abs() / (sigma * (p.slope.max(q.slope) * dist + 2e-3 * p.depth.max(q.depth)) + 1e-6)
        }
        (false, false) => 0.0,
        _ => f32::INFINITY,
    }
}

/// max(0, n_p · n_q)^sigma; 1 where either normal is unknown.
#[inline]
fn normal_weight(a: Vec3, b: Vec3, sigma: i32) -> f32 {
    if a == Vec3::ZERO || b == Vec3::ZERO {
        return 1.0;
    }
    let d = a.dot(b);
    if d >= 1.0 {
        return 1.0;
    }
    // By squaring, inline (powi is a library call).
    let (mut base, mut n, mut out) = (d.max(0.0), sigma.max(0) as u32, 1.0f32);
    while n > 0 {
        if n & 1 == 1 {
            out *= base;
        }
        base *= base;
        n >>= 1;
    }
    out
}

/// Depth, slope and normal of every pixel.
pub(super) fn taps(g: &Guide) -> Vec<Tap> {
    let (w, h) = (g.width, g.height);
    (0..w * h)
        .into_par_iter()
        .map(|p| {
            let (c, r) = (p % w, p / w);
            let d = g.depth[p];
            // The smaller one-sided change along each axis: the surface's
            // own slope, not a step to another surface.
            let change = |q: Option<usize>| q.map(|q| (g.depth[q] - d).abs()).filter(|x| x.is_finite());
            let along = |a: Option<usize>, b: Option<usize>| match (change(a), change(b)) {
                (Some(x), Some(y)) => x.min(y),
                (Some(x), None) | (None, Some(x)) => x,
                (None, None) => 0.0,
            };
            let sx = along((c > 0).then(|| p - 1), (c + 1 < w).then(|| p + 1));
            let sy = along((r > 0).then(|| p - w), (r + 1 < h).then(|| p + w));
            Tap {
                depth: d,
                slope: sx.max(sy),
                normal: Vec3::from_array(g.normal[p]),
            }
        })
        .collect()
}

/// The guide's variances, with unknown ones (pixels of fewer than two rays,
/// or filled by the driver) set to the variance of the luminance around
/// them over a 3 x 3 window: a pixel nobody measured counts as noisy as it
/// looks.
pub(super) fn fill_variance(g: &Guide, color: &[Vec3]) -> Vec<f32> {
    let (w, h) = (g.width, g.height);
    let l: Vec<f32> = color.iter().map(|&c| luminance(c)).collect();
    let mean = box3(&l, w, h);
    let sq = box3(&l.iter().map(|x| x * x).collect::<Vec<_>>(), w, h);
    g.variance
        .iter()
        .enumerate()
        .map(|(p, &v)| {
            if v.is_finite() {
                v
            } else {
                (sq[p] - mean[p] * mean[p]).max(0.0)
            }
        })
        .collect()
}

/// The mean over the 3 x 3 pixels around each (fewer at the borders).
fn box3(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = vec![0.0f32; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(r, o)| {
        for (c, x) in o.iter_mut().enumerate() {
            let (mut s, mut k) = (0.0f32, 0.0f32);
            for rr in r.saturating_sub(1)..=(r + 1).min(h - 1) {
                for cc in c.saturating_sub(1)..=(c + 1).min(w - 1) {
                    s += v[rr * w + cc];
                    k += 1.0;
                }
            }
            *x = s / k;
        }
    });
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Uniform noise in -1..1 from a fixed sequence.
    fn noise(i: usize, seed: u64) -> f32 {
        let mut z = (i as u64 ^ seed.wrapping_mul(0x9E37_79B9_7F4A_7C15)).wrapping_add(0x632B_E59B_D9B4_E019);
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f32 / (1u64 << 52) as f32 - 1.0
    }

    /// A `w` x `h` guide of one plane facing the eye at depth 2, every pixel's
    /// variance `var`.
    fn flat_guide(w: usize, h: usize, var: f32) -> Guide {
        Guide {
            width: w,
            height: h,
            depth: vec![2.0; w * h],
            normal: vec![[0.0, 0.0, 1.0]; w * h],
            variance: vec![var; w * h],
            albedo: Vec::new(),
        }
    }

    /// `truth` plus uniform noise of amplitude `a` times the value (the
    /// variance of the value is a² v² / 3).
    fn noisy(truth: &[f32], w: usize, h: usize, a: f32, seed: u64) -> Picture {
        Picture {
            width: w,
            height: h,
            pixels: truth
                .iter()
                .enumerate()
                .map(|(i, &v)| Vec3::splat(v * (1.0 + a * noise(i, seed))))
                .collect(),
        }
    }

    fn rmse(p: &Picture, truth: &[f32], pick: impl Fn(usize) -> bool) -> f32 {
        let (mut s, mut n) = (0.0f32, 0.0f32);
        for (i, (c, &t)) in p.pixels.iter().zip(truth).enumerate() {
            if pick(i) {
                s += (c.x - t) * (c.x - t);
                n += 1.0;
            }
        }
        (s / n).sqrt()
    }

    fn sum(p: &Picture, pick: impl Fn(usize) -> bool) -> f32 {
        p.pixels
            .iter()
            .enumerate()
            .filter(|(i, _)| pick(*i))
            .map(|(_, c)| c.x)
            .sum()
    }

    #[test]
    fn noise_on_a_plane_falls_and_its_light_stays() {
        let (w, h) = (64, 48);
        let truth = vec![0.5f32; w * h];
        let p = noisy(&truth, w, h, 0.8, 1);
        let var = (0.8f32 * 0.5).powi(2) / 3.0;
        let out = atrous(&p, &flat_guide(w, h, var), &AtrousOptions::default());
        let (before, after) = (rmse(&p, &truth, |_| true), rmse(&out, &truth, |_| true));
        assert!(after < before / 4.0, "{before} -> {after}");
        let kept = sum(&out, |_| true) / sum(&p, |_| true);
        assert!((kept - 1.0).abs() < 0.005, "{kept}");
    }

    #[test]
    fn a_shadow_edge_keeps_its_light_on_both_sides() {
        // Sunlit (4.0) on the left third, shade (0.2) beside it: one
        // surface, so only the luminance can tell them apart.
        let (w, h) = (60, 40);
        let truth: Vec<f32> = (0..w * h).map(|i| if i % w < 20 { 4.0 } else { 0.2 }).collect();
        let p = noisy(&truth, w, h, 0.6, 7);
        let mut g = flat_guide(w, h, 0.0);
        g.variance = truth.iter().map(|v| (0.6 * v).powi(2) / 3.0).collect();
        let out = atrous(&p, &g, &AtrousOptions::default());
        let (lit, shade) = (|i: usize| i % w < 20, |i: usize| i % w >= 20);
        for (name, side) in [("lit", &lit as &dyn Fn(usize) -> bool), ("shade", &shade)] {
            let kept = sum(&out, side) / sum(&p, side);
            assert!((kept - 1.0).abs() < 0.02, "{name}: {kept}");
            assert!(rmse(&out, &truth, side) < rmse(&p, &truth, side) / 2.0, "{name}");
        }
    }

    #[test]
    fn a_silhouette_is_not_blurred_across() {
        // A near wall (depth 1, value 1) on the left, a far one (depth 5,
        // value 0.1) on the right, both noisy; the pixels beside the edge
        // keep their own side's value.
        let (w, h) = (40, 30);
        let truth: Vec<f32> = (0..w * h).map(|i| if i % w < 20 { 1.0 } else { 0.1 }).collect();
        let p = noisy(&truth, w, h, 0.9, 3);
        let mut g = flat_guide(w, h, 0.0);
        g.depth = (0..w * h).map(|i| if i % w < 20 { 1.0 } else { 5.0 }).collect();
        g.variance = truth.iter().map(|v| (0.9 * v).powi(2) / 3.0).collect();
        let out = atrous(&p, &g, &AtrousOptions::default());
        let edge = |i: usize| i % w == 19 || i % w == 20;
        assert!(rmse(&out, &truth, edge) < 0.5 * rmse(&p, &truth, edge));
        for r in 0..h {
            assert!(
                (out.pixels[r * w + 20].x - 0.1).abs() < 0.05,
                "row {r}: {}",
                out.pixels[r * w + 20]
            );
        }
    }

    #[test]
    fn bad_input_comes_out_finite_and_a_wrong_guide_changes_nothing() {
        let (w, h) = (8, 6);
        let mut p = noisy(&vec![1.0; w * h], w, h, 0.5, 2);
        p.pixels[10] = Vec3::NAN;
        p.pixels[11] = Vec3::splat(f32::INFINITY);
        p.pixels[12] = Vec3::splat(-3.0);
        let mut g = flat_guide(w, h, f32::NAN);
        g.depth[5] = f32::INFINITY;
        g.depth[6] = f32::NAN;
        let out = atrous(&p, &g, &AtrousOptions::default());
        assert!(out.pixels.iter().all(|c| c.is_finite() && c.min_element() >= 0.0));
        let wrong = flat_guide(w + 1, h, 0.1);
        let same = atrous(&p, &wrong, &AtrousOptions::default());
        let bits = |q: &Picture| {
            q.pixels
                .iter()
                .map(|c| c.to_array().map(f32::to_bits))
                .collect::<Vec<_>>()
        };
        assert_eq!(bits(&same), bits(&p));
    }
}

/// Times the filter on a 1024 x 768 frame of two noisy planes (run with
/// `cargo test --release -p holodeck-display --lib atrous_speed -- --ignored
/// --nocapture`); `holodeck bench display` reports it on real frames.
#[cfg(test)]
#[test]
#[ignore]
fn atrous_speed() {
    let (w, h) = (1024, 768);
    let picture = Picture {
        width: w,
        height: h,
        pixels: (0..w * h)
            .map(|i| Vec3::splat(if i % w < 400 { 2.0 } else { 0.3 } * (1.0 + 0.5 * ((i * 7919) % 101) as f32 / 101.0)))
            .collect(),
    };
    let guide = Guide {
        width: w,
        height: h,
        depth: (0..w * h).map(|i| if i % w < 600 { 2.0 } else { 5.0 }).collect(),
        normal: vec![[0.0, 0.0, 1.0]; w * h],
        variance: vec![0.05; w * h],
        albedo: Vec::new(),
    };
    for _ in 0..3 {
        let start = web_time::Instant::now();
        std::hint::black_box(atrous(&picture, &guide, &AtrousOptions::default()));
        eprintln!("atrous 1024x768: {:.1} ms", start.elapsed().as_secs_f64() * 1e3);
    }
}
