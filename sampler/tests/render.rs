//! The reference renderer on the built-in room: its error against a
//! high-sample render falls as the sample count grows, at the Monte Carlo rate.

use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;

use holodeck_protocol::View;
use holodeck_sampler::accel::{Hit, RayCaster, WideBvh};
use holodeck_sampler::geom::Ray;
use holodeck_sampler::render::{render, PictureSizeError, RenderError, RenderOptions};
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::{TraceOptions, Tracer};

/// Independent seeds each error is averaged over: squared error has heavy
/// tails (a rare bright path in a dim pixel), and three seeds let one such
/// path decide a ratio.
const SEEDS: u64 = 12;

#[test]
fn room_error_halves_when_samples_double() {
    // Without the sun: sunlight focused by the glass sphere makes caustics that
    // plain path tracing finds only by chance, and their fireflies would set a
    // noise floor even in the reference. The ceiling light and the sky remain.
    let mut scene = generate("room", &GenParams::default()).unwrap();
    scene.sky = holodeck_sampler::Sky::Constant {
        radiance: [0.8, 0.85, 0.9],
    };
    let tracer = Tracer::new(
        scene,
        TraceOptions {
            max_bounces: 4,
            ..TraceOptions::default()
        },
    );
    let view = View::parse("-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56").unwrap();
    let opts = |spp, seed| RenderOptions {
        width: 40,
        height: 30,
        spp,
        seed,
    };
    let none = |_: usize, _: usize| {};
    let reference = render(&tracer, &view, &opts(1024, 99), &none).unwrap();
    assert!(reference.mean_luminance() > 0.01, "the room is lit");
    let mse = |spp: u32| -> f64 {
        (0..SEEDS)
            .map(|s| {
                render(&tracer, &view, &opts(spp, s), &none)
                    .unwrap()
                    .mse(&reference)
                    .unwrap()
            })
            .sum::<f64>()
            / SEEDS as f64
    };
    let (e4, e8, e16) = (mse(4), mse(8), mse(16));
    for (lo, hi) in [(e4, e8), (e8, e16)] {
        let ratio = lo / hi;
        assert!(
            (1.4..3.0).contains(&ratio),
            "MSE {e4:.3e} {e8:.3e} {e16:.3e}: ratio {ratio:.2}"
        );
    }
    assert_eq!(tracer.non_finite_count(), 0);
}

#[test]
fn impossible_sizes_and_zero_samples_are_refused_before_allocating() {
    let tracer = Tracer::new(
        generate("room", &GenParams::default()).unwrap(),
        TraceOptions::default(),
    );
    let view = View::default();
    let run = |width, height, spp| {
        render(
            &tracer,
            &view,
            &RenderOptions {
                width,
                height,
                spp,
                seed: 1,
            },
            &|_, _| {},
        )
    };
    assert!(matches!(
        run(4_000_000_000, 1, 1),
        Err(RenderError::Size(PictureSizeError::TooLarge { .. }))
    ));
    assert!(matches!(
        run(0, 10, 1),
        Err(RenderError::Size(PictureSizeError::Empty { .. }))
    ));
    assert_eq!(run(2, 2, 0).err(), Some(RenderError::NoSamples));
    let p = run(3, 2, 1).unwrap();
    assert_eq!((p.width, p.height, p.pixels.len()), (3, 2, 6));
}

/// A ray caster standing in for the tracer's own: the same wide BVH, built
/// on its own, counting what it is asked.
struct Counting {
    bvh: WideBvh,
    nearest: AtomicUsize,
    occluded: AtomicUsize,
}

impl RayCaster for Counting {
    fn intersect(&self, ray: &Ray) -> Option<Hit> {
        self.nearest.fetch_add(1, Ordering::Relaxed);
        self.bvh.intersect(ray)
    }

    fn occluded_by(&self, ray: &Ray, blocks: &mut dyn FnMut(u32) -> bool) -> bool {
        self.occluded.fetch_add(1, Ordering::Relaxed);
        self.bvh.occluded_by(ray, blocks)
    }
}

