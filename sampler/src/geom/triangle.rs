//! The watertight ray/triangle test of Woop, Benthin and Wald (JCGT 2013):
//! rays are sheared so that they run along +z, and the triangle's edge
//! functions are evaluated in 2D. A ray through a shared edge or vertex hits
//! at least one of the triangles that share it: no cracks.

use glam::Vec3;

/// Per-ray constants of the test: the shear that maps the ray onto +z, as three
/// rows, so that each sheared coordinate is one dot product. Each row has one or
/// two non-zero entries, and adding exact zeros changes nothing, so the results
/// are bit-for-bit those of the permute-then-shear formulation of the paper.
#[derive(Clone, Copy, Debug)]
pub struct RayPrep {
    origin: Vec3,
    row_x: Vec3,
    row_y: Vec3,
    row_z: Vec3,
}

impl RayPrep {
    /// Prepares a ray with origin `origin` and direction `dir` (non-zero).
    #[inline]
    pub fn new(origin: Vec3, dir: Vec3) -> RayPrep {
        let [kx, ky, kz] = axis_permutation(dir);
        // Arrays, not `Vec3`'s indexing, which branches on the index.
        let d = dir.to_array();
        let (sx, sy, sz) = (d[kx] / d[kz], d[ky] / d[kz], 1.0 / d[kz]);
        let (mut row_x, mut row_y, mut row_z) = ([0f32; 3], [0f32; 3], [0f32; 3]);
        row_x[kx] = 1.0;
        row_x[kz] = -sx;
        row_y[ky] = 1.0;
        row_y[kz] = -sy;
        row_z[kz] = sz;
        RayPrep {
            origin,
            row_x: Vec3::from(row_x),
            row_y: Vec3::from(row_y),
            row_z: Vec3::from(row_z),
        }
    }
}

/// The axes (x', y', z') of the sheared space: z' is the direction's largest
/// component, and x', y' are swapped when it is negative so that triangles keep
/// their winding.
#[inline]
pub fn axis_permutation(dir: Vec3) -> [usize; 3] {
    let a = dir.abs();
    let kz = if a.x > a.y {
        if a.x > a.z {
            0
        } else {
            2
        }
    } else if a.y > a.z {
        1
    } else {
        2
    };
    let (mut kx, mut ky) = ((kz + 1) % 3, (kz + 2) % 3);
    // An array, not `Vec3`'s indexing, which branches on the index.
    if dir.to_array()[kz] < 0.0 {
        std::mem::swap(&mut kx, &mut ky);
    }
    [kx, ky, kz]
}

/// Where a ray hits a triangle: distance and barycentrics of vertices 1 and 2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TriangleHit {
    /// Ray parameter.
    pub t: f32,
    /// Barycentric weight of vertex 1.
    pub u: f32,
    /// Barycentric weight of vertex 2.
    pub v: f32,
}

