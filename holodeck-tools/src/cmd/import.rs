//! `holodeck import radiance`: a Radiance holodeck (rholo's .hdk) into a new holodeck file.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_file::radiance::{self, ByteOrder, ImportOptions};
use holodeck_protocol::SectionKind;

use holodeck_cli::human::count;

/// Arguments of `holodeck import`.
#[derive(clap::Args)]
#[command(after_help = "Example:\n  holodeck import radiance office.hdk -o office-holo.hdk")]
pub struct Args {
    #[command(subcommand)]
    format: Format,
}

#[derive(clap::Subcommand)]
enum Format {
    /// A Radiance holodeck written by rholo, rhcopy or rhoptimize, of any byte order.
    Radiance(RadianceArgs),
}

/// Arguments of `holodeck import radiance`.
#[derive(clap::Args)]
#[command(after_help = "\
Every ray keeps its cell bytes, color and depth code exactly; the sections keep Radiance's
depth coding, so rays added later match them. Sections, grids and the settings rholo
recorded (CACHE, DISKSPACE, GRID, OBSTRUCTIONS, VDISTANCE, TIME, REPORT) carry over;
rendering options and the octree name are listed as not carried over. The new file is
collated in beam order.

Examples:
  holodeck import radiance office.hdk -o office-holo.hdk
  holodeck import radiance object.hdk -o object-holo.hdk --kind exterior
  holodeck import radiance cut.hdk -o salvaged.hdk --accept-loss   # a file cut short")]
struct RadianceArgs {
    /// The Radiance holodeck.
    file: PathBuf,
    /// The new holodeck file (refuses to replace an existing one).
    #[arg(short, long, value_name = "NEW.hdk")]
    output: PathBuf,
    /// Kind of every section: interior (looked out of) or exterior (looked into).
    /// Radiance does not record it; files this program exported do.
    #[arg(long, value_parser = parse_kind)]
    kind: Option<SectionKind>,
    /// Import what can be read of a damaged file: beams whose rays lie past its end or
    /// overlap other data, and sections whose records are cut off, are left out and
    /// listed, instead of refusing the whole file.
    #[arg(long)]
    accept_loss: bool,
}

fn parse_kind(s: &str) -> Result<SectionKind, String> {
    match s {
        "interior" => Ok(SectionKind::Interior),
        "exterior" => Ok(SectionKind::Exterior),
        other => Err(format!("{other:?} is not interior or exterior")),
    }
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let Format::Radiance(a) = a.format;
    let bar = holodeck_cli::progress::Progress::counting("importing", holodeck_cli::progress::Unit::Rays, Some(0));
    let r = radiance::import(
        &a.file,
        &a.output,
        &ImportOptions {
            kind: a.kind,
            accept_loss: a.accept_loss,
        },
        |done, total| {
            bar.set_total(total);
            bar.set(done);
        },
    );
    bar.finish();
    let r = r.with_context(|| format!("importing {}", a.file.display()))?;
    let order = match r.layout.order {
        ByteOrder::Little => "little-endian",
        ByteOrder::Big => "big-endian",
    };
    summary!(
        "{} -> {}: {} section(s), {} beams holding {} rays ({order}, {}-byte offsets) in {:.2} s ({}/s)",
        a.file.display(),
        a.output.display(),
        r.sections,
        count(r.beams),
        count(r.rays),
        r.layout.offset_bytes,
        r.seconds,
        count((r.rays as f64 / r.seconds.max(1e-9)) as u64)
    );
    for line in &r.unused {
        summary!("  not carried over: {line}");
    }
    for note in &r.notes {
        summary!("  note: {note}");
    }
    if !r.lost.is_empty() {
        eprintln!(
            "holodeck import: {} rays of the damaged file were left out (--accept-loss):",
            count(r.lost_rays)
        );
        for line in &r.lost {
            eprintln!("  lost: {line}");
        }
    }
    Ok(ExitCode::SUCCESS)
}
