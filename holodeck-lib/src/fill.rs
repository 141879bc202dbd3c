//! A batch fill in one process: the schedule picks beams, the cores trace
//! them, the storage engine keeps the rays. This is the holodeck's main loop,
//! which the networked server spreads over sampler processes.

use std::time::{Duration, Instant};

use std::collections::HashMap;

use holodeck_file::HoloFile;
use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::{BeamKey, Section, View, ViewBeams};
use holodeck_sampler::beam::{trace_batch, FileRules};
use holodeck_sampler::shade::AUTO_MIN_PATHS;
use holodeck_sampler::{Reorder, Tracer};
use holodeck_server::schedule::BatchSchedule;

/// Scenes whose in-core structure and mesh exceed this (a typical
/// last-level cache) are filled in rounds large enough to sort.
const LARGE_SCENE_BYTES: usize = 32 << 20;

/// Paths in a round of such a scene: enough for four cores to sort their
/// shares ([`AUTO_MIN_PATHS`] each, twice over).
const LARGE_ROUND_PATHS: usize = 4 * 2 * AUTO_MIN_PATHS;

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

impl Default for FillOptions {
    /// No limit (set one), packets of 4 rays per beam visit, batches of
    /// 4096 beams, seed 0, every beam of the file: `holodeck fill`'s defaults.
    fn default() -> FillOptions {
        FillOptions {
            rays: None,
            time: None,
            packet: 4,
            batch: 4096,
            seed: 0,
            views: None,
        }
    }
}

/// A fill limited to what some views see.
#[derive(Clone, Debug, Default)]
pub struct ViewFill {
    /// (beam, view rays in it), over all the views.
    pub seen: Vec<(BeamKey, u32)>,
    /// How to choose each beam's rays: near the eye of each view that sees
    /// it (Appendix A), with the view rays it has there; none: uniformly.
    pub modes: HashMap<BeamKey, Vec<(SamplingMode, u32)>>,
}

impl ViewFill {
    /// The beams `views` see in `sections`, one view ray per `stride` pixels
    /// of a 256 x 192 frame; new rays pass within `eye_radius` (a fraction
    /// of the smallest section diagonal) of the eyes that see their beam, or
    /// anywhere in it for 0.
    pub fn new(sections: &[Section], views: &[View], eye_radius: f64) -> ViewFill {
        let radius = holodeck_protocol::eye_radius(sections, eye_radius);
        let mut fill = ViewFill::default();
        for (i, v) in views.iter().enumerate() {
            let counts = ViewBeams::select(sections, v, 256, 192, i as u64).counts;
            if let Some(radius) = radius {
                let near = SamplingMode::NearEye {
                    eye: v.position.to_array(),
                    radius,
                    frustum: v.frustum(),
                };
                for &(k, n) in &counts {
                    fill.modes.entry(k).or_default().push((near, n));
                }
            }
            fill.seen.extend(counts);
        }
        fill
    }

