//! `holodeck run`: the server and local sampler processes in one command
//! (like Radiance's rholo), and optionally a headless display. Without a
//! display it is a batch fill.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Command, ExitCode, ExitStatus, Stdio};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_file::settings::parse_duration;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::{client, Control};

use holodeck_cli::args::{frame_size, MAX_WORKERS, SIDE};
use holodeck_cli::human::count;
use holodeck_cli::progress::Progress;

use crate::supervise::{how, me, stop_on_signals, stop_signal, Child};

/// Arguments of `holodeck run`.
#[derive(clap::Args)]
#[command(after_help = "\
Starts `holodeck serve` on a free local port and WORKERS `holodeck sample` processes
(one tracing thread each), lets them fill FILE for --time, then asks the server to quit
(it flushes) and waits for everything to end. Ctrl-C or SIGTERM to `run` stops early, also
cleanly (summary printed; exit status 130 or 143). A server that stops answering fails the
run within 20 s. The
children stop with `run` however it ends (even killed), the server flushing its file.
If the server, a sampler or the display dies by a signal or fails, `run` says which and
how, stops the rest, and exits with status 1. With
--driver DRIVER, a display (`holodeck view`) opens a window on the session where there is a screen
(DISPLAY or WAYLAND_DISPLAY set): walk through the holodeck as the samplers fill it, with
the samplers tracing what the window looks at first; closing it (q) ends the run. With
--headless, or without a screen, the display instead walks --views, sharing --time among
them, and its frames go to --frames.
For workers on other hosts, start `holodeck serve` and `holodeck sample` yourself.

Examples:
  holodeck run builtin:room room.hdk -n 2 --time 30s
  holodeck run builtin:room room.hdk -n 2 --time 1h --web 127.0.0.1:8080    # share the link it prints
  holodeck run builtin:room room.hdk -n 2 --driver mesh                  # a window, until q
  holodeck run builtin:room room.hdk -n 2 --driver quadtree --listen 127.0.0.1:7777
  holodeck view --connect 127.0.0.1:7777 --token-file room.hdk.viewer.token   # a second window
  holodeck run builtin:room room.hdk -n 2 --time 20s --driver quadtree --headless --views walk.vf --frames out
  holodeck run scenes/room.toml room.hdk -n 16 --time 2h")]
pub struct Args {
    /// Scene file, or builtin:NAME.
    scene: String,
    /// The holodeck file (created from the scene if missing).
    file: PathBuf,
    /// Local sampler processes.
    #[arg(short = 'n', long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..=MAX_WORKERS))]
    workers: u32,
    /// How long to fill (e.g. 30s, 10m, 2h); bounds every mode. A run with a
    /// window may leave it out: it lasts until the window is closed (q); so
    /// may one with --web: it lasts until Ctrl-C.
    #[arg(long)]
    time: Option<String>,
    /// Display: none (a batch fill), or a driver (quadtree, splat, voronoi,
    /// mesh) for a window, or with --headless a display that walks --views,
    /// drawing frames into --frames.
    #[arg(long, value_parser = driver_names(), default_value = "none")]
    driver: String,
    /// The driver, as older versions spelled it (`-o DRIVER`); use --driver.
    #[arg(short = 'o', long = "output", hide = true, value_parser = driver_names(), conflicts_with = "driver")]
    old_driver: Option<String>,
    /// Draw frames into --frames instead of opening a window.
    #[arg(long)]
    headless: bool,
    /// Views for the display (a file of Radiance views, one per line; a
    /// window starts at the first); default: one view from the middle of
    /// the first section.
    #[arg(long)]
    views: Option<PathBuf>,
    /// Directory for the display's frames (created if missing).
    #[arg(long, default_value = "frames")]
    frames: PathBuf,
    /// The file's size limit for this run, replacing its DISKSPACE setting (e.g. 2G; 0 for
    /// none); the run stops when it is reached, keeping every ray stored.
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    diskspace: Option<u64>,
    /// Where the server listens (HOST:PORT), so that other displays can join
    /// with `holodeck view --connect`; default: a free port on this machine only.
    #[arg(long, default_value = "127.0.0.1:0")]
    listen: String,
    /// Also serve the web display here (HOST:PORT; see `holodeck serve --help`):
    /// the link it prints lets anyone with a browser join the session.
    #[arg(long, value_name = "ADDR")]
    web: Option<String>,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 512, value_parser = clap::value_parser!(u32).range(SIDE))]
    width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 384, value_parser = clap::value_parser!(u32).range(SIDE))]
    height: u32,
    /// The display's denoiser: auto (the atrous filter on a hardware GPU where there is
    /// one, else on the CPU), atrous, atrous-gpu, oidn (a build with --features oidn) or off.
    #[arg(long, default_value = holodeck_cli::args::DEFAULT_DENOISER)]
    denoise: String,
    /// Largest number of bounces.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    /// Path samples averaged per ray (less noise per ray, fewer rays).
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    #[command(flatten)]
    reorder: holodeck_cli::args::ReorderArgs,
    /// Write on top of a file whose newest commit is damaged, keeping what can
    /// still be read and losing the rest for good (see `holodeck check`).
    #[arg(long)]
    accept_loss: bool,
    /// For a new FILE: record virtual distances through windows and mirrors
    /// (VDISTANCE; see `holodeck fill --help`).
    #[arg(long)]
    vdistance: bool,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = holodeck_cli::human::count_in(1, holodeck_cli::args::MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// For a .hds scene file: decompressed blocks each sampler keeps in memory (K, M, G; default: all).
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    scene_memory: Option<u64>,
}

