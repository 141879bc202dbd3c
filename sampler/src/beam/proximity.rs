//! Viewpoint-proximity sampling (holodeck paper, Appendix A): rays of a beam
//! chosen to pass near the eye, so that an interactive view converges faster.
//!
//! The paper bounds, on the entry wall, the region of lines from the exit
//! cell's corners that pass within the eye radius, picks entry points there
//! and exit points in the cone back through the eye sphere. Where the walls
//! are not parallel the corners' image is skewed and its box misses part of
//! the beam, and with a small radius the box goes flat: whole beams then fell
//! back to uniform rays, which land far from the pixels that asked for them
//! (holes in the picture, measured in `docs/DISPLAY.md`). We sample the lines
//! themselves: a point on whichever of the two cells looks smaller from the
//! eye, a point in the eye's sphere, and the line through both, kept if it
//! crosses the other cell (and, given a frustum, if it runs where the
//! display looks). A ray no try finds is traced uniformly.

use glam::DVec3;
use holodeck_protocol::{BeamIndex, Frustum, Section, SectionError, Wall, WallCell};

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

/// Lines tried per ray before it falls back to a uniform ray (or, when all
/// that missed was the frustum, to the last line near the eye).
const TRIES: u32 = 64;

/// The world point on `wall` at grid coordinates `g`.
fn world_point(section: &Section, wall: Wall, g: [f64; 2]) -> DVec3 {
    let [u, v] = wall.cell_axes();
    let mut unit = DVec3::ZERO;
    unit[wall.axis()] = f64::from(wall.side());
    unit[u] = g[0] / f64::from(section.grid()[u]);
    unit[v] = g[1] / f64::from(section.grid()[v]);
    section.unit_to_world(unit)
}

/// How large cell `c` looks from `eye`: its area over the squared distance,
/// times the cosine at its center.
fn apparent_size(section: &Section, c: &WallCell, eye: DVec3) -> f64 {
    let [u, v] = c.wall.cell_axes();
    let axes = section.axes();
    let area = (axes[u] / f64::from(section.grid()[u])).cross(axes[v] / f64::from(section.grid()[v]));
    let center = world_point(
        section,
        c.wall,
        [f64::from(c.cell[0]) + 0.5, f64::from(c.cell[1]) + 0.5],
    );
    let d = center - eye;
    let d2 = d.length_squared().max(1e-300);
    area.dot(d).abs() / (d2 * d2.sqrt())
}

/// Grid coordinates where the line through world points `p` and `q` meets
/// the plane of `wall`, if it does.
fn meet(section: &Section, wall: Wall, p: DVec3, q: DVec3) -> Option<[f64; 2]> {
    let (a, b) = (section.world_to_unit(p), section.world_to_unit(q));
    let axis = wall.axis();
    let denom = b[axis] - a[axis];
    if denom.abs() < 1e-12 {
        return None;
    }
    let x = a + (b - a) * ((f64::from(wall.side()) - a[axis]) / denom);
    let [u, v] = wall.cell_axes();
    let g = [x[u] * f64::from(section.grid()[u]), x[v] * f64::from(section.grid()[v])];
    g.iter().all(|c| c.is_finite()).then_some(g)
}

/// True when grid coordinates `g` lie in cell `c`.
fn inside(c: &WallCell, g: [f64; 2]) -> bool {
    (0..2).all(|i| (f64::from(c.cell[i])..f64::from(c.cell[i]) + 1.0).contains(&g[i]))
}

/// Sub-cell bytes of grid point `g` inside cell `c`.
fn sub_bytes(c: &WallCell, g: [f64; 2]) -> [u8; 2] {
    std::array::from_fn(|i| ((g[i] - f64::from(c.cell[i])) * 256.0).clamp(0.0, 255.0) as u8)
}

/// A point uniformly in the ball of `radius` around `center`.
fn in_ball(center: DVec3, radius: f64, rng: &mut Rng) -> DVec3 {
    loop {
        let (a, b) = rng.f32x2();
        let p = DVec3::new(f64::from(a), f64::from(b), f64::from(rng.f32())) * 2.0 - DVec3::ONE;
        if p.length_squared() <= 1.0 {
            return center + p * radius;
        }
    }
}

