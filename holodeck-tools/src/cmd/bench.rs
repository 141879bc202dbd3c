//! `holodeck bench`: measurements of the storage engine, each reported with a
//! baseline taken in the same run (raw sequential reads of the same file), so
//! results compare across shared machines whose absolute speed drifts.

use std::fs::File;
use std::io::Read;
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_protocol::{BeamKey, DepthCode, RayRecord, Rgbe, Section, SectionKind};
use holodeck_server::settings::{parse_size, Settings};
use holodeck_server::storage;
use holodeck_server::{HoloFile, OpenOptions};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

use crate::human::{bytes, count};

/// Arguments of `holodeck bench`.
#[derive(clap::Args)]
#[command(after_help = "\
Example:
  holodeck bench storage --rays 50M --dir target/bench
  holodeck bench storage --rays 2M --reference-rays 1M     (a quick run)

Files are written under --dir and removed afterwards unless --keep is given.")]
pub struct Args {
    /// What to measure.
    #[arg(value_enum)]
    what: Target,
    /// Rays in the large file (suffixes K, M, G as powers of 1000).
    #[arg(long, default_value = "50M", value_parser = parse_count)]
    rays: u64,
    /// Rays in the Radiance-like reference file (1 section, 154,728 beams).
    #[arg(long, default_value = "6.2M", value_parser = parse_count)]
    reference_rays: u64,
    /// Beams in each request list.
    #[arg(long, default_value = "10000")]
    request: usize,
    /// Beam cache budget.
    #[arg(long, default_value = "64M")]
    cache: String,
    /// Where to write the files.
    #[arg(long, default_value = "target/holodeck-bench")]
    dir: PathBuf,
    /// Keep the files.
    #[arg(long)]
    keep: bool,
}

/// Benchmarks available.
#[derive(Clone, Copy, clap::ValueEnum)]
enum Target {
    /// The holodeck file engine.
    Storage,
}

fn parse_count(s: &str) -> std::result::Result<u64, String> {
    let s = s.trim();
    let (num, mult) = match s.chars().last() {
        Some('K' | 'k') => (&s[..s.len() - 1], 1e3),
        Some('M' | 'm') => (&s[..s.len() - 1], 1e6),
        Some('G' | 'g') => (&s[..s.len() - 1], 1e9),
        _ => (s, 1.0),
    };
    let v: f64 = num.parse().map_err(|_| format!("{s:?} is not a count like 50M"))?;
    Ok((v * mult).round() as u64)
}

/// The section of Radiance's reference fill: grid 13 x 10 x 4 gives 154,728 beams.
fn reference_settings(cache: u64) -> Result<Settings> {
    let room = Section::new(
        [0.0; 3],
        [[6.5, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 2.0]],
        [13, 10, 4],
        SectionKind::Interior,
    )?;
    Ok(Settings {
        sections: vec![room],
        cache_bytes: cache,
        ..Settings::default()
    })
}

fn random_ray(rng: &mut StdRng) -> RayRecord {
    let b: [u8; 8] = rng.gen();
    RayRecord::new(
        [b[0], b[1]],
        [b[2], b[3]],
        Rgbe([b[4], b[5], b[6] | 128, 120 + (b[7] & 15)]),
        DepthCode(rng.gen_range(0..60000)),
    )
}

/// Appends `rays` in packets of 1-21 rays (as the paper's server did) to random beams.
fn fill(path: &Path, settings: &Settings, rays: u64, seed: u64) -> Result<f64> {
    HoloFile::create(path, settings)?;
    let mut f = HoloFile::open(path, &OpenOptions::default())?;
    let beams = f.sections()[0].beam_count();
    let mut rng = StdRng::seed_from_u64(seed);
    let packet: Vec<RayRecord> = (0..4096).map(|_| random_ray(&mut rng)).collect();
    let bar = indicatif::ProgressBar::new(rays);
    let start = Instant::now();
    let mut done = 0u64;
    while done < rays {
        let n = rng.gen_range(1..=21u64).min(rays - done) as usize;
        let at = rng.gen_range(0..packet.len() - n);
        f.append(BeamKey::new(0, rng.gen_range(0..beams)), &packet[at..at + n])?;
        done += n as u64;
        if done % (1 << 20) < 21 {
            bar.set_position(done);
        }
    }
    f.close()?;
    bar.finish_and_clear();
    Ok(start.elapsed().as_secs_f64())
}

fn drop_os_cache(path: &Path) -> Result<()> {
    let f = File::open(path)?;
    f.sync_all()?;
    // SAFETY: advisory call on a valid descriptor.
    unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
    Ok(())
}

