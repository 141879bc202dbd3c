//! How each material scatters light: evaluation (f times the cosine, and the
//! sampling pdf, for light sampling and MIS) and importance sampling. All
//! directions are local, the shading normal is +z, and `wo` points away from
//! the surface toward where the light goes.

use glam::Vec3;
use std::f32::consts::FRAC_1_PI;

use super::microfacet::{self as mf, MIN_ALPHA};
use super::sampling::cosine_hemisphere;
use crate::scene::Material;

/// A sampled incoming direction.
#[derive(Clone, Copy, Debug)]
pub struct Sampled {
    /// Direction toward the light, local frame.
    pub wi: Vec3,
    /// f * cos / pdf: what the path throughput is multiplied by.
    pub weight: Vec3,
    /// Pdf in solid angle (0 for delta lobes).
    pub pdf: f32,
    /// True for perfectly specular scattering (no light sampling possible).
    pub delta: bool,
}

/// f * cos(theta_i) and the pdf [`sample`] would give `wi`.
#[derive(Clone, Copy, Debug, Default)]
pub struct Eval {
    /// BSDF times the incoming cosine.
    pub f_cos: Vec3,
    /// Pdf of sampling `wi` in solid angle.
    pub pdf: f32,
}

fn v3(c: &[f32; 3]) -> Vec3 {
    Vec3::from_array(*c)
}

fn alpha_of(roughness: f32) -> f32 {
    (roughness * roughness).max(MIN_ALPHA)
}

/// Metals smoother than this are perfect mirrors.
const SMOOTH_METAL: f32 = 0.02;

/// True when the material scatters only in discrete directions.
pub fn is_delta(m: &Material) -> bool {
    match m {
        Material::Mirror { .. } | Material::Glass { .. } => true,
        Material::Metal { roughness, .. } => *roughness < SMOOTH_METAL,
        _ => false,
    }
}

/// True when light can pass through (the caller must keep the geometric side).
pub fn transmits(m: &Material) -> bool {
    matches!(m, Material::Glass { .. })
}

/// Probability of choosing the coat's specular lobe of plastic.
fn plastic_spec_prob(wo: Vec3, ior: f32) -> f32 {
    mf::fresnel_dielectric(wo.z, ior).clamp(0.15, 0.85)
}

/// Evaluates a non-delta material for `wo` (wo.z > 0) and `wi`.
pub fn eval(m: &Material, wo: Vec3, wi: Vec3) -> Eval {
    if wo.z <= 0.0 || wi.z <= 0.0 {
        return Eval::default();
    }
    match m {
        Material::Lambertian { albedo, .. } => Eval {
            f_cos: v3(albedo) * (FRAC_1_PI * wi.z),
            pdf: wi.z * FRAC_1_PI,
        },
        Material::Plastic { albedo, roughness, ior } => {
            let alpha = alpha_of(*roughness);
            let h = (wo + wi).normalize();
            let f = mf::fresnel_dielectric(wo.dot(h), *ior);
            let spec = f * mf::d(h, alpha) * mf::g2(wo, wi, alpha) / (4.0 * wo.z);
            let diffuse_scale = (1.0 - mf::fresnel_dielectric(wo.z, *ior)) * (1.0 - mf::fresnel_dielectric(wi.z, *ior));
            let f_cos = Vec3::splat(spec) + v3(albedo) * (FRAC_1_PI * wi.z * diffuse_scale);
            let ps = plastic_spec_prob(wo, *ior);
            let pdf = ps * mf::reflect_pdf(wo, h, alpha) + (1.0 - ps) * wi.z * FRAC_1_PI;
            Eval { f_cos, pdf }
        }
        Material::Metal { color, roughness } if *roughness >= SMOOTH_METAL => {
            let alpha = alpha_of(*roughness);
            let h = (wo + wi).normalize();
            let f = mf::fresnel_schlick(wo.dot(h), v3(color));
            let f_cos = f * (mf::d(h, alpha) * mf::g2(wo, wi, alpha) / (4.0 * wo.z));
            Eval {
                f_cos,
                pdf: mf::reflect_pdf(wo, h, alpha),
            }
        }
        _ => Eval::default(),
    }
}

fn reflect_z(w: Vec3) -> Vec3 {
    Vec3::new(-w.x, -w.y, w.z)
}

