//! Radiance's sky luminance distributions, as its generators write them:
//! gensky's CIE skies (`skybr` in `skybright.cal`, and the older
//! `skybright` function of the same file) and gendaylit's Perez all-weather
//! sky (`skybright` in `perezlum.cal`). Each gives a brightness per
//! direction that multiplies the colour of the `glow` it modifies; both
//! blend into a constant ground brightness below the horizon with weights
//! (Dz + 1.01)^10 and (Dz + 1.01)^-10, as the `.cal` files do.

use serde::{Deserialize, Serialize};

/// The CIE sky types of `skybright.cal` (its first argument).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum CieSky {
    /// 1: CIE clear sky (gensky +s, -s).
    Clear,
    /// 2: CIE overcast sky (gensky -c).
    Overcast,
    /// 3: uniform sky (gensky -u).
    Uniform,
    /// 4: CIE intermediate sky (gensky +i, -i).
    Intermediate,
}

/// A sky brightness distribution with its arguments.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "model", rename_all = "lowercase", deny_unknown_fields)]
pub enum SkyDistribution {
    /// gensky's `skybright.cal`.
    Cie {
        /// Sky type (A1).
        kind: CieSky,
        /// Zenith brightness (A2).
        zenith: f32,
        /// Ground plane brightness (A3).
        ground: f32,
        /// Normalization factor for the sun's position (A4).
        normalization: f32,
        /// Unit direction toward the sun (A5, A6, A7).
        toward_sun: [f32; 3],
    },
    /// gendaylit's `perezlum.cal`.
    Perez {
        /// Diffuse normalization (A1).
        normalization: f32,
        /// Ground brightness (A2).
        ground: f32,
        /// The Perez model's coefficients a to e (A3 to A7).
        coefficients: [f32; 5],
        /// Unit direction toward the sun (A8, A9, A10).
        toward_sun: [f32; 3],
    },
}

/// Radiance's `Acos`: acos clamped to its domain.
fn acos(x: f64) -> f64 {
    x.clamp(-1.0, 1.0).acos()
}

/// Radiance's `wmean`.
fn wmean(a: f64, x: f64, b: f64, y: f64) -> f64 {
    (a * x + b * y) / (a + b)
}

impl SkyDistribution {
    /// The brightness in unit direction `d` (+z up), in double precision
    /// as Radiance's calculator evaluates it.
    pub fn brightness(&self, d: [f64; 3]) -> f64 {
        let [dx, dy, dz] = d;
        let above = (dz + 1.01).powi(10);
        let below = (dz + 1.01).powi(-10);
        match self {
            SkyDistribution::Cie {
                kind,
                zenith,
                ground,
                normalization,
                toward_sun: [sx, sy, sz],
            } => {
                let (a2, a4) = (f64::from(*zenith), f64::from(*normalization));
                let cosgamma = dx * f64::from(*sx) + dy * f64::from(*sy) + dz * f64::from(*sz);
                let gamma = acos(cosgamma);
                let sky = match kind {
                    CieSky::Clear => {
                        let horizon = if dz - 0.01 > 0.0 { 1.0 - (-0.32 / dz).exp() } else { 1.0 };
                        a2 * (0.91 + 10.0 * (-3.0 * gamma).exp() + 0.45 * cosgamma * cosgamma) * horizon / a4
                    }
                    CieSky::Overcast => a2 * (1.0 + 2.0 * dz) / 3.0,
                    CieSky::Uniform => a2,
                    CieSky::Intermediate => {
                        let zt = acos(f64::from(*sz));
                        let eta = acos(dz);
                        a2 * ((1.35 * (5.631 - 3.59 * eta).sin() + 3.12) * (4.396 - 2.6 * zt).sin() + 6.37 - eta)
                            / 2.326
                            * (gamma * -0.563 * ((2.629 - eta) * (1.562 - zt) + 0.812)).exp()
                            / a4
                    }
                };
                wmean(above, sky, below, f64::from(*ground))
            }
            SkyDistribution::Perez {
                normalization,
                ground,
                coefficients: [a, b, c, dd, e],
                toward_sun: [sx, sy, sz],
            } => {
                let cosgamma = dx * f64::from(*sx) + dy * f64::from(*sy) + dz * f64::from(*sz);
                let gamma = acos(cosgamma);
                let (a, b, c, dd, e) = (
                    f64::from(*a),
                    f64::from(*b),
                    f64::from(*c),
                    f64::from(*dd),
                    f64::from(*e),
                );
                let z = if dz - 0.01 > 0.0 { dz } else { 0.01 };
                let sky = f64::from(*normalization)
                    * (1.0 + a * (b / z).exp())
                    * (1.0 + c * (dd * gamma).exp() + e * gamma.cos() * gamma.cos());
                wmean(above, sky, below, f64::from(*ground))
            }
        }
    }

    /// Checks that every argument is finite, brightnesses are not negative
    /// and the sun direction is a direction; the error says which.
    pub fn validate(&self) -> Result<(), String> {
        let (numbers, toward): (Vec<f32>, [f32; 3]) = match self {
            SkyDistribution::Cie {
                zenith,
                ground,
                normalization,
                toward_sun,
                ..
            } => {
                if *zenith < 0.0 || *ground < 0.0 {
                    return Err("zenith and ground brightness must not be negative".into());
                }
                if *normalization == 0.0 {
                    return Err("normalization must not be zero".into());
                }
                (vec![*zenith, *ground, *normalization], *toward_sun)
            }
            SkyDistribution::Perez {
                normalization,
                ground,
                coefficients,
                toward_sun,
            } => {
                if *ground < 0.0 || *normalization < 0.0 {
                    return Err("normalization and ground brightness must not be negative".into());
                }
                let mut v = vec![*normalization, *ground];
                v.extend_from_slice(coefficients);
                (v, *toward_sun)
            }
        };
        if numbers.iter().chain(&toward).any(|v| !v.is_finite()) {
            return Err("every argument must be finite".into());
        }
        if toward.iter().all(|&v| v == 0.0) {
            return Err("the sun direction must not be zero".into());
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn below_the_horizon_the_ground_brightness_takes_over() {
        let clear = SkyDistribution::Cie {
            kind: CieSky::Clear,
            zenith: 35.6,
            ground: 43.8,
            normalization: 0.241,
            toward_sun: [0.0, -0.644_212, 0.764_848],
        };
        let down = clear.brightness([0.0, 0.0, -1.0]);
        assert!((down - 43.8).abs() < 1e-3 * 43.8, "{down}");
        let uniform = SkyDistribution::Cie {
            kind: CieSky::Uniform,
            zenith: 2.0,
            ground: 1.0,
            normalization: 1.0,
            toward_sun: [0.0, 0.0, 1.0],
        };
        // Straight up the weights are 2.01^10 and 2.01^-10: all sky.
        assert!((uniform.brightness([0.0, 0.0, 1.0]) - 2.0).abs() < 1e-5);
        assert!(clear.validate().is_ok());
        let bad = SkyDistribution::Cie {
            kind: CieSky::Clear,
            zenith: f32::NAN,
            ground: 1.0,
            normalization: 1.0,
            toward_sun: [0.0, 0.0, 1.0],
        };
        assert!(bad.validate().is_err());
    }
}
