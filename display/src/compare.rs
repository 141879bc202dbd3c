//! Image error metrics for tests and charts: how far a displayed picture is
//! from a reference rendering of the same view.
//!
//! In every function `a` is the picture under test and `b` the reference.
//! Radiance metrics ([`rmse`], [`relative_rmse`], [`psnr`]) work on linear
//! radiance, all three channels; [`ssim`] works on what a viewer would see,
//! the luma of the tone-mapped 8-bit picture, because structural similarity
//! was designed and calibrated for display values, not for radiance.
//!
//! A display may leave pixels unfilled, so each metric has a `_masked`
//! variant that compares only the pixels whose mask entry is true; a test
//! wants both numbers, since the unmasked one also charges for the holes.
//!
//! A pixel with any non-finite channel (NaN or infinite) is compared as
//! black, in either picture. A NaN is an error in the picture, and counting
//! it as black charges it as one (against anything that is not black)
//! instead of turning the whole metric into NaN or silently skipping it; the
//! tone map shows such pixels as black too, so [`ssim`] agrees.

use glam::Vec3;
use holodeck_protocol::Picture;
use rayon::prelude::*;

use crate::tonemap::ToneMap;

/// Why two pictures cannot be compared.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum CompareError {
    /// The pictures have different sizes.
    #[error("pictures differ in size: {a_width}x{a_height} vs {b_width}x{b_height}")]
    SizeMismatch {
        /// Width of the picture under test.
        a_width: usize,
        /// Height of the picture under test.
        a_height: usize,
        /// Width of the reference.
        b_width: usize,
        /// Height of the reference.
        b_height: usize,
    },
    /// A picture whose pixel count is not width times height.
    #[error("a {width}x{height} picture holds {pixels} pixels")]
    Malformed {
        /// Declared width.
        width: usize,
        /// Declared height.
        height: usize,
        /// Pixels actually present.
        pixels: usize,
    },
    /// A mask that does not have one entry per pixel.
    #[error("the mask has {mask} entries for {pixels} pixels")]
    MaskSize {
        /// Mask entries.
        mask: usize,
        /// Pixels in the pictures.
        pixels: usize,
    },
    /// Nothing to compare: an empty picture or a mask with no true entry.
    #[error("no pixels to compare")]
    NoPixels,
}

/// All metrics of one comparison, for charts and test reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Metrics {
    /// Pixels compared.
    pub pixels: usize,
    /// See [`rmse`].
    pub rmse: f64,
    /// See [`relative_rmse`].
    pub relative_rmse: f64,
    /// See [`psnr`], with the reference's peak.
    pub psnr_db: f64,
    /// See [`ssim`].
    pub ssim: f64,
}

fn check_shape(p: &Picture) -> Result<usize, CompareError> {
    match p.width.checked_mul(p.height) {
        Some(n) if n == p.pixels.len() => Ok(n),
        _ => Err(CompareError::Malformed {
            width: p.width,
            height: p.height,
            pixels: p.pixels.len(),
        }),
    }
}

/// Checks sizes and the mask; returns the number of pixels compared.
fn check(a: &Picture, b: &Picture, mask: Option<&[bool]>) -> Result<usize, CompareError> {
    if a.width != b.width || a.height != b.height {
        return Err(CompareError::SizeMismatch {
            a_width: a.width,
            a_height: a.height,
            b_width: b.width,
            b_height: b.height,
        });
    }
    let n = check_shape(a)?;
    check_shape(b)?;
    let selected = match mask {
        Some(m) if m.len() != n => {
            return Err(CompareError::MaskSize {
                mask: m.len(),
                pixels: n,
            })
        }
        Some(m) => m.iter().filter(|&&x| x).count(),
        None => n,
    };
    if selected == 0 {
        return Err(CompareError::NoPixels);
    }
    Ok(selected)
}

/// A pixel as f64 channels, black if any channel is not finite.
fn channels(v: Vec3) -> [f64; 3] {
    if v.is_finite() {
        [f64::from(v.x), f64::from(v.y), f64::from(v.z)]
    } else {
        [0.0; 3]
    }
}

/// Sums over the compared pixels: squared error, squared reference, and the
/// reference's largest channel.
struct Sums {
    pixels: usize,
    squared_error: f64,
    squared_reference: f64,
    peak: f64,
}

fn sums(a: &Picture, b: &Picture, mask: Option<&[bool]>) -> Result<Sums, CompareError> {
    let pixels = check(a, b, mask)?;
    let mut s = Sums {
        pixels,
        squared_error: 0.0,
        squared_reference: 0.0,
        peak: 0.0,
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
        }
    }
    Ok(s)
}

