//! Scene geometry as a display uses it: triangles for a depth pass, cut
//! down to a triangle budget so that a massive scene still draws in a
//! frame's time (the Voronoi driver culls estimates by it).

use std::collections::HashMap;

use glam::{DVec3, Vec3};

/// Triangles a display draws by default at most.
pub const DEFAULT_BUDGET: usize = 500_000;

/// Triangles in world space, in f32 relative to an origin kept in f64 (so
/// that a kilometer-wide scene keeps millimeters).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Geometry {
    /// The point the positions are relative to.
    pub origin: DVec3,
    /// Triangles, three positions each, relative to `origin`.
    pub triangles: Vec<[Vec3; 3]>,
    /// Triangles in the scene before simplification.
    pub source_triangles: usize,
}

impl Geometry {
    /// Geometry from world-space triangles, simplified to at most `budget`
    /// triangles (see [`simplify`]) and, with `bounds`, cut to those that
    /// touch the box (the part of a scene a holodeck's sections see).
    pub fn new(triangles: &[[Vec3; 3]], budget: usize, bounds: Option<(Vec3, Vec3)>) -> Geometry {
        let kept: Vec<[Vec3; 3]> = match bounds {
            Some((lo, hi)) => triangles
                .iter()
                .filter(|t| {
                    let (a, b) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
                    a.cmple(hi).all() && b.cmpge(lo).all()
                })
                .copied()
                .collect(),
            None => triangles.to_vec(),
        };
        let simplified = simplify(&kept, budget);
        let (lo, hi) = bounds_of(&simplified);
        let origin = ((lo + hi) * 0.5).as_dvec3();
        let o = origin.as_vec3();
        Geometry {
            origin,
            triangles: simplified.iter().map(|t| t.map(|p| p - o)).collect(),
            source_triangles: triangles.len(),
        }
    }
}

fn bounds_of(triangles: &[[Vec3; 3]]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for p in triangles.iter().flatten() {
        lo = lo.min(*p);
        hi = hi.max(*p);
    }
    if lo.is_finite() && hi.is_finite() {
        (lo, hi)
    } else {
        (Vec3::ZERO, Vec3::ZERO)
    }
}

/// At most `budget` triangles that keep the shape of `triangles`: vertex
/// clustering (Rossignac and Borrel) on the finest grid that meets the
/// budget. Each vertex moves to the mean of its cell's vertices, triangles
/// whose corners share a cell vanish, and repeats are dropped; the grid is
/// found by bisection on its resolution. Fine detail goes first, large
/// walls and floors stay where they were, which is what a depth pass needs.
pub fn simplify(triangles: &[[Vec3; 3]], budget: usize) -> Vec<[Vec3; 3]> {
    let finite: Vec<[Vec3; 3]> = triangles
        .iter()
        .filter(|t| t.iter().all(|p| p.is_finite()))
        .copied()
        .collect();
    if finite.len() <= budget {
        return finite;
    }
    if budget == 0 {
        return Vec::new();
    }
    let (lo, hi) = bounds_of(&finite);
    let extent = (hi - lo).max_element().max(f32::MIN_POSITIVE);
    // Cells along the longest side: the answer lies in [1, 2^20].
    let (mut fewer, mut more) = (1u32, 1u32 << 20);
    let mut best = cluster(&finite, lo, extent, fewer);
    while more - fewer > 1 {
        let mid = fewer + (more - fewer) / 2;
        let out = cluster(&finite, lo, extent, mid);
        if out.len() <= budget {
            fewer = mid;
            best = out;
        } else {
            more = mid;
        }
    }
    best
}

/// Vertex clustering on a grid of `cells` cells along the longest side.
fn cluster(triangles: &[[Vec3; 3]], lo: Vec3, extent: f32, cells: u32) -> Vec<[Vec3; 3]> {
    let scale = cells as f32 / extent;
    let cell = |p: Vec3| -> [u32; 3] {
        let c = ((p - lo) * scale).floor();
        [c.x, c.y, c.z].map(|v| (v.max(0.0) as u32).min(cells - 1))
    };
    let mut means: HashMap<[u32; 3], (Vec3, u32)> = HashMap::new();
    for p in triangles.iter().flatten() {
        let m = means.entry(cell(*p)).or_insert((Vec3::ZERO, 0));
        m.0 += *p;
        m.1 += 1;
    }
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for t in triangles {
        let c = t.map(cell);
        if c[0] == c[1] || c[1] == c[2] || c[0] == c[2] {
            continue;
        }
        // The same three cells in any rotation or winding are one triangle.
        let mut key = c;
        key.sort_unstable();
        if !seen.insert(key) {
            continue;
        }
        out.push(c.map(|k| {
            let (sum, n) = means[&k];
            sum / n as f32
        }));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A w x h grid of squares in the plane z = 0, two triangles each.
    fn sheet(w: usize, h: usize) -> Vec<[Vec3; 3]> {
        let mut out = Vec::new();
        for y in 0..h {
            for x in 0..w {
                let p = |i: usize, j: usize| Vec3::new(i as f32, j as f32, 0.0);
                out.push([p(x, y), p(x + 1, y), p(x + 1, y + 1)]);
                out.push([p(x, y), p(x + 1, y + 1), p(x, y + 1)]);
            }
        }
        out
    }

    #[test]
    fn geometry_within_budget_is_kept_as_it_is() {
        let s = sheet(4, 4);
        assert_eq!(simplify(&s, 32), s);
        assert_eq!(simplify(&s, 1000).len(), 32);
    }

    #[test]
    fn simplified_geometry_meets_the_budget_and_keeps_the_outline() {
        let s = sheet(100, 100);
        for budget in [10_000, 2_000, 200, 20] {
            let out = simplify(&s, budget);
            assert!(out.len() <= budget, "{budget}: {}", out.len());
            assert!(out.len() > budget / 8, "{budget}: only {} triangles", out.len());
            // Still a flat sheet spanning most of the original square.
            let (lo, hi) = bounds_of(&out);
            assert!(lo.z.abs() < 1e-6 && hi.z.abs() < 1e-6);
            let least = if budget >= 200 { 80.0 } else { 50.0 };
            assert!(hi.x - lo.x > least && hi.y - lo.y > least, "{lo} {hi}");
        }
    }

    #[test]
    fn bounds_keep_only_triangles_that_touch_the_box() {
        let s = sheet(10, 10);
        let g = Geometry::new(&s, 1000, Some((Vec3::new(0.0, 0.0, -1.0), Vec3::new(2.5, 2.5, 1.0))));
        // Squares 0..=2 on each side touch [0, 2.5].
        assert_eq!(g.triangles.len(), 3 * 3 * 2);
        assert_eq!(g.source_triangles, 200);
        let back: Vec<Vec3> = g.triangles.iter().flatten().map(|p| *p + g.origin.as_vec3()).collect();
        assert!(back.iter().all(|p| p.x <= 3.0 && p.y <= 3.0));
    }

    #[test]
    fn nonfinite_triangles_are_dropped() {
        let mut s = sheet(2, 2);
        s.push([Vec3::NAN, Vec3::ZERO, Vec3::X]);
        assert_eq!(simplify(&s, 100).len(), 8);
    }
}
