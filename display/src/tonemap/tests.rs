use glam::Vec3;
use proptest::prelude::*;

use super::*;

const EFFICACY: f64 = DEFAULT_LUMINOUS_EFFICACY as f64;

/// Radiance of a grey with luminance `l` cd/m².
fn grey(l: f64) -> [f32; 3] {
    [(l / EFFICACY) as f32; 3]
}

/// Radiance of colour `c` scaled to luminance `l` cd/m².
fn tinted(c: [f64; 3], l: f64) -> [f32; 3] {
    let y = vision::luminance(c);
    c.map(|v| (v * l / (y * EFFICACY)) as f32)
}

fn picture(pixels: Vec<[f32; 3]>) -> Picture {
    Picture {
        width: pixels.len(),
        height: 1,
        pixels: pixels.into_iter().map(Vec3::from).collect(),
    }
}

/// `n` greys spread evenly in log luminance from `lo` to `hi` cd/m².
fn log_ramp(lo: f64, hi: f64, n: usize) -> Vec<[f32; 3]> {
    (0..n)
        .map(|i| grey(lo * (hi / lo).powf(i as f64 / (n - 1).max(1) as f64)))
        .collect()
}

/// SplitMix64: deterministic noise without a dependency.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
}

fn map_for(pixels: &[[f32; 3]], mode: ToneMode) -> ToneMap {
    ToneMap::from_picture(&picture(pixels.to_vec()), mode)
}

/// Relative chroma of an 8-bit colour: 0 for grey, 1 for a pure primary.
fn chroma(c: [u8; 3]) -> f64 {
    let (lo, hi) = (
        c.iter().min().copied().unwrap_or(0),
        c.iter().max().copied().unwrap_or(0),
    );
    if hi == 0 {
        0.0
    } else {
        f64::from(hi - lo) / f64::from(hi)
    }
}

