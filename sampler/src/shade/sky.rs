//! What escaping rays see: a constant sky, or a sun disk over a sky that blends
//! from horizon to zenith with a ground color below (+z up). The sun is small
//! and bright, so it is also sampled directly.

use glam::Vec3;

use super::sampling::{uniform_cone, Frame};
use crate::scene::sky_distribution::SkyDistribution;
use crate::scene::Sky;

/// A sky ready for shading.
#[derive(Clone, Debug)]
pub struct SkyModel {
    background: Background,
    sun: Option<Sun>,
}

#[derive(Clone, Debug)]
enum Background {
    Constant(Vec3),
    Gradient {
        zenith: Vec3,
        horizon: Vec3,
        ground: Vec3,
    },
    Distribution {
        brightness: SkyDistribution,
        sky: Vec3,
        ground: Vec3,
        shaped: [bool; 2],
    },
}

#[derive(Clone, Debug)]
struct Sun {
    frame: Frame,
    cos_max: f32,
    one_minus_cos: f32,
    radiance: Vec3,
}

impl Sun {
    /// A sun toward `direction` (any length) of `radiance`, `diameter_deg`
    /// across; `None` where it points nowhere or has no size.
    fn new(direction: &[f32; 3], radiance: &[f32; 3], diameter_deg: f32) -> Option<Sun> {
        // Normalized in double precision: huge or tiny directions
        // would overflow or underflow single precision on the way.
        let dir = Vec3::from_array(*direction).as_dvec3();
        let length = dir.length();
        let pointed = length > 0.0 && length.is_finite();
        (pointed && diameter_deg > 0.0 && diameter_deg <= 180.0).then(|| Sun {
            frame: Frame::new((dir / length).as_vec3()),
            cos_max: (f64::from(diameter_deg).to_radians() * 0.5).cos() as f32,
            one_minus_cos: {
                // 1 - cos(x) = 2 sin^2(x/2): exact even for a tiny sun.
                let h = (f64::from(diameter_deg).to_radians() * 0.25).sin();
                (2.0 * h * h) as f32
            },
            radiance: Vec3::from_array(*radiance).max(Vec3::ZERO).min(Vec3::splat(f32::MAX)),
        })
    }
}

impl SkyModel {
    /// Prepares a scene's sky. Non-finite or negative values become black.
    pub fn new(sky: &Sky) -> SkyModel {
        let c = |v: &[f32; 3]| Vec3::from_array(*v).max(Vec3::ZERO).min(Vec3::splat(f32::MAX));
        match sky {
            Sky::None => SkyModel {
                background: Background::Constant(Vec3::ZERO),
                sun: None,
            },
            Sky::Constant { radiance } => SkyModel {
                background: Background::Constant(c(radiance)),
                sun: None,
            },
            Sky::Sun {
                direction,
                sun_radiance,
                diameter_deg,
                zenith,
                horizon,
                ground,
            } => {
                let sun = Sun::new(direction, sun_radiance, *diameter_deg);
                SkyModel {
                    background: Background::Gradient {
                        zenith: c(zenith),
                        horizon: c(horizon),
                        ground: c(ground),
                    },
                    sun,
                }
            }
            Sky::Radiance {
                distribution,
                sky,
                ground,
                sky_shaped,
                ground_shaped,
                sun,
            } => SkyModel {
                background: Background::Distribution {
                    brightness: distribution.clone(),
                    sky: c(sky),
                    ground: c(ground),
                    shaped: [*sky_shaped, *ground_shaped],
                },
                sun: sun
                    .as_ref()
                    .and_then(|s| Sun::new(&s.direction, &s.radiance, s.diameter_deg)),
            },
        }
    }

    /// Radiance from direction `d` (unit), sun excluded.
    pub fn background(&self, d: Vec3) -> Vec3 {
        match &self.background {
            Background::Constant(c) => *c,
            Background::Gradient {
                zenith,
                horizon,
                ground,
            } => {
                if d.z < 0.0 {
                    *ground
                } else {
                    let t = d.z.sqrt();
                    *horizon * (1.0 - t) + *zenith * t
                }
            }
            Background::Distribution {
                brightness,
                sky,
                ground,
                shaped,
            } => {
                let (color, shaped) = if d.z < 0.0 {
                    (*ground, shaped[1])
                } else {
                    (*sky, shaped[0])
                };
                if !shaped {
                    return color;
                }
                let b = brightness.brightness(d.as_dvec3().to_array()) as f32;
                color * if b.is_finite() { b.max(0.0) } else { 0.0 }
            }
        }
    }

    /// True when there is a sun to sample.
    pub fn has_sun(&self) -> bool {
        self.sun.is_some()
    }

    /// Sun radiance if `d` (unit) points into the sun's disk, else zero.
    pub fn sun(&self, d: Vec3) -> Vec3 {
        match &self.sun {
            Some(s) if d.dot(s.frame.n) >= s.cos_max => s.radiance,
            _ => Vec3::ZERO,
        }
    }

    /// Pdf (solid angle) of [`SkyModel::sample_sun`].
    pub fn sun_pdf(&self) -> f32 {
        self.sun
            .as_ref()
            .map_or(0.0, |s| 1.0 / (2.0 * std::f32::consts::PI * s.one_minus_cos))
    }

    /// A direction toward the sun's disk, with the sun's radiance and the pdf.
    pub fn sample_sun(&self, u: (f32, f32)) -> Option<(Vec3, Vec3, f32)> {
        let s = self.sun.as_ref()?;
        let d = s.frame.to_world(uniform_cone(u, s.cos_max));
        Some((d, s.radiance, 1.0 / (2.0 * std::f32::consts::PI * s.one_minus_cos)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn suns_point_where_their_direction_says_however_long_it_is() {
        for direction in [[f32::MAX, f32::MAX, 0.0], [1e-30, 1e-30, 0.0], [3.0, 3.0, 0.0]] {
            let sky = SkyModel::new(&Sky::Sun {
                direction,
                sun_radiance: [5.0; 3],
                diameter_deg: 1.0,
                zenith: [0.0; 3],
                horizon: [0.0; 3],
                ground: [0.0; 3],
            });
            let toward = Vec3::new(1.0, 1.0, 0.0).normalize();
            assert_eq!(sky.sun(toward), Vec3::splat(5.0), "{direction:?}");
            assert_eq!(sky.sun(Vec3::Z), Vec3::ZERO, "{direction:?}");
        }
    }
}
