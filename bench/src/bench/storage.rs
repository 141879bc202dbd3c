//! `holodeck bench storage`: measurements of the storage engine, each
//! reported with a baseline taken in the same run (raw sequential reads of
//! the same file), so results compare across shared machines whose absolute
//! speed drifts.

use std::fs::File;
use std::io::Read;
use std::os::unix::io::AsRawFd;
use std::path::{Path, PathBuf};
use std::process::ExitCode;
use std::time::Instant;

use anyhow::{Context, Result};
use holodeck_file::settings::{parse_size, Settings};
use holodeck_file::storage;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::{BeamKey, DepthCode, RayRecord, Rgbe, Section, SectionKind, MAX_BEAMS_PER_SECTION};
use rand::rngs::StdRng;
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};

use super::row;
use super::rss;
use holodeck_cli::human::{bytes, count, count_in};

/// Arguments of `holodeck bench storage`.
#[derive(clap::Args)]
#[command(after_help = "\
Fills a file with random rays in packets of 1-21 (as the paper's server did), recalls request
lists cold and OS-cached, optimizes it, and fills a Radiance-sized reference file; every figure
beside a baseline measured in the same run (raw sequential reads of the same file).

Examples:
  holodeck bench storage --rays 50M --dir target/bench
  holodeck bench storage --rays 2M --reference-rays 1M     (a quick run)")]
pub struct Args {
    /// Rays in the large file (suffixes K, M, G as powers of 1000).
    #[arg(long, default_value = "50M", value_parser = count_in(1, u64::MAX))]
    pub rays: u64,
    /// Rays in the Radiance-like reference file (1 section, 154,728 beams).
    #[arg(long, default_value = "6.2M", value_parser = count_in(1, u64::MAX))]
    pub reference_rays: u64,
    /// Beams in each request list.
    #[arg(long, default_value = "10000", value_parser = count_in(1, MAX_BEAMS_PER_SECTION))]
    pub request: u64,
    /// Beam cache budget.
    #[arg(long, default_value = "64M")]
    pub cache: String,
    #[command(flatten)]
    pub files: super::Files,
}

/// Arguments of the child processes of the memory measurements (hidden
/// subcommands): the file, its cache budget, and what to do with it.
#[derive(clap::Args)]
pub struct ChildArgs {
    /// The file.
    #[arg(long)]
    file: PathBuf,
    /// Beam cache budget.
    #[arg(long, default_value = "64M")]
    cache: String,
    /// Beams in each request list (streaming).
    #[arg(long, default_value = "10000", value_parser = count_in(1, MAX_BEAMS_PER_SECTION))]
    request: u64,
    /// Rays to append (filling).
    #[arg(long, default_value = "1M", value_parser = count_in(1, u64::MAX))]
    rays: u64,
}

/// The section of Radiance's reference fill: a 6.5 x 5 x 2 m room, grid
/// 13 x 10 x 4, 154,728 beams.
pub(crate) fn reference_section() -> Result<Section> {
    Ok(Section::new(
        [0.0; 3],
        [[6.5, 0.0, 0.0], [0.0, 5.0, 0.0], [0.0, 0.0, 2.0]],
        [13, 10, 4],
        SectionKind::Interior,
    )?)
}

/// Settings of the reference fill's file, with a beam cache of `cache` bytes.
fn reference_settings(cache: u64) -> Result<Settings> {
    let room = reference_section()?;
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

/// Appends `rays` in packets of 1-21 rays (as the paper's server did) to
/// random beams. Returns the seconds until every ray is flushed, and those the
/// close then takes (compacting the file).
/// Appends `rays` random rays to a new file at `path` in packets of 1-21
/// rays to random beams: seconds appending (flushed) and closing.
pub(super) fn fill(path: &Path, settings: &Settings, rays: u64, seed: u64) -> Result<(f64, f64)> {
    HoloFile::create(path, settings)?;
    let mut f = HoloFile::open(path, &OpenOptions::default())?;
    let beams = f.sections()[0].beam_count();
    let mut rng = StdRng::seed_from_u64(seed);
    let packet: Vec<RayRecord> = (0..4096).map(|_| random_ray(&mut rng)).collect();
    let bar = holodeck_cli::progress::Progress::counting("appending", holodeck_cli::progress::Unit::Rays, Some(rays));
    let start = Instant::now();
    let mut done = 0u64;
    while done < rays {
        let n = rng.gen_range(1..=21u64).min(rays - done) as usize;
        let at = rng.gen_range(0..packet.len() - n);
        f.append(BeamKey::new(0, rng.gen_range(0..beams)), &packet[at..at + n])?;
        done += n as u64;
        if done % (1 << 20) < 21 {
            bar.set(done);
        }
    }
    f.flush()?;
    let appended = start.elapsed().as_secs_f64();
    f.close()?;
    bar.finish();
    Ok((appended, start.elapsed().as_secs_f64() - appended))
}

fn drop_os_cache(path: &Path) -> Result<()> {
    let f = File::open(path)?;
    f.sync_all()?;
    // SAFETY: advisory call on a valid descriptor.
    unsafe { libc::posix_fadvise(f.as_raw_fd(), 0, 0, libc::POSIX_FADV_DONTNEED) };
    Ok(())
}

/// Seconds to read the whole file sequentially in 8 MiB reads, from a cold OS
/// cache (`cold`) or after one read has warmed it.
fn raw_read(path: &Path, cold: bool) -> Result<(f64, u64)> {
    if cold {
        drop_os_cache(path)?;
    } else {
        raw_read(path, true)?;
    }
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

/// The beams seen along a short walk through the room (eye points and
/// directions changing a little at a time, 90 degree field of view), in the
/// order a display would first ask for them: the kind of list displays send.
fn view_request(section: &Section, want: usize) -> Vec<BeamKey> {
    let mut seen = std::collections::HashSet::new();
    let mut out = Vec::new();
    for step in 0..10_000 {
        let t = f64::from(step) * 0.01;
        let eye = section.unit_to_world(glam::DVec3::new(0.5 + 0.3 * t.sin(), 0.5 + 0.3 * (0.7 * t).cos(), 0.45));
        let heading = 0.4 * t;
        let (forward, left) = (
            glam::DVec3::new(heading.cos(), heading.sin(), 0.0),
            glam::DVec3::new(-heading.sin(), heading.cos(), 0.0),
        );
        for i in 0..64 {
            for j in 0..48 {
                let (x, y) = (f64::from(i) / 63.0 * 2.0 - 1.0, f64::from(j) / 47.0 * 1.5 - 0.75);
                if let Some(hit) = section.locate(eye, forward + left * x + glam::DVec3::Z * y) {
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

/// Recall of request lists from a freshly opened file (cold: after dropping the
/// OS cache), copying every ray out as a consumer would. Returns (rays, seconds).
fn recall(path: &Path, cache: u64, requests: &[&[BeamKey]], cold: bool) -> Result<(u64, f64)> {
    if cold {
        drop_os_cache(path)?;
    }
    let mut f = reader(path, cache)?;
    let mut sink: Vec<RayRecord> = Vec::with_capacity(1 << 20);
    let start = Instant::now();
    let mut rays = 0;
    for request in requests {
        rays += f
            .read_beams(request, |_, r| {
                sink.clear();
                sink.extend_from_slice(r);
            })?
            .rays;
    }
    Ok((rays, start.elapsed().as_secs_f64()))
}

/// Runs `holodeck ARGS --file PATH` as a child process that prints its starting
/// and peak RSS first; returns the peak above the start, in bytes, and what it printed.
fn child_rss(args: &[&str], path: &Path) -> Result<(u64, String)> {
    let exe = std::env::current_exe()?;
    let out = std::process::Command::new(exe)
        .args(args)
        .arg("--file")
        .arg(path)
        .output()?;
    anyhow::ensure!(
        out.status.success(),
        "child {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    // The child's own peak (VmHWM counts from its exec, unlike getrusage, which
    // also counts the parent's pages a forked child shares until exec).
    let text = String::from_utf8_lossy(&out.stdout).trim().to_string();
    let field = |k: usize| {
        text.split_whitespace()
            .nth(k)
            .and_then(|v| v.parse::<u64>().ok())
            .unwrap_or(0)
    };
    Ok((field(1).saturating_sub(field(0)), text))
}

/// Opens a file for reading with a cache budget.
fn reader(path: &Path, cache: u64) -> Result<HoloFile> {
    Ok(HoloFile::open(
        path,
        &OpenOptions {
            cache_bytes: Some(cache),
            ..OpenOptions::read_only()
        },
    )?)
}

/// The child side of the streaming memory measurement: prints its starting
/// and peak RSS and the rays it read.
fn stream(path: &Path, cache: u64, request: usize) -> Result<ExitCode> {
    let (_, start) = rss();
    let mut f = reader(path, cache)?;
    let mut keys: Vec<BeamKey> = Vec::new();
    for (s, section) in f.sections().iter().enumerate() {
        keys.extend((0..section.beam_count()).map(|b| BeamKey::new(s as u32, b)));
    }
    keys.shuffle(&mut StdRng::seed_from_u64(5));
    let mut rays = 0;
    for chunk in keys.chunks(request.max(1)) {
        rays += f.read_beams(chunk, |_, _| {})?.rays;
    }
    let (peak, _) = rss();
    println!("{start} {peak} {rays}");
    Ok(ExitCode::SUCCESS)
}

fn rate(n: u64, secs: f64) -> String {
    format!("{:.1} M/s", n as f64 / secs / 1e6)
}

/// The request lists every cold-recall measurement uses.
struct RequestLists<'a> {
    random: &'a [BeamKey],
    view: &'a [BeamKey],
    all: &'a [BeamKey],
    in_order: &'a [BeamKey],
    size: usize,
}

impl RequestLists<'_> {
    /// One row per list: cold recall rate against the raw read rate `raw` (rays/s).
    fn report(&self, label: &str, path: &Path, cache: u64, raw: f64, raw_text: &str) -> Result<()> {
        let n = count(self.size as u64);
        for (what, requests) in [
            (
                format!("{} random beams", count(self.random.len() as u64)),
                vec![self.random],
            ),
            (
                format!("{} beams seen along a walk", count(self.view.len() as u64)),
                vec![self.view],
            ),
            (
                format!("all beams, random lists of {n}"),
                self.all.chunks(self.size).collect(),
            ),
            (
                format!("all beams, beam-order lists of {n}"),
                self.in_order.chunks(self.size).collect(),
            ),
        ] {
            let (rays, secs) = recall(path, cache, &requests, true)?;
            let what = format!("cold recall {label}: {what} ({} rays)", count(rays));
            row(&what, rate(rays, secs), raw_text.to_string(), rays as f64 / secs / raw);
        }
        Ok(())
    }
}

/// The child that streams one file's beams: prints its starting and peak
/// RSS and the rays it read.
pub fn run_stream(a: &ChildArgs) -> Result<ExitCode> {
    let cache = parse_size(&a.cache).context("--cache")?;
    stream(&a.file, cache, a.request as usize)
}

/// The child that fills one file: prints its starting and peak RSS and
/// the seconds appending and closing took.
pub fn run_fill(a: &ChildArgs) -> Result<ExitCode> {
    let cache = parse_size(&a.cache).context("--cache")?;
    let (_, start) = rss();
    let (secs, close) = fill(&a.file, &reference_settings(cache)?, a.rays, 1)?;
    let (peak, _) = rss();
    println!("{start} {peak} {secs} {close}");
    Ok(ExitCode::SUCCESS)
}

/// Runs the storage benchmark.
pub fn run(a: &Args) -> Result<ExitCode> {
    let cache = parse_size(&a.cache).context("--cache")?;
    // At most MAX_BEAMS_PER_SECTION, as parsed.
    let request = a.request as usize;
    let dir = &a.files.dir;
    std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
    let big = dir.join("bench-large.hdk");
    let reference = dir.join("bench-reference.hdk");
    for p in [&big, &reference] {
        let _ = std::fs::remove_file(p);
    }
    let settings = reference_settings(cache)?;
    let section = settings.sections[0].clone();
    println!(
        "holodeck bench storage: {} rays in 154,728 beams, CACHE {}, requests of {} beams",
        count(a.rays),
        bytes(cache),
        count(request as u64)
    );
    println!();
    println!("| measurement | result | baseline (same run) | ratio |");
    println!("|---|---|---|---|");
    let filled = fill_rows(a, &big, cache)?;
    let beams = section.beam_count();
    let mut all: Vec<BeamKey> = (0..beams).map(|b| BeamKey::new(0, b)).collect();
    all.shuffle(&mut StdRng::seed_from_u64(2));
    let random = &all[..request.min(all.len())];
    let view = view_request(&section, request);
    let in_order: Vec<BeamKey> = (0..beams).map(|b| BeamKey::new(0, b)).collect();
    let lists = RequestLists {
        random,
        view: &view,
        all: &all,
        in_order: &in_order,
        size: request,
    };
    lists.report("as filled", &big, cache, filled.rays_per_sec, &filled.text)?;
    let optimized_bytes = optimize_rows(&big, filled.secs)?;
    let raw = RawRead::of(&big, true)?;
    lists.report("optimized", &big, cache, raw.rays_per_sec, &raw.text)?;
    os_cached_rows(&big, cache, &lists)?;
    cache_hit_row(&big, cache, random, &raw)?;
    stream_row(a, &big, optimized_bytes, cache)?;
    reference_rows(a, &reference, &settings, &raw)?;
    if !a.files.keep {
        for p in [&big, &reference] {
            let _ = std::fs::remove_file(p);
        }
    }
    Ok(ExitCode::SUCCESS)
}

/// A raw read of a whole file, the baseline of the rows beside it.
struct RawRead {
    /// Seconds it took.
    secs: f64,
    /// Its bytes as 10-byte records per second.
    rays_per_sec: f64,
    /// The baseline's words in the table.
    text: String,
}

impl RawRead {
    /// Reads `path` whole, from the disk (`cold`: the OS cache dropped
    /// first) or from the OS cache.
    fn of(path: &Path, cold: bool) -> Result<RawRead> {
        let (secs, n) = raw_read(path, cold)?;
        let what = if cold { "raw read" } else { "raw read, OS-cached" };
        Ok(RawRead {
            secs,
            rays_per_sec: n as f64 / 10.0 / secs,
            text: format!("{what} {} ({}/s)", rate(n / 10, secs), bytes((n as f64 / secs) as u64)),
        })
    }
}

/// The large fill (in a child process, so that its peak memory is its
/// own): append, close and peak memory rows, beside a raw read of the file.
fn fill_rows(a: &Args, big: &Path, cache: u64) -> Result<RawRead> {
    let (fill_rss, fill_out) = child_rss(
        &["bench", "fill", "--rays", &a.rays.to_string(), "--cache", &a.cache],
        big,
    )?;
    let field = |n: usize| -> f64 {
        fill_out
            .split_whitespace()
            .nth(n)
            .and_then(|v| v.parse().ok())
            .unwrap_or(f64::NAN)
    };
    let (fill_secs, close_secs) = (field(2), field(3));
    let raw = RawRead::of(big, true)?;
    row(
        "append: random beams, packets of 1-21 rays, flush every 2 s and at the end",
        rate(a.rays, fill_secs),
        raw.text.clone(),
        a.rays as f64 / fill_secs / raw.rays_per_sec,
    );
    row(
        "close: compacting the file as filled",
        format!("{close_secs:.2} s"),
        format!("appending {fill_secs:.2} s"),
        close_secs / fill_secs,
    );
    row(
        &format!("peak RSS filling {} rays, child process", count(a.rays)),
        format!("{} above its start", bytes(fill_rss)),
        format!("CACHE {}", bytes(cache)),
        fill_rss as f64 / cache as f64,
    );
    Ok(raw)
}

/// Optimizes the large file: its time against a raw read of it (`raw_secs`)
/// and its bytes per ray before and after. The optimized file's bytes.
fn optimize_rows(big: &Path, raw_secs: f64) -> Result<u64> {
    let before = HoloFile::open(big, &OpenOptions::read_only())?.summary();
    let start = Instant::now();
    storage::optimize(big, |_, _| {})?;
    let opt_secs = start.elapsed().as_secs_f64();
    let after = HoloFile::open(big, &OpenOptions::read_only())?.summary();
    row(
        &format!("optimize {}", bytes(before.file_bytes)),
        format!("{opt_secs:.2} s"),
        format!("raw read of it {raw_secs:.2} s"),
        opt_secs / raw_secs,
    );
    row(
        "bytes per ray before / after optimize",
        format!("{:.3} / {:.3}", before.bytes_per_ray(), after.bytes_per_ray()),
        "10 (records alone)".into(),
        after.bytes_per_ray() / 10.0,
    );
    Ok(after.file_bytes)
}

/// Recall of the optimized file from the OS page cache: the engine's
/// overhead alone, free of the disk.
fn os_cached_rows(big: &Path, cache: u64, lists: &RequestLists<'_>) -> Result<()> {
    let warm = RawRead::of(big, false)?;
    let requests: Vec<&[BeamKey]> = lists.in_order.chunks(lists.size).collect();
    let (rays, secs) = recall(big, cache, &requests, false)?;
    row(
        &format!(
            "OS-cached recall optimized: all beams, beam-order lists of {} ({} rays)",
            count(lists.size as u64),
            count(rays)
        ),
        rate(rays, secs),
        warm.text.clone(),
        rays as f64 / secs / warm.rays_per_sec,
    );
    let (rays, secs) = recall(big, cache, &[lists.view], false)?;
    row(
        &format!(
            "OS-cached recall optimized: {} beams seen along a walk ({} rays)",
            count(lists.view.len() as u64),
            count(rays)
        ),
        rate(rays, secs),
        warm.text,
        rays as f64 / secs / warm.rays_per_sec,
    );
    Ok(())
}

/// Cache hits: the random request again, rays copied out, five times.
fn cache_hit_row(big: &Path, cache: u64, random: &[BeamKey], raw: &RawRead) -> Result<()> {
    let mut f = reader(big, cache)?;
    let first = f.read_beams(random, |_, _| {})?;
    let mut sink: Vec<RayRecord> = Vec::with_capacity(1 << 20);
    let start = Instant::now();
    let mut hit_rays = 0;
    for _ in 0..5 {
        hit_rays += f
            .read_beams(random, |_, r| {
                sink.clear();
                sink.extend_from_slice(r);
            })?
            .rays;
    }
    let hit_secs = start.elapsed().as_secs_f64();
    row(
        &format!(
            "cache-hit recall: {} random beams x5, rays copied out ({} of them cached)",
            count(random.len() as u64),
            count(first.beams)
        ),
        rate(hit_rays, hit_secs),
        raw.text.clone(),
        hit_rays as f64 / hit_secs / raw.rays_per_sec,
    );
    Ok(())
}

/// Peak memory of a child process streaming every beam of the file
/// (`file_bytes` long).
fn stream_row(a: &Args, big: &Path, file_bytes: u64, cache: u64) -> Result<()> {
    let request_text = a.request.to_string();
    let (above, _) = child_rss(
        &["bench", "stream", "--cache", &a.cache, "--request", &request_text],
        big,
    )?;
    row(
        &format!(
            "peak RSS streaming every beam of a {} file ({:.1}x CACHE), child process",
            bytes(file_bytes),
            file_bytes as f64 / cache as f64
        ),
        format!("{} above its start", bytes(above)),
        format!("CACHE {}", bytes(cache)),
        above as f64 / cache as f64,
    );
    Ok(())
}

/// The reference fill (Radiance's sizes): append, a cold optimize, and
/// bytes per ray against Radiance's.
fn reference_rows(a: &Args, reference: &Path, settings: &Settings, raw: &RawRead) -> Result<()> {
    let (ref_fill, _) = fill(reference, settings, a.reference_rays, 3)?;
    let before = HoloFile::open(reference, &OpenOptions::read_only())?.summary();
    let (raw_ref, _) = raw_read(reference, true)?;
    drop_os_cache(reference)?;
    let start = Instant::now();
    storage::optimize(reference, |_, _| {})?;
    let opt_secs = start.elapsed().as_secs_f64();
    let after = HoloFile::open(reference, &OpenOptions::read_only())?.summary();
    row(
        &format!(
            "reference fill ({} rays, 154,728 beams): append",
            count(a.reference_rays)
        ),
        rate(a.reference_rays, ref_fill),
        raw.text.clone(),
        a.reference_rays as f64 / ref_fill / raw.rays_per_sec,
    );
    row(
        &format!("reference fill: optimize {} (cold)", bytes(before.file_bytes)),
        format!("{opt_secs:.3} s"),
        format!("raw read of it {raw_ref:.3} s; rhoptimize 0.57 s on a 65 MB file (DESIGN.md)"),
        opt_secs / raw_ref,
    );
    row(
        "reference fill: whole-file bytes per ray, as filled / optimized",
        format!("{:.3} / {:.3}", before.bytes_per_ray(), after.bytes_per_ray()),
        "Radiance 10.40".into(),
        after.bytes_per_ray() / 10.40,
    );
    Ok(())
}

/// The fast version for `bench all`: a million random rays appended to the
/// Radiance-sized section, every beam recalled in beam order from the OS
/// cache, the file optimized; beside raw reads of the same file (from the OS
/// cache: the engine's overhead, free of the disk), each repeat a new file.
pub fn fast(ctx: &super::fast::Fast) -> Result<Vec<super::report::Figure>> {
    use super::report::Figure;
    let cache = 64 << 20;
    let settings = reference_settings(cache)?;
    std::fs::create_dir_all(&ctx.dir).with_context(|| format!("creating {}", ctx.dir.display()))?;
    let path = ctx.dir.join("all-storage.hdk");
    let rays = 1_000_000u64;
    let beams = settings.sections[0].beam_count();
    let in_order: Vec<BeamKey> = (0..beams).map(|b| BeamKey::new(0, b)).collect();
    let lists: Vec<&[BeamKey]> = in_order.chunks(10_000).collect();
    let (mut append, mut recalled, mut raw, mut opt, mut raw_secs, mut per_ray) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut measure = |r: u64| -> Result<()> {
        let _ = std::fs::remove_file(&path);
        let (secs, _) = fill(&path, &settings, rays, 100 + r)?;
        append.push(rays as f64 / secs / 1e6);
        let (rs, rb) = raw_read(&path, false)?;
        raw.push(rb as f64 / 10.0 / rs / 1e6);
        raw_secs.push(rs);
        let (n, s) = recall(&path, cache, &lists, false)?;
        recalled.push(n as f64 / s / 1e6);
        let start = Instant::now();
        storage::optimize(&path, |_, _| {})?;
        opt.push(start.elapsed().as_secs_f64());
        per_ray.push(
            HoloFile::open(&path, &OpenOptions::read_only())?
                .summary()
                .bytes_per_ray(),
        );
        Ok(())
    };
    let measured = (0..ctx.repeats as u64).try_for_each(&mut measure);
    // Made here, removed here, whether or not it went well.
    let _ = std::fs::remove_file(&path);
    measured?;
    let radiance = vec![10.40; per_ray.len()];
    Ok(vec![
        Figure::new("storage", "append 1M rays, packets of 1-21", "Mrays/s", true, append)
            .against("raw read of the file", raw.clone()),
        Figure::new(
            "storage",
            "recall every beam in beam order, OS-cached",
            "Mrays/s",
            true,
            recalled,
        )
        .against("raw read of the file", raw),
        Figure::new("storage", "optimize the file", "s", false, opt).against("raw read of the file", raw_secs),
        Figure::new(
            "storage",
            "whole-file bytes per ray after optimize",
            "B",
            false,
            per_ray,
        )
        .against("Radiance's rholo", radiance),
    ])
}
