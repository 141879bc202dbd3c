//! `holodeck check`: verify every copy of the metadata and every beam's
//! checksum, and say what is damaged, what it costs and what `--repair`
//! saves; `--repair` salvages into a new file.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_file::storage::{self, CheckReport, StorageError};

use holodeck_cli::human::count;

/// Arguments of `holodeck check`.
#[derive(clap::Args)]
#[command(after_help = "\
Every piece of a holodeck file's metadata is stored twice, so most damage costs
nothing; check still reports it, and any writing command (or --repair) rewrites
the damaged copy. When the newest commit cannot be read in full, check says what
is lost and what --repair can save, and writing commands refuse the file unless
given --accept-loss.

Exit status: 0 when everything verifies (or --repair salvaged what did), 1 when the
file cannot be read at all (missing, unreadable, in use), 2 when damage was found.

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

/// True for errors that say the file holds no readable holodeck (damage),
/// rather than that it could not be read at all.
fn is_damage(e: &StorageError) -> bool {
    matches!(
        e,
        StorageError::Format { .. } | StorageError::Settings { .. } | StorageError::NoValidCommit { .. }
    )
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let name = a.file.display().to_string();
    if let Some(dest) = &a.repair {
        let r = storage::repair(&a.file, dest).with_context(|| format!("salvaging {name}"))?;
        print_findings(&name, &r.check);
        println!(
            "salvaged {} beams ({} rays) into {}; {} beams fail their checksum and were left behind",
            count(r.beams),
            count(r.rays),
            dest.display(),
            count(r.beams_lost),
        );
        return Ok(ExitCode::SUCCESS);
    }
    let bar = holodeck_cli::progress::Progress::counting("verifying", holodeck_cli::progress::Unit::Bytes, Some(0));
    let report = storage::check(&a.file, |done, total| {
        bar.set_total(total);
        bar.set(done);
    });
    bar.finish();
    let report = match report {
        Ok(r) => r,
        Err(e) if is_damage(&e) => {
            println!("{name}: damaged, nothing can be read: {e}");
            return Ok(ExitCode::from(2));
        }
        Err(e) => return Err(anyhow::Error::new(e).context(format!("cannot check {name}"))),
    };
    print_findings(&name, &report);
    println!(
        "{name}: commit {}, {} beams and {} rays verified",
        report.generation,
        count(report.beams_ok),
        count(report.rays_ok)
    );
    if report.is_clean() {
        println!("all checksums verify");
        return Ok(ExitCode::SUCCESS);
    }
    if report.loses_rays() {
        println!(
            "`holodeck check {name} --repair NEW_FILE` saves those {} beams ({} rays): every beam whose rays verify",
            count(report.beams_ok),
            count(report.rays_ok)
        );
    } else {
        println!("nothing is lost: the next write to the file (or --repair) rewrites the damaged copies");
    }
    Ok(ExitCode::from(2))
}

/// Prints what is damaged, most serious first.
fn print_findings(name: &str, r: &CheckReport) {
    if let Some(d) = &r.damage {
        println!("{name}: DAMAGED: {}", d.describe());
    }
    if !r.corrupt.is_empty() {
        println!(
            "{} beams ({} rays) fail their checksum:",
            count(r.corrupt.len() as u64),
            count(r.corrupt_rays)
        );
        for k in r.corrupt.iter().take(20) {
            println!("  section {} beam {}", k.section, k.beam);
        }
        if r.corrupt.len() > 20 {
            println!("  ...");
        }
    }
    for s in &r.repaired {
        println!("damaged copy (its twin verifies, nothing lost): {s}");
    }
    for s in &r.skipped {
        println!("note: {s}");
    }
}
