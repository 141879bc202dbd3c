//! Helpers shared by the integration tests that run the `holodeck` binary.

use std::process::{Command, Output};

pub mod process;
#[allow(dead_code)]
pub mod screen;

/// Runs `holodeck` with `args` to the end (within [`process::DEADLINE`]);
/// the process is killed if the test fails first.
#[allow(dead_code)]
pub fn holodeck(args: &[&str]) -> Output {
    process::run(Command::new(env!("CARGO_BIN_EXE_holodeck")).args(args))
}

/// Adds `rays` rays of the built-in room with up to `bounces` bounces to
/// `file` (`holodeck fill`), failing the test with its output if it fails.
#[allow(dead_code)]
pub fn fill_room(file: &std::path::Path, rays: &str, bounces: &str) {
    let args = [
        "fill",
        "builtin:room",
        &file.to_string_lossy(),
        "--rays",
        rays,
        "--bounces",
        bounces,
    ];
    let o = holodeck(&args);
    assert!(o.status.success(), "{args:?}: {}", text(&o));
}

/// Standard output and standard error together, as text.
#[allow(dead_code)]
pub fn text(o: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&o.stdout),
        String::from_utf8_lossy(&o.stderr)
    )
}

/// Checks every ray of a holodeck of the built-in room filled with no
/// bounces against the scene itself: the stored depth is where the ray hits,
/// a ray that sees the light carries its exact radiance, and one that sees an
/// unlit surface is black. Returns (rays checked, rays that saw the light).
#[allow(dead_code)]
pub fn check_rays_against_room(hdk: &mut holodeck_file::HoloFile) -> (u64, u64) {
    use holodeck_protocol::BeamKey;
    use holodeck_sampler::geom::Ray;
    use holodeck_sampler::scene::gen::{generate, GenParams};
    use holodeck_sampler::{KdTree, Material};
    let scene = generate("room", &GenParams::default()).unwrap();
    let tree = KdTree::build(&scene, &Default::default());
    let section = hdk.sections()[0].clone();
    let keys: Vec<BeamKey> = (0..section.beam_count()).map(|b| BeamKey::new(0, b)).collect();
    let (mut checked, mut lights) = (0, 0);
    let mut grazing = Vec::new();
    hdk.read_beams(&keys, |key, rays| {
        for r in rays {
            let d = section.decode_record(key.beam, r).unwrap();
            // The interior section's rays were traced from the exit wall outward.
            let start = d.ray.origin + d.ray.direction * d.ray.length;
            let probe = Ray::new(start.as_vec3(), d.ray.direction.as_vec3());
            let hit = tree.intersect(&probe).expect("the room is closed but for its pane");
            let traced = d.ray.length + f64::from(hit.t);
            let holodeck_protocol::Hit::Point(p) = d.hit else {
                panic!("finite hits decode as points")
            };
            let stored = (p - d.ray.origin).length();
            let tolerance = 6e-4 * traced.max(section.diagonal()) + 1e-4;
            if (stored - traced).abs() > tolerance {
                // A ray that grazes an edge may hit or miss it depending on
                // the last bit of its origin (the checker rebuilds the ray
                // from the record); allow one in 10,000.
                grazing.push(format!("beam {}: stored {stored}, traced {traced}", key.beam));
                continue;
            }
            assert!(d.color.iter().all(|c| c.is_finite() && *c >= 0.0));
            let m = &scene.materials[scene.triangles[hit.tri as usize].material as usize];
            match m {
                Material::Emitter { radiance } => {
                    // Seen directly, a light shows its exact radiance (within RGBE's quantization).
                    for (got, want) in d.color.iter().zip(radiance) {
                        assert!((got - want).abs() <= want / 64.0, "light seen as {:?}", d.color);
                    }
                    lights += 1;
                }
                Material::Glass { thin: true, .. } => {} // the window: sky and sun behind it
                _ => assert_eq!(d.color, [0.0; 3], "an unlit surface without bounces is black"),
            }
            checked += 1;
        }
    })
    .unwrap();
    assert!(
        grazing.len() as u64 <= 1 + (checked + grazing.len() as u64) / 10_000,
        "{} rays disagree with the scene: {:?}",
        grazing.len(),
        &grazing[..grazing.len().min(5)]
    );
    (checked + grazing.len() as u64, lights)
}
