//! The path tracer against analytic answers.

use glam::{Mat4, Vec3};
use holodeck_sampler::{Material, Rng, SceneBuilder, TraceOptions, Tracer};

/// A closed UV sphere of radius `r` with normals facing inward.
fn inward_sphere(b: &mut SceneBuilder, r: f32, material: u32) {
    let (rings, segments) = (48u32, 96u32);
    let mut p = Vec::new();
    for i in 0..=rings {
        let theta = std::f32::consts::PI * i as f32 / rings as f32;
        for j in 0..segments {
            let phi = std::f32::consts::TAU * j as f32 / segments as f32;
            p.push(Vec3::new(theta.sin() * phi.cos(), theta.sin() * phi.sin(), theta.cos()) * r);
        }
    }
    let mut t = Vec::new();
    for i in 0..rings {
        for j in 0..segments {
            let a = i * segments + j;
            let b2 = i * segments + (j + 1) % segments;
            let (c, d) = (a + segments, b2 + segments);
            // Counter-clockwise seen from inside.
            t.push([a, b2, c]);
            t.push([b2, d, c]);
        }
    }
    b.add_mesh("sphere", &p, &t, &[material], Mat4::IDENTITY).unwrap();
}

fn mean_radiance(tracer: &Tracer, n: u32, seed: u64) -> Vec3 {
    let mut sum = Vec3::ZERO;
    for i in 0..n {
        let mut rng = Rng::new(seed, u64::from(i));
        let (u, v) = rng.f32x2();
        let z = 1.0 - 2.0 * u;
        let r = (1.0 - z * z).sqrt();
        let dir = Vec3::new(
            r * (std::f32::consts::TAU * v).cos(),
            r * (std::f32::consts::TAU * v).sin(),
            z,
        );
        sum += tracer.trace(Vec3::new(0.01, -0.02, 0.03), dir, &mut rng).radiance;
    }
    sum / n as f32
}

#[test]
fn furnace_converges_to_the_analytic_radiance() {
    for (albedo, emission) in [(0.5f32, 1.0f32), (0.8, 0.25)] {
        let mut b = SceneBuilder::new();
        let m = b
            .material(
                "furnace",
                Material::Lambertian {
                    albedo: [albedo; 3],
                    emission: [emission; 3],
                },
            )
            .unwrap();
        inward_sphere(&mut b, 1.0, m);
        let scene = b.finish();
        // With light sampling (NEE + MIS) and without it (BSDF sampling alone):
        // both estimators are unbiased.
        for light_sampling in [true, false] {
            let options = TraceOptions {
                max_bounces: 400,
                light_sampling,
                ..TraceOptions::default()
            };
            let tracer = Tracer::new(scene.clone(), options);
            let expected = emission / (1.0 - albedo);
            let got = mean_radiance(&tracer, 60_000, 1);
            for c in got.to_array() {
                assert!(
                    (c / expected - 1.0).abs() < 0.01,
                    "albedo {albedo}, NEE {light_sampling}: {got} vs {expected}"
                );
            }
            assert_eq!(tracer.non_finite_count(), 0);
        }
    }
}

#[test]
fn estimates_are_deterministic_for_a_seed() {
    let mut b = SceneBuilder::new();
    let m = b
        .material(
            "furnace",
            Material::Lambertian {
                albedo: [0.7; 3],
                emission: [1.0; 3],
            },
        )
        .unwrap();
    inward_sphere(&mut b, 2.0, m);
    let tracer = Tracer::new(b.finish(), TraceOptions::default());
    assert_eq!(mean_radiance(&tracer, 500, 9), mean_radiance(&tracer, 500, 9));
    assert_ne!(mean_radiance(&tracer, 500, 9), mean_radiance(&tracer, 500, 10));
}

