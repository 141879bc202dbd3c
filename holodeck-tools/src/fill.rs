//! A batch fill in one process: the schedule picks beams, the cores trace
//! them, the storage engine keeps the rays. This is the holodeck's main loop,
//! which the networked server spreads over sampler processes.

use std::time::{Duration, Instant};

use holodeck_protocol::{BeamKey, RayRecord, Section};
use holodeck_sampler::beam::{trace_sample, uniform_rays};
use holodeck_sampler::{Rng, Tracer};
use holodeck_server::schedule::BatchSchedule;
use holodeck_server::HoloFile;
use rayon::prelude::*;

/// When to stop, and how work is cut up.
#[derive(Clone, Debug)]
pub struct FillOptions {
    /// Stop after this many rays (this run).
    pub rays: Option<u64>,
    /// Stop after this long.
    pub time: Option<Duration>,
    /// Rays per beam per visit.
    pub packet: u32,
    /// Beams traced between appends.
    pub batch: usize,
    /// Seed of this run's random sequence.
    pub seed: u64,
    /// Fill only these beams, weighted by view rays (beams some views see).
    pub views: Option<Vec<(BeamKey, u32)>>,
}

/// What a fill did.
#[derive(Clone, Debug, Default)]
pub struct FillReport {
    /// Rays traced and stored by this run.
    pub rays: u64,
    /// Wall-clock seconds.
    pub secs: f64,
    /// Seconds spent storing (appending and flushing), not tracing.
    pub store_secs: f64,
    /// Beams holding rays at the end, and all beams.
    pub beams_filled: u64,
    /// All beams.
    pub beams: u64,
}

/// Fills `file` with rays traced by `tracer` until a limit is reached.
pub fn fill(
    tracer: &Tracer,
    file: &mut HoloFile,
    o: &FillOptions,
    progress: &dyn Fn(u64),
) -> anyhow::Result<FillReport> {
    let sections = file.sections().to_vec();
    let obstructions = file.settings().obstructions;
    let stored = |k| file.beam_len(k).unwrap_or(0);
    let mut schedule = match &o.views {
        Some(seen) => BatchSchedule::for_views(&sections, seen, stored),
        None => BatchSchedule::new(&sections, stored)?,
    };
    let start = Instant::now();
    let mut report = FillReport::default();
    let mut round = 0u64;
    loop {
        if o.rays.is_some_and(|n| report.rays >= n) || o.time.is_some_and(|t| start.elapsed() >= t) {
            break;
        }
        let left = o.rays.map_or(u64::MAX, |n| n - report.rays);
        let beams = (o.batch as u64).min(left.div_ceil(u64::from(o.packet.max(1)))).max(1) as usize;
        let mut batch = schedule.next(beams, o.packet.max(1));
        if batch.is_empty() {
            break;
        }
        // Trim to exactly the rays asked for (empty beams get single rays, so
        // the batch may hold fewer or more than beams x packet).
        let mut budget = left;
        for (key, n) in batch.iter_mut() {
            let keep = u64::from(*n).min(budget) as u32;
            if keep < *n {
                schedule.give_back(*key, *n - keep);
            }
            *n = keep;
            budget -= u64::from(keep);
        }
        batch.retain(|b| b.1 > 0);
        let traced = trace_batch(tracer, &sections, obstructions, &batch, o.seed ^ round.rotate_left(32));
        let store = Instant::now();
        for (key, records) in &traced {
            file.append(*key, records)?;
            report.rays += records.len() as u64;
        }
        report.store_secs += store.elapsed().as_secs_f64();
        progress(report.rays);
        round += 1;
    }
    let store = Instant::now();
    file.flush()?;
    report.store_secs += store.elapsed().as_secs_f64();
    report.secs = start.elapsed().as_secs_f64();
    let summary = file.summary();
    report.beams = summary.sections.iter().map(|s| u64::from(s.0)).sum();
    report.beams_filled = summary.sections.iter().map(|s| u64::from(s.1)).sum();
    Ok(report)
}

/// Traces a batch of (beam, rays) with all cores of the current rayon pool:
/// uniform beam rays, one random sequence per beam.
pub fn trace_batch(
    tracer: &Tracer,
    sections: &[Section],
    obstructions: bool,
    batch: &[(BeamKey, u32)],
    seed: u64,
) -> Vec<(BeamKey, Vec<RayRecord>)> {
    batch
        .par_iter()
        .enumerate()
        .map(|(i, &(key, n))| {
            let mut rng = Rng::new(seed, i as u64);
            let section = &sections[key.section as usize];
            let samples = uniform_rays(section, key.beam, n as usize, &mut rng).unwrap_or_default();
            let records = samples
                .iter()
                .map(|s| trace_sample(tracer, section, obstructions, s, &mut rng))
                .collect();
            (key, records)
        })
        .collect()
}
