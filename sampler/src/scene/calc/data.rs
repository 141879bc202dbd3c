//! Radiance data files (`brightdata`, `colordata`): a table of values over
//! one to six coordinates, read as Radiance writes it (the number of
//! dimensions; per dimension `begin end count`, or `0 0 count` and the
//! count's coordinates; then the values, the last dimension fastest; `#`
//! comments) and interpolated multilinearly, extrapolating one cell past
//! either end and fading toward zero beyond.

use serde::{Deserialize, Serialize};

use super::CalcError;

/// Most dimensions a table may have.
const MAX_DIMENSIONS: usize = 6;
/// Most values a table may hold.
const MAX_VALUES: usize = 1 << 24;

/// Where a dimension's samples lie.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub enum Axis {
    /// `count` samples evenly from `begin` to `end`.
    Even {
        /// The first sample's coordinate.
        begin: f64,
        /// The last sample's coordinate.
        end: f64,
        /// How many.
        count: usize,
    },
    /// Samples at the coordinates listed (monotonic).
    Listed(Vec<f64>),
}

impl Axis {
    fn count(&self) -> usize {
        match self {
            Axis::Even { count, .. } => *count,
            Axis::Listed(v) => v.len(),
        }
    }

    /// The cell `i` (at most count − 2) and the fractional index of `p`.
    fn locate(&self, p: f64) -> (usize, f64) {
        match self {
            Axis::Even { begin, end, count } => {
                let x = (p - begin) / (end - begin) * (*count as f64 - 1.0);
                let i = (x.max(0.0) as usize).min(count - 2);
                (i, x)
            }
            Axis::Listed(v) => {
                let up = v[v.len() - 1] > v[0];
                // The first interval whose far end is past p.
                let k = v.partition_point(|&c| if up { c <= p } else { c >= p });
                let i = k.saturating_sub(1).min(v.len() - 2);
                let x = i as f64 + (p - v[i]) / (v[i + 1] - v[i]);
                (i, x)
            }
        }
    }
}

/// A data file's table.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Table {
    /// The dimensions, first to last.
    pub axes: Vec<Axis>,
    /// The values, the last dimension fastest.
    pub values: Vec<f32>,
}

impl Table {
    /// Reads a data file's text; `what` names it in errors.
    pub fn parse(text: &str, what: &str) -> Result<Table, CalcError> {
        let bad = |message: String| CalcError::Data {
            what: what.to_string(),
            message,
        };
        let mut words = text
            .lines()
            .flat_map(|l| l.split('#').next().unwrap_or("").split_whitespace());
        let mut number = |name: &str| -> Result<f64, CalcError> {
            let w = words
                .next()
                .ok_or_else(|| bad(format!("the file ends before {name}")))?;
            w.parse::<f64>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or_else(|| bad(format!("{w:?} ({name}) is not a number")))
        };
        let dims = number("the number of dimensions")?;
        if !(dims >= 1.0 && dims <= MAX_DIMENSIONS as f64 && dims.fract() == 0.0) {
            return Err(bad(format!("{dims} dimensions: 1 to {MAX_DIMENSIONS} are read")));
        }
        let mut axes = Vec::new();
        let mut total = 1usize;
        for d in 0..dims as usize {
            let (begin, end) = (number("a dimension's start")?, number("a dimension's end")?);
            let count = number("a dimension's count")?;
            if !(count >= 2.0 && count.fract() == 0.0 && count <= MAX_VALUES as f64) {
                return Err(bad(format!(
                    "dimension {} has {count} samples; at least 2 are needed",
                    d + 1
                )));
            }
            let count = count as usize;
            total = total.saturating_mul(count);
            if total > MAX_VALUES {
                return Err(bad(format!("more than {MAX_VALUES} values")));
            }
            axes.push(if begin == end {
                let v: Vec<f64> = (0..count)
                    .map(|_| number("a listed coordinate"))
                    .collect::<Result<_, _>>()?;
                let up = v.windows(2).all(|w| w[1] > w[0]);
                let down = v.windows(2).all(|w| w[1] < w[0]);
                if !(up || down) {
                    return Err(bad(format!("the coordinates of dimension {} are not monotonic", d + 1)));
                }
                Axis::Listed(v)
            } else {
                Axis::Even { begin, end, count }
            });
        }
        let values = (0..total)
            .map(|_| number("a value").map(|v| v as f32))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(Table { axes, values })
    }

    /// The interpolated value at `at` (one coordinate per dimension;
    /// missing ones read as 0).
    pub fn value(&self, at: &[f64]) -> f64 {
        self.at(0, 0, at)
    }

    fn at(&self, dim: usize, offset: usize, at: &[f64]) -> f64 {
        let Some(axis) = self.axes.get(dim) else {
            return self.values.get(offset).map_or(0.0, |&v| f64::from(v));
        };
        let p = at.get(dim).copied().unwrap_or(0.0);
        if !p.is_finite() {
            return 0.0;
        }
        let (i, x) = axis.locate(p);
        let fi = i as f64;
        // Linear within a cell past either end; beyond, a fade toward zero.
        let (w0, w1) = if x > fi + 2.0 {
            let w0 = 1.0 / (fi - 1.0 - x);
            (w0, -2.0 * w0)
        } else if x < fi - 1.0 {
            let w1 = 1.0 / (x - fi);
            (-2.0 * w1, w1)
        } else {
            (fi + 1.0 - x, x - fi)
        };
        let stride: usize = self.axes[dim + 1..].iter().map(Axis::count).product();
        let mut sum = 0.0;
        for (k, w) in [(i, w0), (i + 1, w1)] {
            if w.abs() > 1e-6 {
                sum += w * self.at(dim + 1, offset + k * stride, at);
            }
        }
        sum
    }
}
