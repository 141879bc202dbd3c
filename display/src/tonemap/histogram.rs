//! The brightness histogram a display gathers as samples arrive (Ward et al.
//! 1999, §2.4.6): fixed log-luminance bins, so adding samples never rebins and
//! a tone map can be recomputed from it at any moment.

use holodeck_protocol::Picture;

use super::vision::LUMINANCE_WEIGHTS;

/// Radiance's luminous efficacy of its equal-energy white (lm/W): multiplied
/// into radiance it gives luminance in cd/m², which human mode needs because
/// what the eye sees depends on absolute level.
pub const DEFAULT_LUMINOUS_EFFICACY: f32 = 179.0;

/// log10 of the lowest luminance (cd/m²) with a bin of its own; below starlight.
pub const HISTOGRAM_LOG10_MIN: f64 = -6.0;

/// log10 of the highest luminance (cd/m²) with a bin of its own; above the
/// solar disc, so sun sources land in their own bins too.
pub const HISTOGRAM_LOG10_MAX: f64 = 10.0;

/// Bins per decade. A bin (0.05 decades, 12 %) is about twice the photopic
/// contrast threshold, fine enough that the mapping has no visible steps and
/// coarse enough that a sparse picture still has meaningful counts.
pub const BINS_PER_DECADE: usize = 20;

/// Number of bins between [`HISTOGRAM_LOG10_MIN`] and [`HISTOGRAM_LOG10_MAX`].
pub const HISTOGRAM_BINS: usize = ((HISTOGRAM_LOG10_MAX - HISTOGRAM_LOG10_MIN) as usize) * BINS_PER_DECADE;

/// A histogram of log10 world luminance, fed one sample at a time.
///
/// Luminances outside the binned range are counted in the end bins (and in
/// the minimum and maximum, which are exact), so nothing a display sees is
/// lost. Samples with a non-finite channel or a luminance that is not
/// positive carry no brightness to adapt to and are only counted as skipped.
#[derive(Clone, Debug, PartialEq)]
pub struct Histogram {
    bins: Vec<u64>,
    count: u64,
    skipped: u64,
    min_log10: f64,
    max_log10: f64,
    sum_log10: f64,
    efficacy: f32,
}

impl Default for Histogram {
    fn default() -> Self {
        Histogram::new()
    }
}

/// The bin a log10 luminance falls into; out-of-range values go to the ends.
pub(crate) fn bin_of(log10_l: f64) -> usize {
    let t = ((log10_l - HISTOGRAM_LOG10_MIN) * BINS_PER_DECADE as f64).floor();
    if t.is_nan() || t < 0.0 {
        0
    } else {
        (t as usize).min(HISTOGRAM_BINS - 1)
    }
}

/// The lower edge of bin `i` in log10 cd/m².
pub(crate) fn bin_floor(i: usize) -> f64 {
    HISTOGRAM_LOG10_MIN + i as f64 / BINS_PER_DECADE as f64
}

impl Histogram {
    /// An empty histogram at [`DEFAULT_LUMINOUS_EFFICACY`].
    pub fn new() -> Histogram {
        Histogram::with_luminous_efficacy(DEFAULT_LUMINOUS_EFFICACY)
    }

    /// An empty histogram whose radiance unit is `efficacy` cd/m² per unit of
    /// luminance. A value that is not finite and positive falls back to the
    /// default rather than making every sample invisible.
    pub fn with_luminous_efficacy(efficacy: f32) -> Histogram {
        let efficacy = if efficacy.is_finite() && efficacy > 0.0 {
            efficacy
        } else {
            DEFAULT_LUMINOUS_EFFICACY
        };
        Histogram {
            bins: vec![0; HISTOGRAM_BINS],
            count: 0,
            skipped: 0,
            min_log10: f64::INFINITY,
            max_log10: f64::NEG_INFINITY,
            sum_log10: 0.0,
            efficacy,
        }
    }