/// The names `--driver` takes: none, or a display driver.
fn driver_names() -> clap::builder::PossibleValuesParser {
    clap::builder::PossibleValuesParser::new(std::iter::once("none").chain(holodeck_display::DRIVERS.iter().copied()))
}

/// Asks the server at `addr` to flush and quit.
pub(crate) fn quit(addr: &str, token: &str) -> Result<()> {
    client::send_control(addr, token, Control::Quit)?;
    Ok(())
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    frame_size(a.width, a.height)?;
    let plan = Plan::new(&a)?;
    let file = a
        .file
        .to_str()
        .context("the file name must be valid UTF-8")?
        .to_string();
    let (server, addr) = start_server(&a, &file)?;
    let token_file = format!("{file}.token");
    let token = holodeck_cli::args::read_token_file(Path::new(&token_file))?.0;
    let workers = (0..a.workers)
        .map(|i| Child::spawn(format!("sampler {}", i + 1), sampler_command(&a, &addr, &file, i)?))
        .collect::<Result<Vec<_>>>()?;
    let how_long = if plan.time == Duration::MAX && !plan.windowed {
        "until Ctrl-C".to_string()
    } else if plan.time == Duration::MAX {
        "until the window is closed".to_string()
    } else {
        format!("for {:?}", plan.time)
    };
    summary!(
        "filling {} with {} local samplers {how_long} (server {addr}; another display joins with \
         `holodeck view --connect {addr} --token-file {file}.viewer.token`)",
        a.file.display(),
        workers.len()
    );
    let start = Instant::now();
    let viewer = match &plan.display {
        Some((driver, views)) => {
            let cmd = display_command(&a, &plan, &addr, &token_file, driver, views)?;
            Some(Child::spawn(if plan.windowed { "window" } else { "display" }, cmd)?)
        }
        None => None,
    };
    let mut session = Session {
        server,
        workers,
        viewer,
        failures: Vec::new(),
        server_stopped: false,
    };
    stop_on_signals();
    session.supervise(start, &plan)?;
    session.close_display(plan.windowed)?;
    let secs = start.elapsed().as_secs_f64();
    let early = session.server_stopped
        && stop_signal().is_none()
        && plan.time != Duration::MAX
        && secs + 1.0 < plan.time.as_secs_f64();
    session.stop(&addr, &token)?;
    report(&a, plan.rays_before, secs, early)?;
    if !session.failures.is_empty() {
        bail!("{}", session.failures.join("; "));
    }
    if let Some(signal) = stop_signal() {
        let name = if signal == libc::SIGINT { "SIGINT" } else { "SIGTERM" };
        eprintln!("holodeck run: interrupted by {name}: stopped early, the file flushed");
        return Ok(ExitCode::from(128 + signal as u8));
    }
    Ok(ExitCode::SUCCESS)
}

