//! Ray generation within beams: which rays of a beam to trace, and how a traced
//! ray becomes a 10-byte record.
//!
//! Uniform sampling picks four random sub-cell bytes (the paper's batch mode).
//! Viewpoint-proximity sampling (Appendix A) picks rays that pass near an eye
//! point, so an interactive display converges faster.

mod batch;
mod proximity;

pub use batch::{trace_batch, trace_samples};
pub(crate) use batch::{trace_tasks, BeamTask};
pub use proximity::{proximity_rays, ProximityStats};

use glam::{DVec3, Vec3};
use holodeck_protocol::{BeamIndex, BeamRay, DepthCode, RayRecord, Rgbe, Section, SectionError, SectionKind};

use crate::ooc::Fetch;
use crate::shade::{Rng, Sample, Tracer};

/// One ray of a beam to trace: its sub-cell bytes and its world geometry.
#[derive(Clone, Copy, Debug)]
pub struct BeamSample {
    /// Sub-cell position in the entry cell.
    pub entry: [u8; 2],
    /// Sub-cell position in the exit cell.
    pub exit: [u8; 2],
    /// The ray from the entry wall through the exit cell.
    pub ray: BeamRay,
}

/// `n` rays spread uniformly over a beam's cells.
pub fn uniform_rays(
    section: &Section,
    beam: BeamIndex,
    n: usize,
    rng: &mut Rng,
) -> Result<Vec<BeamSample>, SectionError> {
    (0..n)
        .map(|_| {
            let b = rng.next_u32().to_le_bytes();
            let (entry, exit) = ([b[0], b[1]], [b[2], b[3]]);
            Ok(BeamSample {
                entry,
                exit,
                ray: section.beam_ray(beam, entry, exit)?,
            })
        })
        .collect()
}

/// Where tracing starts along a beam ray, in world units from the entry wall.
/// Interior sections are looked out of: geometry lies outside, so rays start at
/// the exit wall unless the section may contain obstructions. Exterior
/// sections are looked into, so rays start at the entry wall.
pub fn trace_start(kind: SectionKind, obstructions: bool, ray: &BeamRay) -> f64 {
    match kind {
        SectionKind::Interior if !obstructions => ray.length,
        _ => 0.0,
    }
}

/// The settings of a holodeck file that every sampler filling it must obey,
/// whatever its own tracer options say.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FileRules {
    /// Sections may contain geometry: trace from the entry wall.
    pub obstructions: bool,
    /// Record virtual distances through flat mirrors and thin glass.
    pub vdistance: bool,
}

/// Traces one beam sample and encodes it: radiance and the distance from the
/// entry wall to the first hit (or infinity).
pub fn trace_sample(
    tracer: &Tracer,
    section: &Section,
    obstructions: bool,
    s: &BeamSample,
    rng: &mut Rng,
) -> RayRecord {
    let rules = FileRules {
        obstructions,
        vdistance: tracer.options.vdistance,
    };
    trace_sample_under(tracer, section, rules, s, rng)
}

/// [`trace_sample`] under a file's rules.
pub fn trace_sample_under(
    tracer: &Tracer,
    section: &Section,
    rules: FileRules,
    s: &BeamSample,
    rng: &mut Rng,
) -> RayRecord {
    trace_sample_fetching(tracer, section, rules, s, rng, &mut Fetch::load())
}

/// [`trace_sample_under`] with out-of-core data fetched as `fetch` says; a
/// record whose `fetch.missed` comes back true must be traced again.
pub fn trace_sample_fetching(
    tracer: &Tracer,
    section: &Section,
    rules: FileRules,
    s: &BeamSample,
    rng: &mut Rng,
    fetch: &mut Fetch,
) -> RayRecord {
    let (start, origin, dir) = traced_ray(section, rules, s);
    let sample = tracer.trace_with(origin, dir, rules.vdistance, rng, fetch);
    encode(section, s, start, &sample)
}

/// Where the traced part of a beam sample's ray starts (in world units from
/// the entry wall), its origin there and its direction.
pub fn traced_ray(section: &Section, rules: FileRules, s: &BeamSample) -> (f64, Vec3, Vec3) {
    let start = trace_start(section.kind(), rules.obstructions, &s.ray);
    let origin: DVec3 = s.ray.origin + s.ray.direction * start;
    (start, origin.as_vec3(), s.ray.direction.as_vec3())
}

