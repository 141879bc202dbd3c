//! Structural similarity (Wang, Bovik, Sheikh & Simoncelli 2004) on what a
//! viewer sees: the luma of the tone-mapped 8-bit picture, since SSIM was
//! designed and calibrated for display values, not for radiance.

use glam::Vec3;
use holodeck_protocol::Picture;
use rayon::prelude::*;

use super::{check, CompareError};
use crate::tonemap::ToneMap;

/// Half-width of the SSIM window: an 11x11 Gaussian, σ = 1.5 pixels, as in
/// Wang, Bovik, Sheikh & Simoncelli (2004).
const SSIM_RADIUS: usize = 5;
const SSIM_SIGMA: f64 = 1.5;
/// Stabilisers for 8-bit values: (0.01 · 255)² and (0.03 · 255)².
const SSIM_C1: f64 = (0.01 * 255.0) * (0.01 * 255.0);
const SSIM_C2: f64 = (0.03 * 255.0) * (0.03 * 255.0);

fn ssim_kernel() -> [f64; 2 * SSIM_RADIUS + 1] {
    std::array::from_fn(|i| {
        let d = i as f64 - SSIM_RADIUS as f64;
        (-d * d / (2.0 * SSIM_SIGMA * SSIM_SIGMA)).exp()
    })
}

/// Rec. 709 luma (0..=255) of the tone-mapped pixel.
fn display_luma(tone: &ToneMap, v: Vec3) -> f64 {
    let c = tone.map(v.to_array());
    0.2126 * f64::from(c[0]) + 0.7152 * f64::from(c[1]) + 0.0722 * f64::from(c[2])
}

pub(super) fn ssim_impl(a: &Picture, b: &Picture, tone: &ToneMap, mask: Option<&[bool]>) -> Result<f64, CompareError> {
    check(a, b, mask)?;
    let (w, h) = (a.width, a.height);
    let x: Vec<f64> = a.pixels.par_iter().map(|&v| display_luma(tone, v)).collect();
    let y: Vec<f64> = b.pixels.par_iter().map(|&v| display_luma(tone, v)).collect();
    let used = |i: usize| mask.is_none_or(|m| m[i]);
    let g = ssim_kernel();
    // Weighted moments 1, x, y, x², y², xy: the window is the Gaussian times
    // the mask, renormalised, so borders and holes need no padding values.
    let mut rows = vec![[0.0f64; 6]; w * h];
    rows.par_chunks_mut(w.max(1)).enumerate().for_each(|(r, out)| {
        for (c, o) in out.iter_mut().enumerate() {
            let lo = c.saturating_sub(SSIM_RADIUS);
            let hi = (c + SSIM_RADIUS).min(w - 1);
            for cc in lo..=hi {
                let i = r * w + cc;
                if !used(i) {
                    continue;
                }
                let k = g[cc + SSIM_RADIUS - c];
                let (xv, yv) = (x[i], y[i]);
                let m = [1.0, xv, yv, xv * xv, yv * yv, xv * yv];
                for (acc, v) in o.iter_mut().zip(m) {
                    *acc += k * v;
                }
            }
        }
    });
    // Per-row partial sums added in row order, so the result is the same
    // on every run whatever the thread count.
    let per_row: Vec<(f64, usize)> = (0..h)
        .into_par_iter()
        .map(|r| {
            let (mut sum, mut count) = (0.0f64, 0usize);
            let lo = r.saturating_sub(SSIM_RADIUS);
            let hi = (r + SSIM_RADIUS).min(h - 1);
            for c in 0..w {
                if !used(r * w + c) {
                    continue;
                }
                let mut m = [0.0f64; 6];
                for rr in lo..=hi {
                    let k = g[rr + SSIM_RADIUS - r];
                    for (acc, v) in m.iter_mut().zip(rows[rr * w + c]) {
                        *acc += k * v;
                    }
                }
                if m[0] <= 0.0 {
                    continue;
                }
                let [mx, my, xx, yy, xy] = [m[1], m[2], m[3], m[4], m[5]].map(|v| v / m[0]);
                let (vx, vy, cov) = (xx - mx * mx, yy - my * my, xy - mx * my);
                let s = ((2.0 * mx * my + SSIM_C1) * (2.0 * cov + SSIM_C2))
                    / ((mx * mx + my * my + SSIM_C1) * (vx + vy + SSIM_C2));
                sum += s;
                count += 1;
            }
            (sum, count)
        })
        .collect();
    let (sum, count) = per_row.iter().fold((0.0, 0), |p, q| (p.0 + q.0, p.1 + q.1));
    if count == 0 {
        return Err(CompareError::NoPixels);
    }
    Ok(sum / count as f64)
}

/// Mean structural similarity (Wang et al. 2004) of the luma of both
/// pictures tone-mapped by `tone` (usually built from the reference), with
/// an 11x11 Gaussian window (σ = 1.5) truncated and renormalised at the
/// borders, and C1 = (0.01·255)², C2 = (0.03·255)². 1 for identical
/// pictures, lower as structure differs. NaN where [`super::rmse`] would refuse;
/// use [`super::Yardstick`] to see the error.
pub fn ssim(a: &Picture, b: &Picture, tone: &ToneMap) -> f64 {
    ssim_impl(a, b, tone, None).unwrap_or(f64::NAN)
}

/// [`ssim`] using only the pixels whose `mask` entry is true, both as
/// window centres and inside the windows, so unfilled pixels neither count
/// nor blur the statistics of their filled neighbours.
pub fn ssim_masked(a: &Picture, b: &Picture, tone: &ToneMap, mask: &[bool]) -> f64 {
    ssim_impl(a, b, tone, Some(mask)).unwrap_or(f64::NAN)
}
