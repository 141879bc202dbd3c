use super::*;
use crate::geometry::Geometry;
use crate::splat::SplatDriver;
use crate::testkit::*;

fn exact() -> EstimatorOptions {
    EstimatorOptions {
        angle_scale: f32::INFINITY,
        firefly_ratio: f32::INFINITY,
        subpixels: 1,
        ..EstimatorOptions::default()
    }
}

#[test]
fn a_full_frame_of_cones_draws_exactly_what_the_cpu_splat_draws() {
    // One estimate per pixel: every pixel's nearest apex is its own, so the
    // GPU picture must be the CPU splat picture.
    let (w, h) = (48, 32);
    let vp = grid_viewport(w, h);
    let mut samples = Vec::new();
    for row in 0..h {
        for col in 0..w {
            let c = [col as f32 / 7.0, row as f32 / 5.0, ((col * row) % 11) as f32 * 0.3];
            samples.push(grid_sample(
                w,
                h,
                f64::from(col) + 0.3,
                f64::from(row) + 0.6,
                5.0,
                0.0,
                c,
            ));
        }
    }
    let mut gpu_driver = VoronoiDriver::new(gpu(), vp.clone(), exact(), None);
    let mut cpu = SplatDriver::with_options(vp, exact());
    gpu_driver.add(&samples);
    cpu.add(&samples);
    let (a, b) = (gpu_driver.render(), cpu.render());
    let worst = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| (*p - *q).abs().max_element() / q.max_element().max(1e-3))
        .fold(0.0f32, f32::max);
    assert!(worst < 1e-6, "largest relative difference {worst}");
    assert_eq!(
        gpu_driver.cones_by_fan()[0],
        w * h,
        "dense estimates draw the smallest fans"
    );
}

#[test]
fn voronoi_error_falls_as_rays_are_added_and_beats_the_splat_when_sparse() {
    let vp = viewport(EYE_VIEW, 96, 64);
    let truth = analytic(&vp);
    let samples = random_plane_samples(&vp.view, 40_000, 3);
    let mut d = VoronoiDriver::new(gpu(), vp.clone(), EstimatorOptions::default(), None);
    let mut errors = Vec::new();
    let mut added = 0;
    for n in [300, 3_000, 40_000] {
        d.add(&samples[added..n]);
        added = n;
        errors.push(rmse(&d.render(), &truth));
    }
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    assert!(errors[2] < 0.02, "{errors:?}");
    let mut splat = SplatDriver::new(vp.clone());
    splat.add(&samples[..300]);
    let sparse_splat = rmse(&splat.render(), &truth);
    assert!(
        errors[0] < 0.5 * sparse_splat,
        "voronoi {} splat {sparse_splat}",
        errors[0]
    );
    // Few estimates: large cones with more triangles.
    let mut sparse = VoronoiDriver::new(gpu(), vp, EstimatorOptions::default(), None);
    sparse.add(&samples[..50]);
    sparse.render();
    let fans = sparse.cones_by_fan();
    assert!(fans[2] + fans[3] > 0, "{fans:?}");
}

#[test]
fn geometry_culls_multidepth_estimates_and_sharpens_silhouettes() {
    let vp = viewport(EYE_VIEW, 120, 90);
    let truth = occluded_truth(&vp);
    let band = edge_band(&truth, 2, 0.1);
    assert!(band.iter().filter(|b| **b).count() > 300);
    let samples = occluded_samples(&vp.view, 4_000, 0.6, 11);
    let geometry = Geometry::new(&occluded_triangles(), 1000, None);
    let mut with = VoronoiDriver::new(gpu(), vp.clone(), EstimatorOptions::default(), Some(&geometry));
    let mut without = VoronoiDriver::new(gpu(), vp.clone(), EstimatorOptions::default(), None);
    assert!(with.has_geometry() && !without.has_geometry());
    with.add(&samples);
    without.add(&samples);
    let (a, b) = (with.render(), without.render());
    let (band_with, band_without) = (masked_rmse(&a, &truth, &band), masked_rmse(&b, &truth, &band));
    let all = vec![true; band.len()];
    let (all_with, all_without) = (masked_rmse(&a, &truth, &all), masked_rmse(&b, &truth, &all));
    println!("silhouette band RMSE: {band_with:.4} with geometry, {band_without:.4} without; whole frame {all_with:.4} / {all_without:.4}");
    assert!(band_with < 0.7 * band_without, "{band_with} vs {band_without}");
    assert!(all_with < all_without, "{all_with} vs {all_without}");
}
