//! Material and sky descriptions: plain parameters, as written in scene files.
//! How they scatter light is in `crate::shade`.

use serde::{Deserialize, Serialize};

use super::sky_distribution::SkyDistribution;

/// A surface's reflectance model. Colors are linear RGB in [0, 1] unless noted.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Material {
    /// Ideal diffuse reflector, optionally glowing (a lampshade, a furnace wall).
    Lambertian {
        /// Diffuse reflectance.
        albedo: [f32; 3],
        /// Radiance emitted from the front face, besides what it reflects.
        #[serde(default)]
        emission: [f32; 3],
    },
    /// Diffuse base under a dielectric coat with GGX roughness (varnish, plastic).
    Plastic {
        /// Diffuse reflectance of the base.
        albedo: [f32; 3],
        /// GGX roughness (alpha = roughness²), 0 = polished.
        roughness: f32,
        /// Index of refraction of the coat (1.5 typical).
        #[serde(default = "default_ior")]
        ior: f32,
    },
    /// Conductor with GGX roughness; `color` is the reflectance at normal incidence.
    Metal {
        /// Reflectance at normal incidence.
        color: [f32; 3],
        /// GGX roughness, 0 = polished.
        roughness: f32,
    },
    /// Perfect specular reflector (flat mirrors get virtual distances).
    Mirror {
        /// Reflectance.
        color: [f32; 3],
    },
    /// Smooth dielectric: Fresnel reflection and refraction.
    Glass {
        /// Index of refraction.
        ior: f32,
        /// Transmission tint.
        #[serde(default = "white")]
        color: [f32; 3],
        /// A thin sheet (window pane): rays pass straight through, no bending.
        #[serde(default)]
        thin: bool,
    },
    /// Area light: emits `radiance` (W/sr/m², RGB) from its front face, reflects nothing.
    Emitter {
        /// Emitted radiance.
        radiance: [f32; 3],
    },
}

fn default_ior() -> f32 {
    1.5
}

fn white() -> [f32; 3] {
    [1.0; 3]
}

impl Material {
    /// Radiance emitted from the front face (zero for non-emitters).
    pub fn emission(&self) -> [f32; 3] {
        match self {
            Material::Emitter { radiance } => *radiance,
            Material::Lambertian { emission, .. } => *emission,
            _ => [0.0; 3],
        }
    }

    /// A plain diffuse reflector.
    pub fn lambertian(albedo: [f32; 3]) -> Material {
        Material::Lambertian {
            albedo,
            emission: [0.0; 3],
        }
    }

    /// Checks parameter ranges; the error names the parameter.
    pub fn validate(&self) -> Result<(), MaterialError> {
        let unit = |key: &'static str, value: &[f32; 3]| {
            if value.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v)) {
                Ok(())
            } else {
                Err(MaterialError::NotUnit { key, value: *value })
            }
        };
        let radiance = |key: &'static str, value: &[f32; 3]| {
            if value.iter().all(|v| v.is_finite() && *v >= 0.0) {
                Ok(())
            } else {
                Err(MaterialError::NotRadiance { key, value: *value })
            }
        };
        let rough = |r: f32| {
            if r.is_finite() && (0.0..=1.0).contains(&r) {
                Ok(())
            } else {
                Err(MaterialError::Roughness(r))
            }
        };
        let ior = |n: f32| {
            if n.is_finite() && n >= 1.0 {
                Ok(())
            } else {
                Err(MaterialError::Ior(n))
            }
        };
        match self {
            Material::Lambertian { albedo, emission } => {
                unit("albedo", albedo)?;
                radiance("emission", emission)
            }
            Material::Plastic {
                albedo,
                roughness,
                ior: n,
            } => {
                unit("albedo", albedo)?;
                rough(*roughness)?;
                ior(*n)
            }
            Material::Metal { color, roughness } => {
                unit("color", color)?;
                rough(*roughness)
            }
            Material::Mirror { color } => unit("color", color),
            Material::Glass { ior: n, color, .. } => {
                ior(*n)?;
                unit("color", color)
            }
            Material::Emitter { radiance: r } => radiance("radiance", r),
        }
    }
}

