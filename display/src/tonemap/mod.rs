//! Tone mapping: world radiance to 8-bit display values.
//!
//! The drivers use the histogram adjustment of Ward Larson, Rushmeier &
//! Piatko ("A Visibility Matching Tone Reproduction Operator for High Dynamic
//! Range Scenes", IEEE TVCG 1997), as the holodeck paper does (§2.4.6): the
//! display gathers a [`Histogram`] as samples arrive and builds a new
//! [`ToneMap`] when asked (a full redraw), because recomputing the mapping on
//! every sample would make the picture flicker and cost time.
//!
//! Histogram adjustment maps world brightness through the cumulative
//! distribution of world brightness, so luminance ranges that many pixels
//! share get more of the display range, then limits that so no range gets
//! more contrast than it has (camera mode) or than a person would see there
//! (human mode). Human mode also removes colour the way night vision does.
//! The paper's other two human effects, veiling glare and loss of acuity, are
//! not modelled: both need the whole image and its field of view, not one
//! pixel at a time, and neither matters for judging a reconstruction.

mod histogram;
pub mod vision;

#[cfg(test)]
mod tests;

pub use histogram::{
    Histogram, BINS_PER_DECADE, DEFAULT_LUMINOUS_EFFICACY, HISTOGRAM_BINS, HISTOGRAM_LOG10_MAX, HISTOGRAM_LOG10_MIN,
};

use holodeck_protocol::Picture;
use rayon::prelude::*;

use histogram::bin_floor;
use vision::{luminance, mesopic_color, threshold_versus_intensity, TOP_MESOPIC};

/// How world radiance becomes display values.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum ToneMode {
    /// Multiply radiance by this and clamp, like `image_io::write_png`; the
    /// histogram is ignored. A non-finite exposure means 1, a negative one 0.
    Exposure(f32),
    /// Histogram adjustment with the linear ceiling: every luminance level in
    /// the picture made visible, none shown with more contrast than it has.
    Camera,
    /// Histogram adjustment with the ceiling from human contrast sensitivity,
    /// plus mesopic/scotopic colour loss: roughly what a person in the scene
    /// would be able to see.
    Human,
}

/// The luminance range the display can show, in cd/m².
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DisplayRange {
    /// Black: the display's luminance at drive value 0 (its own glow and
    /// reflected room light).
    pub ld_min: f32,
    /// White: the display's luminance at drive value 1.
    pub ld_max: f32,
}

impl Default for DisplayRange {
    /// A typical monitor of the paper's time: 1 to 100 cd/m², the 2 decades
    /// `pcond` assumes.
    fn default() -> Self {
        DisplayRange {
            ld_min: 1.0,
            ld_max: 100.0,
        }
    }
}

impl DisplayRange {
    /// The range with nonsense replaced: a maximum that is not finite and
    /// positive becomes 100 cd/m², a minimum that is not finite, positive
    /// and below the maximum becomes 1 % of the maximum.
    pub fn sanitized(self) -> DisplayRange {
        let ld_max = if self.ld_max.is_finite() && self.ld_max > 0.0 {
            self.ld_max
        } else {
            100.0
        };
        let ld_min = if self.ld_min.is_finite() && self.ld_min > 0.0 && self.ld_min < ld_max {
            self.ld_min
        } else {
            ld_max / 100.0
        };
        DisplayRange { ld_min, ld_max }
    }
}

/// Which mapping a [`ToneMap`] ended up with; worth logging, because the
/// fallbacks behave differently from the paper's main case.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum MapKind {
    /// [`ToneMode::Exposure`]: a plain multiply.
    Exposure,
    /// The histogram had no samples: a multiply by 1, as
    /// `Picture::auto_exposure` would give for a picture with nothing in it.
    NoData,
    /// The paper's histogram adjustment converged.
    Adjusted,
    /// The picture's luminance levels need less display range than there is
    /// (few levels, or a narrow range): the paper gives up here and goes
    /// linear. We show every populated level at the ceiling's contrast,
    /// compress the empty ranges between levels evenly to fit, and centre
    /// the result, so a picture of two far-apart levels shows both.
    Sparse,
}

/// Tolerance on trimming (fraction of the histogram total), from the paper.
const TOLERANCE: f64 = 0.025;

/// Guard against the human ceiling oscillating instead of converging.
const MAX_ITERATIONS: usize = 100;

/// Empty bins added on each side of the picture's range, so a sparse picture
/// has room to be centred instead of pinning its darkest level to black.
const MARGIN_BINS: usize = BINS_PER_DECADE;

/// Rounds of the human ceiling's fixed point in the sparse case, where the
/// ceiling depends on where the levels end up on the display.
const SPARSE_ROUNDS: usize = 8;

