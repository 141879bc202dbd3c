//! `holodeck compare`: how far a picture is from a reference.

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use holodeck_display::compare::metrics;
use holodeck_display::image_io::read_picture;
use holodeck_display::tonemap::{DisplayRange, Histogram, ToneMap, ToneMode};

/// Arguments of `holodeck compare`.
#[derive(clap::Args)]
#[command(after_help = "\
Prints the error of PICTURE against REFERENCE (same size): RMSE and relative RMSE in linear
radiance, PSNR against the reference's peak, and SSIM on luminance tone mapped (camera mode)
by the reference's histogram. Pictures are .hdr (linear) or 8-bit (decoded from sRGB).

Examples:
  holodeck render builtin:room --spp 256 -o ref.hdr
  holodeck pict room.hdk -o pict.hdr
  holodeck compare pict.hdr ref.hdr")]
pub struct Args {
    /// The picture under test.
    picture: PathBuf,
    /// The reference.
    reference: PathBuf,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let p = read_picture(&a.picture)?;
    let r = read_picture(&a.reference)?;
    let tone = ToneMap::new(&Histogram::from_picture(&r), ToneMode::Camera, DisplayRange::default());
    let m = metrics(&p, &r, &tone, None)
        .with_context(|| format!("comparing {} with {}", a.picture.display(), a.reference.display()))?;
    println!(
        "rmse {:.6} relative_rmse {:.4} psnr_db {:.2} ssim {:.4} pixels {}",
        m.rmse, m.relative_rmse, m.psnr_db, m.ssim, m.pixels
    );
    Ok(ExitCode::SUCCESS)
}
