//! `holodeck info`: what a holodeck file holds (like Radiance's rhinfo).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use holodeck_file::{HoloFile, OpenOptions};

use holodeck_cli::human::{bytes, count};

/// Arguments of `holodeck info`.
#[derive(clap::Args)]
#[command(after_help = "\
Shows what can be read. Exit status: 0, or 2 when the newest commit is damaged
(then it also says what is lost; `holodeck check` tells more).

Example:
  holodeck info room.hdk")]
pub struct Args {
    /// The holodeck file.
    file: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let f = HoloFile::open(&a.file, &OpenOptions::read_only())?;
    let s = f.summary();
    println!("{}: holodeck, commit {}", a.file.display(), s.generation);
    let info = f.open_info();
    if let Some(d) = &info.damage {
        println!("  DAMAGED: {}", d.describe().replace('\n', "\n  "));
    }
    for r in &info.repaired {
        println!("  note: damaged copy (its twin verifies, nothing lost): {r}");
    }
    for skipped in &info.skipped {
        println!("  note: {skipped}");
    }
    for (i, (section, (beams, filled, rays))) in f.sections().iter().zip(&s.sections).enumerate() {
        let g = section.grid();
        println!("section {i}: {}", section.spec());
        println!(
            "  grid {} x {} x {}, {} beams, {} holding rays ({:.1}%), {} rays ({:.1} per filled beam)",
            g[0],
            g[1],
            g[2],
            count(u64::from(*beams)),
            count(u64::from(*filled)),
            100.0 * f64::from(*filled) / f64::from((*beams).max(1)),
            count(*rays),
            *rays as f64 / f64::from((*filled).max(1))
        );
    }
    if s.rays() == 0 {
        println!("file: {}, no rays", bytes(s.file_bytes));
    } else {
        println!(
            "file: {}, {} rays, {:.3} bytes per ray",
            bytes(s.file_bytes),
            count(s.rays()),
            s.bytes_per_ray()
        );
    }
    println!(
        "space: {} rays, {} directories, {} free in {} fragments ({:.1}% of the file)",
        bytes(s.ray_bytes),
        bytes(s.metadata_bytes),
        bytes(s.free_bytes),
        count(s.fragments as u64),
        100.0 * s.free_bytes as f64 / s.file_bytes.max(1) as f64
    );
    let st = f.settings();
    let unset = |d: std::time::Duration, none: &str| {
        if d.is_zero() {
            none.to_string()
        } else {
            format!("{d:?}")
        }
    };
    println!(
        "settings: OBSTRUCTIONS={} VDISTANCE={} CACHE={} DISKSPACE={} TIME={} REPORT={}{}",
        st.obstructions,
        st.vdistance,
        bytes(st.cache_bytes),
        if st.diskspace_bytes == 0 {
            "unlimited".to_string()
        } else {
            bytes(st.diskspace_bytes)
        },
        unset(st.time, "unlimited"),
        unset(st.report, "off"),
        st.scene.as_ref().map(|h| format!(" SCENE={h}")).unwrap_or_default()
    );
    if st.stale {
        println!(
            "  note: STALE: some rays were traced in an older version of the scene (kept when an edited scene was adopted); `holodeck admin ... clobber` drops them"
        );
    }
    Ok(if info.damage.is_some() {
        ExitCode::from(2)
    } else {
        ExitCode::SUCCESS
    })
}
