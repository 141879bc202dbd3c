//! `holodeck optimize`: collate beams in beam order, drop free space (like rhoptimize).

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::Instant;

use anyhow::Result;
use holodeck_file::storage;

use holodeck_cli::human::{bytes, count};

/// Arguments of `holodeck optimize`.
#[derive(clap::Args)]
#[command(after_help = "\
The file is rewritten beside the original and renamed over it only once complete and
synced: a crash or a damaged beam leaves the original untouched. No server may hold
the file meanwhile.

Example:
  holodeck optimize room.hdk")]
pub struct Args {
    /// The holodeck file.
    file: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let bar = holodeck_cli::progress::Progress::counting("optimizing", holodeck_cli::progress::Unit::Bytes, Some(0));
    let start = Instant::now();
    let r = storage::optimize(&a.file, |done, total| {
        bar.set_total(total);
        bar.set(done);
    });
    bar.finish();
    let r = r?;
    summary!(
        "{}: {} rays, {} -> {} in {:.2} s",
        a.file.display(),
        count(r.rays),
        bytes(r.bytes_before),
        bytes(r.bytes_after),
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
