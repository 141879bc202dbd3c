//! A small, fast, deterministic random number generator (PCG32, O'Neill 2014),
//! seeded per ray so that results do not depend on thread scheduling.

/// PCG32 state.
#[derive(Clone, Debug)]
pub struct Rng {
    state: u64,
    inc: u64,
}

impl Rng {
    /// A generator for stream `stream` of seed `seed`.
    pub fn new(seed: u64, stream: u64) -> Rng {
        let mut r = Rng {
            state: 0,
            inc: (stream << 1) | 1,
        };
        r.next_u32();
        r.state = r.state.wrapping_add(seed ^ 0x853c_49e6_748f_ea9b);
        r.next_u32();
        r
    }
    /// Next 32 random bits.
    #[inline]
    pub fn next_u32(&mut self) -> u32 {
        let old = self.state;
        self.state = old.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(self.inc);
        let xorshifted = (((old >> 18) ^ old) >> 27) as u32;
        let rot = (old >> 59) as u32;
        xorshifted.rotate_right(rot)
    }
    /// Uniform in [0, 1).
    #[inline]
    pub fn f32(&mut self) -> f32 {
        (self.next_u32() >> 8) as f32 * (1.0 / (1u32 << 24) as f32)
    }
    /// Two uniforms in [0, 1).
    #[inline]
    pub fn f32x2(&mut self) -> (f32, f32) {
        (self.f32(), self.f32())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn deterministic_uniform_and_stream_separated() {
        let mut a = Rng::new(7, 3);
        let mut b = Rng::new(7, 3);
        let mut c = Rng::new(7, 4);
        let xs: Vec<f32> = (0..10_000).map(|_| a.f32()).collect();
        assert!(xs.iter().zip((0..10_000).map(|_| b.f32())).all(|(x, y)| *x == y));
        assert!(
            xs.iter()
                .zip((0..10_000).map(|_| c.f32()))
                .filter(|(x, y)| *x == y)
                .count()
                < 5
        );
        let mean = xs.iter().sum::<f32>() / xs.len() as f32;
        assert!((mean - 0.5).abs() < 0.01 && xs.iter().all(|x| (0.0..1.0).contains(x)));
    }
}
