//! What a denoiser knows of each pixel besides its colour, from the sample
//! store: the depth of the surface seen, its normal (from the depths of the
//! pixels around it, so no geometry is needed), and how noisy the pixel's
//! estimate is (the variance of its mean, from its rays' spread).

use glam::DVec3;

use crate::project::Projector;
use crate::viewport::Viewport;

/// Per-pixel guides of one frame, row-major, top row first.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Guide {
    /// Frame width.
    pub width: usize,
    /// Frame height.
    pub height: usize,
    /// Distance from the eye to the nearest surface seen in the pixel
    /// (infinite: sky; NaN: no estimate there).
    pub depth: Vec<f32>,
    /// World-space unit normal of that surface, facing the eye (zero where
    /// unknown: sky, no estimate, or a pixel with no neighbour on its surface).
    pub normal: Vec<[f32; 3]>,
    /// Variance of the pixel's mean luminance (NaN where unknown).
    pub variance: Vec<f32>,
    /// Albedo (0..=1) of the surface seen, where a display was given it
    /// (from the scene: [`Guide::with_albedo`]); empty where unknown, as
    /// the store's rays carry none.
    pub albedo: Vec<[f32; 3]>,
}

/// A pixel's ray sums, as the store keeps them: weight, weighted luminance
/// sum, weighted squared-luminance sum, and rays.
pub type RaySums = (f32, f32, f32, u32);

impl Guide {
    /// The guide of a `viewport` frame from each pixel's nearest depth and
    /// ray sums (both row-major).
    pub fn new(viewport: &Viewport, depth: Vec<f32>, sums: &[RaySums]) -> Guide {
        let (w, h) = (viewport.width as usize, viewport.height as usize);
        let variance = sums
            .iter()
            .map(|&(wt, l, lsq, n)| {
                if n >= 2 && wt > 0.0 {
                    let mean = l / wt;
                    (lsq / wt - mean * mean).max(0.0) / n as f32
                } else {
                    f32::NAN
                }
            })
            .collect();
        let normal = normals(viewport, &depth);
        Guide {
            width: w,
            height: h,
            depth,
            normal,
            variance,
            albedo: Vec::new(),
        }
    }

    /// The same guide with the albedo of the surface each pixel sees
    /// (row-major, top row first); a picture of another size is ignored.
    pub fn with_albedo(mut self, albedo: &holodeck_protocol::Picture) -> Guide {
        if (albedo.width, albedo.height) == (self.width, self.height) && albedo.pixels.len() == self.width * self.height
        {
            self.albedo = albedo.pixels.iter().map(|p| p.to_array()).collect();
        }
        self
    }
}

/// Relative depth difference beyond which a neighbour is never taken for
/// the same surface (within it, the side that continues the surface best
/// is taken, so a steep floor keeps its pixels and a silhouette loses the
/// far side).
const SAME_SURFACE: f32 = 0.5;

