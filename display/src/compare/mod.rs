//! Image error metrics: how far a displayed picture is from a converged
//! reference of the same view, in the measures a lighting designer and a
//! rendering engineer trust together.
//!
//! A [`Yardstick`] holds a reference and measures pictures against it
//! ([`Metrics`]): radiance errors ([`relative_rmse`], [`relative_mse`],
//! [`clamped_relative_rmse`], [`rmse`], [`psnr`]), what a viewer sees ([`ssim`]
//! on the tone-mapped luma; LDR- and HDR-FLIP, [`flip`]) and the light kept
//! in the darkest quarter, the middle half and the brightest quarter of the
//! reference's pixels and in the band around silhouettes ([`light`]).
//! Relative RMSE alone is ruled by a few bright pixels; an estimate that
//! loses light in the shadows can score as well as one that keeps it, so
//! every report gives all of them.
//!
//! In every function `a` is the picture under test and `b` the reference.
//!
//! A display may leave pixels unfilled, so the measures can be restricted to
//! the pixels whose mask entry is true; a test wants both numbers, since the
//! unmasked one also charges for the holes.
//!
//! A pixel with any non-finite channel (NaN or infinite) is compared as
//! black, in either picture. A NaN is an error in the picture, and counting
//! it as black charges it as one (against anything that is not black)
//! instead of turning the whole metric into NaN or silently skipping it; the
//! tone map shows such pixels as black too, so [`ssim`] and FLIP agree.

pub mod flip;
pub mod light;
mod radiance;
mod ssim;
#[cfg(test)]
mod tests;

use holodeck_protocol::Picture;
use serde::Serialize;

pub use light::{LightKept, Region, Regions};
pub use radiance::{
    clamped_relative_mse, clamped_relative_rmse, psnr, psnr_masked, relative_mse, relative_rmse, relative_rmse_masked,
    rmse, rmse_masked, DEFAULT_CLAMP, RELATIVE_MSE_EPSILON,
};
pub use ssim::{ssim, ssim_masked};

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

/// Every measure of one comparison, for reports, charts and scripts.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Metrics {
    /// Pixels compared.
    pub pixels: usize,
    /// See [`rmse`].
    pub rmse: f64,
    /// See [`relative_rmse`].
    pub relative_rmse: f64,
    /// See [`relative_mse`].
    pub relative_mse: f64,
    /// See [`clamped_relative_rmse`], at [`Metrics::clamp`].
    pub clamped_relative_rmse: f64,
    /// See [`clamped_relative_mse`], at [`Metrics::clamp`].
    pub clamped_relative_mse: f64,
    /// The level values were clamped at for `clamped_relative_rmse`.
    pub clamp: f64,
    /// See [`psnr`], with the reference's peak.
    pub psnr_db: f64,
    /// See [`ssim`].
    pub ssim: f64,
    /// Mean LDR-FLIP of both pictures under the reference's tone map
    /// (0: the same; 1: as different as black and white).
    pub flip: f64,
    /// Mean HDR-FLIP over the reference's range of exposures.
    pub hdr_flip: f64,
    /// Relative RMSE in the band around silhouettes, where one is given.
    pub band_relative_rmse: Option<f64>,
    /// Light kept per region.
    pub light: LightKept,
    /// The brightest spot kept: the picture's brightest luminance within
    /// two pixels of the reference's brightest pixel (a glint, the sun),
    /// over that pixel's luminance. A denoiser that smears highlights shows
    /// here first.
    pub peak: f64,
}

/// A reference picture ready to measure others against: its tone map, the
/// regions of its luminance, the exposures of HDR-FLIP, and optionally the
/// band around its silhouettes.
#[derive(Clone, Debug)]
pub struct Yardstick {
    reference: Picture,
    tone: ToneMap,
    regions: Regions,
    band: Option<Vec<bool>>,
    clamp: f64,
    pixels_per_degree: f32,
    exposures: flip::Exposures,
    /// The reference under its own tone map, for LDR-FLIP.
    ldr: Vec<u8>,
    /// The two independent halves the reference is the mean of, where it
    /// was made so (see [`Yardstick::from_halves`]).
    halves: Option<Box<(Picture, Picture)>>,
    /// The reference's own noise, where it was made of two halves.
    noise: Option<ReferenceNoise>,
}

