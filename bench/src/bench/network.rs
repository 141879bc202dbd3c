//! `holodeck bench network`: the server over loopback, against baselines
//! measured in the same run.
//! - Batch fill with 1 and 2 local sampler processes (`holodeck run`) against
//!   the tracer's own rays/s on the same kind of rays with as many threads.
//! - Recall to one display: cached rays/s, and the time from a request for
//!   about 100k cached samples to the last byte.
//! - 16 light synthetic samplers and 8 displays at once: throughput, request
//!   latency, and the server's memory.

use std::path::Path;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use anyhow::{bail, Context, Result};
use holodeck_file::settings::Settings;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::wire::client::{self, ClientStream};
use holodeck_protocol::wire::{Control, Frame, FrameLink, Message, Role, SamplingMode};
use holodeck_protocol::{BeamKey, DepthCode, RayRecord, Rgbe, Section};
use holodeck_sampler::{TraceOptions, Tracer};
use holodeck_server::schedule::BatchSchedule;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};

use super::row;
use holodeck_cli::human::count;
use holodeck_sampler::beam::trace_batch;

/// Arguments of `holodeck bench network`.
#[derive(clap::Args)]
#[command(after_help = "\
Runs a real server over loopback: the fill overhead against tracing in one process, recall to
displays, and many peers at once.

Example:
  holodeck bench network --seconds 8")]
pub struct Args {
    /// Seconds per fill measurement.
    #[arg(long, default_value_t = 8.0, value_parser = holodeck_cli::args::positive)]
    pub seconds: f64,
    #[command(flatten)]
    pub files: super::Files,
}

/// Runs `holodeck bench network`.
pub fn run_args(a: &Args) -> Result<std::process::ExitCode> {
    run(&a.files.dir, a.seconds, a.files.keep)?;
    Ok(std::process::ExitCode::SUCCESS)
}

/// This `holodeck` executable, to start servers and samplers from.
pub(super) fn me() -> Result<Command> {
    Ok(Command::new(
        std::env::current_exe().context("finding the holodeck executable")?,
    ))
}

/// The tracer alone on `threads` threads: batch-schedule beams of the room,
/// trace them, store nothing. Rays per second.
pub(super) fn tracer_rate(threads: usize, seconds: f64) -> Result<f64> {
    let scene = holodeck::load("builtin:room", None)?;
    let sections = scene.sections.clone();
    let tracer = Tracer::new(scene, TraceOptions::default());
    let mut schedule = BatchSchedule::new(&sections, |_| 0)?;
    let pool = rayon::ThreadPoolBuilder::new().num_threads(threads).build()?;
    let start = Instant::now();
    let (mut rays, mut round) = (0u64, 0u64);
    while start.elapsed().as_secs_f64() < seconds {
        let batch = schedule.next(1024, 4);
        let traced = pool.install(|| {
            trace_batch(
                &tracer,
                &sections,
                holodeck_sampler::beam::FileRules {
                    obstructions: true,
                    vdistance: false,
                },
                &batch,
                &|_| SamplingMode::Uniform,
                round,
            )
        });
        rays += traced.iter().map(|t| t.1.len() as u64).sum::<u64>();
        round += 1;
    }
    Ok(rays as f64 / start.elapsed().as_secs_f64())
}

/// `holodeck run` with `workers` samplers for `seconds`; rays/s it reports.
fn run_rate(dir: &Path, workers: usize, seconds: f64) -> Result<f64> {
    let file = dir.join(format!("net-fill-{workers}.hdk"));
    let _ = std::fs::remove_file(&file);
    let o = me()?
        .args(["run", "builtin:room"])
        .arg(&file)
        .args(["-n", &workers.to_string(), "--time", &format!("{seconds}s")])
        .output()?;
    if !o.status.success() {
        bail!("holodeck run failed: {}", String::from_utf8_lossy(&o.stderr));
    }
    let text = String::from_utf8_lossy(&o.stdout);
    let rate = text
        .split(" rays/s")
        .next()
        .and_then(|s| s.rsplit('(').next())
        .and_then(|s| s.trim().replace(',', "").parse::<f64>().ok())
        .with_context(|| format!("no rate in {text:?}"))?;
    let _ = std::fs::remove_file(&file);
    for level in ["", ".writer", ".viewer"] {
        let _ = std::fs::remove_file(dir.join(format!("net-fill-{workers}.hdk{level}.token")));
    }
    Ok(rate)
}

