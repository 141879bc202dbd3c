//! Samples as displays see them: a decoded ray with its world hit point, so
//! that the same sample can be reprojected into any nearby view.

use glam::DVec3;
use holodeck_protocol::{BeamDecoder, BeamIndex, Hit, RayRecord, Section};

/// One ray sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// A point on the ray: where it entered its section.
    pub origin: DVec3,
    /// Unit direction the ray was traced in (away from the eye that sees it).
    pub direction: DVec3,
    /// First surface hit in world coordinates; `None` when the ray escaped and
    /// the sample lies at infinity along `direction`.
    pub hit: Option<DVec3>,
    /// Linear RGB radiance.
    pub color: [f32; 3],
}

impl Sample {
    /// Distance from `eye` to the ray's line: the smaller, the better the sample
    /// stands for what an eye there sees (paper, 2.4.2).
    pub fn miss_distance(&self, eye: DVec3) -> f64 {
        (eye - self.origin).cross(self.direction).length()
    }

    /// True when every number in it is finite (a broken sampler may send NaN or
    /// infinite radiance; drivers reject such samples and count them).
    pub fn is_finite(&self) -> bool {
        self.origin.is_finite()
            && self.direction.is_finite()
            && self.hit.is_none_or(|h| h.is_finite())
            && self.color.iter().all(|c| c.is_finite())
    }

    /// The point to reproject: the hit, or a point far along the direction from
    /// `eye` for rays that escaped (so that they stay put under translation).
    pub fn target(&self, eye: DVec3) -> DVec3 {
        match self.hit {
            Some(h) => h,
            None => eye + self.direction * 1e9,
        }
    }
}

/// Decodes records of one section's beams into samples.
#[derive(Clone, Debug)]
pub struct SampleDecoder {
    sections: Vec<Section>,
}

impl SampleDecoder {
    /// A decoder for the holodeck's sections, in index order.
    pub fn new(sections: Vec<Section>) -> SampleDecoder {
        SampleDecoder { sections }
    }

    /// The sections.
    pub fn sections(&self) -> &[Section] {
        &self.sections
    }

    /// The samples of `records` of one beam, lazily (for parallel decoding
    /// into a reused buffer); `None` for an unknown section or beam.
    pub fn samples<'a>(
        &self,
        section: u32,
        beam: BeamIndex,
        records: &'a [RayRecord],
    ) -> Option<impl Iterator<Item = Sample> + 'a> {
        let d = self.beam(section, beam)?;
        Some(records.iter().map(move |r| SampleDecoder::sample(&d, r)))
    }

    /// The decoder of one beam's records; `None` for an unknown section or
    /// beam.
    pub fn beam(&self, section: u32, beam: BeamIndex) -> Option<BeamDecoder> {
        self.sections.get(section as usize)?.beam_decoder(beam).ok()
    }

    /// The sample of one record of the beam `d` decodes.
    #[inline]
    pub fn sample(d: &BeamDecoder, r: &RayRecord) -> Sample {
        let ray = d.decode(r);
        Sample {
            origin: ray.ray.origin,
            direction: ray.ray.direction,
            hit: match ray.hit {
                Hit::Point(p) => Some(p),
                Hit::Infinite => None,
            },
            color: ray.color,
        }
    }

    /// Appends the samples of `records` (all of beam `beam` of section
    /// `section`) to `out`. Returns the records that could not be decoded
    /// (unknown section or beam): the caller counts them.
    pub fn decode(&self, section: u32, beam: BeamIndex, records: &[RayRecord], out: &mut Vec<Sample>) -> usize {
        match self.samples(section, beam, records) {
            Some(samples) => {
                out.extend(samples);
                0
            }
            None => records.len(),
        }
    }
}
