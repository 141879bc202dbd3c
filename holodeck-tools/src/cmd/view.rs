//! `holodeck view`: a display client. Headless for now: it walks a file of
//! views, asks the server for each view's beams, draws the frame after the
//! immediate transfer and again as traced samples arrive, and saves them.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_display::client::DisplaySession;
use holodeck_display::request::{BeamRequest, RequestOptions};
use holodeck_display::tonemap::Histogram;
use holodeck_display::{new_driver, output, Sample, Viewport};
use holodeck_protocol::View;
use holodeck_server::settings::parse_duration;

use crate::human::count;

/// Arguments of `holodeck view`.
#[derive(clap::Args)]
#[command(after_help = "\
Connects to a holodeck server as a display. For every view in --views it requests the beams
the view sees (new samples are traced near the eye), draws the frame as soon as the stored
samples are in, then keeps drawing as traced samples arrive for --wait, in --steps frames.
Frames go to DIR as view0001_00.png, view0001_01.png, ... (or .hdr with --format hdr).
Against a server with no samplers this replays the holodeck file.

Examples:
  holodeck view --connect 127.0.0.1:7777 --token-file room.hdk.token --headless \\
      --views walk.vf -o frames --wait 5s --steps 5
  holodeck view --connect unix:/tmp/room.sock --token-file room.hdk.token --headless \\
      --views walk.vf -o frames --format hdr --read-only")]
pub struct Args {
    /// The server: HOST:PORT or unix:PATH.
    #[arg(long)]
    connect: String,
    #[command(flatten)]
    token: super::args::TokenArgs,
    /// Run without a window (the only front end so far).
    #[arg(long)]
    headless: bool,
    /// A file of views, one per line.
    #[arg(long)]
    views: PathBuf,
    /// Directory for the frames.
    #[arg(short, long)]
    output: PathBuf,
    #[command(flatten)]
    frame: super::args::FrameArgs,
    /// Frame format: png or hdr.
    #[arg(long, default_value = "png")]
    format: String,
    /// How long to keep receiving traced samples per view (0: stored samples only).
    #[arg(long, default_value = "0s")]
    wait: String,
    /// Frames drawn while waiting (after the first).
    #[arg(long, default_value_t = 1)]
    steps: u32,
    /// Samples wanted per pixel.
    #[arg(long, default_value_t = 1.0)]
    density: f64,
    /// New samples pass this near the eye, as a fraction of the section diagonal.
    #[arg(long, default_value_t = 0.01)]
    eye_radius: f64,
    /// Connect read-only (cannot clobber, kill samplers or quit the server).
    #[arg(long)]
    read_only: bool,
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    if !a.headless {
        bail!("the windowed display is not built yet: add --headless to draw frames into files");
    }
    if a.format != "png" && a.format != "hdr" {
        bail!("--format must be png or hdr, not {:?}", a.format);
    }
    let token = a.token.token()?;
    let wait = parse_duration(&a.wait, 1.0)
        .map_err(anyhow::Error::msg)
        .context("--wait")?;
    let text = std::fs::read_to_string(&a.views).with_context(|| format!("reading {}", a.views.display()))?;
    let views = View::parse_list(&text).map_err(|(line, e)| anyhow::anyhow!("{}:{line}: {e}", a.views.display()))?;
    if views.is_empty() {
        bail!("{} holds no views", a.views.display());
    }
    std::fs::create_dir_all(&a.output).with_context(|| format!("creating {}", a.output.display()))?;
    let mut session = DisplaySession::connect(&a.connect, &token, a.read_only)
        .with_context(|| format!("connecting to {}", a.connect))?;
    let options = RequestOptions {
        density: a.density,
        eye_radius: a.eye_radius,
        ..RequestOptions::default()
    };
    let first = Viewport::new(views[0].clone(), a.frame.width, a.frame.height)?;
    let mut driver = new_driver(&a.frame.driver, first).map_err(anyhow::Error::msg)?;
    let mut hist = Histogram::new();
    for (i, view) in views.into_iter().enumerate() {
        let viewport = Viewport::new(view, a.frame.width, a.frame.height)?;
        driver.set_view(viewport.clone());
        let request = BeamRequest::for_viewport(session.sections(), &viewport, &options, i as u64);
        let mut sink = |s: &[Sample]| {
            hist.add_many(s.iter().map(|x| x.color));
            driver.add(s);
        };
        let t = session.request(&request, &mut sink)?;
        let mut received = t.samples;
        let mut step = 0u32;
        let save = |driver: &mut dyn holodeck_display::Driver,
                    hist: &Histogram,
                    step: u32,
                    new: u64,
                    total: u64,
                    took: Duration|
         -> Result<()> {
            let start = Instant::now();
            let picture = driver.render();
            let render = start.elapsed();
            let path = a.output.join(format!("view{:04}_{step:02}.{}", i + 1, a.format));
            let mode = output::parse_tone(&a.frame.tone, Some(&picture)).map_err(anyhow::Error::msg)?;
            output::save(&picture, hist, mode, &path)?;
            println!(
                "{}: {} new samples in {:.0} ms ({} in all, {} kept), drawn in {:.1} ms",
                path.display(),
                count(new),
                took.as_secs_f64() * 1e3,
                count(total),
                count(driver.stats().kept),
                render.as_secs_f64() * 1e3
            );
            Ok(())
        };
        save(driver.as_mut(), &hist, step, t.samples, received, t.elapsed)?;
        let steps = a.steps.max(1);
        if !wait.is_zero() {
            for _ in 0..steps {
                step += 1;
                let start = Instant::now();
                let deadline = start + wait / steps;
                let mut sink = |s: &[Sample]| {
                    hist.add_many(s.iter().map(|x| x.color));
                    driver.add(s);
                };
                let n = session.refine(deadline, &mut sink)?;
                received += n;
                save(driver.as_mut(), &hist, step, n, received, start.elapsed())?;
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