    /// The histogram of every pixel of a picture, in pixel order (so it equals
    /// adding the same pixels one by one).
    pub fn from_picture(p: &Picture) -> Histogram {
        let mut h = Histogram::new();
        h.add_many(p.pixels.iter().copied());
        h
    }

    /// The luminance in cd/m² of a linear RGB radiance, or `None` if it
    /// cannot be adapted to.
    pub fn world_luminance(&self, rgb: [f32; 3]) -> Option<f64> {
        if !rgb.iter().all(|v| v.is_finite()) {
            return None;
        }
        let y = LUMINANCE_WEIGHTS[0] * f64::from(rgb[0])
            + LUMINANCE_WEIGHTS[1] * f64::from(rgb[1])
            + LUMINANCE_WEIGHTS[2] * f64::from(rgb[2]);
        let l = y * f64::from(self.efficacy);
        (l > 0.0 && l.is_finite()).then_some(l)
    }

    /// Adds one sample of linear RGB radiance.
    pub fn add(&mut self, rgb: [f32; 3]) {
        let Some(l) = self.world_luminance(rgb) else {
            self.skipped += 1;
            return;
        };
        let b = l.log10();
        self.bins[bin_of(b)] += 1;
        self.count += 1;
        self.min_log10 = self.min_log10.min(b);
        self.max_log10 = self.max_log10.max(b);
        self.sum_log10 += b;
    }

    /// Adds samples in order; anything convertible to `[f32; 3]` (a
    /// `glam::Vec3` too) will do.
    pub fn add_many<I>(&mut self, samples: I)
    where
        I: IntoIterator,
        I::Item: Into<[f32; 3]>,
    {
        for s in samples {
            self.add(s.into());
        }
    }

    /// Adds every pixel of a picture.
    pub fn add_picture(&mut self, p: &Picture) {
        self.add_many(p.pixels.iter().copied());
    }

    /// Forgets every sample (after a large view change the old brightness
    /// distribution no longer describes what is on screen), keeping the
    /// efficacy.
    pub fn clear(&mut self) {
        *self = Histogram::with_luminous_efficacy(self.efficacy);
    }

    /// Samples counted in the bins.
    pub fn count(&self) -> u64 {
        self.count
    }

    /// Samples skipped: a non-finite channel or a luminance that is not positive.
    pub fn skipped(&self) -> u64 {
        self.skipped
    }

    /// True when no sample has been counted (skipped ones do not count).
    pub fn is_empty(&self) -> bool {
        self.count == 0
    }

    /// cd/m² per unit of radiance luminance.
    pub fn luminous_efficacy(&self) -> f32 {
        self.efficacy
    }

    /// The bin counts, from [`HISTOGRAM_LOG10_MIN`] up in steps of
    /// 1/[`BINS_PER_DECADE`] decades.
    pub fn bins(&self) -> &[u64] {
        &self.bins
    }

    /// The lowest luminance counted, in cd/m².
    pub fn min_luminance(&self) -> Option<f64> {
        (self.count > 0).then(|| 10f64.powf(self.min_log10))
    }

    /// The highest luminance counted, in cd/m².
    pub fn max_luminance(&self) -> Option<f64> {
        (self.count > 0).then(|| 10f64.powf(self.max_log10))
    }

    /// The log-average (geometric mean) luminance counted, in cd/m²: the
    /// adaptation level of the classic exposure rules.
    pub fn log_average_luminance(&self) -> Option<f64> {
        (self.count > 0).then(|| 10f64.powf(self.sum_log10 / self.count as f64))
    }

