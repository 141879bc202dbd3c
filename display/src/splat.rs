//! The benchmark baseline: plain point splatting. Each pixel shows the
//! estimate of the rays that land on it and nothing fills the gaps, so what
//! it costs and how it looks is the floor the quadtree and the GPU drivers
//! are measured against.
//!
//! It keeps estimates in the same [`Store`] as the quadtree (same rules, same
//! counters, the same drop after a large turn), so the two differ only in
//! reconstruction.

use glam::Vec3;
use holodeck_protocol::Picture;

use crate::driver::{Driver, Viewport};
use crate::store::{Entry, EstimatorOptions, PixelIndex, Spot, Store};

/// A pixel without an estimate.
const EMPTY: u32 = u32::MAX;

/// One estimate slot per pixel, row-major from the top: the key of a pixel
/// is its position here.
#[derive(Clone, Debug, Default)]
pub struct Grid {
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

    #[inline]
    fn pixel(&self, key: u64) -> (u32, u32) {
        let w = u64::from(self.width.max(1));
        ((key % w) as u32, (key / w) as u32)
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

    fn heap_bytes(&self) -> usize {
        self.slots.capacity() * std::mem::size_of::<u32>()
    }

    #[inline]
    fn block(&self, key: u64, shift: u32) -> usize {
        let w = u64::from(self.width.max(1));
        let (col, row) = (key % w, key / w);
        ((row >> shift) * (w >> shift).max(1) + (col >> shift)) as usize
    }

    fn blocks(&self, shift: u32) -> usize {
        let w = self.width.max(1) as usize;
        let h = self.slots.len() / w;
        (w >> shift).max(1) * (h >> shift).max(1)
    }
}

/// The point-splat baseline driver: each pixel shows the estimate of the
/// rays on it, or black.
///
/// Estimates that a view change moves off the frame are forgotten (unlike
/// the quadtree, which keeps them for a turn back): the baseline stays minimal.
#[derive(Clone, Debug)]
pub struct SplatDriver {
    store: Store<Grid>,
}

impl SplatDriver {
    /// An empty driver for `viewport`.
    pub fn new(viewport: Viewport) -> SplatDriver {
        SplatDriver::with_options(viewport, EstimatorOptions::default())
    }

    /// An empty driver whose pixels combine rays as `options` say.
    pub fn with_options(viewport: Viewport, options: EstimatorOptions) -> SplatDriver {
        SplatDriver {
            store: Store::new(viewport, Grid::default(), false, options),
        }
    }
}

impl Driver for SplatDriver {
    fn name(&self) -> &'static str {
        "splat"
    }

    fn store(&self) -> &dyn crate::store::SampleStore {
        &self.store
    }

    fn store_mut(&mut self) -> &mut dyn crate::store::SampleStore {
        &mut self.store
    }

    fn render(&mut self) -> Picture {
        self.store.update_colors();
        let colors = self.store.colors();
        let (w, h) = (
            self.store.viewport().width as usize,
            self.store.viewport().height as usize,
        );
        let sub = self.store.subpixels() as usize;
        let slots = &self.store.index().slots;
        // A pixel is the mean of its sub-pixels that hold an estimate.
        let mut pixels = Vec::with_capacity(w * h);
        for row in 0..h {
            for col in 0..w {
                let (mut sum, mut n) = (Vec3::ZERO, 0u32);
                for r in row * sub..(row + 1) * sub {
                    for &slot in &slots[r * w * sub + col * sub..r * w * sub + (col + 1) * sub] {
                        if slot != EMPTY {
                            sum += colors[slot as usize];
                            n += 1;
                        }
                    }
                }
                pixels.push(if n > 0 { sum / n as f32 } else { Vec3::ZERO });
            }
        }
        Picture {
            width: w,
            height: h,
            pixels,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::testkit::*;
    use glam::DVec3;
    use std::collections::HashMap;

    fn exact(vp: Viewport) -> SplatDriver {
        SplatDriver::with_options(
            vp,
            EstimatorOptions {
                angle_scale: f32::INFINITY,
                firefly_ratio: f32::INFINITY,
                subpixels: 1,
                ..EstimatorOptions::default()
            },
        )
    }

    #[test]
    fn splat_pixels_show_the_mean_of_their_rays_and_black_without() {
        let vp = viewport(EYE_VIEW, 96, 64);
        let samples = random_plane_samples(&vp.view, 2000, 21);
        let mut d = exact(vp.clone());
        d.add(&samples);
        let eye = vp.view.position;
        let mut rays: HashMap<usize, Vec<Vec3>> = HashMap::new();
        for s in &samples {
            let (c, r, _) = vp.pixel(s.target(eye)).unwrap();
            rays.entry(r as usize * 96 + c as usize)
                .or_default()
                .push(Vec3::from_array(s.color));
        }
        let pic = d.render();
        assert_eq!((pic.width, pic.height), (96, 64));
        for (i, p) in pic.pixels.iter().enumerate() {
            match rays.get(&i) {
                Some(c) => {
                    let mean = c.iter().sum::<Vec3>() / c.len() as f32;
                    assert!((*p - mean).abs().max_element() < 1e-5, "pixel {i}: {p} vs {mean}");
                }
                None => assert_eq!(*p, Vec3::ZERO, "pixel {i} has no ray"),
            }
        }
        assert_eq!(d.stats().kept, rays.len() as u64);
        assert_eq!(d.name(), "splat");
    }

    #[test]
    fn splat_counts_every_ray_once() {
        let mut d = exact(grid_viewport(4, 4));
        d.add(&[
            grid_sample(4, 4, 2.0, 2.0, 1.0, 0.3, [1.0; 3]),
            grid_sample(4, 4, 2.5, 2.5, 2.0, 0.2, [2.0; 3]),
            grid_sample(4, 4, 2.9, 2.9, 1.01, 0.25, [3.0; 3]),
            grid_sample(4, 4, 2.1, 2.1, 0.5, 0.25, [5.0; 3]),
            grid_sample(4, 4, 0.5, 0.5, 1.0, 0.3, [4.0; 3]),
            grid_sample(4, 4, 9.0, 0.5, 1.0, 0.3, [5.0; 3]),
        ]);
        let st = d.stats();
        // Pixel (2, 2): 1.0 starts, 2.0 is behind, 1.01 joins, 0.5 is in
        // front and starts over. Pixel (0, 0): one ray. One ray is off the frame.
        assert_eq!(
            (st.received, st.kept, st.merged, st.replaced, st.discarded, st.outside),
            (6, 2, 1, 1, 1, 1)
        );
        let pic = d.render();
        assert_eq!(pic.pixels[2 * 4 + 2], Vec3::splat(5.0));
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
        assert_eq!(d.stats().rejected_nonfinite, 2);
        assert!(d.stats().kept >= 1);
        // A large turn drops the estimates.
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
