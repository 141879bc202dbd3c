//! `holodeck bench scale`: how many samplers one server can feed. N light
//! sampler processes (each answers every trace packet at once with random
//! rays, so that the server, not tracing, is what is measured) fill one
//! server for a while, N = 1, 4, 16, 64, speaking TLS and plain in turn;
//! beside them, the storage engine's own append rate in the same run.

use std::io::{BufRead, BufReader};
use std::path::{Path, PathBuf};
use std::process::{Child, ExitCode, Stdio};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_file::settings::Settings;
use holodeck_file::HoloFile;
use holodeck_protocol::wire::{client, Frame, Message, Role};
use holodeck_protocol::{DepthCode, RayRecord, Rgbe};
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::network::me;
use holodeck_cli::human::count;

/// Arguments of `holodeck bench scale`.
#[derive(clap::Args)]
#[command(after_help = "\
Starts one server and N light sampler processes (each answers every trace packet at once with
random rays) for --seconds, for each N of --samplers, with the samplers speaking TLS and then
plain; reports rays stored per second, the server's CPU per million rays, the periodic
commits' latency and the samplers' queues, beside the storage engine's own append rate
measured in the same run.

Example:
  holodeck bench scale --samplers 1 --samplers 4 --samplers 16 --samplers 64 --seconds 5")]
pub struct Args {
    /// Sampler processes (repeat for several points).
    #[arg(long, default_values_t = [1u32, 4, 16, 64])]
    pub samplers: Vec<u32>,
    /// Seconds per point.
    #[arg(long, default_value_t = 5.0, value_parser = holodeck_cli::args::positive)]
    pub seconds: f64,
    /// Rays per trace packet the server hands out (`serve --packet`).
    #[arg(long, default_value_t = 16)]
    pub packet: u32,
    #[command(flatten)]
    pub files: super::Files,
}

