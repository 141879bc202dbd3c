//! Ray geometry in single precision: rays, boxes, the watertight ray/triangle
//! test, and robust offsetting of secondary ray origins.

mod lanes;
mod offset;
mod rays8;
#[cfg(test)]
mod testing;
mod triangle;
mod triangle4;

#[cfg(target_arch = "x86_64")]
pub(crate) use lanes::avx;
pub use lanes::{LaneOps, Lanes};
pub use offset::offset_origin;
pub use rays8::Rays8;
pub use triangle::{axis_permutation, intersect_triangle, RayPrep, TriangleHit};
pub use triangle4::{Ray4, RayWide, Tri4, Tri8};

use glam::Vec3;

/// A ray: origin, direction (any length; `t` is in units of it), and the
/// largest `t` of interest.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ray {
    /// Origin.
    pub origin: Vec3,
    /// Direction.
    pub dir: Vec3,
    /// Hits beyond this parameter are ignored.
    pub t_max: f32,
}

impl Ray {
    /// A ray with no far limit.
    pub fn new(origin: Vec3, dir: Vec3) -> Ray {
        Ray {
            origin,
            dir,
            t_max: f32::INFINITY,
        }
    }
    /// The point at parameter `t`.
    pub fn at(&self, t: f32) -> Vec3 {
        self.origin + self.dir * t
    }
}

/// Axis-aligned box.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Aabb {
    /// Minimum corner.
    pub lo: Vec3,
    /// Maximum corner.
    pub hi: Vec3,
}

impl Aabb {
    /// The empty box (grows from nothing).
    pub const EMPTY: Aabb = Aabb {
        lo: Vec3::splat(f32::INFINITY),
        hi: Vec3::splat(f32::NEG_INFINITY),
    };

    /// Grows to include a point.
    pub fn grow(&mut self, p: Vec3) {
        self.lo = self.lo.min(p);
        self.hi = self.hi.max(p);
    }
    /// Union of two boxes.
    pub fn union(&self, o: &Aabb) -> Aabb {
        Aabb {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
    /// Grows to include `o`, by plain comparisons: cheaper than
    /// [`Aabb::union`] in a build's inner loops (`f32::min` blends for NaN
    /// on every operation), and the same for boxes without NaN.
    #[inline(always)]
    pub(crate) fn include(&mut self, o: &Aabb) {
        let lt = |a: f32, b: f32| if a < b { a } else { b };
        let gt = |a: f32, b: f32| if a > b { a } else { b };
        self.lo = Vec3::new(lt(o.lo.x, self.lo.x), lt(o.lo.y, self.lo.y), lt(o.lo.z, self.lo.z));
        self.hi = Vec3::new(gt(o.hi.x, self.hi.x), gt(o.hi.y, self.hi.y), gt(o.hi.z, self.hi.z));
    }
    /// Intersection of two boxes (may be empty).
    pub fn clip(&self, o: &Aabb) -> Aabb {
        Aabb {
            lo: self.lo.max(o.lo),
            hi: self.hi.min(o.hi),
        }
    }
    /// True when it contains nothing.
    pub fn is_empty(&self) -> bool {
        self.lo.x > self.hi.x || self.lo.y > self.hi.y || self.lo.z > self.hi.z
    }
    /// Surface area (0 for an empty box).
    pub fn area(&self) -> f32 {
        if self.is_empty() {
            return 0.0;
        }
        let d = self.hi - self.lo;
        2.0 * (d.x * d.y + d.y * d.z + d.z * d.x)
    }
    /// Parametric range `[t0, t1]` of the ray inside the box, clipped to `[0, t_max]`.
    pub fn range(&self, ray: &Ray, inv_dir: Vec3) -> Option<(f32, f32)> {
        let a = (self.lo - ray.origin) * inv_dir;
        let b = (self.hi - ray.origin) * inv_dir;
        // NaN (0 * inf on a face) compares false both ways: min/max of glam
        // ignore it in favour of the other operand, which keeps the slab open.
        let t0 = a.min(b).max_element().max(0.0);
        let t1 = a.max(b).min_element().min(ray.t_max);
        // A tiny relative slack keeps hits exactly on the box faces.
        (t0 <= t1 * (1.0 + 4.0 * f32::EPSILON)).then_some((t0, t1))
    }
}

#[cfg(test)]
mod tests {
    use proptest::prelude::*;

    use super::testing::vec3;
    use super::*;

    proptest! {
        /// `include` is `union` for boxes without NaN, empty ones included.
        #[test]
        fn include_is_union(a in vec3(), b in vec3(), c in vec3(), d in vec3(), empty in 0u8..3) {
            let mut x = Aabb { lo: a.min(b), hi: a.max(b) };
            let y = if empty == 0 { Aabb::EMPTY } else { Aabb { lo: c.min(d), hi: c.max(d) } };
            if empty == 1 {
                x = Aabb::EMPTY;
            }
            let want = x.union(&y);
            x.include(&y);
            prop_assert_eq!(x, want);
        }
    }
}
