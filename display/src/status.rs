//! The walkthrough's status line, as the window and the web page show it:
//! samples per second, received and shown, the frame's time, and the
//! server's rays, rate, samplers and whether the fill is paused.

use holodeck_protocol::wire::Progress;

/// What the status line reports.
#[derive(Clone, Copy, Debug, Default)]
pub struct Status {
    /// Samples received per second lately.
    pub rate: f64,
    /// Samples received in all.
    pub received: u64,
    /// Samples the driver keeps in its estimates.
    pub shown: u64,
    /// The last frame took this long, milliseconds.
    pub frame_ms: f64,
    /// The server's last report, if it sent one.
    pub server: Option<Progress>,
    /// The eye's height is kept while moving.
    pub head_fixed: bool,
    /// Pixels of the settled view filled from neighbouring beams.
    pub filled: u64,
}

impl Status {
    /// The line.
    pub fn line(&self) -> String {
        let mut s = format!(
            "{} samples/s  {} received  {} shown  frame {:.0} ms",
            human(self.rate),
            human(self.received as f64),
            human(self.shown as f64),
            self.frame_ms
        );
        if let Some(server) = self.server {
            s.push_str(&format!(
                "  server {} rays, {}/s, {} samplers{}",
                human(server.rays as f64),
                human(server.rays_per_second),
                server.samplers,
                if server.paused { ", paused" } else { "" }
            ));
        }
        if self.filled > 0 {
            s.push_str(&format!("  {} px from neighbouring beams", human(self.filled as f64)));
        }
        if self.head_fixed {
            s.push_str("  head fixed");
        }
        s
    }
}

/// Samples received lately, per second: the status line's rate, over
/// windows of at least a second. The time is passed in (seconds from any
/// fixed origin), so a web page, which has no clock here, keeps one too.
#[derive(Clone, Debug, Default)]
pub struct RateMeter {
    since: f64,
    count: u64,
    rate: f64,
}

impl RateMeter {
    /// Counts `n` samples received at `now`.
    pub fn add(&mut self, n: u64, now: f64) {
        self.count += n;
        if now - self.since >= 1.0 {
            self.rate = self.count as f64 / (now - self.since);
            self.count = 0;
            self.since = now;
        }
    }

    /// Samples per second over the last whole window.
    pub fn rate(&self) -> f64 {
        self.rate
    }
}

/// A count in few characters: 950, 12k, 3.4M, 1.2G.
pub fn human(v: f64) -> String {
    match v {
        v if v >= 1e9 => format!("{:.1}G", v / 1e9),
        v if v >= 1e6 => format!("{:.1}M", v / 1e6),
        v if v >= 1e4 => format!("{:.0}k", v / 1e3),
        v => format!("{v:.0}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_rate_is_the_count_over_each_window_of_a_second_or_more() {
        let mut m = RateMeter::default();
        m.add(500, 0.5);
        assert_eq!(m.rate(), 0.0);
        m.add(1000, 1.5);
        assert_eq!(m.rate(), 1000.0);
        m.add(300, 2.0);
        m.add(300, 3.5);
        assert_eq!(m.rate(), 300.0);
    }

    #[test]
    fn the_line_reads_counts_short_and_names_a_pause() {
        let s = Status {
            rate: 12_345.0,
            received: 3_400_000,
            shown: 950,
            frame_ms: 16.4,
            server: Some(Progress {
                rays: 1_200_000_000,
                rays_per_second: 2.5e6,
                samplers: 3,
                paused: true,
                ..Progress::default()
            }),
            head_fixed: true,
            filled: 0,
        };
        assert_eq!(
            s.line(),
            "12k samples/s  3.4M received  950 shown  frame 16 ms  server 1.2G rays, 2.5M/s, 3 samplers, paused  head fixed"
        );
        let sparse = Status {
            server: None,
            head_fixed: false,
            filled: 2412,
            ..s
        };
        assert_eq!(
            sparse.line(),
            "12k samples/s  3.4M received  950 shown  frame 16 ms  2412 px from neighbouring beams"
        );
    }
}
