//! `holodeck bench all`: the fast version of every benchmark in one run
//! (a few minutes on two cores), one table of every figure beside the
//! baseline measured in the same run, and the figures as JSON for
//! `holodeck bench compare`.

use super::fast::Fast;
use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Instant, SystemTime, UNIX_EPOCH};

use anyhow::{Context, Result};

use super::report::{table, Figure, Report, FORMAT};

/// Arguments of `holodeck bench all`.
#[derive(clap::Args)]
#[command(after_help = "\
Runs the fast version of each benchmark: storage (append, recall, optimize, bytes per ray),
tracer (wide BVH beside the kd-tree, packets, path tracing), out-of-core (a scene file with a
cache of a tenth), display (every driver's insertion rate and frame), network (a server and
samplers over loopback beside the tracer alone) and accuracy (a holodeck picture beside a direct
render with the same paths). Each figure is the median of --repeats, taken in turns with its
baseline; the spread of the repeats is the noise `bench compare` holds changes against. A
bench that fails is reported and the others still run (the exit status is then 1).

Examples:
  holodeck bench all
  holodeck bench all --json before.json
  holodeck bench all --markdown docs/results
  holodeck bench all --only tracer --only storage --repeats 5")]
pub struct Args {
    /// Write the figures as JSON here.
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write the table as DIR/bench-all.md, headed by this command, the commit and the
    /// date, and refresh the blocks quoting it in the Markdown files of DIR's parent
    /// (docs/RESULTS.md quotes docs/results/bench-all.md).
    #[arg(long, value_name = "DIR")]
    markdown: Option<PathBuf>,
    /// Repeats of each figure.
    #[arg(long, default_value_t = 3, value_parser = clap::value_parser!(u32).range(2..=50))]
    repeats: u32,
    /// Only these benchmarks (repeat for several): storage, tracer, out-of-core, display, network, accuracy.
    #[arg(long)]
    only: Vec<String>,
    #[command(flatten)]
    files: super::Files,
}

/// A fast benchmark.
type Bench = fn(&Fast) -> Result<Vec<Figure>>;

/// The fast benchmarks, by name, in the order they run.
pub const BENCHES: [(&str, Bench); 6] = [
    ("storage", super::storage::fast),
    ("tracer", super::tracer::fast),
    ("out-of-core", super::scene_file::fast),
    ("display", super::display::fast),
    ("network", super::network::fast),
    ("accuracy", super::accuracy::fast),
];

/// Runs the command.
pub fn run(a: &Args) -> Result<ExitCode> {
    for o in &a.only {
        if !BENCHES.iter().any(|(n, _)| n == o) {
            anyhow::bail!(
                "--only {o:?}: no such benchmark (known: {})",
                BENCHES.map(|b| b.0).join(", ")
            );
        }
    }
    let ctx = Fast {
        dir: a.files.dir.clone(),
        repeats: a.repeats as usize,
    };
    let started = SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs());
    let mut figures = Vec::new();
    let mut failed = Vec::new();
    for (name, bench) in BENCHES {
        if !a.only.is_empty() && !a.only.iter().any(|o| o == name) {
            continue;
        }
        eprintln!("bench {name}...");
        let start = Instant::now();
        match bench(&ctx) {
            Ok(f) => {
                eprintln!(
                    "bench {name}: {} figures in {:.0} s",
                    f.len(),
                    start.elapsed().as_secs_f64()
                );
                figures.extend(f);
            }
            Err(e) => {
                eprintln!("bench {name} failed: {e:#}");
                failed.push(name);
            }
        }
    }
    let mut text = table(&figures);
    if !failed.is_empty() {
        text += &format!("\nFailed: {}.\n", failed.join(", "));
    }
    print!("{text}");
    if let Some(dir) = &a.markdown {
        holodeck_cli::generated::publish_with_charts(
            dir,
            "bench-all",
            &holodeck_cli::generated::command_line(),
            text,
            &[],
        )?;
    }
    let report = Report {
        format: FORMAT,
        version: env!("CARGO_PKG_VERSION").into(),
        cpu: holodeck_cli::generated::cpu(),
        threads: std::thread::available_parallelism().map_or(1, |n| n.get()),
        started,
        figures,
    };
    if let Some(path) = &a.json {
        let text = serde_json::to_string_pretty(&report).context("encoding the figures")?;
        std::fs::write(path, text + "\n").with_context(|| format!("writing {}", path.display()))?;
    }
    Ok(if failed.is_empty() {
        ExitCode::SUCCESS
    } else {
        ExitCode::from(1)
    })
}
