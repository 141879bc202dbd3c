use super::*;
use crate::driver::{DriverError, MAX_VIEWPORT_PIXELS};
use crate::splat::SplatDriver;
use crate::store::{Fit, CACHE_DROP_DEGREES};
use crate::testkit::*;
use crate::{DriverStats, Sample};
use glam::DVec3;
use holodeck_protocol::{PictureSizeError, View};
use proptest::prelude::*;
use std::collections::HashMap;

fn px(p: &Picture, col: u32, row: u32) -> Vec3 {
    p.pixels[row as usize * p.width + col as usize]
}

/// Plain means, one estimate per pixel: what the structural tests check.
fn exact() -> EstimatorOptions {
    EstimatorOptions {
        angle_scale: f32::INFINITY,
        firefly_ratio: f32::INFINITY,
        subpixels: 1,
        ..EstimatorOptions::default()
    }
}

fn exact_driver(vp: Viewport) -> QuadtreeDriver {
    QuadtreeDriver::with_options(vp, exact())
}

/// What the store must hold, by brute force: the rays of each pixel in
/// arrival order, each joining, replacing or missing the pixel's surface by
/// the depth rule, and the plain mean of those that count.
fn model(vp: &Viewport, samples: &[Sample]) -> HashMap<(u32, u32), Vec3> {
    let eye = vp.view.position;
    let mut pixels: HashMap<(u32, u32), (f32, f32, Vec<Vec3>)> = HashMap::new();
    for s in samples.iter().filter(|s| s.is_finite()) {
        let Some((c, r, depth)) = vp.pixel(s.target(eye)) else {
            continue;
        };
        let d = if s.hit.is_some() { depth as f32 } else { f32::INFINITY };
        let color = Vec3::from_array(s.color);
        let e = pixels.entry((c, r)).or_insert((d, d, Vec::new()));
        if e.2.is_empty() {
            e.2.push(color);
            continue;
        }
        let tolerance = EstimatorOptions::default().depth_tolerance;
        if d < e.0 * (1.0 - tolerance) {
            *e = (d, d, vec![color]);
        } else if d <= e.1 * (1.0 + tolerance) {
            e.0 = e.0.min(d);
            e.1 = e.1.max(d);
            e.2.push(color);
        }
    }
    pixels
        .into_iter()
        .map(|(k, (_, _, c))| (k, c.iter().sum::<Vec3>() / c.len() as f32))
        .collect()
}

fn close(a: Vec3, b: Vec3) -> bool {
    (a - b).abs().max_element() <= 1e-5 * (1.0 + b.abs().max_element())
}

#[test]
fn every_pixel_shows_the_mean_of_its_rays() {
    let vp = viewport(EYE_VIEW, 128, 96);
    let samples = random_plane_samples(&vp.view, 60_000, 7);
    let mut d = exact_driver(vp.clone());
    d.add(&samples);
    let pic = d.render();
    let want = model(&vp, &samples);
    assert_eq!(d.stats().kept, want.len() as u64);
    assert!(want.len() > 11_000, "most pixels have rays: {}", want.len());
    for (&(c, r), m) in &want {
        assert!(close(px(&pic, c, r), *m), "pixel {c},{r}: {} vs {m}", px(&pic, c, r));
    }
    let st = d.stats();
    assert_eq!(st.received, 60_000);
    assert_eq!(
        st.kept + st.merged + st.replaced + st.discarded + st.outside + st.rejected_nonfinite,
        st.received
    );
    // One plane: every ray of a pixel is on its surface.
    assert_eq!((st.replaced, st.discarded), (0, 0));
    assert_eq!(st.merged, 60_000 - st.kept);
}

