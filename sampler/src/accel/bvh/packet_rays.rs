//! A packet's rays by axis, one ray per lane, prepared once for every walk
//! over them: reciprocal directions eight at a time, direction octants from
//! the lanes' sign bits, and whether they run nearly one way. Done ray by
//! ray, this setup cost a third of a coherent packet's time.

use super::slab::safe_recip;
use crate::accel::packet::{COHERENT_COS, PACKET};
use crate::geom::{Lanes, Ray};

/// Up to [`PACKET`] rays by axis (`o[axis][lane]`). Lanes without a ray of
/// their own repeat one that has, so that every lane computes with real
/// numbers and reductions over all lanes need no mask.
#[derive(Clone, Copy)]
pub(super) struct PacketRays {
    pub(super) o: [[f32; PACKET]; 3],
    pub(super) d: [[f32; PACKET]; 3],
    /// Reciprocal directions, as [`safe_recip`] gives them.
    pub(super) inv: [[f32; PACKET]; 3],
    pub(super) t_max: [f32; PACKET],
    /// The lanes with rays of their own.
    pub(super) lanes: u32,
}

impl PacketRays {
    /// The first [`PACKET`] of `rays`, which must not be empty; those with
    /// a non-finite origin or direction get no lane of their own.
    #[inline(always)]
    pub(super) fn new<L: Lanes>(rays: &[Ray]) -> PacketRays {
        let n = rays.len().min(PACKET);
        let ray = |i: usize| &rays[if i < n { i } else { 0 }];
        let o = [
            L::from_fn(|i| ray(i).origin.x),
            L::from_fn(|i| ray(i).origin.y),
            L::from_fn(|i| ray(i).origin.z),
        ];
        let d = [
            L::from_fn(|i| ray(i).dir.x),
            L::from_fn(|i| ray(i).dir.y),
            L::from_fn(|i| ray(i).dir.z),
        ];
        let mut p = PacketRays {
            o: [o[0].to_array(), o[1].to_array(), o[2].to_array()],
            d: [d[0].to_array(), d[1].to_array(), d[2].to_array()],
            inv: [[0.0; PACKET]; 3],
            t_max: L::from_fn(|i| ray(i).t_max).to_array(),
            lanes: (1u32 << n) - 1,
        };
        // Rays with a non-finite origin or direction find nothing: they would
        // make the packet's bounds meaningless for the others.
        let finite = |x: L| x.sub(x).eq(L::splat(0.0));
        let ok = finite(o[0]) & finite(o[1]) & finite(o[2]) & finite(d[0]) & finite(d[1]) & finite(d[2]);
        if ok & p.lanes != p.lanes {
            p.lanes &= ok;
            if p.lanes == 0 {
                return p;
            }
            p = p.only(p.lanes);
        }
        for c in 0..3 {
            let d = if p.lanes == (1u32 << n) - 1 {
                d[c]
            } else {
                L::new(p.d[c])
            };
            // Division is correctly rounded in every lane, as in `safe_recip`;
            // zero components then get its largest float of their sign.
            let mut inv = L::splat(1.0).div(d).to_array();
            let mut zero = d.eq(L::splat(0.0));
            while zero != 0 {
                let i = zero.trailing_zeros() as usize;
                zero &= zero - 1;
                inv[i] = safe_recip(p.d[c][i]);
            }
            p.inv[c] = inv;
        }
        p
    }

    /// The lanes' direction sign bits on each axis.
    #[inline(always)]
    pub(super) fn signs<L: Lanes>(&self) -> [u32; 3] {
        [
            L::new(self.d[0]).sign_bits(),
            L::new(self.d[1]).sign_bits(),
            L::new(self.d[2]).sign_bits(),
        ]
    }

    /// The lanes of `left` (not empty) whose direction octant is that of
    /// the first of them: by sign bit, so that a -0.0 component walks as
    /// it does alone, where its inverse is negative.
    #[inline(always)]
    pub(super) fn octant(signs: [u32; 3], left: u32) -> u32 {
        let i = left.trailing_zeros();
        let same = |s: u32| if s >> i & 1 != 0 { s } else { !s };
        same(signs[0]) & same(signs[1]) & same(signs[2]) & left
    }

    /// These rays with only the lanes of `mask` (not empty) their own: the
    /// others repeat the first of them.
    #[inline(always)]
    pub(super) fn only(&self, mask: u32) -> PacketRays {
        let f = mask.trailing_zeros() as usize;
        let mut p = *self;
        for i in 0..PACKET {
            if mask & (1 << i) == 0 {
                for c in 0..3 {
                    p.o[c][i] = self.o[c][f];
                    p.d[c][i] = self.d[c][f];
                    p.inv[c][i] = self.inv[c][f];
                }
                p.t_max[i] = self.t_max[f];
            }
        }
        p.lanes = mask;
        p
    }

    /// Whether the rays run nearly one way: within [`COHERENT_COS`] of the
    /// first lane's direction, as the kd-tree's packets decide.
    #[inline(always)]
    pub(super) fn coherent<L: Lanes>(&self) -> bool {
        let d = [L::new(self.d[0]), L::new(self.d[1]), L::new(self.d[2])];
        let (fx, fy, fz) = (self.d[0][0], self.d[1][0], self.d[2][0]);
        let f2 = fx * fx + fy * fy + fz * fz;
        let dot = d[0]
            .mul(L::splat(fx))
            .add(d[1].mul(L::splat(fy)))
            .add(d[2].mul(L::splat(fz)));
        let len2 = d[0].mul(d[0]).add(d[1].mul(d[1])).add(d[2].mul(d[2]));
        // cos >= c, squared, without a square root.
        let near = dot.gt(L::splat(0.0)) & L::splat(COHERENT_COS * COHERENT_COS * f2).mul(len2).le(dot.mul(dot));
        near == (1u32 << PACKET) - 1
    }
}