/// A raw peer over TCP (no decoding: the server's rate is what is measured).
pub(super) struct Peer {
    /// The framed connection.
    pub(super) link: FrameLink<ClientStream>,
}

impl Peer {
    /// Connects and says hello as `role` with the bench token.
    pub(super) fn connect(addr: &str, role: Role, scene: &str) -> Result<Peer> {
        let (link, _) = client::open(addr, client::hello(role, "bench", scene, false))?;
        Ok(Peer { link })
    }

    /// Requests beams; returns rays received up to Delivered and the time taken.
    fn request(&mut self, beams: &[(BeamKey, u32)]) -> Result<(u64, Duration)> {
        let start = Instant::now();
        self.link.write(&Frame::Message(Message::BeamRequest {
            beams: beams.to_vec(),
            eye: None,
            replace: true,
            // Every stored ray each time: this measures recall.
            resend: true,
        }))?;
        let mut rays = 0u64;
        loop {
            match self.link.read()? {
                Some(Frame::Beam { records, .. }) => rays += records.len() as u64,
                Some(Frame::Message(Message::Delivered { .. })) => return Ok((rays, start.elapsed())),
                Some(Frame::Message(Message::Progress(_))) => {}
                other => bail!("unexpected {other:?}"),
            }
        }
    }
}

/// A test file: one room-sized section with `rays` random records.
fn recall_file(path: &Path, rays: u64) -> Result<Section> {
    let section = super::storage::reference_section()?;
    let _ = std::fs::remove_file(path);
    HoloFile::create(
        path,
        &Settings {
            sections: vec![section.clone()],
            scene: Some("bench-synthetic".into()),
            cache_bytes: 512 << 20,
            ..Settings::default()
        },
    )?;
    let mut f = HoloFile::open(path, &OpenOptions::default())?;
    let mut rng = StdRng::seed_from_u64(3);
    let beams = section.beam_count();
    let mut left = rays;
    while left > 0 {
        let n = left.min(40) as usize;
        let recs: Vec<RayRecord> = (0..n).map(|_| random_record(&mut rng)).collect();
        f.append(BeamKey::new(0, rng.gen_range(0..beams)), &recs)?;
        left -= n as u64;
    }
    f.close()?;
    Ok(section)
}

fn random_record(rng: &mut StdRng) -> RayRecord {
    let b: [u8; 6] = rng.gen();
    RayRecord::new(
        [b[0], b[1]],
        [b[2], b[3]],
        Rgbe([b[4], b[5], 128, 128]),
        DepthCode(rng.gen_range(0..60000)),
    )
}

/// Starts `holodeck serve` on `path` (token `bench`); returns it and its address.
pub(super) fn serve(path: &Path, extra: &[&str]) -> Result<(Child, String)> {
    let mut child = me()?
        .arg("serve")
        .arg(path)
        .args(["--listen", "127.0.0.1:0", "--token", "bench"])
        .args(extra)
        .stdout(Stdio::piped())
        .stderr(Stdio::inherit())
        .spawn()?;
    let mut line = String::new();
    std::io::BufRead::read_line(
        &mut std::io::BufReader::new(child.stdout.as_mut().context("server output")?),
        &mut line,
    )?;
    let addr = line
        .trim()
        .strip_prefix("listening on ")
        .context("server address")?
        .to_string();
    Ok((child, addr))
}

/// Tells the server at `addr` to quit and waits for it.
pub(super) fn quit(addr: &str, mut child: Child) -> Result<()> {
    client::send_control(addr, "bench", Control::Quit)?;
    child.wait()?;
    Ok(())
}