/// `n` rays of `beam` passing near `eye` (within about `radius`), with
/// uniform rays where no such line is found. With a `frustum`, rays are
/// chosen among those whose direction is in it (those a display looking
/// from the eye shows), as long as a few tries find one.
pub fn proximity_rays(
    section: &Section,
    beam: BeamIndex,
    n: usize,
    eye: DVec3,
    radius: f64,
    frustum: Option<&Frustum>,
    rng: &mut Rng,
) -> Result<(Vec<BeamSample>, ProximityStats), SectionError> {
    let cells = section.beam_cells(beam)?;
    let mut stats = ProximityStats::default();
    // Points go on the cell that looks smaller: lines from it through the
    // eye then mostly cross the larger one.
    let exit_first = apparent_size(section, &cells.exit, eye) <= apparent_size(section, &cells.entry, eye);
    let (from, to) = if exit_first {
        (cells.exit, cells.entry)
    } else {
        (cells.entry, cells.exit)
    };
    let mut rays = Vec::with_capacity(n);
    for _ in 0..n {
        let (mut chosen, mut near_only) = (None, None);
        for _ in 0..TRIES {
            let (a, b) = rng.f32x2();
            let g = [
                f64::from(from.cell[0]) + f64::from(a),
                f64::from(from.cell[1]) + f64::from(b),
            ];
            let p = world_point(section, from.wall, g);
            let Some(h) = meet(section, to.wall, p, in_ball(eye, radius, rng)) else {
                continue;
            };
            if !inside(&to, h) {
                continue;
            }
            let (entry_g, exit_g) = if exit_first { (h, g) } else { (g, h) };
            let (entry, exit) = (sub_bytes(&cells.entry, entry_g), sub_bytes(&cells.exit, exit_g));
            let ray = section.beam_ray(beam, entry, exit)?;
            let sample = BeamSample { entry, exit, ray };
            if frustum.is_some_and(|f| !f.contains(ray.direction, 0.0)) {
                near_only = Some(sample);
                continue;
            }
            chosen = Some(sample);
            break;
        }
        match chosen.or(near_only) {
            Some(s) => {
                stats.near += 1;
                rays.push(s);
            }
            None => {
                stats.uniform += 1;
                rays.push(super::uniform_rays(section, beam, 1, rng)?.remove(0));
            }
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
            let (rays, stats) = proximity_rays(&s, beam, 8, eye, radius, None, &mut rng).unwrap();
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
        let (rays, stats) = proximity_rays(&s, beam, 6, DVec3::new(5.7, 3.7, 1.2), 0.1, None, &mut rng).unwrap();
        assert_eq!(rays.len(), 6);
        assert_eq!(stats.uniform, 6, "{stats:?}");
        for r in rays {
            assert_eq!(s.locate(r.ray.origin, r.ray.direction).unwrap().beam, beam);
        }
    }

    #[test]
    fn a_frustum_keeps_rays_in_the_frame_of_the_eye() {
        let s = room();
        let view =
            holodeck_protocol::View::parse("-vtv -vp 2.2 1.7 1.1 -vd 1 0.1 -0.3 -vu 0 0 1 -vh 40 -vv 30").unwrap();
        let frustum = view.frustum().unwrap();
        let eye = view.position;
        // A beam straddling the frame's edge: seen through a ray at the edge.
        let (_, edge) = view.ray(0.0, 0.5).unwrap();
        let beam = s.locate(eye, edge).unwrap().beam;
        let mut rng = Rng::new(9, 0);
        let (free, _) = proximity_rays(&s, beam, 400, eye, 0.05, None, &mut rng).unwrap();
        let (kept, _) = proximity_rays(&s, beam, 400, eye, 0.05, Some(&frustum), &mut rng).unwrap();
        let inside = |rays: &[BeamSample]| rays.iter().filter(|r| frustum.contains(r.ray.direction, 0.0)).count();
        let (a, b) = (inside(&free), inside(&kept));
        assert!(
            a < 360 && b >= 396,
            "without the frustum {a} of 400 in the frame, with it {b}"
        );
        for r in &kept {
            assert_eq!(s.locate(r.ray.origin, r.ray.direction).unwrap().beam, beam);
            assert!(distance_to_line(eye, r.ray.origin, r.ray.direction) < 0.2);
        }
    }
}
