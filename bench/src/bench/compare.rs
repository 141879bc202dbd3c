//! `holodeck bench compare BEFORE AFTER`: two runs of `bench all --json`
//! side by side. Each figure's comparable number (its ratio to the baseline
//! measured beside it, or its value where it has none) after over before,
//! and a verdict: a change within the noise either run measured across its
//! repeats is no change; beyond it, better or worse by the figure's
//! direction.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use anyhow::{bail, Context, Result};

use super::report::{number, Figure, Report, FORMAT};

/// Arguments of `holodeck bench compare`.
#[derive(clap::Args)]
#[command(after_help = "\
A change counts only beyond the noise: the larger of the two runs' spreads across repeats
(at least --floor). Figures with a baseline are compared by their ratio to it, taken in
the same run, which machines that drift in speed change far less than the figure itself.

Examples:
  holodeck bench all --json before.json
  holodeck bench all --json after.json
  holodeck bench compare before.json after.json
  holodeck bench compare before.json after.json --fail-on-regression   (exit 1 on a regression)")]
pub struct Args {
    /// The earlier run.
    before: PathBuf,
    /// The later run.
    after: PathBuf,
    /// Smallest relative change that can count, whatever the noise.
    #[arg(long, default_value_t = 0.03, value_parser = holodeck_cli::args::non_negative)]
    floor: f64,
    /// Exit with status 1 when a figure got worse beyond the noise.
    #[arg(long)]
    fail_on_regression: bool,
}

/// How a figure moved between two runs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Verdict {
    /// Within the noise.
    Same,
    /// Better beyond the noise.
    Better,
    /// Worse beyond the noise.
    Worse,
}

/// One figure in both runs.
#[derive(Clone, Debug)]
pub struct Change {
    /// Bench and figure.
    pub key: String,
    /// Comparable numbers before and after.
    pub before: f64,
    /// After.
    pub after: f64,
    /// After over before.
    pub ratio: f64,
    /// The threshold the change was held against.
    pub noise: f64,
    /// The verdict.
    pub verdict: Verdict,
}

/// Reads a run written by `bench all --json`.
pub fn read(path: &Path) -> Result<Report> {
    let text = std::fs::read_to_string(path).with_context(|| format!("reading {}", path.display()))?;
    let r: Report = serde_json::from_str(&text)
        .with_context(|| format!("{} is not a `holodeck bench all --json` report", path.display()))?;
    if r.format != FORMAT {
        bail!(
            "{} is a report of layout {} (this holodeck reads layout {FORMAT})",
            path.display(),
            r.format
        );
    }
    Ok(r)
}

/// The verdict on one figure measured in both runs.
pub fn change(before: &Figure, after: &Figure, floor: f64) -> Change {
    let (b, a) = (before.comparable(), after.comparable());
    let ratio = a / b;
    let noise = before.noise().max(after.noise()).max(floor);
    let up = ratio > 1.0 + noise;
    let down = ratio < 1.0 - noise;
    let verdict = match (after.higher_is_better, up, down) {
        (true, true, _) | (false, _, true) => Verdict::Better,
        (true, _, true) | (false, true, _) => Verdict::Worse,
        _ => Verdict::Same,
    };
    Change {
        key: after.key(),
        before: b,
        after: a,
        ratio,
        noise,
        verdict,
    }
}

/// Every figure of `after` beside the same figure of `before`, and the
/// keys found in only one of them.
pub fn changes(before: &Report, after: &Report, floor: f64) -> (Vec<Change>, Vec<String>) {
    let mut out = Vec::new();
    let mut lonely = Vec::new();
    for a in &after.figures {
        match before.figures.iter().find(|b| b.key() == a.key()) {
            Some(b) => out.push(change(b, a, floor)),
            None => lonely.push(format!("{} (only in the later run)", a.key())),
        }
    }
    for b in &before.figures {
        if !after.figures.iter().any(|a| a.key() == b.key()) {
            lonely.push(format!("{} (only in the earlier run)", b.key()));
        }
    }
    (out, lonely)
}