/// Runs the benchmark.
pub fn run(dir: &Path, seconds: f64, keep: bool) -> Result<()> {
    std::fs::create_dir_all(dir)?;
    println!("| measurement | result | baseline (same run) | ratio |");
    println!("|---|---|---|---|");
    for workers in [1, 2] {
        eprintln!("fill with {workers} sampler(s) and the tracer alone, {seconds} s each...");
        let own = tracer_rate(workers, seconds)?;
        let net = run_rate(dir, workers, seconds)?;
        row(
            &format!("batch fill, `holodeck run -n {workers}` over loopback, rays/s"),
            format!("{:.0}k", net / 1e3),
            format!("tracer alone on {workers} thread(s) {:.0}k", own / 1e3),
            net / own,
        );
    }
    let path = dir.join("net-recall.hdk");
    eprintln!("writing a 20M-ray file for recall...");
    let section = recall_file(&path, 20_000_000)?;
    recall_rows(&path, &section)?;
    crowd_rows(&path, &section, seconds)?;
    if !keep {
        let _ = std::fs::remove_file(&path);
        for level in ["writer", "viewer"] {
            let _ = std::fs::remove_file(dir.join(format!("net-recall.hdk.{level}.token")));
        }
    }
    Ok(())
}

/// Recall to one display: cached against uncached, and the latency of a
/// request for about 100k cached samples.
fn recall_rows(path: &Path, section: &Section) -> Result<()> {
    let (server, addr) = serve(path, &["--no-fill"])?;
    let mut display = Peer::connect(&addr, Role::Display, "")?;
    let all: Vec<(BeamKey, u32)> = (0..section.beam_count()).map(|b| (BeamKey::new(0, b), 1)).collect();
    let some = &all[..all.len() / 2];
    let (cold, cold_t) = display.request(some)?;
    let (warm, warm_t) = display.request(some)?;
    let hot = warm as f64 / warm_t.as_secs_f64();
    row(
        &format!(
            "recall to one display over loopback, {} cached rays of {} beams",
            count(warm),
            count(some.len() as u64)
        ),
        format!("{:.1} M/s", hot / 1e6),
        format!(
            "first, uncached request {:.1} M/s",
            cold as f64 / cold_t.as_secs_f64() / 1e6
        ),
        hot / (cold as f64 / cold_t.as_secs_f64()),
    );
    // About 100k samples: beams at ~130 rays each.
    let per = (20_000_000 / u64::from(section.beam_count())).max(1);
    let small = &all[..(100_000 / per) as usize];
    display.request(small)?;
    let mut times = Vec::new();
    let mut got = 0;
    for _ in 0..20 {
        let (n, t) = display.request(small)?;
        got = n;
        times.push(t.as_secs_f64() * 1e3);
    }
    times.sort_by(f64::total_cmp);
    row(
        &format!(
            "request for {} cached samples to the last byte, median of 20 (max {:.1} ms)",
            count(got),
            times[19]
        ),
        format!("{:.1} ms", times[10]),
        "target 100 ms".into(),
        times[10] / 100.0,
    );
    drop(display);
    quit(&addr, server)?;
    Ok(())
}

