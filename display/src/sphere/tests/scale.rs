//! Large inputs: the counters of a million random insertions and of
//! pixel-order ones, and what makes location fast.

use super::*;

#[test]
fn a_million_random_insertions() {
    let n = 1_000_000;
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(n, 1) {
        mesh.insert(d).unwrap();
    }
    mesh.validate().unwrap();
    let stats = mesh.stats();
    assert_eq!((stats.insertions + stats.duplicates) as usize, n);
    assert_eq!(mesh.real_count(), stats.insertions as usize);
    // Random points in general position: the new vertex ends with about six
    // neighbours, three from the split and one per flip.
    let flips = stats.flips_per_insertion();
    assert!((2.7..3.2).contains(&flips), "{flips} flips per insertion");
    // The grid keeps walks short.
    let steps = stats.steps_per_location();
    assert!(steps < 4.0, "{steps} steps per location");
    // About 100 bytes per vertex, plus what growing vectors keep spare.
    let per_vertex = mesh.heap_bytes() / mesh.vertex_count();
    assert!((100..160).contains(&per_vertex), "{per_vertex} bytes per vertex");
}

#[test]
fn coherent_insertions() {
    let n = 200_000;
    let dirs = coherent_directions(n, 8);
    assert_eq!(dirs.len(), n);
    let mut mesh = SphereMesh::new(0.0);
    insert_all(&mut mesh, &dirs).unwrap();
    mesh.validate().unwrap();
    let stats = mesh.stats();
    assert_eq!(stats.insertions as usize + stats.duplicates as usize, n);
    // In pixel order each new vertex sits on the edge of the filled region,
    // where long thin triangles still reach across the empty part: it
    // starts with more neighbours than a random one (measured: 5.1).
    let flips = stats.flips_per_insertion();
    assert!((4.0..6.0).contains(&flips), "{flips} flips per insertion");
    let steps = stats.steps_per_location();
    assert!(steps < 4.0, "{steps} steps per location");
}

#[test]
fn bench_insertions_reports_its_mesh() {
    for coherent in [false, true] {
        let (secs, stats) = bench_insertions(2000, coherent, 11);
        assert!(secs > 0.0);
        assert_eq!(stats.insertions + stats.duplicates, 2000);
        assert!(stats.flips > 0 && stats.locations >= 2000);
    }
}

#[test]
fn the_grid_starts_walks_near_the_direction() {
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(50_000, 12) {
        mesh.insert(d).unwrap();
    }
    let width = mesh.grid.cell_chord2().sqrt();
    for p in random_directions(5000, 13) {
        let v = mesh.grid.get(p);
        let angle = mesh.direction(v).angle_between(p);
        assert!(
            angle < 4.0 * width,
            "{p}: vertex {v} is {angle} away, cells are {width} wide"
        );
    }
}

#[test]
fn many_insertions_in_hilbert_order_make_the_same_mesh() {
    let n = 200_000;
    let dirs = random_directions(n, 21);
    let mut one_by_one = SphereMesh::new(0.0);
    for &d in &dirs {
        one_by_one.insert(d).unwrap();
    }
    let mut sorted = SphereMesh::new(0.0);
    let got = sorted.insert_many(&dirs);
    sorted.validate().unwrap();
    assert_eq!(got.len(), n);
    // Every direction is a vertex (random directions are never within the
    // floor of each other), found where it was given.
    for (d, r) in dirs.iter().zip(&got) {
        let Ok(Insert::Added(v)) = r else {
            panic!("{d}: {r:?}");
        };
        assert_eq!(sorted.direction(*v), unit(*d).unwrap());
    }
    // The Delaunay triangulation is unique: the same triangles, by direction.
    let triangles = |m: &SphereMesh| {
        let mut t: Vec<[[u64; 3]; 3]> = m
            .triangles()
            .map(|tri| {
                let mut c = tri.map(|v| m.direction(v).to_array().map(f64::to_bits));
                c.sort();
                c
            })
            .collect();
        t.sort();
        t
    };
    assert_eq!(triangles(&sorted), triangles(&one_by_one));
    // In Hilbert order each walk is a step or two.
    let steps = sorted.stats().steps_per_location();
    assert!(steps < 2.5, "{steps} steps per location");
}

#[test]
fn hilbert_keys_follow_the_curve() {
    // The curve visits the four quadrants of a face in order: lower left,
    // upper left, upper right, lower right (x right, y up).
    let face = |u: f64, v: f64| order::hilbert_key(DVec3::new(1.0, u, v));
    let quadrants = [face(-0.5, -0.5), face(-0.5, 0.5), face(0.5, 0.5), face(0.5, -0.5)];
    assert!(quadrants.windows(2).all(|w| w[0] < w[1]), "{quadrants:?}");
    // Neighbouring cells along the curve are neighbours on the face: the
    // keys of a fine grid, sorted, step one cell at a time.
    let n = 64;
    let mut cells: Vec<(u64, (i32, i32))> = (0..n)
        .flat_map(|i| (0..n).map(move |j| (i, j)))
        .map(|(i, j)| {
            let c = |k: i32| (f64::from(k) + 0.5) / f64::from(n) * 2.0 - 1.0;
            (face(c(i), c(j)), (i, j))
        })
        .collect();
    cells.sort();
    for w in cells.windows(2) {
        let ((a, b), (c, d)) = (w[0].1, w[1].1);
        assert_eq!((a - c).abs() + (b - d).abs(), 1, "{:?} then {:?}", w[0], w[1]);
    }
    // Each axis's faces apart, and what is not a direction last.
    assert_ne!(
        order::hilbert_key(DVec3::X) >> 32,
        order::hilbert_key(DVec3::NEG_X) >> 32
    );
    assert_eq!(order::hilbert_key(DVec3::ZERO), u64::MAX);
    assert_eq!(order::hilbert_key(DVec3::new(f64::NAN, 0.0, 1.0)), u64::MAX);
}
