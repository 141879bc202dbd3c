//! Where a ray lands: the view's constants every core shares while a
//! batch is projected ([`Lens`]), and the keys of rays that land nowhere.

use glam::DVec3;

use super::{EstimatorOptions, Pending};
use crate::project::Projector;
use crate::sample::Sample;

/// The key of a ray that lands off the frame.
pub(super) const OFF: u64 = u64::MAX;

/// The key of a ray with a number in it that is not finite.
pub(super) const NOT_FINITE: u64 = u64::MAX - 1;

/// What projecting a ray needs: the view's constants, shared by every core
/// (and apart from the index, so that one batch is projected while the one
/// before is merged). A projected ray's key is its pixel, packed by
/// [`pack`]; merging turns it into the index's key.
pub(super) struct Lens<'a> {
    pub(super) eye: DVec3,
    pub(super) projector: &'a Projector,
    pub(super) options: &'a EstimatorOptions,
}

/// Pixel (`col`, `row`) as one number, until the index numbers it.
#[inline(always)]
fn pack(col: u32, row: u32) -> u64 {
    u64::from(row) << 32 | u64::from(col)
}

impl Lens<'_> {
    /// Where `s` lands, with its weight and depth (its key [`OFF`] or
    /// [`NOT_FINITE`] where it lands nowhere).
    #[inline(always)]
    pub(super) fn project(&self, s: &Sample) -> Pending {
        if !s.is_finite() {
            return Pending::nowhere(NOT_FINITE);
        }
        match s.hit {
            Some(h) => {
                let Some((col, row, at, depth)) = self.projector.locate(h) else {
                    return Pending::nowhere(OFF);
                };
                let cos = s.direction.dot(self.projector.look(h, depth));
                self.surface(col, row, at, depth, cos, s.color)
            }
            // Parallel rays see the same point of the sky from anywhere
            // nothing stands between: from the eye, if it passed through
            // the eye; otherwise unless a surface of its pixel may hide it
            // (checked on insertion, against the pixel's nearest depth).
            None => {
                let Some((col, row, at, _)) = self.projector.locate(s.target(self.eye)) else {
                    return Pending::nowhere(OFF);
                };
                let miss = s.miss_distance(self.eye) as f32;
                Pending {
                    key: pack(col, row),
                    color: s.color,
                    weight: if miss > 0.0 { -miss } else { 1.0 },
                    depth: f32::INFINITY,
                    at: sub_position(at),
                }
            }
        }
    }

    /// A ray that hit a surface at `depth` in pixel (`col`, `row`), at `at`
    /// within it, arriving at `cos` (cosine of the angle) from the direction
    /// the eye looks at its hit point along.
    #[inline(always)]
    pub(super) fn surface(&self, col: u32, row: u32, at: [f32; 2], depth: f64, cos: f64, color: [f32; 3]) -> Pending {
        let w = self.options.weight(cos);
        // 2 (1 - cos θ) is θ², as in the weight.
        let angle = self.projector.pixel_angle(depth);
        let trusted = 2.0 * (1.0 - cos.clamp(-1.0, 1.0)) <= angle * angle;
        Pending {
            key: pack(col, row),
            color,
            weight: if trusted { w } else { -w },
            depth: depth as f32,
            at: sub_position(at),
        }
    }
}

/// Where in its pixel a ray lands, in 65536ths.
#[inline(always)]
fn sub_position(at: [f32; 2]) -> [u16; 2] {
    at.map(|a| (a * 65536.0).min(65535.0) as u16)
}
