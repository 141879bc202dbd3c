//! `holodeck check`: verify every checksum; `--repair` salvages into a new file.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use holodeck_server::storage;

use crate::human::count;

/// Arguments of `holodeck check`.
#[derive(clap::Args)]
#[command(after_help = "\
Exit status: 0 when every beam verifies (or --repair salvaged what did), 1 on errors,
2 when damage was found and not repaired.

Examples:
  holodeck check room.hdk
  holodeck check room.hdk --repair room-salvaged.hdk")]
pub struct Args {
    /// The holodeck file (only ever read).
    file: PathBuf,
    /// Copy every beam that verifies into this new file.
    #[arg(long, value_name = "NEW_FILE")]
    repair: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    if let Some(dest) = &a.repair {
        let r = storage::repair(&a.file, dest)?;
        println!(
            "salvaged {} beams ({} rays) into {}; {} beams lost{}",
            count(r.beams),
            count(r.rays),
            dest.display(),
            count(r.beams_lost),
            if r.sections_lost.is_empty() {
                String::new()
            } else {
                format!("; sections with no readable directory: {:?}", r.sections_lost)
            }
        );
        return Ok(ExitCode::SUCCESS);
    }
    let bar = crate::progress::bytes_bar("verifying");
    let report = storage::check(&a.file, |done, total| {
        bar.set_length(total);
        bar.set_position(done);
    });
    bar.finish_and_clear();
    let report = match report {
        Ok(r) => r,
        Err(e) => {
            println!("{}: damaged: {e}", a.file.display());
            return Ok(ExitCode::from(2));
        }
    };
    for s in &report.skipped {
        println!("note: passed over a damaged newer commit: {s}");
    }
    println!(
        "{}: commit {}, {} beams and {} rays verified",
        a.file.display(),
        report.generation,
        count(report.beams_ok),
        count(report.rays_ok)
    );
    if report.is_clean() {
        println!("all checksums verify");
        return Ok(ExitCode::SUCCESS);
    }
    println!("{} beams fail their checksum:", count(report.corrupt.len() as u64));
    for k in report.corrupt.iter().take(20) {
        println!("  section {} beam {}", k.section, k.beam);
    }
    if report.corrupt.len() > 20 {
        println!("  ...");
    }
    println!(
        "run `holodeck check {} --repair NEW_FILE` to salvage the rest",
        a.file.display()
    );
    Ok(ExitCode::from(2))
}
