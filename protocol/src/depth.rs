//! The 16-bit depth code of a ray record: distance from the entry wall.
//!
//! Codes below 2^11 are linear in steps of diagonal / 2^11; above, each code is a
//! factor (1 + 2^-11) further, so the largest finite code reaches about
//! 3e13 section diagonals. Code 0xFFFF means the ray escaped to infinity.
//!
//! Sections imported from Radiance keep Radiance's own coding
//! ([`DepthCoding::Radiance`]): the same 2^11 linear and logarithmic steps,
//! scaled by the sum of the section's axis lengths, with codes that truncate
//! and decode to the middle of their step. A section records which coding its
//! rays use, so imported codes are kept exactly and new rays match them.

use serde::{Deserialize, Serialize};

/// Number of linear codes; also the code of a distance of exactly one diagonal.
pub const DEPTH_LINEAR_CODES: u16 = 1 << 11;

/// The code of a ray that hit nothing.
pub const DEPTH_INFINITE: u16 = u16::MAX;

/// Ratio between successive logarithmic codes; matches the linear step at the border.
const LOG_STEP: f64 = 1.0 + 1.0 / DEPTH_LINEAR_CODES as f64;

/// A quantized ray distance, relative to a section's diagonal length.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord, Hash, Serialize, Deserialize)]
pub struct DepthCode(pub u16);

impl DepthCode {
    /// The code of a ray that escaped the scene.
    pub const INFINITE: DepthCode = DepthCode(DEPTH_INFINITE);

    /// Encodes `distance` (world units from the entry wall) for a section whose
    /// diagonal is `diagonal` world units. Negative distances become 0; NaN,
    /// infinity and distances beyond the largest finite code become [`DepthCode::INFINITE`].
    pub fn encode(distance: f64, diagonal: f64) -> DepthCode {
        if distance.is_nan() || distance == f64::INFINITY {
            return DepthCode::INFINITE;
        }
        if distance <= 0.0 {
            return DepthCode(0);
        }
        let linear = distance / diagonal * f64::from(DEPTH_LINEAR_CODES);
        if linear < f64::from(DEPTH_LINEAR_CODES) {
            // Rounding may give 2^11, which is also the log range's first code: consistent.
            return DepthCode(linear.round() as u16);
        }
        let steps = ((distance / diagonal).ln() / LOG_STEP.ln()).round();
        let code = f64::from(DEPTH_LINEAR_CODES) + steps;
        if code >= f64::from(DEPTH_INFINITE) {
            DepthCode::INFINITE
        } else {
            DepthCode(code as u16)
        }
    }

    /// Decodes to world units, or `None` for a ray that escaped.
    pub fn decode(self, diagonal: f64) -> Option<f64> {
        match self.0 {
            DEPTH_INFINITE => None,
            c if c < DEPTH_LINEAR_CODES => Some(f64::from(c) * diagonal / f64::from(DEPTH_LINEAR_CODES)),
            c => Some(diagonal * LOG_STEP.powi(i32::from(c - DEPTH_LINEAR_CODES))),
        }
    }

    /// True for the escaped-ray code.
    pub fn is_infinite(self) -> bool {
        self.0 == DEPTH_INFINITE
    }

    /// Largest finite distance that can be encoded, in world units.
    pub fn max_finite(diagonal: f64) -> f64 {
        DepthCode(DEPTH_INFINITE - 1).decode(diagonal).unwrap_or(f64::MAX)
    }
}

/// How a section's depth codes map to distances.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum DepthCoding {
    /// This program's coding ([`DepthCode::encode`]): scaled by the section's
    /// main diagonal, codes rounded to the nearest step.
    #[default]
    Holodeck,
    /// Radiance's (`hdcode`/`hddepth` in rholo): scaled by the sum of the
    /// section's axis lengths, codes truncated, decoded at the middle of the step.
    Radiance,
}

/// Radiance's infinite distance (`FHUGE`); distances from 0.99 of it are infinite.
const RADIANCE_HUGE: f64 = 1e10;

