//! `holodeck bench replay`: display-only replay of a filled file, as on a
//! low-end machine with no GPU. A walk of views (each a step further and a
//! few degrees turned) is drawn from the file by each CPU driver, every
//! view from a fresh driver (a view change to a complete picture from the
//! file's cached beams), on one core and on all cores in the same run: the
//! time to each complete picture, the frames per second of the walk, and
//! the samples recalled per second, with the stages of the recall.

use std::path::PathBuf;
use std::process::ExitCode;
use std::time::{Duration, Instant};

use anyhow::{Context, Result};
use holodeck::recall::draw;
use holodeck::DriverChoice;
use holodeck_display::Viewport;
use holodeck_file::{HoloFile, OpenOptions};
use holodeck_protocol::View;

use super::row;
use holodeck_cli::human::count;

/// Arguments of `holodeck bench replay`.
#[derive(clap::Args)]
#[command(after_help = "\
Draws a walk of views from FILE with each CPU driver, one fresh driver per view, on one core and
on all cores, and prints frames per second, the time to each complete picture and samples/s.
The file's beams are read once before timing, so the figures are those of a cached file.

Examples:
  holodeck fill builtin:room room.hdk --views views.txt --rays 4M
  holodeck bench replay room.hdk --views 20 -x 1280 -y 720
  holodeck bench replay room.hdk -x 1920 -y 1080 --memory-limit-mib 1024
  holodeck bench replay room.hdk --walks window --drivers splat   (one walk, one driver)
  taskset -c 0 holodeck bench replay room.hdk      (one core for the whole process)")]
pub struct Args {
    /// The holodeck file to replay.
    pub file: PathBuf,
    /// The walk's first view (Radiance view options).
    #[arg(long, default_value = holodeck::ROOM_VIEW, allow_hyphen_values = true)]
    pub view: String,
    /// Views in the walk.
    #[arg(long, default_value_t = 12, value_parser = clap::value_parser!(u32).range(1..=10_000))]
    pub views: u32,
    /// Metres between views.
    #[arg(long, default_value_t = 0.05)]
    pub step: f64,
    /// Degrees turned between views.
    #[arg(long, default_value_t = 2.0)]
    pub turn: f64,
    /// Frame width.
    #[arg(short = 'x', long, default_value_t = 1280)]
    pub width: u32,
    /// Frame height.
    #[arg(short = 'y', long, default_value_t = 720)]
    pub height: u32,
    /// Which walks: `fresh` (a fresh driver for each view) and `window`
    /// (one driver for the walk, as the window replays it).
    #[arg(long, value_delimiter = ',', default_value = "fresh,window", value_parser = ["fresh", "window"])]
    pub walks: Vec<String>,
    /// The CPU drivers walked.
    #[arg(long, value_delimiter = ',', default_value = "quadtree,splat", value_parser = ["quadtree", "splat"])]
    pub drivers: Vec<String>,
    /// Limit the process's data memory to this many MiB (as a low-end
    /// machine would; 0: no limit). An allocation beyond it fails.
    #[arg(long, default_value_t = 0)]
    pub memory_limit_mib: u64,
}

/// One walk's figures.
#[derive(Default)]
struct Walk {
    frames: u32,
    /// Every view's recall and frame.
    total: Duration,
    /// The slowest view.
    worst: Duration,
    recall: Duration,
    read: Duration,
    decode: Duration,
    insert: Duration,
    frame: Duration,
    samples: u64,
    /// The driver's heap after each view, summed, and its estimates.
    heap: u64,
    estimates: u64,
}

/// Draws every view of `views` from `file` with `driver`, on the current rayon pool.
fn walk(file: &mut HoloFile, views: &[View], size: (u32, u32), driver: &str) -> Result<Walk> {
    let choice = DriverChoice::plain(driver, Default::default());
    let mut w = Walk::default();
    for (i, view) in views.iter().enumerate() {
        let viewport = Viewport::new(view.clone(), size.0, size.1)?;
        let start = Instant::now();
        let (_, _, s) = draw(file, viewport, &choice, 2, i as u64)?;
        let took = start.elapsed();
        w.frames += 1;
        w.total += took;
        w.worst = w.worst.max(took);
        w.recall += s.recall;
        w.read += s.stages.read;
        w.decode += s.stages.decode;
        w.insert += s.stages.insert;
        w.frame += s.render;
        w.samples += s.samples;
        w.heap += s.heap as u64;
        w.estimates += s.driver.kept;
    }
    Ok(w)
}

