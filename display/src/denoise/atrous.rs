//! The edge-avoiding à-trous wavelet filter (Dammertz et al., HPG 2010)
//! steered by each pixel's variance (Schied et al., "Spatiotemporal
//! Variance-Guided Filtering", HPG 2017): five passes of a 5 x 5 B3-spline
//! kernel whose taps spread 1, 2, 4, 8 and 16 pixels apart, each tap
//! weighed by how alike its pixel is to the centre in depth, normal and
//! luminance, the luminance measured in the centre's own standard
//! deviations, so noise is smoothed and edges are kept. The variance is
//! filtered along, so each pass knows how noisy its input still is.
//!
//! Weights never depend on a pixel's own noisy value alone: the luminance
//! compared is that of the previous pass (for the first, a 3 x 3 mean), so
//! that bright noise is not weighed down more than dark noise and the
//! filter keeps the light of dark regions.

use glam::Vec3;
use holodeck_protocol::Picture;
use rayon::prelude::*;

use super::guide::Guide;

/// How the filter weighs its taps.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AtrousOptions {
    /// Passes (each doubles the reach): 5 reaches 31 pixels each way.
    pub passes: u32,
    /// Luminance differences of this many standard deviations weigh 1/e.
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
            sigma_luminance: 4.0,
            sigma_normal: 128,
            sigma_depth: 1.0,
        }
    }
}

const KERNEL: [f32; 5] = [1.0 / 16.0, 1.0 / 4.0, 3.0 / 8.0, 1.0 / 4.0, 1.0 / 16.0];

fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

/// One pixel's guide as the passes read it.
#[derive(Clone, Copy, Debug)]
struct Tap {
    depth: f32,
    /// Depth change per pixel along the surface (its slope on screen).
    slope: f32,
    normal: Vec3,
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
    let mut guide_l: Vec<f32> = box3(&color.iter().map(|&c| luminance(c)).collect::<Vec<_>>(), w, h);
    let mut next_color = vec![Vec3::ZERO; n];
    let mut next_var = vec![0.0f32; n];
    for pass in 0..o.passes {
        let step = 1usize << pass;
        let sd: Vec<f32> = box3(&variance, w, h).into_iter().map(|v| v.max(0.0).sqrt()).collect();
        let (color_in, var_in, gl, taps) = (&color, &variance, &guide_l, &taps);
        next_color
            .par_chunks_mut(w)
            .zip(next_var.par_chunks_mut(w))
            .enumerate()
            .for_each(|(r, (out_c, out_v))| {
                for c in 0..w {
                    let p = r * w + c;
                    let tp = taps[p];
                    let scale_l = o.sigma_luminance * sd[p] + 1e-6 + 1e-3 * gl[p];
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
                                let tq = taps[q];
                                let dist = ((i as f32 - 2.0).abs() + (j as f32 - 2.0).abs()) * step as f32;
                                let e = depth_term(tp, tq, dist, o.sigma_depth) + (gl[p] - gl[q]).abs() / scale_l;
                                let nw = normal_weight(tp.normal, tq.normal, o.sigma_normal);
                                k * nw * (-e).exp()
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
        (true, true) => (p.depth - q.depth).abs() / (sigma * (p.slope * dist + 2e-3 * p.depth) + 1e-6),
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
    a.dot(b).max(0.0).powi(sigma)
}

/// Depth, slope and normal of every pixel.
fn taps(g: &Guide) -> Vec<Tap> {
    let (w, h) = (g.width, g.height);
    (0..w * h)
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
fn fill_variance(g: &Guide, color: &[Vec3]) -> Vec<f32> {
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