impl Sums {
    fn rmse(&self) -> f64 {
        (self.squared_error / (3 * self.pixels) as f64).sqrt()
    }

    fn relative_rmse(&self) -> f64 {
        if self.squared_error == 0.0 {
            0.0
        } else if self.squared_reference == 0.0 {
            f64::INFINITY
        } else {
            (self.squared_error / self.squared_reference).sqrt()
        }
    }

    fn psnr(&self, peak: Option<f64>) -> f64 {
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
    Ok(sums(a, b, None)?.rmse())
}

/// [`rmse`] over the pixels whose `mask` entry is true (row-major, top row
/// first, like the pixels).
pub fn rmse_masked(a: &Picture, b: &Picture, mask: &[bool]) -> Result<f64, CompareError> {
    Ok(sums(a, b, Some(mask))?.rmse())
}

/// [`rmse`] divided by the RMS of the reference `b` over the same channels
/// and pixels, i.e. sqrt(Σ(a−b)² / Σb²): scale-free, so scenes of different
/// brightness can share a chart. The RMS rather than the mean luminance, so
/// that a picture wrong only in colour still counts. 0 for identical
/// pictures; infinite when only the reference is all black.
pub fn relative_rmse(a: &Picture, b: &Picture) -> Result<f64, CompareError> {
    Ok(sums(a, b, None)?.relative_rmse())
}

/// [`relative_rmse`] over the pixels whose `mask` entry is true.
pub fn relative_rmse_masked(a: &Picture, b: &Picture, mask: &[bool]) -> Result<f64, CompareError> {
    Ok(sums(a, b, Some(mask))?.relative_rmse())
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
/// for charts; use [`metrics`] to see the error.
pub fn psnr(a: &Picture, b: &Picture, peak: Option<f64>) -> f64 {
    sums(a, b, None).map_or(f64::NAN, |s| s.psnr(peak))
}

/// [`psnr`] over the pixels whose `mask` entry is true; `None` takes the
/// peak from those pixels of the reference.
pub fn psnr_masked(a: &Picture, b: &Picture, mask: &[bool], peak: Option<f64>) -> f64 {
    sums(a, b, Some(mask)).map_or(f64::NAN, |s| s.psnr(peak))
}

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

fn ssim_impl(a: &Picture, b: &Picture, tone: &ToneMap, mask: Option<&[bool]>) -> Result<f64, CompareError> {
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
/// pictures, lower as structure differs. NaN where [`rmse`] would refuse;
/// use [`metrics`] to see the error.
pub fn ssim(a: &Picture, b: &Picture, tone: &ToneMap) -> f64 {
    ssim_impl(a, b, tone, None).unwrap_or(f64::NAN)
}

/// [`ssim`] using only the pixels whose `mask` entry is true, both as
/// window centres and inside the windows, so unfilled pixels neither count
/// nor blur the statistics of their filled neighbours.
pub fn ssim_masked(a: &Picture, b: &Picture, tone: &ToneMap, mask: &[bool]) -> f64 {
    ssim_impl(a, b, tone, Some(mask)).unwrap_or(f64::NAN)
}

/// Every metric at once, over all pixels or those whose `mask` entry is
/// true, with the error instead of NaN when the pictures cannot be compared.
/// The PSNR peak is the reference's (see [`psnr`]).
pub fn metrics(a: &Picture, b: &Picture, tone: &ToneMap, mask: Option<&[bool]>) -> Result<Metrics, CompareError> {
    let s = sums(a, b, mask)?;
    Ok(Metrics {
        pixels: s.pixels,
        rmse: s.rmse(),
        relative_rmse: s.relative_rmse(),
        psnr_db: s.psnr(None),
        ssim: ssim_impl(a, b, tone, mask)?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::tonemap::ToneMode;

    /// SplitMix64 with Box–Muller: deterministic Gaussian noise without a
    /// dependency.
    struct Rng(u64);

    impl Rng {
        fn uniform(&mut self) -> f64 {
            self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
            let mut z = self.0;
            z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
            ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
        }

        fn gaussian(&mut self) -> f64 {
            let (u, v) = (self.uniform().max(1e-300), self.uniform());
            (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
        }
    }

    /// A reference with structure: a gradient, a checkerboard and a disc.
    fn reference(width: usize, height: usize) -> Picture {
        let pixels = (0..width * height)
            .map(|i| {
                let (x, y) = ((i % width) as f32, (i / width) as f32);
                let check = if ((x as usize / 8) + (y as usize / 8)).is_multiple_of(2) {
                    0.3
                } else {
                    0.0
                };
                let disc = if (x - 60.0).powi(2) + (y - 40.0).powi(2) < 400.0 {
                    0.5
                } else {
                    0.0
                };
                let base = 0.4 + 0.6 * x / width as f32 + check + disc;
                Vec3::new(base, 0.8 * base + 0.1, 0.5 * base + 0.2 * y / height as f32)
            })
            .collect();
        Picture { width, height, pixels }
    }

    fn noisy(p: &Picture, sigma: f64, seed: u64) -> Picture {
        let mut rng = Rng(seed);
        let mut q = p.clone();
        for v in &mut q.pixels {
            *v += Vec3::new(rng.gaussian() as f32, rng.gaussian() as f32, rng.gaussian() as f32) * sigma as f32;
        }
        q
    }

    #[test]
    fn identical_pictures_are_perfect() {
        let p = reference(160, 120);
        let tone = ToneMap::from_picture(&p, ToneMode::Camera);
        assert_eq!(rmse(&p, &p), Ok(0.0));
        assert_eq!(relative_rmse(&p, &p), Ok(0.0));
        assert_eq!(psnr(&p, &p, None), f64::INFINITY);
        assert_eq!(psnr(&p, &p, Some(1.0)), f64::INFINITY);
        assert!((ssim(&p, &p, &tone) - 1.0).abs() < 1e-12);
        let m = metrics(&p, &p, &tone, None).unwrap();
        assert_eq!(m.pixels, 160 * 120);
        assert_eq!((m.rmse, m.psnr_db), (0.0, f64::INFINITY));
    }

    #[test]
    fn gaussian_noise_gives_its_sigma_back() {
        let p = reference(200, 150);
        let rms = (p.pixels.iter().map(|v| f64::from(v.length_squared())).sum::<f64>() / (3.0 * 200.0 * 150.0)).sqrt();
        let peak = p.pixels.iter().map(|v| f64::from(v.max_element())).fold(0.0, f64::max);
        for (seed, sigma) in [0.002, 0.01, 0.05, 0.2].into_iter().enumerate() {
            let q = noisy(&p, sigma, seed as u64 + 1);
            let e = rmse(&q, &p).unwrap();
            assert!((e / sigma - 1.0).abs() < 0.05, "sigma {sigma}: rmse {e}");
            let rel = relative_rmse(&q, &p).unwrap();
            assert!(
                (rel / (sigma / rms) - 1.0).abs() < 0.05,
                "sigma {sigma}: relative {rel}"
            );
            let db = psnr(&q, &p, Some(1.0));
            assert!(
                (db - 20.0 * (1.0 / sigma).log10()).abs() < 0.5,
                "sigma {sigma}: {db} dB"
            );
            let db = psnr(&q, &p, None);
            assert!(
                (db - 20.0 * (peak / sigma).log10()).abs() < 0.5,
                "sigma {sigma}: {db} dB at peak {peak}"
            );
        }
    }

    #[test]
    fn ssim_falls_as_noise_grows() {
        let p = reference(160, 120);
        let tone = ToneMap::from_picture(&p, ToneMode::Camera);
        let scores: Vec<f64> = [0.003, 0.01, 0.03, 0.1, 0.3]
            .iter()
            .map(|&s| ssim(&noisy(&p, s, 9), &p, &tone))
            .collect();
        assert!(scores[0] > 0.95, "{scores:?}");
        assert!(scores.windows(2).all(|w| w[1] < w[0]), "{scores:?}");
        assert!(scores[4] < 0.5, "{scores:?}");
        let human = ToneMap::from_picture(&p, ToneMode::Human);
        assert!(ssim(&noisy(&p, 0.1, 9), &p, &human) < ssim(&noisy(&p, 0.01, 9), &p, &human));
    }

    #[test]
    fn mismatched_or_broken_inputs_are_errors_not_panics() {
        let (p, q) = (reference(40, 30), reference(30, 40));
        let tone = ToneMap::from_picture(&p, ToneMode::Camera);
        let mismatch = CompareError::SizeMismatch {
            a_width: 40,
            a_height: 30,
            b_width: 30,
            b_height: 40,
        };
        assert_eq!(rmse(&p, &q), Err(mismatch.clone()));
        assert_eq!(relative_rmse(&p, &q), Err(mismatch.clone()));
        assert_eq!(metrics(&p, &q, &tone, None), Err(mismatch));
        assert!(psnr(&p, &q, None).is_nan());
        assert!(ssim(&p, &q, &tone).is_nan());

        let mut short = p.clone();
        short.pixels.pop();
        let malformed = Err(CompareError::Malformed {
            width: 40,
            height: 30,
            pixels: 1199,
        });
        assert_eq!(rmse(&short, &p), malformed);
        assert_eq!(rmse(&p, &short), malformed);
        assert!(ssim(&short, &p, &tone).is_nan());

        assert_eq!(
            rmse_masked(&p, &p, &[true; 3]),
            Err(CompareError::MaskSize { mask: 3, pixels: 1200 })
        );
        assert_eq!(rmse_masked(&p, &p, &vec![false; 1200]), Err(CompareError::NoPixels));
        assert!(ssim_masked(&p, &p, &tone, &vec![false; 1200]).is_nan());
        let empty = Picture {
            width: 0,
            height: 0,
            pixels: vec![],
        };
        assert_eq!(rmse(&empty, &empty), Err(CompareError::NoPixels));
        assert!(psnr(&p, &noisy(&p, 0.1, 1), Some(f64::NAN)).is_nan());
        assert!(psnr(&p, &noisy(&p, 0.1, 1), Some(-1.0)).is_nan());
        assert_eq!(mismatch_message(), "pictures differ in size: 40x30 vs 30x40");
    }

    fn mismatch_message() -> String {
        CompareError::SizeMismatch {
            a_width: 40,
            a_height: 30,
            b_width: 30,
            b_height: 40,
        }
        .to_string()
    }

    #[test]
    fn tiny_pictures_work() {
        for (w, h) in [(1, 1), (3, 2), (1, 17), (12, 1)] {
            let p = reference(w, h);
            let tone = ToneMap::from_picture(&p, ToneMode::Camera);
            assert!((ssim(&p, &p, &tone) - 1.0).abs() < 1e-12);
            let s = ssim(&noisy(&p, 0.3, 4), &p, &tone);
            assert!(s.is_finite() && s < 1.0, "{w}x{h}: {s}");
        }
    }

    #[test]
    fn masks_leave_out_unfilled_pixels() {
        let p = reference(120, 90);
        let tone = ToneMap::from_picture(&p, ToneMode::Camera);
        let sigma = 0.01;
        let mut shown = noisy(&p, sigma, 5);
        let mut mask = vec![true; shown.pixels.len()];
        let mut rng = Rng(11);
        for (i, v) in shown.pixels.iter_mut().enumerate() {
            if rng.uniform() < 0.2 {
                *v = if i % 2 == 0 { Vec3::ZERO } else { Vec3::NAN };
                mask[i] = false;
            }
        }
        let masked = rmse_masked(&shown, &p, &mask).unwrap();
        let all = rmse(&shown, &p).unwrap();
        assert!((masked / sigma - 1.0).abs() < 0.05, "masked {masked}");
        assert!(all > 10.0 * masked, "holes count without the mask: {all}");
        assert!(psnr_masked(&shown, &p, &mask, Some(1.0)) > psnr(&shown, &p, Some(1.0)) + 10.0);
        assert!(relative_rmse_masked(&shown, &p, &mask).unwrap() < relative_rmse(&shown, &p).unwrap());
        let (s_masked, s_all) = (ssim_masked(&shown, &p, &tone, &mask), ssim(&shown, &p, &tone));
        assert!(
            s_masked > 0.9 && s_all < s_masked - 0.1,
            "masked {s_masked}, all {s_all}"
        );
        let m = metrics(&shown, &p, &tone, Some(&mask)).unwrap();
        assert_eq!(m.pixels, mask.iter().filter(|&&x| x).count());
        assert_eq!((m.rmse, m.ssim), (masked, s_masked));

        // NaN counts as black, in either picture.
        let mut black = p.clone();
        let mut nan = p.clone();
        black.pixels[7] = Vec3::ZERO;
        nan.pixels[7] = Vec3::new(1.0, f32::NAN, 1.0);
        assert_eq!(rmse(&nan, &p), rmse(&black, &p));
        assert_eq!(rmse(&p, &nan), rmse(&p, &black));
        assert!(rmse(&nan, &p).unwrap() > 0.0);
        assert_eq!(ssim(&nan, &p, &tone), ssim(&black, &p, &tone));
        assert!(psnr(&nan, &nan, None).is_infinite());
    }
}