/// Seconds to read the whole file sequentially in 8 MiB reads, from a cold OS cache.
fn raw_read(path: &Path) -> Result<(f64, u64)> {
    drop_os_cache(path)?;
    let mut f = File::open(path)?;
    let mut buf = vec![0u8; 8 << 20];
    let start = Instant::now();
    let mut total = 0u64;
    loop {
        let n = f.read(&mut buf)?;
        if n == 0 {
            break;
        }
        total += n as u64;
    }
    Ok((start.elapsed().as_secs_f64(), total))
}

/// Peak resident memory since the last reset, and the current, in bytes (Linux).
fn rss() -> (u64, u64) {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    let field = |name: &str| {
        status
            .lines()
            .find(|l| l.starts_with(name))
            .and_then(|l| l.split_whitespace().nth(1))
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
            * 1024
    };
    (field("VmHWM:"), field("VmRSS:"))
}

fn reset_peak_rss() {
    let _ = std::fs::write("/proc/self/clear_refs", "5");
}

/// The beams seen from a few eye points near the middle of the section, looking
/// along +x with a 90 degree field: the kind of list a display asks for.
fn view_request(section: &Section, want: usize) -> Vec<BeamKey> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for step in 0..64 {
        let eye = section.unit_to_world(glam::DVec3::new(0.3 + 0.01 * f64::from(step), 0.5, 0.45));
        for i in 0..200 {
            for j in 0..150 {
                let (x, y) = (f64::from(i) / 199.0 * 2.0 - 1.0, f64::from(j) / 149.0 * 1.5 - 0.75);
                let dir = glam::DVec3::new(1.0, x, y);
                if let Some(hit) = section.locate(eye, dir) {
                    if seen.insert(hit.beam) {
                        out.push(BeamKey::new(0, hit.beam));
                        if out.len() == want {
                            return out;
                        }
                    }
                }
            }
        }
    }
    out
}

fn rate(n: u64, secs: f64) -> String {
    format!("{:.1} M/s", n as f64 / secs / 1e6)
}

