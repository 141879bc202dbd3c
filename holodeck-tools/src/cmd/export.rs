//! `holodeck export radiance`: a holodeck file as a Radiance holodeck rholo's tools read.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_file::radiance::{self, Layout};

use holodeck_cli::human::{bytes, count};

/// Arguments of `holodeck export`.
#[derive(clap::Args)]
#[command(after_help = "Example:\n  holodeck export radiance room.hdk -o room-rholo.hdk")]
pub struct Args {
    #[command(subcommand)]
    format: Format,
}

#[derive(clap::Subcommand)]
enum Format {
    /// A Radiance holodeck (little-endian, 64-bit offsets: what rholo writes on
    /// today's systems) for rhinfo, rhpict, rhcopy, rhoptimize and rholo.
    Radiance(RadianceArgs),
}

/// Arguments of `holodeck export radiance`.
#[derive(clap::Args)]
#[command(after_help = "\
Rays keep their cell bytes and colors. Depth codes of sections this program traced are
converted to Radiance's coding (to within half of Radiance's depth step); those of
sections imported from Radiance are kept exactly, so import then export gives back the
same rays. Section kinds and the scene identity are written on header lines Radiance
ignores, so importing the export restores them.

Example:
  holodeck export radiance room.hdk -o room-rholo.hdk && rhinfo room-rholo.hdk")]
struct RadianceArgs {
    /// The holodeck file.
    file: PathBuf,
    /// The Radiance holodeck to write (refuses to replace an existing one).
    #[arg(short, long, value_name = "FILE.hdk")]
    output: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let Format::Radiance(a) = a.format;
    let bar = holodeck_cli::progress::Progress::counting("exporting", holodeck_cli::progress::Unit::Rays, Some(0));
    let r = radiance::export(&a.file, &a.output, Layout::LP64, |done, total| {
        bar.set_total(total);
        bar.set(done);
    });
    bar.finish();
    let r = r.with_context(|| format!("exporting {}", a.file.display()))?;
    summary!(
        "{} -> {}: {} section(s), {} beams holding {} rays, {} in {:.2} s",
        a.file.display(),
        a.output.display(),
        r.sections,
        count(r.beams),
        count(r.rays),
        bytes(r.bytes),
        r.seconds
    );
    if r.converted > 0 {
        summary!("  {} depth codes converted to Radiance's coding", count(r.converted));
    }
    Ok(ExitCode::SUCCESS)
}
