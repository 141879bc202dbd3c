//! Whether holodeck sections fit their scene, and sections that do.
//!
//! An interior section is where the eye moves: geometry inside it is seen
//! from both sides at once and draws as black wedges, so every triangle that
//! reaches into it is reported. An exterior section holds the geometry and
//! the eye stays outside: triangles that cross its walls are reported.
//! [`free_box`] proposes the largest axis-aligned interior section around an
//! eye that no triangle enters; [`around`] the exterior section around all
//! the geometry.

use glam::{DMat3, DVec3};
use holodeck_protocol::{Section, SectionKind};

use super::Scene;

/// Triangles a section cuts, and where.
#[derive(Clone, Debug, PartialEq)]
pub struct Cut {
    /// How many triangles enter an interior section, or cross an exterior one's walls.
    pub triangles: u64,
    /// The bounds of those triangles (low, high corners).
    pub bounds: (DVec3, DVec3),
}

/// Whether triangle (a, b, c) meets the box [lo, hi] (closed), by the
/// separating axis test (Akenine-Möller 2001).
pub fn triangle_meets_box(lo: DVec3, hi: DVec3, [a, b, c]: [DVec3; 3]) -> bool {
    let center = (lo + hi) * 0.5;
    let half = (hi - lo) * 0.5;
    let (v0, v1, v2) = (a - center, b - center, c - center);
    // The box's faces.
    let (tlo, thi) = (v0.min(v1).min(v2), v0.max(v1).max(v2));
    if (0..3).any(|k| tlo[k] > half[k] || thi[k] < -half[k]) {
        return false;
    }
    let (e0, e1, e2) = (v1 - v0, v2 - v1, v0 - v2);
    // The triangle's plane.
    let n = e0.cross(e1);
    let r = half.x * n.x.abs() + half.y * n.y.abs() + half.z * n.z.abs();
    if n.dot(v0).abs() > r {
        return false;
    }
    // The nine cross products of edges and box axes.
    for e in [e0, e1, e2] {
        for axis in [DVec3::X, DVec3::Y, DVec3::Z] {
            let l = axis.cross(e);
            if l == DVec3::ZERO {
                continue;
            }
            let (p0, p1, p2) = (l.dot(v0), l.dot(v1), l.dot(v2));
            let r = half.x * l.x.abs() + half.y * l.y.abs() + half.z * l.z.abs();
            if p0.min(p1).min(p2) > r || p0.max(p1).max(p2) < -r {
                return false;
            }
        }
    }
    true
}

