//! Ward's shared-exponent RGBE color: three 8-bit mantissas and one 8-bit
//! exponent, covering about 76 orders of magnitude in four bytes.
//!
//! Conversion never lets NaN or infinity escape: non-finite and negative inputs
//! are sanitized on the way in, and every one of the 2^32 byte patterns decodes
//! to finite, non-negative components.

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

/// Exponent bias of the fourth byte (a byte value of 128 means 2^0 for a mantissa in [0.5, 1)).
const EXPONENT_BIAS: i32 = 128;

/// A color in RGBE format: bytes are red, green and blue mantissas then the shared exponent.
#[repr(transparent)]
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Pod, Zeroable, Serialize, Deserialize)]
pub struct Rgbe(pub [u8; 4]);

/// Largest value one channel can hold: mantissa 255 with exponent byte 255.
pub const RGBE_MAX: f32 = 255.0 / 256.0 * (1u128 << 127) as f32;

/// Splits a positive finite `x` into `m * 2^e` with `m` in [0.5, 1).
fn frexp(x: f64) -> (f64, i32) {
    let bits = x.to_bits();
    let biased = ((bits >> 52) & 0x7ff) as i32;
    if biased == 0 {
        // Subnormal: scale into the normal range first.
        let (m, e) = frexp(x * (1u64 << 54) as f64);
        return (m, e - 54);
    }
    let mantissa = f64::from_bits((bits & !(0x7ffu64 << 52)) | (1022u64 << 52));
    (mantissa, biased - 1022)
}

/// Replaces NaN and negative values by zero and clamps to the largest encodable value.
fn sanitize(c: f32) -> f64 {
    if c.is_nan() || c <= 0.0 {
        0.0
    } else {
        f64::from(c.min(RGBE_MAX))
    }
}

impl Rgbe {
    /// Black (all bytes zero).
    pub const ZERO: Rgbe = Rgbe([0; 4]);

    /// Encodes linear RGB radiance. NaN and negative channels become 0, +inf and
    /// values above [`RGBE_MAX`] saturate; values too small for the exponent become 0.
    pub fn from_rgb(rgb: [f32; 3]) -> Rgbe {
        let c = rgb.map(sanitize);
        let d = c[0].max(c[1]).max(c[2]);
        if d <= 0.0 {
            return Rgbe::ZERO;
        }
        let (m, e) = frexp(d);
        let exponent = e + EXPONENT_BIAS;
        if exponent < 1 {
            return Rgbe::ZERO;
        }
        // Saturation above guarantees exponent <= 255.
        let scale = m * 256.0 / d;
        let q = |v: f64| ((v * scale) as u32).min(255) as u8;
        Rgbe([q(c[0]), q(c[1]), q(c[2]), exponent.min(255) as u8])
    }

    /// Decodes to linear RGB at the center of each mantissa's quantization step.
    /// Always finite and non-negative.
    #[inline]
    pub fn to_rgb(self) -> [f32; 3] {
        let [r, g, b, e] = self.0;
        if e == 0 {
            return [0.0; 3];
        }
        let f = scale_of(e);
        [r, g, b].map(|m| ((f64::from(m) + 0.5) * f) as f32)
    }

    /// True when the pattern is what [`Rgbe::from_rgb`] produces (largest mantissa
    /// normalized to 128..=255, or all zero); only these round-trip byte for byte.
    pub fn is_canonical(self) -> bool {
        let [r, g, b, e] = self.0;
        if e == 0 {
            return r == 0 && g == 0 && b == 0;
        }
        r.max(g).max(b) >= 128
    }
}

/// 2^(e - 136), the value of a mantissa step for exponent byte `e` (1 to
/// 255): built from its bits (every such power is a normal `f64`), exactly
/// what `2f64.powi(e - 136)` gives, without its loop of multiplications.
#[inline]
fn scale_of(e: u8) -> f64 {
    let n = i64::from(e) - i64::from(EXPONENT_BIAS + 8);
    f64::from_bits(((n + 1023) as u64) << 52)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_exponent_scales_as_a_power_of_two() {
        for e in 1..=255u8 {
            assert_eq!(
                scale_of(e),
                2f64.powi(i32::from(e) - (EXPONENT_BIAS + 8)),
                "exponent byte {e}"
            );
        }
    }
    use proptest::prelude::*;

    #[test]
    fn zero_tiny_and_special_values() {
        assert_eq!(Rgbe::from_rgb([0.0; 3]), Rgbe::ZERO);
        assert_eq!(Rgbe::ZERO.to_rgb(), [0.0; 3]);
        assert_eq!(Rgbe::from_rgb([1e-45, 0.0, 0.0]), Rgbe::ZERO);
        assert_eq!(Rgbe::from_rgb([f32::NAN, -1.0, f32::NEG_INFINITY]), Rgbe::ZERO);
        let inf = Rgbe::from_rgb([f32::INFINITY, 1.0, 0.0]);
        assert_eq!(inf.0[3], 255);
        assert!(inf.to_rgb().iter().all(|c| c.is_finite()));
        // 1.0 is 0.5 * 2^1: mantissa 128, exponent byte 129.
        assert_eq!(Rgbe::from_rgb([1.0, 0.5, 0.25]), Rgbe([128, 64, 32, 129]));
    }

    #[test]
    fn every_byte_pattern_decodes_finite_and_canonical_ones_round_trip() {
        for e in 0..=255u8 {
            for m in 0..=255u8 {
                for other in [0u8, 1, 77, 127, 128, 254, 255] {
                    let c = Rgbe([m, other, other / 2, e]);
                    let rgb = c.to_rgb();
                    assert!(rgb.iter().all(|v| v.is_finite() && *v >= 0.0), "{c:?}");
                    if c.is_canonical() {
                        assert_eq!(Rgbe::from_rgb(rgb), c, "round trip of {c:?}");
                    }
                }
            }
        }
    }

    proptest! {
        #[test]
        fn rgb_round_trips_within_quantization(
            r in 0f32..1e6, g in 0f32..1e6, b in 0f32..1e6, scale_exp in -60i32..60
        ) {
            let s = 2f32.powi(scale_exp);
            let rgb = [r * s, g * s, b * s];
            let back = Rgbe::from_rgb(rgb).to_rgb();
            let max = rgb[0].max(rgb[1]).max(rgb[2]);
            // One mantissa step is max/128 at worst; decoding at step centers halves it.
            let step = f64::from(max) / 128.0;
            for k in 0..3 {
                let err = (f64::from(back[k]) - f64::from(rgb[k])).abs();
                prop_assert!(err <= step * 0.5 + 1e-300, "channel {k}: {rgb:?} -> {back:?}");
            }
        }
    }
}
