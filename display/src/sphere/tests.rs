use std::collections::BTreeSet;
use std::f64::consts::PI;

use glam::DVec3;
use proptest::prelude::*;

use super::bench::{coherent_directions, random_directions, SplitMix};
use super::predicates::{chord2, in_circle, side, unit};
use super::*;

/// Every vertex against every triangle: none strictly inside a
/// circumcircle. Quadratic: small meshes only.
fn global_delaunay(mesh: &SphereMesh) -> Result<(), String> {
    let dirs: Vec<DVec3> = (0..mesh.vertex_count() as u32).map(|v| mesh.direction(v)).collect();
    for tri in mesh.triangles() {
        let [a, b, c] = tri.map(|v| dirs[v as usize]);
        for (d, &dd) in dirs.iter().enumerate() {
            if !tri.contains(&(d as u32)) && in_circle(a, b, c, dd) > 0.0 {
                return Err(format!("vertex {d} is inside the circumcircle of {tri:?}"));
            }
        }
    }
    Ok(())
}

/// What a run of insertions returned, each answer checked against its promise.
#[derive(Debug, Default)]
struct Tally {
    added: usize,
    duplicates: usize,
}

fn insert_all(mesh: &mut SphereMesh, dirs: &[DVec3]) -> Result<Tally, String> {
    let threshold = chord_threshold(mesh);
    let mut tally = Tally::default();
    for (k, &d) in dirs.iter().enumerate() {
        let p = unit(d).map_err(|e| format!("direction {k} {d}: {e}"))?;
        let before = mesh.vertex_count();
        match mesh.insert(d).map_err(|e| format!("direction {k} {d}: {e}"))? {
            Insert::Added(v) if (v as usize) < GHOSTS => {
                if chord2(p, mesh.direction(v)) > threshold {
                    return Err(format!("direction {k} {p} claimed ghost {v} from too far"));
                }
                if mesh.vertex_count() != before || mesh.is_ghost(v) {
                    return Err(format!(
                        "claiming ghost {v} changed the vertex count or left it a ghost"
                    ));
                }
                tally.added += 1;
            }
            Insert::Added(v) => {
                if v as usize != before || mesh.direction(v) != p {
                    return Err(format!("direction {k} {p} became vertex {v} at {}", mesh.direction(v)));
                }
                tally.added += 1;
            }
            Insert::Duplicate(v) => {
                if mesh.is_ghost(v) || chord2(p, mesh.direction(v)) > threshold {
                    return Err(format!(
                        "direction {k} {p} called a duplicate of vertex {v} at {}, {} radians away",
                        mesh.direction(v),
                        mesh.direction(v).angle_between(p)
                    ));
                }
                if mesh.vertex_count() != before {
                    return Err(format!("duplicate direction {k} changed the vertex count"));
                }
                tally.duplicates += 1;
            }
            Insert::Rejected => return Err(format!("direction {k} rejected without a test")),
        }
    }
    Ok(tally)
}

fn chord_threshold(mesh: &SphereMesh) -> f64 {
    let chord = 2.0 * (0.5 * mesh.min_angle()).sin();
    chord * chord
}

/// No two vertices (unclaimed ghosts included) closer than `min_angle`.
fn separated(mesh: &SphereMesh) -> Result<(), String> {
    let threshold = chord_threshold(mesh);
    let n = mesh.vertex_count() as u32;
    for a in 0..n {
        for b in a + 1..n {
            if chord2(mesh.direction(a), mesh.direction(b)) <= threshold {
                return Err(format!("vertices {a} and {b} are within min_angle"));
            }
        }
    }
    Ok(())
}

/// The full set of checks for a mesh built from `dirs`.
fn check_run(min_angle: f64, dirs: &[DVec3]) -> Result<SphereMesh, String> {
    let mut mesh = SphereMesh::new(min_angle);
    let tally = insert_all(&mut mesh, dirs)?;
    mesh.validate()?;
    let stats = mesh.stats();
    if tally.added + tally.duplicates != dirs.len()
        || mesh.real_count() != tally.added
        || stats.insertions as usize != tally.added
        || stats.duplicates as usize != tally.duplicates
        || stats.rejected != 0
    {
        return Err(format!(
            "{} directions, {tally:?}, real {}, {stats:?}",
            dirs.len(),
            mesh.real_count()
        ));
    }
    if mesh.vertex_count() <= 400 {
        global_delaunay(&mesh)?;
        separated(&mesh)?;
    }
    Ok(mesh)
}

