use glam::{Vec2, Vec4};
use proptest::prelude::*;

use super::*;

/// A 2×2 texture: red, green / blue, white (8-bit values given).
fn quad(encoding: Encoding) -> Texture {
    let texels = vec![[255, 0, 0, 255], [0, 128, 0, 255], [0, 0, 64, 255], [255, 255, 255, 0]];
    Texture::from_rgba8("quad", 2, 2, texels, encoding).unwrap()
}

fn close(a: Vec4, b: Vec4) -> bool {
    (a - b).abs().max_element() < 1e-5
}

#[test]
fn texel_centres_read_their_texel_decoded_as_the_encoding_says() {
    let srgb = quad(Encoding::Srgb);
    let centre = |x: f32, y: f32| Vec2::new((x + 0.5) / 2.0, (y + 0.5) / 2.0);
    let wrap = [Wrap::Repeat; 2];
    assert!(close(
        srgb.sample(centre(0.0, 0.0), wrap, 0.0),
        Vec4::new(1.0, 0.0, 0.0, 1.0)
    ));
    // sRGB 128 is linear 0.2158605; 64 is 0.0512695.
    let g = srgb.sample(centre(1.0, 0.0), wrap, 0.0);
    assert!((g.y - 0.215_860_5).abs() < 1e-6, "{g}");
    let b = srgb.sample(centre(0.0, 1.0), wrap, 0.0);
    assert!((b.z - 0.051_269_5).abs() < 1e-6, "{b}");
    assert!(close(
        srgb.sample(centre(1.0, 1.0), wrap, 0.0),
        Vec4::new(1.0, 1.0, 1.0, 0.0)
    ));
    let linear = quad(Encoding::Linear);
    let g = linear.sample(centre(1.0, 0.0), wrap, 0.0);
    assert!((g.y - 128.0 / 255.0).abs() < 1e-6);
    assert!(srgb.has_alpha);
}

#[test]
fn bilinear_blends_neighbours_and_wraps_as_told() {
    let t = quad(Encoding::Linear);
    // Halfway between the red and green texel centres.
    let mid = t.sample(Vec2::new(0.5, 0.25), [Wrap::Repeat; 2], 0.0);
    assert!(close(mid, Vec4::new(0.5, 64.0 / 255.0, 0.0, 1.0)), "{mid}");
    // At u = 0 (the left edge) repeat blends with the right column, clamp does not.
    let edge = Vec2::new(0.0, 0.25);
    let repeat = t.sample(edge, [Wrap::Repeat; 2], 0.0);
    let clamp = t.sample(edge, [Wrap::Clamp; 2], 0.0);
    let mirror = t.sample(edge, [Wrap::Mirror; 2], 0.0);
    assert!(close(repeat, mid));
    assert!(close(clamp, Vec4::new(1.0, 0.0, 0.0, 1.0)));
    assert!(close(mirror, Vec4::new(1.0, 0.0, 0.0, 1.0)));
    // One period further reads the same under repeat.
    assert!(close(t.sample(Vec2::new(3.5, 2.25), [Wrap::Repeat; 2], 0.0), mid));
    // Mirror: u in [1, 2) reads the image reversed.
    let m = t.sample(Vec2::new(1.25, 0.25), [Wrap::Mirror; 2], 0.0);
    assert!(close(m, Vec4::new(0.0, 128.0 / 255.0, 0.0, 1.0)), "{m}");
}

#[test]
fn the_pyramid_averages_in_linear_light() {
    // A black and white checker averages to linear 0.5, which is sRGB 188.
    let checker = vec![
        [0, 0, 0, 255],
        [255, 255, 255, 255],
        [255, 255, 255, 255],
        [0, 0, 0, 255],
    ];
    let t = Texture::from_rgba8("checker", 2, 2, checker, Encoding::Srgb).unwrap();
    assert_eq!(t.levels(), 2);
    let top = t.sample(Vec2::splat(0.3), [Wrap::Repeat; 2], 1.0);
    assert!((top.x - 0.5).abs() < 0.005, "{top}");
    // Half a level up blends the two levels: full size at this point is
    // black (texel 0, 0), the top level 0.5.
    let half = t.sample(Vec2::splat(0.25), [Wrap::Repeat; 2], 0.5);
    assert!((half.x - 0.25).abs() < 0.005, "{half}");
    assert_eq!(Texture::lod_for(0.5), 0.0);
    assert_eq!(Texture::lod_for(4.0), 2.0);
    assert_eq!(Texture::lod_for(f32::NAN), 0.0);
    assert!(Texture::lod_for(f32::INFINITY) > 100.0);
    assert_eq!(t.bytes(), 4 * 4 + 4);
}

