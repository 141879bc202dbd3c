//! `holodeck create`: a new, empty holodeck file.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use holodeck_file::settings::{parse_size, Settings};
use holodeck_file::HoloFile;
use holodeck_protocol::{SectionSpec, SectionTextError, MAX_BEAMS_PER_SECTION};

use holodeck_cli::human::count_in;

/// Arguments of `holodeck create`.
#[derive(clap::Args)]
#[command(after_help = "\
Examples:
  holodeck create room.hdk --section 'interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5' --grid 0.25
  holodeck create two.hdk --section 'interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5 grid=24,16,10' \\
                          --section 'exterior origin=8,0,0 x=1,0,0 y=0,1,0 z=0,0,1 grid=8,8,8'
  holodeck create room.hdk --control room.toml

A section is 'interior|exterior origin=X,Y,Z x=AX,AY,AZ y=... z=... [grid=W,D,H | beams=N]':
a parallelepiped from a corner and three edge vectors. Without grid= or beams=, the grid
comes from --grid (cell length, like Radiance's GRID), else --beams (a target beam count;
the paper advises 50,000-500,000), else 150,000 beams.")]
pub struct Args {
    /// The file to create (refuses to replace an existing one).
    file: PathBuf,
    /// A section (repeat for more).
    #[arg(long = "section", value_name = "SPEC")]
    sections: Vec<String>,
    /// A TOML control file with [[section]] tables and settings.
    #[arg(long, value_name = "TOML", conflicts_with = "sections")]
    control: Option<PathBuf>,
    /// Cell length for sections without grid= (Radiance's GRID).
    #[arg(long, value_name = "LENGTH")]
    grid: Option<f64>,
    /// Target beam count per section for sections without grid= (K, M suffixes).
    #[arg(long, value_name = "N", value_parser = count_in(1, MAX_BEAMS_PER_SECTION))]
    beams: Option<u64>,
    /// Beam cache budget, e.g. 64M (CACHE).
    #[arg(long, value_name = "SIZE")]
    cache: Option<String>,
    /// Largest file size, e.g. 2G; 0 for no limit (DISKSPACE).
    #[arg(long, value_name = "SIZE")]
    diskspace: Option<String>,
    /// Sections contain geometry: trace from the entry wall (OBSTRUCTIONS).
    #[arg(long)]
    obstructions: bool,
    /// Record virtual distances through flat mirrors and glass (VDISTANCE).
    #[arg(long)]
    vdistance: bool,
    /// Content hash of the scene these rays belong to (SCENE).
    #[arg(long, value_name = "HASH")]
    scene: Option<String>,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let mut settings = if let Some(control) = &a.control {
        let text = std::fs::read_to_string(control).with_context(|| format!("reading {}", control.display()))?;
        Settings::from_toml(&text).with_context(|| format!("in control file {}", control.display()))?
    } else {
        if a.sections.is_empty() {
            bail!("give at least one --section, or --control FILE.toml (see holodeck create --help)");
        }
        let mut s = Settings {
            grid: a.grid,
            ..Settings::default()
        };
        for (i, spec) in a.sections.iter().enumerate() {
            let section = spec
                .parse::<SectionSpec>()
                .and_then(|s| s.resolve(a.grid, a.beams).map_err(SectionTextError::from))
                .with_context(|| format!("--section number {} ({spec:?})", i + 1))?;
            s.sections.push(section);
        }
        s
    };
    if let Some(c) = &a.cache {
        settings.cache_bytes = parse_size(c).context("--cache")?;
    }
    if let Some(d) = &a.diskspace {
        settings.diskspace_bytes = parse_size(d).context("--diskspace")?;
    }
    settings.obstructions |= a.obstructions;
    settings.vdistance |= a.vdistance;
    if a.scene.is_some() {
        settings.scene = a.scene.clone();
    }
    HoloFile::create(&a.file, &settings)?;
    let beams: u64 = settings.sections.iter().map(|s| u64::from(s.beam_count())).sum();
    summary!(
        "created {} with {} section(s), {} beams",
        a.file.display(),
        settings.sections.len(),
        holodeck_cli::human::count(beams)
    );
    Ok(ExitCode::SUCCESS)
}
