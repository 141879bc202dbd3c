//! Hand-made cases: each shape of input, each promise of the API, and
//! each way validate() must fail.

use super::*;

#[test]
fn octahedron_is_valid() {
    let mesh = SphereMesh::new(0.0);
    mesh.validate().unwrap();
    assert_eq!(
        (mesh.vertex_count(), mesh.real_count(), mesh.triangle_count()),
        (6, 0, 8)
    );
    assert!((0..6).all(|g| mesh.is_ghost(g)));
    assert_eq!(sorted_neighbours(&mesh, 0), vec![2, 3, 4, 5]);
    assert_eq!(mesh.min_angle(), MIN_ANGLE_FLOOR);
}

#[test]
fn min_angle_is_clamped() {
    assert_eq!(SphereMesh::new(f64::NAN).min_angle(), MIN_ANGLE_FLOOR);
    assert_eq!(SphereMesh::new(-1.0).min_angle(), MIN_ANGLE_FLOOR);
    assert_eq!(SphereMesh::new(5.0).min_angle(), MAX_MIN_ANGLE);
    assert_eq!(SphereMesh::new(0.01).min_angle(), 0.01);
}

#[test]
fn four_cocircular_points_ring_the_ghost_inside_their_circle() {
    let dirs = [
        DVec3::new(0.8, 0.0, 0.6),
        DVec3::new(0.0, 0.8, 0.6),
        DVec3::new(-0.8, 0.0, 0.6),
        DVec3::new(0.0, -0.8, 0.6),
    ];
    let mesh = check_run(0.0, &dirs).unwrap();
    assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (10, 16));
    // +z is the centre of their circle: every one of them is its neighbour,
    // and they form a ring around it.
    assert_eq!(sorted_neighbours(&mesh, 4), vec![6, 7, 8, 9]);
    assert_eq!(mesh.neighbours(4).collect::<Vec<_>>().len(), 4);
    for v in 6..10 {
        let n = sorted_neighbours(&mesh, v);
        assert!(n.contains(&4), "vertex {v}: {n:?}");
    }
}

#[test]
fn six_axis_directions_claim_the_ghosts() {
    let mut mesh = SphereMesh::new(1e-4);
    let axes = [
        DVec3::new(3.0, 0.0, 0.0),
        DVec3::new(-1e-300, 0.0, 0.0),
        DVec3::new(0.0, 1e300, 0.0),
        DVec3::new(0.0, -1.0, 0.0),
        DVec3::new(0.0, 0.0, 7.5),
        DVec3::new(0.0, 0.0, -0.25),
    ];
    for (g, &d) in axes.iter().enumerate() {
        assert_eq!(mesh.insert(d), Ok(Insert::Added(g as u32)));
        assert!(!mesh.is_ghost(g as u32));
        assert_eq!(mesh.direction(g as u32), AXES[g]);
    }
    assert_eq!(
        (mesh.vertex_count(), mesh.real_count(), mesh.triangle_count()),
        (6, 6, 8)
    );
    for (g, &d) in axes.iter().enumerate() {
        assert_eq!(mesh.insert(d), Ok(Insert::Duplicate(g as u32)));
        let near = unit(d).unwrap() + DVec3::new(1e-12, -1e-12, 1e-12);
        assert_eq!(mesh.insert(near), Ok(Insert::Duplicate(g as u32)));
    }
    let stats = mesh.stats();
    assert_eq!((stats.insertions, stats.duplicates, stats.flips), (6, 12, 0));
    mesh.validate().unwrap();
}

