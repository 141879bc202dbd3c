//! Progress on stderr for long work, in one style for every command:
//!
//! ```text
//! filling [=========>          ] 412,160/1,000,000 rays · 253,544 rays/s · 1.6 s elapsed · 2.3 s left
//! running [=========>          ] 12 s of 30 s · 868,354 rays · 72,362 rays/s · 18 s left
//! scanning 999,872 triangles · 2,210,411 triangles/s · 0.5 s elapsed
//! ```
//!
//! A label, counts with thousands separators, the rate with its unit, the time
//! elapsed and the time left; work bounded by time shows the time as its
//! progress. Nothing is drawn when stderr is not a terminal, and the lines
//! carry no colour codes.

use std::io::IsTerminal;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressState, ProgressStyle};

use crate::human;

/// What a progress line counts: its unit, and whether it is bytes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Unit {
    /// Rays (traced, copied, imported, exported).
    Rays,
    /// Bytes (read, verified, rewritten), shown in binary units.
    Bytes,
    /// Picture rows.
    Rows,
    /// Views of a walk.
    Views,
    /// Triangles of a scene.
    Triangles,
    /// Blocks of a scene file.
    Blocks,
}

impl Unit {
    /// The unit's plural name as the line prints it.
    pub fn name(self) -> &'static str {
        match self {
            Unit::Rays => "rays",
            Unit::Bytes => "bytes",
            Unit::Rows => "rows",
            Unit::Views => "views",
            Unit::Triangles => "triangles",
            Unit::Blocks => "blocks",
        }
    }

    /// `n` of this unit: `1,234 rays` or `1.2 MiB`.
    pub fn amount(self, n: u64) -> String {
        match self {
            Unit::Bytes => human::bytes(n),
            _ => format!("{} {}", human::count(n), self.name()),
        }
    }

    /// `done/total` of this unit: `1,234/5,000 rays` or `1.2 MiB/4.0 MiB`.
    pub fn fraction(self, done: u64, total: u64) -> String {
        match self {
            Unit::Bytes => format!("{}/{}", human::bytes(done), human::bytes(total)),
            _ => format!("{}/{} {}", human::count(done), human::count(total), self.name()),
        }
    }

    /// A rate of this unit: `253,544 rays/s`, `3.2 rows/s` or `120.0 MiB/s`.
    pub fn rate(self, per_sec: f64) -> String {
        if !per_sec.is_finite() || per_sec <= 0.0 {
            return format!("0 {}/s", self.short());
        }
        match self {
            Unit::Bytes => format!("{}/s", human::bytes(per_sec as u64)),
            _ if per_sec < 100.0 => format!("{per_sec:.1} {}/s", self.name()),
            _ => format!("{} {}/s", human::count(per_sec.round() as u64), self.name()),
        }
    }

    fn short(self) -> &'static str {
        match self {
            Unit::Bytes => "B",
            _ => self.name(),
        }
    }
}

/// A span of time as people read it: `0.4 s`, `12 s`, `2 min 05 s`, `1 h 02 min`.
pub fn duration(d: Duration) -> String {
    let s = d.as_secs_f64();
    if s < 10.0 {
        format!("{s:.1} s")
    } else if s < 60.0 {
        format!("{} s", s as u64)
    } else if s < 3600.0 {
        let s = s as u64;
        format!("{} min {:02} s", s / 60, s % 60)
    } else {
        let m = s as u64 / 60;
        format!("{} h {:02} min", m / 60, m % 60)
    }
}

/// One progress line on stderr (see the module's documentation).
pub struct Progress {
    bar: ProgressBar,
    /// For work bounded by time: what is counted, and the limit.
    timed: Option<(Arc<AtomicU64>, Duration, Instant)>,
}

impl Progress {
    /// Counts `unit`s toward `total` (or without a total, as a running count).
    pub fn counting(label: &str, unit: Unit, total: Option<u64>) -> Progress {
        let bar = new_bar(total.unwrap_or(0));
        bar.set_style(count_style(unit, total.is_some()));
        bar.set_message(label.to_string());
        Progress { bar, timed: None }
    }

