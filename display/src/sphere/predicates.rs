//! Exact predicates on directions, and the one place a direction becomes a
//! point on the unit sphere.
//!
//! Every topological decision of the mesh goes through [`side`] or
//! [`in_circle`], which are exact for any finite inputs (Shewchuk's adaptive
//! orientation test from the `robust` crate); floating point only measures
//! closeness ([`chord2`]). Nothing here knows triangles.

use glam::DVec3;
use robust::{orient3d, Coord3D};

use super::SphereError;

/// Components smaller than this become zero when a direction is made unit:
/// the predicates' exact products of three coordinates would otherwise
/// underflow, and a turn of 1e-60 radians means nothing.
const FLUSH: f64 = 1e-60;

#[inline]
fn coord(p: DVec3) -> Coord3D<f64> {
    Coord3D { x: p.x, y: p.y, z: p.z }
}

/// Shewchuk's error bound for the first, plain floating-point stage of
/// orient3d: a determinant larger than this times its permanent has the
/// right sign.
const ORIENT3D_BOUND: f64 = (7.0 + 56.0 * f64::EPSILON / 2.0) * (f64::EPSILON / 2.0);

/// det[a - d, b - d, c - d], exact in sign: the `robust` crate's orient3d,
/// with its first stage inlined because nearly every call ends there.
#[inline(always)]
fn orient3d_exact(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    let (ad, bd, cd) = (a - d, b - d, c - d);
    let bdxcdy = bd.x * cd.y;
    let cdxbdy = cd.x * bd.y;
    let cdxady = cd.x * ad.y;
    let adxcdy = ad.x * cd.y;
    let adxbdy = ad.x * bd.y;
    let bdxady = bd.x * ad.y;
    let det = ad.z * (bdxcdy - cdxbdy) + bd.z * (cdxady - adxcdy) + cd.z * (adxbdy - bdxady);
    let permanent = (bdxcdy.abs() + cdxbdy.abs()) * ad.z.abs()
        + (cdxady.abs() + adxcdy.abs()) * bd.z.abs()
        + (adxbdy.abs() + bdxady.abs()) * cd.z.abs();
    if det.abs() > ORIENT3D_BOUND * permanent {
        det
    } else {
        orient3d_slow(a, b, c, d)
    }
}

#[cold]
#[inline(never)]
fn orient3d_slow(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    orient3d(coord(a), coord(b), coord(c), coord(d))
}

/// The sign of det[a, b, p]: positive when `p` is left of the great-circle
/// arc from `a` to `b` seen from outside the sphere, zero on its plane.
/// `side(a, b, c) > 0` is "abc is counter-clockwise from outside".
#[inline]
pub(crate) fn side(a: DVec3, b: DVec3, p: DVec3) -> f64 {
    orient3d_exact(a, b, p, DVec3::ZERO)
}

/// Positive when `d` is strictly inside the circumcircle of `abc`
/// (counter-clockwise from outside): `d` is beyond the plane of `abc`, on
/// the side away from the origin. Zero when the four are cocircular.
#[inline]
pub(crate) fn in_circle(a: DVec3, b: DVec3, c: DVec3, d: DVec3) -> f64 {
    -orient3d_exact(a, b, c, d)
}

/// The squared chord between two unit directions: monotone in their angle
/// and accurate down to tiny angles, where `1 - cos` is not.
#[inline]
pub(crate) fn chord2(a: DVec3, b: DVec3) -> f64 {
    (a - b).length_squared()
}

/// `dir` scaled to unit length. Any finite, non-zero length works: the
/// direction is first scaled by its largest component, so neither 1e-300
/// nor 1e300 overflows or underflows on the way.
pub(crate) fn unit(dir: DVec3) -> Result<DVec3, SphereError> {
    if !dir.is_finite() {
        return Err(SphereError::NotFinite);
    }
    let largest = dir.abs().max_element();
    if largest == 0.0 {
        return Err(SphereError::Zero);
    }
    let scaled = dir / largest;
    let u = scaled / scaled.length();
    let flush = |c: f64| if c.abs() < FLUSH { 0.0 } else { c };
    Ok(DVec3::new(flush(u.x), flush(u.y), flush(u.z)))
}