/// Display log10 luminance at evenly spaced world log10 luminances, linear
/// in between and flat beyond the ends.
#[derive(Clone, Debug, PartialEq)]
struct Curve {
    start: f64,
    step: f64,
    bd: Vec<f64>,
}

impl Curve {
    fn eval(&self, b: f64) -> f64 {
        let n = self.bd.len() - 1;
        let t = (b - self.start) / self.step;
        if t.is_nan() || t <= 0.0 {
            return self.bd[0];
        }
        if t >= n as f64 {
            return self.bd[n];
        }
        let i = (t as usize).min(n - 1);
        let f = t - i as f64;
        self.bd[i] + (self.bd[i + 1] - self.bd[i]) * f
    }

    /// Display log luminance at the centre of bin `j`.
    fn center(&self, j: usize) -> f64 {
        0.5 * (self.bd[j] + self.bd[j + 1])
    }
}

/// The most display contrast a world brightness range may get, as the slope
/// d log Ld / d log Lw at world log luminance `bw` shown at display log
/// luminance `bd`: 1 for the camera (never steeper than linear), and for a
/// person the slope at which a just-visible world difference becomes a
/// just-visible display difference, ΔLt(Ld) Lw / (ΔLt(Lw) Ld).
fn ceiling_slope(human: bool, bw: f64, bd: f64) -> f64 {
    if !human {
        return 1.0;
    }
    let (lw, ld) = (10f64.powf(bw), 10f64.powf(bd));
    let s = threshold_versus_intensity(ld) / threshold_versus_intensity(lw) * lw / ld;
    if s.is_finite() && s > 0.0 {
        s
    } else {
        1.0
    }
}

/// Builds the display curve by cumulating per-bin display shares `d`
/// (log10 units) from `bd0`.
fn cumulate(start: f64, step: f64, bd0: f64, d: &[f64]) -> Curve {
    let mut bd = Vec::with_capacity(d.len() + 1);
    bd.push(bd0);
    let mut acc = bd0;
    for &x in d {
        acc += x;
        bd.push(acc);
    }
    Curve { start, step, bd }
}

/// Histogram adjustment (the paper's `histogram_ceiling` loop, as in
/// `pcond`'s `mkbrmap`), with the sparse fallback described at
/// [`MapKind::Sparse`]. Returns `None` for an empty histogram.
fn build_curve(hist: &Histogram, human: bool, bld_min: f64, bld_max: f64) -> Option<(Curve, MapKind)> {
    let bins = hist.bins();
    let first = bins.iter().position(|&n| n > 0)?;
    let last = bins.iter().rposition(|&n| n > 0)?;
    let step = 1.0 / BINS_PER_DECADE as f64;
    let r = bld_max - bld_min;
    let n = last - first + 1 + 2 * MARGIN_BINS;
    let start = bin_floor(first) - MARGIN_BINS as f64 * step;
    let f: Vec<f64> = (0..n)
        .map(|j| match (j + first).checked_sub(MARGIN_BINS) {
            Some(i) if i <= last => bins[i] as f64,
            _ => 0.0,
        })
        .collect();
    let bw_center = |j: usize| start + (j as f64 + 0.5) * step;
    let total: f64 = f.iter().sum();

    let mut fm = f.clone();
    let mut adjusted = false;
    for _ in 0..MAX_ITERATIONS {
        let t: f64 = fm.iter().sum();
        if t <= TOLERANCE * total {
            break;
        }
        let current = human.then(|| cumulate(start, step, bld_min, &fm.iter().map(|x| r * x / t).collect::<Vec<_>>()));
        let mut trimmings = 0.0;
        for (j, x) in fm.iter_mut().enumerate() {
            let bd = current.as_ref().map_or(0.0, |c| c.center(j));
            let ceiling = t * ceiling_slope(human, bw_center(j), bd) * step / r;
            if *x > ceiling {
                trimmings += *x - ceiling;
                *x = ceiling;
            }
        }
        if trimmings <= TOLERANCE * t {
            adjusted = true;
            break;
        }
    }
    let t: f64 = fm.iter().sum();
    if adjusted && t > TOLERANCE * total {
        let d: Vec<f64> = fm.iter().map(|x| r * x / t).collect();
        return Some((cumulate(start, step, bld_min, &d), MapKind::Adjusted));
    }

    // Sparse: populated bins at the ceiling slope, empty ones share the rest.
    let mut slope = vec![1.0; n];
    let mut curve = None;
    for _ in 0..if human { SPARSE_ROUNDS } else { 1 } {
        let mut d: Vec<f64> = (0..n).map(|j| if f[j] > 0.0 { slope[j] * step } else { 0.0 }).collect();
        let used: f64 = d.iter().sum();
        if used > r {
            d.iter_mut().for_each(|x| *x *= r / used);
        }
        let left = (r - used).max(0.0);
        let empty = f.iter().filter(|&&x| x == 0.0).count() as f64 * step;
        let mu = if empty > 0.0 { (left / empty).min(1.0) } else { 0.0 };
        for (x, &count) in d.iter_mut().zip(&f) {
            if count == 0.0 {
                *x = mu * step;
            }
        }
        let spread: f64 = d.iter().sum();
        let c = cumulate(start, step, bld_min + 0.5 * (r - spread).max(0.0), &d);
        if human {
            for (j, s) in slope.iter_mut().enumerate() {
                *s = ceiling_slope(true, bw_center(j), c.center(j));
            }
        }
        curve = Some(c);
    }
    curve.map(|c| (c, MapKind::Sparse))
}

