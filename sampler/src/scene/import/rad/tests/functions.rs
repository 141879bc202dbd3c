//! Function and data patterns rendered: a `colorfunc` checkerboard shows
//! its squares where its function file puts them, moved with the file an
//! `!xform` places; a `brightfunc` dims; a `texfunc` bends the normal as
//! far as its expressions say; an IES-style `brightdata` light lights a
//! floor with the intensity its data file gives at each angle; and files
//! that cannot be used are noted, the scene still loading.

use glam::Vec3;

use super::*;
use crate::scene::material::Sky;
use crate::shade::{Rng, TraceOptions, Tracer};

/// The mean radiance of `n` paths from `origin` along `dir`.
fn radiance(t: &Tracer, origin: Vec3, dir: Vec3, n: u64) -> Vec3 {
    (0..n)
        .map(|i| t.trace(origin, dir.normalize(), &mut Rng::new(5, i)).radiance)
        .sum::<Vec3>()
        / n as f32
}

/// Reads `root` (in `dir`) under a white sky of radiance 1.
fn under_white_sky(root: &Path) -> (Tracer, RadReport) {
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, root, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
    (Tracer::new(b.finish(), TraceOptions::default()), report)
}

/// A checkerboard of 0.9 and 0.1 squares half a unit wide (the function
/// file's unit squares scaled by `-s 0.5`), on a 4 x 4 floor at z = 0.
const CHECKERED_FLOOR: &str = "\
void colorfunc checker
6 shade shade shade check.cal -s .5
0
2 .9 .1
checker plastic paint
0
0
5 1 1 1 0 0
paint polygon floor
0
0
12 0 0 0  4 0 0  4 4 0  0 4 0
";

/// The function file: `A1` where floor(x) + floor(y) is even, else `A2`.
const CHECK_CAL: &str = "
{ squares of a unit { as in any checker } }
even(n) = if(.5 - abs(mod(n, 2)), 1, 0);
shade = if(even(floor(Px) + floor(Py)) - .5, A1, A2);
";

/// The shade the checkerboard has at (x, y) of its own frame, worked out here.
fn square(x: f32, y: f32) -> f32 {
    let n = (x / 0.5).floor() as i64 + (y / 0.5).floor() as i64;
    if n.rem_euclid(2) == 0 {
        0.9
    } else {
        0.1
    }
}

#[test]
fn a_colorfunc_paints_what_its_function_file_computes_and_moves_with_its_file() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "check.cal", CHECK_CAL);
    let floor = write(dir.path(), "floor.rad", CHECKERED_FLOOR);
    let moved = write(dir.path(), "moved.rad", "!xform -rz 90 -t 10 0 0 floor.rad\n");
    for (root, place) in [
        (&floor, (|p: Vec3| p) as fn(Vec3) -> Vec3),
        (&moved, |p: Vec3| Vec3::new(10.0 - p.y, p.x, p.z)),
    ] {
        let (t, report) = under_white_sky(root);
        assert_eq!(report.count(NoteKind::PatternIgnored), 0, "{report:?}");
        for (x, y) in [(0.25f32, 0.25f32), (0.75, 0.25), (1.3, 2.2), (3.9, 3.4), (2.6, 0.1)] {
            let at = place(Vec3::new(x, y, 1.0));
            let seen = radiance(&t, at, -Vec3::Z, 1);
            let want = square(x, y);
            assert!(
                (seen - Vec3::splat(want)).abs().max_element() < 1e-3,
                "{} at ({x}, {y}): {seen} against {want}",
                root.display()
            );
        }
    }
}

#[test]
fn a_brightfunc_without_a_file_scales_and_a_texfunc_bends_the_normal() {
    let dir = tempfile::tempdir().unwrap();
    // A sun 30 degrees from the zenith toward +x lights two floors; the
    // second's normal is bent 30 degrees toward it by a texfunc of no file,
    // the first's colour halved by a brightfunc of no file.
    let text = "\
void light solar
0
0
3 1e5 1e5 1e5
solar source sun
0
0
4 .5 0 .8660254 .5
void brightfunc half
2 A1 .
0
1 .5
half plastic dim
0
0
5 .6 .6 .6 0 0
void texfunc tilt
4 .57735027 0 0 .
0
0
tilt plastic bent
0
0
5 .6 .6 .6 0 0
void plastic flat
0
0
5 .6 .6 .6 0 0
dim polygon a
0
0
12 0 0 0  1 0 0  1 1 0  0 1 0
bent polygon b
0
0
12 2 0 0  3 0 0  3 1 0  2 1 0
flat polygon c
0
0
12 4 0 0  5 0 0  5 1 0  4 1 0
";
    let path = write(dir.path(), "sun.rad", text);
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    assert_eq!(report.count(NoteKind::PatternIgnored), 0, "{report:?}");
    let t = Tracer::new(b.finish(), TraceOptions::default());
    let look = |x: f32| radiance(&t, Vec3::new(x, 0.5, 1.0), -Vec3::Z, 64).x;
    let (dim, bent, flat) = (look(0.5), look(2.5), look(4.5));
    assert!(flat > 0.0);
    assert!((dim / flat - 0.5).abs() < 0.01, "halved: {dim} against {flat}");
    let want = 1.0 / 30f32.to_radians().cos();
    assert!(
        (bent / flat - want).abs() < 0.01,
        "bent toward the sun: {} against {want}",
        bent / flat
    );
}

