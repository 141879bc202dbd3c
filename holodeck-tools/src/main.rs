//! `holodeck`: the one command users learn. It parses arguments and calls
//! into the libraries (`holodeck`: scenes, fills, pictures from a file,
//! references; `holodeck_bench`: the benchmarks, charts and the demo's
//! measured walk), printing and showing progress through `holodeck_cli`.
//!
//! * `cmd` — one module per command: its arguments and a `run` over the libraries.
//! * `parent` — living and dying with a parent process.
//! * `supervise` — child processes a command starts and watches, and stop signals.
//! * `web` — the web display's page and WebAssembly, embedded for `serve --web`.
//! * `window` — what `view` and `pict --window` share to open the walkthrough window.

use std::process::ExitCode;

use clap::{Parser, Subcommand};

#[macro_use]
extern crate holodeck_cli;

mod cmd;
mod parent;
mod supervise;
mod web;
mod window;

/// Interactive walkthroughs of globally illuminated scenes from a persistent ray cache.
#[derive(Parser)]
#[command(name = "holodeck", version, about = ABOUT, long_about = None, after_help = EXAMPLES)]
struct Cli {
    /// More log output (-v info, -vv debug, -vvv trace).
    #[arg(short, long, action = clap::ArgAction::Count, global = true)]
    verbose: u8,
    /// Only errors.
    #[arg(short, long, global = true)]
    quiet: bool,
    /// Stop when the parent process ends (set by `holodeck run` for its children).
    #[arg(long, global = true, hide = true)]
    exit_with_parent: bool,
    #[command(subcommand)]
    command: Command,
}

/// What `holodeck --help` says the program is.
const ABOUT: &str = "Holodeck: interactive walkthroughs of globally illuminated scenes from a persistent, \
crash-safe ray cache. Fill a holodeck file with path-traced rays (in one process, or from sampler \
workers on any number of hosts), walk through it in a window as it fills, draw pictures from it \
without a server, and create, check, optimize, copy and benchmark its files.";

const EXAMPLES: &str = "\
Examples:
  holodeck demo
  holodeck run builtin:room room.hdk -n 2 --driver quadtree          # a walkthrough window, until q
  holodeck create room.hdk --section 'interior origin=0,0,0 x=6,0,0 y=0,4,0 z=0,0,2.5' --grid 0.25
  holodeck create room.hdk --control room.toml
  holodeck info room.hdk
  holodeck check room.hdk --repair salvaged.hdk
  holodeck optimize room.hdk
  holodeck copy night.hdk room.hdk
  holodeck import radiance office.hdk -o office-holo.hdk
  holodeck export radiance room.hdk -o room-rholo.hdk
  holodeck grid room.hdk -o grid.obj
  holodeck bench storage --rays 50M
  holodeck scene gen landscape --triangles 10M -o landscape.toml
  holodeck scene info landscape.toml
  holodeck render builtin:room --spp 64 -o room.png
  holodeck fill builtin:room room.hdk --rays 2M
  holodeck run builtin:room room.hdk -n 2 --time 30s
  holodeck serve room.hdk --listen 0.0.0.0:7777
  holodeck sample builtin:room --connect host:7777 --token-file room.hdk.writer.token
  holodeck admin --connect host:7777 --token-file room.hdk.token status";

