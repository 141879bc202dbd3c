//! Benchmark figures as `bench all` collects them and `bench compare`
//! reads them back: each a value with its unit, the repeats it is the
//! median of (their spread is the noise), and the baseline measured in the
//! same run beside it. Across runs the ratio to the baseline is what is
//! compared where there is one: machines drift, a ratio taken in one run
//! much less.

use serde::{Deserialize, Serialize};

/// The version of the JSON layout.
pub const FORMAT: u32 = 1;

/// A baseline measured in the same run as its figure.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Baseline {
    /// What it is.
    pub name: String,
    /// Its median over the repeats.
    pub value: f64,
    /// Each repeat's value, taken in turns with the figure's.
    pub repeats: Vec<f64>,
}

/// One measured figure.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Figure {
    /// The benchmark it belongs to.
    pub bench: String,
    /// What it measures.
    pub name: String,
    /// Its unit.
    pub unit: String,
    /// Whether more is better (rates) or less (errors, seconds, bytes).
    pub higher_is_better: bool,
    /// The median over the repeats.
    pub value: f64,
    /// Each repeat's value.
    pub repeats: Vec<f64>,
    /// The baseline beside it, when there is one.
    pub baseline: Option<Baseline>,
}

/// The median of `v` (NaN for none).
pub fn median(v: &[f64]) -> f64 {
    let mut v: Vec<f64> = v.iter().copied().filter(|x| !x.is_nan()).collect();
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(f64::total_cmp);
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        (v[n / 2 - 1] + v[n / 2]) / 2.0
    }
}

impl Figure {
    /// A figure of `bench` from its repeats.
    pub fn new(bench: &str, name: &str, unit: &str, higher_is_better: bool, repeats: Vec<f64>) -> Figure {
        Figure {
            bench: bench.into(),
            name: name.into(),
            unit: unit.into(),
            higher_is_better,
            value: median(&repeats),
            repeats,
            baseline: None,
        }
    }

    /// The figure with the baseline `name`, measured in turns with it.
    pub fn against(mut self, name: &str, repeats: Vec<f64>) -> Figure {
        self.baseline = Some(Baseline {
            name: name.into(),
            value: median(&repeats),
            repeats,
        });
        self
    }

    /// The figure over its baseline: the median of the repeats' own
    /// ratios (each taken beside its baseline), `None` without one.
    pub fn ratio(&self) -> Option<f64> {
        let b = self.baseline.as_ref()?;
        Some(median(&self.ratios(b)))
    }

    fn ratios(&self, b: &Baseline) -> Vec<f64> {
        if b.repeats.len() == self.repeats.len() {
            self.repeats.iter().zip(&b.repeats).map(|(v, w)| v / w).collect()
        } else {
            vec![self.value / b.value]
        }
    }

    /// What is compared across runs: the ratio where there is a
    /// baseline, else the value.
    pub fn comparable(&self) -> f64 {
        self.ratio().unwrap_or(self.value)
    }

    /// The noise of [`Figure::comparable`] within this run: the spread of
    /// its repeats, (largest - smallest) / median; 0 with one repeat.
    pub fn noise(&self) -> f64 {
        let v = match &self.baseline {
            Some(b) => self.ratios(b),
            None => self.repeats.clone(),
        };
        let v: Vec<f64> = v.into_iter().filter(|x| x.is_finite()).collect();
        if v.len() < 2 {
            return 0.0;
        }
        let (lo, hi) = v.iter().fold((f64::MAX, f64::MIN), |(l, h), x| (l.min(*x), h.max(*x)));
        let m = median(&v);
        if m == 0.0 {
            0.0
        } else {
            (hi - lo) / m.abs()
        }
    }

    /// Where it is written in tables: bench and name.
    pub fn key(&self) -> String {
        format!("{}: {}", self.bench, self.name)
    }
}

/// A run of `bench all`: what ran where, and its figures.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
pub struct Report {
    /// The JSON layout's version ([`FORMAT`]).
    pub format: u32,
    /// The holodeck's version.
    pub version: String,
    /// The CPU, as the system names it.
    pub cpu: String,
    /// Logical CPUs.
    pub threads: usize,
    /// Seconds since the Unix epoch when the run started.
    pub started: u64,
    /// The figures, in the order measured.
    pub figures: Vec<Figure>,
}

/// A number as a table shows it: three significant digits, and a thousands
/// separator for the large ones.
pub fn number(v: f64) -> String {
    if !v.is_finite() {
        return "—".into();
    }
    let a = v.abs();
    if a >= 10_000.0 {
        holodeck_cli::human::count(v.round() as u64)
    } else if a >= 100.0 {
        format!("{v:.0}")
    } else if a >= 10.0 {
        format!("{v:.1}")
    } else if a >= 1.0 {
        format!("{v:.2}")
    } else {
        format!("{v:.3}")
    }
}

/// The figures as one Markdown table, each beside its baseline.
pub fn table(figures: &[Figure]) -> String {
    let mut out =
        String::from("| bench | figure | result | baseline (same run) | ratio | noise |\n|---|---|---|---|---|---|\n");
    for f in figures {
        let (base, ratio) = match &f.baseline {
            Some(b) => (
                format!("{}: {} {}", b.name, number(b.value), f.unit),
                f.ratio().map_or("—".into(), |r| format!("{r:.2}")),
            ),
            None => (String::new(), "—".into()),
        };
        out.push_str(&format!(
            "| {} | {} | {} {} | {} | {} | ±{:.0}% |\n",
            f.bench,
            f.name,
            number(f.value),
            f.unit,
            base,
            ratio,
            50.0 * f.noise()
        ));
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn medians_ratios_and_noise() {
        assert_eq!(median(&[3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(&[4.0, 1.0, 2.0, 3.0]), 2.5);
        assert!(median(&[]).is_nan());
        let f = Figure::new("tracer", "rays", "M/s", true, vec![10.0, 12.0, 11.0]).against("kd", vec![5.0, 6.0, 5.5]);
        assert_eq!(f.value, 11.0);
        assert_eq!(f.ratio(), Some(2.0));
        assert_eq!(f.comparable(), 2.0);
        // The ratios are all 2: no noise in what is compared.
        assert_eq!(f.noise(), 0.0);
        let g = Figure::new("storage", "bytes/ray", "B", false, vec![10.0, 12.0]);
        assert_eq!(g.ratio(), None);
        assert_eq!(g.comparable(), 11.0);
        assert!((g.noise() - 2.0 / 11.0).abs() < 1e-12);
        let t = table(&[f, g]);
        assert!(
            t.contains("| tracer | rays | 11.0 M/s | kd: 5.50 M/s | 2.00 | ±0% |"),
            "{t}"
        );
        assert!(t.contains("| storage | bytes/ray | 11.0 B |  | — | ±9% |"), "{t}");
        assert_eq!(number(1_234_567.0), "1,234,567");
        assert_eq!(number(0.01234), "0.012");
    }
}
