//! FLIP (Andersson et al., "FLIP: A Difference Evaluator for Alternating
//! Images", HPG 2020), NVIDIA's perceptual difference of two pictures as a
//! viewer flipping between them sees it, through the reference
//! implementation (the `nv-flip` crate). LDR-FLIP compares what a display
//! shows; HDR-FLIP ("Visualizing Errors in Rendered High Dynamic Range
//! Images", Eurographics 2021) takes, per pixel, the largest LDR-FLIP over a
//! range of exposures of both pictures tone mapped alike, so that an error
//! in a highlight or in a shadow counts at the exposure that shows it.

use glam::Vec3;
use holodeck_protocol::Picture;

use super::radiance::channels;
use crate::tonemap::encode_srgb;

/// Pixels per degree of visual angle FLIP assumes by default: a 0.7 m wide
/// 4K monitor seen from 0.7 m.
pub const PIXELS_PER_DEGREE: f32 = 67.0;

/// The per-pixel LDR-FLIP error (0..=1) of `test` against `reference`, both
/// 8-bit sRGB, three bytes a pixel, `width` x `height`, rows from the top.
///
/// # Panics
/// If either slice holds fewer than `3 * width * height` bytes (the callers
/// in this module check sizes first).
pub fn flip_map(test: &[u8], reference: &[u8], width: usize, height: usize, pixels_per_degree: f32) -> Vec<f32> {
    let (w, h) = (width as u32, height as u32);
    let r = nv_flip::FlipImageRgb8::with_data(w, h, reference);
    let t = nv_flip::FlipImageRgb8::with_data(w, h, test);
    nv_flip::flip(r, t, pixels_per_degree).to_vec()
}

/// The ACES filmic curve HDR-FLIP tone maps with (Narkowicz's fit, with
/// the reference implementation's 0.6 pre-exposure cancelled).
fn aces(x: f64) -> f64 {
    const C: [f64; 6] = [0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14];
    let x = x.max(0.0);
    ((x * (C[0] * x + C[1]) + C[2]) / (x * (C[3] * x + C[4]) + C[5])).clamp(0.0, 1.0)
}

/// Rec. 709 luminance of a pixel (black when not finite).
fn luminance(v: Vec3) -> f64 {
    let c = channels(v);
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// The exposures HDR-FLIP compares at, chosen from the reference as the
/// reference implementation chooses them: from the exposure that maps the
/// reference's brightest luminance to 0.85 of the tone curve's white, to the
/// one that maps its median there, in whole stops (at least two).
#[derive(Clone, Debug, PartialEq)]
pub struct Exposures {
    /// log2 of the scale of each exposure.
    pub stops: Vec<f64>,
}

impl Exposures {
    /// The exposures for `reference`; a black reference gets one exposure
    /// of 1.
    pub fn of(reference: &Picture) -> Exposures {
        // The x where the ACES curve reaches t = 0.85: a x² + b x + c = 0.
        const C: [f64; 6] = [0.6 * 0.6 * 2.51, 0.6 * 0.03, 0.0, 0.6 * 0.6 * 2.43, 0.6 * 0.59, 0.14];
        let t = 0.85;
        let (a, b, c) = (C[0] - t * C[3], C[1] - t * C[4], C[2] - t * C[5]);
        let disc = (b * b - 4.0 * a * c).max(0.0).sqrt();
        let x_max = ((-b + disc) / (2.0 * a)).max((-b - disc) / (2.0 * a));
        let mut l: Vec<f64> = reference.pixels.iter().map(|&v| luminance(v)).collect();
        if l.is_empty() {
            return Exposures { stops: vec![0.0] };
        }
        l.sort_by(f64::total_cmp);
        let max = l[l.len() - 1];
        let mid = l.len() / 2;
        let median = if l.len() >= 2 {
            0.5 * (l[mid - 1] + l[mid])
        } else {
            l[0]
        };
        if max.is_nan() || max <= 0.0 {
            return Exposures { stops: vec![0.0] };
        }
        let start = (x_max / max).log2();
        // A median of 0 (a mostly black picture) stops where the brightest
        // stops plus a few, not at infinity.
        let stop = if median > 0.0 {
            (x_max / median).log2()
        } else {
            start + 8.0
        };
        let count = ((stop - start).ceil() as usize).max(2);
        let step = (stop - start) / (count - 1) as f64;
        Exposures {
            stops: (0..count).map(|i| start + step * i as f64).collect(),
        }
    }

    /// `p` at exposure `stop`, tone mapped by ACES into 8-bit sRGB.
    fn apply(p: &Picture, stop: f64) -> Vec<u8> {
        let m = stop.exp2();
        p.pixels
            .iter()
            .flat_map(|&v| channels(v).map(|c| encode_srgb(aces(c * m) as f32)))
            .collect()
    }
}

/// The per-pixel HDR-FLIP error of `test` against `reference` over
/// `exposures` (the largest LDR-FLIP of any exposure, each exposure's
/// pictures tone mapped by ACES and quantized to 8-bit sRGB as the reference
/// implementation's LDR path takes them).
pub fn hdr_flip_map(test: &Picture, reference: &Picture, exposures: &Exposures, pixels_per_degree: f32) -> Vec<f32> {
    let (w, h) = (reference.width, reference.height);
    let mut out = vec![0.0f32; w * h];
    for &stop in &exposures.stops {
        let t = Exposures::apply(test, stop);
        let r = Exposures::apply(reference, stop);
        for (o, e) in out.iter_mut().zip(flip_map(&t, &r, w, h, pixels_per_degree)) {
            *o = o.max(e);
        }
    }
    out
}

/// The mean of `map` over the pixels whose `mask` entry is true (all
/// without a mask); NaN for none.
pub(super) fn mean(map: &[f32], mask: Option<&[bool]>) -> f64 {
    let (mut sum, mut n) = (0.0f64, 0usize);
    for (i, &e) in map.iter().enumerate() {
        if mask.is_none_or(|m| m[i]) {
            sum += f64::from(e);
            n += 1;
        }
    }
    if n == 0 {
        f64::NAN
    } else {
        sum / n as f64
    }
}