#[derive(Subcommand)]
enum Command {
    /// The whole system on the built-in scene in one command: fill, walk, every driver, references, charts.
    Demo(cmd::demo::Args),
    /// Create an empty holodeck file from sections or a TOML control file.
    Create(cmd::create::Args),
    /// Show sections, grids, beams, rays, size and fragmentation (like rhinfo).
    Info(cmd::info::Args),
    /// Verify every checksum; optionally salvage what verifies into a new file.
    Check(cmd::check::Args),
    /// Rewrite a file with beams collated in beam order and no free space but the gap between metadata copies (like rhoptimize).
    Optimize(cmd::optimize::Args),
    /// Add the rays of one holodeck to another: merged, or resampled into other sections (like rhcopy).
    Copy(cmd::copy::Args),
    /// Read a holodeck of another program into a new holodeck file (Radiance's rholo).
    Import(cmd::import::Args),
    /// Write a holodeck file for another program (Radiance's rholo, rhinfo, rhpict).
    Export(cmd::export::Args),
    /// Write the section grids as an OBJ line mesh for any 3D viewer.
    Grid(cmd::grid::Args),
    /// Speed against accuracy, drawn: error by paths and time, a walkthrough, LOD, grid resolution, scene memory.
    Chart(holodeck_bench::chart::Args),
    /// Benchmarks, each beside a baseline measured in the same run; `all` runs them all and `compare` diffs two runs.
    Bench(holodeck_bench::bench::Args),
    /// Generate built-in scenes and inspect scene files.
    Scene(cmd::scene::Args),
    /// Render a view of a scene directly with the path tracer (the accuracy reference).
    Render(cmd::render::Args),
    /// Trace rays of a scene into a holodeck file (a batch fill in this process).
    Fill(cmd::fill::Args),
    /// Fill with a server and local sampler processes in one command (like rholo).
    Run(cmd::run::Args),
    /// Serve a holodeck file to samplers and displays over TCP or a Unix socket.
    Serve(cmd::serve::Args),
    /// Compare a picture with a reference: FLIP, SSIM, relative errors, the light kept.
    Compare(cmd::compare::Args),
    /// Draw pictures straight from a holodeck file (like rhpict).
    Pict(cmd::pict::Args),
    /// A display client on a server: a window to walk through, or with --headless frames of --views.
    View(cmd::view::Args),
    /// Trace packets for a holodeck server (a sampler worker; any host).
    Sample(cmd::sample::Args),
    /// Send a command to a running server: pause, kill, adopt an edited scene, status...
    Admin(cmd::admin::Args),
}

fn init_logging(verbose: u8, quiet: bool) {
    let level = match (quiet, verbose) {
        (true, _) => "error",
        (false, 0) => "warn",
        (false, 1) => "info",
        (false, 2) => "debug",
        _ => "trace",
    };
    let filter = tracing_subscriber::EnvFilter::try_from_env("HOLODECK_LOG")
        // winit warns about harmless things of virtual screens (no XSETTINGS,
        // a 0 mm display): only with -vv.
        .unwrap_or_else(|_| {
            let windows = if verbose >= 2 { "" } else { ",winit=error" };
            tracing_subscriber::EnvFilter::new(format!("{level}{windows}"))
        });
    // Colour only on a terminal, and never where NO_COLOR asks for none:
    // logs sent to a file carry no escape codes.
    use std::io::IsTerminal;
    let colour = std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty());
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(colour)
        .init();
}

/// Standard output that closes or fills up ends the program as Unix tools
/// end: a closed pipe quietly with status 141 (`info F | head -0`), a full
/// device with a message and status 1 (`info F > /dev/full`), not with a
/// panic's backtrace. Every other panic reports as before.
fn quiet_on_closed_stdout() {
    let default = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let message = info
            .payload()
            .downcast_ref::<String>()
            .map(String::as_str)
            .or_else(|| info.payload().downcast_ref::<&str>().copied())
            .unwrap_or("");
        if message.starts_with("failed printing to stdout") {
            if message.contains("Broken pipe") {
                std::process::exit(141);
            }
            eprintln!(
                "holodeck: error: writing to standard output: {}",
                message.trim_start_matches("failed printing to stdout: ")
            );
            std::process::exit(1);
        }
        default(info);
    }));
}

/// A Radiance view option given on its own (`holodeck render S -vp 1 2 1.5`,
/// as rpict takes it), which clap would answer with advice about `--`; the
/// option found, if any.
fn loose_view_option(args: &[String]) -> Option<&str> {
    let numeric = |t: Option<&String>| t.is_some_and(|t| t.parse::<f64>().is_ok());
    args.iter().enumerate().skip(1).find_map(|(i, a)| {
        let after_view = args.get(i - 1).is_some_and(|p| p == "--view" || p == "--views");
        if after_view {
            return None;
        }
        let typed = matches!(a.as_str(), "-vtv" | "-vta" | "-vth" | "-vtl");
        let with_number = matches!(
            a.as_str(),
            "-vp" | "-vd" | "-vu" | "-vh" | "-vv" | "-vs" | "-vl" | "-vo" | "-va"
        ) && numeric(args.get(i + 1));
        (typed || with_number || a == "-vf").then_some(a.as_str())
    })
}

/// Gives this process (and those it starts) a private runtime directory
/// where the environment names none (a headless machine, a container): the
/// graphics stack's window-system probes otherwise print "XDG_RUNTIME_DIR
/// is invalid or not set" twice on every GPU use. The directory is
/// `$TMPDIR/holodeck-runtime-UID`, owned by this user and private (0700); a
/// path that is anything else is left alone.
fn runtime_dir_where_missing() {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    if std::env::var_os("XDG_RUNTIME_DIR").is_some_and(|v| !v.is_empty()) {
        return;
    }
    // SAFETY: getuid cannot fail and has no memory effects.
    let uid = unsafe { libc::getuid() };
    let dir = std::env::temp_dir().join(format!("holodeck-runtime-{uid}"));
    let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
    let ours = std::fs::symlink_metadata(&dir)
        .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o077 == 0);
    if ours {
        // Still one thread: nothing else reads the environment meanwhile.
        std::env::set_var("XDG_RUNTIME_DIR", &dir);
    }
}

