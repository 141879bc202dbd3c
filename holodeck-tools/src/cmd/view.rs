//! `holodeck view`: a display client. In a window, a person walks through
//! the holodeck (the paper's input model); headless, it walks a file of
//! views, asks the server for each view's beams, draws the frame after the
//! immediate transfer and again as traced samples arrive, and saves them.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_display::client::DisplaySession;
use holodeck_display::gather::Gather;
use holodeck_display::request::{outstanding, BeamRequest, Refinement, RequestOptions};
use holodeck_display::tonemap::Histogram;
use holodeck_display::{output, Sample, Viewport};
use holodeck_file::settings::parse_duration;
use holodeck_protocol::View;

use holodeck_cli::human::count;

/// Arguments of `holodeck view`.
#[derive(clap::Args)]
#[command(after_help = "\
Connects to a holodeck server as a display and opens a window on it: the left button moves
toward what is under the cursor, the right backs away, the middle turns, shift orbits; keys
and -i commands as below. New beams are asked for when motion stops; while the view stays,
the samples it asks for per pixel double as they arrive (up to --max-density).

Keys: l last view, v print view, f frame the focus rectangle (ctrl+shift drag), p pause,
Enter resume, ctrl+R redraw, ctrl+L refresh from server, K kill samplers, R restart,
C clobber, h/H fix/release head height, t re-tone-map, q quit.

With --headless there is no window: for every view in --views it requests the beams
the view sees (new samples are traced near the eye, in the frame), draws the frame as soon as
the stored samples are in, then keeps drawing as traced samples arrive for --wait, in --steps
frames. While a view stays, the samples it asks for per pixel double each time most of them
have arrived (up to --max-density), so the picture keeps converging. Moving to the next view
keeps every pixel's estimate (reprojected), and the server sends only rays not sent before.
Frames go to --frames DIR as view0001_00.png, view0001_01.png, ... (or .hdr with --format hdr).
Against a server with no samplers this replays the holodeck file.

Examples:
  holodeck view --connect 127.0.0.1:7777 --token-file room.hdk.token --driver mesh
  printf 'where\\nquit\\n' | holodeck view --connect 127.0.0.1:7777 --token-file room.hdk.viewer.token -i
  holodeck view --connect 127.0.0.1:7777 --token-file room.hdk.token --headless \\
      --views walk.vf --frames frames --wait 5s --steps 5
  holodeck view --connect unix:/tmp/room.sock --token-file room.hdk.token --headless \\
      --views walk.vf --frames frames --format hdr --read-only")]
pub struct Args {
    /// The server: HOST:PORT or unix:PATH.
    #[arg(long)]
    connect: String,
    #[command(flatten)]
    token: holodeck_cli::args::TokenArgs,
    /// Run without a window: walk --views and write frames into --frames.
    #[arg(long, requires = "views")]
    headless: bool,
    /// A file of views, one per line (in a window: the first is where it starts).
    #[arg(long)]
    views: Option<PathBuf>,
    /// Directory for the frames (headless; created if missing).
    #[arg(long, value_name = "DIR")]
    frames: Option<PathBuf>,
    /// The frames' directory, as older versions spelled it (`-o DIR`); use --frames.
    #[arg(short = 'o', long = "output", hide = true, conflicts_with = "frames")]
    old_frames: Option<PathBuf>,
    #[command(flatten)]
    window: crate::window::WindowArgs,
    #[command(flatten)]
    frame: holodeck_cli::args::FrameArgs,
    /// Frame format: png or hdr.
    #[arg(long, default_value = "png")]
    format: String,
    /// How long to keep receiving traced samples per view (0: stored samples only).
    #[arg(long, default_value = "0s")]
    wait: String,
    /// Frames drawn while waiting (after the first).
    #[arg(long, default_value_t = 1)]
    steps: u32,
    /// Samples wanted per pixel at first; doubled as they arrive while a view stays.
    #[arg(long, default_value_t = 1.0)]
    density: f64,
    /// Most samples per pixel a still view asks for.
    #[arg(long, default_value_t = 1024.0)]
    max_density: f64,
    /// New samples pass this near the eye, as a fraction of the section diagonal.
    #[arg(long, default_value_t = RequestOptions::default().eye_radius, value_parser = holodeck_cli::args::non_negative)]
    eye_radius: f64,
    /// Connect read-only (cannot clobber, kill samplers or quit the server).
    #[arg(long)]
    read_only: bool,
}

