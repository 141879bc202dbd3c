//! The 16-bit depth code of a ray record: distance from the entry wall.
//!
//! Codes below 2^11 are linear in steps of diagonal / 2^11; above, each code is a
//! factor (1 + 2^-11) further, so the largest finite code reaches about
//! 3e13 section diagonals. Code 0xFFFF means the ray escaped to infinity.

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