impl DepthCoding {
    /// The name used in section lines and scene files.
    pub fn name(self) -> &'static str {
        match self {
            DepthCoding::Holodeck => "holodeck",
            DepthCoding::Radiance => "radiance",
        }
    }

    /// The coding of `name` ([`DepthCoding::name`]).
    pub fn from_name(name: &str) -> Option<DepthCoding> {
        match name {
            "holodeck" => Some(DepthCoding::Holodeck),
            "radiance" => Some(DepthCoding::Radiance),
            _ => None,
        }
    }

    /// Encodes `distance` (world units from the entry wall) for a section whose
    /// depth scale ([`crate::Section::depth_scale`]) is `scale`.
    pub fn encode(self, distance: f64, scale: f64) -> DepthCode {
        match self {
            DepthCoding::Holodeck => DepthCode::encode(distance, scale),
            DepthCoding::Radiance => {
                if distance.is_nan() || distance >= 0.99 * RADIANCE_HUGE {
                    return DepthCode::INFINITE;
                }
                if distance <= 0.0 {
                    return DepthCode(0);
                }
                let linear = f64::from(DEPTH_LINEAR_CODES);
                if distance < scale {
                    // Below one scale the truncated code is below 2^11.
                    return DepthCode((distance * linear / scale) as u16);
                }
                let code = ((distance / scale).ln() / LOG_STEP.ln()).floor() + linear;
                DepthCode(code.min(f64::from(DEPTH_INFINITE)) as u16)
            }
        }
    }

    /// Decodes to world units, or `None` for a ray that escaped.
    pub fn decode(self, code: DepthCode, scale: f64) -> Option<f64> {
        match self {
            DepthCoding::Holodeck => code.decode(scale),
            DepthCoding::Radiance => match code.0 {
                DEPTH_INFINITE => None,
                c if c < DEPTH_LINEAR_CODES => Some(scale * (f64::from(c) + 0.5) / f64::from(DEPTH_LINEAR_CODES)),
                c => Some(
                    scale
                        * (1.0 + 0.5 / f64::from(DEPTH_LINEAR_CODES))
                        * LOG_STEP.powi(i32::from(c - DEPTH_LINEAR_CODES)),
                ),
            },
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    #[test]
    fn border_and_extremes() {
        let diag = 7.5;
        assert_eq!(DepthCode::encode(0.0, diag), DepthCode(0));
        assert_eq!(DepthCode::encode(-3.0, diag), DepthCode(0));
        assert_eq!(DepthCode::encode(diag, diag), DepthCode(DEPTH_LINEAR_CODES));
        assert_eq!(DepthCode::encode(f64::INFINITY, diag), DepthCode::INFINITE);
        assert_eq!(DepthCode::encode(f64::NAN, diag), DepthCode::INFINITE);
        assert_eq!(DepthCode::encode(1e300, diag), DepthCode::INFINITE);
        assert_eq!(DepthCode::INFINITE.decode(diag), None);
        let max = DepthCode::max_finite(diag) / diag;
        assert!(max > 1e13 && max < 1e14, "max finite distance {max} diagonals");
        // Decoding is monotonic and continuous across the linear/log border.
        let below = DepthCode(DEPTH_LINEAR_CODES - 1).decode(diag).unwrap();
        let at = DepthCode(DEPTH_LINEAR_CODES).decode(diag).unwrap();
        let above = DepthCode(DEPTH_LINEAR_CODES + 1).decode(diag).unwrap();
        assert!((at - below - (above - at)).abs() < 1e-6 * diag);
    }

    #[test]
    fn every_finite_code_round_trips_exactly() {
        let diag = 3.25;
        for c in 0..DEPTH_INFINITE {
            let d = DepthCode(c).decode(diag).unwrap();
            assert_eq!(DepthCode::encode(d, diag), DepthCode(c), "code {c} -> {d}");
        }
    }

    #[test]
    fn radiance_codes_match_rholos_worked_values_and_round_trip() {
        let r = DepthCoding::Radiance;
        // rholo with axis lengths summing to 6: 1.5 -> 512, 2.5 -> 853, 10 -> 3094;
        // code 3072 reads back as 9.8935.
        assert_eq!(r.encode(1.5, 6.0), DepthCode(512));
        assert_eq!(r.encode(2.5, 6.0), DepthCode(853));
        assert_eq!(r.encode(10.0, 6.0), DepthCode(3094));
        assert!((r.decode(DepthCode(3072), 6.0).unwrap() - 9.8935).abs() < 1e-4);
        assert_eq!(r.encode(-1.0, 6.0), DepthCode(0));
        assert_eq!(r.encode(1e10, 6.0), DepthCode::INFINITE);
        assert_eq!(r.decode(DepthCode::INFINITE, 6.0), None);
        // Every code decodes to the middle of its step, which encodes back to
        // it, up to Radiance's infinity (0.99e10).
        let mut kept = 0;
        for c in (0..DEPTH_INFINITE).step_by(7) {
            let d = r.decode(DepthCode(c), 6.0).unwrap();
            if d < 0.99e10 {
                assert_eq!(r.encode(d, 6.0), DepthCode(c), "code {c} -> {d}");
                kept += 1;
            } else {
                assert_eq!(r.encode(d, 6.0), DepthCode::INFINITE, "code {c} -> {d}");
            }
        }
        assert!(kept > 6000, "{kept}");
        assert_eq!(DepthCoding::from_name(r.name()), Some(r));
        assert_eq!(DepthCoding::from_name("holodeck"), Some(DepthCoding::Holodeck));
    }

    proptest! {
        #[test]
        fn distances_round_trip_within_half_a_step(
            log_d in -8f64..30.0, diag in 0.01f64..1000.0
        ) {
            let d = diag * 10f64.powf(log_d);
            prop_assume!(d < DepthCode::max_finite(diag));
            let back = DepthCode::encode(d, diag).decode(diag).unwrap();
            // 0.05% relative in the log range; below one diagonal the linear
            // step bounds the error to 0.05% of the diagonal.
            let tolerance = 5e-4 * d.max(diag);
            prop_assert!((back - d).abs() <= tolerance, "{d} -> {back}");
            if d >= diag {
                prop_assert!((back - d).abs() <= 2.5e-4 * d);
            }
        }
    }
}
