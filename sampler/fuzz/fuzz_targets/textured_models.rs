//! OBJ files with MTL libraries and textures, and glTF files (seed the
//! corpus with small textured models): the first third is the model, the
//! second its material library (`m.mtl`), the last an image both may name
//! (`t.png`). Import fails with an error or succeeds, never panics, and
//! what it reads traces without panicking.
#![no_main]

use std::collections::HashMap;

use glam::{Mat4, Vec3};
use holodeck_sampler::scene::import::import_file;
use holodeck_sampler::{SceneBuilder, TraceOptions, Tracer};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let dir = std::env::temp_dir().join(format!("hds-fuzz-textured-{}", std::process::id()));
    let _ = std::fs::create_dir_all(&dir);
    let third = data.len() / 3;
    let (model, rest) = data.split_at(third);
    let (library, image) = rest.split_at(third);
    let is_gltf = model.first().is_some_and(|&b| b == b'{');
    let path = dir.join(if is_gltf { "model.gltf" } else { "model.obj" });
    let written = std::fs::write(&path, model)
        .and_then(|_| std::fs::write(dir.join("m.mtl"), library))
        .and_then(|_| std::fs::write(dir.join("t.png"), image));
    if written.is_err() {
        return;
    }
    let mut b = SceneBuilder::new();
    let Ok(grey) = b.material("grey", holodeck_sampler::Material::lambertian([0.5; 3])) else {
        return;
    };
    if import_file(&mut b, &path, Mat4::IDENTITY, Some(grey), &HashMap::new()).is_err() {
        return;
    }
    let scene = b.finish();
    if scene.triangles.len() <= 1 << 16 {
        let tracer = Tracer::new(scene, TraceOptions::default());
        let mut rng = holodeck_sampler::Rng::new(0, 0);
        for dir in [Vec3::X, -Vec3::Z, Vec3::new(0.3, 0.2, -1.0)] {
            let s = tracer.trace(Vec3::new(0.1, 0.2, 5.0), dir.normalize(), &mut rng);
            assert!(s.radiance.is_finite());
        }
    }
});
