//! Viewpoint-proximity sampling (holodeck paper, Appendix A): rays of a beam
//! chosen to pass near the eye, so that an interactive view converges faster.
//!
//! The paper's steps:
//! 1. Cut the cone from one exit-cell corner around the eye sphere with the
//!    entry wall, and take the cut's extents within the entry cell.
//! 2. Do the same for the opposite corner, and grow the region to hold both.
//! 3. If the region is empty, sample the whole beam uniformly.
//! 4. For each ray, pick an entry point in the region, cut the cone from it
//!    around the eye sphere with the exit wall, and pick the exit point within
//!    that cut's extents inside the exit cell.
//! 5. When a cut misses the exit cell, try again; the whole packet may retry
//!    as many times as it has rays plus two, after which rays fall back to
//!    uniform sampling.
//!
//! The extents of a cut are found from 32 of the cone's generator lines. A cone
//! that reaches the wall on both nappes, or runs parallel to it, cuts an
//! unbounded region, and then the whole cell is allowed.

use glam::DVec3;
use holodeck_protocol::{BeamIndex, Section, SectionError, Wall, WallCell};

use super::BeamSample;
use crate::shade::Rng;

/// How a proximity packet came out.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ProximityStats {
    /// Rays sampled near the eye.
    pub near: usize,
    /// Rays that fell back to uniform sampling.
    pub uniform: usize,
}

/// A rectangle in a wall's grid coordinates (cell units along the wall's two axes).
#[derive(Clone, Copy, Debug)]
struct Rect {
    lo: [f64; 2],
    hi: [f64; 2],
}

impl Rect {
    const ALL: Rect = Rect {
        lo: [f64::NEG_INFINITY; 2],
        hi: [f64::INFINITY; 2],
    };

    fn clip(&self, o: &Rect) -> Option<Rect> {
        let r = Rect {
            lo: [self.lo[0].max(o.lo[0]), self.lo[1].max(o.lo[1])],
            hi: [self.hi[0].min(o.hi[0]), self.hi[1].min(o.hi[1])],
        };
        (r.lo[0] < r.hi[0] && r.lo[1] < r.hi[1]).then_some(r)
    }

    fn union(&self, o: &Rect) -> Rect {
        Rect {
            lo: [self.lo[0].min(o.lo[0]), self.lo[1].min(o.lo[1])],
            hi: [self.hi[0].max(o.hi[0]), self.hi[1].max(o.hi[1])],
        }
    }
}

const GENERATORS: usize = 32;

/// The cell of a wall as a rectangle in that wall's grid coordinates.
fn cell_rect(c: &WallCell) -> Rect {
    let (u, v) = (f64::from(c.cell[0]), f64::from(c.cell[1]));
    Rect {
        lo: [u, v],
        hi: [u + 1.0, v + 1.0],
    }
}

/// A world point on `wall` in that wall's grid coordinates.
fn grid_coords(section: &Section, wall: Wall, p: DVec3) -> [f64; 2] {
    let unit = section.world_to_unit(p);
    let [u, v] = wall.cell_axes();
    [
        unit[u] * f64::from(section.grid()[u]),
        unit[v] * f64::from(section.grid()[v]),
    ]
}

/// The world point on `wall` at grid coordinates `g`.
fn world_point(section: &Section, wall: Wall, g: [f64; 2]) -> DVec3 {
    let [u, v] = wall.cell_axes();
    let mut unit = DVec3::ZERO;
    unit[wall.axis()] = f64::from(wall.side());
    unit[u] = g[0] / f64::from(section.grid()[u]);
    unit[v] = g[1] / f64::from(section.grid()[v]);
    section.unit_to_world(unit)
}

