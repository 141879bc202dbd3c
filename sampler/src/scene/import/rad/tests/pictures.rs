//! `colorpict` with `picture.cal`: the picture lies on the pattern's xy
//! plane, lower left at the origin, scaled by the pattern's transform.

use glam::Vec3;

use super::*;
use crate::scene::material::Sky;
use crate::shade::{Rng, TraceOptions, Tracer};

/// A 4 x 4 linear picture: texel (x, y), row 0 at the top, is (0.1 + 0.2x, 0.1 + 0.2y, 0.5).
fn palette(dir: &Path) {
    let img = image::Rgb32FImage::from_fn(4, 4, |x, y| {
        image::Rgb([0.1 + 0.2 * x as f32, 0.1 + 0.2 * y as f32, 0.5])
    });
    image::DynamicImage::ImageRgb32F(img).save(dir.join("pal.hdr")).unwrap();
}

/// The scene read from `root` (in `dir`), seen from 1 above each of four
/// texel centres of the palette mapped by `-s 2` onto the square [0, 2]²
/// and placed by `placed`: every texel's colour.
fn shows_the_palette(dir: &Path, root: &Path, placed: impl Fn(Vec3) -> Vec3) {
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, root, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    assert_eq!(report.count(NoteKind::PatternIgnored), 0, "{report:?}");
    b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
    let scene = b.finish();
    assert_eq!(scene.textures.len(), 1, "{}", dir.display());
    let t = Tracer::new(scene, TraceOptions::default());
    for (x, y) in [(0u32, 0u32), (3, 0), (1, 2), (3, 3)] {
        // Texel (x, y) centre: picture coordinates ((x + .5) / 4, 1 - (y + .5) / 4), times 2.
        let at = placed(Vec3::new(
            2.0 * (x as f32 + 0.5) / 4.0,
            2.0 * (1.0 - (y as f32 + 0.5) / 4.0),
            1.0,
        ));
        let mut rng = Rng::new(1, 0);
        let seen = t.trace(at, -Vec3::Z, &mut rng).radiance;
        let want = Vec3::new(0.1 + 0.2 * x as f32, 0.1 + 0.2 * y as f32, 0.5);
        assert!(
            (seen - want).abs().max_element() < 0.01,
            "texel ({x}, {y}) at {at}: {seen} vs {want}"
        );
    }
}

/// A floor 2 wide pictured by the palette at twice its size.
const PICTURED_FLOOR: &str = "\
void colorpict checker
9 red green blue pal.hdr picture.cal pic_u pic_v -s 2
0
0
checker plastic paint
0
0
5 1 1 1 0 0
paint polygon floor
0
0
12 0 0 0  2 0 0  2 2 0  0 2 0
";

#[test]
fn a_colorpict_shows_its_picture_where_picture_cal_puts_it() {
    let dir = tempfile::tempdir().unwrap();
    palette(dir.path());
    let path = write(dir.path(), "pict.rad", PICTURED_FLOOR);
    shows_the_palette(dir.path(), &path, |p| p);
}

#[test]
fn a_colorpict_in_a_moved_file_moves_with_it() {
    let dir = tempfile::tempdir().unwrap();
    palette(dir.path());
    write(dir.path(), "pict.rad", PICTURED_FLOOR);
    // Turned a quarter about z and moved: the picture turns and moves with its floor.
    let root = write(dir.path(), "main.rad", "!xform -rz 90 -t 5 -3 0 pict.rad\n");
    shows_the_palette(dir.path(), &root, |p| Vec3::new(5.0 - p.y, -3.0 + p.x, p.z));
}

#[test]
fn other_patterns_stay_ignored_and_a_missing_picture_is_noted() {
    let dir = tempfile::tempdir().unwrap();
    let text = "\
void colorpict gone
7 red green blue missing.hdr picture.cal pic_u pic_v
0
0
gone plastic paint
0
0
5 .5 .5 .5 0 0
void colorfunc swirl
4 red green blue swirl.cal
0
0
swirl plastic other
0
0
5 .5 .5 .5 0 0
paint polygon a
0
0
9 0 0 0 1 0 0 0 1 0
other polygon b
0
0
9 0 0 1 1 0 1 0 1 1
";
    let path = write(dir.path(), "gone.rad", text);
    let mut b = SceneBuilder::new();
    let report = read_rad(&mut b, &path, Mat4::IDENTITY, &ImportOptions::default()).unwrap();
    assert_eq!(report.count(NoteKind::PatternIgnored), 1, "the colorfunc");
    let scene = b.finish();
    assert!(scene.textures.is_empty());
    assert!(
        scene.notes.iter().any(|n| n.what.contains("missing.hdr")),
        "{:?}",
        scene.notes
    );
}