/// A mapping from linear RGB radiance to 8-bit sRGB display values, fixed at
/// construction: build a new one when the histogram has grown enough to
/// matter.
#[derive(Clone, Debug, PartialEq)]
pub struct ToneMap {
    mode: ToneMode,
    range: DisplayRange,
    kind: MapKind,
    efficacy: f64,
    exposure: f64,
    curve: Option<Curve>,
    mesopic: bool,
}

impl ToneMap {
    /// The mapping for the samples in `hist`, shown on a display with
    /// `range` (sanitized, see [`DisplayRange::sanitized`]).
    ///
    /// In human mode colour is taken away only if at least 5 % of the
    /// histogram is below the top of the mesopic range, as `pcond` does: a
    /// viewer adapted to a bright scene still sees its few dark corners in
    /// colour.
    pub fn new(hist: &Histogram, mode: ToneMode, range: DisplayRange) -> ToneMap {
        let range = range.sanitized();
        let efficacy = f64::from(hist.luminous_efficacy());
        let mut map = ToneMap {
            mode,
            range,
            kind: MapKind::NoData,
            efficacy,
            exposure: 1.0,
            curve: None,
            mesopic: false,
        };
        let human = match mode {
            ToneMode::Exposure(e) => {
                map.kind = MapKind::Exposure;
                map.exposure = if e.is_nan() || e.is_infinite() {
                    1.0
                } else {
                    f64::from(e.max(0.0))
                };
                return map;
            }
            ToneMode::Camera => false,
            ToneMode::Human => true,
        };
        let (bld_min, bld_max) = (f64::from(range.ld_min).log10(), f64::from(range.ld_max).log10());
        if let Some((curve, kind)) = build_curve(hist, human, bld_min, bld_max) {
            map.curve = Some(curve);
            map.kind = kind;
            map.mesopic = human && hist.percentile(0.05).is_some_and(|l| l < TOP_MESOPIC);
        }
        map
    }

    /// The mapping for a whole picture on the default display.
    pub fn from_picture(p: &Picture, mode: ToneMode) -> ToneMap {
        ToneMap::new(&Histogram::from_picture(p), mode, DisplayRange::default())
    }

    /// The mode asked for.
    pub fn mode(&self) -> ToneMode {
        self.mode
    }

    /// The display range in use (after sanitizing).
    pub fn display_range(&self) -> DisplayRange {
        self.range
    }

    /// Which mapping was built.
    pub fn kind(&self) -> MapKind {
        self.kind
    }

    /// The brightness curve as (log10 world cd/m², log10 display cd/m²)
    /// knots, linear in between and flat outside; empty for a plain multiply.
    /// For charts and for drivers that map on the GPU.
    pub fn brightness_curve(&self) -> Vec<(f64, f64)> {
        self.curve.as_ref().map_or_else(Vec::new, |c| {
            c.bd.iter()
                .enumerate()
                .map(|(i, &bd)| (c.start + i as f64 * c.step, bd))
                .collect()
        })
    }

    /// The display luminance (cd/m²) a grey of world luminance `lw` (cd/m²)
    /// is shown at, within the display range.
    pub fn display_luminance(&self, lw: f64) -> f64 {
        let (ld_min, ld_max) = (f64::from(self.range.ld_min), f64::from(self.range.ld_max));
        if lw.is_nan() || lw <= 0.0 {
            return ld_min;
        }
        match &self.curve {
            Some(c) => 10f64.powf(c.eval(lw.log10())),
            None => ld_min + (ld_max - ld_min) * (self.exposure * lw / self.efficacy).min(1.0),
        }
    }

