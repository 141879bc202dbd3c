//! `holodeck sample`: a sampler worker for a holodeck server on any host.

use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_sampler::scene::hash::content_hash;
use holodeck_sampler::worker::{run_worker, WorkerError};
use holodeck_sampler::{TraceOptions, Tracer};
use holodeck_server::settings::parse_duration;

use super::args::{MAX_TRIANGLES, MAX_WORKERS};
use crate::human::{count, count_in};

/// Arguments of `holodeck sample`.
#[derive(clap::Args)]
#[command(after_help = "\
Loads the scene, proves to the server that it is the same scene (content hash), and traces
the packets the server hands out until the server stops. If the server goes away (a restart,
say), each worker retries with growing delays for --retry-for before ending. Workers are stateless: start and
stop them at any time, on any host that can reach the server.

Examples:
  holodeck sample builtin:room --connect 127.0.0.1:7777 --token-file room.hdk.token
  holodeck sample scenes/room.toml --connect server:7777 --token 3f9c... -j 16")]
pub struct Args {
    /// Scene file, or builtin:NAME (must be the scene the holodeck was made for).
    scene: String,
    /// The server's address.
    #[arg(long)]
    connect: String,
    #[command(flatten)]
    token: super::args::TokenArgs,
    /// Worker connections (one tracing thread each); default: one per core.
    #[arg(short = 'j', long, value_parser = clap::value_parser!(u32).range(1..=MAX_WORKERS))]
    jobs: Option<u32>,
    /// Largest number of bounces.
    #[arg(long, default_value_t = 8)]
    bounces: u32,
    /// Path samples averaged per ray.
    #[arg(long, default_value_t = 1, value_parser = clap::value_parser!(u32).range(1..))]
    samples: u32,
    /// Seed (give each worker host its own to trace independent rays).
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Triangles for builtin:landscape (K, M suffixes).
    #[arg(long, value_parser = count_in(1, MAX_TRIANGLES))]
    triangles: Option<u64>,
    /// After losing the server, keep trying to reconnect this long (e.g. 30s, 5m; 0s: give up at once).
    #[arg(long, default_value = "60s")]
    retry_for: String,
}

/// Runs one worker connection, reconnecting with exponential backoff while
/// the server is away (restarting, say) for up to `retry_for`; a refusal ends it.
fn work(
    addr: &str,
    tracer: &Tracer,
    hash: &str,
    token: &str,
    seed: u64,
    retry_for: Duration,
) -> Result<u64, WorkerError> {
    let (mut total, mut round) = (0u64, 0u64);
    let mut delay = Duration::from_millis(250);
    let mut lost_since: Option<Instant> = None;
    loop {
        match run_worker(
            addr,
            tracer,
            hash,
            token,
            seed.wrapping_add(round.wrapping_mul(0x9E37_79B9)),
        ) {
            Ok(n) => {
                total += n;
                if n > 0 {
                    delay = Duration::from_millis(250);
                    lost_since = None;
                }
            }
            Err(WorkerError::Io { .. }) => {}
            Err(e) => return Err(e),
        }
        round += 1;
        let since = *lost_since.get_or_insert_with(Instant::now);
        if since.elapsed() >= retry_for {
            return Ok(total);
        }
        tracing::info!("{addr}: server unavailable; retrying in {delay:?}");
        std::thread::sleep(delay.min(retry_for.saturating_sub(since.elapsed())));
        delay = (delay * 2).min(Duration::from_secs(10));
    }
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let token = a.token.token()?;
    let scene = super::render::load(&a.scene, a.triangles)?;
    let hash = content_hash(&scene);
    let options = TraceOptions {
        max_bounces: a.bounces,
        samples: a.samples,
        ..TraceOptions::default()
    };
    let tracer = Tracer::new(scene, options);
    let retry_for = parse_duration(&a.retry_for, 1.0).context("--retry-for")?;
    let jobs = a.jobs.map_or_else(
        || std::thread::available_parallelism().map_or(1, |n| n.get()),
        |j| j as usize,
    );
    let results: Vec<Result<u64, WorkerError>> = std::thread::scope(|s| {
        let handles: Vec<_> = (0..jobs)
            .map(|j| {
                let (tracer, hash, token, addr) = (&tracer, &hash, &token, &a.connect);
                s.spawn(move || {
                    work(
                        addr,
                        tracer,
                        hash,
                        token,
                        a.seed.wrapping_mul(1000).wrapping_add(j as u64),
                        retry_for,
                    )
                })
            })
            .collect();
        handles.into_iter().map(|h| h.join().unwrap_or(Ok(0))).collect()
    });
    let mut rays = 0;
    for r in results {
        match r {
            Ok(n) => rays += n,
            Err(e) => bail!(e),
        }
    }
    println!("traced {} rays for {}", count(rays), a.connect);
    Ok(ExitCode::SUCCESS)
}
