//! Distant `source`s as the scene's sky. A `light` source becomes the sun
//! (its radiance and angular diameter as given). A `glow` source at least a
//! hemisphere wide becomes the sky of the half it faces (both halves from
//! 360 degrees): shaped by its sky distribution where gensky's or
//! gendaylit's `skyfunc` modifies it (the colour multiplying the
//! distribution, as in Radiance), else uniform. A second sun, a narrower
//! glow source and sources of any other material are refused.

use glam::{DVec3, Mat4, Vec3};

use super::error::{Location, RadError, RadErrorKind};
use super::materials::{LightKind, Slot};
use super::report::{NoteKind, RadReport};
use crate::scene::material::{Sky, SunDisk};
use crate::scene::sky_distribution::SkyDistribution;

/// A distant source as read.
#[derive(Clone, Debug, PartialEq)]
pub(super) struct Source {
    /// Direction toward it, in the frame of the file that was read first.
    pub direction: DVec3,
    /// Angular diameter, degrees.
    pub angle: f64,
    /// Its material.
    pub slot: usize,
    /// Where it is.
    pub at: Location,
    /// `source "name"`, for messages.
    pub what: String,
}

/// The sky the `sources` make, turned by `transform` (the import's), or
/// `None` without sources.
pub(super) fn sky(
    sources: &[Source],
    slots: &[Slot],
    transform: Mat4,
    report: &mut RadReport,
) -> Result<Option<Sky>, RadError> {
    let mut sun: Option<(&Source, Vec3, [f32; 3])> = None;
    let (mut upper, mut lower) = (None::<[f32; 3]>, None::<[f32; 3]>);
    let mut distribution: Option<SkyDistribution> = None;
    // Whether the glows of the upper and lower half are shaped by it.
    let mut shaped = [false; 2];
    let refuse = |s: &Source, message: String| {
        let what = s.what.clone();
        RadError::new(&s.at, RadErrorKind::Source { what, message })
    };
    for s in sources {
        let slot = &slots[s.slot];
        let direction = transform.transform_vector3(s.direction.as_vec3());
        if !(direction.is_finite() && direction.length_squared() > 0.0) {
            return Err(refuse(s, "its direction is zero or not finite".to_string()));
        }
        let radiance = slot.material.emission();
        match slot.light {
            LightKind::Light => {
                if let Some((first, ..)) = sun {
                    let message = format!("the scene has one sun, and {} already is it", first.at);
                    return Err(refuse(s, message));
                }
                sun = Some((s, direction, radiance));
            }
            LightKind::Glow => {
                if s.angle < 180.0 {
                    let message = format!(
                        "a glow source {} degrees wide: only glow sources of at least a hemisphere (180) become the sky",
                        s.angle
                    );
                    return Err(refuse(s, message));
                }
                match (&slot.sky, &distribution) {
                    (Some(d), None) => distribution = Some(d.clone()),
                    (Some(d), Some(first)) if d != first => {
                        report.note(NoteKind::SkyDistributions, &s.at, || s.what.clone());
                    }
                    (Some(_), Some(_)) => {}
                    (None, _) => report.note(NoteKind::GlowSky, &s.at, || s.what.clone()),
                }
                let add = |half: &mut Option<[f32; 3]>| {
                    let before = half.unwrap_or([0.0; 3]);
                    *half = Some([0, 1, 2].map(|k| before[k] + radiance[k]));
                };
                if s.angle >= 360.0 || direction.z >= 0.0 {
                    add(&mut upper);
                    shaped[0] |= slot.sky.is_some();
                }
                if s.angle >= 360.0 || direction.z < 0.0 {
                    add(&mut lower);
                    shaped[1] |= slot.sky.is_some();
                }
            }
            LightKind::None | LightKind::Spot => {
                let message = format!(
                    "its material {:?} ({}) is not light (a sun) or glow (a sky)",
                    slot.name, slot.at
                );
                return Err(refuse(s, message));
            }
        }
    }
    let (up, down) = (upper.unwrap_or([0.0; 3]), lower.unwrap_or([0.0; 3]));
    if let Some(distribution) = distribution {
        let sun = sun.map(|(s, direction, radiance)| SunDisk {
            direction: direction.normalize().to_array(),
            radiance,
            diameter_deg: s.angle as f32,
        });
        let sky = Sky::Radiance {
            distribution: turned(distribution, transform),
            sky: up,
            ground: down,
            sky_shaped: shaped[0],
            ground_shaped: shaped[1],
            sun,
        };
        if let (Err(e), Some(s)) = (sky.validate(), sources.first()) {
            return Err(refuse(s, e.to_string()));
        }
        return Ok(Some(sky));
    }
    let sky = match sun {
        Some((s, direction, radiance)) => {
            let sky = Sky::Sun {
                direction: direction.normalize().to_array(),
                sun_radiance: radiance,
                diameter_deg: s.angle as f32,
                zenith: up,
                horizon: up,
                ground: down,
            };
            sky.validate().map_err(|e| refuse(s, e.to_string()))?;
            sky
        }
        None if upper.is_none() && lower.is_none() => return Ok(None),
        None if up == down => Sky::Constant { radiance: up },
        None => Sky::Sun {
            direction: [0.0, 0.0, 1.0],
            sun_radiance: [0.0; 3],
            diameter_deg: 0.53,
            zenith: up,
            horizon: up,
            ground: down,
        },
    };
    Ok(Some(sky))
}

/// `d` with its sun direction turned by `transform` (the import's).
fn turned(d: SkyDistribution, transform: Mat4) -> SkyDistribution {
    // Turned, its length kept: the .cal files use the numbers as given.
    let turn = |v: [f32; 3]| {
        let v = Vec3::from_array(v);
        let t = transform.transform_vector3(v);
        t.try_normalize().map_or(v, |t| t * v.length()).to_array()
    };
    match d {
        SkyDistribution::Cie {
            kind,
            zenith,
            ground,
            normalization,
            toward_sun,
        } => SkyDistribution::Cie {
            kind,
            zenith,
            ground,
            normalization,
            toward_sun: turn(toward_sun),
        },
        SkyDistribution::Perez {
            normalization,
            ground,
            coefficients,
            toward_sun,
        } => SkyDistribution::Perez {
            normalization,
            ground,
            coefficients,
            toward_sun: turn(toward_sun),
        },
    }
}