/// How noisy a reference made of two independent halves is: each measure
/// of one half against the other, scaled to what the whole reference's own
/// error against the (unknown) truth is expected to be. Independent noise
/// adds in squares, so a reported error is inflated by at most 3% where the
/// reference's is under a quarter of it ([`ReferenceNoise::NOISE_SHARE`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct ReferenceNoise {
    /// Relative RMSE of the reference against the truth: half that of one
    /// half against the other (each half has twice the whole's variance,
    /// and their difference twice that again).
    pub relative_rmse: f64,
    /// The same for [`clamped_relative_rmse`].
    pub clamped_relative_rmse: f64,
    /// [`relative_mse`]: a quarter of one half's against the other.
    pub relative_mse: f64,
    /// The same for [`clamped_relative_mse`].
    pub clamped_relative_mse: f64,
    /// Mean LDR-FLIP of one half against the other (an upper bound: FLIP
    /// does not scale with the noise).
    pub flip_between_halves: f64,
}

impl ReferenceNoise {
    /// The largest share of an error the reference's own noise may be.
    pub const NOISE_SHARE: f64 = 0.25;

    /// The measures of `m` that the reference's noise is not under a
    /// quarter of, by name: where the comparison says more about the
    /// reference than about the picture.
    pub fn too_noisy_for(&self, m: &Metrics) -> Vec<&'static str> {
        let mut out = Vec::new();
        if self.relative_rmse > Self::NOISE_SHARE * m.relative_rmse {
            out.push("relative_rmse");
        }
        if self.clamped_relative_rmse > Self::NOISE_SHARE * m.clamped_relative_rmse {
            out.push("clamped_relative_rmse");
        }
        // Squared measures: a quarter in RMSE terms is a sixteenth here.
        if self.relative_mse > Self::NOISE_SHARE * Self::NOISE_SHARE * m.relative_mse {
            out.push("relative_mse");
        }
        if self.clamped_relative_mse > Self::NOISE_SHARE * Self::NOISE_SHARE * m.clamped_relative_mse {
            out.push("clamped_relative_mse");
        }
        out
    }
}

impl Yardstick {
    /// A yardstick of `reference`, whose pictures are shown under `tone`
    /// (usually the reference's own, [`ToneMap::from_picture`]).
    pub fn new(reference: Picture, tone: ToneMap) -> Result<Yardstick, CompareError> {
        check_shape(&reference)?;
        Ok(Yardstick {
            regions: Regions::of(&reference),
            exposures: flip::Exposures::of(&reference),
            ldr: tone.apply(&reference),
            reference,
            tone,
            band: None,
            clamp: DEFAULT_CLAMP,
            pixels_per_degree: flip::PIXELS_PER_DEGREE,
            halves: None,
            noise: None,
        })
    }

    /// A yardstick of the mean of two independent renders `a` and `b` of
    /// the same view (the same samples per pixel, other random sequences),
    /// shown under `tone` (usually [`ToneMap::from_picture`] of the mean).
    ///
    /// Every measure is against the mean, but for the light kept: its
    /// regions are chosen on `a` and its ratios measured against `b`. A
    /// region chosen by ranking a noisy picture holds the pixels whose noise
    /// happened to be low (the darkest quarter) or high (the brightest), so
    /// measuring against the same picture would credit any unbiased estimate
    /// with more light in the dark and less in the bright; the other half's
    /// noise is independent of the choice. The two halves also state the
    /// reference's own noise ([`Yardstick::noise`]).
    pub fn from_halves(a: &Picture, b: &Picture, tone: ToneMap) -> Result<Yardstick, CompareError> {
        check(a, b, None)?;
        let mean = Picture {
            width: a.width,
            height: a.height,
            pixels: a.pixels.iter().zip(&b.pixels).map(|(&x, &y)| 0.5 * (x + y)).collect(),
        };
        let mut y = Yardstick::new(mean, tone)?;
        y.regions = Regions::of(a);
        y.halves = Some(Box::new((a.clone(), b.clone())));
        y.state_noise()?;
        Ok(y)
    }

    /// Measures the halves against each other into `self.noise`.
    fn state_noise(&mut self) -> Result<(), CompareError> {
        let Some(h) = &self.halves else {
            return Ok(());
        };
        let (a, b) = (&h.0, &h.1);
        let s = radiance::sums(a, b, None, self.clamp)?;
        let (ldr_a, ldr_b) = (self.tone.apply(a), self.tone.apply(b));
        let flip_between_halves = flip::mean(
            &flip::flip_map(&ldr_a, &ldr_b, a.width, a.height, self.pixels_per_degree),
            None,
        );
        self.noise = Some(ReferenceNoise {
            relative_rmse: 0.5 * s.relative_rmse(),
            clamped_relative_rmse: 0.5 * s.clamped_relative_rmse(),
            relative_mse: 0.25 * s.relative_mse(),
            clamped_relative_mse: 0.25 * s.clamped_relative_mse(),
            flip_between_halves,
        });
        Ok(())
    }