    /// Linear display drive values in 0..=1 (before the sRGB transfer), for
    /// drivers that encode on their own.
    ///
    /// Chromaticity is kept by scaling RGB by display over world luminance;
    /// a colour that then leaves the display gamut is desaturated toward its
    /// grey until it fits, so the luminance the curve chose is what is shown.
    /// (The plain multiply clamps each channel instead, as `write_png` does.)
    /// A pixel with a non-finite channel is black; negative channels count
    /// as 0.
    pub fn map_linear(&self, rgb: [f32; 3]) -> [f32; 3] {
        if !rgb.iter().all(|v| v.is_finite()) {
            return [0.0; 3];
        }
        let c = rgb.map(|v| f64::from(v).max(0.0));
        let Some(curve) = &self.curve else {
            return c.map(|v| (v * self.exposure).min(1.0) as f32);
        };
        let mut c = c;
        let mut y = luminance(c);
        if self.mesopic {
            c = mesopic_color(c, y * self.efficacy);
            y = luminance(c);
        }
        if y.is_nan() || y <= 0.0 {
            return [0.0; 3];
        }
        let (ld_min, ld_max) = (f64::from(self.range.ld_min), f64::from(self.range.ld_max));
        let ld = 10f64.powf(curve.eval((y * self.efficacy).log10()));
        let v = ((ld - ld_min) / (ld_max - ld_min)).clamp(0.0, 1.0);
        let k = v / y;
        let mut out = c.map(|x| x * k);
        let m = out[0].max(out[1]).max(out[2]);
        if m > 1.0 {
            if v >= 1.0 {
                return [1.0; 3];
            }
            let t = (1.0 - v) / (m - v);
            out = out.map(|x| v + t * (x - v));
        }
        out.map(|x| x.clamp(0.0, 1.0) as f32)
    }

    /// 8-bit sRGB display values for one radiance.
    pub fn map(&self, rgb: [f32; 3]) -> [u8; 3] {
        self.map_linear(rgb).map(encode_srgb)
    }

    /// RGB8 bytes for a picture, rows from the top, one triple per pixel in
    /// `p.pixels` (which for a well-formed picture is `width * height`).
    /// Large pictures are mapped in parallel.
    pub fn apply(&self, p: &Picture) -> Vec<u8> {
        const PARALLEL_PIXELS: usize = 1 << 16;
        const CHUNK: usize = 4096;
        let mut out = vec![0u8; 3 * p.pixels.len()];
        let run = |(px, o): (&[glam::Vec3], &mut [u8])| {
            for (c, o) in px.iter().zip(o.chunks_exact_mut(3)) {
                o.copy_from_slice(&self.map(c.to_array()));
            }
        };
        if p.pixels.len() >= PARALLEL_PIXELS {
            p.pixels
                .par_chunks(CHUNK)
                .zip(out.par_chunks_mut(3 * CHUNK))
                .for_each(run);
        } else {
            run((&p.pixels, &mut out));
        }
        out
    }
}

/// The sRGB transfer function to 8 bits, the same as `image_io` uses:
/// [`encode_srgb_exact`]'s value, found among the 255 steps where its
/// output rises (the function rises monotonically), with no power function
/// per value (which a web page's WebAssembly computes slowly).
pub fn encode_srgb(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    srgb_steps().partition_point(|&step| step <= v) as u8
}

/// Where [`encode_srgb_exact`] rises: entry `k` is the least value in 0..=1
/// it encodes as `k + 1` or more, found once by bisecting the float's bits.
fn srgb_steps() -> &'static [f32; 255] {
    static STEPS: std::sync::OnceLock<[f32; 255]> = std::sync::OnceLock::new();
    STEPS.get_or_init(|| {
        let mut steps = [0f32; 255];
        for (k, step) in steps.iter_mut().enumerate() {
            let target = k as u8 + 1;
            // Non-negative floats order as their bits do.
            let (mut lo, mut hi) = (0u32, 1f32.to_bits());
            while lo < hi {
                let mid = lo + (hi - lo) / 2;
                if encode_srgb_exact(f32::from_bits(mid)) >= target {
                    hi = mid;
                } else {
                    lo = mid + 1;
                }
            }
            *step = f32::from_bits(lo);
        }
        steps
    })
}

/// The sRGB transfer function to 8 bits, computed: what [`encode_srgb`]
/// gives by table.
pub fn encode_srgb_exact(v: f32) -> u8 {
    let v = if v.is_nan() { 0.0 } else { v.clamp(0.0, 1.0) };
    let s = if v <= 0.003_130_8 {
        12.92 * v
    } else {
        1.055 * v.powf(1.0 / 2.4) - 0.055
    };
    (s * 255.0 + 0.5) as u8
}

/// The inverse of [`encode_srgb`]: linear 0..=1 from an 8-bit sRGB value.
pub fn decode_srgb(v: u8) -> f32 {
    let s = f32::from(v) / 255.0;
    if s <= 0.040_45 {
        s / 12.92
    } else {
        ((s + 0.055) / 1.055).powf(2.4)
    }
}