/// The record of a beam sample traced from `start`: radiance, and the
/// distance from the entry wall to the first hit (or infinity).
fn encode(section: &Section, s: &BeamSample, start: f64, sample: &Sample) -> RayRecord {
    let depth = if sample.distance.is_finite() {
        section.encode_depth(start + f64::from(sample.distance))
    } else {
        DepthCode::INFINITE
    };
    RayRecord::new(s.entry, s.exit, Rgbe::from_rgb(sample.radiance.to_array()), depth)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::shade::FirstHits;

    #[test]
    fn uniform_rays_belong_to_their_beam() {
        let s = Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [4, 3, 2],
            SectionKind::Interior,
        )
        .unwrap();
        let mut rng = Rng::new(1, 2);
        for beam in (0..s.beam_count()).step_by(37) {
            for r in uniform_rays(&s, beam, 20, &mut rng).unwrap() {
                let found = s.locate(r.ray.origin, r.ray.direction).unwrap();
                assert_eq!((found.beam, found.entry_sub, found.exit_sub), (beam, r.entry, r.exit));
                assert_eq!(trace_start(SectionKind::Interior, false, &r.ray), r.ray.length);
                assert_eq!(trace_start(SectionKind::Exterior, false, &r.ray), 0.0);
            }
        }
        assert!(uniform_rays(&s, s.beam_count(), 1, &mut rng).is_err());
    }

    /// Finding a beam's first hits in packets, or once for all the
    /// estimates along a ray, or tracing the paths a segment at a time in
    /// any order, changes no record: every record equals the one made ray
    /// by ray with each estimate walking from the start.
    #[test]
    fn first_hits_in_packets_change_no_record() {
        use crate::scene::{generate, GenParams};
        use crate::{Reorder, TraceOptions};
        let scene = generate("room", &GenParams::default()).unwrap();
        let sections = scene.sections.clone();
        let mut tracer = Tracer::new(
            scene,
            TraceOptions {
                samples: 3,
                ..TraceOptions::default()
            },
        );
        let (mut records, mut hits) = (0, 0);
        for (i, section) in sections.iter().enumerate() {
            for obstructions in [false, true] {
                let rules = FileRules {
                    obstructions,
                    vdistance: i % 2 == 0,
                };
                for beam in (0..section.beam_count()).step_by(97) {
                    let n = 1 + (beam as usize % 21);
                    let samples = uniform_rays(section, beam, n, &mut Rng::new(5, beam.into())).unwrap();
                    let mut want = Vec::new();
                    let seed = crate::shade::batch_seed(&mut Rng::new(6, beam.into()));
                    for (k, s) in samples.iter().enumerate() {
                        // The estimates one by one, each walking from the start as before.
                        let (start, origin, dir) = traced_ray(section, rules, s);
                        let mut fetch = Fetch::load();
                        let mut sum = Vec3::ZERO;
                        let mut distance = 0.0;
                        for j in 0..3 {
                            // Each estimate draws from its own stream.
                            let mut rng = Rng::new(seed, k as u64 * 3 + j);
                            let (l, d) =
                                tracer.estimate_walking(origin, dir.normalize(), rules.vdistance, &mut rng, &mut fetch);
                            sum += l;
                            if j == 0 {
                                distance = d;
                            }
                        }
                        let sample = Sample {
                            radiance: sum / 3.0,
                            distance,
                        };
                        want.push(encode(section, s, start, &sample));
                    }
                    for first in [FirstHits::Packets, FirstHits::Single, FirstHits::Measured] {
                        for reorder in [Reorder::Off, Reorder::HitPoint, Reorder::Origin] {
                            tracer.options.reorder = reorder;
                            let got =
                                trace_samples(&tracer, section, rules, &samples, first, &mut Rng::new(6, beam.into()));
                            assert_eq!(got, want, "section {i} beam {beam} {first:?} {reorder:?}");
                        }
                    }
                    records += want.len();
                    hits += want.iter().filter(|r| r.depth_code() != DepthCode::INFINITE).count();
                }
            }
        }
        assert!(records > 1000 && hits > records / 2, "{records} records, {hits} hit");
    }
}