    /// Work that ends after `limit`: the bar is the time; with a `unit`, the
    /// line also shows the units counted with [`Progress::set`] and their rate.
    pub fn timed(label: &str, unit: Option<Unit>, limit: Duration) -> Progress {
        let counted = Arc::new(AtomicU64::new(0));
        let limit_ms = u64::try_from(limit.as_millis()).unwrap_or(u64::MAX).max(1);
        let bar = new_bar(limit_ms);
        bar.set_style(timed_style(unit, limit, counted.clone()));
        bar.set_message(label.to_string());
        Progress {
            bar,
            timed: Some((counted, limit, Instant::now())),
        }
    }

    /// Work whose end is not known beforehand and that counts nothing: a
    /// label and the time elapsed.
    pub fn waiting(label: &str) -> Progress {
        let bar = ProgressBar::new_spinner();
        if !std::io::stderr().is_terminal() {
            bar.set_draw_target(ProgressDrawTarget::hidden());
        }
        bar.set_style(
            ProgressStyle::with_template("{msg} {spinner} {elapsed_human}")
                .unwrap_or_else(|_| ProgressStyle::default_spinner())
                .with_key("elapsed_human", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
                    let _ = write!(w, "· {} elapsed", duration(s.elapsed()));
                }),
        );
        bar.set_message(label.to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        Progress { bar, timed: None }
    }

    /// Sets how many units are done; for timed work, also moves the bar to
    /// the time elapsed.
    pub fn set(&self, done: u64) {
        match &self.timed {
            Some((counted, limit, start)) => {
                counted.store(done, Ordering::Relaxed);
                let ms = start.elapsed().min(*limit).as_millis();
                self.bar.set_position(u64::try_from(ms).unwrap_or(u64::MAX));
            }
            None => self.bar.set_position(done),
        }
    }

    /// Adds `n` units done.
    pub fn inc(&self, n: u64) {
        match &self.timed {
            Some((counted, _, _)) => {
                let done = counted.fetch_add(n, Ordering::Relaxed) + n;
                self.set(done);
            }
            None => self.bar.inc(n),
        }
    }

    /// Moves a timed bar to the time elapsed (counts stay).
    pub fn tick(&self) {
        if let Some((counted, _, _)) = &self.timed {
            self.set(counted.load(Ordering::Relaxed));
        }
    }

    /// Sets the total a counting line works toward.
    pub fn set_total(&self, total: u64) {
        if self.timed.is_none() {
            self.bar.set_length(total);
        }
    }

    /// Changes the label (the phase of the work) and what is counted, with
    /// the phase's own total.
    pub fn phase(&self, label: &str, unit: Unit, done: u64, total: Option<u64>) {
        if self.bar.message() != label {
            // Style, counts and label change together: no line is drawn
            // with the new label and the last phase's counts.
            self.bar.set_style(count_style(unit, total.is_some()));
            // The rate and the time left start over with the phase.
            self.bar.reset();
            self.bar.set_length(total.unwrap_or(0).max(done));
            self.bar.set_position(done);
            self.bar.set_message(label.to_string());
            return;
        }
        if let Some(t) = total {
            self.bar.set_length(t.max(done));
        }
        self.bar.set_position(done);
    }

    /// Changes the label.
    pub fn set_label(&self, label: &str) {
        self.bar.set_message(label.to_string());
    }

    /// Runs `f` (which prints) with the line out of the way.
    pub fn suspend<R>(&self, f: impl FnOnce() -> R) -> R {
        self.bar.suspend(f)
    }

    /// Removes the line.
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}

fn new_bar(len: u64) -> ProgressBar {
    let bar = ProgressBar::new(len);
    if !std::io::stderr().is_terminal() {
        bar.set_draw_target(ProgressDrawTarget::hidden());
    }
    bar
}