/// Extents (grid coordinates of `wall`) of the lines through `apex` that pass
/// within `radius` of `eye`, where they meet the wall's plane.
fn cone_cut(section: &Section, apex: DVec3, eye: DVec3, radius: f64, wall: Wall) -> Rect {
    let to_eye = eye - apex;
    let dist = to_eye.length();
    if dist <= radius {
        return Rect::ALL;
    }
    let axis = to_eye / dist;
    let sin = radius / dist;
    let cos = (1.0 - sin * sin).sqrt();
    let (b1, b2) = axis.any_orthonormal_pair();
    let [u, v] = wall.cell_axes();
    let axes = section.axes();
    let normal = axes[u].cross(axes[v]);
    let plane = section.origin() + axes[wall.axis()] * f64::from(wall.side());
    let mut r = Rect {
        lo: [f64::INFINITY; 2],
        hi: [f64::NEG_INFINITY; 2],
    };
    let mut side = 0.0f64;
    for k in 0..GENERATORS {
        let phi = std::f64::consts::TAU * k as f64 / GENERATORS as f64;
        let d = axis * cos + (b1 * phi.cos() + b2 * phi.sin()) * sin;
        let denom = d.dot(normal);
        if denom.abs() < 1e-12 * normal.length() {
            return Rect::ALL;
        }
        let t = (plane - apex).dot(normal) / denom;
        if side != 0.0 && t.signum() != side {
            // The wall meets both nappes: the cut is unbounded.
            return Rect::ALL;
        }
        side = t.signum();
        let g = grid_coords(section, wall, apex + d * t);
        for (i, gi) in g.iter().enumerate() {
            r.lo[i] = r.lo[i].min(*gi);
            r.hi[i] = r.hi[i].max(*gi);
        }
    }
    // The generators make an inscribed polygon: widen by a little to cover the ellipse.
    for i in 0..2 {
        let pad = 0.02 * (r.hi[i] - r.lo[i]);
        r.lo[i] -= pad;
        r.hi[i] += pad;
    }
    r
}

fn pick(r: &Rect, rng: &mut Rng) -> [f64; 2] {
    let (a, b) = rng.f32x2();
    [
        r.lo[0] + (r.hi[0] - r.lo[0]) * f64::from(a),
        r.lo[1] + (r.hi[1] - r.lo[1]) * f64::from(b),
    ]
}

/// Sub-cell bytes of grid point `g` inside cell `c`.
fn sub_bytes(c: &WallCell, g: [f64; 2]) -> [u8; 2] {
    std::array::from_fn(|i| ((g[i] - f64::from(c.cell[i])) * 256.0).clamp(0.0, 255.0) as u8)
}