/// Normals from depths: the cross product of the world-space steps to the
/// neighbour across and the neighbour down, each taken on the side whose
/// depth is nearer (so a silhouette does not bend the surface beside it).
fn normals(viewport: &Viewport, depth: &[f32]) -> Vec<[f32; 3]> {
    let (w, h) = (viewport.width as usize, viewport.height as usize);
    let projector = Projector::new(viewport);
    let point = |c: usize, r: usize| -> Option<DVec3> {
        let d = depth[r * w + c];
        if !d.is_finite() {
            return None;
        }
        let (o, dir) = projector.ray(c as u32, r as u32, [0.5, 0.5])?;
        Some(o + dir * f64::from(d))
    };
    let mut out = vec![[0.0f32; 3]; w * h];
    for r in 0..h {
        for c in 0..w {
            let Some(p) = point(c, r) else { continue };
            let d = depth[r * w + c];
            // The step to the neighbour along each axis on the side that
            // continues the pixel's surface best: the side whose two pixels
            // extrapolate nearest to this depth (a fold or a silhouette
            // bends only the other side), signed so that the cross product
            // keeps one orientation.
            let at = |c: isize, r: isize| -> Option<f32> {
                (c >= 0 && r >= 0 && (c as usize) < w && (r as usize) < h)
                    .then(|| depth[r as usize * w + c as usize])
                    .filter(|z| z.is_finite())
            };
            let side = |dc: isize, dr: isize| -> Option<(DVec3, f32)> {
                let (c1, r1) = (c as isize + dc, r as isize + dr);
                let z1 = at(c1, r1).filter(|z1| (z1 - d).abs() <= SAME_SURFACE * d)?;
                let miss = match at(c1 + dc, r1 + dr) {
                    Some(z2) => (2.0 * z1 - z2 - d).abs(),
                    None => (z1 - d).abs(),
                };
                Some((point(c1 as usize, r1 as usize)?, miss))
            };
            let pick = |a: Option<(DVec3, f32)>, b: Option<(DVec3, f32)>| -> Option<DVec3> {
                match (a, b) {
                    (Some((pa, ea)), Some((pb, eb))) => Some(if ea <= eb { p - pa } else { pb - p }),
                    (Some((pa, _)), None) => Some(p - pa),
                    (None, Some((pb, _))) => Some(pb - p),
                    (None, None) => None,
                }
            };
            let across = pick(side(-1, 0), side(1, 0));
            let down = pick(side(0, -1), side(0, 1));
            let (Some(x), Some(y)) = (across, down) else { continue };
            let n = y.cross(x).normalize_or_zero();
            let Some((_, dir)) = projector.ray(c as u32, r as u32, [0.5, 0.5]) else {
                continue;
            };
            let n = if n.dot(dir) > 0.0 { -n } else { n };
            out[r * w + c] = n.as_vec3().to_array();
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::View;

    #[test]
    fn a_plane_seen_at_an_angle_gets_its_normal_and_a_step_keeps_both_sides() {
        // Looking along +y from the origin at the floor z = -1 (the lower
        // half of the frame) and, above, at a wall y = 5.
        let view = View::parse("-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 60").unwrap();
        let vp = Viewport::new(view, 40, 40).unwrap();
        let projector = Projector::new(&vp);
        let mut depth = vec![f32::NAN; 1600];
        let mut floor = vec![false; 1600];
        for r in 0..40 {
            for c in 0..40 {
                let (o, d) = projector.ray(c, r, [0.5, 0.5]).unwrap();
                let t_floor = if d.z < 0.0 { (-1.0 - o.z) / d.z } else { f64::INFINITY };
                let t_wall = (5.0 - o.y) / d.y;
                depth[(r * 40 + c) as usize] = t_floor.min(t_wall) as f32;
                floor[(r * 40 + c) as usize] = t_floor < t_wall;
            }
        }
        let g = Guide::new(&vp, depth, &vec![(0.0, 0.0, 0.0, 0); 1600]);
        let at = |c: usize, r: usize| glam::Vec3::from_array(g.normal[r * 40 + c]);
        // Deep in the floor and the wall, and on each side of the fold.
        assert!(at(20, 38).distance(glam::Vec3::Z) < 1e-3, "{}", at(20, 38));
        assert!(at(20, 2).distance(-glam::Vec3::Y) < 1e-3, "{}", at(20, 2));
        let fold = (0..40)
            .find(|&r| floor[r * 40 + 20])
            .expect("the floor starts somewhere");
        assert!(fold > 20 && fold < 38, "{fold}");
        assert!(at(20, fold).distance(glam::Vec3::Z) < 1e-2, "{}", at(20, fold));
        assert!(at(20, fold - 1).distance(-glam::Vec3::Y) < 1e-2, "{}", at(20, fold - 1));
        assert!(g.variance.iter().all(|v| v.is_nan()));
    }
}