    /// How to choose the rays of the `visit`th packet of `key`. A beam seen
    /// by several views takes its packets near each view's eye in turn, in
    /// proportion to the view rays each has in it: rays traced for another
    /// eye a step away see a glossy or glass surface from there, and a view
    /// made only of those shows highlights where its own eye sees none.
    pub fn mode(&self, key: BeamKey, visit: u64) -> SamplingMode {
        let Some(eyes) = self.modes.get(&key) else {
            return SamplingMode::Uniform;
        };
        let total: u64 = eyes.iter().map(|e| u64::from(e.1)).sum();
        // The golden-ratio sequence spreads the turns evenly at any count.
        let x = ((visit as f64 * 0.618_033_988_749_895).fract() * total as f64) as u64;
        let mut below = 0u64;
        for &(mode, n) in eyes {
            below += u64::from(n);
            if x < below {
                return mode;
            }
        }
        eyes.last().map_or(SamplingMode::Uniform, |e| e.0)
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
) -> Result<FillReport, crate::Error> {
    let sections = file.sections().to_vec();
    // The file's settings, not the tracer's options, decide how it is filled.
    let rules = FileRules {
        obstructions: file.settings().obstructions,
        vdistance: file.settings().vdistance,
    };
    let stored = |k| file.beam_len(k).unwrap_or(0);
    let mut schedule = match &o.views {
        Some(v) => BatchSchedule::for_views(&sections, &v.seen, stored),
        None => BatchSchedule::new(&sections, stored)?,
    };
    // A scene larger than a typical cache gets rounds big enough for the
    // cores to sort their shares of the paths. Which rays a seed gives
    // depends on the rounds, so they follow the scene and the options
    // alone, never this machine's cache or cores; whether the cores then
    // sort changes nothing in the records.
    let round_beams = if tracer.options.reorder != Reorder::Off && tracer.in_core_bytes() > LARGE_SCENE_BYTES {
        let per_beam = o.packet.max(1) as usize * tracer.options.samples.max(1) as usize;
        o.batch.max(LARGE_ROUND_PATHS.div_ceil(per_beam))
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
        // A beam's packets so far, from what the file holds: the turns
        // between eyes go on across fills.
        let packet = u64::from(o.packet.max(1));
        let modes: HashMap<BeamKey, SamplingMode> = match &o.views {
            Some(v) => batch
                .iter()
                .map(|&(k, _)| (k, v.mode(k, file.beam_len(k).unwrap_or(0) / packet)))
                .collect(),
            None => HashMap::new(),
        };
        let mode = |k: BeamKey| modes.get(&k).copied().unwrap_or(SamplingMode::Uniform);
        let traced = trace_batch(tracer, &sections, rules, &batch, &mode, o.seed ^ round.rotate_left(32));
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

#[cfg(test)]
mod tests {
    use super::*;

    fn eye(x: f32) -> SamplingMode {
        SamplingMode::NearEye {
            eye: [f64::from(x), 0.0, 0.0],
            radius: 0.01,
            frustum: None,
        }
    }

    /// A beam seen by two views, with three and one view rays: its packets
    /// go near each eye in turn, three to one, whatever the count so far.
    #[test]
    fn a_shared_beam_takes_packets_near_each_eye_by_its_share() {
        let k = BeamKey::new(0, 7);
        let mut fill = ViewFill::default();
        fill.modes.insert(k, vec![(eye(1.0), 3), (eye(2.0), 1)]);
        for visits in [4u64, 40, 400] {
            let first = (0..visits).filter(|&v| fill.mode(k, v) == eye(1.0)).count() as u64;
            let second = (0..visits).filter(|&v| fill.mode(k, v) == eye(2.0)).count() as u64;
            assert_eq!(first + second, visits);
            assert!(first.abs_diff(visits * 3 / 4) <= 1 + visits / 50, "{first} of {visits}");
        }
        // A beam no view sees is sampled uniformly.
        assert_eq!(fill.mode(BeamKey::new(0, 8), 0), SamplingMode::Uniform);
    }

    /// Two views 15 cm apart share most of their beams: after a fill for
    /// both, each finds rays passing within a millimetre of its own eye in
    /// every shared beam, about as many as the other (a fill that sent each
    /// beam's rays near one eye left the other view with the first's rays,
    /// 15 cm off, which show a glossy surface as seen from there).
    #[test]
    fn views_that_share_beams_each_get_rays_near_their_own_eye() {
        use holodeck_file::{OpenOptions, Settings};
        let input = crate::scene_input::SceneInput::open("builtin:room", None, None).unwrap();
        let sections = input.sections().to_vec();
        let tracer = input.tracer(holodeck_sampler::TraceOptions {
            max_bounces: 0,
            ..holodeck_sampler::TraceOptions::default()
        });
        let views: Vec<View> = ["1.5 2 1.5", "1.65 2 1.5"]
            .iter()
            .map(|p| View::parse(&format!("-vtv -vp {p} -vd 1 0.2 -0.1 -vu 0 0 1 -vh 60 -vv 45")).unwrap())
            .collect();
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("walk.hdk");
        let settings = Settings {
            sections: sections.clone(),
            ..Settings::default()
        };
        HoloFile::create(&path, &settings).unwrap();
        let mut file = HoloFile::open(&path, &OpenOptions::default()).unwrap();
        let views_fill = ViewFill::new(
            &sections,
            &views,
            holodeck_display::request::RequestOptions::default().eye_radius,
        );
        let shared: Vec<BeamKey> = views_fill
            .modes
            .iter()
            .filter(|(_, eyes)| eyes.len() == 2 && eyes.iter().all(|e| e.1 >= 4))
            .map(|(k, _)| *k)
            .collect();
        assert!(shared.len() > 50, "{} shared beams", shared.len());
        let o = FillOptions {
            rays: Some(40_000),
            time: None,
            packet: 8,
            batch: 1024,
            seed: 3,
            views: Some(views_fill),
        };
        fill(&tracer, &mut file, &o, &|_| {}).unwrap();
        let decoder = holodeck_display::SampleDecoder::new(sections);
        // Per shared beam of eight rays or more: rays near each eye.
        let (mut both, mut beams, mut near_all) = (0u32, 0u32, [0u64; 2]);
        file.read_beams(&shared, |k, rays| {
            let mut near = [0u64; 2];
            for s in decoder.samples(k.section, k.beam, rays).into_iter().flatten() {
                for (n, v) in near.iter_mut().zip(&views) {
                    let to_eye = v.position - s.origin;
                    if (to_eye - s.direction * to_eye.dot(s.direction)).length() < 0.001 {
                        *n += 1;
                    }
                }
            }
            if rays.len() >= 8 {
                beams += 1;
                both += u32::from(near[0] > 0 && near[1] > 0);
            }
            near_all[0] += near[0];
            near_all[1] += near[1];
        })
        .unwrap();
        assert!(beams > 20, "{beams} shared beams of eight rays");
        assert!(
            both * 10 >= beams * 8,
            "{both} of {beams} shared beams hold rays near both eyes"
        );
        let (a, b) = (near_all[0] as f64, near_all[1] as f64);
        assert!(a.min(b) > 0.5 * a.max(b), "rays near each eye: {near_all:?}");
    }
}
