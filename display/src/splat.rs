//! The benchmark baseline: plain point splatting. Each sample is written to
//! the pixel it reprojects to and nothing fills the gaps, so what it costs and
//! how it looks is the floor the quadtree and the GPU drivers are measured
//! against.
//!
//! It keeps samples by the same rules as the quadtree (closest miss per pixel,
//! the same counters, the same cache drop after a large turn), so the two
//! differ only in reconstruction.

use glam::Vec3;
use holodeck_protocol::Picture;

use crate::driver::{Driver, DriverStats, Viewport};
use crate::quadtree::{Entry, PixelIndex, Spot, Store};
use crate::sample::Sample;

/// A pixel without a sample.
const EMPTY: u32 = u32::MAX;

/// One sample slot per pixel, row-major from the top: the key of a pixel is
/// its position here.
#[derive(Clone, Debug, Default)]
struct Grid {
    slots: Vec<u32>,
    width: u32,
}

impl PixelIndex for Grid {
    fn reset(&mut self, width: u32, height: u32) {
        let n = width as usize * height as usize;
        self.slots.clear();
        self.slots.resize(n, EMPTY);
        self.width = width;
    }

    #[inline]
    fn key(&self, col: u32, row: u32) -> u64 {
        u64::from(row) * u64::from(self.width) + u64::from(col)
    }

    fn key_bits(&self) -> u32 {
        64 - (self.slots.len() as u64).saturating_sub(1).leading_zeros()
    }

    #[inline]
    fn find(&mut self, _entries: &[Entry], key: u64) -> Spot {
        let at = key as usize;
        match self.slots[at] {
            EMPTY => Spot::Free(at),
            slot => Spot::Taken(slot),
        }
    }

    #[inline]
    fn fill(&mut self, at: usize, slot: u32) {
        self.slots[at] = slot;
    }
}

/// The point-splat baseline driver: each pixel shows the sample on it whose
/// ray passed closest to the eye, or black.
///
/// Samples that a view change moves off the frame are forgotten (unlike the
/// quadtree, which keeps them for a turn back): the baseline stays minimal.
#[derive(Clone, Debug)]
pub struct SplatDriver {
    store: Store<Grid>,
}

impl SplatDriver {
    /// An empty driver for `viewport`.
    pub fn new(viewport: Viewport) -> SplatDriver {
        SplatDriver {
            store: Store::new(viewport, Grid::default(), false),
        }
    }
}

impl Driver for SplatDriver {
    fn name(&self) -> &'static str {
        "splat"
    }

    fn add(&mut self, samples: &[Sample]) {
        self.store.add(samples);
    }

    fn set_view(&mut self, viewport: Viewport) {
        self.store.set_view(viewport);
    }

    fn viewport(&self) -> &Viewport {
        &self.store.viewport
    }

    fn render(&mut self) -> Picture {
        let entries = &self.store.entries;
        let pixels = self
            .store
            .index
            .slots
            .iter()
            .map(|&slot| match slot {
                EMPTY => Vec3::ZERO,
                s => Vec3::from_array(entries[s as usize].color),
            })
            .collect();
        Picture {
            width: self.store.viewport.width as usize,
            height: self.store.viewport.height as usize,
            pixels,
        }
    }

    fn stats(&self) -> DriverStats {
        self.store.stats()
    }

    fn clear(&mut self) {
        self.store.clear();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::quadtree::testkit::*;
    use glam::DVec3;
    use std::collections::HashMap;

    #[test]
    fn splat_pixels_equal_the_inserted_colors() {
        let vp = viewport(EYE_VIEW, 96, 64);
        let samples = random_plane_samples(&vp.view, 2000, 21);
        let mut d = SplatDriver::new(vp.clone());
        d.add(&samples);
        let eye = vp.view.position;
        let mut best: HashMap<usize, Sample> = HashMap::new();
        for s in &samples {
            let (c, r, _) = vp.pixel(s.target(eye)).unwrap();
            let e = best.entry(r as usize * 96 + c as usize).or_insert(*s);
            if s.miss_distance(eye) < e.miss_distance(eye) {
                *e = *s;
            }
        }
        let pic = d.render();
        assert_eq!((pic.width, pic.height), (96, 64));
        for (i, p) in pic.pixels.iter().enumerate() {
            match best.get(&i) {
                Some(s) => assert_eq!(p.to_array(), s.color, "pixel {i}"),
                None => assert_eq!(*p, Vec3::ZERO, "pixel {i} has no sample"),
            }
        }
        assert_eq!(d.stats().kept, best.len() as u64);
        assert_eq!(d.name(), "splat");
    }

    #[test]
    fn splat_keeps_the_closest_miss_with_exact_counters() {
        let mut d = SplatDriver::new(grid_viewport(4, 4));
        d.add(&[
            grid_sample(4, 4, 2.0, 2.0, 1.0, 0.3, [1.0; 3]),
            grid_sample(4, 4, 2.5, 2.5, 2.0, 0.2, [2.0; 3]),
            grid_sample(4, 4, 2.9, 2.9, 1.01, 0.25, [3.0; 3]),
            grid_sample(4, 4, 0.5, 0.5, 1.0, 0.3, [4.0; 3]),
            grid_sample(4, 4, 9.0, 0.5, 1.0, 0.3, [5.0; 3]),
        ]);
        let st = d.stats();
        assert_eq!(
            (
                st.received,
                st.kept,
                st.replaced,
                st.discarded,
                st.multidepth,
                st.outside
            ),
            (5, 2, 1, 1, 2, 1)
        );
        let pic = d.render();
        assert_eq!(pic.pixels[2 * 4 + 2], Vec3::splat(2.0));
        assert_eq!(pic.pixels[0], Vec3::splat(4.0));
        assert_eq!(pic.pixels.iter().filter(|&&p| p == Vec3::ZERO).count(), 14);
    }

    #[test]
    fn splat_rejects_nonfinite_and_handles_views() {
        let vp = viewport(EYE_VIEW, 1, 1);
        let mut d = SplatDriver::new(vp.clone());
        let mut samples = random_plane_samples(&vp.view, 10, 3);
        samples[4].color[1] = f32::NAN;
        samples[7].hit = Some(DVec3::new(f64::INFINITY, 0.0, 0.0));
        d.add(&samples);
        assert_eq!((d.stats().rejected_nonfinite, d.stats().kept), (2, 1));
        // A small turn keeps (or loses off-frame) samples; a large one drops them.
        let (s, c) = 40f64.to_radians().sin_cos();
        d.set_view(viewport(&format!("{EYE_VIEW} -vd {s} {c} 0"), 1, 1));
        assert_eq!((d.stats().cache_drops, d.stats().kept), (1, 0));
        assert_eq!(d.render().pixels, vec![Vec3::ZERO]);
        d.clear();
        assert_eq!(d.viewport().width, 1);
    }

    /// Release-mode timing, as the quadtree's: `cargo test --release -p
    /// holodeck-display --lib splat -- --ignored --nocapture --test-threads=1`.
    #[test]
    #[ignore]
    fn timing_splat_one_million_samples_at_1024x768() {
        time_driver(|vp| Box::new(SplatDriver::new(vp)));
    }
}
