//! Area lights: every triangle whose material emits, chosen for light sampling
//! in proportion to its power (area times emitted luminance).

use std::collections::HashMap;

use glam::Vec3;

use super::sampling::{luminance, uniform_triangle};
use crate::scene::Scene;

/// A point sampled on a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// World position.
    pub point: Vec3,
    /// Unit geometric normal (the emitting side).
    pub normal: Vec3,
    /// Emitted radiance.
    pub radiance: Vec3,
    /// Pdf of choosing this point, per unit area.
    pub pdf_area: f32,
}

/// The emissive triangles and their selection distribution.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Triangle ids.
    tris: Vec<u32>,
    /// Their vertices and emitted radiance.
    shapes: Vec<([Vec3; 3], Vec3)>,
    cdf: Vec<f32>,
    /// Selection probability divided by area, by triangle id.
    pdf_area: HashMap<u32, f32>,
}

impl Lights {
    /// Collects the emitters of a scene.
    pub fn new(scene: &Scene) -> Lights {
        Lights::from_emitters(scene.triangles.iter().enumerate().filter_map(|(i, t)| {
            let le = Vec3::from_array(scene.materials[t.material as usize].emission());
            (le.max_element() > 0.0).then(|| (i as u32, scene.vertices(i), le))
        }))
    }

    /// Lights from emissive triangles given as (id, vertices, emitted radiance).
    pub fn from_emitters(emitters: impl Iterator<Item = (u32, [Vec3; 3], Vec3)>) -> Lights {
        let mut tris = Vec::new();
        let mut shapes = Vec::new();
        let mut weights = Vec::new();
        for (id, [a, b, c], le) in emitters {
            if le.max_element() <= 0.0 {
                continue;
            }
            let area = 0.5 * (b - a).cross(c - a).length();
            let w = area * luminance(le).max(1e-6);
            if w.is_finite() && w > 0.0 {
                tris.push(id);
                shapes.push(([a, b, c], le));
                weights.push(w);
            }
        }
        let total: f64 = weights.iter().map(|w| f64::from(*w)).sum();
        let mut acc = 0.0f64;
        let mut cdf = Vec::with_capacity(weights.len());
        let mut pdf_area = HashMap::with_capacity(weights.len());
        for (k, w) in weights.iter().enumerate() {
            acc += f64::from(*w);
            cdf.push((acc / total) as f32);
            let [a, b, c] = shapes[k].0;
            let area = 0.5 * (b - a).cross(c - a).length();
            pdf_area.insert(tris[k], (f64::from(*w) / total) as f32 / area);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Lights {
            tris,
            shapes,
            cdf,
            pdf_area,
        }
    }

    /// Number of emissive triangles.
    pub fn len(&self) -> usize {
        self.tris.len()
    }
    /// True when nothing emits.
    pub fn is_empty(&self) -> bool {
        self.tris.is_empty()
    }

    /// Pdf per unit area of sampling a point on triangle `tri` (0 if it does not emit).
    pub fn pdf_area(&self, tri: u32) -> f32 {
        self.pdf_area.get(&tri).copied().unwrap_or(0.0)
    }

    /// Samples a point on a light.
    pub fn sample(&self, u: f32, uv: (f32, f32)) -> Option<LightSample> {
        if self.tris.is_empty() {
            return None;
        }
        let k = self.cdf.partition_point(|&c| c <= u).min(self.tris.len() - 1);
        let ([a, b, c], radiance) = self.shapes[k];
        let (b1, b2) = uniform_triangle(uv);
        let point = a * (1.0 - b1 - b2) + b * b1 + c * b2;
        let normal = (b - a).cross(c - a).normalize();
        Some(LightSample {
            point,
            normal,
            radiance,
            pdf_area: self.pdf_area(self.tris[k]),
        })
    }
}