#[test]
fn dense_samples_match_the_analytic_image() {
    let vp = viewport(EYE_VIEW, 256, 192);
    let truth = analytic(&vp);
    let mut dense = QuadtreeDriver::new(vp.clone());
    dense.add(&random_plane_samples(&vp.view, 2 * 256 * 192, 11));
    let dense_err = rmse(&dense.render(), &truth);
    let mut sparse = QuadtreeDriver::new(vp.clone());
    sparse.add(&random_plane_samples(&vp.view, 500, 11));
    let sparse_err = rmse(&sparse.render(), &truth);
    // A pixel spans about 0.018 world units on the plane, over which the
    // color changes by under 0.02: the dense image is that close.
    assert!(dense_err < 0.01, "dense RMSE {dense_err}");
    assert!(sparse_err > 2.0 * dense_err, "sparse {sparse_err} vs dense {dense_err}");
    assert!(sparse_err < 0.1, "sparse RMSE {sparse_err}");
}

#[test]
fn sparse_samples_leave_no_black_pixels() {
    let vp = viewport(EYE_VIEW, 200, 150);
    let mut d = QuadtreeDriver::new(vp);
    d.add(&random_plane_samples(&d.viewport().view.clone(), 40, 3));
    assert_eq!(d.stats().kept, 40);
    let pic = d.render();
    assert!(pic.pixels.iter().all(|p| p.min_element() > 0.0));
}

#[test]
fn leaf_boundary_samples_fill_exact_quadrants() {
    let vp = grid_viewport(4, 4);
    let (a, b) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let mut d = exact_driver(vp.clone());
    // (2, 2) is exactly the image center x = y = 0.5: it belongs to the
    // lower-right quadrant. (1, 1) is the corner of the upper-left one.
    d.add(&[
        grid_sample(4, 4, 2.0, 2.0, 5.0, 0.1, b),
        grid_sample(4, 4, 1.0, 1.0, 5.0, 0.1, a),
    ]);
    assert_eq!(vp.pixel(DVec3::new(0.0, 5.0, 0.0)).map(|p| (p.0, p.1)), Some((2, 2)));
    let pic = d.render();
    let mean = (Vec3::from(a) + Vec3::from(b)) / 2.0;
    for row in 0..4 {
        for col in 0..4 {
            let want = match (col >= 2, row >= 2) {
                (false, false) => Vec3::from(a),
                (true, true) => Vec3::from(b),
                _ => mean,
            };
            assert_eq!(px(&pic, col, row), want, "{col},{row}");
        }
    }
    assert_eq!(d.node_count(), 5);
}

#[test]
fn odd_frames_clip_the_power_of_two_root() {
    // A 3 x 3 frame sits in the top-left of a 4 x 4 root: the split is at
    // pixel 2, and the right and bottom quadrants are one pixel thick.
    let vp = grid_viewport(3, 3);
    let (a, b) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let mut d = exact_driver(vp);
    d.add(&[
        grid_sample(3, 3, 0.5, 0.5, 5.0, 0.1, a),
        grid_sample(3, 3, 2.5, 2.5, 5.0, 0.1, b),
    ]);
    let pic = d.render();
    let (a, b, ab) = (Vec3::from(a), Vec3::from(b), Vec3::new(0.5, 0.0, 0.5));
    let want = [[a, a, ab], [a, a, ab], [ab, ab, b]];
    for (row, line) in want.iter().enumerate() {
        for (col, w) in line.iter().enumerate() {
            assert_eq!(px(&pic, col as u32, row as u32), *w, "{col},{row}");
        }
    }
}

#[test]
fn zero_sized_hand_built_viewports_take_nothing() {
    let vp = Viewport {
        view: View::parse(EYE_VIEW).unwrap(),
        width: 0,
        height: 5,
    };
    let mut d = QuadtreeDriver::new(vp.clone());
    let mut s = SplatDriver::new(vp.clone());
    let samples = random_plane_samples(&vp.view, 10, 1);
    d.add(&samples);
    s.add(&samples);
    assert_eq!((d.stats().outside, s.stats().outside), (10, 10));
    assert!(d.render().pixels.is_empty() && s.render().pixels.is_empty());
}

