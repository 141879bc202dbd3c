//! From a viewport to beam requests (paper, 2.4.2): which beams the view sees
//! and how many samples each should get so the image refines uniformly, with
//! the eye point that new samples should pass near (Appendix A).

use holodeck_protocol::wire::EyePoint;
use holodeck_protocol::{BeamKey, Section, ViewBeams};

use crate::driver::Viewport;

/// How a display asks for samples.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RequestOptions {
    /// Samples wanted per pixel at convergence (the paper aims at about one).
    pub density: f64,
    /// One view ray per this many pixels across (and down) for beam selection.
    pub stride: u32,
    /// New samples should pass this near the eye, as a fraction of the
    /// smallest section diagonal (0: uniform sampling).
    pub eye_radius: f64,
}

impl Default for RequestOptions {
    fn default() -> Self {
        RequestOptions {
            density: 1.0,
            stride: 8,
            eye_radius: 0.01,
        }
    }
}

/// What to ask the server for, for one view.
#[derive(Clone, Debug, PartialEq)]
pub struct BeamRequest {
    /// (beam, samples wanted in total), by beam.
    pub beams: Vec<(BeamKey, u32)>,
    /// The eye, for proximity sampling.
    pub eye: Option<EyePoint>,
    /// The selection behind it.
    pub seen: ViewBeams,
}

impl BeamRequest {
    /// Selects the beams `viewport` sees in `sections`. A view outside every
    /// section still gets the beams whose lines it looks along; a view whose
    /// lines cross no section gets an empty request.
    pub fn for_viewport(sections: &[Section], viewport: &Viewport, o: &RequestOptions, seed: u64) -> BeamRequest {
        let stride = o.stride.max(1);
        let columns = viewport.width.div_ceil(stride).clamp(4, 1024);
        let rows = viewport.height.div_ceil(stride).clamp(3, 1024);
        let seen = ViewBeams::select(sections, &viewport.view, columns, rows, seed);
        let pixels = f64::from(viewport.width) * f64::from(viewport.height);
        let beams = seen.desired((pixels * o.density.max(0.0)).ceil() as u64);
        let smallest = sections.iter().map(Section::diagonal).fold(f64::INFINITY, f64::min);
        let radius = o.eye_radius * smallest;
        let eye = (radius.is_finite() && radius > 0.0).then(|| EyePoint {
            position: viewport.view.position.to_array(),
            radius,
        });
        BeamRequest { beams, eye, seen }
    }

    /// Samples wanted in all.
    pub fn total(&self) -> u64 {
        self.beams.iter().map(|b| u64::from(b.1)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use holodeck_protocol::{SectionKind, View};

    fn room() -> Section {
        Section::new(
            [0.0; 3],
            [[4.0, 0.0, 0.0], [0.0, 3.0, 0.0], [0.0, 0.0, 2.0]],
            [16, 12, 8],
            SectionKind::Interior,
        )
        .unwrap()
    }

    #[test]
    fn a_view_asks_for_about_one_sample_per_pixel_in_the_beams_it_sees() {
        let s = room();
        let v = View::parse("-vtv -vp 2 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45").unwrap();
        let vp = Viewport::new(v, 320, 240).unwrap();
        let r = BeamRequest::for_viewport(std::slice::from_ref(&s), &vp, &RequestOptions::default(), 1);
        assert_eq!(r.seen.rays, 40 * 30);
        let total = r.total();
        // Rounding up per beam adds at most one per beam.
        assert!(
            total >= 320 * 240 && total <= 320 * 240 + r.beams.len() as u64,
            "{total}"
        );
        let eye = r.eye.unwrap();
        assert_eq!(eye.position, [2.0, 1.5, 1.0]);
        assert!((eye.radius - 0.01 * s.diagonal()).abs() < 1e-12);
    }

    #[test]
    fn views_that_see_no_section_ask_for_nothing_and_uniform_requests_have_no_eye() {
        let s = room();
        let v = View::parse("-vtv -vp 50 50 50 -vd 0 0 1 -vu 0 1 0 -vh 10 -vv 10").unwrap();
        let vp = Viewport::new(v, 64, 64).unwrap();
        let o = RequestOptions {
            eye_radius: 0.0,
            ..RequestOptions::default()
        };
        let r = BeamRequest::for_viewport(std::slice::from_ref(&s), &vp, &o, 1);
        assert!(r.beams.is_empty());
        assert_eq!(r.eye, None);
        assert_eq!(r.total(), 0);
    }
}
