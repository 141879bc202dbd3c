//! Whole scene files (seed the corpus with a small one from `holodeck scene
//! build builtin:room`): opening fails with an error or succeeds, and then
//! every block either reads or is refused, rays through the scene trace
//! without panicking, and assembling it in memory succeeds or is refused.
#![no_main]

use holodeck_sampler::geom::Ray;
use holodeck_sampler::ooc::{Fetch, OocScene};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("hds-fuzz-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let path = dir.join("scene.hds");
    if std::fs::write(&path, data).is_err() {
        return;
    }
    if let Ok(scene) = OocScene::open(&path, Some(1 << 20), 0) {
        for id in 0..scene.header().blocks.min(64) {
            let _ = scene.cache().read(id);
        }
        let b = scene.bounds();
        let c = (b.lo + b.hi) * 0.5;
        for dir in [glam::Vec3::X, glam::Vec3::NEG_Y, glam::Vec3::new(0.3, 0.4, -0.5)] {
            let _ = scene.intersect(&Ray::new(c - dir * 100.0, dir), 0.0, &mut Fetch::load());
        }
        if scene.header().blocks <= 64 {
            if let Ok((_, tree, _)) = scene.in_core() {
                let _ = tree.intersect(&Ray::new(c - glam::Vec3::X * 100.0, glam::Vec3::X));
            }
        }
    }
});
