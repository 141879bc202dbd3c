//! The scene's content hash: BLAKE3 over its geometry, materials and sky in a
//! fixed little-endian layout, so samplers and holodeck files can prove they
//! describe the same scene. Sections are not part of it: the same scene may be
//! sampled into differently shaped holodecks.

use super::Scene;

/// `blake3:` followed by 64 hex digits.
pub fn content_hash(scene: &Scene) -> String {
    let mut h = blake3::Hasher::new();
    h.update(b"holodeck scene v1");
    // The same byte stream as one update per value, batched for speed.
    let mut buf: Vec<u8> = Vec::with_capacity(1 << 16);
    fn flush(h: &mut blake3::Hasher, buf: &mut Vec<u8>, force: bool) {
        if force || buf.len() + 16 > buf.capacity() {
            h.update(buf);
            buf.clear();
        }
    }
    buf.extend_from_slice(&(scene.positions.len() as u64).to_le_bytes());
    for p in &scene.positions {
        for c in p.to_array() {
            buf.extend_from_slice(&c.to_bits().to_le_bytes());
        }
        flush(&mut h, &mut buf, false);
    }
    buf.extend_from_slice(&(scene.triangles.len() as u64).to_le_bytes());
    for t in &scene.triangles {
        for v in t.v {
            buf.extend_from_slice(&v.to_le_bytes());
        }
        buf.extend_from_slice(&t.material.to_le_bytes());
        flush(&mut h, &mut buf, false);
    }
    flush(&mut h, &mut buf, true);
    // Debug output of plain parameter structs is stable and exact for f32
    // (shortest round-trip formatting), which is all the hash needs.
    h.update(format!("{:?}", scene.materials).as_bytes());
    h.update(format!("{:?}", scene.sky).as_bytes());
    // Textured scenes add their coordinates, maps and images; an untextured
    // scene hashes as it always has, so existing holodeck files still match.
    if !scene.uvs.is_empty() || scene.maps.iter().any(|m| !m.is_empty()) {
        h.update(b"textures v1");
        h.update(&(scene.uvs.len() as u64).to_le_bytes());
        for t in &scene.tangents {
            for c in t.to_array() {
                h.update(&c.to_bits().to_le_bytes());
            }
        }
        for uv in &scene.uvs {
            h.update(&uv.x.to_bits().to_le_bytes());
            h.update(&uv.y.to_bits().to_le_bytes());
        }
        // Each map by what its image holds, not by where the image sits in
        // the texture list: the same scene loaded another way hashes the same.
        for maps in &scene.maps {
            let mut maps = maps.clone();
            for r in maps.refs_mut() {
                let digest = scene.textures.get(r.texture).map_or([0; 32], |t| t.digest);
                h.update(&digest);
                r.texture = 0;
            }
            h.update(format!("{maps:?}").as_bytes());
        }
    }
    format!("blake3:{}", h.finalize().to_hex())
}
