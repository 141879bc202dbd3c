//! Point location: which triangle a direction falls in.
//!
//! A walk starts at a triangle of the vertex the grid remembers near the
//! direction and steps across an edge whose great-circle plane has the
//! direction on its far side, until no edge does. The first failing edge is
//! looked for from a pseudo-random corner each step, so that no
//! configuration can make the walk circle forever; a walk that still runs
//! past every triangle falls back to testing them all.

use glam::DVec3;

use super::predicates::{chord2, side};
use super::{index_of, tri_of, SphereMesh};

/// The end of a walk.
#[derive(Clone, Copy, Debug)]
pub(crate) struct Located {
    /// A triangle containing the direction (edges included).
    pub tri: u32,
    /// Bit `i` set: the direction lies on the great circle of the edge
    /// opposite corner `i` (exactly, by the predicate).
    pub zeros: u8,
    /// Triangles stepped across.
    pub steps: u64,
}

impl SphereMesh {
    /// Where a walk toward unit direction `p` should start: at the last
    /// vertex when it is within a cell's width (directions in pixel order,
    /// and it is in cache), else at the nearer of it and the grid's vertex.
    #[inline]
    pub(crate) fn walk_start(&self, p: DVec3) -> u32 {
        let recent = self.recent as usize;
        let to_recent = chord2(p, self.dirs[recent]);
        if to_recent < self.grid.cell_chord2() {
            return self.vert_tri[recent];
        }
        let cell = self.grid.get(p) as usize;
        let nearer = if chord2(p, self.dirs[cell]) <= to_recent {
            cell
        } else {
            recent
        };
        self.vert_tri[nearer]
    }

    /// Walks from triangle `start` to the triangle containing unit direction `p`.
    pub(crate) fn walk(&self, p: DVec3, start: u32) -> Located {
        let limit = 2 * self.tris.len() as u64 + 64;
        let mut rng = seed(p);
        let mut t = start;
        let mut tri = self.tris[t as usize];
        let mut at = tri.v.map(|v| self.dirs[v as usize]);
        // The edge the walk came in by: p is on this side of it.
        let mut skip = 3;
        let mut steps = 0u64;
        'walk: loop {
            rng ^= rng << 13;
            rng ^= rng >> 7;
            rng ^= rng << 17;
            // A uniform pick of 0, 1 or 2 without a division.
            let first = (((rng >> 33) * 3) >> 31) as usize;
            let mut zeros = 0u8;
            for k in 0..3 {
                let i = (first + k) % 3;
                if i == skip {
                    continue;
                }
                let (i1, i2) = ((i + 1) % 3, (i + 2) % 3);
                let s = side(at[i1], at[i2], p);
                if s < 0.0 {
                    // The next triangle is (far, b, a) from its corner j on:
                    // its far vertex's direction and the triangle load
                    // together.
                    let (a, b) = (at[i1], at[i2]);
                    let j = index_of(tri.n[i]);
                    t = tri_of(tri.n[i]);
                    at[j] = self.dirs[tri.o[i] as usize];
                    at[(j + 1) % 3] = b;
                    at[(j + 2) % 3] = a;
                    tri = self.tris[t as usize];
                    skip = j;
                    steps += 1;
                    if steps > limit {
                        break 'walk;
                    }
                    continue 'walk;
                }
                if s == 0.0 {
                    zeros |= 1 << i;
                }
            }
            return Located { tri: t, zeros, steps };
        }
        let mut found = self.scan(p);
        found.steps += steps;
        found
    }

    /// Tests every triangle: the walk's safety net, never its plan.
    fn scan(&self, p: DVec3) -> Located {
        for (t, tri) in self.tris.iter().enumerate() {
            let mut zeros = 0u8;
            let mut inside = true;
            for i in 0..3 {
                let a = self.dirs[tri.v[(i + 1) % 3] as usize];
                let b = self.dirs[tri.v[(i + 2) % 3] as usize];
                let s = side(a, b, p);
                if s < 0.0 {
                    inside = false;
                    break;
                }
                if s == 0.0 {
                    zeros |= 1 << i;
                }
            }
            if inside {
                return Located {
                    tri: t as u32,
                    zeros,
                    steps: self.tris.len() as u64,
                };
            }
        }
        // The triangles tile the sphere, so some triangle contains p; a mesh
        // that lost that property fails `validate`, and any triangle is as
        // good an answer as none.
        Located {
            tri: 0,
            zeros: 0,
            steps: self.tris.len() as u64,
        }
    }
}

/// A non-zero xorshift state from the direction's bits: the same walk for
/// the same mesh and direction, different corners for different directions.
#[inline]
fn seed(p: DVec3) -> u64 {
    let h = p.x.to_bits() ^ p.y.to_bits().rotate_left(21) ^ p.z.to_bits().rotate_left(42);
    h.wrapping_mul(0x9E37_79B9_7F4A_7C15) | 1
}