/// What the arguments decide before anything starts.
struct Plan {
    /// Whether the display is a window (a driver, a screen, not --headless).
    windowed: bool,
    /// How long to run (`Duration::MAX`: until the window closes).
    time: Duration,
    /// The display's driver and views file, if there is a display.
    display: Option<(String, PathBuf)>,
    /// Rays the file held before.
    rays_before: u64,
}

impl Plan {
    /// Checks the arguments, prepares the file (created or adopted), and
    /// writes a views file for a display given none.
    fn new(a: &Args) -> Result<Plan> {
        let chosen = match &a.old_driver {
            Some(d) => {
                eprintln!(
                    "holodeck run: -o {d} names the display driver as older versions did; it is --driver {d} now"
                );
                d.as_str()
            }
            None => a.driver.as_str(),
        };
        let driver = (chosen != "none").then(|| chosen.to_string());
        let screen = ["DISPLAY", "WAYLAND_DISPLAY"]
            .iter()
            .any(|v| std::env::var_os(v).is_some_and(|s| !s.is_empty()));
        let windowed = driver.is_some() && screen && !a.headless;
        let time = match (&a.time, windowed) {
            (Some(t), _) => parse_duration(t, 1.0).context("--time")?,
            // Until the window closes.
            (None, true) => Duration::MAX,
            // A session for browsers: until SIGINT (Ctrl-C) or SIGTERM.
            (None, false) if a.web.is_some() => Duration::MAX,
            (None, false) => {
                bail!(
                    "give --time: without a window nothing else ends the run (with one, closing it does: q; \
                     with --web, Ctrl-C does)"
                )
            }
        };
        holodeck_display::denoise::Denoiser::parse(&a.denoise).context("--denoise")?;
        let (_, file) = holodeck_cli::prepare::prepare(
            &a.scene,
            &a.file,
            a.triangles,
            a.scene_memory,
            a.accept_loss,
            a.vdistance,
        )?;
        let display = match (driver, &a.views) {
            (None, _) => None,
            (Some(d), Some(views)) => Some((d, views.clone())),
            (Some(d), None) => {
                // No views given: the room's own view, or along the first section from its middle.
                let view = if a.scene == "builtin:room" {
                    holodeck::ROOM_VIEW.to_string()
                } else {
                    holodeck_display::navigate::default_view(&file.sections()[0]).to_spec()
                };
                std::fs::create_dir_all(&a.frames).with_context(|| format!("creating {}", a.frames.display()))?;
                let path = a.frames.join("views.vf");
                std::fs::write(&path, format!("{view}\n")).with_context(|| format!("writing {}", path.display()))?;
                Some((d, path))
            }
        };
        Ok(Plan {
            windowed,
            time,
            display,
            rays_before: file.summary().rays(),
        })
    }
}

/// Starts `holodeck serve` on `file` and reads the address it says it
/// listens on (its first line of output).
fn start_server(a: &Args, file: &str) -> Result<(Child, String)> {
    let mut cmd = me()?;
    cmd.args(["serve", file, "--listen", &a.listen])
        .args(a.accept_loss.then_some("--accept-loss"))
        .args(a.web.iter().flat_map(|w| ["--web", w.as_str()]))
        .args(
            a.diskspace
                .iter()
                .flat_map(|d| ["--diskspace".to_string(), d.to_string()]),
        )
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit());
    let mut server = Child::spawn("server", cmd)?;
    let mut line = String::new();
    let mut out = BufReader::new(server.process.stdout.as_mut().context("server output")?);
    out.read_line(&mut line)?;
    let Some(addr) = line.trim().strip_prefix("listening on ").map(str::to_string) else {
        drop(out);
        let why = server.finish(Duration::from_secs(5)).unwrap_or_default();
        bail!("the server did not start: {why}");
    };
    if a.web.is_some() {
        // The server's next line gives the page's address and a viewer's link.
        let mut web = String::new();
        out.read_line(&mut web)?;
        if !web.starts_with("web display on ") {
            drop(out);
            let why = server.finish(Duration::from_secs(5)).unwrap_or_default();
            bail!("the server did not start its web display: {}{why}", web.trim());
        }
        println!("{}", web.trim());
    }
    drop(out);
    Ok((server, addr))
}