#[test]
fn a_point_on_an_edge_splits_it_into_four() {
    let mut mesh = SphereMesh::new(0.0);
    // Exactly on the great circle z = 0 between the +x and +y ghosts.
    assert_eq!(mesh.insert(DVec3::new(1.0, 1.0, 0.0)), Ok(Insert::Added(6)));
    mesh.validate().unwrap();
    assert_eq!(mesh.triangle_count(), 10);
    assert_eq!(sorted_neighbours(&mesh, 6), vec![0, 2, 4, 5]);
    assert_eq!(mesh.stats().flips, 0);

    // Inside a face it is three.
    let mut inside = SphereMesh::new(0.0);
    assert_eq!(inside.insert(DVec3::new(1.0, 1.0, 1.0)), Ok(Insert::Added(6)));
    inside.validate().unwrap();
    assert_eq!(sorted_neighbours(&inside, 6), vec![0, 2, 4]);

    // And on an edge between two real vertices of the equator.
    let deg = |d: f64| DVec3::new(d.to_radians().cos(), d.to_radians().sin(), 0.0);
    let mut equator = SphereMesh::new(0.0);
    let mesh = &mut equator;
    assert_eq!(mesh.insert(deg(20.0)), Ok(Insert::Added(6)));
    assert_eq!(mesh.insert(deg(60.0)), Ok(Insert::Added(7)));
    assert!(sorted_neighbours(mesh, 6).contains(&7));
    assert_eq!(mesh.insert(deg(40.0)), Ok(Insert::Added(8)));
    mesh.validate().unwrap();
    let n = sorted_neighbours(mesh, 8);
    assert!(n.contains(&6) && n.contains(&7), "{n:?}");
    assert!(!sorted_neighbours(mesh, 6).contains(&7));
}

#[test]
fn a_perspective_frame_of_directions() {
    // Pixel centres of a 64 × 48 frame looking down -z: rows and columns lie
    // on great circles, so many are collinear on the sphere.
    let (w, h, focal) = (64, 48, 55.0);
    let dirs: Vec<DVec3> = (0..h)
        .flat_map(|y| (0..w).map(move |x| DVec3::new(x as f64 - 31.5, y as f64 - 23.5, -focal)))
        .collect();
    let mesh = check_run(1e-4, &dirs).unwrap();
    assert_eq!(mesh.real_count(), w * h);
    assert_eq!(mesh.triangle_count(), 2 * (w * h + 6) - 4);
    for (k, &d) in dirs.iter().enumerate() {
        let v = (k + GHOSTS) as u32;
        assert!(mesh.locate(d).unwrap().contains(&v), "pixel {k}");
    }
    // An inner pixel's neighbours are pixels around it.
    let v = (GHOSTS + 20 * w + 30) as u32;
    for n in mesh.neighbours(v) {
        let (x, y) = ((n as usize - GHOSTS) % w, (n as usize - GHOSTS) / w);
        assert!(
            x.abs_diff(30) <= 1 && y.abs_diff(20) <= 1,
            "neighbour {n} at ({x}, {y})"
        );
    }
}

#[test]
fn bad_directions_are_errors_and_change_nothing() {
    let mut mesh = SphereMesh::new(0.0);
    mesh.insert(DVec3::new(0.3, 0.4, 0.5)).unwrap();
    let before: Vec<_> = mesh.triangles().collect();
    for (d, e) in [
        (DVec3::new(f64::NAN, 0.0, 1.0), SphereError::NotFinite),
        (DVec3::new(0.0, f64::INFINITY, 1.0), SphereError::NotFinite),
        (DVec3::ZERO, SphereError::Zero),
        (DVec3::new(-0.0, 0.0, -0.0), SphereError::Zero),
    ] {
        assert_eq!(mesh.insert(d), Err(e));
        assert_eq!(mesh.locate(d), Err(e));
    }
    assert_eq!(mesh.triangles().collect::<Vec<_>>(), before);
    assert_eq!(mesh.stats().insertions, 1);
    assert_eq!(unit(DVec3::new(5e-324, 0.0, 0.0)), Ok(DVec3::X));
    assert_eq!(unit(DVec3::new(-1e308, 1e308, 0.0)), unit(DVec3::new(-1.0, 1.0, 0.0)));
}

