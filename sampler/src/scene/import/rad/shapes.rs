//! Radiance surfaces as triangles, in the file's own coordinates (f64): the
//! argument checks Radiance makes, then tessellation. Front faces follow
//! Radiance's surface normals: a polygon's by the right-hand rule over its
//! vertex order, outward for `sphere`, `cone` and `cylinder`, inward for
//! `bubble`, `cup` and `tube`, along the given normal for `ring`.
//!
//! Curved surfaces use a fixed tessellation: [`SEGMENTS`] segments around
//! every circle and [`SPHERE_BANDS`] bands from pole to pole, so a sphere's
//! mesh area is within 0.25 % of 4πr², a disk's within 0.2 % of πr², and a
//! cylinder's within 0.05 % of 2πrh.
//! Vertices lie on the true surface, so meshes sit slightly inside it.

use glam::{DVec2, DVec3};

/// Segments around every circle of a sphere, cone, cylinder or ring.
pub const SEGMENTS: u32 = 64;
/// Bands of latitude of a sphere, pole to pole.
pub const SPHERE_BANDS: u32 = 32;
/// Largest concave polygon that is ear-clipped (the method costs the square
/// of the vertex count); larger ones are fanned from their first vertex.
pub(super) const MAX_EAR_CLIP: usize = 10_000;
/// Vertex tests that ear clipping may spend on one file with all it includes
/// (about a second): past it, concave polygons are fanned, so that a hostile
/// file of many large concave polygons cannot stall the reader.
pub(super) const EAR_CLIP_BUDGET: u64 = 1 << 28;

/// The surface types read.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum SurfaceKind {
    /// A flat polygon.
    Polygon,
    /// A sphere, normal outward.
    Sphere,
    /// A sphere, normal inward.
    Bubble,
    /// A truncated cone, open at both ends, normal outward.
    Cone,
    /// A cone, normal inward.
    Cup,
    /// An open cylinder, normal outward.
    Cylinder,
    /// A cylinder, normal inward.
    Tube,
    /// A flat annulus (a disk when the inner radius is 0).
    Ring,
}

impl SurfaceKind {
    /// The surface type named `kind`, if it is one of those read.
    pub(super) fn parse(kind: &str) -> Option<SurfaceKind> {
        Some(match kind {
            "polygon" => SurfaceKind::Polygon,
            "sphere" => SurfaceKind::Sphere,
            "bubble" => SurfaceKind::Bubble,
            "cone" => SurfaceKind::Cone,
            "cup" => SurfaceKind::Cup,
            "cylinder" => SurfaceKind::Cylinder,
            "tube" => SurfaceKind::Tube,
            "ring" => SurfaceKind::Ring,
            _ => return None,
        })
    }
}

/// Triangles in a file's coordinates, counter-clockwise seen from the front.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct ShapeMesh {
    /// Vertex positions.
    pub positions: Vec<DVec3>,
    /// Triangles indexing `positions`.
    pub triangles: Vec<[u32; 3]>,
}

impl ShapeMesh {
    fn vertex(&mut self, p: DVec3) -> u32 {
        self.positions.push(p);
        (self.positions.len() - 1) as u32
    }
}

/// Something about a surface worth reporting.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ShapeNote {
    /// A negative radius turned the surface inside out, as in Radiance.
    NegativeRadius,
    /// A polygon with no area: nothing to show.
    ZeroArea,
    /// A polygon too twisted (or too large) to ear-clip, fanned instead.
    Fanned,
}

/// Why a surface's arguments describe no surface.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum ShapeError {
    /// The wrong number of reals; what the type takes.
    Count(&'static str),
    /// Arguments that make no surface.
    Bad(String),
}

/// A tessellated surface and what to report about it.
#[derive(Clone, Debug, Default, PartialEq)]
pub(super) struct Shape {
    /// The triangles.
    pub mesh: ShapeMesh,
    /// What to report, if anything.
    pub note: Option<ShapeNote>,
}