/// The command line of local sampler `i` (one thread; writer access only).
fn sampler_command(a: &Args, addr: &str, file: &str, i: u32) -> Result<Command> {
    let mut cmd = me()?;
    // Samplers need no more than writer access.
    let writer_token_file = format!("{file}.writer.token");
    cmd.args([
        "sample",
        &a.scene,
        "--connect",
        addr,
        "--token-file",
        &writer_token_file,
        "-j",
        "1",
    ])
    .args(["--bounces", &a.bounces.to_string(), "--samples", &a.samples.to_string()])
    .args(["--reorder", &a.reorder.reorder.to_string(), "--retry-for", "0s"])
    .args(["--seed", &(u64::from(i) + 1).to_string()])
    .stdout(Stdio::null())
    .stderr(Stdio::inherit());
    if let Some(m) = a.scene_memory {
        cmd.args(["--scene-memory", &m.to_string()]);
    }
    if let Some(t) = a.triangles {
        cmd.args(["--triangles", &t.to_string()]);
    }
    Ok(cmd)
}

/// The display's command line: a window, or a headless walk of `views`
/// sharing the run's time among them.
fn display_command(a: &Args, plan: &Plan, addr: &str, token_file: &str, driver: &str, views: &Path) -> Result<Command> {
    let mut cmd = me()?;
    cmd.args([
        "view",
        "--connect",
        addr,
        "--token-file",
        token_file,
        "--driver",
        driver,
    ])
    .args(["--denoise", &a.denoise])
    .arg("--views")
    .arg(views)
    .args(["-x", &a.width.to_string(), "-y", &a.height.to_string()])
    .stderr(Stdio::inherit());
    if driver == "voronoi" {
        cmd.args(["--geometry", a.scene.as_str()]);
    }
    if !plan.windowed {
        let count = std::fs::read_to_string(views)
            .with_context(|| format!("reading {}", views.display()))?
            .lines()
            .filter(|l| !l.trim().is_empty() && !l.trim_start().starts_with('#'))
            .count()
            .max(1);
        let wait = format!("{}s", plan.time.as_secs_f64() / count as f64);
        cmd.arg("--headless")
            .arg("--frames")
            .arg(&a.frames)
            .args(["--wait", &wait, "--steps", "2"]);
    }
    Ok(cmd)
}

/// The processes of a run and what went wrong with them.
struct Session {
    server: Child,
    workers: Vec<Child>,
    viewer: Option<Child>,
    /// Each failure, in words, in the order seen.
    failures: Vec<String>,
    /// Whether the server has exited (and was reported).
    server_stopped: bool,
}

impl Session {
    /// Watches the processes until the plan's time is up, a signal asks to
    /// stop, the server or the display ends, or every sampler has ended.
    fn supervise(&mut self, start: Instant, plan: &Plan) -> Result<()> {
        // A window shows its own progress; a run bounded by TIME shows the time.
        let bar = (plan.time != Duration::MAX).then(|| Progress::timed("running", None, plan.time));
        while start.elapsed() < plan.time && stop_signal().is_none() {
            if let Some(status) = self.server.exited()? {
                // A server stops on its own at TIME or a full DISKSPACE; anything else is a failure.
                self.server_ended(status);
                break;
            }
            if let Some(v) = &mut self.viewer {
                if let Some(status) = v.exited()? {
                    v.done = true;
                    if !status.success() {
                        self.failures.push(format!("the display {}", how(status)));
                    }
                    break;
                }
            }
            for w in self.workers.iter_mut().filter(|w| !w.done) {
                if let Some(status) = w.exited()? {
                    w.done = true;
                    if !status.success() {
                        let failure = format!("{} {}", w.name, how(status));
                        match &bar {
                            Some(bar) => bar.suspend(|| eprintln!("holodeck run: {failure}")),
                            None => eprintln!("holodeck run: {failure}"),
                        }
                        self.failures.push(failure);
                    }
                }
            }
            let display_done = self.viewer.as_ref().is_none_or(|v| v.done || !plan.windowed);
            if !self.workers.is_empty() && self.workers.iter().all(|w| w.done) && display_done {
                self.samplers_all_ended()?;
                break;
            }
            std::thread::sleep(Duration::from_millis(200));
            if let Some(bar) = &bar {
                bar.tick();
            }
        }
        if let Some(bar) = &bar {
            bar.finish();
        }
        Ok(())
    }

    /// Notes that the server exited with `status`.
    fn server_ended(&mut self, status: ExitStatus) {
        self.server.done = true;
        self.server_stopped = true;
        if !status.success() {
            self.failures.push(format!("the server {}", how(status)));
        }
    }

