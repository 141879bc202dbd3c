use glam::Vec3;
use holodeck_protocol::Picture;

use super::*;
use crate::tonemap::ToneMode;

/// SplitMix64 with Box–Muller: deterministic Gaussian noise without a
/// dependency.
struct Rng(u64);

impl Rng {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }

    fn gaussian(&mut self) -> f64 {
        let (u, v) = (self.uniform().max(1e-300), self.uniform());
        (-2.0 * u.ln()).sqrt() * (std::f64::consts::TAU * v).cos()
    }
}

/// A reference with structure: a gradient, a checkerboard and a disc.
fn reference(width: usize, height: usize) -> Picture {
    let pixels = (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f32, (i / width) as f32);
            let check = if ((x as usize / 8) + (y as usize / 8)).is_multiple_of(2) {
                0.3
            } else {
                0.0
            };
            let disc = if (x - 60.0).powi(2) + (y - 40.0).powi(2) < 400.0 {
                0.5
            } else {
                0.0
            };
            let base = 0.4 + 0.6 * x / width as f32 + check + disc;
            Vec3::new(base, 0.8 * base + 0.1, 0.5 * base + 0.2 * y / height as f32)
        })
        .collect();
    Picture { width, height, pixels }
}

fn noisy(p: &Picture, sigma: f64, seed: u64) -> Picture {
    let mut rng = Rng(seed);
    let mut q = p.clone();
    for v in &mut q.pixels {
        *v += Vec3::new(rng.gaussian() as f32, rng.gaussian() as f32, rng.gaussian() as f32) * sigma as f32;
    }
    q
}

#[test]
fn identical_pictures_are_perfect() {
    let p = reference(160, 120);
    let tone = ToneMap::from_picture(&p, ToneMode::Camera);
    assert_eq!(rmse(&p, &p), Ok(0.0));
    assert_eq!(relative_rmse(&p, &p), Ok(0.0));
    assert_eq!(psnr(&p, &p, None), f64::INFINITY);
    assert_eq!(psnr(&p, &p, Some(1.0)), f64::INFINITY);
    assert!((ssim(&p, &p, &tone) - 1.0).abs() < 1e-12);
    let m = metrics(&p, &p, &tone, None).unwrap();
    assert_eq!(m.pixels, 160 * 120);
    assert_eq!((m.rmse, m.psnr_db), (0.0, f64::INFINITY));
}

#[test]
fn gaussian_noise_gives_its_sigma_back() {
    let p = reference(200, 150);
    let rms = (p.pixels.iter().map(|v| f64::from(v.length_squared())).sum::<f64>() / (3.0 * 200.0 * 150.0)).sqrt();
    let peak = p.pixels.iter().map(|v| f64::from(v.max_element())).fold(0.0, f64::max);
    for (seed, sigma) in [0.002, 0.01, 0.05, 0.2].into_iter().enumerate() {
        let q = noisy(&p, sigma, seed as u64 + 1);
        let e = rmse(&q, &p).unwrap();
        assert!((e / sigma - 1.0).abs() < 0.05, "sigma {sigma}: rmse {e}");
        let rel = relative_rmse(&q, &p).unwrap();
        assert!(
            (rel / (sigma / rms) - 1.0).abs() < 0.05,
            "sigma {sigma}: relative {rel}"
        );
        let db = psnr(&q, &p, Some(1.0));
        assert!(
            (db - 20.0 * (1.0 / sigma).log10()).abs() < 0.5,
            "sigma {sigma}: {db} dB"
        );
        let db = psnr(&q, &p, None);
        assert!(
            (db - 20.0 * (peak / sigma).log10()).abs() < 0.5,
            "sigma {sigma}: {db} dB at peak {peak}"
        );
    }
}

#[test]
fn ssim_falls_as_noise_grows() {
    let p = reference(160, 120);
    let tone = ToneMap::from_picture(&p, ToneMode::Camera);
    let scores: Vec<f64> = [0.003, 0.01, 0.03, 0.1, 0.3]
        .iter()
        .map(|&s| ssim(&noisy(&p, s, 9), &p, &tone))
        .collect();
    assert!(scores[0] > 0.95, "{scores:?}");
    assert!(scores.windows(2).all(|w| w[1] < w[0]), "{scores:?}");
    assert!(scores[4] < 0.5, "{scores:?}");
    let human = ToneMap::from_picture(&p, ToneMode::Human);
    assert!(ssim(&noisy(&p, 0.1, 9), &p, &human) < ssim(&noisy(&p, 0.01, 9), &p, &human));
}

