//! Error measures on linear radiance: RMSE, relative RMSE, PSNR, relative MSE
//! and relative RMSE on values clamped at a display level.

use glam::Vec3;
use holodeck_protocol::Picture;

use super::{check, CompareError};

/// The epsilon of [`relative_mse`]: (x − y)² / (y² + ε), as in the denoising
/// literature (Rousselle et al. 2011, the OIDN and Cycles benchmarks).
pub const RELATIVE_MSE_EPSILON: f64 = 0.01;

/// The level [`clamped_relative_rmse`] clamps at by default: values above it
/// are all white on a display exposed for the scene's middle tones, so a few
/// glints cannot decide the comparison.
pub const DEFAULT_CLAMP: f64 = 2.0;

/// A pixel as f64 channels, black if any channel is not finite.
pub(super) fn channels(v: Vec3) -> [f64; 3] {
    if v.is_finite() {
        [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
    } else {
        [0.0; 3]
    }
}

/// Sums over the compared pixels.
pub(super) struct Sums {
    pub pixels: usize,
    squared_error: f64,
    squared_reference: f64,
    peak: f64,
    relative_squared: f64,
    clamped_error: f64,
    clamped_reference: f64,
    clamped_relative: f64,
}

/// The sums of `a` against `b` over the pixels whose `mask` entry is true,
/// with values clamped at `clamp` for the clamped measure.
pub(super) fn sums(a: &Picture, b: &Picture, mask: Option<&[bool]>, clamp: f64) -> Result<Sums, CompareError> {
    let pixels = check(a, b, mask)?;
    let mut s = Sums {
        pixels,
        squared_error: 0.0,
        squared_reference: 0.0,
        peak: 0.0,
        relative_squared: 0.0,
        clamped_error: 0.0,
        clamped_reference: 0.0,
        clamped_relative: 0.0,
    };
    for (i, (&pa, &pb)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        let (ca, cb) = (channels(pa), channels(pb));
        for k in 0..3 {
            let d = ca[k] - cb[k];
            s.squared_error += d * d;
            s.squared_reference += cb[k] * cb[k];
            s.peak = s.peak.max(cb[k]);
            s.relative_squared += d * d / (cb[k] * cb[k] + RELATIVE_MSE_EPSILON);
            let (x, y) = (ca[k].clamp(0.0, clamp), cb[k].clamp(0.0, clamp));
            s.clamped_error += (x - y) * (x - y);
            s.clamped_reference += y * y;
            s.clamped_relative += (x - y) * (x - y) / (y * y + RELATIVE_MSE_EPSILON);
        }
    }
    Ok(s)
}

/// sqrt(error / reference), 0 when there is no error, infinite when only the
/// reference is black.
fn ratio(error: f64, reference: f64) -> f64 {
    if error == 0.0 {
        0.0
    } else if reference == 0.0 {
        f64::INFINITY
    } else {
        (error / reference).sqrt()
    }
}

impl Sums {
    pub fn rmse(&self) -> f64 {
        (self.squared_error / (3 * self.pixels) as f64).sqrt()
    }

    pub fn relative_rmse(&self) -> f64 {
        ratio(self.squared_error, self.squared_reference)
    }

    pub fn relative_mse(&self) -> f64 {
        self.relative_squared / (3 * self.pixels) as f64
    }

    pub fn clamped_relative_rmse(&self) -> f64 {
        ratio(self.clamped_error, self.clamped_reference)
    }

    pub fn clamped_relative_mse(&self) -> f64 {
        self.clamped_relative / (3 * self.pixels) as f64
    }

    pub fn psnr(&self, peak: Option<f64>) -> f64 {
        let peak = peak.unwrap_or(self.peak);
        let rmse = self.rmse();
        if rmse == 0.0 {
            f64::INFINITY
        } else if peak.is_finite() && peak > 0.0 {
            20.0 * (peak / rmse).log10()
        } else {
            f64::NAN
        }
    }
}

/// Root-mean-square difference of linear radiance over all channels of all
/// pixels.
pub fn rmse(a: &Picture, b: &Picture) -> Result<f64, CompareError> {
    Ok(sums(a, b, None, DEFAULT_CLAMP)?.rmse())
}

/// [`rmse`] over the pixels whose `mask` entry is true (row-major, top row
/// first, like the pixels).
pub fn rmse_masked(a: &Picture, b: &Picture, mask: &[bool]) -> Result<f64, CompareError> {
    Ok(sums(a, b, Some(mask), DEFAULT_CLAMP)?.rmse())
}

/// [`rmse`] divided by the RMS of the reference `b` over the same channels
/// and pixels, i.e. sqrt(Σ(a−b)² / Σb²): scale-free, so scenes of different
/// brightness can share a chart. The RMS rather than the mean luminance, so
/// that a picture wrong only in colour still counts. 0 for identical
/// pictures; infinite when only the reference is all black. Ruled by the
/// brightest pixels: report it beside [`relative_mse`],
/// [`clamped_relative_rmse`], FLIP and the light kept per region.
pub fn relative_rmse(a: &Picture, b: &Picture) -> Result<f64, CompareError> {
    Ok(sums(a, b, None, DEFAULT_CLAMP)?.relative_rmse())
}

/// [`relative_rmse`] over the pixels whose `mask` entry is true.
pub fn relative_rmse_masked(a: &Picture, b: &Picture, mask: &[bool]) -> Result<f64, CompareError> {
    Ok(sums(a, b, Some(mask), DEFAULT_CLAMP)?.relative_rmse())
}

/// Relative mean squared error: the mean over channels and pixels of
/// (a − b)² / (b² + 0.01) ([`RELATIVE_MSE_EPSILON`]). Every pixel counts in
/// proportion to its own brightness, so dark regions weigh as much as bright
/// ones.
pub fn relative_mse(a: &Picture, b: &Picture) -> Result<f64, CompareError> {
    Ok(sums(a, b, None, DEFAULT_CLAMP)?.relative_mse())
}

/// [`relative_rmse`] of both pictures with every channel clamped to
/// `0..=clamp` first: the error a display shows, which a few pixels far
/// above white cannot rule.
pub fn clamped_relative_rmse(a: &Picture, b: &Picture, clamp: f64) -> Result<f64, CompareError> {
    Ok(sums(a, b, None, clamp)?.clamped_relative_rmse())
}

/// [`relative_mse`] of both pictures with every channel clamped to
/// `0..=clamp` first: the relative error of what a display shows.
pub fn clamped_relative_mse(a: &Picture, b: &Picture, clamp: f64) -> Result<f64, CompareError> {
    Ok(sums(a, b, None, clamp)?.clamped_relative_mse())
}

/// Peak signal-to-noise ratio in dB, 20 log10(peak / [`rmse`]), on linear
/// radiance.
///
/// `peak` is the largest value the signal can take; `None` uses the
/// reference's largest channel value, which suits HDR pictures that have
/// no fixed white (but makes a picture with a small bright light look
/// better than without it, so pass a fixed peak when comparing scenes).
/// Identical pictures give +∞. Anything that [`rmse`] refuses, or a peak
/// that is not finite and positive, gives NaN: this returns a bare number
/// for charts; use [`super::Yardstick`] to see the error.
pub fn psnr(a: &Picture, b: &Picture, peak: Option<f64>) -> f64 {
    sums(a, b, None, DEFAULT_CLAMP).map_or(f64::NAN, |s| s.psnr(peak))
}

/// [`psnr`] over the pixels whose `mask` entry is true; `None` takes the
/// peak from those pixels of the reference.
pub fn psnr_masked(a: &Picture, b: &Picture, mask: &[bool], peak: Option<f64>) -> f64 {
    sums(a, b, Some(mask), DEFAULT_CLAMP).map_or(f64::NAN, |s| s.psnr(peak))
}