/// The triangles of a surface of type `kind` with real arguments `r`;
/// ear clipping spends from `budget` (see [`EAR_CLIP_BUDGET`]).
pub(super) fn tessellate(kind: SurfaceKind, r: &[f64], budget: &mut u64) -> Result<Shape, ShapeError> {
    let p = |k: usize| DVec3::new(r[k], r[k + 1], r[k + 2]);
    match kind {
        SurfaceKind::Polygon => {
            if r.len() < 9 || !r.len().is_multiple_of(3) {
                return Err(ShapeError::Count("9 or more reals, a multiple of 3"));
            }
            let vertices: Vec<DVec3> = r.chunks_exact(3).map(|c| DVec3::new(c[0], c[1], c[2])).collect();
            Ok(polygon(vertices, budget))
        }
        SurfaceKind::Sphere | SurfaceKind::Bubble => {
            if r.len() != 4 {
                return Err(ShapeError::Count("4 reals: center and radius"));
            }
            if r[3] == 0.0 {
                return Err(ShapeError::Bad("zero radius".to_string()));
            }
            let flip = r[3] < 0.0;
            let inward = (kind == SurfaceKind::Bubble) != flip;
            Ok(noted(sphere(p(0), r[3].abs(), inward), flip))
        }
        SurfaceKind::Cylinder | SurfaceKind::Tube => {
            if r.len() != 7 {
                return Err(ShapeError::Count("7 reals: two end points and a radius"));
            }
            if r[6] == 0.0 {
                return Err(ShapeError::Bad("zero radius".to_string()));
            }
            let flip = r[6] < 0.0;
            let inward = (kind == SurfaceKind::Tube) != flip;
            let radius = r[6].abs();
            Ok(noted(cone(p(0), p(3), radius, radius, inward)?, flip))
        }
        SurfaceKind::Cone | SurfaceKind::Cup => {
            if r.len() != 8 {
                return Err(ShapeError::Count("8 reals: two end points and two radii"));
            }
            let (r0, r1) = (r[6], r[7]);
            // Radiance: one radius may be zero, not both; a negative radius
            // turns the cone inside out, but radii of both signs are illegal.
            let (s0, s1) = (r0.signum() * f64::from(r0 != 0.0), r1.signum() * f64::from(r1 != 0.0));
            if s0 + s1 == 0.0 {
                return Err(ShapeError::Bad(format!("illegal radii {r0} and {r1}")));
            }
            let flip = s0 < 0.0 || s1 < 0.0;
            let inward = (kind == SurfaceKind::Cup) != flip;
            Ok(noted(cone(p(0), p(3), r0.abs(), r1.abs(), inward)?, flip))
        }
        SurfaceKind::Ring => {
            if r.len() != 8 {
                return Err(ShapeError::Count("8 reals: center, normal and two radii"));
            }
            let (r0, r1) = (r[6], r[7]);
            if r0 < 0.0 || r1 < 0.0 || r0 == r1 {
                return Err(ShapeError::Bad(format!("illegal radii {r0} and {r1}")));
            }
            let normal = p(3);
            if normal.length_squared() == 0.0 || !normal.length_squared().is_finite() {
                return Err(ShapeError::Bad("zero normal".to_string()));
            }
            Ok(Shape {
                mesh: ring(p(0), normal.normalize(), r0.min(r1), r0.max(r1)),
                note: None,
            })
        }
    }
}

/// `mesh` with the negative-radius note when `flipped`.
fn noted(mesh: ShapeMesh, flipped: bool) -> Shape {
    Shape {
        mesh,
        note: flipped.then_some(ShapeNote::NegativeRadius),
    }
}

/// A polygon's triangles: ear clipping in the plane of its normal (found as
/// Radiance does, from the whole outline), so concave outlines and outlines
/// whose holes are joined by seams come out right.
pub(super) fn polygon(mut v: Vec<DVec3>, budget: &mut u64) -> Shape {
    // Radiance drops a last vertex that repeats the first.
    if v.len() > 3 && v[0].distance_squared(v[v.len() - 1]) == 0.0 {
        v.pop();
    }
    let mut normal = DVec3::ZERO;
    for k in 2..v.len() {
        normal += (v[k - 1] - v[0]).cross(v[k] - v[0]);
    }
    let mut shape = Shape::default();
    if !(normal.length_squared() > 0.0 && normal.is_finite()) {
        shape.note = Some(ShapeNote::ZeroArea);
        return shape;
    }
    // Project along the normal's largest axis onto a plane where the outline
    // runs counter-clockwise: (i, j, ax) cyclic, j negated when the normal
    // points down that axis.
    let a = normal.abs();
    let ax = if a.x >= a.y && a.x >= a.z {
        0
    } else if a.y >= a.z {
        1
    } else {
        2
    };
    let (i, j) = [(1, 2), (2, 0), (0, 1)][ax];
    let sign = normal[ax].signum();
    let flat: Vec<DVec2> = v.iter().map(|p| DVec2::new(p[i], p[j] * sign)).collect();
    let (triangles, fanned) = triangulate(&flat, budget);
    shape.mesh = ShapeMesh {
        positions: v,
        triangles,
    };
    shape.note = fanned.then_some(ShapeNote::Fanned);
    shape
}