#[test]
fn mismatched_or_broken_inputs_are_errors_not_panics() {
    let (p, q) = (reference(40, 30), reference(30, 40));
    let tone = ToneMap::from_picture(&p, ToneMode::Camera);
    let mismatch = CompareError::SizeMismatch {
        a_width: 40,
        a_height: 30,
        b_width: 30,
        b_height: 40,
    };
    assert_eq!(rmse(&p, &q), Err(mismatch.clone()));
    assert_eq!(relative_rmse(&p, &q), Err(mismatch.clone()));
    assert_eq!(metrics(&p, &q, &tone, None), Err(mismatch));
    assert!(psnr(&p, &q, None).is_nan());
    assert!(ssim(&p, &q, &tone).is_nan());

    let mut short = p.clone();
    short.pixels.pop();
    let malformed = Err(CompareError::Malformed {
        width: 40,
        height: 30,
        pixels: 1199,
    });
    assert_eq!(rmse(&short, &p), malformed);
    assert_eq!(rmse(&p, &short), malformed);
    assert!(ssim(&short, &p, &tone).is_nan());

    assert_eq!(
        rmse_masked(&p, &p, &[true; 3]),
        Err(CompareError::MaskSize { mask: 3, pixels: 1200 })
    );
    assert_eq!(rmse_masked(&p, &p, &vec![false; 1200]), Err(CompareError::NoPixels));
    assert!(ssim_masked(&p, &p, &tone, &vec![false; 1200]).is_nan());
    let empty = Picture {
        width: 0,
        height: 0,
        pixels: vec![],
    };
    assert_eq!(rmse(&empty, &empty), Err(CompareError::NoPixels));
    assert!(psnr(&p, &noisy(&p, 0.1, 1), Some(f64::NAN)).is_nan());
    assert!(psnr(&p, &noisy(&p, 0.1, 1), Some(-1.0)).is_nan());
    assert_eq!(mismatch_message(), "pictures differ in size: 40x30 vs 30x40");
}

fn mismatch_message() -> String {
    CompareError::SizeMismatch {
        a_width: 40,
        a_height: 30,
        b_width: 30,
        b_height: 40,
    }
    .to_string()
}

#[test]
fn tiny_pictures_work() {
    for (w, h) in [(1, 1), (3, 2), (1, 17), (12, 1)] {
        let p = reference(w, h);
        let tone = ToneMap::from_picture(&p, ToneMode::Camera);
        assert!((ssim(&p, &p, &tone) - 1.0).abs() < 1e-12);
        let s = ssim(&noisy(&p, 0.3, 4), &p, &tone);
        assert!(s.is_finite() && s < 1.0, "{w}x{h}: {s}");
    }
}

#[test]
fn masks_leave_out_unfilled_pixels() {
    let p = reference(120, 90);
    let tone = ToneMap::from_picture(&p, ToneMode::Camera);
    let sigma = 0.01;
    let mut shown = noisy(&p, sigma, 5);
    let mut mask = vec![true; shown.pixels.len()];
    let mut rng = Rng(11);
    for (i, v) in shown.pixels.iter_mut().enumerate() {
        if rng.uniform() < 0.2 {
            *v = if i % 2 == 0 { Vec3::ZERO } else { Vec3::NAN };
            mask[i] = false;
        }
    }
    let masked = rmse_masked(&shown, &p, &mask).unwrap();
    let all = rmse(&shown, &p).unwrap();
    assert!((masked / sigma - 1.0).abs() < 0.05, "masked {masked}");
    assert!(all > 10.0 * masked, "holes count without the mask: {all}");
    assert!(psnr_masked(&shown, &p, &mask, Some(1.0)) > psnr(&shown, &p, Some(1.0)) + 10.0);
    assert!(relative_rmse_masked(&shown, &p, &mask).unwrap() < relative_rmse(&shown, &p).unwrap());
    let (s_masked, s_all) = (ssim_masked(&shown, &p, &tone, &mask), ssim(&shown, &p, &tone));
    assert!(
        s_masked > 0.9 && s_all < s_masked - 0.1,
        "masked {s_masked}, all {s_all}"
    );
    let m = metrics(&shown, &p, &tone, Some(&mask)).unwrap();
    assert_eq!(m.pixels, mask.iter().filter(|&&x| x).count());
    assert_eq!((m.rmse, m.ssim), (masked, s_masked));

    // NaN counts as black, in either picture.
    let mut black = p.clone();
    let mut nan = p.clone();
    black.pixels[7] = Vec3::ZERO;
    nan.pixels[7] = Vec3::new(1.0, f32::NAN, 1.0);
    assert_eq!(rmse(&nan, &p), rmse(&black, &p));
    assert_eq!(rmse(&p, &nan), rmse(&p, &black));
    assert!(rmse(&nan, &p).unwrap() > 0.0);
    assert_eq!(ssim(&nan, &p, &tone), ssim(&black, &p, &tone));
    assert!(psnr(&nan, &nan, None).is_infinite());
}

