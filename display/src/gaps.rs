//! Pixels a view's beams leave without a ray, and the beams next to the
//! ones their view rays pass through: where a sparse file has nothing for a
//! pixel, the rays of the neighbouring beams pass near the eye and can fill
//! it, as Radiance's rhpict does (only pixels without a ray take them; see
//! [`crate::Driver::add_beams_where_empty`]).

use holodeck_protocol::{BeamKey, Section};

use crate::Viewport;

/// How many pixels of `empty` are empty.
pub fn count(empty: &[bool]) -> u64 {
    empty.iter().filter(|e| **e).count() as u64
}

/// The beams next to those that the view's rays through the centres of
/// the pixels without a ray (`empty`, row-major, top row first) pass
/// through, less the beams already given (`given`, sorted), sorted.
pub fn neighbour_beams(sections: &[Section], viewport: &Viewport, empty: &[bool], given: &[BeamKey]) -> Vec<BeamKey> {
    let (w, h) = (viewport.width as usize, viewport.height as usize);
    let rays = viewport.view.rays();
    let around = holodeck_protocol::select::usable_sections(sections, viewport.view.position);
    let mut through: Vec<BeamKey> = Vec::new();
    for (p, _) in empty.iter().enumerate().filter(|(_, e)| **e) {
        // The view's y runs bottom to top; the frame's rows top to bottom.
        let x = ((p % w) as f64 + 0.5) / w as f64;
        let y = 1.0 - ((p / w) as f64 + 0.5) / h as f64;
        let Some((origin, dir)) = rays.ray(x, y) else { continue };
        for &si in &around {
            if let Some(at) = sections[si].locate(origin, dir) {
                through.push(BeamKey::new(si as u32, at.beam));
            }
        }
    }
    through.sort_unstable();
    through.dedup();
    let mut near: Vec<BeamKey> = through
        .iter()
        .flat_map(|k| {
            sections
                .get(k.section as usize)
                .and_then(|s| s.neighbour_beams(k.beam).ok())
                .unwrap_or_default()
                .into_iter()
                .map(move |b| BeamKey::new(k.section, b))
        })
        .filter(|k| given.binary_search(k).is_err())
        .collect();
    near.sort_unstable();
    near.dedup();
    near
}