fn main() -> ExitCode {
    runtime_dir_where_missing();
    quiet_on_closed_stdout();
    let args: Vec<String> = std::env::args().collect();
    if let Some(option) = loose_view_option(&args) {
        eprintln!(
            "holodeck: error: {option} is a view option: give the view in --view, as one argument \
             (for example --view '-vtv -vp 1 2 1.5 -vd 1 0 0 -vh 60 -vv 45')"
        );
        return ExitCode::from(2);
    }
    let cli = Cli::parse();
    holodeck_cli::verbosity::set(cli.verbose, cli.quiet);
    init_logging(cli.verbose, cli.quiet);
    if cli.exit_with_parent {
        parent::exit_with_parent();
    }
    let result = match cli.command {
        Command::Demo(a) => cmd::demo::run(a),
        Command::Create(a) => cmd::create::run(a),
        Command::Info(a) => cmd::info::run(a),
        Command::Check(a) => cmd::check::run(a),
        Command::Optimize(a) => cmd::optimize::run(a),
        Command::Copy(a) => cmd::copy::run(a),
        Command::Import(a) => cmd::import::run(a),
        Command::Export(a) => cmd::export::run(a),
        Command::Grid(a) => cmd::grid::run(a),
        Command::Bench(a) => holodeck_bench::bench::run(a),
        Command::Chart(a) => holodeck_bench::chart::run(a),
        Command::Scene(a) => cmd::scene::run(a),
        Command::Render(a) => cmd::render::run(a),
        Command::Fill(a) => cmd::fill::run(a),
        Command::Run(a) => cmd::run::run(a),
        Command::Serve(a) => cmd::serve::run(a),
        Command::Pict(a) => cmd::pict::run(a),
        Command::Compare(a) => cmd::compare::run(a),
        Command::View(a) => cmd::view::run(a),
        Command::Sample(a) => cmd::sample::run(a),
        Command::Admin(a) => cmd::admin::run(a),
    };
    match result {
        Ok(code) => code,
        Err(e) => {
            eprintln!("holodeck: error: {}", describe(&e));
            ExitCode::FAILURE
        }
    }
}

/// An error and its causes on one line, each said once: many errors already
/// name their cause in their own message, so a cause whose text is already
/// there is not repeated.
fn describe(e: &anyhow::Error) -> String {
    let mut out = String::new();
    for cause in e.chain() {
        let text = cause.to_string();
        if text.is_empty() || out.contains(&text) {
            continue;
        }
        if !out.is_empty() {
            out.push_str(": ");
        }
        out.push_str(&text);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::{describe, loose_view_option};

    #[test]
    fn radiance_view_options_outside_view_are_caught_and_verbosity_is_not() {
        let args = |s: &str| s.split_whitespace().map(String::from).collect::<Vec<_>>();
        assert_eq!(
            loose_view_option(&args("holodeck render builtin:room -vp 1 2 1.5")),
            Some("-vp")
        );
        assert_eq!(
            loose_view_option(&args("holodeck pict f.hdk -vtv -o a.png")),
            Some("-vtv")
        );
        assert_eq!(
            loose_view_option(&args("holodeck -vv render builtin:room -o a.png")),
            None
        );
        assert_eq!(loose_view_option(&args("holodeck render s --view -vp -o a.png")), None);
        let mut quoted = args("holodeck render s --view");
        quoted.push("-vtv -vp 1 2 3".into());
        assert_eq!(loose_view_option(&quoted), None);
    }

    #[test]
    fn causes_already_in_a_message_are_said_once() {
        let io = std::io::Error::new(std::io::ErrorKind::NotFound, "No such file or directory");
        let storage = holodeck_file::StorageError::Io {
            path: "room.hdk".into(),
            op: "opening",
            source: io,
        };
        let e = anyhow::Error::new(storage).context("cannot check room.hdk");
        assert_eq!(
            describe(&e),
            "cannot check room.hdk: room.hdk: opening: No such file or directory"
        );
        let plain = anyhow::anyhow!("inner").context("outer");
        assert_eq!(describe(&plain), "outer: inner");
    }
}