/// A picture of one colour.
fn flat(width: usize, height: usize, c: Vec3) -> Picture {
    Picture {
        width,
        height,
        pixels: vec![c; width * height],
    }
}

#[test]
fn relative_mse_and_clamping_match_hand_computed_values() {
    let b = flat(10, 10, Vec3::ONE);
    let a = flat(10, 10, Vec3::splat(1.1));
    // (0.1)² / (1² + 0.01) in every channel of every pixel.
    let want = 0.01 / 1.01;
    assert!((relative_mse(&a, &b).unwrap() - want).abs() < 1e-6);
    // A glint of 100 in the reference shown as 10: above the clamp both are
    // white and nothing is wrong; unclamped it rules the error.
    let (mut a, mut b) = (flat(10, 10, Vec3::splat(0.5)), flat(10, 10, Vec3::splat(0.5)));
    b.pixels[37] = Vec3::splat(100.0);
    a.pixels[37] = Vec3::splat(10.0);
    assert_eq!(clamped_relative_rmse(&a, &b, 2.0), Ok(0.0));
    let rel = relative_rmse(&a, &b).unwrap();
    let want = (90.0f64 * 90.0 / (100.0 * 100.0 + 99.0 * 0.25)).sqrt();
    assert!((rel - want).abs() < 1e-6, "{rel} {want}");
    // Clamped at 20, the glint counts as 10 against 20.
    let c = clamped_relative_rmse(&a, &b, 20.0).unwrap();
    let want = (10.0f64 * 10.0 / (20.0 * 20.0 + 99.0 * 0.25)).sqrt();
    assert!((c - want).abs() < 1e-6, "{c} {want}");
}

/// A reference whose luminance ranks are known: pixel i has luminance i + 1.
fn ramp(n: usize) -> Picture {
    Picture {
        width: n,
        height: 1,
        pixels: (0..n).map(|i| Vec3::splat(i as f32 + 1.0)).collect(),
    }
}

#[test]
fn regions_are_exact_quarters_by_the_reference_rank() {
    let mut r = ramp(20);
    r.pixels.reverse();
    let regions = Regions::of(&r);
    let count = |k: Region| (0..20).filter(|&i| regions.get(i) == k).count();
    assert_eq!(
        (count(Region::Dark), count(Region::Middle), count(Region::Bright)),
        (5, 10, 5)
    );
    // Reversed: the first five pixels are the brightest.
    assert!((0..5).all(|i| regions.get(i) == Region::Bright));
    assert!((15..20).all(|i| regions.get(i) == Region::Dark));
    // Ties go by pixel order, so a flat picture still has exact quarters.
    let flat = Regions::of(&flat(4, 2, Vec3::ONE));
    let kinds: Vec<Region> = (0..8).map(|i| flat.get(i)).collect();
    use Region::*;
    assert_eq!(kinds, vec![Dark, Dark, Middle, Middle, Middle, Middle, Bright, Bright]);
}