/// Triangles of a counter-clockwise outline, and whether ear clipping gave up
/// (a self-crossing outline, or `budget` spent) and the rest was fanned.
fn triangulate(p: &[DVec2], budget: &mut u64) -> (Vec<[u32; 3]>, bool) {
    let n = p.len();
    let cross = |a: usize, b: usize, c: usize| (p[b] - p[a]).perp_dot(p[c] - p[b]);
    let fan = |idx: &[u32], out: &mut Vec<[u32; 3]>| {
        for k in 1..idx.len().saturating_sub(1) {
            out.push([idx[0], idx[k], idx[k + 1]]);
        }
    };
    let mut out = Vec::with_capacity(n.saturating_sub(2));
    let convex = (0..n).all(|k| cross(k, (k + 1) % n, (k + 2) % n) >= 0.0);
    let idx: Vec<u32> = (0..n as u32).collect();
    if convex || n > MAX_EAR_CLIP {
        fan(&idx, &mut out);
        return (out, !convex);
    }
    let (lo, hi) = p.iter().fold((p[0], p[0]), |(lo, hi), q| (lo.min(*q), hi.max(*q)));
    let eps = 1e-12 * (hi - lo).length_squared();
    let mut idx = idx;
    let mut k = 0;
    let mut tried = 0;
    while idx.len() > 3 {
        let m = idx.len();
        let (a, b, c) = (idx[(k + m - 1) % m], idx[k % m], idx[(k + 1) % m]);
        let (ua, ub, uc) = (a as usize, b as usize, c as usize);
        if *budget < m as u64 {
            fan(&idx, &mut out);
            return (out, true);
        }
        *budget -= m as u64;
        if cross(ua, ub, uc) > eps && !idx.iter().any(|&q| blocks(p, q as usize, [ua, ub, uc])) {
            out.push([a, b, c]);
            idx.remove(k % m);
            k %= m - 1;
            tried = 0;
            continue;
        }
        k = (k + 1) % m;
        tried += 1;
        if tried >= m {
            // No ear: drop a vertex where the outline runs straight or folds
            // back on itself (it adds no area), else fan what is left.
            let m = idx.len();
            let flat = (0..m).find(|&t| {
                let (a, b, c) = (idx[(t + m - 1) % m], idx[t], idx[(t + 1) % m]);
                cross(a as usize, b as usize, c as usize).abs() <= eps
            });
            match flat {
                Some(t) => {
                    idx.remove(t);
                    k = 0;
                    tried = 0;
                }
                None => {
                    fan(&idx, &mut out);
                    return (out, true);
                }
            }
        }
    }
    if idx.len() == 3 {
        out.push([idx[0], idx[1], idx[2]]);
    }
    (out, false)
}

/// Whether vertex `q` lies in the triangle `t` (edges included), and is not
/// one of its corners (a seam repeats corners; those do not block an ear).
fn blocks(p: &[DVec2], q: usize, t: [usize; 3]) -> bool {
    let x = p[q];
    if t.iter().any(|&c| p[c] == x) {
        return false;
    }
    let [a, b, c] = t.map(|k| p[k]);
    let d1 = (b - a).perp_dot(x - a);
    let d2 = (c - b).perp_dot(x - b);
    let d3 = (a - c).perp_dot(x - c);
    d1 >= 0.0 && d2 >= 0.0 && d3 >= 0.0
}

/// A sphere of `SEGMENTS` x `SPHERE_BANDS` quads (triangles at the poles).
pub(super) fn sphere(center: DVec3, radius: f64, inward: bool) -> ShapeMesh {
    let (seg, bands) = (SEGMENTS, SPHERE_BANDS);
    let mut m = ShapeMesh::default();
    let top = m.vertex(center + DVec3::Z * radius);
    for band in 1..bands {
        let theta = std::f64::consts::PI * f64::from(band) / f64::from(bands);
        for s in 0..seg {
            let phi = std::f64::consts::TAU * f64::from(s) / f64::from(seg);
            let d = DVec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos());
            m.vertex(center + d * radius);
        }
    }
    let bottom = m.vertex(center - DVec3::Z * radius);
    let at = |band: u32, s: u32| 1 + (band - 1) * seg + s % seg;
    for s in 0..seg {
        m.triangles.push([top, at(1, s), at(1, s + 1)]);
        for band in 1..bands - 1 {
            let (a, b, c, d) = (at(band, s), at(band + 1, s), at(band + 1, s + 1), at(band, s + 1));
            m.triangles.push([a, b, c]);
            m.triangles.push([a, c, d]);
        }
        m.triangles.push([bottom, at(bands - 1, s + 1), at(bands - 1, s)]);
    }
    if inward {
        flip(&mut m);
    }
    m
}