/// Why a material's parameters are impossible, naming the parameter.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum MaterialError {
    /// A reflectance outside [0, 1] (it would create energy) or not finite.
    #[error("{key} {value:?} must be in [0, 1]")]
    NotUnit {
        /// `albedo` or `color`.
        key: &'static str,
        /// The value given.
        value: [f32; 3],
    },
    /// An emitted radiance that is negative or not finite.
    #[error("{key} {value:?} must be finite and non-negative")]
    NotRadiance {
        /// `emission` or `radiance`.
        key: &'static str,
        /// The value given.
        value: [f32; 3],
    },
    /// A roughness outside [0, 1].
    #[error("roughness {0} must be in [0, 1]")]
    Roughness(f32),
    /// An index of refraction below 1 or not finite.
    #[error("ior {0} must be at least 1")]
    Ior(f32),
}

/// What rays that leave the scene see.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[serde(tag = "type", rename_all = "lowercase", deny_unknown_fields)]
pub enum Sky {
    /// Black.
    #[default]
    None,
    /// The same radiance from every direction.
    Constant {
        /// Radiance.
        radiance: [f32; 3],
    },
    /// A sun disk plus a sky that blends from horizon to zenith color (+z is up),
    /// and a ground color below the horizon.
    Sun {
        /// Direction toward the sun (normalized on use).
        direction: [f32; 3],
        /// Radiance of the sun disk.
        sun_radiance: [f32; 3],
        /// Angular diameter of the sun, degrees (0.53 for the real one).
        #[serde(default = "sun_diameter")]
        diameter_deg: f32,
        /// Sky radiance straight up.
        zenith: [f32; 3],
        /// Sky radiance at the horizon.
        horizon: [f32; 3],
        /// Radiance below the horizon.
        ground: [f32; 3],
    },
    /// A Radiance sky: a brightness distribution (gensky's CIE skies,
    /// gendaylit's Perez sky) times one colour above the horizon and
    /// another below (the `glow`s it modifies), with an optional sun.
    Radiance {
        /// The brightness per direction.
        distribution: SkyDistribution,
        /// Colour multiplying it above the horizon (the sky glow's).
        sky: [f32; 3],
        /// Colour multiplying it below the horizon (the ground glow's; black without one).
        ground: [f32; 3],
        /// Whether the distribution shapes the sky above the horizon (else
        /// `sky` is sent uniformly, as a glow with no `skyfunc` does).
        #[serde(default = "yes")]
        sky_shaped: bool,
        /// The same below the horizon.
        #[serde(default = "yes")]
        ground_shaped: bool,
        /// The sun (gensky's `light` source), if any.
        #[serde(default, skip_serializing_if = "Option::is_none")]
        sun: Option<SunDisk>,
    },
}

fn yes() -> bool {
    true
}

fn sun_diameter() -> f32 {
    0.53
}

/// A sun disk: direction, radiance and angular size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SunDisk {
    /// Direction toward the sun (normalized on use).
    pub direction: [f32; 3],
    /// Radiance of the disk.
    pub radiance: [f32; 3],
    /// Angular diameter, degrees.
    #[serde(default = "sun_diameter")]
    pub diameter_deg: f32,
}

