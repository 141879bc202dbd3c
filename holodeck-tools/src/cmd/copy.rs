//! `holodeck copy`: rays from one holodeck into another (like Radiance's rhcopy).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_file::storage;

use holodeck_cli::human::count;

/// Arguments of `holodeck copy`.
#[derive(clap::Args)]
#[command(after_help = "\
A section of DST equal to one of SRC (same corner, axes, grid, kind and depth coding)
gets that section's rays beam for beam. Rays of other sections are resampled: each goes
into every section of DST that its line enters no earlier than SRC's section and no later
than its hit, where the ray holds what DST's samplers would trace (colors keep their
bytes; cells and depth codes become DST's); where DST's sections hold no geometry
(OBSTRUCTIONS false), also into one the ray started inside of and left before its hit
(rays crossing a wall two sections share, as Radiance's rhcopy keeps them). Rays valid
nowhere in DST are counted as dropped. Without DST, a copy with SRC's settings is made.

Examples:
  holodeck copy day1.hdk all.hdk        merge a night's fill into the main file
  holodeck create fine.hdk --section 'interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5 beams=400000'
  holodeck copy coarse.hdk fine.hdk     resample into a finer grid
  holodeck copy big.hdk small.hdk --diskspace 0   ignore small.hdk's DISKSPACE limit")]
pub struct Args {
    /// The holodeck to read.
    src: PathBuf,
    /// The holodeck to add the rays to (created with SRC's settings if missing).
    dst: PathBuf,
    /// DST's size limit for this copy, replacing its DISKSPACE setting (e.g. 2G; 0 for
    /// none). A copy that reaches the limit stops, keeping every ray stored so far.
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    diskspace: Option<u64>,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let bar = holodeck_cli::progress::Progress::counting("copying", holodeck_cli::progress::Unit::Rays, Some(0));
    let options = storage::CopyOptions { diskspace: a.diskspace };
    let r = storage::copy_with(&a.src, &a.dst, &options, |done, total| {
        bar.set_total(total);
        bar.set(done);
    });
    bar.finish();
    let r = r.with_context(|| format!("copying {} into {}", a.src.display(), a.dst.display()))?;
    summary!(
        "{} -> {}{}: {} rays read, {} stored ({} section(s) merged beam for beam, {} resampled), {} valid in no section",
        a.src.display(),
        a.dst.display(),
        if r.created { " (new)" } else { "" },
        count(r.rays_read),
        count(r.rays_written),
        r.merged_sections,
        r.resampled_sections,
        count(r.rays_dropped)
    );
    if let Some(why) = &r.stopped {
        eprintln!(
            "holodeck copy: stopped early: {why}. The {} rays stored are committed in {}; \
             copy again with --diskspace SIZE (0 for no limit) to add the rest",
            count(r.rays_written),
            a.dst.display()
        );
        return Ok(ExitCode::from(1));
    }
    Ok(ExitCode::SUCCESS)
}
