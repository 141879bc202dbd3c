//! `holodeck fill` end to end: a real process traces the built-in room into a
//! holodeck file; the test then checks every stored ray against the scene.

use std::process::Command;

use holodeck_protocol::BeamKey;
use holodeck_sampler::geom::Ray;
use holodeck_sampler::scene::gen::{generate, GenParams};
use holodeck_sampler::{KdTree, Material};
use holodeck_server::{HoloFile, OpenOptions};

fn holodeck(args: &[&str]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_holodeck"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn filled_rays_agree_with_the_scene() {
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("room.hdk");
    let f = file.to_str().unwrap();
    // No bounces: every stored color is then exact. A ray that sees the light
    // carries its radiance; any other opaque surface is black. 600,000 rays of
    // 4 visit every one of the section's 129,438 beams at least once.
    let o = holodeck(&["fill", "builtin:room", f, "--rays", "600K", "--bounces", "0"]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(String::from_utf8_lossy(&o.stdout).contains("600,000 rays"));

    let scene = generate("room", &GenParams::default()).unwrap();
    let tree = KdTree::build(&scene, &Default::default());
    let mut hdk = HoloFile::open(&file, &OpenOptions::read_only()).unwrap();
    assert_eq!(
        hdk.sections(),
        scene.sections.as_slice(),
        "the file takes the scene's sections"
    );
    let summary = hdk.summary();
    assert_eq!(summary.rays(), 600_000);
    assert_eq!(summary.sections[0].1, summary.sections[0].0, "every beam holds rays");
    // First runs are exact: the only hole is the empty directory written at
    // creation, freed by the first commit (one byte per beam).
    assert_eq!(summary.fragments, 1, "{summary:?}");
    assert!(
        summary.free_bytes <= u64::from(section_beams(&summary)) + 64,
        "{summary:?}"
    );

    let section = hdk.sections()[0].clone();
    let keys: Vec<BeamKey> = (0..section.beam_count()).map(|b| BeamKey::new(0, b)).collect();
    let (mut checked, mut lights) = (0, 0);
    hdk.read_beams(&keys, |key, rays| {
        for r in rays {
            let d = section.decode_record(key.beam, r).unwrap();
            // The interior section's rays were traced from the exit wall outward.
            let start = d.ray.origin + d.ray.direction * d.ray.length;
            let probe = Ray::new(start.as_vec3(), d.ray.direction.as_vec3());
            let hit = tree
                .intersect(&scene, &probe)
                .expect("the room is closed but for its pane");
            let traced = d.ray.length + f64::from(hit.t);
            let holodeck_protocol::Hit::Point(p) = d.hit else {
                panic!("finite hits decode as points")
            };
            let stored = (p - d.ray.origin).length();
            let tolerance = 6e-4 * traced.max(section.diagonal()) + 1e-4;
            assert!(
                (stored - traced).abs() <= tolerance,
                "beam {}: stored {stored}, traced {traced}",
                key.beam
            );
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
    assert_eq!(checked, 600_000);
    assert!(lights > 100, "some rays see the ceiling light ({lights})");

    drop(hdk);
    // Another scene may not be filled into this file.
    let o = holodeck(&["fill", "builtin:landscape", f, "--triangles", "2000", "--rays", "10"]);
    assert!(!o.status.success());
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains("another scene"), "{err}");
}

fn section_beams(s: &holodeck_server::storage::FileSummary) -> u32 {
    s.sections.iter().map(|x| x.0).sum()
}