/// Test pictures covering the adjusted and the sparse cases.
fn assorted() -> Vec<(&'static str, Vec<[f32; 3]>)> {
    let mut rng = Rng(7);
    let mut spiky = vec![grey(10.0); 2000];
    spiky.extend(log_ramp(1e-2, 1e4, 2000));
    let mut clusters = log_ramp(0.01, 0.02, 300);
    clusters.extend(log_ramp(5.0, 8.0, 300));
    clusters.extend(log_ramp(2e4, 3e4, 300));
    let lognormal = (0..5000)
        .map(|_| {
            let (u, v) = (rng.next().max(1e-12), rng.next());
            let z = (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos();
            grey(10f64.powf(1.0 + 1.5 * z))
        })
        .collect();
    let mut two = vec![grey(1.0); 500];
    two.extend(vec![grey(1e4); 500]);
    vec![
        ("wide ramp", log_ramp(1e-3, 1e5, 4000)),
        ("spike on a ramp", spiky),
        ("three clusters", clusters),
        ("log-normal", lognormal),
        ("two levels", two),
        ("narrow", log_ramp(1.0, 1.02, 256)),
        ("one value", vec![grey(5.0); 100]),
    ]
}

#[test]
fn brighter_world_is_never_dimmer_display() {
    for (name, pixels) in assorted() {
        for mode in [ToneMode::Camera, ToneMode::Human, ToneMode::Exposure(0.01)] {
            let tm = map_for(&pixels, mode);
            let (mut prev_ld, mut prev_v) = (0.0, 0u8);
            let mut b = -8.0;
            while b < 12.0 {
                let lw = 10f64.powf(b);
                let ld = tm.display_luminance(lw);
                let v = tm.map(grey(lw))[0];
                assert!(
                    ld >= prev_ld * (1.0 - 1e-12),
                    "{name} {mode:?} at {lw}: {ld} < {prev_ld}"
                );
                assert!(v >= prev_v, "{name} {mode:?} at {lw}: {v} < {prev_v}");
                (prev_ld, prev_v) = (ld, v);
                b += 0.01;
            }
        }
    }
}

#[test]
fn camera_shows_both_of_two_far_apart_levels_and_an_exposure_cannot() {
    let mut pixels = vec![grey(1.0); 2048];
    pixels.extend(vec![grey(1e4); 2048]);
    let tm = map_for(&pixels, ToneMode::Camera);
    assert_eq!(tm.kind(), MapKind::Sparse);
    let (dark, bright) = (tm.map(grey(1.0))[0], tm.map(grey(1e4))[0]);
    assert!(
        dark >= 10 && bright <= 245 && bright - dark >= 100,
        "dark {dark}, bright {bright}"
    );
    for stop in -120..=120 {
        let e = 10f32.powf(stop as f32 * 0.1);
        let tm = map_for(&pixels, ToneMode::Exposure(e));
        let (dark, bright) = (tm.map(grey(1.0))[0], tm.map(grey(1e4))[0]);
        assert!(
            !(dark >= 10 && bright <= 245),
            "exposure {e} shows both: {dark}, {bright}"
        );
    }
}

#[test]
fn camera_uses_the_whole_display_for_a_wide_smooth_picture() {
    let pixels = log_ramp(1e-3, 1e5, 4000);
    let tm = map_for(&pixels, ToneMode::Camera);
    assert_eq!(tm.kind(), MapKind::Adjusted);
    assert!(tm.map(grey(1e-3))[0] <= 3);
    assert!(tm.map(grey(1e5))[0] >= 252);
    let mid = tm.map(grey(10.0))[0];
    assert!((60..=200).contains(&mid), "{mid}");
}

#[test]
fn camera_is_never_steeper_than_linear() {
    // The paper stops trimming within 2.5 % of the total, which leaves the
    // ceiling up to 1/(1 - 0.025) too high.
    let limit = 1.0 / (1.0 - TOLERANCE) + 1e-9;
    for (name, pixels) in assorted() {
        let tm = map_for(&pixels, ToneMode::Camera);
        for w in tm.brightness_curve().windows(2) {
            let slope = (w[1].1 - w[0].1) / (w[1].0 - w[0].0);
            assert!(slope <= limit && slope >= 0.0, "{name}: slope {slope} at {:?}", w[0]);
        }
        let h = 0.004;
        let mut b = -8.0;
        while b < 12.0 {
            let (l0, l1) = (
                tm.display_luminance(10f64.powf(b)),
                tm.display_luminance(10f64.powf(b + h)),
            );
            let slope = (l1.log10() - l0.log10()) / h;
            assert!(slope <= limit + 1e-6, "{name}: slope {slope} at log Lw {b}");
            b += 0.0037;
        }
    }
}

#[test]
fn human_mode_takes_colour_away_at_night_and_keeps_it_by_day() {
    let red = [1.0, 0.0, 0.0];
    let mut night = log_ramp(1e-4, 1e-2, 1000);
    night.extend(vec![tinted(red, 2e-3); 100]);
    let camera = map_for(&night, ToneMode::Camera).map(tinted(red, 2e-3));
    let human = map_for(&night, ToneMode::Human).map(tinted(red, 2e-3));
    assert!(chroma(camera) > 0.9, "camera {camera:?}");
    assert!(chroma(human) < 0.05, "human {human:?}");
    assert!(human[0] > 0, "desaturated, not black");

    let mut day = log_ramp(10.0, 1e4, 1000);
    day.extend(vec![tinted(red, 100.0); 100]);
    let camera = map_for(&day, ToneMode::Camera).map(tinted(red, 100.0));
    let human = map_for(&day, ToneMode::Human).map(tinted(red, 100.0));
    assert!(chroma(camera) > 0.9, "camera {camera:?}");
    assert!(chroma(human) > 0.9, "human {human:?}");

    // Dusk: colour is reduced, not gone.
    let mut dusk = log_ramp(0.01, 1.0, 1000);
    dusk.extend(vec![tinted(red, 0.1); 100]);
    let human = map_for(&dusk, ToneMode::Human).map(tinted(red, 0.1));
    assert!((0.05..0.9).contains(&chroma(human)), "dusk {human:?}");
}

#[test]
fn contrast_below_the_eye_threshold_stays_low_in_human_mode() {
    // 2 % at 1 cd/m² is far below the 39 % threshold there.
    let narrow = log_ramp(1.0, 1.02, 256);
    let camera = map_for(&narrow, ToneMode::Camera);
    let human = map_for(&narrow, ToneMode::Human);
    let contrast = |tm: &ToneMap| tm.display_luminance(1.02) / tm.display_luminance(1.0) - 1.0;
    assert!(
        (contrast(&camera) - 0.02).abs() < 0.001,
        "camera keeps the world contrast: {}",
        contrast(&camera)
    );
    assert!(contrast(&human) < 0.5 * contrast(&camera), "human {}", contrast(&human));

    // 50 % at 0.01 cd/m² is still below the ~51 % rod threshold there.
    let dim = log_ramp(0.01, 0.015, 256);
    let levels = |mode| {
        let tm = map_for(&dim, mode);
        let mut v: Vec<u8> = dim.iter().map(|&c| tm.map(c)[1]).collect();
        v.dedup();
        v.len()
    };
    let (camera, human) = (levels(ToneMode::Camera), levels(ToneMode::Human));
    assert!(camera >= 10, "camera shows the gradient: {camera} levels");
    assert!(2 * human <= camera, "human {human} levels vs camera {camera}");
}

#[test]
fn empty_flat_and_broken_inputs_do_not_panic() {
    let empty = Histogram::new();
    let one = ToneMap::new(&empty, ToneMode::Exposure(1.0), DisplayRange::default());
    for mode in [ToneMode::Camera, ToneMode::Human] {
        let tm = ToneMap::new(&empty, mode, DisplayRange::default());
        assert_eq!(tm.kind(), MapKind::NoData);
        assert_eq!(tm.map([0.25, 0.5, 0.125]), one.map([0.25, 0.5, 0.125]));
        assert!(tm.brightness_curve().is_empty());
    }
    let mut junk = Histogram::new();
    junk.add_many([[f32::NAN; 3], [0.0; 3], [-1.0; 3], [f32::INFINITY, 0.0, 0.0]]);
    assert_eq!(
        ToneMap::new(&junk, ToneMode::Camera, DisplayRange::default()).kind(),
        MapKind::NoData
    );

    for mode in [ToneMode::Camera, ToneMode::Human] {
        let tm = map_for(&[grey(5.0); 64], mode);
        assert_eq!(tm.kind(), MapKind::Sparse);
        let v = tm.map(grey(5.0))[0];
        assert!(
            (20..=200).contains(&v),
            "{mode:?}: a flat picture shows as a mid grey, got {v}"
        );
        assert_eq!(tm.map([f32::NAN, 1.0, 1.0]), [0, 0, 0]);
        assert_eq!(tm.map([f32::INFINITY; 3]), [0, 0, 0]);
        assert_eq!(tm.map([-1.0; 3]), [0, 0, 0]);
        assert_eq!(tm.map([f32::MAX; 3]), [255, 255, 255]);
        assert_eq!(tm.map([f32::MIN_POSITIVE; 3]), [0, 0, 0]);
    }
    let weird = DisplayRange {
        ld_min: f32::NAN,
        ld_max: -4.0,
    };
    let tm = ToneMap::new(
        &Histogram::from_picture(&picture(log_ramp(1.0, 1e3, 100))),
        ToneMode::Camera,
        weird,
    );
    assert_eq!(tm.display_range(), DisplayRange::default());
    let inverted = DisplayRange {
        ld_min: 50.0,
        ld_max: 10.0,
    }
    .sanitized();
    assert_eq!(
        inverted,
        DisplayRange {
            ld_min: 0.1,
            ld_max: 10.0
        }
    );
    for e in [f32::NAN, f32::INFINITY, -2.0] {
        let tm = ToneMap::new(&empty, ToneMode::Exposure(e), DisplayRange::default());
        assert!(tm.map([0.5; 3])[0] == one.map([0.5; 3])[0] || e < 0.0);
    }
    assert_eq!(
        ToneMap::new(&empty, ToneMode::Exposure(-2.0), DisplayRange::default()).map([0.5; 3]),
        [0, 0, 0]
    );
}

#[test]
fn exposure_is_a_plain_multiply_like_write_png() {
    let tm = ToneMap::new(&Histogram::new(), ToneMode::Exposure(2.0), DisplayRange::default());
    assert_eq!(tm.kind(), MapKind::Exposure);
    assert_eq!(tm.map([0.25, 0.125, 1.0]), [188, 137, 255]);
    assert_eq!(tm.map_linear([0.25, 0.125, 1.0]), [0.5, 0.25, 1.0]);
    for v in 0..=255u8 {
        assert_eq!(encode_srgb(decode_srgb(v)), v);
    }
}

#[test]
fn saturated_colours_keep_the_chosen_luminance() {
    let tm = map_for(&log_ramp(1e-2, 1e4, 1000), ToneMode::Camera);
    let blue = tinted([0.0, 0.0, 1.0], 100.0);
    let out = tm.map_linear(blue);
    let want = (tm.display_luminance(100.0) - 1.0) / 99.0;
    let got = vision::luminance(out.map(f64::from));
    assert!(out[2] == 1.0 && out[0] > 0.0, "out of gamut blue desaturates: {out:?}");
    assert!((got - want).abs() < 1e-5, "{got} vs {want}");
}

#[test]
fn apply_matches_map_per_pixel_in_parallel_too() {
    let mut rng = Rng(3);
    for (width, height) in [(300, 300), (17, 5), (0, 0)] {
        let pixels: Vec<Vec3> = (0..width * height)
            .map(|_| {
                let l = 10f64.powf(6.0 * rng.next() - 2.0) as f32;
                Vec3::new(l * rng.next() as f32, l * rng.next() as f32, l * rng.next() as f32)
            })
            .collect();
        let p = Picture { width, height, pixels };
        for mode in [ToneMode::Camera, ToneMode::Human, ToneMode::Exposure(0.3)] {
            let tm = ToneMap::from_picture(&p, mode);
            let bytes = tm.apply(&p);
            assert_eq!(bytes.len(), 3 * width * height);
            for (px, b) in p.pixels.iter().zip(bytes.chunks_exact(3)) {
                assert_eq!(tm.map(px.to_array()), [b[0], b[1], b[2]]);
            }
        }
    }
}

#[test]
fn incremental_histogram_gives_the_same_map() {
    let pixels = log_ramp(1e-2, 1e4, 3000);
    let p = picture(pixels.clone());
    let mut h = Histogram::new();
    for chunk in pixels.chunks(100) {
        h.add_many(chunk.iter().copied());
    }
    assert_eq!(h, Histogram::from_picture(&p));
    assert_eq!(
        ToneMap::new(&h, ToneMode::Human, DisplayRange::default()),
        ToneMap::from_picture(&p, ToneMode::Human)
    );
}

#[test]
fn applied_bytes_write_as_a_png() {
    let p = Picture {
        width: 5,
        height: 3,
        pixels: log_ramp(0.1, 1e3, 15).into_iter().map(Vec3::from).collect(),
    };
    let tm = ToneMap::from_picture(&p, ToneMode::Camera);
    let bytes = tm.apply(&p);
    let path = std::env::temp_dir().join(format!("holodeck-tonemap-{}.png", std::process::id()));
    crate::image_io::write_rgb8(&path, 5, 3, &bytes).unwrap();
    let back = image::open(&path).unwrap().to_rgb8();
    let _ = std::fs::remove_file(&path);
    assert_eq!((back.width(), back.height()), (5, 3));
    assert_eq!(back.into_raw(), bytes);
    assert!(crate::image_io::write_rgb8(&path, 5, 3, &bytes[1..]).is_err());
    assert!(crate::image_io::write_rgb8(&path, usize::MAX, 3, &bytes).is_err());
    assert!(!path.exists());
}

fn levels_picture(levels: &[f64]) -> Picture {
    let mut pixels = Vec::new();
    for (i, &b) in levels.iter().enumerate() {
        for k in 0..(10 + 7 * i) {
            pixels.push(grey(10f64.powf(b + 0.002 * k as f64)));
        }
    }
    picture(pixels)
}

proptest! {
    #[test]
    fn grey_mapping_is_monotone(
        levels in prop::collection::vec(-5.0f64..7.0, 1..6),
        a in -7.0f64..9.0,
        b in -7.0f64..9.0,
        human in any::<bool>(),
    ) {
        let mode = if human { ToneMode::Human } else { ToneMode::Camera };
        let tm = ToneMap::from_picture(&levels_picture(&levels), mode);
        let (lo, hi) = (10f64.powf(a.min(b)), 10f64.powf(a.max(b)));
        prop_assert!(tm.display_luminance(lo) <= tm.display_luminance(hi) * (1.0 + 1e-12));
        let (dark, bright) = (tm.map(grey(lo)), tm.map(grey(hi)));
        prop_assert!(dark[0] <= bright[0] && dark[1] <= bright[1] && dark[2] <= bright[2]);
    }

    #[test]
    fn colour_mapping_is_monotone_in_luminance(
        levels in prop::collection::vec(-5.0f64..7.0, 1..6),
        rgb in prop::array::uniform3(0.0f64..1.0),
        a in -7.0f64..9.0,
        b in -7.0f64..9.0,
        human in any::<bool>(),
    ) {
        prop_assume!(vision::luminance(rgb) > 1e-3);
        let mode = if human { ToneMode::Human } else { ToneMode::Camera };
        let tm = ToneMap::from_picture(&levels_picture(&levels), mode);
        let (lo, hi) = (10f64.powf(a.min(b)), 10f64.powf(a.max(b)));
        let shown = |l| vision::luminance(tm.map_linear(tinted(rgb, l)).map(f64::from));
        prop_assert!(shown(lo) <= shown(hi) + 1e-6, "{} > {}", shown(lo), shown(hi));
        if !human {
            // Same chromaticity: every channel is monotone, even after the gamut fit.
            let (dark, bright) = (tm.map(tinted(rgb, lo)), tm.map(tinted(rgb, hi)));
            prop_assert!(dark[0] <= bright[0] && dark[1] <= bright[1] && dark[2] <= bright[2], "{dark:?} {bright:?}");
        }
    }
}

#[test]
fn human_mode_gives_a_night_region_less_contrast_than_the_camera() {
    // Half the picture under starlight, half lamp-lit: the eye adapted to
    // the lamps sees little in the dark, the camera shows it all.
    let mut pixels = log_ramp(1e-4, 1e-2, 2000);
    pixels.extend(log_ramp(10.0, 1e3, 2000));
    let dark_levels = |mode| {
        let tm = map_for(&pixels, mode);
        assert_eq!(tm.kind(), MapKind::Adjusted);
        let mut v: Vec<u8> = pixels[..2000].iter().map(|&c| tm.map(c)[1]).collect();
        v.dedup();
        v.len()
    };
    let (camera, human) = (dark_levels(ToneMode::Camera), dark_levels(ToneMode::Human));
    assert!(camera >= 60, "camera {camera}");
    assert!(2 * human <= camera, "human {human} vs camera {camera}");
}

#[test]
fn the_srgb_table_encodes_every_value_as_the_formula_does() {
    // Every step and its neighbours, then a sweep of the range.
    for k in 0..=255u32 {
        let v = (k as f32 + 0.5) / 255.0;
        for x in [v, f32::from_bits(v.to_bits() - 1), f32::from_bits(v.to_bits() + 1)] {
            assert_eq!(encode_srgb(x), encode_srgb_exact(x), "{x}");
        }
    }
    for i in 0..=200_000u32 {
        let v = i as f32 / 200_000.0;
        assert_eq!(encode_srgb(v), encode_srgb_exact(v), "{v}");
    }
    for v in [-1.0, 0.0, 1.0, 2.0, f32::NAN, f32::INFINITY, 0.003_130_8, 1e-30] {
        assert_eq!(encode_srgb(v), encode_srgb_exact(v), "{v}");
    }
}

/// Every float from 0 to 1 (a billion; seconds in a release build:
/// `cargo test --release -p holodeck-display -- --ignored srgb`).
#[test]
#[ignore]
fn every_float_in_the_unit_range_encodes_as_the_formula_does() {
    for bits in 0..=1f32.to_bits() {
        let v = f32::from_bits(bits);
        assert_eq!(encode_srgb(v), encode_srgb_exact(v), "{v}");
    }
}

proptest::proptest! {
    #[test]
    fn any_float_encodes_as_the_formula_does(bits in proptest::prelude::any::<u32>()) {
        let v = f32::from_bits(bits);
        proptest::prop_assert_eq!(encode_srgb(v), encode_srgb_exact(v));
    }
}
