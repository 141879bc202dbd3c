//! The GGX (Trowbridge-Reitz) microfacet distribution with Smith masking, its
//! visible-normal sampling (Heitz, JCGT 2018), and Fresnel terms. Directions
//! are in the local frame: the surface normal is +z.

use glam::Vec3;
use std::f32::consts::PI;

/// Smallest alpha used: smoother surfaces are treated as perfectly specular.
pub const MIN_ALPHA: f32 = 1e-3;

/// GGX normal distribution D(h).
#[inline]
pub fn d(h: Vec3, alpha: f32) -> f32 {
    let a2 = alpha * alpha;
    let c2 = h.z * h.z;
    let denom = c2 * (a2 - 1.0) + 1.0;
    a2 / (PI * denom * denom)
}

/// Smith Lambda(w).
#[inline]
fn lambda(w: Vec3, alpha: f32) -> f32 {
    let c2 = w.z * w.z;
    if c2 <= 0.0 {
        return f32::INFINITY;
    }
    let tan2 = (1.0 - c2).max(0.0) / c2;
    ((1.0 + alpha * alpha * tan2).sqrt() - 1.0) * 0.5
}

/// Masking G1(w).
#[inline]
pub fn g1(w: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + lambda(w, alpha))
}

/// Height-correlated masking-shadowing G2(wo, wi).
#[inline]
pub fn g2(wo: Vec3, wi: Vec3, alpha: f32) -> f32 {
    1.0 / (1.0 + lambda(wo, alpha) + lambda(wi, alpha))
}

/// Samples a visible microfacet normal for outgoing direction `wo` (wo.z > 0).
pub fn sample_visible_normal(wo: Vec3, alpha: f32, u: (f32, f32)) -> Vec3 {
    let vh = Vec3::new(alpha * wo.x, alpha * wo.y, wo.z).normalize();
    let len2 = vh.x * vh.x + vh.y * vh.y;
    let t1 = if len2 > 0.0 {
        Vec3::new(-vh.y, vh.x, 0.0) / len2.sqrt()
    } else {
        Vec3::X
    };
    let t2 = vh.cross(t1);
    let r = u.0.sqrt();
    let phi = 2.0 * PI * u.1;
    let p1 = r * phi.cos();
    let s = 0.5 * (1.0 + vh.z);
    let p2 = (1.0 - s) * (1.0 - p1 * p1).max(0.0).sqrt() + s * r * phi.sin();
    let nh = t1 * p1 + t2 * p2 + vh * (1.0 - p1 * p1 - p2 * p2).max(0.0).sqrt();
    Vec3::new(alpha * nh.x, alpha * nh.y, nh.z.max(1e-6)).normalize()
}

/// Pdf (solid angle of wi) of reflecting `wo` about a visible normal.
#[inline]
pub fn reflect_pdf(wo: Vec3, h: Vec3, alpha: f32) -> f32 {
    g1(wo, alpha) * d(h, alpha) / (4.0 * wo.z)
}

/// Fresnel reflectance of a dielectric interface for incidence cosine `cos_i`
/// (> 0) and relative index `eta` = n_transmitted / n_incident.
pub fn fresnel_dielectric(cos_i: f32, eta: f32) -> f32 {
    let cos_i = cos_i.clamp(0.0, 1.0);
    let sin2_t = (1.0 - cos_i * cos_i) / (eta * eta);
    if sin2_t >= 1.0 {
        return 1.0;
    }
    let cos_t = (1.0 - sin2_t).sqrt();
    let rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    let rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    0.5 * (rs * rs + rp * rp)
}

/// Schlick's approximation for conductors with normal-incidence reflectance `f0`.
#[inline]
pub fn fresnel_schlick(cos_i: f32, f0: Vec3) -> Vec3 {
    let m = (1.0 - cos_i.clamp(0.0, 1.0)).powi(5);
    f0 + (Vec3::ONE - f0) * m
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::rng::Rng;

    #[test]
    fn projected_distribution_integrates_to_one() {
        // Integral of D(h) cos(theta_h) over the hemisphere is 1.
        let mut rng = Rng::new(3, 0);
        // Uniform sampling cannot resolve very sharp lobes; moderate ones suffice here.
        for alpha in [0.2f32, 0.4, 0.8] {
            let n = 400_000;
            let mut sum = 0.0f64;
            for _ in 0..n {
                let (u1, u2) = rng.f32x2();
                // Uniform hemisphere: pdf 1/(2 pi).
                let z = u1;
                let r = (1.0 - z * z).max(0.0).sqrt();
                let h = Vec3::new(r * (2.0 * PI * u2).cos(), r * (2.0 * PI * u2).sin(), z);
                sum += f64::from(d(h, alpha) * h.z * 2.0 * PI);
            }
            let mean = sum / n as f64;
            assert!((mean - 1.0).abs() < 0.03, "alpha {alpha}: {mean}");
        }
    }

    #[test]
    fn fresnel_limits() {
        assert!((fresnel_dielectric(1.0, 1.5) - 0.04).abs() < 1e-4);
        assert_eq!(fresnel_dielectric(0.1, 1.0 / 1.5), 1.0, "total internal reflection");
        assert!((fresnel_dielectric(0.0, 1.5) - 1.0).abs() < 1e-4);
        assert_eq!(fresnel_schlick(1.0, Vec3::splat(0.9)), Vec3::splat(0.9));
    }
}
