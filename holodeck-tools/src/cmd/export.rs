//! `holodeck export radiance`: a holodeck file as a Radiance holodeck rholo's
//! tools read. `holodeck export web`: a holodeck file as a static web site
//! whose page replays it with no server.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_file::radiance::{self, Layout};

use holodeck_cli::human::{bytes, count};

/// Arguments of `holodeck export`.
#[derive(clap::Args)]
#[command(
    after_help = "Examples:\n  holodeck export radiance room.hdk -o room-rholo.hdk\n  holodeck export web room.hdk -o site/"
)]
pub struct Args {
    #[command(subcommand)]
    format: Format,
}

#[derive(clap::Subcommand)]
enum Format {
    /// A Radiance holodeck (little-endian, 64-bit offsets: what rholo writes on
    /// today's systems) for rhinfo, rhpict, rhcopy, rhoptimize and rholo.
    Radiance(RadianceArgs),
    /// A static web site: the web display's page and the file's rays in
    /// chunks it fetches by byte range, for any static web host; opening it
    /// replays the holodeck with no process running anywhere.
    Web(WebArgs),
}

/// Arguments of `holodeck export web`.
#[derive(clap::Args)]
#[command(after_help = "\
Writes into DIR the page (index.html, app.js), the display in WebAssembly, the index
holodeck.idx (the sections, and where each beam's rays are) and the rays in chunk files
beams-0000.bin, ... (whole beams in key order, about --chunk each). The page fetches only
the beams its view sees, by HTTP byte range (a host that ignores ranges costs whole chunks).
Open it with a link's options after '#': view=..., driver=quadtree|splat|voronoi|mesh, width=, height=.

Examples:
  holodeck export web room.hdk -o site/
  python3 -m http.server -d site 8000       # then open http://127.0.0.1:8000/")]
struct WebArgs {
    /// The holodeck file.
    file: PathBuf,
    /// The folder to write (created; refuses one that holds files).
    #[arg(short, long, value_name = "DIR")]
    output: PathBuf,
    /// Chunk file size to aim at (K, M, G).
    #[arg(long, default_value = "4M", value_parser = holodeck_file::settings::parse_size)]
    chunk: u64,
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
    let a = match a.format {
        Format::Radiance(a) => a,
        Format::Web(a) => return web(a),
    };
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

/// `holodeck export web`.
fn web(a: WebArgs) -> Result<ExitCode> {
    let assets = crate::web::assets()?;
    if a.output.exists()
        && std::fs::read_dir(&a.output)
            .map(|mut d| d.next().is_some())
            .unwrap_or(true)
    {
        anyhow::bail!(
            "{} exists and is not an empty folder: give a new one (nothing was written)",
            a.output.display()
        );
    }
    let mut file = holodeck_file::HoloFile::open(&a.file, &holodeck_file::OpenOptions::read_only())
        .with_context(|| format!("opening {}", a.file.display()))?;
    std::fs::create_dir_all(&a.output).with_context(|| format!("creating {}", a.output.display()))?;
    for asset in assets.iter() {
        let path = a.output.join(asset.path.trim_start_matches('/'));
        std::fs::write(&path, asset.bytes).with_context(|| format!("writing {}", path.display()))?;
    }
    let start = std::time::Instant::now();
    let total = file.summary().rays();
    let bar = holodeck_cli::progress::Progress::counting("exporting", holodeck_cli::progress::Unit::Rays, Some(total));
    let r = holodeck::site::export_site(&mut file, &a.output, a.chunk, &mut |n| bar.set(n));
    bar.finish();
    let r = r.with_context(|| format!("exporting {} to {}", a.file.display(), a.output.display()))?;
    summary!(
        "{} -> {}: {} beams holding {} rays in {} chunk file(s), {} in {:.2} s; serve the folder with any \
         static web host and open its index.html",
        a.file.display(),
        a.output.display(),
        count(r.beams as u64),
        count(r.rays),
        r.chunks,
        bytes(r.bytes),
        start.elapsed().as_secs_f64()
    );
    Ok(ExitCode::SUCCESS)
}