#[test]
fn a_rejected_direction_changes_nothing() {
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(50, 3) {
        mesh.insert(d).unwrap();
    }
    let before: Vec<_> = mesh.triangles().collect();
    let d = DVec3::new(0.2, -0.7, 0.1);
    let containing = mesh.locate(d).unwrap();
    let mut asked = None;
    let answer = mesh.insert_with(d, |t| {
        asked = Some(t);
        false
    });
    assert_eq!(answer, Ok(Insert::Rejected));
    assert_eq!(asked, Some(containing));
    assert_eq!(mesh.triangles().collect::<Vec<_>>(), before);
    assert_eq!((mesh.vertex_count(), mesh.stats().rejected), (56, 1));
    // A ghost is not claimed against the test either.
    assert_eq!(mesh.insert_with(DVec3::NEG_Y, |_| false), Ok(Insert::Rejected));
    assert!(mesh.is_ghost(3));
    // Accepted, the same direction goes in; duplicates never ask.
    assert_eq!(mesh.insert_with(d, |t| t == containing), Ok(Insert::Added(56)));
    assert_eq!(
        mesh.insert_with(d, |_| panic!("asked for a duplicate")),
        Ok(Insert::Duplicate(56))
    );
    mesh.validate().unwrap();
}

#[test]
fn dense_directions_keep_min_angle_apart_even_when_only_a_flip_shows_the_near_vertex() {
    let mut undone = 0;
    for seed in 0..4 {
        let mut rng = SplitMix(seed);
        let centre = rng.direction();
        let (e1, e2) = frame(centre);
        let dirs: Vec<DVec3> = (0..1500)
            .map(|_| centre + 0.3 * (rng.unit() - 0.5) * e1 + 0.3 * (rng.unit() - 0.5) * e2)
            .collect();
        let mesh = check_run(0.01, &dirs).unwrap();
        separated(&mesh).unwrap();
        undone += mesh.stats().undone;
    }
    // The insertions taken back are the ones this test is about.
    assert!(undone > 0);
}

#[test]
fn neighbours_go_counter_clockwise_around_the_vertex() {
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(300, 9) {
        mesh.insert(d).unwrap();
    }
    let triangles: BTreeSet<[VertexId; 3]> = mesh.triangles().flat_map(|t| [t, [t[1], t[2], t[0]]]).collect();
    let mut edges = 0;
    for v in 0..mesh.vertex_count() as u32 {
        let ring: Vec<_> = mesh.neighbours(v).collect();
        for k in 0..ring.len() {
            let t = [v, ring[k], ring[(k + 1) % ring.len()]];
            let is_triangle = triangles.contains(&t) || triangles.contains(&[t[2], t[0], t[1]]);
            assert!(is_triangle, "{t:?} is not a triangle");
        }
        edges += ring.len();
    }
    assert_eq!(edges, 3 * mesh.triangle_count());
    assert_eq!(mesh.neighbours(10_000).count(), 0);
}

#[test]
fn locate_finds_a_triangle_containing_the_direction() {
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(500, 4) {
        mesh.insert(d).unwrap();
    }
    for p in random_directions(500, 5) {
        let [a, b, c] = mesh.locate(p).unwrap().map(|v| mesh.direction(v));
        assert!(side(a, b, p) >= 0.0 && side(b, c, p) >= 0.0 && side(c, a, p) >= 0.0);
    }
}

#[test]
fn clear_goes_back_to_the_octahedron_and_keeps_memory() {
    let dirs = coherent_directions(5000, 6);
    let mut mesh = SphereMesh::new(0.0);
    insert_all(&mut mesh, &dirs).unwrap();
    let first: Vec<_> = mesh.triangles().collect();
    let bytes = mesh.heap_bytes();
    assert!(bytes >= 5000 * (24 + 4) + 10_000 * 24, "{bytes}");
    mesh.clear();
    assert_eq!(mesh.heap_bytes(), bytes);
    assert_eq!((mesh.vertex_count(), mesh.triangle_count()), (6, 8));
    assert_eq!(mesh.stats(), MeshStats::default());
    mesh.validate().unwrap();
    insert_all(&mut mesh, &dirs).unwrap();
    assert_eq!(mesh.triangles().collect::<Vec<_>>(), first);
    let copy = mesh.clone();
    assert_eq!(copy.triangles().collect::<Vec<_>>(), first);
    assert!(format!("{copy:?}").contains("vertices: 5006"));
}

