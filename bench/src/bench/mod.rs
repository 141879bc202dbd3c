//! `holodeck bench`: every benchmark, one file each with its own flags.
//! Each reports its figures beside a baseline measured in the same run,
//! because the machines are shared and absolute speed drifts; `bench all`
//! runs the fast version of each, prints one table and writes JSON that
//! `bench compare` diffs.

pub mod accuracy;
pub mod all;
pub mod compare;
pub mod display;
pub mod fast;
pub mod kept;
pub mod network;
pub mod paths;
pub mod publish;
pub mod replay;
pub mod report;
pub mod scale;
pub mod scene_file;
pub mod share;
pub mod storage;
pub mod textures;
pub mod tracer;

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;

/// Arguments of `holodeck bench`.
#[derive(clap::Args)]
#[command(after_help = "\
Examples:
  holodeck bench all --json today.json           (the fast version of every benchmark)
  holodeck bench compare yesterday.json today.json
  holodeck bench storage --rays 2M --reference-rays 1M
  holodeck bench tracer --triangles 1M --triangles 10M
  holodeck bench tracer --triangles 10M --embree  (beside Embree; needs --features embree)
  holodeck bench scene-file --triangles 10M --charts docs
  holodeck bench display --samples 1M --rays 4M
  holodeck bench network --seconds 8
  holodeck bench scale --samplers 1 --samplers 4 --samplers 16 --samplers 64
  holodeck bench share
  holodeck bench accuracy --paths 250K --paths 1M --repeats 3 --walk-views 0
  holodeck bench textures --repeats 5
  holodeck bench replay room.hdk --views 20 -x 1280 -y 720

`holodeck bench BENCH --help` lists each one's flags.")]
pub struct Args {
    /// The benchmark.
    #[command(subcommand)]
    bench: Bench,
}

/// The benchmarks.
#[derive(clap::Subcommand)]
enum Bench {
    /// The fast version of every benchmark: one table, and JSON for `bench compare`.
    All(all::Args),
    /// Differences between two runs of `bench all --json`: ratios, and regressions beyond the noise.
    Compare(compare::Args),
    /// The holodeck file engine: append, recall, optimize, memory.
    Storage(storage::Args),
    /// The ray tracer: kd-tree, wide BVH, packets, reordering, whole paths, beside Embree.
    Tracer(tracer::Args),
    /// The out-of-core scene file against the in-core tracer: build, size, rays/s by cache budget, LOD.
    SceneFile(scene_file::Args),
    /// Display drivers and pictures from a holodeck.
    Display(display::Args),
    /// The server over loopback: fill overhead, recall to displays, many peers.
    Network(network::Args),
    /// How many samplers one server feeds: light samplers N = 1..64, TLS and plain, beside the engine's append rate.
    Scale(scale::Args),
    /// Two displays, one greedy, sharing real samplers: each display's share of the rays.
    Share(share::Args),
    /// Holodeck pictures against direct renders at equal compute: one view, a walkthrough.
    Accuracy(accuracy::Args),
    /// What textures cost: loading, building, memory and samples/s, textured against untextured.
    Textures(textures::Args),
    /// Display-only replay of a file: frames per second, view changes, samples/s, one core and all.
    Replay(replay::Args),
    /// Write tables a script measured (standard input) as a generated results document.
    Publish(publish::Args),
    /// Internal: stream one file's beams (the child process of a memory measurement).
    #[command(hide = true)]
    Stream(storage::ChildArgs),
    /// Internal: fill one file (the child process of a memory measurement).
    #[command(hide = true)]
    Fill(storage::ChildArgs),
    /// Internal: one light sampler (the child process of `bench scale`).
    #[command(hide = true)]
    ScaleSampler(scale::SamplerArgs),
}

/// Where a benchmark writes its files, and whether it keeps them.
#[derive(clap::Args, Clone, Debug)]
pub struct Files {
    /// Where to write the files.
    #[arg(long, default_value = "target/holodeck-bench")]
    pub dir: PathBuf,
    /// Keep the files.
    #[arg(long)]
    pub keep: bool,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    match a.bench {
        Bench::All(a) => all::run(&a),
        Bench::Compare(a) => compare::run(&a),
        Bench::Storage(a) => storage::run(&a),
        Bench::Tracer(a) => tracer::run_args(&a),
        Bench::SceneFile(a) => scene_file::run_args(&a),
        Bench::Display(a) => display::run_args(&a),
        Bench::Network(a) => network::run_args(&a),
        Bench::Scale(a) => scale::run_args(&a),
        Bench::ScaleSampler(a) => scale::run_sampler(&a),
        Bench::Share(a) => share::run_args(&a),
        Bench::Accuracy(a) => accuracy::run_args(&a),
        Bench::Textures(a) => textures::run_args(&a),
        Bench::Replay(a) => replay::run_args(&a),
        Bench::Publish(a) => publish::run(&a),
        Bench::Stream(a) => storage::run_stream(&a),
        Bench::Fill(a) => storage::run_fill(&a),
    }
}

/// Peak resident memory of this process, and the current, in bytes (Linux).
pub(crate) fn rss() -> (u64, u64) {
    rss_of("self")
}

/// Peak and current resident memory of process `pid` (a number or
/// `self`), in bytes, from /proc (Linux; 0 where it cannot be read).
pub(crate) fn rss_of(pid: &str) -> (u64, u64) {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
            * 1024
    };
    (field("VmHWM:"), field("VmRSS:"))
}

/// One row of a bench's table: what, the result, the baseline beside it
/// and their ratio.
pub(crate) fn row(what: &str, result: String, baseline: String, ratio: f64) {
    println!("| {what} | {result} | {baseline} | {ratio:.2} |");
}

/// Starts this process's peak resident memory over from the current
/// (Linux's `clear_refs`); false where that cannot be done.
pub(crate) fn reset_peak_rss() -> bool {
    std::fs::write("/proc/self/clear_refs", "5").is_ok()
}
