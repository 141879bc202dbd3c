//! Many insertions at once, in an order that keeps the walk short and the
//! memory it touches in cache: directions sorted along a Hilbert curve on
//! each face of the cube around the eye, so that consecutive insertions
//! land next to each other on the sphere whatever order they came in.

use glam::DVec3;

use super::{Insert, SphereError, SphereMesh};

/// Bits per axis of a face's Hilbert curve: cells of about 3e-5 radians.
const BITS: u32 = 16;

/// Where `dir` lies along the curve: the cube face it points through (the
/// axis of its largest component, with its sign) in the high bits, then its
/// place on that face's Hilbert curve. Directions that are not finite sort
/// last.
pub fn hilbert_key(dir: DVec3) -> u64 {
    if !dir.is_finite() {
        return u64::MAX;
    }
    let (face, u, v, m) = super::grid::cube_face(dir);
    if m == 0.0 {
        return u64::MAX;
    }
    let side = f64::from((1u32 << BITS) - 1);
    let cell = |c: f64| ((c / m + 1.0) * 0.5 * side).clamp(0.0, side) as u32;
    (face as u64) << (2 * BITS) | hilbert_index(cell(u), cell(v))
}

/// The index of cell (`x`, `y`) along the Hilbert curve through the
/// 2^[`BITS`] x 2^[`BITS`] grid.
fn hilbert_index(mut x: u32, mut y: u32) -> u64 {
    let n = 1u32 << BITS;
    let mut d = 0u64;
    let mut s = n / 2;
    while s > 0 {
        let rx = u32::from(x & s != 0);
        let ry = u32::from(y & s != 0);
        d += u64::from(s) * u64::from(s) * u64::from((3 * rx) ^ ry);
        // Turn the quadrant so the curve inside it starts where the last ended.
        if ry == 0 {
            if rx == 1 {
                x = n - 1 - x;
                y = n - 1 - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s /= 2;
    }
    d
}

impl SphereMesh {
    /// Inserts every direction of `dirs`, in Hilbert order rather than the
    /// order given (see the module docs), and returns what became of each,
    /// in the order given. The mesh is the Delaunay triangulation of the
    /// same directions; only which of two directions within `min_angle` of
    /// each other becomes the vertex can differ from one-by-one insertion.
    pub fn insert_many(&mut self, dirs: &[DVec3]) -> Vec<Result<Insert, SphereError>> {
        let mut order: Vec<(u64, u32)> = dirs
            .iter()
            .enumerate()
            .map(|(i, d)| (hilbert_key(*d), i as u32))
            .collect();
        order.sort_unstable();
        let mut out = vec![Ok(Insert::Rejected); dirs.len()];
        for (_, i) in order {
            out[i as usize] = self.insert(dirs[i as usize]);
        }
        out
    }
}
