//! Radiance scene files (seed the corpus with small `.rad` scenes): reading
//! one fails with an error or succeeds, never panics or hangs, and what it
//! reads traces without panicking. The file may include itself or a second
//! file written beside it, so `!xform` lines are exercised too.
#![no_main]

use std::collections::HashMap;

use glam::{Mat4, Vec3};
use holodeck_sampler::scene::import::import_file;
use holodeck_sampler::{SceneBuilder, TraceOptions, Tracer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("hds-fuzz-rad-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    // The first half is the scene, the second a file it may include as `b.rad`.
    let (scene, other) = data.split_at(data.len() / 2);
    let path = dir.join("scene.rad");
    if std::fs::write(&path, scene).is_err() || std::fs::write(dir.join("b.rad"), other).is_err() {
        return;
    }
    let mut b = SceneBuilder::new();
    if import_file(&mut b, &path, Mat4::IDENTITY, None, &HashMap::new()).is_err() {
        return;
    }
    let scene = b.finish();
    if scene.triangles.len() <= 1 << 16 {
        let tracer = Tracer::new(scene, TraceOptions::default());
        let mut rng = holodeck_sampler::Rng::new(0, 0);
        let _ = tracer.trace(Vec3::new(-100.0, 0.1, 0.2), Vec3::X, &mut rng);
    }
});