/// Arguments of one light sampler (the bench's child process).
#[derive(clap::Args)]
pub struct SamplerArgs {
    /// The server.
    #[arg(long)]
    pub connect: String,
    #[command(flatten)]
    pub token: holodeck_cli::args::TokenArgs,
    /// Seed of its random rays.
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// One light sampler: connects, answers every trace packet with random
/// rays at once until the server closes, and prints the rays it sent.
pub fn run_sampler(a: &SamplerArgs) -> Result<ExitCode> {
    let token = a.token.token()?;
    let addr = a.token.address(&a.connect)?;
    let (mut link, _) = client::open(&addr, client::hello(Role::Sampler, &token, SCENE, false))?;
    let mut rng = StdRng::seed_from_u64(a.seed);
    let pool = random_records(&mut rng, 1 << 16);
    let mut sent = 0u64;
    while let Ok(Some(frame)) = link.read() {
        let Frame::Message(Message::Trace(t)) = frame else {
            continue;
        };
        let n = t.rays as usize;
        let at = rng.gen_range(0..pool.len() - n.min(pool.len() - 1));
        let records = pool[at..(at + n).min(pool.len())].to_vec();
        sent += records.len() as u64;
        if link
            .write(&Frame::Finished {
                id: t.id,
                key: t.key,
                records,
            })
            .is_err()
        {
            break;
        }
    }
    println!("sent {sent}");
    Ok(ExitCode::SUCCESS)
}

/// `n` rays of random positions and colours at one depth: what the light
/// samplers send, and what the engine alone appends.
fn random_records(rng: &mut StdRng, n: usize) -> Vec<RayRecord> {
    (0..n)
        .map(|_| {
            let b: [u8; 6] = rng.gen();
            RayRecord::new(
                [b[0], b[1]],
                [b[2], b[3]],
                Rgbe([b[4], b[5], 128, 128]),
                DepthCode(1000),
            )
        })
        .collect()
}

/// The scene the light samplers claim (the bench's files record it).
const SCENE: &str = "bench-synthetic";

/// Runs `holodeck bench scale`.
pub fn run_args(a: &Args) -> Result<ExitCode> {
    let dir = &a.files.dir;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let steady = engine_on_schedule(dir, a)?;
    println!(
        "holodeck bench scale: light samplers against one server, {} s a point, packets of {} rays. \
         The storage engine alone, in the same run: the storage bench's fill (2M rays in random \
         beams, all in the cache, one commit at the end), measured again just before each point \
         so that the machine's drift over the run does not decide the ratio; {:.2} M rays/s on the \
         server's own workload (the batch schedule's packets for as long as a point, \
         evicting and committing every 2 s as the server does)",
        a.seconds,
        a.packet,
        steady / 1e6
    );
    println!();
    println!("| samplers | link | rays stored/s | engine alone just before | / engine, storage bench | / engine, same workload | server CPU s per M rays | commit latency, median (max) | queue per sampler when it left, mean |");
    println!("|---|---|---|---|---|---|---|---|---|");
    let mut best = 0f64;
    for &n in &a.samplers {
        for tls in [true, false] {
            let engine = engine_rate(dir)?;
            let p = point(dir, n, tls, a)?;
            if tls {
                best = best.max(p.rate);
            }
            println!(
                "| {n} | {} | {:.2} M | {:.2} M | {:.2} | {:.2} | {:.3} | {:.1} ms ({:.1} ms) | {} |",
                if tls { "TLS" } else { "plain" },
                p.rate / 1e6,
                engine / 1e6,
                p.rate / engine,
                p.rate / steady,
                p.cpu_per_m,
                p.commit_median,
                p.commit_max,
                p.queue
                    .map_or_else(|| "not logged".to_string(), |q| format!("{} rays", count(q as u64)))
            );
        }
    }
    // What one sampler core traces: the room, the samplers' default bounces.
    let core = super::network::tracer_rate(1, a.seconds)?;
    println!();
    println!(
        "One sampler core traces {} rays/s of the built-in room (8 bounces, the tracer alone, same run): \
         one server storing {} rays/s over TLS (the best point above) feeds about {:.0} such cores.",
        count(core.round() as u64),
        count(best.round() as u64),
        best / core.max(1.0)
    );
    if !a.files.keep {
        let _ = std::fs::remove_file(dir.join("scale.hdk"));
    }
    Ok(ExitCode::SUCCESS)
}

/// The storage engine's own append rate: the storage bench's fill (random
/// beams, packets of 1-21 rays), 2M rays.
fn engine_rate(dir: &Path) -> Result<f64> {
    let path = dir.join("scale-engine.hdk");
    let _ = std::fs::remove_file(&path);
    let settings = settings()?;
    let rays = 2_000_000;
    let (secs, _) = super::storage::fill(&path, &settings, rays, 9)?;
    let _ = std::fs::remove_file(&path);
    Ok(rays as f64 / secs)
}

/// The storage engine alone on the server's workload: the packets a batch
/// fill hands out (`--packet` rays, lowest ratio first) appended for one
/// second of warm-up and then `--seconds`, with a commit every 2 s as the
/// server makes them; the rate over the measured part, its commits included.
fn engine_on_schedule(dir: &Path, a: &Args) -> Result<f64> {
    let path = dir.join("scale-engine.hdk");
    let _ = std::fs::remove_file(&path);
    HoloFile::create(&path, &settings()?)?;
    let mut file = HoloFile::open(
        &path,
        &holodeck_file::OpenOptions {
            flush_interval: Some(Duration::from_secs(2)),
            ..holodeck_file::OpenOptions::default()
        },
    )?;
    let mut schedule = holodeck_server::schedule::BatchSchedule::new(file.sections(), |_| 0)?;
    let mut rng = StdRng::seed_from_u64(7);
    let pool = random_records(&mut rng, 4096);
    let start = Instant::now();
    let warm = Duration::from_secs(1);
    let end = warm + Duration::from_secs_f64(a.seconds);
    let mut measured: Option<(Instant, u64)> = None;
    let mut rays = 0u64;
    while start.elapsed() < end {
        if measured.is_none() && start.elapsed() >= warm {
            measured = Some((Instant::now(), rays));
        }
        for (key, n) in schedule.next(4096, a.packet) {
            let n = (n as usize).min(pool.len());
            file.append(key, &pool[..n])?;
            rays += n as u64;
        }
    }
    file.flush()?;
    let (from, before) = measured.context("the engine's run ended before it was measured")?;
    let rate = (rays - before) as f64 / from.elapsed().as_secs_f64();
    file.close()?;
    let _ = std::fs::remove_file(&path);
    Ok(rate)
}

/// The bench's file settings: Radiance's reference section, 64 MiB cache.
fn settings() -> Result<Settings> {
    Ok(Settings {
        sections: vec![super::storage::reference_section()?],
        scene: Some(SCENE.into()),
        cache_bytes: 64 << 20,
        ..Settings::default()
    })
}

/// What one point measured.
struct Point {
    rate: f64,
    cpu_per_m: f64,
    commit_median: f64,
    commit_max: f64,
    /// Mean over the samplers whose rate the server knew when they left.
    queue: Option<f64>,
}

/// `n` light samplers against a fresh server for the bench's time.
fn point(dir: &Path, n: u32, tls: bool, a: &Args) -> Result<Point> {
    let path = dir.join("scale.hdk");
    let _ = std::fs::remove_file(&path);
    HoloFile::create(&path, &settings()?)?;
    let lines = Arc::new(Mutex::new(Vec::<String>::new()));
    let (mut server, addr) = serve(&path, a.packet, &lines)?;
    let pid = server.id();
    let writer = token_path(&path, "writer");
    let mut samplers: Vec<Child> = Vec::new();
    for i in 0..n {
        let mut cmd = me()?;
        cmd.args(["bench", "scale-sampler", "--connect", &addr, "--seed", &i.to_string()]);
        if tls {
            cmd.arg("--token-file").arg(&writer);
        } else {
            let (token, _) = holodeck_cli::args::read_token_file(&writer)?;
            cmd.args(["--token", &token]);
        }
        samplers.push(cmd.stdout(Stdio::piped()).stderr(Stdio::inherit()).spawn()?);
    }
    // Warm up (connections, queues), then measure.
    std::thread::sleep(Duration::from_secs(1));
    let (rays0, cpu0) = (stored(&addr)?, cpu_seconds(pid)?);
    let start = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(a.seconds));
    let (rays1, cpu1) = (stored(&addr)?, cpu_seconds(pid)?);
    let secs = start.elapsed().as_secs_f64();
    // The samplers leave first, so that the server logs each one's queue as
    // it goes (a server told to quit first drops them unlogged).
    for s in &samplers {
        // SAFETY: kill only sends a signal to the sampler we started.
        unsafe { libc::kill(s.id() as libc::pid_t, libc::SIGTERM) };
    }
    // Every sampler is waited for, and the server told to quit, before
    // any failure is reported.
    let waited: Vec<std::io::Result<std::process::ExitStatus>> = samplers.iter_mut().map(Child::wait).collect();
    let logged = || {
        lines
            .lock()
            .map(|v| v.iter().filter(|l| l.contains("(queue ")).count())
            .unwrap_or(0)
    };
    let deadline = Instant::now() + Duration::from_secs(5);
    while logged() < n as usize && Instant::now() < deadline {
        std::thread::sleep(Duration::from_millis(20));
    }
    client::send_control(&addr, "bench", holodeck_protocol::wire::Control::Quit)?;
    let status = server.wait()?;
    if !status.success() {
        bail!("the server failed: {status}");
    }
    for w in waited {
        w.context("waiting for a sampler")?;
    }
    let lines = lines
        .lock()
        .map_err(|_| anyhow::anyhow!("the server's log reader failed"))?;
    let mut commits: Vec<f64> = lines
        .iter()
        .filter_map(|l| {
            l.split("periodic flush took ")
                .nth(1)?
                .strip_suffix(" ms")?
                .parse()
                .ok()
        })
        .collect();
    commits.sort_by(f64::total_cmp);
    let queues: Vec<f64> = lines
        .iter()
        .filter_map(|l| l.split("(queue ").nth(1)?.strip_suffix(" rays)")?.parse().ok())
        .collect();
    let rays = rays1.saturating_sub(rays0) as f64;
    Ok(Point {
        rate: rays / secs,
        cpu_per_m: (cpu1 - cpu0) / (rays / 1e6).max(1e-9),
        commit_median: commits.get(commits.len() / 2).copied().unwrap_or(f64::NAN),
        commit_max: commits.last().copied().unwrap_or(f64::NAN),
        queue: (!queues.is_empty()).then(|| queues.iter().sum::<f64>() / queues.len() as f64),
    })
}

