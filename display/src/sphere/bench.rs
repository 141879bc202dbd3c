//! Insertion speed, measured on directions made here, and the direction
//! sets the tests share: uniform over the sphere, or in the pixel order of
//! frames covering it.

use std::f64::consts::PI;
use std::time::Instant;

use glam::DVec3;

use super::{MeshStats, SphereMesh};

/// Times `n` insertions into a fresh mesh (`min_angle` at its floor) and
/// returns the seconds they took and the mesh's stats. `coherent` feeds the
/// directions in pixel order over the six faces of a cube of frames, as a
/// display receives them; otherwise they come uniformly at random. Making
/// the directions is not timed. Used by `holodeck bench display`.
pub fn bench_insertions(n: usize, coherent: bool, seed: u64) -> (f64, MeshStats) {
    let dirs = if coherent {
        coherent_directions(n, seed)
    } else {
        random_directions(n, seed)
    };
    let mut mesh = SphereMesh::new(0.0);
    let start = Instant::now();
    for &d in &dirs {
        // The generated directions are finite and non-zero.
        let _ = mesh.insert(d);
    }
    (start.elapsed().as_secs_f64(), mesh.stats())
}

/// Times [`SphereMesh::insert_many`] of `n` random directions into a fresh
/// mesh (`min_angle` at its floor), the sort along the Hilbert curve
/// included, and returns the seconds it took and the mesh's stats. Making
/// the directions is not timed. Used by `holodeck bench display`.
pub fn bench_sorted_insertions(n: usize, seed: u64) -> (f64, MeshStats) {
    let dirs = random_directions(n, seed);
    let mut mesh = SphereMesh::new(0.0);
    let start = Instant::now();
    let _ = mesh.insert_many(&dirs);
    (start.elapsed().as_secs_f64(), mesh.stats())
}

/// SplitMix64: deterministic noise without a dependency.
#[derive(Clone, Debug)]
pub(crate) struct SplitMix(pub u64);

impl SplitMix {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }

    /// Uniform in [0, 1).
    pub fn unit(&mut self) -> f64 {
        (self.next_u64() >> 11) as f64 * (1.0 / (1u64 << 53) as f64)
    }

    /// Uniform over the unit sphere.
    pub fn direction(&mut self) -> DVec3 {
        let z = 2.0 * self.unit() - 1.0;
        let phi = 2.0 * PI * self.unit();
        let r = (1.0 - z * z).max(0.0).sqrt();
        DVec3::new(r * phi.cos(), r * phi.sin(), z)
    }
}

/// `n` directions uniform over the sphere.
pub(crate) fn random_directions(n: usize, seed: u64) -> Vec<DVec3> {
    let mut rng = SplitMix(seed);
    (0..n).map(|_| rng.direction()).collect()
}

/// `n` directions through jittered pixels of six square frames that cover
/// the sphere (the faces of a cube around the eye), face by face, row by
/// row: the spatial coherence of a display's sample stream.
pub(crate) fn coherent_directions(n: usize, seed: u64) -> Vec<DVec3> {
    let mut rng = SplitMix(seed);
    let side = ((n as f64 / 6.0).sqrt().ceil() as usize).max(1);
    let faces = [
        (DVec3::X, DVec3::Y, DVec3::Z),
        (DVec3::NEG_X, DVec3::Z, DVec3::Y),
        (DVec3::Y, DVec3::Z, DVec3::X),
        (DVec3::NEG_Y, DVec3::X, DVec3::Z),
        (DVec3::Z, DVec3::X, DVec3::Y),
        (DVec3::NEG_Z, DVec3::Y, DVec3::X),
    ];
    let mut dirs = Vec::with_capacity(n);
    'frames: for (ahead, right, up) in faces {
        for row in 0..side {
            for col in 0..side {
                if dirs.len() == n {
                    break 'frames;
                }
                let u = 2.0 * (col as f64 + rng.unit()) / side as f64 - 1.0;
                let v = 2.0 * (row as f64 + rng.unit()) / side as f64 - 1.0;
                dirs.push(ahead + u * right + v * up);
            }
        }
    }
    dirs
}
