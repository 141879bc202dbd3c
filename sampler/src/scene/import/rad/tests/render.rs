//! A Radiance scene through the scene file and the path tracer.

use glam::Vec3;

use super::*;

#[test]
fn a_rad_scene_traces_as_its_primitives_say() {
    use crate::geom::Ray;
    use crate::shade::{Rng, TraceOptions, Tracer};

    let dir = tempfile::tempdir().unwrap();
    let text = "\
void plastic grey 0 0 5 .5 .5 .5 0 0
grey sphere ball 0 0 4 0 0 0 1
void light lamp 0 0 3 10 9 8
# clockwise seen from above: the lamp faces down
lamp polygon ceiling 0 0 12 -1 -1 5 -1 1 5 1 1 5 1 -1 5
void light sunlight 0 0 3 1e4 1e4 1e4
sunlight source sun 0 0 4 1 0 1 0.53
";
    write(dir.path(), "scene.rad", text);
    let toml = write(dir.path(), "scene.toml", "[[geometry]]\nfile = \"scene.rad\"\n");
    let scene = crate::scene::load_scene(&toml).unwrap();
    // The .rad file alone is a scene too, the same one.
    let alone = crate::scene::load_scene(&dir.path().join("scene.rad")).unwrap();
    assert_eq!(alone.triangles.len(), scene.triangles.len());
    assert_eq!(alone.sky, scene.sky);
    assert!(alone.sections.is_empty());
    assert!(
        matches!(scene.sky, Sky::Sun { .. }),
        "the file's sun is the scene's sky"
    );
    let tracer = Tracer::new(scene, TraceOptions::default());
    let t = tracer.first_hit(&Ray::new(Vec3::new(-5.0, 0.0, 0.0), Vec3::X)).unwrap();
    // The mesh's vertices lie on the sphere; its faces at most r (1 - cos(π/64)) inside.
    assert!((t - 4.0).abs() < 0.002, "hit at {t}");
    let t = tracer.first_hit(&Ray::new(Vec3::new(0.3, 0.2, 1.5), Vec3::Z));
    assert!(t.is_some_and(|t| (t - 3.5).abs() < 1e-5), "{t:?}");
    let mut rng = Rng::new(1, 0);
    let up = tracer.trace(Vec3::new(0.3, 0.2, 2.0), Vec3::Z, &mut rng);
    assert_eq!(
        up.radiance,
        Vec3::new(10.0, 9.0, 8.0),
        "the lamp's radiance, seen from below"
    );
    assert!((up.distance - 3.0).abs() < 1e-5);
    let down = tracer.trace(Vec3::new(0.3, 0.2, 9.0), -Vec3::Z, &mut rng);
    assert_eq!(down.radiance, Vec3::ZERO, "its back is dark");
}