#[test]
fn bad_sizes_are_refused_with_the_name() {
    let err = Texture::from_rgba8("empty.png", 0, 4, vec![], Encoding::Srgb).unwrap_err();
    assert!(err.to_string().contains("empty.png"), "{err}");
    let err = Texture::from_rgba8("short.png", 2, 2, vec![[0; 4]; 3], Encoding::Srgb).unwrap_err();
    assert!(err.to_string().contains("3 texels for 2x2"), "{err}");
    let err = Texture::from_rgba8("huge.png", 1 << 14, 1 << 14, vec![], Encoding::Srgb).unwrap_err();
    assert!(matches!(err, TextureError::TooLarge { .. }), "{err}");
    let hdr = Texture::from_rgba32f("hdr", 1, 1, vec![[f32::NAN, -1.0, 2.5, 1.0]]).unwrap();
    assert_eq!(
        hdr.sample(Vec2::ZERO, [Wrap::Clamp; 2], 0.0),
        Vec4::new(0.0, 0.0, 2.5, 1.0)
    );
}

#[test]
fn files_load_once_and_bad_files_say_what_is_wrong() {
    let dir = tempfile::tempdir().unwrap();
    let png = dir.path().join("a.png");
    image::RgbaImage::from_pixel(3, 2, image::Rgba([10, 20, 30, 255]))
        .save(&png)
        .unwrap();
    let mut set = TextureSet::new();
    let a = set.load(&png, Encoding::Srgb).unwrap();
    let again = set.load(&dir.path().join(".").join("a.png"), Encoding::Srgb).unwrap();
    assert_eq!(a, again, "one file, one texture");
    let data = set.load(&png, Encoding::Linear).unwrap();
    assert_ne!(a, data, "colour and data decodings differ");
    assert_eq!((set.get(a).unwrap().width(), set.get(a).unwrap().height()), (3, 2));
    let missing = set.load(&dir.path().join("missing.png"), Encoding::Srgb).unwrap_err();
    assert!(missing.to_string().contains("missing.png"), "{missing}");
    let junk = dir.path().join("junk.png");
    std::fs::write(&junk, b"\x89PNG\r\n\x1a\n not really").unwrap();
    let err = set.load(&junk, Encoding::Srgb).unwrap_err();
    assert!(err.to_string().contains("junk.png"), "{err}");
    let text = dir.path().join("notes.txt");
    std::fs::write(&text, b"hello").unwrap();
    assert!(set.load(&text, Encoding::Srgb).is_err());
    assert_eq!(set.len(), 2);
}

proptest! {
    #[test]
    fn lookups_stay_within_the_texels_range(
        u in -1e6f32..1e6, v in -1e6f32..1e6, lod in -4.0f32..20.0,
        wrap in 0usize..3,
    ) {
        let t = quad(Encoding::Srgb);
        let w = [Wrap::Repeat, Wrap::Clamp, Wrap::Mirror][wrap];
        let c = t.sample(Vec2::new(u, v), [w, w], lod);
        prop_assert!(c.is_finite());
        prop_assert!(c.min_element() >= 0.0 && c.max_element() <= 1.0 + 1e-6);
    }

    #[test]
    fn decoding_arbitrary_bytes_never_panics(bytes in proptest::collection::vec(any::<u8>(), 0..512)) {
        let mut set = TextureSet::new();
        let _ = set.load_bytes("fuzz", &bytes, Encoding::Srgb);
    }
}
