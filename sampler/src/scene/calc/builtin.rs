//! The functions and constants every function file may use without
//! defining them: Radiance's core library (`if`, `select`, `min`, `max`,
//! `rand`, `floor`, `ceil`, `sqrt`, the trigonometric functions, `exp`,
//! `log`, `log10`), the renderer's (`arg`, `erf`, `erfc`, the noise
//! functions, the light-source corrections), the names Radiance's start-up
//! file defines (`PI`, `DEGREE`, `AC`, `A1`..., `abs`, `sgn`, `bound`,
//! `and`, `or`, `dot`, `U`, `V`, ...) and those of its `source.cal` and
//! `tilt.cal` (`src_theta`, `src_phi`, `flatcorr`, `boxcorr`, ...), all
//! written here natively from their published definitions.

use serde::{Deserialize, Serialize};

/// A native function or constant.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
pub enum Builtin {
    If,
    Select,
    Min,
    Max,
    Rand,
    Floor,
    Ceil,
    Sqrt,
    Sin,
    Cos,
    Tan,
    Asin,
    Acos,
    Atan,
    Atan2,
    Exp,
    Log,
    Log10,
    Arg,
    Erf,
    Erfc,
    Noise3,
    Noise3x,
    Noise3y,
    Noise3z,
    Noise3d,
    Fnoise3,
    SourceCorr,
    SourceTheta,
    SourcePhi,
    Pi,
    Degree,
    Ftiny,
    Bound,
    SafeAcos,
    SafeAsin,
    SafeAtan2,
    SafeExp,
    SafeSqrt,
    And,
    Or,
    Not,
    Xor,
    Abs,
    Sgn,
    Sq,
    Inside,
    Frac,
    Mod,
    Tri,
    Linterp,
    Noop,
    Clip,
    Noneg,
    Red,
    Green,
    Blue,
    Grey,
    ClipR,
    ClipG,
    ClipB,
    ClipGrey,
    Fade,
    Hermite,
    Bezier,
    Bspline,
    Turbulence,
    Unif2Norm,
    Nrand,
    DComp,
    NComp,
    PComp,
    Dot,
    Cross,
    U,
    V,
    /// `source.cal`'s coordinates and corrections, by what they call.
    SrcTheta,
    SrcPhi(u16),
    SrcBVert,
    SrcBHoriz,
    SrcBVert2,
    SrcBHoriz2,
    /// `corr`, `flatcorr`, `boxcorr`, `lboxcorr`, `cylcorr`: `source_corr(v, k)`.
    Corr(u8),
    /// `tilt.cal`'s angles: `tilt_ang`, `tilt_ang2`, `tilt_xang`, `tilt_xang2`.
    TiltAng,
    TiltAng2,
    TiltXang,
    TiltXang2,
}

