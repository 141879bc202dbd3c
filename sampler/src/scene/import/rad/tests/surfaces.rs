//! Surfaces: areas, orientation, holes and polygon triangulation.

use std::f64::consts::PI;

use glam::Vec3;

use super::*;

#[test]
fn every_surface_has_the_area_and_orientation_of_its_radiance_primitive() {
    let dir = tempfile::tempdir().unwrap();
    let (s, _) = read(dir.path(), "everything.rad", EVERYTHING).unwrap();

    let ball = triangles(&s, "m_sphere");
    let r = 2.0;
    assert!(
        close(area(&ball), 4.0 * PI * r * r, 0.01),
        "sphere area {}",
        area(&ball)
    );
    let c = Vec3::new(1.0, 2.0, 3.0);
    assert!(
        ball.iter().all(|t| normal(t).dot(centroid(t) - c) > 0.0),
        "sphere faces out"
    );

    let dome = triangles(&s, "m_bubble");
    let c = Vec3::new(10.0, 0.0, 0.0);
    assert!(close(area(&dome), 4.0 * PI * 1.5 * 1.5, 0.01));
    assert!(
        dome.iter().all(|t| normal(t).dot(centroid(t) - c) < 0.0),
        "bubble faces in"
    );

    // Cone: lateral area π (r0 + r1) · slant, normals away from the axis.
    let horn = triangles(&s, "m_cone");
    let slant = (2.0f64 * 2.0 + 0.5 * 0.5).sqrt();
    assert!(close(area(&horn), PI * 1.5 * slant, 0.01), "cone area {}", area(&horn));
    let out = |t: &[Vec3; 3], axis_at: Vec3| {
        let p = centroid(t);
        normal(t).dot(Vec3::new(p.x, p.y, 0.0) - Vec3::new(axis_at.x, axis_at.y, 0.0))
    };
    assert!(horn.iter().all(|t| out(t, Vec3::ZERO) > 0.0), "cone faces out");
    let funnel = triangles(&s, "m_cup");
    let slant = (1.0f64 + 0.25).sqrt();
    assert!(
        close(area(&funnel), PI * 0.5 * slant, 0.01),
        "cup area {}",
        area(&funnel)
    );
    assert!(
        funnel.iter().all(|t| out(t, Vec3::new(5.0, 5.0, 0.0)) < 0.0),
        "cup faces in"
    );

    let pipe = triangles(&s, "m_cylinder");
    assert!(
        close(area(&pipe), 2.0 * PI * 0.5 * 3.0, 0.01),
        "cylinder area {}",
        area(&pipe)
    );
    assert!(
        pipe.iter().all(|t| out(t, Vec3::new(0.0, 10.0, 0.0)) > 0.0),
        "cylinder faces out"
    );
    let sleeve = triangles(&s, "m_tube");
    assert!(close(area(&sleeve), 2.0 * PI * 0.25 * 3.0, 0.01));
    let from_x_axis = |t: &[Vec3; 3]| {
        let p = centroid(t);
        normal(t).dot(Vec3::new(0.0, p.y - 20.0, p.z))
    };
    assert!(sleeve.iter().all(|t| from_x_axis(t) < 0.0), "tube faces in");

    // Ring: an annulus facing +z, nothing over its centre.
    let washer = triangles(&s, "m_ring");
    assert!(
        close(area(&washer), PI * (4.0 - 1.0), 0.01),
        "ring area {}",
        area(&washer)
    );
    assert!(washer.iter().all(|t| normal(t).z > 0.0 && normal(t).x.abs() < 1e-4));
    let centre = Vec3::new(0.0, 0.0, -5.0);
    let covers = |t: &[Vec3; 3], p: Vec3| {
        let n = normal(t);
        (0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(p - t[k]).dot(n) >= 0.0)
    };
    assert!(!washer.iter().any(|t| covers(t, centre)), "the ring has a hole");
    assert!(washer
        .iter()
        .all(|t| t.iter().all(|v| (v.distance(centre) - 1.5).abs() >= 0.49)));
    // Radii given outer first, normal down: a disk facing -z.
    let plate = triangles(&s, "m_disk");
    assert!(close(area(&plate), PI * 1.5 * 1.5, 0.01));
    assert!(plate.iter().all(|t| normal(t).z < 0.0));

    // The light: its normal follows the vertex order, its radiance is kept.
    let ceiling = triangles(&s, "lamp");
    assert_eq!(ceiling.len(), 2);
    assert!(ceiling.iter().all(|t| normal(t).normalize().abs_diff_eq(Vec3::Z, 1e-6)));
    assert!((area(&ceiling) - 4.0).abs() < 1e-6);
    assert_eq!(
        material(&s, "lamp"),
        &Material::Emitter {
            radiance: [10.0, 9.0, 8.0]
        }
    );
}

#[test]
fn concave_polygons_and_seamed_holes_are_ear_clipped() {
    let dir = tempfile::tempdir().unwrap();
    let text = "\
void plastic l 0 0 5 .5 .5 .5 0 0
void plastic holed 0 0 5 .5 .5 .5 0 0
# an L, counter-clockwise seen from above
l polygon ell 0 0 18 0 0 0 2 0 0 2 1 0 1 1 0 1 2 0 0 2 0
# a 4 x 4 square with a 2 x 2 hole, joined by a seam from (0,0) to (1,1)
holed polygon frame 0 0 30
    0 0 5  4 0 5  4 4 5  0 4 5  0 0 5
    1 1 5  1 3 5  3 3 5  3 1 5  1 1 5
";
    let (s, report) = read(dir.path(), "concave.rad", text).unwrap();
    let ell = triangles(&s, "l");
    assert_eq!(ell.len(), 4);
    assert!((area(&ell) - 3.0).abs() < 1e-6, "L area {}", area(&ell));
    assert!(ell.iter().all(|t| normal(t).z > 0.0));
    let frame = triangles(&s, "holed");
    assert!((area(&frame) - 12.0).abs() < 1e-5, "frame area {}", area(&frame));
    assert!(frame.iter().all(|t| normal(t).z >= 0.0));
    let hole = Vec3::new(2.0, 2.0, 5.0);
    assert!(frame.iter().all(|t| {
        let n = normal(t);
        !(0..3).all(|k| (t[(k + 1) % 3] - t[k]).cross(hole - t[k]).dot(n) > 0.0)
    }));
    assert_eq!(report.count(NoteKind::Fanned), 0, "{report:?}");
}

#[test]
fn ear_clipping_stops_when_its_budget_is_spent() {
    // An L: concave, so it is ear-clipped while budget lasts, then fanned.
    let l = [[0, 0], [2, 0], [2, 1], [1, 1], [1, 2], [0, 2]].map(|[x, y]| glam::DVec3::new(x as f64, y as f64, 0.0));
    let mut budget = shapes::EAR_CLIP_BUDGET;
    let clipped = shapes::polygon(l.to_vec(), &mut budget);
    assert_eq!((clipped.note, clipped.mesh.triangles.len()), (None, 4));
    assert!(budget < shapes::EAR_CLIP_BUDGET);
    let mut spent = 0;
    let fanned = shapes::polygon(l.to_vec(), &mut spent);
    assert_eq!(
        (fanned.note, fanned.mesh.triangles.len()),
        (Some(shapes::ShapeNote::Fanned), 4)
    );
}
