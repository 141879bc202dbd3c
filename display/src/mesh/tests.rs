use super::*;
use crate::quadtree::QuadtreeDriver;
use crate::testkit::*;

#[test]
fn mesh_error_falls_as_rays_are_added_and_beats_the_quadtree_on_a_smooth_surface() {
    let vp = viewport(EYE_VIEW, 96, 64);
    let truth = analytic(&vp);
    let samples = random_plane_samples(&vp.view, 30_000, 5);
    let mut mesh = MeshDriver::new(gpu(), vp.clone(), EstimatorOptions::default());
    let mut quad = QuadtreeDriver::new(vp.clone());
    let mut errors = Vec::new();
    let mut added = 0;
    for n in [300, 3_000, 30_000] {
        mesh.add(&samples[added..n]);
        quad.add(&samples[added..n]);
        added = n;
        let (m, q) = (rmse(&mesh.render(), &truth), rmse(&quad.render(), &truth));
        println!("{n} rays: mesh {m:.4}, quadtree {q:.4}");
        errors.push(m);
        assert!(m < q, "{n} rays: mesh {m} quadtree {q}");
    }
    assert!(errors[0] > errors[1] && errors[1] > errors[2], "{errors:?}");
    let s = mesh.mesh_stats();
    assert!(s.vertices > 1000 && s.drawn > 1000, "{s:?}");
    assert!(s.flips_per_insertion > 1.0 && s.flips_per_insertion < 5.0, "{s:?}");
}

#[test]
fn a_small_move_keeps_the_mesh_and_a_large_one_rebuilds_it() {
    let vp = viewport(EYE_VIEW, 80, 60);
    let samples = random_plane_samples(&vp.view, 20_000, 8);
    let mut mesh = MeshDriver::new(gpu(), vp.clone(), EstimatorOptions::default());
    mesh.add(&samples);
    let mut quad = QuadtreeDriver::new(vp.clone());
    quad.add(&samples);
    mesh.render();
    let inserted = mesh.mesh_stats().inserted;
    // Turn 2 degrees: the estimates keep their vertices.
    let turned = viewport(&format!("{EYE_VIEW} -vd 0.035 1 0"), 80, 60);
    mesh.set_view(turned.clone());
    quad.set_view(turned.clone());
    let truth = analytic(&turned);
    let (after, quad_after) = (rmse(&mesh.render(), &truth), rmse(&quad.render(), &truth));
    let s = mesh.mesh_stats();
    assert_eq!(s.rebuilds, 0);
    assert!(
        s.inserted - inserted < inserted / 10,
        "{} new insertions after a small turn",
        s.inserted - inserted
    );
    // The strip the turn brings in has no samples: both fill it alike.
    assert!(after < 1.2 * quad_after, "mesh {after} quadtree {quad_after}");
    // Step a meter sideways (a quarter of the depth): a new canonical eye.
    let moved = viewport("-vtv -vp 1 0 0 -vd 0 1 0 -vu 0 0 1 -vh 60 -vv 45", 80, 60);
    mesh.set_view(moved);
    mesh.render();
    assert_eq!(mesh.mesh_stats().rebuilds, 1);
}

#[test]
fn likely_multidepth_estimates_are_rejected_from_their_neighbours_depths() {
    let vp = viewport(EYE_VIEW, 120, 90);
    let truth = occluded_truth(&vp);
    let band = edge_band(&truth, 2, 0.1);
    let samples = occluded_samples(&vp.view, 20_000, 0.6, 13);
    let mut mesh = MeshDriver::new(gpu(), vp.clone(), EstimatorOptions::default());
    mesh.add(&samples);
    let pic = mesh.render();
    let s = mesh.mesh_stats();
    let all = vec![true; band.len()];
    println!(
        "{s:?}; band RMSE {:.4}, frame {:.4}",
        masked_rmse(&pic, &truth, &band),
        masked_rmse(&pic, &truth, &all)
    );
    assert!(s.multidepth > 0, "{s:?}");
    assert!(masked_rmse(&pic, &truth, &all) < 0.15);
}