/// `n` rays of `beam` passing near `eye` (within about `radius`), with
/// uniform rays wherever the paper's algorithm gives up.
pub fn proximity_rays(
    section: &Section,
    beam: BeamIndex,
    n: usize,
    eye: DVec3,
    radius: f64,
    rng: &mut Rng,
) -> Result<(Vec<BeamSample>, ProximityStats), SectionError> {
    let cells = section.beam_cells(beam)?;
    let (entry_cell, exit_cell) = (cell_rect(&cells.entry), cell_rect(&cells.exit));
    let mut stats = ProximityStats::default();
    let uniform = |rng: &mut Rng, stats: &mut ProximityStats| -> Result<BeamSample, SectionError> {
        stats.uniform += 1;
        Ok(super::uniform_rays(section, beam, 1, rng)?.remove(0))
    };
    // Steps 1-3: the entry region from two opposite exit-cell corners.
    let corners = [exit_cell.lo, exit_cell.hi].map(|g| world_point(section, cells.exit.wall, g));
    let region = corners
        .iter()
        .filter_map(|&c| cone_cut(section, c, eye, radius, cells.entry.wall).clip(&entry_cell))
        .reduce(|a, b| a.union(&b));
    let Some(region) = region else {
        let rays = (0..n).map(|_| uniform(rng, &mut stats)).collect::<Result<_, _>>()?;
        return Ok((rays, stats));
    };
    // Steps 4-5.
    let mut retries = n + 2;
    let mut rays = Vec::with_capacity(n);
    while rays.len() < n {
        let a = pick(&region, rng);
        let apex = world_point(section, cells.entry.wall, a);
        match cone_cut(section, apex, eye, radius, cells.exit.wall).clip(&exit_cell) {
            Some(exit_region) => {
                let b = pick(&exit_region, rng);
                let (entry, exit) = (sub_bytes(&cells.entry, a), sub_bytes(&cells.exit, b));
                rays.push(BeamSample {
                    entry,
                    exit,
                    ray: section.beam_ray(beam, entry, exit)?,
                });
                stats.near += 1;
            }
            None if retries > 0 => retries -= 1,
            None => rays.push(uniform(rng, &mut stats)?),
        }
    }
    Ok((rays, stats))
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::SectionKind;

    fn room() -> Section {
        Section::new(
            [0.0; 3],
            [[6.0, 0.0, 0.0], [0.0, 4.0, 0.0], [0.0, 0.0, 2.5]],
            [6, 4, 3],
            SectionKind::Interior,
        )
        .unwrap()
    }

    fn distance_to_line(p: DVec3, o: DVec3, d: DVec3) -> f64 {
        (p - o).cross(d).length() / d.length()
    }

    #[test]
    fn rays_stay_in_their_beam_and_mostly_pass_near_the_eye() {
        let s = room();
        let eye = DVec3::new(2.2, 1.7, 1.1);
        let radius = 0.25;
        let mut rng = Rng::new(3, 0);
        let (mut near_hits, mut total, mut near_rays, mut uniform_near) = (0, 0, 0, 0);
        // Beams whose lines pass near the eye: found by shooting rays through it.
        let mut beams = Vec::new();
        for k in 0..200 {
            let phi = k as f64 * 0.7;
            let theta = (k as f64 * 0.37).sin();
            let dir = DVec3::new(phi.cos() * theta.cos(), phi.sin() * theta.cos(), theta.sin());
            if let Some(hit) = s.locate(eye + dir * 0.05, dir) {
                beams.push(hit.beam);
            }
        }
        for &beam in &beams {
            let (rays, stats) = proximity_rays(&s, beam, 8, eye, radius, &mut rng).unwrap();
            assert_eq!(rays.len(), 8);
            near_rays += stats.near;
            for r in &rays {
                let found = s.locate(r.ray.origin, r.ray.direction).unwrap();
                assert_eq!(found.beam, beam, "every ray stays in its beam");
                total += 1;
                if distance_to_line(eye, r.ray.origin, r.ray.direction) <= radius * 1.5 {
                    near_hits += 1;
                }
            }
            // Uniform rays of the same beam, for comparison.
            for r in crate::beam::uniform_rays(&s, beam, 8, &mut rng).unwrap() {
                if distance_to_line(eye, r.ray.origin, r.ray.direction) <= radius * 1.5 {
                    uniform_near += 1;
                }
            }
        }
        let near_fraction = near_hits as f64 / total as f64;
        let uniform_fraction = uniform_near as f64 / total as f64;
        assert!(near_rays > total / 2, "{near_rays} of {total} sampled near the eye");
        assert!(near_fraction > 0.8, "only {near_fraction:.2} of rays pass near the eye");
        assert!(
            near_fraction > uniform_fraction + 0.2,
            "proximity {near_fraction:.2} vs uniform {uniform_fraction:.2}"
        );
    }

    #[test]
    fn an_eye_far_from_a_beam_falls_back_to_uniform() {
        let s = room();
        let mut rng = Rng::new(5, 0);
        // A beam between two cells of the floor and ceiling at one corner, an eye at the other.
        let beam = s.locate(DVec3::new(0.3, 0.3, -1.0), DVec3::Z).unwrap().beam;
        let (rays, stats) = proximity_rays(&s, beam, 6, DVec3::new(5.7, 3.7, 1.2), 0.1, &mut rng).unwrap();
        assert_eq!(rays.len(), 6);
        assert_eq!(stats.uniform, 6, "{stats:?}");
        for r in rays {
            assert_eq!(s.locate(r.ray.origin, r.ray.direction).unwrap().beam, beam);
        }
    }
}