/// The walk as the window replays it: one driver for every view, moved to
/// each (its estimates reprojected) and given only the rays of beams it has
/// not had yet, then a frame.
#[derive(Default)]
struct Following {
    frames: u32,
    total: Duration,
    worst: Duration,
    reproject: Duration,
    recall: Duration,
    frame: Duration,
    /// New samples over the walk (the first view's included).
    samples: u64,
    /// Those of the first view.
    first: u64,
}

/// Walks `views` in one `driver`, on the current rayon pool.
fn follow_walk(file: &mut HoloFile, views: &[View], size: (u32, u32), driver: &str) -> Result<Following> {
    let choice = DriverChoice::plain(driver, Default::default());
    let mut d = choice.make(Viewport::new(views[0].clone(), size.0, size.1)?)?;
    let mut given = std::collections::HashMap::new();
    let mut f = Following::default();
    for (i, view) in views.iter().enumerate() {
        let viewport = Viewport::new(view.clone(), size.0, size.1)?;
        let start = Instant::now();
        let got = holodeck::recall::follow(file, d.as_mut(), viewport, &mut given, 2, i as u64)?;
        let at = Instant::now();
        std::hint::black_box(d.render());
        let frame = at.elapsed();
        let took = start.elapsed();
        if i == 0 {
            f.first = got.samples;
            continue;
        }
        f.frames += 1;
        f.total += took;
        f.worst = f.worst.max(took);
        f.reproject += got.reproject;
        f.recall += got.recall;
        f.frame += frame;
        f.samples += got.samples;
    }
    Ok(f)
}