    /// The luminance (cd/m², resolved to a bin centre) below which a fraction
    /// `p` of the counted samples lie.
    pub fn percentile(&self, p: f64) -> Option<f64> {
        if self.count == 0 {
            return None;
        }
        let target = p.clamp(0.0, 1.0) * self.count as f64;
        let mut sum = 0.0;
        let mut last = 0;
        for (i, &n) in self.bins.iter().enumerate() {
            if n == 0 {
                continue;
            }
            last = i;
            sum += n as f64;
            if sum >= target {
                break;
            }
        }
        Some(10f64.powf(bin_floor(last) + 0.5 / BINS_PER_DECADE as f64))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::Vec3;

    fn picture() -> Picture {
        let (width, height) = (37, 23);
        let pixels = (0..width * height)
            .map(|i| {
                let t = i as f32 / (width * height) as f32;
                match i % 11 {
                    0 => Vec3::new(f32::NAN, 1.0, 1.0),
                    1 => Vec3::ZERO,
                    2 => Vec3::new(-1.0, -1.0, -1.0),
                    3 => Vec3::splat(f32::INFINITY),
                    _ => Vec3::new(10f32.powf(8.0 * t - 4.0), 10f32.powf(4.0 * t - 3.0), 0.5),
                }
            })
            .collect();
        Picture { width, height, pixels }
    }

    #[test]
    fn incremental_equals_whole_picture() {
        let p = picture();
        let whole = Histogram::from_picture(&p);
        let mut incremental = Histogram::new();
        for chunk in p.pixels.chunks(7) {
            incremental.add_many(chunk.iter().copied());
        }
        assert_eq!(incremental, whole);
        let mut one_by_one = Histogram::new();
        for px in &p.pixels {
            one_by_one.add(px.to_array());
        }
        assert_eq!(one_by_one, whole);
        assert_eq!(whole.count() + whole.skipped(), p.pixels.len() as u64);
        let bad = (0..p.pixels.len()).filter(|i| i % 11 < 4).count() as u64;
        assert_eq!(whole.skipped(), bad, "NaN, zero, negative, infinite pixels are skipped");
        assert_eq!(whole.bins().iter().sum::<u64>(), whole.count());
    }

    #[test]
    fn tracks_extremes_and_averages_in_candelas() {
        let mut h = Histogram::new();
        assert!(h.is_empty());
        assert_eq!(h.min_luminance(), None);
        assert_eq!(h.log_average_luminance(), None);
        assert_eq!(h.percentile(0.5), None);
        h.add([1.0 / 179.0; 3]);
        h.add([100.0 / 179.0; 3]);
        assert!((h.min_luminance().unwrap() - 1.0).abs() < 1e-4);
        assert!((h.max_luminance().unwrap() - 100.0).abs() < 1e-2);
        assert!((h.log_average_luminance().unwrap() - 10.0).abs() < 1e-3);
        assert_eq!(h.bins()[bin_of(h.min_luminance().unwrap().log10())], 1);
        assert_eq!(h.bins()[bin_of(h.max_luminance().unwrap().log10())], 1);
        assert_eq!(h.bins().iter().filter(|&&n| n > 0).count(), 2);
        let p5 = h.percentile(0.05).unwrap();
        assert!((0.9..1.1).contains(&p5), "{p5}");
        h.clear();
        assert!(h.is_empty());
        assert_eq!(h.luminous_efficacy(), DEFAULT_LUMINOUS_EFFICACY);
    }

    #[test]
    fn out_of_range_luminance_lands_in_end_bins() {
        let mut h = Histogram::with_luminous_efficacy(1.0);
        h.add([1e-9; 3]);
        h.add([1e30; 3]);
        assert_eq!(h.bins()[0], 1);
        assert_eq!(h.bins()[HISTOGRAM_BINS - 1], 1);
        assert!(h.max_luminance().unwrap() > 1e29);
        assert_eq!(
            Histogram::with_luminous_efficacy(f32::NAN).luminous_efficacy(),
            DEFAULT_LUMINOUS_EFFICACY
        );
        assert_eq!(
            Histogram::with_luminous_efficacy(-3.0).luminous_efficacy(),
            DEFAULT_LUMINOUS_EFFICACY
        );
    }
}
