//! Stateless pseudo-random numbers and 2D gradient noise for the generators:
//! every value is a pure function of (seed, coordinates), so generation can run
//! on any number of threads in any order and give the same scene.

/// A well-mixed 64-bit hash of `seed` and `k` (SplitMix64 finalizer).
pub fn hash(seed: u64, k: u64) -> u64 {
    let mut z = seed ^ k.wrapping_mul(0x9E37_79B9_7F4A_7C15);
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// A uniform number in [0, 1) from `hash(seed, k)`.
pub fn unit(seed: u64, k: u64) -> f32 {
    (hash(seed, k) >> 40) as f32 / (1u64 << 24) as f32
}

/// Gradient (Perlin-style) noise at (x, y), roughly in [-1, 1], smooth, zero at lattice points.
pub fn gradient(seed: u64, x: f32, y: f32) -> f32 {
    let (x0, y0) = (x.floor(), y.floor());
    let (fx, fy) = (x - x0, y - y0);
    let (ix, iy) = (x0 as i64, y0 as i64);
    let corner = |dx: i64, dy: i64| {
        let k = ((ix + dx) as u64)
            .wrapping_mul(0x0100_0000_01B3)
            .wrapping_add((iy + dy) as u64);
        let angle = unit(seed, k) * std::f32::consts::TAU;
        let (s, c) = angle.sin_cos();
        c * (fx - dx as f32) + s * (fy - dy as f32)
    };
    let fade = |t: f32| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let (u, v) = (fade(fx), fade(fy));
    let a = corner(0, 0) + u * (corner(1, 0) - corner(0, 0));
    let b = corner(0, 1) + u * (corner(1, 1) - corner(0, 1));
    (a + v * (b - a)) * std::f32::consts::SQRT_2
}

/// Fractal Brownian motion: `octaves` of gradient noise, each at twice the
/// frequency and half the amplitude of the one before, normalized to about [-1, 1].
pub fn fbm(seed: u64, x: f32, y: f32, octaves: u32) -> f32 {
    let (mut sum, mut amp, mut freq, mut norm) = (0.0, 1.0, 1.0, 0.0);
    for o in 0..octaves {
        sum += amp * gradient(hash(seed, u64::from(o)), x * freq, y * freq);
        norm += amp;
        amp *= 0.5;
        freq *= 2.0;
    }
    sum / norm
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn noise_is_deterministic_bounded_and_seeded() {
        let a: Vec<f32> = (0..500)
            .map(|i| fbm(7, i as f32 * 0.137, i as f32 * 0.071, 5))
            .collect();
        let b: Vec<f32> = (0..500)
            .map(|i| fbm(7, i as f32 * 0.137, i as f32 * 0.071, 5))
            .collect();
        let c: Vec<f32> = (0..500)
            .map(|i| fbm(8, i as f32 * 0.137, i as f32 * 0.071, 5))
            .collect();
        assert_eq!(a, b);
        assert_ne!(a, c);
        assert!(a.iter().all(|v| v.abs() <= 1.5), "{a:?}");
        let spread = a.iter().fold(0.0f32, |m, v| m.max(v.abs()));
        assert!(spread > 0.2, "noise is nearly flat: {spread}");
        assert_eq!(gradient(3, 5.0, -2.0), 0.0);
        let u: Vec<f32> = (0..1000).map(|k| unit(1, k)).collect();
        assert!(u.iter().all(|v| (0.0..1.0).contains(v)));
        let mean = u.iter().sum::<f32>() / 1000.0;
        assert!((mean - 0.5).abs() < 0.05, "{mean}");
    }
}
