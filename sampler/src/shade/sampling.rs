//! Sampling building blocks: local frames, hemisphere and cone sampling, the
//! power heuristic for multiple importance sampling.

use glam::Vec3;
use std::f32::consts::PI;

/// An orthonormal frame around a unit normal (Duff et al., JCGT 2017).
#[derive(Clone, Copy, Debug)]
pub struct Frame {
    /// Tangent.
    pub s: Vec3,
    /// Bitangent.
    pub t: Vec3,
    /// Normal.
    pub n: Vec3,
}

impl Frame {
    /// The frame around `n` (unit length).
    pub fn new(n: Vec3) -> Frame {
        let sign = 1f32.copysign(n.z);
        let a = -1.0 / (sign + n.z);
        let b = n.x * n.y * a;
        Frame {
            s: Vec3::new(1.0 + sign * n.x * n.x * a, sign * b, -sign * n.x),
            t: Vec3::new(b, sign + n.y * n.y * a, -n.y),
            n,
        }
    }
    /// World to local (z along the normal).
    #[inline]
    pub fn to_local(&self, v: Vec3) -> Vec3 {
        Vec3::new(v.dot(self.s), v.dot(self.t), v.dot(self.n))
    }
    /// Local to world.
    #[inline]
    pub fn to_world(&self, v: Vec3) -> Vec3 {
        self.s * v.x + self.t * v.y + self.n * v.z
    }
}

/// Cosine-weighted direction on the +z hemisphere; pdf = z / pi.
pub fn cosine_hemisphere(u: (f32, f32)) -> Vec3 {
    let r = u.0.sqrt();
    let phi = 2.0 * PI * u.1;
    Vec3::new(r * phi.cos(), r * phi.sin(), (1.0 - u.0).max(0.0).sqrt())
}

/// Uniform direction in the cone of half-angle acos(cos_max) around +z.
pub fn uniform_cone(u: (f32, f32), cos_max: f32) -> Vec3 {
    let cos = 1.0 - u.0 * (1.0 - cos_max);
    let sin = (1.0 - cos * cos).max(0.0).sqrt();
    let phi = 2.0 * PI * u.1;
    Vec3::new(sin * phi.cos(), sin * phi.sin(), cos)
}

/// Pdf of [`uniform_cone`].
pub fn uniform_cone_pdf(cos_max: f32) -> f32 {
    1.0 / (2.0 * PI * (1.0 - cos_max))
}

/// Uniform point on a triangle: barycentrics (b1, b2).
pub fn uniform_triangle(u: (f32, f32)) -> (f32, f32) {
    let s = u.0.sqrt();
    (1.0 - s, u.1 * s)
}

/// Power heuristic (beta = 2) weight of strategy `a` against `b`.
#[inline]
pub fn power_heuristic(a: f32, b: f32) -> f32 {
    let (a2, b2) = (a * a, b * b);
    if a2 + b2 == 0.0 || !a2.is_finite() {
        return if a.is_infinite() { 1.0 } else { 0.0 };
    }
    a2 / (a2 + b2)
}

/// Luminance of linear Rec. 709 RGB.
#[inline]
pub fn luminance(c: Vec3) -> f32 {
    0.2126 * c.x + 0.7152 * c.y + 0.0722 * c.z
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::rng::Rng;

    #[test]
    fn frames_are_orthonormal_and_samplers_have_right_moments() {
        for n in [Vec3::Z, -Vec3::Z, Vec3::new(0.3, -0.4, 0.866).normalize(), Vec3::X] {
            let f = Frame::new(n);
            assert!(f.s.dot(f.t).abs() < 1e-6 && f.s.dot(f.n).abs() < 1e-6 && (f.s.cross(f.t) - n).length() < 1e-5);
            let v = Vec3::new(0.2, 0.5, -0.1);
            assert!((f.to_world(f.to_local(v)) - v).length() < 1e-6);
        }
        let mut rng = Rng::new(1, 1);
        let n = 200_000;
        // E[cos] under cosine sampling is 2/3.
        let mean_cos: f32 = (0..n).map(|_| cosine_hemisphere(rng.f32x2()).z).sum::<f32>() / n as f32;
        assert!((mean_cos - 2.0 / 3.0).abs() < 0.005, "{mean_cos}");
        let cone: Vec<Vec3> = (0..1000).map(|_| uniform_cone(rng.f32x2(), 0.9)).collect();
        assert!(cone
            .iter()
            .all(|d| d.z >= 0.9 - 1e-6 && (d.length() - 1.0).abs() < 1e-5));
    }
}
