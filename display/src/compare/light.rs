//! Light kept per region: how much of the reference's light a picture
//! shows in its darkest quarter, its middle half, its brightest quarter
//! and the band around silhouettes. An estimate that loses light in
//! shadowed regions is wrong whatever its RMSE, which a few bright pixels
//! rule; these ratios see it.

use holodeck_protocol::Picture;
use serde::Serialize;

use super::radiance::channels;

/// Which part of the reference's luminance range a pixel is in.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[repr(u8)]
pub enum Region {
    /// The darkest quarter of the reference's pixels.
    Dark = 0,
    /// The middle half.
    Middle = 1,
    /// The brightest quarter.
    Bright = 2,
}

/// Each pixel's [`Region`], by the rank of its luminance in the reference
/// (ties broken by pixel order, so the quarters are exact).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Regions {
    region: Vec<Region>,
}

impl Regions {
    /// The regions of `reference`'s pixels.
    pub fn of(reference: &Picture) -> Regions {
        let n = reference.pixels.len();
        let lum: Vec<f64> = reference.pixels.iter().map(|&v| luminance3(channels(v))).collect();
        let mut order: Vec<u32> = (0..n as u32).collect();
        order.sort_by(|&a, &b| lum[a as usize].total_cmp(&lum[b as usize]).then(a.cmp(&b)));
        let mut region = vec![Region::Middle; n];
        let (dark, bright) = (n / 4, n - n / 4);
        for (rank, &i) in order.iter().enumerate() {
            region[i as usize] = if rank < dark {
                Region::Dark
            } else if rank >= bright {
                Region::Bright
            } else {
                Region::Middle
            };
        }
        Regions { region }
    }

    /// The region of pixel `i` (row-major, top row first).
    pub fn get(&self, i: usize) -> Region {
        self.region[i]
    }

    /// Pixels classified.
    pub fn len(&self) -> usize {
        self.region.len()
    }

    /// True for an empty picture.
    pub fn is_empty(&self) -> bool {
        self.region.is_empty()
    }
}

/// The ratio of a picture's luminance to the reference's, summed over each
/// region of the reference: 1 keeps all its light, 0.5 shows half of it,
/// 2 twice as much. NaN where the reference has no light there.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct LightKept {
    /// Over the whole frame.
    pub frame: f64,
    /// Over the darkest quarter of the reference's pixels.
    pub dark: f64,
    /// Over the middle half.
    pub middle: f64,
    /// Over the brightest quarter.
    pub bright: f64,
    /// Over the band around silhouettes, where one is given.
    pub band: Option<f64>,
}

impl LightKept {
    /// Every ratio there is: the frame, the three regions and the band
    /// where one was given.
    fn ratios(&self) -> impl Iterator<Item = f64> {
        [
            Some(self.frame),
            Some(self.dark),
            Some(self.middle),
            Some(self.bright),
            self.band,
        ]
        .into_iter()
        .flatten()
    }

    /// The ratio farthest from 1 (in the ratio's own log scale, so that 0.5
    /// and 2 are equally far), NaN ones left out; NaN if all are.
    pub fn worst(&self) -> f64 {
        self.ratios()
            .filter(|r| !r.is_nan())
            .max_by(|a, b| a.ln().abs().total_cmp(&b.ln().abs()))
            .unwrap_or(f64::NAN)
    }

    /// True when every ratio (of those that exist) is within `1 ± slack`.
    pub fn within(&self, slack: f64) -> bool {
        self.ratios().all(|r| r.is_nan() || (r - 1.0).abs() <= slack)
    }
}

fn luminance3(c: [f64; 3]) -> f64 {
    0.2126 * c[0] + 0.7152 * c[1] + 0.0722 * c[2]
}

/// Sums `test` / sums `reference`: 1 when both are 0, NaN when only the reference is.
fn kept(test: f64, reference: f64) -> f64 {
    if reference > 0.0 {
        test / reference
    } else if test == 0.0 {
        1.0
    } else {
        f64::NAN
    }
}

/// The light `a` keeps of `b`'s in each of `regions` (made from `b`) and in
/// `band`, over the pixels whose `mask` entry is true. Sizes must have been
/// checked.
pub(super) fn light_kept(
    a: &Picture,
    b: &Picture,
    regions: &Regions,
    band: Option<&[bool]>,
    mask: Option<&[bool]>,
) -> LightKept {
    // Per region: test sum, reference sum; then the band; then the frame.
    let mut s = [[0.0f64; 2]; 5];
    for (i, (&pa, &pb)) in a.pixels.iter().zip(&b.pixels).enumerate() {
        if mask.is_some_and(|m| !m[i]) {
            continue;
        }
        let (la, lb) = (luminance3(channels(pa)), luminance3(channels(pb)));
        let mut add = |k: usize| {
            s[k][0] += la;
            s[k][1] += lb;
        };
        add(regions.get(i) as usize);
        if band.is_some_and(|m| m[i]) {
            add(3);
        }
        add(4);
    }
    LightKept {
        frame: kept(s[4][0], s[4][1]),
        dark: kept(s[0][0], s[0][1]),
        middle: kept(s[1][0], s[1][1]),
        bright: kept(s[2][0], s[2][1]),
        band: band.map(|_| kept(s[3][0], s[3][1])),
    }
}

/// The brightest luminance of `a` within two pixels of `b`'s brightest
/// pixel, over that pixel's luminance (1 when `b` is black and so is `a`
/// there; NaN when only `b` is). Sizes must have been checked.
pub(super) fn peak_kept(a: &Picture, b: &Picture) -> f64 {
    const REACH: usize = 2;
    let lum = |v| luminance3(channels(v));
    let Some((at, top)) = b
        .pixels
        .iter()
        .map(|&v| lum(v))
        .enumerate()
        .max_by(|x, y| x.1.total_cmp(&y.1))
    else {
        return f64::NAN;
    };
    let (w, h) = (b.width, b.height);
    let (c, r) = (at % w, at / w);
    let mut best = 0.0f64;
    for rr in r.saturating_sub(REACH)..=(r + REACH).min(h - 1) {
        for cc in c.saturating_sub(REACH)..=(c + REACH).min(w - 1) {
            best = best.max(lum(a.pixels[rr * w + cc]));
        }
    }
    kept(best, top)
}