/// Where `serve` writes the token of `level` for `file`.
fn token_path(file: &Path, level: &str) -> PathBuf {
    PathBuf::from(format!("{}.{level}.token", file.display()))
}

/// Starts `holodeck serve` on `path` with the bench's admin token, logging
/// its commits and samplers' queues into `lines`.
fn serve(path: &Path, packet: u32, lines: &Arc<Mutex<Vec<String>>>) -> Result<(Child, String)> {
    let mut child = me()?
        .arg("serve")
        .arg(path)
        .args(["--listen", "127.0.0.1:0", "--token", "bench", "--new-tokens"])
        .args(["--packet", &packet.to_string()])
        .env("HOLODECK_LOG", "warn,holodeck_server=debug")
        .env("NO_COLOR", "1")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()?;
    let mut out = BufReader::new(child.stdout.take().context("server output")?);
    let mut line = String::new();
    out.read_line(&mut line)?;
    let addr = line
        .trim()
        .strip_prefix("listening on ")
        .with_context(|| format!("no address in {line:?}"))?
        .to_string();
    let err = child.stderr.take().context("server log")?;
    let lines = Arc::clone(lines);
    std::thread::spawn(move || {
        for l in BufReader::new(err).lines().map_while(Result::ok) {
            if l.contains("periodic flush took") || l.contains("(queue ") {
                if let Ok(mut v) = lines.lock() {
                    v.push(l);
                }
            }
        }
    });
    Ok((child, addr))
}

/// The rays the server says are in its file.
fn stored(addr: &str) -> Result<u64> {
    let (mut link, _) = client::open(addr, client::hello(Role::Display, "bench", "", true))?;
    loop {
        match link.read()? {
            Some(Frame::Message(Message::Progress(p))) => return Ok(p.rays),
            Some(_) => {}
            None => bail!("the server closed before reporting"),
        }
    }
}

/// CPU seconds (user and system) process `pid` has used.
fn cpu_seconds(pid: u32) -> Result<f64> {
    let stat = std::fs::read_to_string(format!("/proc/{pid}/stat"))?;
    let after = stat.rsplit_once(')').map(|(_, r)| r).context("/proc stat")?;
    let fields: Vec<&str> = after.split_whitespace().collect();
    // utime and stime are fields 14 and 15 of the line: 12 and 13 after the name.
    let ticks: f64 = fields
        .get(11..13)
        .context("/proc stat fields")?
        .iter()
        .map(|f| f.parse::<f64>().unwrap_or(0.0))
        .sum();
    // SAFETY: sysconf has no memory effects.
    let hz = unsafe { libc::sysconf(libc::_SC_CLK_TCK) }.max(1) as f64;
    Ok(ticks / hz)
}