#[test]
fn empty_leaves_average_siblings_recursively() {
    let vp = grid_viewport(4, 4);
    let (a, b, c) = ([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
    let mut d = exact_driver(vp);
    d.add(&[
        grid_sample(4, 4, 0.5, 0.5, 5.0, 0.1, a),
        grid_sample(4, 4, 1.5, 1.5, 5.0, 0.1, b),
        grid_sample(4, 4, 3.5, 3.5, 5.0, 0.1, c),
    ]);
    let pic = d.render();
    // The upper-left quadrant splits into pixels: a, b and two empty
    // pixels with their average; the empty quadrants get the average of
    // that branch's average and c.
    let ab = Vec3::new(0.5, 0.5, 0.0);
    let abc = Vec3::new(0.25, 0.25, 0.5);
    let want = [
        [Vec3::from(a), ab, abc, abc],
        [ab, Vec3::from(b), abc, abc],
        [abc, abc, Vec3::from(c), Vec3::from(c)],
        [abc, abc, Vec3::from(c), Vec3::from(c)],
    ];
    for (row, line) in want.iter().enumerate() {
        for (col, w) in line.iter().enumerate() {
            assert_eq!(px(&pic, col as u32, row as u32), *w, "{col},{row}");
        }
    }
}

#[test]
fn sub_pixels_give_each_side_of_a_silhouette_its_part() {
    // Pixel (1, 1) of a 4 x 4 frame: a near surface on its left half, a far
    // one on its right half, and a far ray hidden behind the near one.
    let (near, far) = ([1.0, 0.0, 0.0], [0.0, 0.0, 1.0]);
    let rays = [
        grid_sample(4, 4, 1.25, 1.25, 2.0, 0.1, near),
        grid_sample(4, 4, 1.25, 1.75, 2.0, 0.1, near),
        grid_sample(4, 4, 1.75, 1.25, 6.0, 0.1, far),
        grid_sample(4, 4, 1.75, 1.75, 6.0, 0.1, far),
        grid_sample(4, 4, 1.3, 1.3, 6.0, 0.1, [9.0; 3]),
    ];
    // One estimate per pixel: the nearest surface takes the whole pixel.
    let mut d = exact_driver(grid_viewport(4, 4));
    d.add(&rays);
    assert_eq!(px(&d.render(), 1, 1), Vec3::from(near));
    let st = d.stats();
    assert_eq!((st.kept, st.merged, st.replaced, st.discarded), (1, 1, 0, 3));
    // Two by two: each half keeps its surface, and the hidden ray stays out.
    let mut d = QuadtreeDriver::with_options(
        grid_viewport(4, 4),
        EstimatorOptions {
            subpixels: 2,
            ..exact()
        },
    );
    d.add(&rays);
    let pic = d.render();
    assert_eq!(px(&pic, 1, 1), (Vec3::from(near) + Vec3::from(far)) / 2.0);
    let st = d.stats();
    assert_eq!((st.kept, st.discarded), (4, 1));
    // The splat baseline draws the same pixel from the same estimates.
    let mut s = SplatDriver::with_options(
        grid_viewport(4, 4),
        EstimatorOptions {
            subpixels: 2,
            ..exact()
        },
    );
    s.add(&rays);
    assert_eq!(px(&s.render(), 1, 1), px(&pic, 1, 1));
}

#[test]
fn rays_join_the_nearest_surface_of_their_pixel() {
    let vp = grid_viewport(8, 8);
    let mut d = exact_driver(vp);
    let ray = |depth: f64, c: f32| grid_sample(8, 8, 3.5, 6.5, depth, 0.1, [c, 1.0, 1.0]);
    // 5.0 starts; 5.05 joins (within 2%); 9.0 is behind and left out; 3.0
    // is nearer and starts over; 3.03 joins; 5.0 is now behind.
    d.add(&[
        ray(5.0, 1.0),
        ray(5.05, 2.0),
        ray(9.0, 50.0),
        ray(3.0, 4.0),
        ray(3.03, 6.0),
        ray(5.0, 7.0),
    ]);
    let st = d.stats();
    assert_eq!((st.kept, st.merged, st.replaced, st.discarded), (1, 2, 1, 2));
    let pic = d.render();
    assert_eq!(px(&pic, 3, 6), Vec3::new(5.0, 1.0, 1.0));
}

#[test]
fn nonfinite_samples_are_rejected_and_counted() {
    let vp = grid_viewport(8, 8);
    let good = grid_sample(8, 8, 1.5, 1.5, 1.0, 0.2, [1.0; 3]);
    let mut bad = Vec::new();
    for f in [f64::NAN, f64::INFINITY, f64::NEG_INFINITY] {
        bad.push(Sample {
            origin: DVec3::new(f, 0.0, 0.0),
            ..good
        });
        bad.push(Sample {
            direction: DVec3::new(0.0, f, 0.0),
            ..good
        });
        bad.push(Sample {
            hit: Some(DVec3::new(0.0, 0.0, f)),
            ..good
        });
        bad.push(Sample {
            color: [1.0, f as f32, 1.0],
            ..good
        });
    }
    let mut d = QuadtreeDriver::new(vp);
    d.add(&bad);
    d.add(&[good]);
    let st = d.stats();
    assert_eq!((st.received, st.rejected_nonfinite, st.kept), (13, 12, 1));
    assert!(d.render().pixels.iter().all(|&p| p == Vec3::ONE));
}

#[test]
fn no_samples_render_black() {
    let mut d = QuadtreeDriver::new(viewport(EYE_VIEW, 33, 17));
    let pic = d.render();
    assert_eq!((pic.width, pic.height, pic.pixels.len()), (33, 17, 33 * 17));
    assert!(pic.pixels.iter().all(|&p| p == Vec3::ZERO));
    assert_eq!(d.stats(), DriverStats::default());
    assert_eq!(d.name(), "quadtree");
}

#[test]
fn one_pixel_viewport_averages_every_ray() {
    let vp = grid_viewport(1, 1);
    let mut d = exact_driver(vp);
    let rays: Vec<Sample> = (0..100)
        .map(|i| grid_sample(1, 1, 0.5, 0.5, 5.0 + 0.0005 * i as f64, 0.1, [i as f32, 1.0, 2.0]))
        .collect();
    d.add(&rays);
    assert_eq!((d.stats().kept, d.stats().merged), (1, 99));
    assert!(close(d.render().pixels[0], Vec3::new(49.5, 1.0, 2.0)));
}

#[test]
fn oversized_and_empty_frames_are_refused() {
    let view = View::parse(EYE_VIEW).unwrap();
    assert!(matches!(
        Viewport::new(view.clone(), 16384, 16384),
        Err(DriverError::FrameSize(PictureSizeError::TooLarge { .. }))
    ));
    assert_eq!(
        Viewport::new(view.clone(), 0, 10),
        Err(DriverError::FrameSize(PictureSizeError::Empty { width: 0, height: 10 }))
    );
    assert!(Viewport::new(view, 8192, 8192).is_ok());
    assert_eq!(MAX_VIEWPORT_PIXELS, 8192 * 8192);
}

#[test]
fn thin_frames_subdivide_along_one_axis() {
    for (w, h) in [(1, 37), (53, 1), (3, 2)] {
        let vp = grid_viewport(w, h);
        let mut d = QuadtreeDriver::new(vp.clone());
        let mut samples = Vec::new();
        for col in 0..w {
            for row in 0..h {
                let color = [col as f32 + 1.0, row as f32 + 1.0, 1.0];
                samples.push(grid_sample(w, h, col as f64 + 0.5, row as f64 + 0.5, 3.0, 0.1, color));
            }
        }
        d.add(&samples);
        assert_eq!(d.stats().kept, u64::from(w * h));
        let pic = d.render();
        for col in 0..w {
            for row in 0..h {
                assert_eq!(px(&pic, col, row), Vec3::new(col as f32 + 1.0, row as f32 + 1.0, 1.0));
            }
        }
    }
}

#[test]
fn outside_and_behind_samples_are_counted() {
    let vp = viewport(EYE_VIEW, 64, 48);
    let mut d = QuadtreeDriver::new(vp);
    let at = |hit: DVec3| Sample {
        origin: DVec3::ZERO,
        direction: hit.normalize(),
        hit: Some(hit),
        color: [1.0; 3],
    };
    // Behind the eye, far to the side, and exactly at the eye.
    d.add(&[at(DVec3::new(0.0, -3.0, 0.0)), at(DVec3::new(10.0, 1.0, 0.0))]);
    d.add(&[Sample {
        hit: Some(DVec3::ZERO),
        ..at(DVec3::Y)
    }]);
    assert_eq!((d.stats().outside, d.stats().kept), (3, 0));
    assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
}

#[test]
fn escaped_rays_stay_put_when_the_eye_moves() {
    let vp = viewport(EYE_VIEW, 64, 48);
    let mut d = QuadtreeDriver::new(vp.clone());
    let (_, dir) = vp.view.ray(0.25, 0.75).unwrap();
    d.add(&[Sample {
        origin: DVec3::new(0.5, 0.0, 0.0),
        direction: dir,
        hit: None,
        color: [0.5, 0.25, 1.0],
    }]);
    let moved = viewport(&format!("{EYE_VIEW} -vp 3 -2 1"), 64, 48);
    d.set_view(moved.clone());
    assert_eq!(d.stats().kept, 1);
    let pic = d.render();
    assert!(pic.pixels.iter().all(|&p| p == Vec3::new(0.5, 0.25, 1.0)));
    assert_eq!(d.stats().cache_drops, 0);
    // Still the same direction, seen from the new eye.
    let e = d.store().entries()[0];
    let (col, row) = crate::store::PixelIndex::pixel(d.store().index(), e.key);
    let sub = d.store().subpixels();
    let (x, y) = (
        (f64::from(col) + 0.5) / f64::from(64 * sub),
        1.0 - (f64::from(row) + 0.5) / f64::from(48 * sub),
    );
    let (_, seen) = moved.view.ray(x, y).unwrap();
    assert!(seen.dot(dir) > 0.9999, "{seen} vs {dir}");
}

/// A grid of plane samples at pixel centers every 6 pixels (so that no
/// small turn makes two share a pixel).
fn spaced_samples(vp: &Viewport) -> Vec<Sample> {
    let mut out = Vec::new();
    for row in (3..vp.height).step_by(6) {
        for col in (3..vp.width).step_by(6) {
            let (x, y) = (
                (f64::from(col) + 0.5) / f64::from(vp.width),
                1.0 - (f64::from(row) + 0.5) / f64::from(vp.height),
            );
            out.extend(plane_sample(&vp.view, x, y, DVec3::new(0.01, 0.0, 0.0)));
        }
    }
    out
}

fn turned(degrees: f64) -> Viewport {
    let (s, c) = degrees.to_radians().sin_cos();
    viewport(&format!("{EYE_VIEW} -vd {s} {c} 0"), 160, 120)
}

#[test]
fn a_large_turn_drops_the_estimates() {
    let vp = turned(0.0);
    let mut d = QuadtreeDriver::new(vp.clone());
    d.add(&spaced_samples(&vp));
    assert!(d.stats().kept > 400);
    const { assert!(CACHE_DROP_DEGREES < 30.0) };
    d.set_view(turned(30.0));
    assert_eq!((d.stats().cache_drops, d.stats().kept, d.cached()), (1, 0, 0));
    assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
    // Nothing left to drop: turning again counts nothing.
    d.set_view(turned(-30.0));
    assert_eq!(d.stats().cache_drops, 1);
}

#[test]
fn a_small_turn_reprojects_and_turning_back_restores() {
    let vp = turned(0.0);
    let samples = spaced_samples(&vp);
    let mut d = exact_driver(vp.clone());
    d.add(&samples);
    let before = d.render();
    let kept = d.stats().kept;
    assert_eq!(kept, samples.len() as u64);
    let five = turned(5.0);
    let still_in = samples
        .iter()
        .filter(|s| five.pixel(s.target(five.view.position)).is_some())
        .count() as u64;
    assert!(still_in < kept && still_in > kept / 2, "{still_in} of {kept}");
    d.set_view(five.clone());
    let st = d.stats();
    assert_eq!((st.kept, st.cache_drops), (still_in, 0));
    assert_eq!(d.cached() as u64, kept);
    // Each estimate is where its ray's hit point is in the new view.
    let pic = d.render();
    for s in &samples {
        if let Some((c, r, _)) = five.pixel(s.target(five.view.position)) {
            assert!(close(px(&pic, c, r), Vec3::from_array(s.color)));
        }
    }
    // Turns are measured step by step: five of 5 degrees drop nothing,
    // and the way back restores the same picture from parked estimates.
    for step in [10.0, 15.0, 20.0, 25.0, 20.0, 10.0] {
        d.set_view(turned(step));
    }
    assert_eq!((d.stats().cache_drops, d.cached() as u64), (0, kept));
    d.set_view(vp.clone());
    assert_eq!(d.stats().kept, kept);
    let after = d.render();
    for (a, b) in after.pixels.iter().zip(&before.pixels) {
        assert!(close(*a, *b), "{a} vs {b}");
    }
}

#[test]
fn a_new_frame_size_rebuilds() {
    let vp = viewport(EYE_VIEW, 64, 48);
    let samples = random_plane_samples(&vp.view, 3000, 9);
    let mut d = QuadtreeDriver::new(vp);
    d.add(&samples);
    let kept = d.stats().kept;
    let big = viewport(EYE_VIEW, 256, 192);
    d.set_view(big.clone());
    assert_eq!(d.viewport(), &big);
    // Each estimate moves whole: as many as before, on finer pixels.
    assert_eq!(d.stats().kept, kept);
    let pic = d.render();
    assert_eq!((pic.width, pic.height), (256, 192));
    assert!(rmse(&pic, &analytic(&big)) < 0.05);
    // And back down: estimates that meet on one pixel merge.
    d.set_view(viewport(EYE_VIEW, 16, 12));
    let sub = u64::from(d.store().subpixels());
    assert!(d.stats().kept <= 16 * 12 * sub * sub);
    let small = d.render();
    assert!(rmse(&small, &analytic(d.viewport())) < 0.05);
}

#[test]
fn every_view_type_draws_without_gaps() {
    let specs = [
        "-vta -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 180 -vv 180",
        "-vta -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 360 -vv 360",
        "-vth -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 180 -vv 180",
        "-vtl -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 3 -vv 2",
        "-vtv -vp 0 0 0 -vd 0 1 0 -vu 0 0 1 -vh 90 -vv 60 -vs 0.3 -vl -0.2",
        // The eye is behind the plane here, looking away from it: nothing.
        "-vtv -vp 0 10 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45",
    ];
    for spec in specs {
        let vp = viewport(spec, 48, 40);
        let samples: Vec<Sample> = random_plane_samples(&View::parse(EYE_VIEW).unwrap(), 2000, 13);
        let mut d = exact_driver(vp.clone());
        d.add(&samples);
        let want = model(&vp, &samples);
        assert_eq!(d.stats().kept, want.len() as u64, "{spec}");
        let pic = d.render();
        for (&(c, r), m) in &want {
            assert!(close(px(&pic, c, r), *m), "{spec}");
        }
        assert_eq!(
            pic.pixels.iter().all(|p| p.min_element() > 0.0),
            !want.is_empty(),
            "{spec}"
        );
    }
}

#[test]
fn clear_forgets_samples_but_not_counts() {
    let vp = viewport(EYE_VIEW, 64, 48);
    let mut d = QuadtreeDriver::new(vp.clone());
    d.add(&random_plane_samples(&vp.view, 100, 1));
    d.clear();
    assert_eq!((d.stats().kept, d.stats().received, d.cached()), (0, 100, 0));
    assert!(d.render().pixels.iter().all(|&p| p == Vec3::ZERO));
    d.add(&random_plane_samples(&vp.view, 1, 2));
    assert_eq!(d.stats().kept, 1);
}

/// Random samples on the exact grid of a 16 x 12 parallel view, some off
/// the frame, some sharing pixels, at depths near and far, all with
/// positive colors.
fn grid_samples() -> impl Strategy<Value = Vec<Sample>> {
    prop::collection::vec(
        (
            -2.0f64..18.0,
            -2.0f64..14.0,
            prop::sample::select(vec![1.0f64, 1.01, 1.5, 3.0]),
            0.0f64..1.0,
            0.01f32..4.0,
            0.01f32..4.0,
        ),
        0..300,
    )
    .prop_map(|v| {
        v.into_iter()
            .map(|(x, y, depth, miss, r, g)| grid_sample(16, 12, x, y, depth, miss, [r, g, 0.5]))
            .collect()
    })
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(128))]

    #[test]
    fn batches_render_like_one_insertion(
        samples in grid_samples(),
        cuts in prop::collection::vec(0usize..300, 0..8),
    ) {
        let vp = grid_viewport(16, 12);
        let mut whole = QuadtreeDriver::new(vp.clone());
        whole.add(&samples);
        let mut cuts: Vec<usize> = cuts.into_iter().map(|c| c.min(samples.len())).collect();
        cuts.push(0);
        cuts.push(samples.len());
        cuts.sort_unstable();
        let mut parts = QuadtreeDriver::new(vp);
        for pair in cuts.windows(2) {
            parts.add(&samples[pair[0]..pair[1]]);
        }
        prop_assert_eq!(whole.stats(), parts.stats());
        prop_assert_eq!(whole.render(), parts.render());
    }

    #[test]
    fn pixels_follow_the_depth_rule_and_nothing_is_black(samples in grid_samples()) {
        let vp = grid_viewport(16, 12);
        let mut d = exact_driver(vp.clone());
        d.add(&samples);
        let want = model(&vp, &samples);
        let st = d.stats();
        prop_assert_eq!(st.kept, want.len() as u64);
        prop_assert_eq!(st.kept + st.merged + st.replaced + st.discarded + st.outside, st.received);
        let pic = d.render();
        for (&(c, r), m) in &want {
            prop_assert!(close(px(&pic, c, r), *m));
        }
        prop_assert_eq!(pic.pixels.iter().all(|p| p.min_element() > 0.0), !want.is_empty());
        prop_assert_eq!(pic.pixels.iter().all(|&p| p == Vec3::ZERO), want.is_empty());
    }

    #[test]
    fn quadtree_agrees_with_splat_where_splat_has_samples(samples in grid_samples()) {
        // With 2 x 2 sub-pixels the quadtree fills a pixel's empty
        // sub-pixels with the mean of the others: the splat's pixel.
        let vp = grid_viewport(16, 12);
        let o = EstimatorOptions { subpixels: 2, ..EstimatorOptions::default() };
        let mut q = QuadtreeDriver::with_options(vp.clone(), o);
        let mut s = SplatDriver::with_options(vp, o);
        q.add(&samples);
        s.add(&samples);
        prop_assert_eq!(q.stats(), s.stats());
        let (qp, sp) = (q.render(), s.render());
        for (a, b) in qp.pixels.iter().zip(&sp.pixels) {
            if *b != Vec3::ZERO {
                prop_assert!(close(*a, *b), "{} vs {}", a, b);
            }
        }
    }
}

/// The depth rule is the estimate's: keep the test model honest.
#[test]
fn the_model_uses_the_stores_tolerance() {
    assert_eq!(EstimatorOptions::default().depth_tolerance, 0.02);
    let e = crate::store::Estimate::of_ray([1.0; 3], 1.0, 1.0, [0.5; 2]);
    assert_eq!(e.fit(0.979, 0.979, 0.02), Fit::Nearer);
    assert_eq!(e.fit(1.021, 1.021, 0.02), Fit::Behind);
}

/// Release-mode timing: `cargo test --release -p holodeck-display --lib
/// quadtree -- --ignored --nocapture --test-threads=1`.
#[test]
#[ignore]
fn timing_quadtree_one_million_samples_at_1024x768() {
    time_driver(|vp| Box::new(QuadtreeDriver::new(vp)));
}