/// With a stand-in caster every ray the path tracer casts goes through it
/// (first hits one at a time instead of in packets, shadow rays through the
/// window's panes, bounces), and the picture is the very same, bit for bit.
#[test]
fn a_stand_in_caster_renders_the_same_picture() {
    let scene = generate("room", &GenParams::default()).unwrap();
    let options = TraceOptions {
        max_bounces: 2,
        ..TraceOptions::default()
    };
    let counting = Arc::new(Counting {
        bvh: WideBvh::build(&scene).unwrap(),
        nearest: AtomicUsize::new(0),
        occluded: AtomicUsize::new(0),
    });
    let own = Tracer::new(scene.clone(), options);
    let caster = holodeck_sampler::Caster::outside(&scene, counting.clone());
    let stand_in = Tracer::with_caster(scene, caster, options);
    let view = View::parse("-vtv -vp 0.7 2 1.5 -vd 1 0 -0.1 -vu 0 0 1 -vh 75 -vv 56").unwrap();
    let opts = RenderOptions {
        width: 32,
        height: 24,
        spp: 8,
        seed: 3,
    };
    let none = |_: usize, _: usize| {};
    let a = render(&own, &view, &opts, &none).unwrap();
    assert_eq!(counting.nearest.load(Ordering::Relaxed), 0);
    let b = render(&stand_in, &view, &opts, &none).unwrap();
    assert!(a.mean_luminance() > 0.01, "the room is lit");
    assert!(a.pixels == b.pixels, "the pictures differ");
    let (nearest, occluded) = (
        counting.nearest.load(Ordering::Relaxed),
        counting.occluded.load(Ordering::Relaxed),
    );
    // Every sample's first hit, and more for the bounces; shadow rays.
    assert!(nearest > 32 * 24 * 8 && occluded > 32 * 24 * 8, "{nearest} {occluded}");
}

#[test]
fn a_radiance_view_line_clips_a_near_object_and_the_far_wall() {
    use glam::{Mat4, Vec3};
    use holodeck_sampler::{Material, SceneBuilder, Sky};
    // A black card 2 m ahead hides a white wall 10 m ahead; a sky lights the wall.
    let mut b = SceneBuilder::new();
    let black = b.material("black", Material::lambertian([0.0; 3])).unwrap();
    let white = b.material("white", Material::lambertian([0.8; 3])).unwrap();
    let quad = |x: f32, r: f32| {
        [
            Vec3::new(x, -r, -r),
            Vec3::new(x, r, -r),
            Vec3::new(x, r, r),
            Vec3::new(x, -r, r),
        ]
    };
    b.add_mesh(
        "card",
        &quad(2.0, 3.0),
        &[[0, 1, 2], [0, 2, 3]],
        &[black],
        Mat4::IDENTITY,
    )
    .unwrap();
    b.add_mesh(
        "wall",
        &quad(10.0, 50.0),
        &[[0, 2, 1], [0, 3, 2]],
        &[white],
        Mat4::IDENTITY,
    )
    .unwrap();
    b.sky(Sky::Constant { radiance: [1.0; 3] }).unwrap();
    let tracer = Tracer::new(b.finish(), TraceOptions::default());
    let opts = RenderOptions {
        width: 6,
        height: 6,
        spp: 4,
        seed: 1,
    };
    let mean = |line: &str| {
        let view = View::parse(line).unwrap();
        render(&tracer, &view, &opts, &|_, _| {}).unwrap().mean_luminance()
    };
    let base = "rview -vtv -vp 0 0 0 -vd 1 0 0 -vu 0 0 1 -vh 40 -vv 40";
    let hidden = mean(base);
    let through = mean(&format!("{base} -vo 3"));
    let clipped = mean(&format!("{base} -vo 3 -va 5"));
    assert!(hidden < 1e-6, "the black card fills the view: {hidden}");
    assert!(through > 0.3, "-vo 3 clips the card away and shows the wall: {through}");
    assert!(clipped < 1e-6, "-va 5 clips the wall too: {clipped}");
}