/// Flips the edge opposite corner `i` of triangle `t`, Delaunay or not.
fn force_flip(mesh: &mut SphereMesh, t: u32, i: usize) {
    let tri = mesh.tris[t as usize];
    let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
    let (p, a, b) = (tri.v[i], tri.v[i1], tri.v[i2]);
    let (u, j) = (tri_of(tri.n[i]), index_of(tri.n[i]));
    let (j1, j2) = ((j + 1) % 3, (j + 2) % 3);
    let ut = mesh.tris[u as usize];
    let d = ut.v[j];
    mesh.tris[t as usize] = Tri {
        v: [p, a, d],
        n: [ut.n[j1], corner(u, 2), tri.n[i2]],
        o: [ut.o[j1], b, tri.o[i2]],
    };
    mesh.tris[u as usize] = Tri {
        v: [p, d, b],
        n: [ut.n[j2], tri.n[i1], corner(t, 1)],
        o: [ut.o[j2], tri.o[i1], a],
    };
    for (at, new, far) in [
        (ut.n[j1], corner(t, 0), p),
        (ut.n[j2], corner(u, 0), p),
        (tri.n[i1], corner(u, 1), d),
        (tri.n[i2], corner(t, 2), d),
    ] {
        mesh.tris[tri_of(at) as usize].n[index_of(at)] = new;
        mesh.tris[tri_of(at) as usize].o[index_of(at)] = far;
    }
    for (v, t) in [(p, t), (a, t), (d, t), (b, u)] {
        mesh.vert_tri[v as usize] = t;
    }
}

#[test]
fn validate_names_what_is_broken() {
    let mut mesh = SphereMesh::new(0.0);
    for d in random_directions(100, 2) {
        mesh.insert(d).unwrap();
    }
    mesh.validate().unwrap();

    // A flip of a Delaunay edge whose quadrilateral is convex.
    let mut flipped = mesh.clone();
    let (t, i) = (0..flipped.tris.len() as u32)
        .flat_map(|t| (0..3).map(move |i| (t, i)))
        .find(|&(t, i)| {
            let tri = flipped.tris[t as usize];
            let d = tri.o[i];
            let [p, a, b] = [tri.v[i], tri.v[(i + 1) % 3], tri.v[(i + 2) % 3]].map(|v| flipped.dirs[v as usize]);
            let d = flipped.dirs[d as usize];
            side(p, a, d) > 0.0 && side(p, d, b) > 0.0 && in_circle(p, a, b, d) < 0.0
        })
        .unwrap();
    force_flip(&mut flipped, t, i);
    let err = flipped.validate().unwrap_err();
    assert!(err.0.contains("not Delaunay"), "{err}");
    assert!(global_delaunay(&flipped).is_err());

    let mut turned = mesh.clone();
    turned.tris[5].v.swap(0, 1);
    assert!(turned.validate().is_err());

    let mut unlinked = mesh.clone();
    let other = unlinked.tris[7].n[0];
    unlinked.tris[7].n[0] = if other == corner(3, 0) {
        corner(4, 0)
    } else {
        corner(3, 0)
    };
    let err = unlinked.validate().unwrap_err();
    assert!(err.0.contains("link"), "{err}");

    let mut lost = mesh.clone();
    lost.vert_tri[40] = lost.tris.iter().position(|t| !t.v.contains(&40)).unwrap() as u32;
    let err = lost.validate().unwrap_err();
    assert!(err.0.contains("vertex 40"), "{err}");
}