/// Time between checks for a still view's refinement.
const TICK: Duration = Duration::from_millis(100);

/// A still view that got nothing for this long asks for more at once.
const QUIET: Duration = Duration::from_secs(1);

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    a.frame.check()?;
    if !(a.density.is_finite() && a.density > 0.0 && a.max_density.is_finite()) {
        bail!("--density and --max-density must be positive numbers");
    }
    if !a.headless {
        return windowed(a);
    }
    if let Some(d) = &a.old_frames {
        eprintln!(
            "holodeck view: -o {} names the frames' directory as older versions did; it is --frames {0} now",
            d.display()
        );
    }
    let (Some(views_path), Some(output)) = (a.views.clone(), a.frames.clone().or(a.old_frames.clone())) else {
        bail!("--headless needs --views and --frames");
    };
    if a.format != "png" && a.format != "hdr" {
        bail!("--format must be png or hdr, not {:?}", a.format);
    }
    let token = a.token.token()?;
    let addr = a.token.address(&a.connect)?;
    let wait = parse_duration(&a.wait, 1.0).context("--wait")?;
    let views = holodeck_cli::view_arg::read_views(&views_path)?;
    std::fs::create_dir_all(&output).with_context(|| format!("creating {}", output.display()))?;
    let session =
        DisplaySession::connect(&addr, &token, a.read_only).with_context(|| format!("connecting to {}", a.connect))?;
    let first = Viewport::new(views[0].clone(), a.frame.width, a.frame.height)?;
    let driver = a.frame.driver_choice()?.make(first)?;
    let mut walk = Headless {
        a: &a,
        output,
        wait,
        session,
        driver,
        batch: Gather::default(),
        hist: Histogram::new(),
    };
    for (i, view) in views.into_iter().enumerate() {
        walk.view(i, view)?;
    }
    Ok(ExitCode::SUCCESS)
}

/// A headless display walking its views, writing frames.
struct Headless<'a> {
    a: &'a Args,
    /// Where frames go.
    output: PathBuf,
    /// How long each view refines after its first frame.
    wait: Duration,
    session: DisplaySession,
    driver: Box<dyn holodeck_display::Driver>,
    /// Samples received and not yet handed to the driver.
    batch: Gather,
    /// Luminance of every sample received, for the tone map.
    hist: Histogram,
}