#[test]
fn virtual_distance_continues_through_a_flat_mirror() {
    // A mirror facing -x at x = 1, and a white wall facing +x at x = -3.
    let mut b = SceneBuilder::new();
    let mirror = b.material("mirror", Material::Mirror { color: [0.9; 3] }).unwrap();
    let wall = b.material("wall", Material::lambertian([0.5; 3])).unwrap();
    let quad = |x: f32, s: f32| {
        vec![
            Vec3::new(x, -s, -s),
            Vec3::new(x, s, -s),
            Vec3::new(x, s, s),
            Vec3::new(x, -s, s),
        ]
    };
    b.add_mesh(
        "mirror",
        &quad(1.0, 2.0),
        &[[0, 2, 1], [0, 3, 2]],
        &[mirror],
        Mat4::IDENTITY,
    )
    .unwrap();
    b.add_mesh(
        "wall",
        &quad(-3.0, 10.0),
        &[[0, 1, 2], [0, 2, 3]],
        &[wall],
        Mat4::IDENTITY,
    )
    .unwrap();
    let scene = b.finish();
    let plain = Tracer::new(scene.clone(), TraceOptions::default());
    let virt = Tracer::new(
        scene,
        TraceOptions {
            vdistance: true,
            ..TraceOptions::default()
        },
    );
    let mut rng = Rng::new(1, 1);
    assert!((plain.trace(Vec3::ZERO, Vec3::X, &mut rng).distance - 1.0).abs() < 1e-5);
    // 1 m to the mirror, then 4 m back to the wall: the wall's image is 5 m away.
    assert!((virt.trace(Vec3::ZERO, Vec3::X, &mut rng).distance - 5.0).abs() < 1e-4);
    assert_eq!(
        virt.trace(Vec3::ZERO, -Vec3::Y, &mut rng).distance,
        f32::INFINITY,
        "escaped rays"
    );
}

#[test]
fn an_invisible_pane_changes_nothing() {
    // A floor lit by an area light, the sun and sky, seen through (and lit through) a pane of
    // ior 1 and no tint: light sampling through panes and the path's
    // pass-through must agree, so both scenes give the same radiance.
    let sky = holodeck_sampler::Sky::Sun {
        direction: [0.3, 0.2, 0.9],
        sun_radiance: [2e4; 3],
        diameter_deg: 0.53,
        zenith: [0.4; 3],
        horizon: [0.8; 3],
        ground: [0.1; 3],
    };
    let build = |pane: bool| {
        let mut b = SceneBuilder::new();
        let floor = b.material("floor", Material::lambertian([0.6; 3])).unwrap();
        let glass = b
            .material(
                "pane",
                Material::Glass {
                    ior: 1.0,
                    color: [1.0; 3],
                    thin: true,
                },
            )
            .unwrap();
        let big = [
            Vec3::new(-50.0, -50.0, 0.0),
            Vec3::new(50.0, -50.0, 0.0),
            Vec3::new(50.0, 50.0, 0.0),
            Vec3::new(-50.0, 50.0, 0.0),
        ];
        b.add_mesh("floor", &big, &[[0, 1, 2], [0, 2, 3]], &[floor], Mat4::IDENTITY)
            .unwrap();
        // An area light above the pane, facing down: lit through it.
        let lamp = b.material("lamp", Material::Emitter { radiance: [30.0; 3] }).unwrap();
        let quad = [
            Vec3::new(-1.0, -1.0, 6.0),
            Vec3::new(-1.0, 1.0, 6.0),
            Vec3::new(1.0, 1.0, 6.0),
            Vec3::new(1.0, -1.0, 6.0),
        ];
        b.add_mesh("lamp", &quad, &[[0, 1, 2], [0, 2, 3]], &[lamp], Mat4::IDENTITY)
            .unwrap();
        if pane {
            let high = big.map(|p| p + Vec3::Z * 3.0);
            b.add_mesh("pane", &high, &[[0, 1, 2], [0, 2, 3]], &[glass], Mat4::IDENTITY)
                .unwrap();
        }
        b.sky(sky.clone()).unwrap();
        Tracer::new(b.finish(), TraceOptions::default())
    };
    let (open, glazed) = (build(false), build(true));
    let look = |t: &Tracer| {
        let mut sum = Vec3::ZERO;
        for i in 0..40_000u64 {
            let mut rng = Rng::new(3, i);
            sum += t
                .trace(
                    Vec3::new(0.0, 0.0, 1.0),
                    Vec3::new(0.3, 0.1, -1.0).normalize(),
                    &mut rng,
                )
                .radiance;
        }
        sum / 40_000.0
    };
    let (a, b) = (look(&open), look(&glazed));
    assert!(
        (a - b).abs().max_element() < 0.02 * a.max_element(),
        "without pane {a}, with pane {b}"
    );
}