/// The side of a truncated cone from `p0` (radius `r0`) to `p1` (radius
/// `r1`), open at both ends; a zero radius is a single apex vertex.
pub(super) fn cone(p0: DVec3, p1: DVec3, r0: f64, r1: f64, inward: bool) -> Result<ShapeMesh, ShapeError> {
    let axis = p1 - p0;
    if !(axis.length_squared() > 0.0 && axis.is_finite()) {
        return Err(ShapeError::Bad("the end points coincide".to_string()));
    }
    let a = axis.normalize();
    let u = a.any_orthonormal_vector();
    let v = a.cross(u);
    let mut m = ShapeMesh::default();
    let mut circle = |c: DVec3, r: f64| -> Vec<u32> {
        if r == 0.0 {
            return vec![m.vertex(c); SEGMENTS as usize];
        }
        (0..SEGMENTS)
            .map(|s| {
                let phi = std::f64::consts::TAU * f64::from(s) / f64::from(SEGMENTS);
                m.vertex(c + (u * phi.cos() + v * phi.sin()) * r)
            })
            .collect()
    };
    let (c0, c1) = (circle(p0, r0), circle(p1, r1));
    for s in 0..SEGMENTS as usize {
        let t = (s + 1) % SEGMENTS as usize;
        // Around +a, then along it: the front faces away from the axis.
        if r0 > 0.0 {
            m.triangles.push([c0[s], c0[t], c1[t]]);
        }
        if r1 > 0.0 {
            m.triangles.push([c0[s], c1[t], c1[s]]);
        }
    }
    if inward {
        flip(&mut m);
    }
    Ok(m)
}

/// A flat annulus around `center` facing unit `normal`, radii `inner` <
/// `outer` (a disk for `inner` 0): no triangle covers the hole.
pub(super) fn ring(center: DVec3, normal: DVec3, inner: f64, outer: f64) -> ShapeMesh {
    let u = normal.any_orthonormal_vector();
    let v = normal.cross(u);
    let mut m = ShapeMesh::default();
    let dir = |s: u32| {
        let phi = std::f64::consts::TAU * f64::from(s % SEGMENTS) / f64::from(SEGMENTS);
        u * phi.cos() + v * phi.sin()
    };
    let outer_ring: Vec<u32> = (0..SEGMENTS).map(|s| m.vertex(center + dir(s) * outer)).collect();
    let n = SEGMENTS as usize;
    if inner == 0.0 {
        let c = m.vertex(center);
        for s in 0..n {
            m.triangles.push([c, outer_ring[s], outer_ring[(s + 1) % n]]);
        }
        return m;
    }
    let inner_ring: Vec<u32> = (0..SEGMENTS).map(|s| m.vertex(center + dir(s) * inner)).collect();
    for s in 0..n {
        let t = (s + 1) % n;
        m.triangles.push([inner_ring[s], outer_ring[s], outer_ring[t]]);
        m.triangles.push([inner_ring[s], outer_ring[t], inner_ring[t]]);
    }
    m
}

/// The six faces of `genbox`: a box from the origin to `size`, outward (or
/// `inward`), two triangles a face.
pub(super) fn genbox(size: DVec3, inward: bool) -> ShapeMesh {
    let mut m = ShapeMesh::default();
    let corner = |k: usize| {
        DVec3::new(
            size.x * (k & 1) as f64,
            size.y * (k >> 1 & 1) as f64,
            size.z * (k >> 2 & 1) as f64,
        )
    };
    // Corners (bit 0: x, 1: y, 2: z) of each face, counter-clockwise seen
    // from outside.
    let faces = [
        [0, 2, 3, 1],
        [4, 5, 7, 6],
        [0, 1, 5, 4],
        [2, 6, 7, 3],
        [0, 4, 6, 2],
        [1, 3, 7, 5],
    ];
    for face in faces {
        let v = face.map(|k| m.vertex(corner(k)));
        m.triangles.push([v[0], v[1], v[2]]);
        m.triangles.push([v[0], v[2], v[3]]);
    }
    if inward {
        flip(&mut m);
    }
    m
}

/// Turns every triangle of `m` to face the other way.
pub(super) fn flip(m: &mut ShapeMesh) {
    for t in &mut m.triangles {
        t.swap(1, 2);
    }
}
