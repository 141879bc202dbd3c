//! `holodeck compare`: how far a picture is from a reference, in every
//! measure of the yardstick (see `holodeck_display::compare`).

use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{bail, Context, Result};
use holodeck_display::compare::{Metrics, ReferenceNoise, Yardstick, DEFAULT_CLAMP};
use holodeck_display::image_io::read_picture;
use holodeck_display::tonemap::{ToneMap, ToneMode};
use holodeck_sampler::render::silhouettes;
use holodeck_sampler::TraceOptions;

use holodeck::SceneInput;

/// Arguments of `holodeck compare`.
#[derive(clap::Args)]
#[command(after_help = "\
Prints the error of PICTURE against REFERENCE (same size): relative RMSE, relative RMSE with
values clamped at --clamp, relative MSE ((x-y)^2/(y^2+0.01)), RMSE and PSNR in linear radiance;
SSIM and LDR-FLIP on both pictures tone mapped (camera mode) by the reference's histogram;
HDR-FLIP over the reference's exposures; and the light kept: PICTURE's luminance over
REFERENCE's in the darkest quarter, the middle half and the brightest quarter of the
reference's pixels (and in the band around silhouettes with --scene and --view).
Pictures are .hdr (linear) or 8-bit (decoded from sRGB).

With --second, an independent render of the same view (another --seed), the reference is the
mean of the two, its own noise is stated, and the light kept is measured without the bias of
choosing the darkest pixels on a noisy picture (regions are chosen on REFERENCE and measured
against SECOND). A reference whose noise is not under a quarter of an error is reported so.

Examples:
  holodeck render builtin:room --spp 512 --seed 1 -o ref1.hdr
  holodeck render builtin:room --spp 512 --seed 2 -o ref2.hdr
  holodeck pict room.hdk -o pict.hdr
  holodeck compare pict.hdr ref1.hdr --second ref2.hdr
  holodeck compare pict.hdr ref1.hdr --second ref2.hdr --scene builtin:room --json")]
pub struct Args {
    /// The picture under test.
    picture: PathBuf,
    /// The reference.
    reference: PathBuf,
    /// An independent render of the reference's view: states its noise.
    #[arg(long)]
    second: Option<PathBuf>,
    /// The scene, to find the silhouettes of --view for the band's measures.
    #[arg(long)]
    scene: Option<String>,
    /// The view of the pictures (Radiance notation), for the band.
    #[arg(long, default_value = holodeck::ROOM_VIEW, allow_hyphen_values = true)]
    view: String,
    /// The level the clamped relative RMSE clamps every channel at.
    #[arg(long, default_value_t = DEFAULT_CLAMP, value_parser = holodeck_cli::args::positive)]
    clamp: f64,
    /// Print one JSON object instead of text.
    #[arg(long)]
    json: bool,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let p = read_picture(&a.picture)?;
    let r = read_picture(&a.reference)?;
    let yardstick = match &a.second {
        Some(second) => {
            let s = read_picture(second)?;
            let mean = holodeck_protocol::Picture {
                width: r.width,
                height: r.height,
                pixels: r.pixels.iter().zip(&s.pixels).map(|(&x, &y)| 0.5 * (x + y)).collect(),
            };
            let tone = ToneMap::from_picture(&mean, ToneMode::Camera);
            Yardstick::from_halves(&r, &s, tone)
                .with_context(|| format!("{} and {}", a.reference.display(), second.display()))?
        }
        None => {
            let tone = ToneMap::from_picture(&r, ToneMode::Camera);
            Yardstick::new(r, tone).with_context(|| a.reference.display().to_string())?
        }
    }
    .with_clamp(a.clamp);
    let yardstick = match &a.scene {
        Some(scene) => {
            let view = holodeck_cli::view_arg::parse(&a.view).with_context(|| format!("--view {:?}", a.view))?;
            let input = SceneInput::open(scene, None, None)?;
            let tracer = input.tracer(TraceOptions::default());
            let (w, h) = (yardstick.reference().width, yardstick.reference().height);
            let edges = silhouettes(&tracer, &view, w as u32, h as u32, holodeck::truth::SILHOUETTE_RATIO)?;
            yardstick.with_band(holodeck::truth::dilate(&edges, w, h))?
        }
        None => yardstick,
    };
    let m = yardstick
        .measure(&p)
        .with_context(|| format!("comparing {} with {}", a.picture.display(), a.reference.display()))?;
    let noise = yardstick.noise().copied();
    let too_noisy = noise.map(|n| n.too_noisy_for(&m)).unwrap_or_default();
    if a.json {
        let out = serde_json::json!({
            "picture": a.picture,
            "reference": a.reference,
            "second": a.second,
            "metrics": m,
            "reference_noise": noise,
            "reference_too_noisy_for": too_noisy,
        });
        println!("{}", serde_json::to_string_pretty(&out)?);
    } else {
        print!("{}", report(&m, noise.as_ref(), &too_noisy));
    }
    if m.pixels == 0 {
        bail!("no pixels compared");
    }
    Ok(ExitCode::SUCCESS)
}

/// The text report of one comparison.
pub fn report(m: &Metrics, noise: Option<&ReferenceNoise>, too_noisy: &[&str]) -> String {
    let mut s = format!(
        "relative RMSE {:.4}, relative MSE {:.5}; clamped at {}: {:.4} and {:.5}; RMSE {:.6}, PSNR {:.2} dB\n\
         SSIM {:.4}, FLIP {:.4} (LDR), {:.4} (HDR); {} pixels\n",
        m.relative_rmse,
        m.relative_mse,
        m.clamp,
        m.clamped_relative_rmse,
        m.clamped_relative_mse,
        m.rmse,
        m.psnr_db,
        m.ssim,
        m.flip,
        m.hdr_flip,
        m.pixels
    );
    let l = &m.light;
    s += &format!(
        "light kept: frame {:.3}, darkest quarter {:.3}, middle half {:.3}, brightest quarter {:.3}",
        l.frame, l.dark, l.middle, l.bright
    );
    if let Some(b) = l.band {
        s += &format!(", silhouette band {b:.3}");
    }
    s += &format!("; brightest spot {:.3}\n", m.peak);
    if let Some(b) = m.band_relative_rmse {
        s += &format!("relative RMSE in the silhouette band {b:.4}\n");
    }
    match noise {
        Some(n) => {
            s += &format!(
                "reference noise: relative RMSE {:.4}, relative MSE {:.5}; clamped {:.4} and {:.5}; FLIP between its halves {:.4}\n",
                n.relative_rmse, n.relative_mse, n.clamped_relative_rmse, n.clamped_relative_mse, n.flip_between_halves
            );
            if too_noisy.is_empty() {
                s += "the reference's noise is under a quarter of every error above\n";
            } else {
                s += &format!(
                    "the reference is too noisy for: {} (its noise is not under a quarter of the error: render it with more samples)\n",
                    too_noisy.join(", ")
                );
            }
        }
        None => {
            s += "reference noise: unknown (give --second, an independent render of the view, to state it; \
                  without it the darkest quarter's light kept leans high by the reference's own noise)\n"
        }
    }
    s
}