/// The native named `name`, if any.
pub fn named(name: &str) -> Option<Builtin> {
    use Builtin::*;
    Some(match name {
        "if" => If,
        "select" => Select,
        "min" => Min,
        "max" => Max,
        "rand" => Rand,
        "floor" => Floor,
        "ceil" => Ceil,
        "sqrt" => Sqrt,
        "sin" => Sin,
        "cos" => Cos,
        "tan" => Tan,
        "asin" => Asin,
        "acos" => Acos,
        "atan" => Atan,
        "atan2" => Atan2,
        "exp" => Exp,
        "log" => Log,
        "log10" => Log10,
        "arg" => Arg,
        "erf" => Erf,
        "erfc" => Erfc,
        "noise3" => Noise3,
        "noise3x" | "noise3a" => Noise3x,
        "noise3y" | "noise3b" => Noise3y,
        "noise3z" | "noise3c" => Noise3z,
        "noise3d" => Noise3d,
        "fnoise3" => Fnoise3,
        "source_corr" => SourceCorr,
        "source_theta" => SourceTheta,
        "source_phi" => SourcePhi,
        "PI" => Pi,
        "DEGREE" => Degree,
        "FTINY" => Ftiny,
        "bound" => Bound,
        "Acos" => SafeAcos,
        "Asin" => SafeAsin,
        "Atan2" => SafeAtan2,
        "Exp" => SafeExp,
        "Sqrt" => SafeSqrt,
        "and" => And,
        "or" => Or,
        "not" => Not,
        "xor" => Xor,
        "abs" => Abs,
        "sgn" => Sgn,
        "sq" => Sq,
        "inside" => Inside,
        "frac" => Frac,
        "mod" => Mod,
        "tri" => Tri,
        "linterp" => Linterp,
        "noop" => Noop,
        "clip" => Clip,
        "noneg" => Noneg,
        "red" => Red,
        "green" => Green,
        "blue" => Blue,
        "grey" => Grey,
        "clip_r" => ClipR,
        "clip_g" => ClipG,
        "clip_b" => ClipB,
        "clipgrey" => ClipGrey,
        "fade" => Fade,
        "hermite" => Hermite,
        "bezier" => Bezier,
        "bspline" => Bspline,
        "turbulence" => Turbulence,
        "unif2norm" => Unif2Norm,
        "nrand" => Nrand,
        "D" => DComp,
        "N" => NComp,
        "P" => PComp,
        "dot" => Dot,
        "cross" => Cross,
        "U" => U,
        "V" => V,
        "src_theta" => SrcTheta,
        "src_phi" => SrcPhi(360),
        "src_phi2" => SrcPhi(180),
        "src_phi4" => SrcPhi(90),
        "srcB_vert" => SrcBVert,
        "srcB_horiz" => SrcBHoriz,
        "srcB_vert2" => SrcBVert2,
        "srcB_horiz2" => SrcBHoriz2,
        "corr" => Corr(0),
        "flatcorr" => Corr(1),
        "boxcorr" => Corr(2),
        "lboxcorr" => Corr(3),
        "cylcorr" => Corr(4),
        "tilt_ang" => TiltAng,
        "tilt_ang2" => TiltAng2,
        "tilt_xang" => TiltXang,
        "tilt_xang2" => TiltXang2,
        _ => return None,
    })
}

/// Whether `b` is a value named without arguments (`PI`, `U`, `src_theta`).
pub fn is_value(b: Builtin) -> bool {
    use Builtin::*;
    matches!(
        b,
        Pi | Degree
            | Ftiny
            | U
            | V
            | SrcTheta
            | SrcPhi(_)
            | SrcBVert
            | SrcBHoriz
            | SrcBVert2
            | SrcBHoriz2
            | TiltAng
            | TiltAng2
            | TiltXang
            | TiltXang2
    )
}

/// Radiance's `rand`: a number in [0, 1) that depends only on `x`.
pub fn rand(x: f64) -> f64 {
    let x1 = x * (1.0 / (1.0 + x * x) + std::f64::consts::E);
    let x2 = x1 + std::f64::consts::FRAC_PI_4 - x1.floor();
    let r = 1e5 / x2;
    r - r.floor()
}

/// The error function (Abramowitz and Stegun 7.1.26, within 1.5e-7).
pub fn erf(x: f64) -> f64 {
    let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
    let poly =
        t * (0.254_829_592 + t * (-0.284_496_736 + t * (1.421_413_741 + t * (-1.453_152_027 + t * 1.061_405_429))));
    let y = 1.0 - poly * (-x * x).exp();
    if x < 0.0 {
        -y
    } else {
        y
    }
}

/// A table of the numbers 0 to 255 in a fixed shuffled order, for
/// [`noise3`].
fn permutation() -> &'static [u8; 512] {
    static TABLE: std::sync::OnceLock<[u8; 512]> = std::sync::OnceLock::new();
    TABLE.get_or_init(|| {
        let mut p: [u8; 256] = std::array::from_fn(|i| i as u8);
        let mut state = 0x2545_f491_4f6c_dd1du64;
        for i in (1..256).rev() {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            p.swap(i, (state % (i as u64 + 1)) as usize);
        }
        std::array::from_fn(|i| p[i & 255])
    })
}

