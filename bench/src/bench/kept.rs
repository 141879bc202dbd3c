//! Light kept over repeated runs: the mean of each region's ratio over
//! independent fills and its standard error, so that a claim about an
//! estimate's expected value is not read off one fill's noise.

use std::fmt;

use holodeck_display::compare::Metrics;

/// The mean of some numbers (NaN for none).
pub fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0u32), |(s, n), v| (s + v, n + 1));
    sum / f64::from(n)
}

/// One ratio over several runs: its mean and the standard error of that
/// mean (NaN with a single run).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Spread {
    /// The mean over the runs.
    pub mean: f64,
    /// The standard deviation over the runs divided by the root of their count.
    pub error: f64,
}

impl Spread {
    /// The spread of `values`.
    pub fn of(values: &[f64]) -> Spread {
        let m = mean(values.iter().copied());
        let n = values.len() as f64;
        let var = values.iter().map(|v| (v - m) * (v - m)).sum::<f64>() / (n - 1.0);
        Spread {
            mean: m,
            error: (var / n).sqrt(),
        }
    }
}

impl fmt::Display for Spread {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.error.is_finite() {
            write!(f, "{:.3} ± {:.3}", self.mean, self.error)
        } else {
            write!(f, "{:.3}", self.mean)
        }
    }
}

/// The light kept per region over several runs.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct KeptOver {
    /// The darkest quarter.
    pub dark: Spread,
    /// The middle half.
    pub middle: Spread,
    /// The brightest quarter.
    pub bright: Spread,
    /// The silhouette band (NaN where there is none).
    pub band: Spread,
}

impl KeptOver {
    /// The ratios of `runs`.
    pub fn of(runs: &[Metrics]) -> KeptOver {
        let over = |f: &dyn Fn(&Metrics) -> f64| Spread::of(&runs.iter().map(f).collect::<Vec<_>>());
        KeptOver {
            dark: over(&|m| m.light.dark),
            middle: over(&|m| m.light.middle),
            bright: over(&|m| m.light.bright),
            band: over(&|m| m.light.band.unwrap_or(f64::NAN)),
        }
    }

    /// The regions in order: dark, middle, bright, band.
    fn named(&self) -> [(&'static str, Spread); 4] {
        [
            ("dark", self.dark),
            ("middle", self.middle),
            ("bright", self.bright),
            ("band", self.band),
        ]
    }

    /// The regions whose mean is farther than `slack` from 1, each named
    /// with its mean, how many standard errors it lies past the bound, and
    /// its ratio to `unbiased`'s mean there (a direct render over the same
    /// reference: a finite reference of heavy-tailed paths is more often
    /// short of its expectation than over it, and that shortfall shows in
    /// every method alike).
    pub fn outside(&self, slack: f64, unbiased: &KeptOver) -> Vec<String> {
        self.named()
            .into_iter()
            .zip(unbiased.named())
            .filter(|((_, s), _)| s.mean.is_finite() && (s.mean - 1.0).abs() > slack)
            .map(|((name, s), (_, u))| {
                let past = ((s.mean - 1.0).abs() - slack) / s.error;
                let past = if past.is_finite() {
                    format!("{past:.1} standard errors past, ")
                } else {
                    String::new()
                };
                format!(
                    "{name} {:.3} ({past}{:.3} of the direct render's)",
                    s.mean,
                    s.mean / u.mean
                )
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_spread_of_known_numbers() {
        let s = Spread::of(&[1.0, 1.02, 0.98, 1.04]);
        assert!((s.mean - 1.01).abs() < 1e-12);
        // Sample variance: (0.0001 + 0.0001 + 0.0009 + 0.0009) / 3.
        let want = (0.002f64 / 3.0 / 4.0).sqrt();
        assert!((s.error - want).abs() < 1e-12, "{}", s.error);
        assert_eq!(s.to_string(), "1.010 ± 0.013");
        assert_eq!(Spread::of(&[1.5]).to_string(), "1.500");
    }

    #[test]
    fn regions_outside_the_bound_are_named_with_their_distance() {
        let at = |m: f64| Spread { mean: m, error: 0.01 };
        let k = KeptOver {
            dark: at(1.05),
            middle: at(1.0),
            bright: at(0.97),
            band: Spread {
                mean: f64::NAN,
                error: f64::NAN,
            },
        };
        let direct = KeptOver {
            dark: at(1.01),
            middle: at(1.0),
            bright: at(1.0),
            band: at(1.0),
        };
        assert_eq!(
            k.outside(0.02, &direct),
            vec![
                "dark 1.050 (3.0 standard errors past, 1.040 of the direct render's)".to_string(),
                "bright 0.970 (1.0 standard errors past, 0.970 of the direct render's)".to_string()
            ]
        );
    }
}