impl Headless<'_> {
    /// Draws the driver's frame of `view` into the file `name`, saying how
    /// many samples came (`new`, `total`) in how long.
    fn save(&mut self, view: &View, name: String, new: u64, total: u64, took: Duration) -> Result<()> {
        let start = Instant::now();
        let picture = self.driver.render();
        let render = start.elapsed();
        let path = self.output.join(name);
        let mode = output::parse_tone(&self.a.frame.tone, Some(&picture))?;
        output::save(&picture, &self.hist, mode, &path, Some(view))?;
        summary!(
            "{}: {} new samples in {:.0} ms ({} in all, {} pixel estimates), drawn in {:.1} ms",
            path.display(),
            count(new),
            took.as_secs_f64() * 1e3,
            count(total),
            count(self.driver.stats().kept),
            render.as_secs_f64() * 1e3
        );
        Ok(())
    }

    /// View `i` of the walk: its first request and frame, then `--steps`
    /// frames while the density rises, within `--wait`.
    fn view(&mut self, i: usize, view: View) -> Result<()> {
        let a = self.a;
        let viewport = Viewport::new(view, a.frame.width, a.frame.height)?;
        // The driver keeps its estimates across small moves (reprojected); after
        // a large turn it drops them, and the server must send everything again.
        let drops = self.driver.stats().cache_drops;
        self.driver.set_view(viewport.clone());
        let resend = i == 0 || self.driver.stats().cache_drops > drops;
        let mut refinement = Refinement::new(a.density, a.max_density);
        let options = RequestOptions {
            eye_radius: a.eye_radius,
            ..RequestOptions::default()
        };
        // Each pixel asks for its share of the density, by how much its rays
        // disagree, less what it holds (reprojected from earlier views too).
        let refining = |driver: &dyn holodeck_display::Driver, session: &DisplaySession, density: f64| {
            let want = driver.needs(density as f32);
            BeamRequest::refining(session.sections(), &viewport, &options, i as u64, &want, &|k| {
                session.received(k)
            })
        };
        let mut request = if resend {
            let first = RequestOptions {
                density: a.density,
                ..options
            };
            BeamRequest::for_viewport(self.session.sections(), &viewport, &first, i as u64)
        } else {
            refining(self.driver.as_ref(), &self.session, a.density)
        };
        let t = {
            let (driver, hist, batch) = (&mut self.driver, &mut self.hist, &mut self.batch);
            let mut sink = |s: &[Sample]| {
                hist.add_many(s.iter().map(|x| x.color));
                batch.add(s, driver.as_mut());
            };
            let session = &self.session;
            refinement.asked(outstanding(&request, &|k| if resend { 0 } else { session.received(k) }));
            let t = self.session.request(&request, resend, &mut sink)?;
            self.batch.flush(self.driver.as_mut());
            t
        };
        let mut received = t.samples;
        let name = |step: u32| format!("view{:04}_{step:02}.{}", i + 1, a.format);
        self.save(&viewport.view, name(0), t.samples, received, t.elapsed)?;
        if self.wait.is_zero() {
            return Ok(());
        }
        let steps = a.steps.max(1);
        let mut last = Instant::now();
        for step in 1..=steps {
            let start = Instant::now();
            let deadline = start + self.wait / steps;
            let mut new = 0u64;
            while Instant::now() < deadline {
                let (driver, hist, batch) = (&mut self.driver, &mut self.hist, &mut self.batch);
                let mut sink = |s: &[Sample]| {
                    hist.add_many(s.iter().map(|x| x.color));
                    batch.add(s, driver.as_mut());
                };
                let n = self.session.refine((Instant::now() + TICK).min(deadline), &mut sink)?;
                self.batch.flush(self.driver.as_mut());
                new += n;
                if n > 0 {
                    last = Instant::now();
                }
                let missing = outstanding(&request, &|k| self.session.received(k));
                if let Some(density) = refinement.raise(missing, last.elapsed() >= QUIET) {
                    last = Instant::now();
                    request = refining(self.driver.as_ref(), &self.session, density);
                    refinement.asked(outstanding(&request, &|k| self.session.received(k)));
                    tracing::info!("view {}: asking for {density} samples per pixel", i + 1);
                    self.session.raise(&request)?;
                }
            }
            received += new;
            self.save(&viewport.view, name(step), new, received, start.elapsed())?;
        }
        Ok(())
    }
}

/// The window on a live session.
fn windowed(a: Args) -> Result<ExitCode> {
    let token = a.token.token()?;
    let addr = a.token.address(&a.connect)?;
    let session =
        DisplaySession::connect(&addr, &token, a.read_only).with_context(|| format!("connecting to {}", a.connect))?;
    let view = match &a.views {
        Some(path) => holodeck_cli::view_arg::read_views(path)?.remove(0),
        None => {
            let first = session.sections().first().context("the holodeck has no sections")?;
            holodeck_display::navigate::default_view(first)
        }
    };
    let source = holodeck_display::window::ServerSource::new(session, a.connect.clone());
    let walk = holodeck_display::window::WalkOptions {
        density: a.density,
        max_density: a.max_density,
        request: RequestOptions {
            eye_radius: a.eye_radius,
            ..RequestOptions::default()
        },
        ..Default::default()
    };
    crate::window::open(Box::new(source), view, &a.frame, &a.window, walk)?;
    Ok(ExitCode::SUCCESS)
}
