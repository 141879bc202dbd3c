//! Material and sky descriptions: plain parameters, as written in scene files.
//! How they scatter light is in `crate::shade`.

use serde::{Deserialize, Serialize};

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

    /// Checks parameter ranges; returns what is wrong.
    pub fn validate(&self) -> Result<(), String> {
        let color_ok = |c: &[f32; 3]| c.iter().all(|v| v.is_finite() && *v >= 0.0);
        let unit_ok = |c: &[f32; 3]| c.iter().all(|v| v.is_finite() && (0.0..=1.0).contains(v));
        let rough_ok = |r: f32| r.is_finite() && (0.0..=1.0).contains(&r);
        match self {
            Material::Lambertian { albedo, .. } if !unit_ok(albedo) => {
                Err(format!("albedo {albedo:?} must be in [0, 1]"))
            }
            Material::Lambertian { emission, .. } if !color_ok(emission) => {
                Err(format!("emission {emission:?} must be finite and non-negative"))
            }
            Material::Plastic { albedo, roughness, ior } => {
                if !unit_ok(albedo) {
                    Err(format!("albedo {albedo:?} must be in [0, 1]"))
                } else if !rough_ok(*roughness) {
                    Err(format!("roughness {roughness} must be in [0, 1]"))
                } else if !(ior.is_finite() && *ior >= 1.0) {
                    Err(format!("ior {ior} must be at least 1"))
                } else {
                    Ok(())
                }
            }
            Material::Metal { color, roughness } => {
                if !unit_ok(color) {
                    Err(format!("color {color:?} must be in [0, 1]"))
                } else if !rough_ok(*roughness) {
                    Err(format!("roughness {roughness} must be in [0, 1]"))
                } else {
                    Ok(())
                }
            }
            Material::Mirror { color } if !unit_ok(color) => Err(format!("color {color:?} must be in [0, 1]")),
            Material::Glass { ior, color, .. } => {
                if !(ior.is_finite() && *ior >= 1.0) {
                    Err(format!("ior {ior} must be at least 1"))
                } else if !unit_ok(color) {
                    Err(format!("color {color:?} must be in [0, 1]"))
                } else {
                    Ok(())
                }
            }
            Material::Emitter { radiance } if !color_ok(radiance) => {
                Err(format!("radiance {radiance:?} must be finite and non-negative"))
            }
            _ => Ok(()),
        }
    }
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
}

fn sun_diameter() -> f32 {
    0.53
}
