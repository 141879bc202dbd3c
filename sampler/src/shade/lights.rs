//! Area lights: every triangle whose material emits, chosen for light sampling
//! in proportion to its power (area times emitted luminance).

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
    /// Emitted radiance (before an emission texture, which the tracer
    /// applies at `tri` and `bary`).
    pub radiance: Vec3,
    /// Pdf of choosing this point, per unit area.
    pub pdf_area: f32,
    /// The triangle it lies on.
    pub tri: u32,
    /// That triangle's material.
    pub material: u32,
    /// Its barycentric weights of the triangle's vertices 1 and 2.
    pub bary: (f32, f32),
}

/// The emissive triangles and their selection distribution.
#[derive(Clone, Debug, Default)]
pub struct Lights {
    /// Triangle ids, ascending: a light hit finds its pdf by binary search,
    /// faster than hashing the id.
    tris: Vec<u32>,
    /// Their vertices, emitted radiance and material.
    shapes: Vec<([Vec3; 3], Vec3, u32)>,
    cdf: Vec<f32>,
    /// Selection probability divided by area, in the order of `tris`.
    pdf: Vec<f32>,
}

/// Each material's emitted radiance (plus its emission texture's factor,
/// where it glows through one) and the luminance to choose its triangles
/// by (the texture's mean where it has one).
pub fn emission_of(scene: &Scene) -> Vec<(Vec3, f32)> {
    (0..scene.materials.len())
        .map(|m| {
            let le = Vec3::from_array(scene.materials[m].emission());
            match scene
                .maps_of(m as u32)
                .and_then(|maps| maps.emissive_parts(&scene.textures))
            {
                Some((factor, mean)) => (le + factor, luminance(factor * mean).max(luminance(le))),
                None => (le, luminance(le)),
            }
        })
        .collect()
}

impl Lights {
    /// Collects the emitters of a scene: triangles whose material emits,
    /// or whose emission texture does (chosen by its mean).
    pub fn new(scene: &Scene) -> Lights {
        let emission = emission_of(scene);
        Lights::weighted(scene.triangles.iter().enumerate().filter_map(|(i, t)| {
            let (le, weight) = emission[t.material as usize];
            (le.max_element() > 0.0).then(|| (i as u32, scene.vertices(i), t.material, le, weight))
        }))
    }

    /// Lights from emissive triangles given as (id, vertices, material),
    /// with the emission of the materials of `scene` (a scene file's
    /// shell: materials, maps and textures, no triangles).
    pub fn from_emitters(scene: &Scene, emitters: impl Iterator<Item = (u32, [Vec3; 3], u32)>) -> Lights {
        let emission = emission_of(scene);
        Lights::weighted(emitters.filter_map(|(id, v, m)| {
            let (le, weight) = emission.get(m as usize).copied()?;
            Some((id, v, m, le, weight))
        }))
    }

    /// Lights from emissive triangles given as (id, vertices, material,
    /// emitted radiance, luminance to choose them by).
    fn weighted(emitters: impl Iterator<Item = (u32, [Vec3; 3], u32, Vec3, f32)>) -> Lights {
        // (id, vertices, radiance and material, power, area)
        let mut lights = Vec::new();
        for (id, [a, b, c], m, le, weight) in emitters {
            if le.max_element() <= 0.0 {
                continue;
            }
            let area = 0.5 * (b - a).cross(c - a).length();
            let w = area * weight.max(1e-6);
            if w.is_finite() && w > 0.0 {
                lights.push((id, ([a, b, c], le, m), w, area));
            }
        }
        lights.sort_by_key(|l| l.0);
        let total: f64 = lights.iter().map(|l| f64::from(l.2)).sum();
        let mut acc = 0.0f64;
        let mut cdf = Vec::with_capacity(lights.len());
        let mut pdf = Vec::with_capacity(lights.len());
        for &(_, _, w, area) in &lights {
            acc += f64::from(w);
            cdf.push((acc / total) as f32);
            pdf.push((f64::from(w) / total) as f32 / area);
        }
        if let Some(last) = cdf.last_mut() {
            *last = 1.0;
        }
        Lights {
            tris: lights.iter().map(|l| l.0).collect(),
            shapes: lights.iter().map(|l| l.1).collect(),
            cdf,
            pdf,
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
        self.tris.binary_search(&tri).map_or(0.0, |k| self.pdf[k])
    }

    /// Samples a point on a light.
    pub fn sample(&self, u: f32, uv: (f32, f32)) -> Option<LightSample> {
        if self.tris.is_empty() {
            return None;
        }
        let k = self.cdf.partition_point(|&c| c <= u).min(self.tris.len() - 1);
        let ([a, b, c], radiance, material) = self.shapes[k];
        let (b1, b2) = uniform_triangle(uv);
        let point = a * (1.0 - b1 - b2) + b * b1 + c * b2;
        let normal = (b - a).cross(c - a).normalize();
        Some(LightSample {
            point,
            normal,
            radiance,
            pdf_area: self.pdf[k],
            tri: self.tris[k],
            material,
            bary: (b1, b2),
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Emitters given out of id order: each one's pdf per unit area times
    /// its area is its share of the power, the shares sum to one, the pdf a
    /// sample carries is its triangle's, and a triangle that does not emit
    /// has none.
    #[test]
    fn pdfs_by_id_match_the_samples() {
        let tri = |x: f32, size: f32| {
            [
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + size, 0.0, 0.0),
                Vec3::new(x, size, 0.0),
            ]
        };
        let emitters = [
            (40u32, tri(0.0, 1.0), Vec3::splat(1.0)),
            (7, tri(5.0, 2.0), Vec3::splat(1.0)),
            (19, tri(9.0, 1.0), Vec3::splat(4.0)),
        ];
        let scene = Scene {
            materials: vec![
                crate::scene::Material::Emitter { radiance: [1.0; 3] },
                crate::scene::Material::Emitter { radiance: [4.0; 3] },
            ],
            ..Scene::default()
        };
        let lights = Lights::from_emitters(
            &scene,
            emitters.iter().map(|&(id, v, le)| (id, v, u32::from(le.x > 2.0))),
        );
        assert_eq!(lights.len(), 3);
        // Powers: area 0.5 x 1, 2 x 1, 0.5 x 4 (luminance of grey is itself).
        let want = [0.5 / 4.5, 2.0 / 4.5, 2.0 / 4.5];
        let mut total = 0.0;
        for ((id, [a, b, c], _), want) in emitters.iter().zip(want) {
            let area = 0.5 * (*b - *a).cross(*c - *a).length();
            let share = lights.pdf_area(*id) * area;
            assert!((share - want).abs() < 1e-6, "{id}: {share} against {want}");
            total += share;
        }
        assert!((total - 1.0).abs() < 1e-6);
        assert_eq!(lights.pdf_area(8), 0.0);
        assert_eq!(lights.pdf_area(u32::MAX), 0.0);
        for k in 0..64 {
            let s = lights.sample((k as f32 + 0.5) / 64.0, (0.3, 0.4)).unwrap();
            let id = if s.point.x < 4.0 {
                40
            } else if s.point.x < 8.0 {
                7
            } else {
                19
            };
            assert_eq!(s.pdf_area, lights.pdf_area(id), "sample {k} at {:?}", s.point);
        }
    }
}