#[test]
fn samples_per_ray_average_independent_estimates() {
    let mut b = SceneBuilder::new();
    let m = b
        .material(
            "furnace",
            Material::Lambertian {
                albedo: [0.6; 3],
                emission: [1.0; 3],
            },
        )
        .unwrap();
    inward_sphere(&mut b, 1.0, m);
    let scene = b.finish();
    let spread = |samples: u32| {
        let tracer = Tracer::new(
            scene.clone(),
            TraceOptions {
                samples,
                ..TraceOptions::default()
            },
        );
        let values: Vec<f32> = (0..2000u64)
            .map(|i| tracer.trace(Vec3::ZERO, Vec3::X, &mut Rng::new(4, i)).radiance.x)
            .collect();
        let mean = values.iter().sum::<f32>() / values.len() as f32;
        let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f32>() / values.len() as f32;
        (mean, var)
    };
    let ((m1, v1), (m16, v16)) = (spread(1), spread(16));
    // Same expectation (2.5 = 1 / (1 - 0.6)); variance falls about 16 times.
    assert!((m1 - 2.5).abs() < 0.1 && (m16 - 2.5).abs() < 0.05, "{m1} {m16}");
    assert!(v1 / v16 > 8.0 && v1 / v16 < 32.0, "variance {v1} -> {v16}");
}

/// Rays traced together (first hits in one packet) give what tracing each
/// in turn gives, bit for bit, drawing from one generator in the same
/// order: nearly parallel rays as a pixel's samples are, rays every way,
/// short batches, and a ray that cannot be traced among them.
#[test]
fn rays_traced_together_give_what_each_gives_in_turn() {
    use holodeck_sampler::scene::gen::{generate, GenParams};
    let room = generate("room", &GenParams::default()).unwrap();
    for (samples, vdistance) in [(1, false), (2, true)] {
        let tracer = Tracer::new(
            room.clone(),
            TraceOptions {
                samples,
                vdistance,
                ..TraceOptions::default()
            },
        );
        let mut pick = Rng::new(5, 6);
        let mut lit = 0;
        for batch in 0..120 {
            let n = [8, 8, 3, 1, 19][batch % 5];
            let eye = Vec3::new(1.0 + 4.0 * pick.f32(), 0.5 + 3.0 * pick.f32(), 0.3 + 1.8 * pick.f32());
            let aim = Vec3::new(pick.f32() - 0.5, pick.f32() - 0.5, pick.f32() - 0.5);
            let mut rays: Vec<(Vec3, Vec3)> = (0..n)
                .map(|_| {
                    let spread = if batch % 3 == 0 { 1.0 } else { 0.01 };
                    let d = Vec3::new(pick.f32() - 0.5, pick.f32() - 0.5, pick.f32() - 0.5) * spread;
                    (eye, aim + d)
                })
                .collect();
            if batch % 10 == 7 {
                rays[n / 2] = (eye, Vec3::ZERO);
            }
            let mut together = Vec::new();
            let mut rng = Rng::new(9, batch as u64);
            tracer.trace_together(&rays, &mut rng, |k, s| together.push((k, s)));
            let mut rng = Rng::new(9, batch as u64);
            let each: Vec<_> = rays
                .iter()
                .enumerate()
                .map(|(k, &(o, d))| (k, tracer.trace(o, d, &mut rng)))
                .collect();
            assert_eq!(together, each, "batch {batch}");
            lit += each.iter().filter(|(_, s)| s.radiance.max_element() > 0.0).count();
        }
        assert!(lit > 300, "{lit} lit");
    }
}