    /// The reference's own noise, where it was made of two halves.
    pub fn noise(&self) -> Option<&ReferenceNoise> {
        self.noise.as_ref()
    }

    /// The same with the band around silhouettes: one entry per pixel, true
    /// in the band.
    pub fn with_band(mut self, band: Vec<bool>) -> Result<Yardstick, CompareError> {
        if band.len() != self.reference.pixels.len() {
            return Err(CompareError::MaskSize {
                mask: band.len(),
                pixels: self.reference.pixels.len(),
            });
        }
        self.band = Some(band);
        Ok(self)
    }

    /// The same clamping at `clamp` for the clamped relative RMSE (and the
    /// reference's noise stated at that clamp).
    pub fn with_clamp(mut self, clamp: f64) -> Yardstick {
        self.clamp = clamp;
        // The halves were checked when they were given.
        let _ = self.state_noise();
        self
    }

    /// The reference.
    pub fn reference(&self) -> &Picture {
        &self.reference
    }

    /// The tone map pictures are seen under.
    pub fn tone(&self) -> &ToneMap {
        &self.tone
    }

    /// The band around silhouettes, if given.
    pub fn band(&self) -> Option<&[bool]> {
        self.band.as_deref()
    }

    /// The regions of the reference's luminance.
    pub fn regions(&self) -> &Regions {
        &self.regions
    }

    /// Every measure of `p` against the reference.
    pub fn measure(&self, p: &Picture) -> Result<Metrics, CompareError> {
        self.measure_impl(p, None)
    }

    /// Every measure of `p` over the pixels whose `mask` entry is true.
    pub fn measure_masked(&self, p: &Picture, mask: &[bool]) -> Result<Metrics, CompareError> {
        self.measure_impl(p, Some(mask))
    }

    /// The per-pixel LDR-FLIP error of `p` (0..=1), for error pictures.
    pub fn flip_map(&self, p: &Picture) -> Result<Vec<f32>, CompareError> {
        check(p, &self.reference, None)?;
        let (w, h) = (p.width, p.height);
        Ok(flip::flip_map(
            &self.tone.apply(p),
            &self.ldr,
            w,
            h,
            self.pixels_per_degree,
        ))
    }

    fn measure_impl(&self, p: &Picture, mask: Option<&[bool]>) -> Result<Metrics, CompareError> {
        let b = &self.reference;
        let s = radiance::sums(p, b, mask, self.clamp)?;
        let band_relative_rmse = match &self.band {
            Some(band) => {
                let inside: Vec<bool> = match mask {
                    Some(m) => band.iter().zip(m).map(|(&x, &y)| x && y).collect(),
                    None => band.clone(),
                };
                Some(match radiance::sums(p, b, Some(&inside), self.clamp) {
                    Ok(s) => s.relative_rmse(),
                    Err(CompareError::NoPixels) => f64::NAN,
                    Err(e) => return Err(e),
                })
            }
            None => None,
        };
        let flip = flip::mean(&self.flip_map(p)?, mask);
        let hdr = flip::hdr_flip_map(p, b, &self.exposures, self.pixels_per_degree);
        Ok(Metrics {
            pixels: s.pixels,
            rmse: s.rmse(),
            relative_rmse: s.relative_rmse(),
            relative_mse: s.relative_mse(),
            clamped_relative_rmse: s.clamped_relative_rmse(),
            clamped_relative_mse: s.clamped_relative_mse(),
            clamp: self.clamp,
            psnr_db: s.psnr(None),
            ssim: ssim::ssim_impl(p, b, &self.tone, mask)?,
            flip,
            hdr_flip: flip::mean(&hdr, mask),
            band_relative_rmse,
            light: light::light_kept(
                p,
                self.halves.as_ref().map_or(b, |h| &h.1),
                &self.regions,
                self.band.as_deref(),
                mask,
            ),
            peak: light::peak_kept(p, b),
        })
    }
}

/// Every measure at once, over all pixels or those whose `mask` entry is
/// true, with the error instead of NaN when the pictures cannot be
/// compared: a [`Yardstick`] of `b` for one measurement (build one and keep
/// it to measure many pictures against one reference).
pub fn metrics(a: &Picture, b: &Picture, tone: &ToneMap, mask: Option<&[bool]>) -> Result<Metrics, CompareError> {
    check(a, b, mask)?;
    let y = Yardstick::new(b.clone(), tone.clone())?;
    y.measure_impl(a, mask)
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
pub(super) fn check(a: &Picture, b: &Picture, mask: Option<&[bool]>) -> Result<usize, CompareError> {
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
