//! `holodeck grid`: the section grids as an OBJ line mesh.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use holodeck_file::{HoloFile, OpenOptions};

/// Arguments of `holodeck grid`.
#[derive(clap::Args)]
#[command(after_help = "\
Each section becomes an OBJ object ('o section0', ...) of line elements: its box and
the cell lines on its six walls.

Examples:
  holodeck grid room.hdk -o grid.obj
  holodeck grid room.hdk > grid.obj")]
pub struct Args {
    /// The holodeck file.
    file: PathBuf,
    /// Output file (standard output if omitted).
    #[arg(short, long, value_name = "OBJ")]
    output: Option<PathBuf>,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let f = HoloFile::open(&a.file, &OpenOptions::read_only())?;
    let mut obj = format!("# holodeck section grids of {}\n", a.file.display());
    let mut vertex = 0usize;
    for (i, s) in f.sections().iter().enumerate() {
        let _ = writeln!(obj, "o section{i}");
        for [p, q] in s.grid_lines() {
            let _ = writeln!(obj, "v {} {} {}\nv {} {} {}", p.x, p.y, p.z, q.x, q.y, q.z);
            let _ = writeln!(obj, "l {} {}", vertex + 1, vertex + 2);
            vertex += 2;
        }
    }
    match &a.output {
        Some(path) => holodeck_cli::outfile::write(path, obj.as_bytes(), &[&a.file])?,
        None => print!("{obj}"),
    }
    Ok(ExitCode::SUCCESS)
}