/// 16 synthetic samplers and 8 displays at once on the file for `seconds`:
/// rays stored, the displays' latencies, the server's peak memory.
fn crowd_rows(path: &Path, section: &Section, seconds: f64) -> Result<()> {
    eprintln!("16 samplers and 8 displays for {seconds} s...");
    let (server, addr) = serve(path, &["--cache", "64M"])?;
    let pid = server.id();
    std::thread::sleep(Duration::from_millis(300));
    let (_, rss0) = super::rss_of(&pid.to_string());
    let stop = Arc::new(AtomicBool::new(false));
    let traced = Arc::new(AtomicU64::new(0));
    let mut handles = Vec::new();
    for i in 0..16u64 {
        let (addr, stop, traced) = (addr.clone(), Arc::clone(&stop), Arc::clone(&traced));
        handles.push(std::thread::spawn(move || -> Result<Vec<f64>> {
            let mut p = Peer::connect(&addr, Role::Sampler, "bench-synthetic")?;
            let mut rng = StdRng::seed_from_u64(i);
            while !stop.load(Ordering::Relaxed) {
                match p.link.read()? {
                    Some(Frame::Message(Message::Trace(t))) => {
                        let records = (0..t.rays).map(|_| random_record(&mut rng)).collect();
                        p.link.write(&Frame::Finished {
                            id: t.id,
                            key: t.key,
                            records,
                        })?;
                        traced.fetch_add(u64::from(t.rays), Ordering::Relaxed);
                    }
                    Some(_) => {}
                    None => break,
                }
            }
            Ok(Vec::new())
        }));
    }
    for i in 0..8u64 {
        let (addr, stop) = (addr.clone(), Arc::clone(&stop));
        let beams = section.beam_count();
        handles.push(std::thread::spawn(move || -> Result<Vec<f64>> {
            let mut p = Peer::connect(&addr, Role::Display, "")?;
            let mut rng = StdRng::seed_from_u64(100 + i);
            let mut latencies = Vec::new();
            while !stop.load(Ordering::Relaxed) {
                let start = rng.gen_range(0..beams - 2000);
                let want: Vec<(BeamKey, u32)> = (start..start + 2000).map(|b| (BeamKey::new(0, b), 400)).collect();
                // The server quitting ends the run, not the measurement.
                let Ok((_, t)) = p.request(&want) else { break };
                latencies.push(t.as_secs_f64() * 1e3);
            }
            Ok(latencies)
        }));
    }
    let start = Instant::now();
    std::thread::sleep(Duration::from_secs_f64(seconds));
    let (peak, _) = super::rss_of(&pid.to_string());
    let secs = start.elapsed().as_secs_f64();
    let rays = traced.load(Ordering::Relaxed);
    stop.store(true, Ordering::Relaxed);
    quit(&addr, server)?;
    stop.store(true, Ordering::Relaxed);
    let mut latencies = Vec::new();
    for h in handles {
        if let Ok(Ok(l)) = h.join() {
            latencies.extend(l);
        }
    }
    latencies.sort_by(f64::total_cmp);
    let pick = |q: f64| {
        latencies
            .get(((latencies.len() as f64 - 1.0) * q) as usize)
            .copied()
            .unwrap_or(f64::NAN)
    };
    row(
        "16 synthetic samplers + 8 displays: rays traced and stored",
        format!("{:.1} M/s", rays as f64 / secs / 1e6),
        "-".into(),
        f64::NAN,
    );
    row(
        &format!(
            "the 8 displays' requests of 2,000 beams ({} requests): median / p99 / max latency",
            latencies.len()
        ),
        format!("{:.1} / {:.1} / {:.1} ms", pick(0.5), pick(0.99), pick(1.0)),
        "-".into(),
        f64::NAN,
    );
    row(
        "server peak memory during that run",
        format!("{:.1} MiB", peak as f64 / (1 << 20) as f64),
        format!("after start {:.1} MiB; CACHE 64 MiB", rss0 as f64 / (1 << 20) as f64),
        peak as f64 / rss0.max(1) as f64,
    );
    Ok(())
}

/// The fast version for `bench all`: `holodeck run` (a server and two
/// sampler processes over loopback) filling the room for three seconds,
/// beside the tracer alone on as many threads for as long.
pub fn fast(ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    std::fs::create_dir_all(&ctx.dir).with_context(|| format!("creating {}", ctx.dir.display()))?;
    let (mut served, mut alone) = (Vec::new(), Vec::new());
    for _ in 0..ctx.repeats {
        alone.push(tracer_rate(2, 3.0)? / 1e3);
        served.push(run_rate(&ctx.dir, 2, 3.0)? / 1e3);
    }
    Ok(vec![Figure::new(
        "network",
        "fill by a server and 2 sampler processes over loopback",
        "K rays/s",
        true,
        served,
    )
    .against("the tracer alone on 2 threads", alone)])
}
