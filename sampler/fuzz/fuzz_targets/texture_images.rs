//! Texture images (seed the corpus with small PNG, JPEG, TGA, BMP and HDR
//! files): decoding fails with an error or gives a texture whose lookups
//! stay finite, never panics, hangs or allocates past the size limit.
#![no_main]

use glam::Vec2;
use holodeck_sampler::scene::texture::{Encoding, TextureSet, Wrap};
use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| {
    let mut set = TextureSet::new();
    let Ok(i) = set.load_bytes("fuzz", data, Encoding::Srgb) else {
        return;
    };
    let Some(t) = set.get(i) else { return };
    for (u, v, lod) in [(0.5, 0.5, 0.0), (-3.2, 7.9, 1.5), (1e9, -1e9, 40.0)] {
        let c = t.sample(Vec2::new(u, v), [Wrap::Mirror, Wrap::Clamp], lod);
        assert!(c.is_finite());
    }
});