/// Runs `holodeck bench replay`.
pub fn run_args(a: &Args) -> Result<ExitCode> {
    let options = OpenOptions {
        writable: false,
        ..OpenOptions::default()
    };
    if a.memory_limit_mib > 0 {
        limit_memory(a.memory_limit_mib << 20)?;
    }
    let mut file = HoloFile::open(&a.file, &options).with_context(|| format!("opening {}", a.file.display()))?;
    let first = holodeck_cli::view_arg::parse(&a.view).context("--view")?;
    let views = holodeck::truth::walk(&first, a.views as usize, a.step, a.turn);
    let size = (a.width, a.height);
    // Every beam the walk sees read once, so the file's cache holds them.
    walk(&mut file, &views, (64, 36), "splat")?;
    let cores = rayon::current_num_threads();
    let one = rayon::ThreadPoolBuilder::new().num_threads(1).build()?;
    if a.walks.iter().any(|w| w == "fresh") {
        println!(
            "| measurement ({} views of {}x{}, a fresh driver each) | one core | all {cores} cores | ratio |",
            a.views, a.width, a.height
        );
        println!("|---|---|---|---|");
        for driver in a.drivers.iter().map(String::as_str) {
            let single = one.install(|| walk(&mut file, &views, size, driver))?;
            let all = walk(&mut file, &views, size, driver)?;
            let ms = |d: Duration, n: u32| format!("{:.1} ms", d.as_secs_f64() * 1e3 / f64::from(n.max(1)));
            let fps = |w: &Walk| f64::from(w.frames) / w.total.as_secs_f64().max(1e-9);
            let rate = |w: &Walk| w.samples as f64 / w.recall.as_secs_f64().max(1e-9);
            row(
                &format!("{driver}: frames per second along the walk"),
                format!("{:.1}", fps(&single)),
                format!("{:.1}", fps(&all)),
                fps(&single) / fps(&all),
            );
            row(
                &format!("{driver}: view change to a complete picture, mean (slowest)"),
                format!("{} ({})", ms(single.total, single.frames), ms(single.worst, 1)),
                format!("{} ({})", ms(all.total, all.frames), ms(all.worst, 1)),
                single.total.as_secs_f64() / all.total.as_secs_f64().max(1e-9),
            );
            row(
                &format!(
                    "{driver}: samples recalled into the picture per second ({} samples a view)",
                    count(single.samples / u64::from(single.frames.max(1)))
                ),
                format!("{}/s", count(rate(&single) as u64)),
                format!("{}/s", count(rate(&all) as u64)),
                rate(&single) / rate(&all),
            );
            let per = |w: &Walk| w.heap as f64 / w.estimates.max(1) as f64;
            row(
                &format!(
                    "{driver}: store heap per view, and per estimate ({} estimates a view)",
                    count(single.estimates / u64::from(single.frames.max(1)))
                ),
                format!(
                    "{:.1} MiB, {:.0} B",
                    single.heap as f64 / f64::from(single.frames.max(1)) / 1048576.0,
                    per(&single)
                ),
                format!(
                    "{:.1} MiB, {:.0} B",
                    all.heap as f64 / f64::from(all.frames.max(1)) / 1048576.0,
                    per(&all)
                ),
                per(&single) / per(&all).max(1e-9),
            );
            stage_rows(
                driver,
                (single.frames, all.frames),
                &[
                    ("read", single.read, all.read),
                    ("decode and project (overlaps the merge)", single.decode, all.decode),
                    ("sort and merge into estimates", single.insert, all.insert),
                    ("frame", single.frame, all.frame),
                ],
            );
        }
    }
    if a.walks.iter().any(|w| w == "window") {
        println!(
            "| measurement (the same walk in one driver, as the window replays it: each view's \
             estimates reprojected, only rays of beams not given before read, then a frame; \
             the first view left out) | one core | all {cores} cores | ratio |"
        );
        println!("|---|---|---|---|");
        for driver in a.drivers.iter().map(String::as_str) {
            let single = one.install(|| follow_walk(&mut file, &views, size, driver))?;
            let all = follow_walk(&mut file, &views, size, driver)?;
            let ms = |d: Duration, n: u32| format!("{:.1} ms", d.as_secs_f64() * 1e3 / f64::from(n.max(1)));
            let fps = |w: &Following| f64::from(w.frames) / w.total.as_secs_f64().max(1e-9);
            row(
                &format!("{driver}: frames per second along the walk"),
                format!("{:.1}", fps(&single)),
                format!("{:.1}", fps(&all)),
                fps(&single) / fps(&all).max(1e-9),
            );
            row(
                &format!("{driver}: view change to a complete picture, mean (slowest)"),
                format!("{} ({})", ms(single.total, single.frames), ms(single.worst, 1)),
                format!("{} ({})", ms(all.total, all.frames), ms(all.worst, 1)),
                single.total.as_secs_f64() / all.total.as_secs_f64().max(1e-9),
            );
            row(
                &format!("{driver}: new samples a view (the first view: {})", count(single.first)),
                count(single.samples / u64::from(single.frames.max(1))),
                count(all.samples / u64::from(all.frames.max(1))),
                single.samples as f64 / all.samples.max(1) as f64,
            );
            stage_rows(
                driver,
                (single.frames, all.frames),
                &[
                    ("reprojection", single.reproject, all.reproject),
                    ("new samples read and merged", single.recall, all.recall),
                    ("frame", single.frame, all.frame),
                ],
            );
        }
    }
    println!(
        "| peak resident memory of the process{} | {} MiB | | |",
        if a.memory_limit_mib > 0 {
            format!(" (data limited to {} MiB)", a.memory_limit_mib)
        } else {
            String::new()
        },
        peak_resident_kib() >> 10
    );
    memory_at(&mut file, &views[0], a)?;
    Ok(ExitCode::SUCCESS)
}