/// Gradient noise in [-1, 1] with value 0 at integer points, smooth (its
/// fade is 6t⁵ − 15t⁴ + 10t³), as Perlin's improved noise; its lattice
/// shuffle is this program's own, so the pattern is Radiance's in kind,
/// not texel for texel.
pub fn noise3(x: f64, y: f64, z: f64) -> f64 {
    if !(x.is_finite() && y.is_finite() && z.is_finite()) {
        return 0.0;
    }
    let p = permutation();
    let cell = |v: f64| (v.floor().rem_euclid(256.0)) as usize;
    let (xi, yi, zi) = (cell(x), cell(y), cell(z));
    let (xf, yf, zf) = (x - x.floor(), y - y.floor(), z - z.floor());
    let fade = |t: f64| t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
    let grad = |h: u8, x: f64, y: f64, z: f64| {
        let h = h & 15;
        let u = if h < 8 { x } else { y };
        let v = if h < 4 {
            y
        } else if h == 12 || h == 14 {
            x
        } else {
            z
        };
        (if h & 1 == 0 { u } else { -u }) + (if h & 2 == 0 { v } else { -v })
    };
    let (u, v, w) = (fade(xf), fade(yf), fade(zf));
    let a = p[xi] as usize + yi;
    let (aa, ab) = (p[a] as usize + zi, p[a + 1] as usize + zi);
    let b = p[xi + 1] as usize + yi;
    let (ba, bb) = (p[b] as usize + zi, p[b + 1] as usize + zi);
    let lerp = |t: f64, a: f64, b: f64| a + t * (b - a);
    lerp(
        w,
        lerp(
            v,
            lerp(u, grad(p[aa], xf, yf, zf), grad(p[ba], xf - 1.0, yf, zf)),
            lerp(u, grad(p[ab], xf, yf - 1.0, zf), grad(p[bb], xf - 1.0, yf - 1.0, zf)),
        ),
        lerp(
            v,
            lerp(
                u,
                grad(p[aa + 1], xf, yf, zf - 1.0),
                grad(p[ba + 1], xf - 1.0, yf, zf - 1.0),
            ),
            lerp(
                u,
                grad(p[ab + 1], xf, yf - 1.0, zf - 1.0),
                grad(p[bb + 1], xf - 1.0, yf - 1.0, zf - 1.0),
            ),
        ),
    )
}

/// The partial derivative of [`noise3`] along axis `k` (0, 1, 2), by a
/// backward difference of 0.0005 as Radiance takes it.
pub fn noise3_slope(k: usize, x: f64, y: f64, z: f64) -> f64 {
    const EPS: f64 = 0.0005;
    let mut q = [x, y, z];
    q[k] -= EPS;
    (noise3(x, y, z) - noise3(q[0], q[1], q[2])) / EPS
}

/// Fractal noise: octaves of [`noise3`] down to a 2000th of a unit, each
/// half the amplitude of the one before (Radiance's `fnoise3` in kind).
pub fn fnoise3(x: f64, y: f64, z: f64) -> f64 {
    let (mut sum, mut scale) = (0.0, 1.0);
    for _ in 0..11 {
        sum += noise3(x / scale, y / scale, z / scale) * scale;
        scale *= 0.5;
    }
    sum * 0.5
}

/// The inverse of the standard normal distribution (Abramowitz and Stegun
/// 26.2.23).
pub fn unif2norm(p: f64) -> f64 {
    let q = if p < 0.5 { p } else { 1.0 - p };
    if q <= 0.0 {
        return 0.0;
    }
    let t = (-2.0 * q.ln()).sqrt();
    let x =
        t - (2.515_517 + t * (0.802_853 + t * 0.010_328)) / (1.0 + t * (1.432_788 + t * (0.189_269 + t * 0.001_308)));
    if p < 0.5 {
        -x
    } else {
        x
    }
}