fn sorted_neighbours(mesh: &SphereMesh, v: VertexId) -> Vec<VertexId> {
    let mut n: Vec<_> = mesh.neighbours(v).collect();
    n.sort_unstable();
    n
}

/// Unit vectors perpendicular to `c` and to each other.
fn frame(c: DVec3) -> (DVec3, DVec3) {
    let e1 = c.any_orthonormal_vector();
    (e1, c.cross(e1))
}

/// `k` points at equal angles on the circle `radius` radians around `center`.
fn circle(center: DVec3, radius: f64, k: usize) -> Vec<DVec3> {
    let c = center.normalize();
    let (e1, e2) = frame(c);
    (0..k)
        .map(|i| {
            let t = 2.0 * PI * i as f64 / k as f64;
            radius.cos() * c + radius.sin() * (t.cos() * e1 + t.sin() * e2)
        })
        .collect()
}

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
    assert!(err.contains("not Delaunay"), "{err}");
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
    assert!(err.contains("link"), "{err}");

    let mut lost = mesh.clone();
    lost.vert_tri[40] = lost.tris.iter().position(|t| !t.v.contains(&40)).unwrap() as u32;
    let err = lost.validate().unwrap_err();
    assert!(err.contains("vertex 40"), "{err}");
}

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

/// A group of directions in one of the shapes that trouble triangulations.
#[derive(Clone, Debug)]
enum Piece {
    Uniform {
        seed: u64,
        count: usize,
    },
    /// Around `centre`, spread 10^-`tenths` radians.
    Cluster {
        centre: DVec3,
        spread: i32,
        seed: u64,
        count: usize,
    },
    /// Equal angles on a circle: cocircular.
    Circle {
        centre: DVec3,
        radius: f64,
        count: usize,
    },
    /// Points on the equator, exactly on its plane: collinear on a great
    /// circle, and on the ghosts' edges.
    Equator {
        seed: u64,
        count: usize,
    },
    /// On a tilted great circle.
    GreatCircle {
        normal: DVec3,
        seed: u64,
        count: usize,
    },
    Antipodal(DVec3),
    /// An axis, nudged by `offset`.
    Axis {
        axis: usize,
        offset: f64,
        seed: u64,
    },
    /// An earlier direction again, scaled (-1: its antipode).
    Repeat {
        index: prop::sample::Index,
        scale: f64,
    },
}

fn direction() -> impl Strategy<Value = DVec3> {
    (-1.0f64..1.0, -1.0f64..1.0, -1.0f64..1.0)
        .prop_map(|(x, y, z)| DVec3::new(x, y, z))
        .prop_filter("non-zero", |d| d.length() > 1e-3)
}

fn scale() -> impl Strategy<Value = f64> {
    prop_oneof![Just(1.0), Just(1e-300), Just(1e300), Just(3.7), Just(1e-10), Just(2.0)]
}

fn piece() -> impl Strategy<Value = Piece> {
    prop_oneof![
        (any::<u64>(), 1usize..40).prop_map(|(seed, count)| Piece::Uniform { seed, count }),
        (direction(), 1i32..9, any::<u64>(), 2usize..30).prop_map(|(centre, spread, seed, count)| Piece::Cluster {
            centre,
            spread,
            seed,
            count
        }),
        (direction(), 1e-4f64..1.6, 3usize..13).prop_map(|(centre, radius, count)| Piece::Circle {
            centre,
            radius,
            count
        }),
        (any::<u64>(), 1usize..20).prop_map(|(seed, count)| Piece::Equator { seed, count }),
        (direction(), any::<u64>(), 2usize..20).prop_map(|(normal, seed, count)| Piece::GreatCircle {
            normal,
            seed,
            count
        }),
        direction().prop_map(Piece::Antipodal),
        (
            0usize..6,
            prop_oneof![Just(0.0), Just(1e-12), Just(1e-9), Just(1e-5), Just(1e-3)],
            any::<u64>()
        )
            .prop_map(|(axis, offset, seed)| Piece::Axis { axis, offset, seed }),
        (
            any::<prop::sample::Index>(),
            prop_oneof![Just(1.0), Just(0.5), Just(3.7), Just(-1.0)]
        )
            .prop_map(|(index, scale)| Piece::Repeat { index, scale }),
    ]
}