#[test]
fn light_kept_is_the_ratio_of_sums_per_region() {
    let b = ramp(8); // luminance 1..=8: dark {1, 2}, middle {3..=6}, bright {7, 8}
    let mut a = b.clone();
    a.pixels[0] *= 0.5; // dark: 0.5 + 2 of 3
    a.pixels[7] *= 2.0; // bright: 7 + 16 of 15
    let y = Yardstick::new(b.clone(), ToneMap::from_picture(&b, ToneMode::Camera))
        .unwrap()
        .with_band(vec![true, false, false, false, false, false, false, true])
        .unwrap();
    let m = y.measure(&a).unwrap();
    let close = |x: f64, want: f64| (x - want).abs() < 1e-6;
    assert!(close(m.light.dark, 2.5 / 3.0), "{:?}", m.light);
    assert!(close(m.light.middle, 1.0), "{:?}", m.light);
    assert!(close(m.light.bright, 23.0 / 15.0), "{:?}", m.light);
    assert!(close(m.light.frame, 43.5 / 36.0), "{:?}", m.light);
    assert!(close(m.light.band.unwrap(), 16.5 / 9.0), "{:?}", m.light);
    assert!(close(m.light.worst(), 16.5 / 9.0));
    assert!(!m.light.within(0.02));
    assert!(y.measure(&b).unwrap().light.within(0.0));
    // Masked: only the pixels shown count, in the reference too.
    let mask = [false, true, true, true, true, true, true, true];
    let m = y.measure_masked(&a, &mask).unwrap();
    assert!(close(m.light.dark, 1.0) && close(m.light.band.unwrap(), 2.0));
    // Black in the reference and the picture keeps everything; light where
    // the reference has none cannot be a ratio.
    let dark = flat(4, 1, Vec3::ZERO);
    let y = Yardstick::new(dark.clone(), ToneMap::from_picture(&dark, ToneMode::Camera)).unwrap();
    assert_eq!(y.measure(&dark).unwrap().light.dark, 1.0);
    assert!(y.measure(&flat(4, 1, Vec3::ONE)).unwrap().light.dark.is_nan());
}

/// CIE L*a*b* of a linear-RGB colour as FLIP computes it (sRGB primaries,
/// D65 white as the XYZ of RGB (1, 1, 1)), then FLIP's Hunt adjustment.
fn hunt_lab(rgb: [f64; 3]) -> [f64; 3] {
    let m = [
        [0.412_390_8, 0.357_584_3, 0.180_480_8],
        [0.212_639_0, 0.715_168_7, 0.072_192_3],
        [0.019_330_8, 0.119_194_8, 0.950_532_2],
    ];
    let xyz = |c: [f64; 3]| m.map(|r| r[0] * c[0] + r[1] * c[1] + r[2] * c[2]);
    let (x, w) = (xyz(rgb), xyz([1.0; 3]));
    let f = |t: f64| {
        let d = 6.0f64 / 29.0;
        if t > d * d * d {
            t.cbrt()
        } else {
            t / (3.0 * d * d) + 4.0 / 29.0
        }
    };
    let (fx, fy, fz) = (f(x[0] / w[0]), f(x[1] / w[1]), f(x[2] / w[2]));
    let l = 116.0 * fy - 16.0;
    [l, 0.01 * l * 500.0 * (fx - fy), 0.01 * l * 200.0 * (fy - fz)]
}

/// FLIP's colour error of two flat pictures, by the paper's formulas.
fn flat_flip(a: [f64; 3], b: [f64; 3]) -> f64 {
    let hyab = |p: [f64; 3], q: [f64; 3]| (p[0] - q[0]).abs() + ((p[1] - q[1]).powi(2) + (p[2] - q[2]).powi(2)).sqrt();
    let cmax = hyab(hunt_lab([0.0, 1.0, 0.0]), hunt_lab([0.0, 0.0, 1.0])).powf(0.7);
    let pccmax = 0.4 * cmax;
    let e = hyab(hunt_lab(a), hunt_lab(b)).powf(0.7);
    if e < pccmax {
        e * 0.95 / pccmax
    } else {
        0.95 + (e - pccmax) / (cmax - pccmax) * 0.05
    }
}

