//! `!xform` and `!genbox` lines, refused commands and include cycles.

use glam::Vec3;

use super::*;

#[test]
fn xform_applies_its_options_left_to_right_to_an_included_file() {
    let dir = tempfile::tempdir().unwrap();
    write(
        dir.path(),
        "inner.rad",
        "void plastic m 0 0 5 .5 .5 .5 0 0\nm polygon t 0 0 9 1 0 0 0 1 0 0 0 1\n",
    );
    let (s, _) = read(dir.path(), "outer.rad", "!xform -t 1 0 0 -rz 90 -s 2 inner.rad\n").unwrap();
    assert_eq!(s.triangles.len(), 1);
    let v = s.vertices(0);
    // (1,0,0) -t-> (2,0,0) -rz-> (0,2,0) -s-> (0,4,0), and so on.
    let expected = [
        Vec3::new(0.0, 4.0, 0.0),
        Vec3::new(-2.0, 2.0, 0.0),
        Vec3::new(0.0, 2.0, 2.0),
    ];
    for (got, want) in v.iter().zip(expected) {
        assert!(got.abs_diff_eq(want, 1e-5), "{v:?}");
    }

    // A mirror keeps faces facing the way they did: the normal is mirrored.
    let (s, _) = read(dir.path(), "mirrored.rad", "!xform -mx inner.rad\n").unwrap();
    let n = normal(&s.vertices(0)).normalize();
    assert!(n.abs_diff_eq(Vec3::new(-1.0, 1.0, 1.0).normalize(), 1e-6), "{n}");
    // -I turns surfaces inside out; -m gives them another modifier.
    let text = "void mirror other 0 0 3 1 1 1\n!xform -I -m other inner.rad\n";
    let (s, _) = read(dir.path(), "inverted.rad", text).unwrap();
    let n = normal(&s.vertices(0)).normalize();
    assert!(n.abs_diff_eq(-Vec3::ONE.normalize(), 1e-6), "{n}");
    assert_eq!(s.material_names[s.triangles[0].material as usize], "other");
    // -i repeats the transforms after it; later pipes transform again.
    let text = "!xform -s 2 -i 3 -t 1 0 0 inner.rad | xform -t 0 0 5\n";
    let (s, _) = read(dir.path(), "repeat.rad", text).unwrap();
    assert!(
        s.vertices(0)[0].abs_diff_eq(Vec3::new(5.0, 0.0, 5.0), 1e-6),
        "{:?}",
        s.vertices(0)
    );
}

#[test]
fn genbox_makes_a_closed_box_facing_out() {
    let dir = tempfile::tempdir().unwrap();
    let text = "void plastic m 0 0 5 .5 .5 .5 0 0\n!genbox m box 1 2 3\n";
    let (s, _) = read(dir.path(), "box.rad", text).unwrap();
    let ts = triangles(&s, "m");
    assert_eq!(ts.len(), 12);
    assert!((area(&ts) - 2.0 * (2.0 + 6.0 + 3.0)).abs() < 1e-5, "{}", area(&ts));
    let middle = Vec3::new(0.5, 1.0, 1.5);
    assert!(ts.iter().all(|t| normal(t).dot(centroid(t) - middle) > 0.0));
    let (lo, hi) = s.bounds();
    assert_eq!((lo, hi), (Vec3::ZERO, Vec3::new(1.0, 2.0, 3.0)));

    let text = "void plastic m 0 0 5 .5 .5 .5 0 0\n!genbox m box 1 2 3 -i | xform -t 5 0 0\n";
    let (s, _) = read(dir.path(), "room.rad", text).unwrap();
    let ts = triangles(&s, "m");
    let middle = Vec3::new(5.5, 1.0, 1.5);
    assert!(
        ts.iter().all(|t| normal(t).dot(centroid(t) - middle) < 0.0),
        "-i faces in"
    );
}

#[test]
fn other_commands_and_include_cycles_are_refused_naming_the_line() {
    let dir = tempfile::tempdir().unwrap();
    let e = rad_error(dir.path(), "sky.rad", "# daylight\n!gensky 3 21 12 -a 42\n");
    assert_eq!(e.at.line, 2);
    assert!(matches!(&*e.kind, RadErrorKind::UnsupportedCommand { command } if command == "gensky"));
    assert!(
        e.to_string().contains("sky.rad:2:") && e.to_string().contains("gensky"),
        "{e}"
    );
    let e = rad_error(
        dir.path(),
        "piped.rad",
        "!xform -t 1 0 0 inner.rad | genrev m r 'x' 't' 8\n",
    );
    assert!(matches!(&*e.kind, RadErrorKind::UnsupportedCommand { command } if command == "genrev"));
    let e = rad_error(dir.path(), "array.rad", "!xform -a 3 -t 1 0 0 inner.rad\n");
    assert!(matches!(&*e.kind, RadErrorKind::BadCommand { message, .. } if message.contains("-a")));
    let e = rad_error(dir.path(), "stdin.rad", "!xform -t 1 0 0\n");
    assert!(matches!(&*e.kind, RadErrorKind::BadCommand { message, .. } if message.contains("standard input")));

    write(dir.path(), "a.rad", "!xform -t 1 0 0 b.rad\n");
    write(dir.path(), "b.rad", "\n\n!xform a.rad\n");
    let e = rad_error(dir.path(), "a.rad", "!xform -t 1 0 0 b.rad\n");
    assert!(matches!(*e.kind, RadErrorKind::IncludeCycle { .. }), "{e}");
    assert!(e.at.path.ends_with("b.rad") && e.at.line == 3, "{e}");
    let e = rad_error(dir.path(), "self.rad", "!xform self.rad\n");
    assert!(matches!(*e.kind, RadErrorKind::IncludeCycle { .. }), "{e}");
    let e = rad_error(dir.path(), "missing.rad", "\n!xform nowhere.rad\n");
    assert!(matches!(*e.kind, RadErrorKind::Include { .. }) && e.at.line == 2, "{e}");
    assert!(e.to_string().contains("nowhere.rad"), "{e}");
    let e = rad_error(dir.path(), "dir.rad", "!xform .\n");
    assert!(matches!(*e.kind, RadErrorKind::IncludeRefused { .. }), "{e}");
    // The same file twice is no cycle.
    write(
        dir.path(),
        "leaf.rad",
        "void plastic m 0 0 5 .5 .5 .5 0 0\nm polygon t 0 0 9 1 0 0 0 1 0 0 0 1\n",
    );
    let (s, _) = read(dir.path(), "twice.rad", "!xform leaf.rad\n!xform -t 0 0 1 leaf.rad\n").unwrap();
    assert_eq!(s.triangles.len(), 2);
}