/// Runs the command.
pub fn run(a: Args) -> Result<ExitCode> {
    let Target::Storage = a.what;
    let cache = parse_size(&a.cache).map_err(anyhow::Error::msg)?;
    std::fs::create_dir_all(&a.dir).with_context(|| format!("creating {}", a.dir.display()))?;
    let big = a.dir.join("bench-large.hdk");
    let reference = a.dir.join("bench-reference.hdk");
    for p in [&big, &reference] {
        let _ = std::fs::remove_file(p);
    }
    let settings = reference_settings(cache)?;
    println!(
        "holodeck bench storage: {} rays, 154,728 beams, CACHE {}, requests of {} beams",
        count(a.rays),
        bytes(cache),
        count(a.request as u64)
    );
    println!();
    println!("| measurement | result | baseline (same run) | ratio |");
    println!("|---|---|---|---|");

    let fill_secs = fill(&big, &settings, a.rays, 1)?;
    let (raw_secs, raw_bytes) = raw_read(&big)?;
    let raw_rays_per_s = raw_bytes as f64 / 10.0 / raw_secs;
    println!(
        "| append, random beams, packets of 1-21 (incl. final flush) | {} | raw sequential read {} ({}/s) | {:.2} |",
        rate(a.rays, fill_secs),
        rate(raw_bytes / 10, raw_secs),
        bytes((raw_bytes as f64 / raw_secs) as u64),
        a.rays as f64 / fill_secs / raw_rays_per_s
    );

    // Cold recall: one request list of random beams, then every beam in request lists.
    let beams = settings.sections[0].beam_count();
    let mut all: Vec<BeamKey> = (0..beams).map(|b| BeamKey::new(0, b)).collect();
    let mut rng = StdRng::seed_from_u64(2);
    all.shuffle(&mut rng);
    drop_os_cache(&big)?;
    let mut f = HoloFile::open(
        &big,
        &OpenOptions {
            cache_bytes: Some(cache),
            ..OpenOptions::read_only()
        },
    )?;
    let request = &all[..a.request.min(all.len())];
    let start = Instant::now();
    let r = f.read_beams(request, |_, _| {})?;
    let cold_secs = start.elapsed().as_secs_f64();
    println!(
        "| cold recall, one request of {} random beams ({} rays) | {} | raw sequential read {} | {:.2} |",
        count(request.len() as u64),
        count(r.rays),
        rate(r.rays, cold_secs),
        rate(raw_bytes / 10, raw_secs),
        r.rays as f64 / cold_secs / raw_rays_per_s
    );
    drop(f);
    drop_os_cache(&big)?;
    let mut f = HoloFile::open(
        &big,
        &OpenOptions {
            cache_bytes: Some(cache),
            ..OpenOptions::read_only()
        },
    )?;
    let view = view_request(&settings.sections[0], a.request);
    let start = Instant::now();
    let rv = f.read_beams(&view, |_, _| {})?;
    let view_secs = start.elapsed().as_secs_f64();
    println!(
        "| cold recall, one request of the {} beams seen from nearby views ({} rays) | {} | raw sequential read {} | {:.2} |",
        count(view.len() as u64),
        count(rv.rays),
        rate(rv.rays, view_secs),
        rate(raw_bytes / 10, raw_secs),
        rv.rays as f64 / view_secs / raw_rays_per_s
    );
    drop(f);
    let mut f = HoloFile::open(
        &big,
        &OpenOptions {
            cache_bytes: Some(cache),
            ..OpenOptions::read_only()
        },
    )?;
    f.read_beams(request, |_, _| {})?;
    let mut hit_rays = 0;
    let start = Instant::now();
    for _ in 0..5 {
        hit_rays += f
            .read_beams(request, |_, rays| {
                std::hint::black_box(rays);
            })?
            .rays;
    }
    let hit_secs = start.elapsed().as_secs_f64();
    println!(
        "| cache-hit recall, same request again x5 | {} | cold recall {} | {:.1} |",
        rate(hit_rays, hit_secs),
        rate(r.rays, cold_secs),
        (hit_rays as f64 / hit_secs) / (r.rays as f64 / cold_secs)
    );
    drop(f);

    drop_os_cache(&big)?;
    let mut f = HoloFile::open(
        &big,
        &OpenOptions {
            cache_bytes: Some(cache),
            ..OpenOptions::read_only()
        },
    )?;
    reset_peak_rss();
    let (_, rss_before) = rss();
    let start = Instant::now();
    let mut streamed = 0;
    for chunk in all.chunks(a.request) {
        streamed += f.read_beams(chunk, |_, _| {})?.rays;
    }
    let stream_secs = start.elapsed().as_secs_f64();
    let (peak, _) = rss();
    let file_bytes = f.summary().file_bytes;
    println!(
        "| cold recall of every beam, requests of {} ({} rays) | {} | raw sequential read {} | {:.2} |",
        count(a.request as u64),
        count(streamed),
        rate(streamed, stream_secs),
        rate(raw_bytes / 10, raw_secs),
        streamed as f64 / stream_secs / raw_rays_per_s
    );
    println!(
        "| peak RSS streaming a {} file ({:.1}x CACHE) | {} above start | CACHE {} | {:.2} |",
        bytes(file_bytes),
        file_bytes as f64 / cache as f64,
        bytes(peak.saturating_sub(rss_before)),
        bytes(cache),
        peak.saturating_sub(rss_before) as f64 / cache as f64
    );
    drop(f);

    let before = HoloFile::open(&big, &OpenOptions::read_only())?.summary();
    let start = Instant::now();
    storage::optimize(&big, |_, _| {})?;
    let opt_secs = start.elapsed().as_secs_f64();
    let after = HoloFile::open(&big, &OpenOptions::read_only())?.summary();
    println!(
        "| optimize {} file | {:.2} s ({}) | raw sequential read {:.2} s | {:.2} |",
        bytes(before.file_bytes),
        opt_secs,
        rate(after.rays(), opt_secs),
        raw_secs,
        opt_secs / raw_secs
    );
    println!(
        "| bytes per ray, large file, before / after optimize | {:.3} / {:.3} | 10 (records alone) | overhead after {:.3}% |",
        before.bytes_per_ray(),
        after.bytes_per_ray(),
        100.0 * (after.bytes_per_ray() - 10.0) / 10.0
    );

    let ref_fill = fill(&reference, &settings, a.reference_rays, 3)?;
    let before = HoloFile::open(&reference, &OpenOptions::read_only())?.summary();
    let start = Instant::now();
    storage::optimize(&reference, |_, _| {})?;
    let opt_secs = start.elapsed().as_secs_f64();
    let after = HoloFile::open(&reference, &OpenOptions::read_only())?.summary();
    let (raw_ref, _) = raw_read(&reference)?;
    println!(
        "| reference fill: {} rays in 154,728 beams, append | {} | | |",
        count(a.reference_rays),
        rate(a.reference_rays, ref_fill)
    );
    println!(
        "| reference fill: optimize {} | {:.3} s | raw sequential read {:.3} s; rhoptimize 0.57 s (DESIGN.md) | {:.2} |",
        bytes(before.file_bytes),
        opt_secs,
        raw_ref,
        opt_secs / raw_ref
    );
    println!(
        "| reference fill: whole-file bytes per ray, before / after optimize | {:.3} / {:.3} | Radiance 10.40 | {:.3} |",
        before.bytes_per_ray(),
        after.bytes_per_ray(),
        after.bytes_per_ray() / 10.40
    );
    if !a.keep {
        for p in [&big, &reference] {
            let _ = std::fs::remove_file(p);
        }
    }
    Ok(ExitCode::SUCCESS)
}
