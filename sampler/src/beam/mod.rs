//! Ray generation within beams: which rays of a beam to trace, and how a traced
//! ray becomes a 10-byte record.
//!
//! Uniform sampling picks four random sub-cell bytes (the paper's batch mode).
//! Viewpoint-proximity sampling (Appendix A) picks rays that pass near an eye
//! point, so an interactive display converges faster.

mod proximity;

pub use proximity::{proximity_rays, ProximityStats};

use glam::DVec3;
use holodeck_protocol::wire::SamplingMode;
use holodeck_protocol::{BeamIndex, BeamRay, DepthCode, RayRecord, Rgbe, Section, SectionError, SectionKind};

use crate::ooc::Fetch;
use crate::shade::{Rng, Tracer};

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
    let start = trace_start(section.kind(), rules.obstructions, &s.ray);
    let origin: DVec3 = s.ray.origin + s.ray.direction * start;
    let sample = tracer.trace_fetching(origin.as_vec3(), s.ray.direction.as_vec3(), rules.vdistance, rng, fetch);
    let depth = if sample.distance.is_finite() {
        DepthCode::encode(start + f64::from(sample.distance), section.diagonal())
    } else {
        DepthCode::INFINITE
    };
    RayRecord::new(s.entry, s.exit, Rgbe::from_rgb(sample.radiance.to_array()), depth)
}

/// Chooses `n` rays of `beam` as `mode` says (uniformly, or near an eye)
/// and traces them into records: a sampler's whole job for one packet.
pub fn trace_beam(
    tracer: &Tracer,
    section: &Section,
    obstructions: bool,
    beam: BeamIndex,
    n: usize,
    mode: SamplingMode,
    rng: &mut Rng,
) -> Result<Vec<RayRecord>, SectionError> {
    let rules = FileRules {
        obstructions,
        vdistance: tracer.options.vdistance,
    };
    trace_beam_under(tracer, section, rules, beam, n, mode, rng)
}

/// [`trace_beam`] under a file's rules (a networked sampler's, from the
/// server's welcome).
pub fn trace_beam_under(
    tracer: &Tracer,
    section: &Section,
    rules: FileRules,
    beam: BeamIndex,
    n: usize,
    mode: SamplingMode,
    rng: &mut Rng,
) -> Result<Vec<RayRecord>, SectionError> {
    let samples = match mode {
        SamplingMode::Uniform => uniform_rays(section, beam, n, rng)?,
        SamplingMode::NearEye { eye, radius, frustum } => {
            proximity_rays(section, beam, n, DVec3::from(eye), radius, frustum.as_ref(), rng)?.0
        }
    };
    // Out of core, a ray that met missing data is traced again: no record
    // made from a stand-in for missing geometry is ever returned.
    Ok(tracer.trace_batch(samples.len(), rng, |k, rng, fetch| {
        trace_sample_fetching(tracer, section, rules, &samples[k], rng, fetch)
    }))
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