/// A row per stage: its time per view on one core and on all, from the
/// stages' totals over `frames` (one core's, all cores').
fn stage_rows(driver: &str, frames: (u32, u32), stages: &[(&str, Duration, Duration)]) {
    let ms = |d: Duration, n: u32| format!("{:.1} ms", d.as_secs_f64() * 1e3 / f64::from(n.max(1)));
    for &(stage, s, m) in stages {
        row(
            &format!("{driver}: {stage}, per view"),
            ms(s, frames.0),
            ms(m, frames.1),
            s.as_secs_f64() / m.as_secs_f64().max(1e-9),
        );
    }
}

/// The frame size the store's memory is reported at.
const MEMORY_SIZE: (u32, u32) = (1920, 1080);

/// The store's memory for `view` at [`MEMORY_SIZE`], a fresh driver of each
/// of the walked drivers holding the view's rays: in all, per estimate, and
/// by what holds it. Prints its own table.
fn memory_at(file: &mut HoloFile, view: &View, a: &Args) -> Result<()> {
    use holodeck_display::store::{Entry, Estimate, HeapParts};
    let mut columns = Vec::new();
    for driver in &a.drivers {
        let choice = DriverChoice::plain(driver, Default::default());
        let viewport = Viewport::new(view.clone(), MEMORY_SIZE.0, MEMORY_SIZE.1)?;
        let (mut d, _) = holodeck::recall(file, viewport, &choice, 2, 0)?;
        std::hint::black_box(d.render());
        columns.push((d.heap_bytes(), d.store_heap_parts(), d.stats().kept));
    }
    println!();
    println!(
        "The store at {} x {}, the walk's first view drawn by a fresh driver; an estimate is {} B \
         ({} B of sums, firefly candidate, depths and centroid, and its pixel key):",
        MEMORY_SIZE.0,
        MEMORY_SIZE.1,
        std::mem::size_of::<Entry>(),
        std::mem::size_of::<Estimate>()
    );
    println!();
    let head: Vec<&str> = a.drivers.iter().map(String::as_str).collect();
    println!("| heap | {} |", head.join(" | "));
    println!("|---|{}", "---|".repeat(head.len()));
    let mib = |b: usize| format!("{:.1} MiB", b as f64 / 1048576.0);
    let line = |name: &str, f: &dyn Fn(&(usize, HeapParts, u64)) -> String| {
        let cells: Vec<String> = columns.iter().map(f).collect();
        println!("| {name} | {} |", cells.join(" | "));
    };
    line("estimates on the frame", &|c| count(c.2));
    line("in all", &|c| mib(c.0));
    line("per estimate", &|c| format!("{:.0} B", c.0 as f64 / c.2.max(1) as f64));
    line("estimates, with their pixel keys (the vector's capacity)", &|c| {
        mib(c.1.estimates)
    });
    line("estimates parked off the frame", &|c| mib(c.1.parked));
    line("pixel index and each pixel's nearest depth", &|c| mib(c.1.index));
    line("batches of rays being added", &|c| mib(c.1.batches));
    line("a frame's values, neighbourhoods and firefly light", &|c| {
        mib(c.1.frame)
    });
    line("the driver's own (what it draws with)", &|c| mib(c.0 - c.1.total()));
    println!();
    Ok(())
}

/// Limits the process's data segment (heap and private mappings) to
/// `bytes`, as a machine with that much memory would.
fn limit_memory(bytes: u64) -> Result<()> {
    let limit = libc::rlimit {
        rlim_cur: bytes as libc::rlim_t,
        rlim_max: bytes as libc::rlim_t,
    };
    // SAFETY: setrlimit reads the struct we pass and nothing else.
    if unsafe { libc::setrlimit(libc::RLIMIT_DATA, &limit) } != 0 {
        return Err(std::io::Error::last_os_error()).context("setting the memory limit");
    }
    Ok(())
}

/// The most memory the process has held resident, KiB.
fn peak_resident_kib() -> u64 {
    // SAFETY: getrusage fills the zeroed struct we pass.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    if unsafe { libc::getrusage(libc::RUSAGE_SELF, &mut usage) } != 0 {
        return 0;
    }
    usage.ru_maxrss.max(0) as u64
}