fn count_style(unit: Unit, with_total: bool) -> ProgressStyle {
    let template = if with_total {
        "{msg} [{bar:30}] {counts} · {rate} · {elapsed_human} · {left}"
    } else {
        "{msg} {counts} · {rate} · {elapsed_human}"
    };
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ")
        .with_key("counts", move |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = match s.len() {
                Some(len) if with_total => w.write_str(&unit.fraction(s.pos(), len)),
                _ => w.write_str(&unit.amount(s.pos())),
            };
        })
        .with_key("rate", move |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let secs = s.elapsed().as_secs_f64();
            let _ = w.write_str(&unit.rate(if secs > 0.0 { s.pos() as f64 / secs } else { 0.0 }));
        })
        .with_key("elapsed_human", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = write!(w, "{} elapsed", duration(s.elapsed()));
        })
        .with_key("left", |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = if s.pos() == 0 {
                w.write_str("time left unknown")
            } else {
                write!(w, "{} left", duration(s.eta()))
            };
        })
}

fn timed_style(unit: Option<Unit>, limit: Duration, counted: Arc<AtomicU64>) -> ProgressStyle {
    let rate_counted = counted.clone();
    let template = if unit.is_some() {
        "{msg} [{bar:30}] {time} · {counts} · {rate} · {left}"
    } else {
        "{msg} [{bar:30}] {time} · {left}"
    };
    let unit = unit.unwrap_or(Unit::Rays);
    ProgressStyle::with_template(template)
        .unwrap_or_else(|_| ProgressStyle::default_bar())
        .progress_chars("=> ")
        .with_key("time", move |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = write!(w, "{} of {}", duration(s.elapsed().min(limit)), duration(limit));
        })
        .with_key("counts", move |_: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = w.write_str(&unit.amount(counted.load(Ordering::Relaxed)));
        })
        .with_key("rate", move |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let secs = s.elapsed().as_secs_f64();
            let n = rate_counted.load(Ordering::Relaxed) as f64;
            let _ = w.write_str(&unit.rate(if secs > 0.0 { n / secs } else { 0.0 }));
        })
        .with_key("left", move |s: &ProgressState, w: &mut dyn std::fmt::Write| {
            let _ = write!(w, "{} left", duration(limit.saturating_sub(s.elapsed())));
        })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_read_as_people_say_them() {
        assert_eq!(duration(Duration::from_millis(400)), "0.4 s");
        assert_eq!(duration(Duration::from_secs(12)), "12 s");
        assert_eq!(duration(Duration::from_secs(125)), "2 min 05 s");
        assert_eq!(duration(Duration::from_secs(3720)), "1 h 02 min");
    }

    #[test]
    fn counts_and_rates_carry_separators_and_units() {
        assert_eq!(Unit::Rays.fraction(412_160, 1_000_000), "412,160/1,000,000 rays");
        assert_eq!(Unit::Triangles.amount(999_872), "999,872 triangles");
        assert_eq!(Unit::Rays.rate(253_544.432_2), "253,544 rays/s");
        assert_eq!(Unit::Rows.rate(3.25), "3.2 rows/s");
        assert_eq!(Unit::Bytes.rate(2.0 * 1024.0 * 1024.0), "2.0 MiB/s");
        assert_eq!(Unit::Bytes.fraction(1024, 4096), "1.0 KiB/4.0 KiB");
        assert_eq!(Unit::Rays.rate(f64::NAN), "0 rays/s");
    }

    #[test]
    fn timed_work_counts_and_moves_with_time() {
        let p = Progress::timed("running", Some(Unit::Rays), Duration::from_secs(30));
        p.set(868_354);
        p.inc(6);
        assert_eq!(p.timed.as_ref().map(|t| t.0.load(Ordering::Relaxed)), Some(868_360));
        assert!(p.bar.position() <= 30_000);
        p.finish();
    }
}
