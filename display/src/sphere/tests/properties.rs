//! Random inputs in the shapes that trouble triangulations, checked
//! against every invariant and a global empty-circumcircle test.

use super::*;

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
