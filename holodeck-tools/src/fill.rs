//! A batch fill in one process: the schedule picks beams, the cores trace
//! them, the storage engine keeps the rays. This is the holodeck's main loop,
//! which the networked server spreads over sampler processes.

use std::time::{Duration, Instant};

use std::collections::HashMap;

use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::{BeamKey, Section, View, ViewBeams};
use holodeck_sampler::beam::trace_batch;
use holodeck_sampler::shade::wavefront::AUTO_MIN_PATHS;
use holodeck_sampler::Tracer;
use holodeck_server::schedule::BatchSchedule;
use holodeck_server::HoloFile;

/// When to stop, and how work is cut up.
#[derive(Clone, Debug)]
pub struct FillOptions {
    /// Stop after this many rays (this run).
    pub rays: Option<u64>,
    /// Stop after this long.
    pub time: Option<Duration>,
    /// Rays per beam per visit.
    pub packet: u32,
    /// Beams traced between appends (more for scenes larger than the
    /// caches, whose samplers sort big batches of rays).
    pub batch: usize,
    /// Seed of this run's random sequence.
    pub seed: u64,
    /// Fill only the beams some views see, weighted by view rays.
    pub views: Option<ViewFill>,
}

/// A fill limited to what some views see.
#[derive(Clone, Debug, Default)]
pub struct ViewFill {
    /// (beam, view rays in it), over all the views.
    pub seen: Vec<(BeamKey, u32)>,
    /// How to choose each beam's rays: near the eye of the view that sees
    /// the beam most (Appendix A), or uniformly.
    pub modes: HashMap<BeamKey, SamplingMode>,
}

impl ViewFill {
    /// The beams `views` see in `sections`, one view ray per `stride` pixels
    /// of a 256 x 192 frame; new rays pass within `eye_radius` (a fraction
    /// of the smallest section diagonal) of the eye that sees their beam
    /// most, or anywhere in it for 0.
    pub fn new(sections: &[Section], views: &[View], eye_radius: f64) -> ViewFill {
        let smallest = sections.iter().map(Section::diagonal).fold(f64::INFINITY, f64::min);
        let radius = eye_radius * smallest;
        let mut fill = ViewFill::default();
        let mut best: HashMap<BeamKey, u32> = HashMap::new();
        for (i, v) in views.iter().enumerate() {
            let counts = ViewBeams::select(sections, v, 256, 192, i as u64).counts;
            if radius > 0.0 && radius.is_finite() {
                for &(k, n) in &counts {
                    let b = best.entry(k).or_insert(0);
                    if n > *b {
                        *b = n;
                        fill.modes.insert(
                            k,
                            SamplingMode::NearEye {
                                eye: v.position.to_array(),
                                radius,
                                frustum: v.frustum(),
                            },
                        );
                    }
                }
            }
            fill.seen.extend(counts);
        }
        fill
    }

    /// How to choose the rays of `key`.
    pub fn mode(&self, key: BeamKey) -> SamplingMode {
        self.modes.get(&key).copied().unwrap_or(SamplingMode::Uniform)
    }
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
        Some(v) => BatchSchedule::for_views(&sections, &v.seen, stored),
        None => BatchSchedule::new(&sections, stored)?,
    };
    // A scene larger than the caches gets rounds big enough for every core
    // to sort its share of the paths (the samples are the same whether or
    // not they are sorted; the rounds depend on the scene alone).
    let round_beams = if tracer.exceeds_cache() {
        let paths = 2 * AUTO_MIN_PATHS * rayon::current_num_threads().max(1);
        let per_beam = o.packet.max(1) as usize * tracer.options.samples.max(1) as usize;
        o.batch.max(paths.div_ceil(per_beam))
    } else {
        o.batch
    };
    let start = Instant::now();
    let mut report = FillReport::default();
    let mut round = 0u64;
    loop {
        if o.rays.is_some_and(|n| report.rays >= n) || o.time.is_some_and(|t| start.elapsed() >= t) {
            break;
        }
        let left = o.rays.map_or(u64::MAX, |n| n - report.rays);
        let beams = (round_beams as u64)
            .min(left.div_ceil(u64::from(o.packet.max(1))))
            .max(1) as usize;
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
        let mode = |k: BeamKey| o.views.as_ref().map_or(SamplingMode::Uniform, |v| v.mode(k));
        let traced = trace_batch(
            tracer,
            &sections,
            obstructions,
            &batch,
            &mode,
            o.seed ^ round.rotate_left(32),
        );
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