fn build(pieces: &[Piece], scales: &[f64]) -> Vec<DVec3> {
    let mut dirs: Vec<DVec3> = Vec::new();
    for piece in pieces {
        match piece {
            Piece::Uniform { seed, count } => dirs.extend(random_directions(*count, *seed)),
            Piece::Cluster {
                centre,
                spread,
                seed,
                count,
            } => {
                let mut rng = SplitMix(*seed);
                let c = centre.normalize();
                let s = 10f64.powi(-spread);
                dirs.extend((0..*count).map(|_| c + s * (rng.direction() * rng.unit())));
            }
            Piece::Circle { centre, radius, count } => dirs.extend(circle(*centre, *radius, *count)),
            Piece::Equator { seed, count } => {
                let mut rng = SplitMix(*seed);
                dirs.extend((0..*count).map(|_| {
                    let t = 2.0 * PI * rng.unit();
                    DVec3::new(t.cos(), t.sin(), 0.0)
                }));
            }
            Piece::GreatCircle { normal, seed, count } => {
                let mut rng = SplitMix(*seed);
                let (e1, e2) = frame(normal.normalize());
                dirs.extend((0..*count).map(|_| {
                    let t = 2.0 * PI * rng.unit();
                    t.cos() * e1 + t.sin() * e2
                }));
            }
            Piece::Antipodal(d) => dirs.extend([*d, -*d]),
            Piece::Axis { axis, offset, seed } => {
                let mut rng = SplitMix(*seed);
                dirs.push(AXES[*axis] + *offset * rng.direction());
            }
            Piece::Repeat { index, scale } => {
                if !dirs.is_empty() {
                    let d = dirs[index.index(dirs.len())];
                    dirs.push(d * *scale);
                }
            }
        }
    }
    for (k, d) in dirs.iter_mut().enumerate() {
        *d *= scales[k % scales.len()];
    }
    dirs
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(200))]

    #[test]
    fn any_insertions_keep_a_valid_delaunay_mesh(
        pieces in prop::collection::vec(piece(), 1..10),
        scales in prop::collection::vec(scale(), 1..4),
        min_angle in prop_oneof![Just(0.0), Just(1e-5), Just(1e-3), Just(0.05)],
    ) {
        let dirs = build(&pieces, &scales);
        if let Err(e) = check_run(min_angle, &dirs) {
            return Err(TestCaseError::fail(e));
        }
    }

    #[test]
    fn insertion_order_does_not_matter_for_general_positions(seed in any::<u64>(), count in 4usize..80) {
        // Random points have one Delaunay triangulation, whatever the order.
        let dirs = random_directions(count, seed);
        let forward = check_run(0.0, &dirs).map_err(TestCaseError::fail)?;
        let mut reversed: Vec<_> = dirs.iter().rev().copied().collect();
        reversed.rotate_left(count / 3);
        let backward = check_run(0.0, &reversed).map_err(TestCaseError::fail)?;
        let edges = |mesh: &SphereMesh| {
            let id = |v: VertexId| mesh.direction(v);
            let mut set = BTreeSet::new();
            for t in mesh.triangles() {
                for k in 0..3 {
                    let (a, b) = (id(t[k]).to_array().map(f64::to_bits), id(t[(k + 1) % 3]).to_array().map(f64::to_bits));
                    set.insert(if a < b { (a, b) } else { (b, a) });
                }
            }
            set
        };
        prop_assert_eq!(edges(&forward), edges(&backward));
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
