//! Moving a secondary ray's origin off the surface it leaves, so it cannot hit
//! that surface again through rounding: a step along the geometric normal of
//! a few units in the last place, growing with the coordinates' magnitude
//! (Wächter and Binder, "A Fast and Robust Method for Avoiding
//! Self-Intersection", Ray Tracing Gems, 2019).

use glam::Vec3;

const ORIGIN: f32 = 1.0 / 32.0;
const FLOAT_SCALE: f32 = 1.0 / 65536.0;
const INT_SCALE: f32 = 256.0;

/// Offsets `p` along `n` (the side the ray leaves toward).
pub fn offset_origin(p: Vec3, n: Vec3) -> Vec3 {
    let step = |pc: f32, nc: f32| {
        let ulps = (INT_SCALE * nc) as i32;
        let moved = f32::from_bits((pc.to_bits() as i32).wrapping_add(if pc < 0.0 { -ulps } else { ulps }) as u32);
        if pc.abs() < ORIGIN {
            pc + FLOAT_SCALE * nc
        } else {
            moved
        }
    };
    Vec3::new(step(p.x, n.x), step(p.y, n.y), step(p.z, n.z))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn moves_to_the_side_of_the_normal_at_any_scale() {
        for scale in [1e-3f32, 1.0, 1e3, 1e6] {
            let p = Vec3::new(0.3, -0.7, 0.2) * scale;
            let n = Vec3::new(0.6, 0.0, 0.8);
            let q = offset_origin(p, n);
            assert!((q - p).dot(n) > 0.0, "scale {scale}");
            assert!(
                (q - p).length() < 1e-3 * scale.max(1.0),
                "scale {scale}: moved {}",
                (q - p).length()
            );
        }
    }
}