#[test]
fn an_ies_light_lights_the_floor_with_the_intensity_its_data_gives() {
    let dir = tempfile::tempdir().unwrap();
    // As ies2rad writes a 10 cm square luminaire: intensity over the angle
    // from the nadir, 10 straight down falling to 0 at 90 degrees.
    write(dir.path(), "lamp.dat", "1\n0 90 4\n10 8 4 0\n");
    let text = "\
void brightdata lamp_dist
4 flatcorr lamp.dat source.cal src_theta
0
1 100
lamp_dist light lamp_light
0
0
3 1 1 1
lamp_light polygon lamp.d
0
0
12 -.05 -.05 2  -.05 .05 2  .05 .05 2  .05 -.05 2
void plastic grey
0
0
5 .5 .5 .5 0 0
grey polygon floor
0
0
12 -20 -20 0  20 -20 0  20 20 0  -20 20 0
";
    let path = write(dir.path(), "ies.rad", text);
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    assert_eq!(report.count(NoteKind::PatternIgnored), 0, "{report:?}");
    let scene = b.finish();
    // The same scene as a scene file, traced out of core: the light keeps its pattern.
    let hds = dir.path().join("ies.hds");
    let source = crate::ooc::build::SceneSource::new(scene.clone());
    crate::ooc::build_scene_file(&source, &hds, &Default::default(), &|_, _, _| {}).unwrap();
    let file = std::sync::Arc::new(crate::ooc::OocScene::open(&hds, None, 1).unwrap());
    assert_eq!(file.shell().maps, scene.maps, "the patterns survive the file");
    let from_file = Tracer::out_of_core(file, TraceOptions::default());
    let t = Tracer::new(scene, TraceOptions::default());
    let below = |t: &Tracer| radiance(t, Vec3::new(0.0, 0.0, 0.5), -Vec3::Z, 20_000).x;
    let (core, out_of_core) = (below(&t), below(&from_file));
    assert!((out_of_core - core).abs() < 0.03 * core, "{out_of_core} against {core}");
    // Floor radiance 0.5 E / pi, E = I(theta) cos(theta) / r^2 from the lamp 2 above.
    for (x, intensity) in [
        (0.0f32, 10.0f32),
        (2.0, 6.0),
        (2.0 * 3f32.sqrt(), 4.0),
        (3.0, 8.0 - 4.0 * (1.5f32.atan().to_degrees() - 30.0) / 30.0),
    ] {
        let r2 = 4.0 + x * x;
        let cos = 2.0 / r2.sqrt();
        let want = 0.5 * intensity * cos / r2 / std::f32::consts::PI;
        let seen = radiance(&t, Vec3::new(x, 0.0, 0.5), -Vec3::Z, 20_000).x;
        assert!(
            (seen - want).abs() < 0.03 * want,
            "floor at x {x}: {seen} against {want}"
        );
    }
}

#[test]
fn unusable_function_files_are_noted_with_why_and_the_scene_still_loads() {
    let dir = tempfile::tempdir().unwrap();
    write(dir.path(), "broken.cal", "good = 1;\nbad = (2 + ;\n");
    write(dir.path(), "names.cal", "r = nowhere * 2;\n");
    for (pattern, why) in [
        ("colorfunc p\n4 good good good broken.cal", "broken.cal, line 2"),
        ("colorfunc p\n4 r r r names.cal", "\"nowhere\" is not defined"),
        ("brightfunc p\n2 x absent.cal", "absent.cal is not in"),
        ("brightdata p\n4 noop absent.dat . Px", "absent.dat is not in"),
        ("colorfunc p\n3 r r r", "needs 4 or more strings"),
    ] {
        let text = format!(
            "void {pattern}\n0\n0\np plastic m\n0\n0\n5 .5 .5 .5 0 0\nm polygon a\n0\n0\n9 0 0 0 1 0 0 0 1 0\n"
        );
        let (scene, report) = read(dir.path(), "bad.rad", &text).unwrap();
        assert_eq!(report.count(NoteKind::PatternIgnored), 1, "{report:?}");
        assert_eq!(scene.triangles.len(), 1);
        assert_eq!(
            scene.materials[0],
            Material::lambertian([0.5; 3]),
            "the base colour is kept"
        );
        let note = &report.notes[0].detail;
        assert!(note.contains(why), "{why:?} in {note}");
    }
}
