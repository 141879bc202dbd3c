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