/// The triangles `section` cuts in `scene`; `None` where it cuts none.
/// Triangles that only touch its walls (a section on a wall) do not count.
pub fn cut(scene: &Scene, section: &Section) -> Option<Cut> {
    let axes = section.axes();
    let m = DMat3::from_cols(axes[0], axes[1], axes[2]);
    if m.determinant().abs() < 1e-300 {
        return None;
    }
    let inv = m.inverse();
    let origin = section.origin();
    // In the section's own frame it is the unit cube; shrunk a hair so
    // that touching is not cutting.
    let eps = 1e-6;
    let (lo, hi) = (DVec3::splat(eps), DVec3::splat(1.0 - eps));
    let mut count = 0u64;
    let (mut blo, mut bhi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
    for t in 0..scene.triangles.len() {
        let world = scene.vertices(t).map(|v| v.as_dvec3());
        let local = world.map(|v| inv * (v - origin));
        let meets = triangle_meets_box(lo, hi, local);
        let counts = match section.kind() {
            SectionKind::Interior => meets,
            SectionKind::Exterior => {
                let inside = local.iter().all(|v| v.cmpge(lo).all() && v.cmple(hi).all());
                meets && !inside
            }
        };
        if counts {
            count += 1;
            for v in world {
                blo = blo.min(v);
                bhi = bhi.max(v);
            }
        }
    }
    (count > 0).then_some(Cut {
        triangles: count,
        bounds: (blo, bhi),
    })
}

/// The largest axis-aligned box around `eye` that no triangle of `scene`
/// enters, kept `margin` from the geometry and within `limit` of the eye
/// along each axis (low, high corners); `None` where a triangle passes
/// within `margin` of the eye itself. Each of the six faces in turn moves
/// out as far as it can (by bisection), for a few rounds.
pub fn free_box(scene: &Scene, eye: DVec3, margin: f64, limit: f64) -> Option<(DVec3, DVec3)> {
    let tris: Vec<[DVec3; 3]> = (0..scene.triangles.len())
        .map(|t| scene.vertices(t).map(|v| v.as_dvec3()))
        .filter(|t| {
            let (lo, hi) = (t[0].min(t[1]).min(t[2]), t[0].max(t[1]).max(t[2]));
            (lo - eye).max_element() <= limit + margin && (eye - hi).max_element() <= limit + margin
        })
        .collect();
    let free = |lo: DVec3, hi: DVec3| {
        let (lo, hi) = (lo - DVec3::splat(margin), hi + DVec3::splat(margin));
        !tris.iter().any(|t| triangle_meets_box(lo, hi, *t))
    };
    if !free(eye, eye) {
        return None;
    }
    let (mut lo, mut hi) = (eye, eye);
    for _ in 0..4 {
        for face in 0..6 {
            let (axis, up) = (face / 2, face % 2 == 1);
            let bound = if up { eye[axis] + limit } else { eye[axis] - limit };
            let (mut ok, mut bad) = (if up { hi[axis] } else { lo[axis] }, bound);
            let with = |v: f64| {
                let (mut l, mut h) = (lo, hi);
                if up {
                    h[axis] = v;
                } else {
                    l[axis] = v;
                }
                (l, h)
            };
            let (l, h) = with(bound);
            if free(l, h) {
                ok = bound;
            } else {
                for _ in 0..30 {
                    let mid = 0.5 * (ok + bad);
                    let (l, h) = with(mid);
                    if free(l, h) {
                        ok = mid;
                    } else {
                        bad = mid;
                    }
                }
            }
            if up {
                hi[axis] = ok;
            } else {
                lo[axis] = ok;
            }
        }
    }
    Some((lo, hi))
}

/// The box around all of `scene`'s geometry, padded by `margin` on every
/// side (an exterior section's), or `None` for an empty scene.
pub fn around(scene: &Scene, margin: f64) -> Option<(DVec3, DVec3)> {
    if scene.triangles.is_empty() {
        return None;
    }
    let (lo, hi) = scene.bounds();
    Some((
        lo.as_dvec3() - DVec3::splat(margin),
        hi.as_dvec3() + DVec3::splat(margin),
    ))
}

#[cfg(test)]
mod tests {
    use glam::{Mat4, Vec3};

    use super::*;
    use crate::scene::section::box_section;
    use crate::scene::{Material, SceneBuilder};

    fn scene() -> Scene {
        // A floor 0..10 x 0..10 and a 1 m cube standing on it at (4..5, 4..5).
        let mut b = SceneBuilder::new();
        let m = b.material("m", Material::lambertian([0.5; 3])).unwrap();
        let floor = [
            Vec3::ZERO,
            Vec3::new(10.0, 0.0, 0.0),
            Vec3::new(10.0, 10.0, 0.0),
            Vec3::new(0.0, 10.0, 0.0),
        ];
        b.add_mesh("floor", &floor, &[[0, 1, 2], [0, 2, 3]], &[m], Mat4::IDENTITY)
            .unwrap();
        let mut cube = super::super::gen::shapes::MeshBuf::new();
        cube.cuboid(Vec3::new(4.0, 4.0, 0.0), Vec3::new(5.0, 5.0, 1.0), m);
        cube.flush(&mut b, "cube").unwrap();
        b.finish()
    }

    #[test]
    fn the_box_test_agrees_with_hand_placed_triangles() {
        let (lo, hi) = (DVec3::ZERO, DVec3::ONE);
        let t = |a: [f64; 3], b: [f64; 3], c: [f64; 3]| [DVec3::from(a), DVec3::from(b), DVec3::from(c)];
        assert!(triangle_meets_box(
            lo,
            hi,
            t([0.5, 0.5, 0.5], [3.0, 0.5, 0.5], [0.5, 3.0, 0.5])
        ));
        // Its bounding box overlaps the cube, the triangle does not (beyond the corner diagonal).
        assert!(!triangle_meets_box(
            lo,
            hi,
            t([1.5, 0.0, 0.5], [0.0, 1.5, 0.5], [2.0, 2.0, 0.5]).map(|v| v + DVec3::new(0.6, 0.6, 0.0))
        ));
        // A large triangle slicing through the middle with no vertex inside.
        assert!(triangle_meets_box(
            lo,
            hi,
            t([-5.0, -5.0, 0.5], [10.0, -5.0, 0.5], [-5.0, 10.0, 0.5])
        ));
        // A plane tilted away from the cube.
        assert!(!triangle_meets_box(
            lo,
            hi,
            t([2.0, 0.0, 0.0], [0.0, 2.0, 0.0], [0.0, 0.0, 2.0]).map(|v| v + DVec3::splat(1.0))
        ));
    }

    #[test]
    fn sections_that_cut_geometry_are_found_and_free_boxes_fit() {
        let s = scene();
        let clear = box_section(SectionKind::Interior, [1.0, 1.0, 0.5], [2.0, 2.0, 1.0]).unwrap();
        assert_eq!(cut(&s, &clear), None);
        let through = box_section(SectionKind::Interior, [3.5, 3.5, 0.5], [2.0, 2.0, 1.0]).unwrap();
        let c = cut(&s, &through).unwrap();
        assert_eq!(c.triangles, 10, "the cube's four sides and its top: {c:?}");
        assert_eq!((c.bounds.0.x, c.bounds.1.x), (4.0, 5.0));
        // On the floor exactly: touching is not cutting.
        let on_floor = box_section(SectionKind::Interior, [1.0, 1.0, 0.0], [2.0, 2.0, 1.0]).unwrap();
        assert_eq!(cut(&s, &on_floor), None);
        let ext = box_section(SectionKind::Exterior, [3.9, 3.9, 0.5], [1.2, 1.2, 1.0]).unwrap();
        assert_eq!(cut(&s, &ext).unwrap().triangles, 8, "the cube's sides cross its bottom");

        let (lo, hi) = free_box(&s, DVec3::new(2.0, 2.0, 1.0), 0.1, 50.0).unwrap();
        assert!((lo.z - 0.1).abs() < 1e-6, "kept 0.1 above the floor: {lo}");
        let free = box_section(SectionKind::Interior, lo.to_array(), (hi - lo).to_array()).unwrap();
        assert_eq!(cut(&s, &free), None, "{lo} {hi}");
        assert!(hi.x >= 3.9 - 1e-6 || hi.y >= 3.9 - 1e-6, "grows up to the cube: {hi}");
        assert!((hi - lo).x > 1.0 && (hi - lo).y > 1.0);
        assert_eq!(
            free_box(&s, DVec3::new(2.0, 2.0, 0.05), 0.1, 50.0),
            None,
            "within the margin of the floor"
        );
        let (alo, ahi) = around(&s, 0.5).unwrap();
        assert_eq!((alo.x, ahi.z), (-0.5, 1.5));
    }
}
