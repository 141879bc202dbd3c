//! The rate of a growing count over the last few seconds, for the reports
//! displays show: rays reach the file in bursts (a sampler's packets, a
//! flush), so a rate over one second reads 0 between bursts and double
//! during them.

use std::collections::VecDeque;
use std::time::{Duration, Instant};

/// How far back the rate looks.
pub const RATE_SPAN: Duration = Duration::from_secs(5);

/// Counts seen at moments, kept for [`RATE_SPAN`]; their slope is the rate.
#[derive(Debug, Default)]
pub struct RateWindow {
    marks: VecDeque<(u64, Instant)>,
}

impl RateWindow {
    /// Records `count` at `at` and returns the count's rate per second over
    /// the last [`RATE_SPAN`] (over what there is, when less has passed).
    pub fn push(&mut self, count: u64, at: Instant) -> f64 {
        self.marks.push_back((count, at));
        // Keep the newest mark that is at least RATE_SPAN old as the start.
        while self.marks.len() > 2
            && self
                .marks
                .get(1)
                .is_some_and(|&(_, t)| at.duration_since(t) >= RATE_SPAN)
        {
            self.marks.pop_front();
        }
        let Some(&(first, since)) = self.marks.front() else {
            return 0.0;
        };
        let secs = at.duration_since(since).as_secs_f64();
        if secs > 0.0 {
            count.saturating_sub(first) as f64 / secs
        } else {
            0.0
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bursts_read_as_a_steady_rate() {
        // Counts as a server saw them once a second while rays arrived in
        // bursts (the one-second rates were 0, 363,520, 163,723, 0, 111,903).
        let counts = [0u64, 0, 363_520, 527_243, 527_243, 639_146, 639_146, 1_000_000];
        let t0 = Instant::now();
        let mut w = RateWindow::default();
        let rates: Vec<f64> = counts
            .iter()
            .enumerate()
            .map(|(i, &c)| w.push(c, t0 + Duration::from_secs(i as u64)))
            .collect();
        assert_eq!(rates[0], 0.0);
        // From the third report on the rate never reads zero while rays grow.
        assert!(rates[2..].iter().all(|&r| r > 100_000.0), "{rates:?}");
        // After 7 s it is the slope over the last 5 s: (1,000,000 - 363,520) / 5.
        assert!((rates[7] - 127_296.0).abs() < 1e-6, "{}", rates[7]);
        // A stopped fill reads zero once the span has passed.
        let mut t = t0 + Duration::from_secs(8);
        let mut last = 1.0;
        for _ in 0..6 {
            last = w.push(1_000_000, t);
            t += Duration::from_secs(1);
        }
        assert_eq!(last, 0.0);
    }
}