/// Samples an incoming direction. For reflective materials `wo.z > 0`; for
/// glass `wo.z < 0` means the ray arrives from inside. `u` holds three uniforms.
pub fn sample(m: &Material, wo: Vec3, u: [f32; 3]) -> Option<Sampled> {
    match m {
        Material::Lambertian { albedo, .. } => {
            let wi = cosine_hemisphere((u[1], u[2]));
            (wi.z > 0.0).then(|| Sampled {
                wi,
                weight: v3(albedo),
                pdf: wi.z * FRAC_1_PI,
                delta: false,
            })
        }
        Material::Plastic { roughness, ior, .. } => {
            let wi = if u[0] < plastic_spec_prob(wo, *ior) {
                let h = mf::sample_visible_normal(wo, alpha_of(*roughness), (u[1], u[2]));
                2.0 * wo.dot(h) * h - wo
            } else {
                cosine_hemisphere((u[1], u[2]))
            };
            from_eval(m, wo, wi)
        }
        Material::Metal { color, roughness } if *roughness < SMOOTH_METAL => Some(Sampled {
            wi: reflect_z(wo),
            weight: mf::fresnel_schlick(wo.z, v3(color)),
            pdf: 0.0,
            delta: true,
        }),
        Material::Metal { color, roughness } => {
            let alpha = alpha_of(*roughness);
            let h = mf::sample_visible_normal(wo, alpha, (u[1], u[2]));
            let wi = 2.0 * wo.dot(h) * h - wo;
            if wi.z <= 0.0 {
                return None;
            }
            let weight = mf::fresnel_schlick(wo.dot(h), v3(color)) * (mf::g2(wo, wi, alpha) / mf::g1(wo, alpha));
            Some(Sampled {
                wi,
                weight,
                pdf: mf::reflect_pdf(wo, h, alpha),
                delta: false,
            })
        }
        Material::Mirror { color } => Some(Sampled {
            wi: reflect_z(wo),
            weight: v3(color),
            pdf: 0.0,
            delta: true,
        }),
        Material::Glass { ior, color, thin } => Some(sample_glass(wo, *ior, v3(color), *thin, u[0])),
        Material::Emitter { .. } => None,
    }
}

fn from_eval(m: &Material, wo: Vec3, wi: Vec3) -> Option<Sampled> {
    let e = eval(m, wo, wi);
    (e.pdf > 0.0 && wi.z > 0.0).then(|| Sampled {
        wi,
        weight: e.f_cos / e.pdf,
        pdf: e.pdf,
        delta: false,
    })
}

/// Reflectance of a thin sheet (both faces and their inter-reflections) at
/// incidence cosine `cos`.
pub fn thin_reflectance(cos: f32, ior: f32) -> f32 {
    let r = mf::fresnel_dielectric(cos, ior);
    if r < 1.0 {
        r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r)
    } else {
        1.0
    }
}