/// Runs the command.
pub fn run(a: &Args) -> Result<ExitCode> {
    let (before, after) = (read(&a.before)?, read(&a.after)?);
    if before.cpu != after.cpu {
        println!(
            "The runs were on different CPUs ({} and {}): compare ratios to baselines only.\n",
            before.cpu, after.cpu
        );
    }
    let (changes, lonely) = changes(&before, &after, a.floor);
    println!("| figure | before | after | after / before | noise | verdict |");
    println!("|---|---|---|---|---|---|");
    for c in &changes {
        println!(
            "| {} | {} | {} | {:.3} | ±{:.0}% | {} |",
            c.key,
            number(c.before),
            number(c.after),
            c.ratio,
            100.0 * c.noise,
            match c.verdict {
                Verdict::Same => "same",
                Verdict::Better => "better",
                Verdict::Worse => "**worse**",
            }
        );
    }
    for l in &lonely {
        println!("| {l} | | | | | |");
    }
    let worse = changes.iter().filter(|c| c.verdict == Verdict::Worse).count();
    println!(
        "\n{worse} worse, {} better, {} within the noise.",
        changes.iter().filter(|c| c.verdict == Verdict::Better).count(),
        changes.iter().filter(|c| c.verdict == Verdict::Same).count()
    );
    Ok(if worse > 0 && a.fail_on_regression {
        ExitCode::from(1)
    } else {
        ExitCode::SUCCESS
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fig(name: &str, higher: bool, v: Vec<f64>, base: Option<Vec<f64>>) -> Figure {
        let f = Figure::new("b", name, "u", higher, v);
        match base {
            Some(b) => f.against("base", b),
            None => f,
        }
    }

    #[test]
    fn changes_count_only_beyond_the_noise_and_by_direction() {
        // A rate whose machine got 20% slower: figure and baseline alike,
        // so its ratio holds and it is the same.
        let b = fig("rate", true, vec![10.0, 10.2, 9.9], Some(vec![5.0, 5.1, 4.95]));
        let a = fig("rate", true, vec![8.0, 8.16, 7.92], Some(vec![4.0, 4.08, 3.96]));
        assert_eq!(change(&b, &a, 0.03).verdict, Verdict::Same);
        // The figure itself 20% slower beside the same baseline: worse.
        let a = fig("rate", true, vec![8.0, 8.2, 7.9], Some(vec![5.0, 5.1, 4.95]));
        let c = change(&b, &a, 0.03);
        assert_eq!(c.verdict, Verdict::Worse);
        assert!((c.ratio - 0.8).abs() < 0.01, "{c:?}");
        // An error (less is better) that fell by a third: better.
        let b = fig("error", false, vec![0.30, 0.31, 0.29], None);
        let a = fig("error", false, vec![0.20, 0.21, 0.19], None);
        assert_eq!(change(&b, &a, 0.03).verdict, Verdict::Better);
        // A change inside a noisy run's spread: the same.
        let b = fig("noisy", true, vec![10.0, 14.0, 7.0], None);
        let a = fig("noisy", true, vec![9.0, 9.5, 8.5], None);
        assert_eq!(change(&b, &a, 0.03).verdict, Verdict::Same);
    }

    #[test]
    fn reports_round_trip_and_bad_files_are_named() {
        let dir = tempfile::tempdir().unwrap();
        let r = Report {
            format: FORMAT,
            version: "0.1.0".into(),
            cpu: "cpu".into(),
            threads: 2,
            started: 1,
            figures: vec![fig("rate", true, vec![1.0, 2.0], Some(vec![1.0, 1.0]))],
        };
        let path = dir.path().join("r.json");
        std::fs::write(&path, serde_json::to_string_pretty(&r).unwrap()).unwrap();
        assert_eq!(read(&path).unwrap(), r);
        let mut other = r.clone();
        other.figures[0].name = "another".into();
        let (c, lonely) = changes(&r, &other, 0.03);
        assert!(c.is_empty());
        assert_eq!(lonely.len(), 2, "{lonely:?}");
        std::fs::write(&path, "{\"format\": 1}").unwrap();
        let e = format!("{:#}", read(&path).unwrap_err());
        assert!(e.contains("r.json") && e.contains("not a"), "{e}");
        std::fs::write(&path, serde_json::to_string(&Report { format: 99, ..r }).unwrap()).unwrap();
        assert!(format!("{:#}", read(&path).unwrap_err()).contains("layout 99"));
    }
}