    /// Every sampler has ended: nothing would be traced for the rest of
    /// TIME. Samplers end well by themselves when their server quits: waits
    /// for it to finish closing its file (as a quit would); after failed
    /// samplers, the server is asked to quit later.
    fn samplers_all_ended(&mut self) -> Result<()> {
        let wait = if self.failures.is_empty() { 60 } else { 2 };
        let grace = Instant::now() + Duration::from_secs(wait);
        let mut status = self.server.exited()?;
        while status.is_none() && Instant::now() < grace {
            std::thread::sleep(Duration::from_millis(50));
            status = self.server.exited()?;
        }
        match status {
            Some(status) => self.server_ended(status),
            None if self.failures.is_empty() => self
                .failures
                .push("every sampler ended before TIME, and the server did not stop".to_string()),
            None => {}
        }
        Ok(())
    }

    /// Closes a display still at work: a window (or any display after a
    /// stop signal) at once; a headless display gets two seconds to write
    /// its last frame.
    fn close_display(&mut self, windowed: bool) -> Result<()> {
        let Some(v) = self.viewer.as_mut().filter(|v| !v.done) else {
            return Ok(());
        };
        if windowed || stop_signal().is_some() {
            let _ = v.process.kill();
            let _ = v.process.wait();
            v.done = true;
            return Ok(());
        }
        let grace = Instant::now() + Duration::from_secs(2);
        let mut status = v.exited()?;
        while status.is_none() && Instant::now() < grace {
            std::thread::sleep(Duration::from_millis(50));
            status = v.exited()?;
        }
        match status {
            Some(status) if !status.success() => self.failures.push(format!("the display {}", how(status))),
            Some(_) => {}
            None => {
                tracing::info!("the display was still drawing when TIME was up; stopped");
                let _ = v.process.kill();
                let _ = v.process.wait();
            }
        }
        v.done = true;
        Ok(())
    }

    /// Asks a server still running to flush and quit, and waits for it and
    /// the samplers to end.
    fn stop(&mut self, addr: &str, token: &str) -> Result<()> {
        if stop_signal().is_some() && !self.server_stopped {
            // Ctrl-C reaches the whole process group: the server may have
            // flushed and quit on its own already.
            std::thread::sleep(Duration::from_millis(300));
            if let Some(status) = self.server.exited()? {
                self.server_ended(status);
            }
        }
        if !self.server_stopped {
            if let Err(e) = quit(addr, token) {
                // After a stop signal the server (which took it too, in the
                // same process group) may be closing already: how it exits
                // says whether anything failed.
                if stop_signal().is_none() {
                    self.failures.push(format!("asking the server to quit: {e:#}"));
                }
            }
            self.failures.extend(self.server.finish(Duration::from_secs(60)));
        }
        for w in self.workers.iter_mut().filter(|w| !w.done) {
            // Samplers of a server that failed fail too; that is not news.
            let failure = w.finish(Duration::from_secs(10));
            // Stopped by a signal, samplers that took it too are not news either.
            if self.failures.is_empty() && stop_signal().is_none() {
                self.failures.extend(failure);
            }
        }
        Ok(())
    }
}

/// Prints what the run added to the file, and why it ended early if the
/// server stopped on its own before TIME.
fn report(a: &Args, before: u64, secs: f64, early: bool) -> Result<()> {
    let after = HoloFile::open(&a.file, &OpenOptions::read_only())?.summary();
    let added = after.rays().saturating_sub(before);
    summary!(
        "{}: {} rays added in {secs:.1} s ({} rays/s); {} rays, {} of {} beams hold rays",
        a.file.display(),
        count(added),
        count((added as f64 / secs.max(1e-9)).round() as u64),
        count(after.rays()),
        count(after.sections.iter().map(|s| u64::from(s.1)).sum()),
        count(after.sections.iter().map(|s| u64::from(s.0)).sum())
    );
    if early {
        note!(
            "holodeck run: the server stopped on its own after {secs:.1} s, before --time: its DISKSPACE \
             limit or the file's TIME was reached, or an admin told it to quit (above). Every ray it \
             stored is committed; give --diskspace SIZE (0 for none) to go on past a full DISKSPACE"
        );
    }
    Ok(())
}