/// Smooth dielectric: Fresnel-weighted choice of reflection or refraction.
/// Thin sheets sum the inter-reflections of both faces and pass straight through.
fn sample_glass(wo: Vec3, ior: f32, color: Vec3, thin: bool, u: f32) -> Sampled {
    let cos_o = wo.z.abs();
    let reflect = Sampled {
        wi: reflect_z(wo),
        weight: Vec3::ONE,
        pdf: 0.0,
        delta: true,
    };
    if thin {
        let r = mf::fresnel_dielectric(cos_o, ior);
        let r_total = if r < 1.0 {
            r + (1.0 - r) * (1.0 - r) * r / (1.0 - r * r)
        } else {
            1.0
        };
        if u < r_total {
            return reflect;
        }
        return Sampled {
            wi: -wo,
            weight: color,
            pdf: 0.0,
            delta: true,
        };
    }
    let entering = wo.z > 0.0;
    let eta = if entering { ior } else { 1.0 / ior };
    let f = mf::fresnel_dielectric(cos_o, eta);
    if u < f {
        return reflect;
    }
    let sin2_t = (1.0 - cos_o * cos_o) / (eta * eta);
    let cos_t = (1.0 - sin2_t).max(0.0).sqrt();
    let n = if entering { Vec3::Z } else { -Vec3::Z };
    let wi = (-wo / eta + n * (cos_o / eta - cos_t)).normalize();
    // Radiance is compressed entering a denser medium: scale by (n_i / n_t)^2.
    Sampled {
        wi,
        weight: color / (eta * eta),
        pdf: 0.0,
        delta: true,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::rng::Rng;

    /// Materials whose lobes are wide enough to integrate by uniform sampling.
    fn materials() -> Vec<Material> {
        vec![
            Material::lambertian([1.0; 3]),
            Material::Plastic {
                albedo: [1.0; 3],
                roughness: 0.3,
                ior: 1.5,
            },
            Material::Plastic {
                albedo: [0.5; 3],
                roughness: 0.6,
                ior: 1.5,
            },
            Material::Metal {
                color: [1.0; 3],
                roughness: 0.4,
            },
            Material::Metal {
                color: [0.9, 0.6, 0.3],
                roughness: 0.25,
            },
        ]
    }

    #[test]
    fn sharp_lobes_never_create_energy() {
        let mut rng = Rng::new(13, 0);
        for m in [
            Material::Plastic {
                albedo: [1.0; 3],
                roughness: 0.05,
                ior: 1.5,
            },
            Material::Metal {
                color: [1.0; 3],
                roughness: 0.05,
            },
            Material::Metal {
                color: [1.0; 3],
                roughness: 0.0,
            },
        ] {
            for _ in 0..6 {
                let wo = dir(&mut rng);
                let n = 100_000;
                let mut sum = Vec3::ZERO;
                for _ in 0..n {
                    if let Some(s) = sample(&m, wo, [rng.f32(), rng.f32(), rng.f32()]) {
                        assert!(s.weight.is_finite());
                        sum += s.weight;
                    }
                }
                let albedo = sum / n as f32;
                assert!(albedo.max_element() <= 1.01, "{m:?} wo {wo}: reflects {albedo}");
                assert!(
                    albedo.min_element() > 0.5,
                    "{m:?} wo {wo}: a white sharp lobe loses too much: {albedo}"
                );
            }
        }
    }

    fn dir(rng: &mut Rng) -> Vec3 {
        let (u1, u2) = rng.f32x2();
        let z = u1.max(0.02);
        let r = (1.0 - z * z).sqrt();
        Vec3::new(r * (6.2831855 * u2).cos(), r * (6.2831855 * u2).sin(), z)
    }

    #[test]
    fn white_furnace_conserves_energy_and_sampling_matches_evaluation() {
        let mut rng = Rng::new(11, 0);
        for m in materials() {
            for _ in 0..6 {
                let wo = dir(&mut rng);
                let n = 200_000;
                let (mut by_sampling, mut by_eval, mut pdf_mass) = (Vec3::ZERO, Vec3::ZERO, 0.0f32);
                for _ in 0..n {
                    if let Some(s) = sample(&m, wo, [rng.f32(), rng.f32(), rng.f32()]) {
                        assert!(s.weight.is_finite() && s.pdf > 0.0, "{m:?}");
                        by_sampling += s.weight;
                    }
                    // The same integral by uniform hemisphere sampling of eval (pdf 1/2pi).
                    let wi = dir(&mut rng);
                    let e = eval(&m, wo, wi);
                    by_eval += e.f_cos * std::f32::consts::TAU;
                    pdf_mass += e.pdf * std::f32::consts::TAU;
                }
                let (a, b) = (by_sampling / n as f32, by_eval / n as f32);
                assert!(a.max_element() <= 1.01, "{m:?} wo {wo}: reflects {a} > 1");
                assert!(
                    (a - b).abs().max_element() < 0.03 + 0.05 * b.max_element(),
                    "{m:?} wo {wo}: sampled {a} vs evaluated {b}"
                );
                assert!(
                    pdf_mass / (n as f32) < 1.05,
                    "{m:?}: pdf integrates to {}",
                    pdf_mass / n as f32
                );
            }
        }
        // A white Lambertian reflects exactly everything.
        let wo = Vec3::new(0.3, 0.1, 0.9).normalize();
        let s = sample(&Material::lambertian([1.0; 3]), wo, [0.5, 0.3, 0.7]).unwrap();
        assert_eq!(s.weight, Vec3::ONE);
    }

    #[test]
    fn reciprocity() {
        let mut rng = Rng::new(5, 0);
        for m in materials() {
            for _ in 0..200 {
                let (a, b) = (dir(&mut rng), dir(&mut rng));
                let fab = eval(&m, a, b).f_cos / b.z;
                let fba = eval(&m, b, a).f_cos / a.z;
                assert!(
                    (fab - fba).abs().max_element() <= 1e-3 * fab.max_element().max(1e-3),
                    "{m:?}: {fab} vs {fba}"
                );
            }
        }
    }

    #[test]
    fn glass_reflects_and_transmits_in_fresnel_proportion() {
        let glass = Material::Glass {
            ior: 1.5,
            color: [1.0; 3],
            thin: false,
        };
        let wo = Vec3::new(0.6, 0.0, 0.8);
        let mut rng = Rng::new(2, 0);
        let n = 100_000;
        let reflected = (0..n)
            .filter(|_| sample(&glass, wo, [rng.f32(), 0.0, 0.0]).unwrap().wi.z > 0.0)
            .count();
        let f = mf::fresnel_dielectric(0.8, 1.5);
        assert!((reflected as f32 / n as f32 - f).abs() < 0.005);
        // Refraction obeys Snell's law and a round trip through both faces restores the direction.
        let into = sample(&glass, wo, [0.999, 0.0, 0.0]).unwrap();
        let sin_t = (into.wi.x * into.wi.x + into.wi.y * into.wi.y).sqrt();
        assert!((sin_t * 1.5 - 0.6).abs() < 1e-5, "Snell: {sin_t}");
        // The path continues along wi. Leaving through the parallel back face
        // of a slab (normal -z) restores the original direction of travel, -wo.
        let back = crate::shade::sampling::Frame::new(-Vec3::Z);
        let wo_back = back.to_local(-into.wi);
        assert!(wo_back.z < 0.0, "arriving from inside the glass");
        let out = sample(&glass, wo_back, [0.999, 0.0, 0.0]).unwrap();
        let leaving = back.to_world(out.wi);
        assert!((leaving + wo).length() < 1e-5, "{leaving} vs {}", -wo);
        assert!(
            (into.weight.x * out.weight.x - 1.0).abs() < 1e-5,
            "in and out radiance scaling cancel"
        );
        // A thin pane passes light straight through.
        let pane = Material::Glass {
            ior: 1.5,
            color: [0.9; 3],
            thin: true,
        };
        let s = sample(&pane, wo, [0.999, 0.0, 0.0]).unwrap();
        assert_eq!(s.wi, -wo);
    }
}
