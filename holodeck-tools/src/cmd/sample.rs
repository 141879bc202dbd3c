//! `holodeck sample`: a sampler worker for a holodeck server on any host.

use std::process::ExitCode;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, SystemTime};

use anyhow::{bail, Context, Result};
use holodeck_file::settings::parse_duration;
use holodeck_sampler::worker::{run_worker_retrying, WorkerError};
use holodeck_sampler::{TraceOptions, Tracer};

use holodeck::SceneInput;
use holodeck_cli::args::{MAX_TRIANGLES, MAX_WORKERS};
use holodeck_cli::human::{count, count_in};

/// Arguments of `holodeck sample`.
#[derive(clap::Args)]
#[command(after_help = "\
Loads the scene, proves to the server that it is the same scene (content hash), and traces
the packets the server hands out until the server stops. If the server goes away (a restart,
say), each worker retries with growing delays for --retry-for before ending. While an admin
has stopped the samplers (`holodeck admin ... kill`), workers wait to be let in again, and
reload the scene file first if it changed (for `holodeck admin ... adopt` after an edit). A sampler
that never reached the server in that time fails, naming the address. Workers are stateless: start and
stop them at any time, on any host that can reach the server. It ends by saying how many rays it
traced and handed to the server; SIGINT or SIGTERM ends it at once, saying the same (exit status
130 or 143; rays handed over in its last 20 ms may not have left the process). Work it held is
given to other samplers.

Examples:
  holodeck sample builtin:room --connect 127.0.0.1:7777 --token-file room.hdk.token
  holodeck sample scenes/room.toml --connect server:7777 --token 3f9c... -j 16
  holodeck sample landscape.hds --scene-memory 1G --connect server:7777 --token-file big.hdk.writer.token")]
pub struct Args {
    /// Scene file, or builtin:NAME (must be the scene the holodeck was made for).
    scene: String,
    /// The server's address.
    #[arg(long)]
    connect: String,
    #[command(flatten)]
    token: holodeck_cli::args::TokenArgs,
    /// Worker connections (one tracing thread each); default: one per core.
    #[arg(short = 'j', long, value_parser = clap::value_parser!(u32).range(1..=MAX_WORKERS))]
    jobs: Option<u32>,
    /// Largest number of bounces.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    /// Path samples averaged per ray.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    #[command(flatten)]
    reorder: holodeck_cli::args::ReorderArgs,
    /// Seed (give each worker host its own to trace independent rays).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// For a .hds scene file: decompressed blocks kept in memory (K, M, G; default: all of them).
    #[arg(long, value_parser = holodeck_file::settings::parse_size)]
    scene_memory: Option<u64>,
    /// After losing the server, keep trying to reconnect this long (e.g. 30s, 5m; 0s: give up at once).
    #[arg(long, default_value = "60s")]
    retry_for: String,
}

/// A loaded scene, and when its file was last modified.
struct Loaded {
    tracer: Arc<Tracer>,
    hash: String,
    modified: Option<SystemTime>,
}

/// When the scene file was last modified (`None` for builtin scenes, which never change).
fn modified(spec: &str) -> Option<SystemTime> {
    if spec.starts_with("builtin:") {
        return None;
    }
    std::fs::metadata(spec).and_then(|m| m.modified()).ok()
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let token = a.token.token()?;
    let addr = a.token.address(&a.connect)?;
    let options = TraceOptions {
        max_bounces: a.bounces,
        samples: a.samples,
        reorder: a.reorder.reorder,
        ..TraceOptions::default()
    };
    let load = || -> Result<Loaded> {
        let modified = modified(&a.scene);
        let scene = SceneInput::open(&a.scene, a.triangles, a.scene_memory)?;
        let hash = scene.hash();
        Ok(Loaded {
            tracer: Arc::new(scene.tracer(options)),
            hash,
            modified,
        })
    };
    let loaded = Mutex::new(load()?);
    // Before each connection: the scene file as it is now (an admin may have
    // stopped the samplers to let the scene be edited).
    let scene = || {
        let mut l = loaded.lock().unwrap_or_else(|p| p.into_inner());
        if modified(&a.scene) != l.modified {
            match load() {
                Ok(new) => {
                    tracing::warn!("{}: the scene changed; now {}", a.scene, new.hash);
                    *l = new;
                }
                Err(e) => tracing::warn!("{}: keeping the scene loaded before: {e:#}", a.scene),
            }
        }
        (Arc::clone(&l.tracer), l.hash.clone())
    };
    let retry_for = parse_duration(&a.retry_for, 1.0).context("--retry-for")?;
    let jobs = a.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    // Rays traced and handed to the server, by every worker.
    let traced = AtomicU64::new(0);
    crate::supervise::stop_on_signals();
    let results: Vec<Option<Result<(), WorkerError>>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..jobs)
            .map(|j| {
                let (scene, token, addr, traced) = (&scene, &token, &addr, &traced);
                s.spawn(move || {
                    run_worker_retrying(
                        addr,
                        scene,
                        token,
                        a.seed.wrapping_mul(1000).wrapping_add(j as u64),
                        retry_for,
                        traced,
                    )
                })
            })
            .collect();
        // Stopped by a signal: say what was done, and end every worker.
        while !handles.iter().all(|h| h.is_finished()) {
            if let Some(signal) = crate::supervise::stop_signal() {
                let name = if signal == libc::SIGINT { "SIGINT" } else { "SIGTERM" };
                summary!(
                    "traced {} rays for {} (stopped by {name})",
                    count(traced.load(Ordering::Relaxed)),
                    a.connect
                );
                std::process::exit(128 + signal);
            }
            std::thread::sleep(Duration::from_millis(20));
        }
        handles.into_iter().map(|h| h.join().ok()).collect()
    });
    for r in results {
        match r {
            Some(Ok(())) => {}
            Some(Err(e)) => bail!(e),
            None => bail!("a worker thread failed; see the message above"),
        }
    }
    summary!("traced {} rays for {}", count(traced.into_inner()), a.connect);
    Ok(ExitCode::SUCCESS)
}
