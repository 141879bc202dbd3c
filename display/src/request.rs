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
            eye_radius: 0.0005,
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
        BeamRequest {
            beams,
            eye: eye_point(sections, viewport, o),
            seen,
        }
    }

    /// A request that refines what a display holds: `want` says how many
    /// more rays each pixel wants (row-major, from [`crate::Driver::needs`]),
    /// `have` how many rays of each beam the display was given; each beam
    /// asks for what it has plus its share of the pixels' wants, so the
    /// server traces only that share, where the picture needs it.
    pub fn refining(
        sections: &[Section],
        viewport: &Viewport,
        o: &RequestOptions,
        seed: u64,
        want: &[f32],
        have: &dyn Fn(BeamKey) -> u64,
    ) -> BeamRequest {
        let stride = o.stride.max(1);
        let columns = viewport.width.div_ceil(stride).clamp(4, 1024);
        let rows = viewport.height.div_ceil(stride).clamp(3, 1024);
        let (w, h) = (viewport.width as usize, viewport.height as usize);
        let at = |x: f64, y: f64| {
            let col = ((x * w as f64) as usize).min(w - 1);
            let row = (((1.0 - y) * h as f64) as usize).min(h - 1);
            want.get(row * w + col).map_or(1.0, |&v| f64::from(v))
        };
        let seen = ViewBeams::select_weighted(sections, &viewport.view, columns, rows, seed, at);
        let wanted: f64 = want.iter().map(|&v| f64::from(v)).sum();
        let more = if wanted > 0.0 {
            seen.desired(wanted.ceil() as u64)
        } else {
            Vec::new()
        };
        let more: std::collections::HashMap<BeamKey, u32> = more.into_iter().collect();
        let beams = seen
            .counts
            .iter()
            .map(|&(k, _)| {
                let n = have(k) + u64::from(more.get(&k).copied().unwrap_or(0));
                (k, n.min(u64::from(u32::MAX)) as u32)
            })
            .collect();
        BeamRequest {
            beams,
            eye: eye_point(sections, viewport, o),
            seen,
        }
    }

    /// Samples wanted in all.
    pub fn total(&self) -> u64 {
        self.beams.iter().map(|b| u64::from(b.1)).sum()
    }
}

/// Keeps a still view converging: once most of what was last asked for has
/// arrived (or nothing came for a while: the server has it all), the view's
/// density is doubled, so samplers go on refining what people look at before
/// they fill the rest of the holodeck by volume. A new view starts over.
#[derive(Clone, Debug, PartialEq)]
pub struct Refinement {
    density: f64,
    max: f64,
    asked: u64,
}

impl Refinement {
    /// Starts at `density` samples per pixel and never asks for more than `max`.
    pub fn new(density: f64, max: f64) -> Refinement {
        Refinement {
            density,
            max: max.max(density),
            asked: 0,
        }
    }

    /// The density asked for now.
    pub fn density(&self) -> f64 {
        self.density
    }

    /// Records a request for `rays` more rays than the display holds.
    pub fn asked(&mut self, rays: u64) {
        self.asked = rays;
    }

    /// The density to ask for next, if it is time to raise it: `outstanding`
    /// is how many of the rays last asked for have not arrived, `quiet` says
    /// nothing arrived lately.
    pub fn raise(&mut self, outstanding: u64, quiet: bool) -> Option<f64> {
        let met = outstanding as f64 <= 0.1 * self.asked as f64;
        if (met || quiet) && self.density < self.max {
            self.density = (self.density * 2.0).min(self.max);
            return Some(self.density);
        }
        None
    }
}

/// Rays `request` asks for beyond what `have` says the display holds.
pub fn outstanding(request: &BeamRequest, have: &dyn Fn(BeamKey) -> u64) -> u64 {
    request
        .beams
        .iter()
        .map(|&(k, n)| u64::from(n).saturating_sub(have(k)))
        .sum()
}

/// Where new rays should pass: near the eye, in its frame.
fn eye_point(sections: &[Section], viewport: &Viewport, o: &RequestOptions) -> Option<EyePoint> {
    holodeck_protocol::eye_radius(sections, o.eye_radius).map(|radius| EyePoint {
        position: viewport.view.position.to_array(),
        radius,
        frustum: viewport.view.frustum(),
    })
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
        assert!((eye.radius - RequestOptions::default().eye_radius * s.diagonal()).abs() < 1e-12);
        assert!(eye.frustum.is_some());
    }

    #[test]
    fn a_still_view_doubles_its_density_as_samples_arrive_up_to_the_limit() {
        let mut r = Refinement::new(1.0, 5.0);
        r.asked(1000);
        assert_eq!(r.raise(1000, false), None, "nothing arrived yet");
        assert_eq!(r.raise(101, false), None);
        assert_eq!(r.raise(100, false), Some(2.0));
        r.asked(2000);
        assert_eq!(r.raise(2000, false), None);
        // The server had nothing more to send: ask for more anyway.
        assert_eq!(r.raise(2000, true), Some(4.0));
        assert_eq!(r.raise(0, true), Some(5.0));
        assert_eq!(r.raise(0, true), None, "never past the limit");
        assert_eq!(r.density(), 5.0);
    }

    #[test]
    fn a_refining_request_asks_for_what_the_pixels_want_beyond_what_is_held() {
        let s = room();
        let v = View::parse("-vtv -vp 2 1.5 1 -vd 1 0 0 -vu 0 0 1 -vh 60 -vv 45").unwrap();
        let vp = Viewport::new(v, 64, 48).unwrap();
        let o = RequestOptions::default();
        // The right half wants 8 rays a pixel, the left nothing; every beam
        // already holds 10.
        let want: Vec<f32> = (0..64 * 48).map(|i| if i % 64 >= 32 { 8.0 } else { 0.0 }).collect();
        let r = BeamRequest::refining(std::slice::from_ref(&s), &vp, &o, 1, &want, &|_| 10);
        let more = outstanding(&r, &|_| 10);
        let total = 8 * 32 * 48;
        assert!(more >= total && more <= total + r.beams.len() as u64, "{more}");
        assert!(r.beams.iter().all(|b| b.1 >= 10));
        // Nothing wanted: nothing more asked (but a ray a beam for rounding).
        let none = BeamRequest::refining(std::slice::from_ref(&s), &vp, &o, 1, &vec![0.0; 64 * 48], &|_| 10);
        assert_eq!(outstanding(&none, &|_| 10), 0);
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