#[test]
fn flip_of_flat_pictures_is_the_papers_colour_error() {
    let (w, h) = (24, 16);
    let bytes = |c: [u8; 3]| c.repeat(w * h);
    for (a, b) in [
        ([0u8, 0, 0], [255u8, 255, 255]),
        ([255, 255, 255], [128, 128, 128]),
        ([200, 40, 40], [40, 40, 200]),
    ] {
        let map = flip::flip_map(&bytes(a), &bytes(b), w, h, flip::PIXELS_PER_DEGREE);
        let want = flat_flip(
            a.map(|v| f64::from(crate::tonemap::decode_srgb(v))),
            b.map(|v| f64::from(crate::tonemap::decode_srgb(v))),
        );
        for &e in &map {
            assert!((f64::from(e) - want).abs() < 2e-3, "{a:?} {b:?}: {e} against {want}");
        }
    }
    let same = flip::flip_map(
        &bytes([90, 120, 30]),
        &bytes([90, 120, 30]),
        w,
        h,
        flip::PIXELS_PER_DEGREE,
    );
    assert!(same.iter().all(|&e| e == 0.0));
}

#[test]
fn flip_rises_with_noise_and_hdr_flip_sees_a_dimmed_highlight() {
    let p = reference(96, 64);
    let tone = ToneMap::from_picture(&p, ToneMode::Camera);
    let y = Yardstick::new(p.clone(), tone).unwrap();
    let exact = y.measure(&p).unwrap();
    assert_eq!((exact.flip, exact.hdr_flip), (0.0, 0.0));
    let scores: Vec<(f64, f64)> = [0.01, 0.05, 0.2]
        .iter()
        .map(|&s| {
            let m = y.measure(&noisy(&p, s, 3)).unwrap();
            (m.flip, m.hdr_flip)
        })
        .collect();
    assert!(
        scores.windows(2).all(|w| w[1].0 > w[0].0 && w[1].1 > w[0].1),
        "{scores:?}"
    );
    // A highlight 50 times the scene, dimmed to a third: LDR under the
    // reference's tone map may show both as white, HDR-FLIP does not.
    let mut bright = p.clone();
    let mut dimmed = p.clone();
    for i in [40 * 96 + 20, 40 * 96 + 21, 41 * 96 + 20, 41 * 96 + 21] {
        bright.pixels[i] = Vec3::splat(50.0);
        dimmed.pixels[i] = Vec3::splat(50.0 / 3.0);
    }
    let y = Yardstick::new(bright.clone(), ToneMap::from_picture(&bright, ToneMode::Camera)).unwrap();
    let m = y.measure(&dimmed).unwrap();
    assert!(m.hdr_flip > 1e-3, "{m:?}");
    assert!((m.light.bright - 1.0).abs() > 0.05);
}

#[test]
fn hdr_exposures_span_the_brightest_to_the_median() {
    // Luminance 1 in 15 pixels and 4 in one: from log2(x/4) to log2(x/1).
    let mut p = flat(4, 4, Vec3::ONE);
    p.pixels[5] = Vec3::splat(4.0);
    let e = flip::Exposures::of(&p);
    assert_eq!(e.stops.len(), 2);
    assert!((e.stops[1] - e.stops[0] - 2.0).abs() < 1e-9, "{e:?}");
    let mut q = p.clone();
    q.pixels[5] = Vec3::splat(1000.0);
    let e = flip::Exposures::of(&q);
    // log2(1000) = 9.97: ten exposures.
    assert_eq!(e.stops.len(), 10, "{e:?}");
    assert_eq!(flip::Exposures::of(&flat(2, 2, Vec3::ZERO)).stops, vec![0.0]);
}

#[test]
fn the_peak_is_the_brightest_spot_kept_near_the_references() {
    let mut b = flat(9, 9, Vec3::splat(0.5));
    b.pixels[4 * 9 + 4] = Vec3::splat(100.0);
    let y = Yardstick::new(b.clone(), ToneMap::from_picture(&b, ToneMode::Camera)).unwrap();
    assert_eq!(y.measure(&b).unwrap().peak, 1.0);
    // Smeared: a fifth of it, two pixels off, still counts as a fifth.
    let mut a = flat(9, 9, Vec3::splat(0.5));
    a.pixels[6 * 9 + 4] = Vec3::splat(20.0);
    assert!((y.measure(&a).unwrap().peak - 0.2).abs() < 1e-6);
    // Three pixels off is another spot: only the background is near.
    let mut a = flat(9, 9, Vec3::splat(0.5));
    a.pixels[7 * 9 + 4] = Vec3::splat(100.0);
    assert!((y.measure(&a).unwrap().peak - 0.005).abs() < 1e-6);
}