/// Intersects the prepared ray with triangle (a, b, c) in `(0, t_max]`, both faces.
#[inline(always)]
pub fn intersect_triangle(r: &RayPrep, a: Vec3, b: Vec3, c: Vec3, t_max: f32) -> Option<TriangleHit> {
    let (pa, pb, pc) = (a - r.origin, b - r.origin, c - r.origin);
    let (ax, ay) = (pa.dot(r.row_x), pa.dot(r.row_y));
    let (bx, by) = (pb.dot(r.row_x), pb.dot(r.row_y));
    let (cx, cy) = (pc.dot(r.row_x), pc.dot(r.row_y));
    let mut u = cx * by - cy * bx;
    let mut v = ax * cy - ay * cx;
    let mut w = bx * ay - by * ax;
    if u == 0.0 || v == 0.0 || w == 0.0 {
        // On an edge in single precision: decide in double, as the paper does.
        let d = |p: f32, q: f32, s: f32, t: f32| f64::from(p) * f64::from(q) - f64::from(s) * f64::from(t);
        u = d(cx, by, cy, bx) as f32;
        v = d(ax, cy, ay, cx) as f32;
        w = d(bx, ay, by, ax) as f32;
    }
    if (u < 0.0 || v < 0.0 || w < 0.0) && (u > 0.0 || v > 0.0 || w > 0.0) {
        return None;
    }
    let det = u + v + w;
    if det == 0.0 {
        return None;
    }
    let (az, bz, cz) = (pa.dot(r.row_z), pb.dot(r.row_z), pc.dot(r.row_z));
    let t_scaled = u * az + v * bz + w * cz;
    // Compare before dividing, with det's sign folded in.
    let sign = det.signum();
    // Written so that NaN (from overflowing coordinates) is never a hit.
    if !(t_scaled * sign > 0.0 && t_scaled * sign <= t_max * det * sign) {
        return None;
    }
    let inv = 1.0 / det;
    Some(TriangleHit {
        t: t_scaled * inv,
        u: v * inv,
        v: w * inv,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hits_inside_misses_outside_and_respects_range() {
        let (a, b, c) = (
            Vec3::new(0.0, 0.0, 1.0),
            Vec3::new(1.0, 0.0, 1.0),
            Vec3::new(0.0, 1.0, 1.0),
        );
        let r = RayPrep::new(Vec3::new(0.25, 0.25, 0.0), Vec3::Z);
        let h = intersect_triangle(&r, a, b, c, f32::INFINITY).unwrap();
        assert!((h.t - 1.0).abs() < 1e-6 && (h.u - 0.25).abs() < 1e-6 && (h.v - 0.25).abs() < 1e-6);
        assert!(intersect_triangle(&r, a, b, c, 0.5).is_none(), "beyond t_max");
        let behind = RayPrep::new(Vec3::new(0.25, 0.25, 2.0), Vec3::Z);
        assert!(
            intersect_triangle(&behind, a, b, c, f32::INFINITY).is_none(),
            "behind the origin"
        );
        let miss = RayPrep::new(Vec3::new(0.75, 0.75, 0.0), Vec3::Z);
        assert!(intersect_triangle(&miss, a, b, c, f32::INFINITY).is_none());
    }

    #[test]
    fn an_edge_decided_by_rounding_is_decided_again_in_double() {
        // Seen along the ray (+z from the origin), the edge b-c passes e²
        // (e = 2^-23) beside the origin, outside the triangle; in single
        // precision its two products round to the same value, so the edge
        // function reads exactly 0, which would count the ray as on the edge.
        let e = f32::EPSILON;
        let a = Vec3::new(-5.0, 5.0, 1.0);
        let b = Vec3::new(-(1.0 + e), -1.0, 1.0);
        let c = Vec3::new(1.0 + 2.0 * e, 1.0 + e, 1.0);
        assert_eq!(c.x * b.y - c.y * b.x, 0.0, "the products tie in single precision");
        let exact = f64::from(c.x) * f64::from(b.y) - f64::from(c.y) * f64::from(b.x);
        assert_eq!(exact, f64::from(e) * f64::from(e));
        let r = RayPrep::new(Vec3::ZERO, Vec3::Z);
        assert!(
            intersect_triangle(&r, a, b, c, f32::INFINITY).is_none(),
            "the origin lies outside edge b-c"
        );
        // The triangle across that edge takes the ray: nothing leaks.
        let d = Vec3::new(5.0, -5.0, 1.0);
        let h = intersect_triangle(&r, c, b, d, f32::INFINITY).expect("the neighbour across the edge");
        assert!((h.t - 1.0).abs() < 1e-6);
    }

    #[test]
    fn shared_edges_and_vertices_never_leak() {
        // A fan of triangles around a vertex: rays through the shared vertex
        // and along shared edges hit at least one of them.
        let centre = Vec3::new(0.3, 0.7, 2.0);
        let ring: Vec<Vec3> = (0..7)
            .map(|i| centre + Vec3::new((i as f32).cos(), (i as f32 * 1.3).sin(), 0.1 * i as f32))
            .collect();
        let mut targets = vec![centre];
        targets.extend(ring.iter().map(|r| (centre + *r) * 0.5));
        for target in targets {
            for o in [
                Vec3::new(-1.0, -2.0, -3.0),
                Vec3::new(0.1, 0.2, -0.3),
                Vec3::new(3.0, -1.0, -5.0),
            ] {
                let r = RayPrep::new(o, target - o);
                let hits = (0..7)
                    .filter(|&i| intersect_triangle(&r, centre, ring[i], ring[(i + 1) % 7], f32::INFINITY).is_some())
                    .count();
                assert!(hits >= 1, "ray through {target} from {o} leaked");
            }
        }
    }
}