impl Sky {
    /// Checks that the sun has a direction and every radiance is finite and
    /// non-negative; the error names the key.
    pub fn validate(&self) -> Result<(), SkyError> {
        let radiance = |key: &'static str, value: &[f32; 3]| {
            if value.iter().all(|v| v.is_finite() && *v >= 0.0) {
                Ok(())
            } else {
                Err(SkyError::Radiance { key, value: *value })
            }
        };
        match self {
            Sky::None => Ok(()),
            Sky::Constant { radiance: r } => radiance("radiance", r),
            Sky::Sun {
                direction,
                sun_radiance,
                diameter_deg,
                zenith,
                horizon,
                ground,
            } => {
                // Normalizing divides by the length: it must be finite and above zero.
                let length = direction.iter().map(|c| f64::from(*c).powi(2)).sum::<f64>().sqrt();
                if !(length.is_finite() && length > 0.0) {
                    return Err(SkyError::Direction(*direction));
                }
                if !(*diameter_deg > 0.0 && *diameter_deg <= 180.0) {
                    return Err(SkyError::Diameter(*diameter_deg));
                }
                radiance("sun_radiance", sun_radiance)?;
                radiance("zenith", zenith)?;
                radiance("horizon", horizon)?;
                radiance("ground", ground)
            }
            Sky::Radiance {
                distribution,
                sky,
                ground,
                sun,
                ..
            } => {
                distribution.validate().map_err(SkyError::Distribution)?;
                radiance("sky", sky)?;
                radiance("ground", ground)?;
                if let Some(s) = sun {
                    Sky::Sun {
                        direction: s.direction,
                        sun_radiance: s.radiance,
                        diameter_deg: s.diameter_deg,
                        zenith: [0.0; 3],
                        horizon: [0.0; 3],
                        ground: [0.0; 3],
                    }
                    .validate()?;
                }
                Ok(())
            }
        }
    }
}

/// Why a sky's parameters are impossible, naming the key.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum SkyError {
    /// A brightness distribution with impossible arguments.
    #[error("distribution: {0}")]
    Distribution(String),
    /// A sun direction that is zero or not finite: it points nowhere.
    #[error("direction {0:?} must be finite and not zero: it points toward the sun")]
    Direction([f32; 3]),
    /// A sun whose angular diameter is not in (0, 180] degrees.
    #[error("diameter_deg {0} must be above 0 and at most 180 degrees")]
    Diameter(f32),
    /// A radiance that is negative or not finite.
    #[error("{key} {value:?} must be finite and non-negative")]
    Radiance {
        /// Which radiance.
        key: &'static str,
        /// The value given.
        value: [f32; 3],
    },
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sun(direction: [f32; 3], diameter_deg: f32) -> Sky {
        Sky::Sun {
            direction,
            sun_radiance: [1e5; 3],
            diameter_deg,
            zenith: [0.2, 0.3, 0.6],
            horizon: [0.6; 3],
            ground: [0.1; 3],
        }
    }

    #[test]
    fn skies_without_a_sun_direction_or_with_negative_light_are_refused() {
        assert_eq!(sun([0.2, 0.1, 1.0], 0.53).validate(), Ok(()));
        assert_eq!(sun([1e-30, 0.0, 0.0], 0.53).validate(), Ok(()), "tiny but a direction");
        assert_eq!(sun([0.0; 3], 0.53).validate(), Err(SkyError::Direction([0.0; 3])));
        assert!(matches!(
            sun([f32::NAN, 0.0, 1.0], 0.53).validate(),
            Err(SkyError::Direction(_))
        ));
        assert!(matches!(sun([f32::MAX, f32::MAX, 0.0], 0.53).validate(), Ok(())));
        assert_eq!(sun([0.0, 0.0, 1.0], 0.0).validate(), Err(SkyError::Diameter(0.0)));
        let dark = Sky::Constant {
            radiance: [-1.0, 0.0, 0.0],
        };
        assert_eq!(
            dark.validate(),
            Err(SkyError::Radiance {
                key: "radiance",
                value: [-1.0, 0.0, 0.0]
            })
        );
        assert!(sun([0.0; 3], 0.53)
            .validate()
            .unwrap_err()
            .to_string()
            .starts_with("direction"));
    }

    #[test]
    fn material_errors_name_the_parameter() {
        let glass = Material::Glass {
            ior: 0.5,
            color: [1.0; 3],
            thin: false,
        };
        assert_eq!(glass.validate(), Err(MaterialError::Ior(0.5)));
        let lamp = Material::Lambertian {
            albedo: [0.5; 3],
            emission: [f32::INFINITY, 0.0, 0.0],
        };
        assert!(matches!(
            lamp.validate(),
            Err(MaterialError::NotRadiance { key: "emission", .. })
        ));
        assert_eq!(Material::lambertian([0.5; 3]).validate(), Ok(()));
    }
}
