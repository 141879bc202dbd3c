//! Any driver with a denoiser after it: every frame it draws is cleaned
//! before it is shown, so displays (pictures, the window, headless runs)
//! take a denoised driver as they take any other.
//!
//! A frame drawn after the view moved and before any new sample arrived
//! (motion: the estimates only reprojected, as the window draws while the
//! user drags) is shown as drawn: the denoiser costs a frame's time many
//! times over on a CPU, and a moving picture does not need it. The frame
//! after the next samples is denoised again. A frame asked for again with
//! nothing changed (a still window redrawn) is the last one, not denoised
//! again.

use holodeck_protocol::Picture;

use super::{Denoiser, Guide};
use crate::{Driver, DriverStats, Sample, Viewport};

/// Where a display that knows the scene gets the albedo of the surfaces a
/// view sees (a picture of the viewport's size), for the denoiser's guide.
pub type AlbedoSource = Box<dyn Fn(&Viewport) -> Option<Picture> + Send>;

/// A driver whose frames pass through a denoiser.
pub struct Denoised {
    inner: Box<dyn Driver>,
    denoiser: Denoiser,
    /// The denoiser failed once (OIDN refusing a device, say): frames are
    /// shown as drawn from then on, and the failure was logged.
    failed: bool,
    /// The view moved and no sample arrived since.
    moving: bool,
    /// The last denoised frame, while nothing changed since.
    last: Option<Picture>,
    /// The scene's albedo for the guide, if the display has the scene.
    albedo_source: Option<AlbedoSource>,
    /// The albedo of the current view, once asked for (the outer `None`:
    /// not asked yet; the inner: the source had none).
    albedo: Option<Option<Picture>>,
}

impl Denoised {
    /// `inner`'s frames cleaned by `denoiser`.
    pub fn new(inner: Box<dyn Driver>, denoiser: Denoiser) -> Denoised {
        if let Denoiser::Auto(_) = denoiser {
            crate::gpu::GpuContext::probe_in_background();
        }
        Denoised {
            inner,
            denoiser,
            failed: false,
            moving: false,
            last: None,
            albedo_source: None,
            albedo: None,
        }
    }

    /// The same, its denoiser guided also by the albedo `source` gives for
    /// each view (asked once per view, when a frame is first denoised).
    pub fn with_albedo(mut self, source: AlbedoSource) -> Denoised {
        self.albedo_source = Some(source);
        self
    }

    /// The guide of the current frame, with the scene's albedo where known.
    fn full_guide(&mut self) -> Guide {
        let guide = self.inner.guide();
        let Some(source) = &self.albedo_source else {
            return guide;
        };
        let viewport = self.inner.viewport();
        match self.albedo.get_or_insert_with(|| source(viewport)) {
            Some(a) => guide.with_albedo(a),
            None => guide,
        }
    }

    /// New rays arrive (`any`): the view is still, and the last cleaned
    /// frame is stale.
    fn arriving(&mut self, any: bool) {
        if any {
            self.moving = false;
            self.last = None;
        }
    }
}

/// Whether `chunks` hold any beam.
fn any_beams(chunks: &[&[(holodeck_protocol::BeamKey, &[holodeck_protocol::RayRecord])]]) -> bool {
    chunks.iter().any(|c| !c.is_empty())
}

impl Driver for Denoised {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn store(&self) -> &dyn crate::store::SampleStore {
        self.inner.store()
    }

    /// The inner driver's store: changing it bypasses this wrapper's
    /// bookkeeping, so `add`, `set_view` and `clear` here say what changed.
    fn store_mut(&mut self) -> &mut dyn crate::store::SampleStore {
        self.last = None;
        self.inner.store_mut()
    }

    fn add(&mut self, samples: &[Sample]) {
        self.arriving(!samples.is_empty());
        self.inner.add(samples)
    }

    fn add_beams(
        &mut self,
        decoder: &crate::SampleDecoder,
        chunks: &[&[(holodeck_protocol::BeamKey, &[holodeck_protocol::RayRecord])]],
    ) {
        self.arriving(any_beams(chunks));
        self.inner.add_beams(decoder, chunks)
    }

    fn add_beams_where_empty(
        &mut self,
        decoder: &crate::SampleDecoder,
        chunks: &[&[(holodeck_protocol::BeamKey, &[holodeck_protocol::RayRecord])]],
    ) {
        self.arriving(any_beams(chunks));
        self.inner.add_beams_where_empty(decoder, chunks)
    }

    fn add_where_empty(&mut self, samples: &[Sample]) {
        self.arriving(!samples.is_empty());
        self.inner.add_where_empty(samples)
    }

    fn empty_pixels(&self) -> Vec<bool> {
        self.inner.empty_pixels()
    }

    fn set_view(&mut self, viewport: Viewport) {
        if viewport != *self.inner.viewport() {
            self.moving = true;
            self.last = None;
            self.albedo = None;
        }
        self.inner.set_view(viewport)
    }

    fn viewport(&self) -> &Viewport {
        self.inner.viewport()
    }

    fn render(&mut self) -> Picture {
        if let Some(p) = &self.last {
            return p.clone();
        }
        let picture = self.inner.render();
        if self.failed || self.moving {
            return picture;
        }
        // The inner frame is an old one standing in: cleaned, but not kept.
        let pending = self.inner.frame_pending();
        let guide = self.full_guide();
        match self.denoiser.apply(&picture, &guide) {
            Ok(p) => {
                if !pending {
                    self.last = Some(p.clone());
                }
                p
            }
            Err(e) => {
                tracing::warn!("denoising failed, frames are shown as drawn: {e}");
                self.failed = true;
                picture
            }
        }
    }

    fn stats(&self) -> DriverStats {
        self.inner.stats()
    }

    fn frame_pending(&self) -> bool {
        self.inner.frame_pending()
    }

    fn clear(&mut self) {
        self.last = None;
        self.inner.clear()
    }

    fn heap_bytes(&self) -> usize {
        self.inner.heap_bytes()
    }

    fn point_at(&self, col: u32, row: u32) -> Option<glam::DVec3> {
        self.inner.point_at(col, row)
    }

    fn needs(&self, density: f32) -> Vec<f32> {
        self.inner.needs(density)
    }

    fn guide(&self) -> Guide {
        self.inner.guide()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::denoise::AtrousOptions;
    use crate::testkit::{random_plane_samples, viewport, EYE_VIEW};

    #[test]
    fn frames_are_denoised_but_while_the_view_moves_without_new_samples() {
        let vp = viewport(EYE_VIEW, 32, 24);
        let raw = || crate::new_driver("splat", vp.clone()).unwrap();
        let mut samples = random_plane_samples(&vp.view, 32 * 24 * 8, 3);
        for (i, s) in samples.iter_mut().enumerate() {
            s.color = s.color.map(|c| c * (0.5 + (i % 7) as f32 / 6.0));
        }
        let mut plain = raw();
        let mut d = Denoised::new(raw(), Denoiser::Atrous(AtrousOptions::default()));
        plain.add(&samples);
        d.add(&samples);
        let denoised = d.render();
        assert_ne!(denoised, plain.render(), "a still view's frame is denoised");
        assert_eq!(d.render(), denoised, "and drawn again unchanged");
        let moved = viewport(&format!("{EYE_VIEW} -vp 0.01 0 0"), 32, 24);
        plain.set_view(moved.clone());
        d.set_view(moved);
        assert_eq!(d.render(), plain.render(), "a moving view's frame is shown as drawn");
        plain.add(&samples[..100]);
        d.add(&samples[..100]);
        assert_ne!(d.render(), plain.render(), "new samples: denoised again");
        assert_eq!((d.name(), d.stats()), (plain.name(), plain.stats()));
    }

    #[test]
    fn the_scenes_albedo_is_asked_once_a_view_and_guides_the_denoiser() {
        use std::sync::atomic::{AtomicUsize, Ordering};
        use std::sync::Arc;
        let vp = viewport(EYE_VIEW, 32, 24);
        let asked = Arc::new(AtomicUsize::new(0));
        let counter = Arc::clone(&asked);
        // The albedo of a view: its eye's x + 0.5 in every channel, so
        // that each view's is told apart.
        let source: AlbedoSource = Box::new(move |v: &Viewport| {
            counter.fetch_add(1, Ordering::SeqCst);
            let (w, h) = (v.width as usize, v.height as usize);
            Some(Picture {
                width: w,
                height: h,
                pixels: vec![glam::Vec3::splat(v.view.position.x as f32 + 0.5); w * h],
            })
        });
        let raw = crate::new_driver("splat", vp.clone()).unwrap();
        let mut d = Denoised::new(raw, Denoiser::Atrous(AtrousOptions::default())).with_albedo(source);
        let samples = random_plane_samples(&vp.view, 32 * 24 * 4, 5);
        d.add(&samples);
        d.render();
        assert_eq!(asked.load(Ordering::SeqCst), 1);
        d.add(&samples[..50]);
        d.render();
        assert_eq!(asked.load(Ordering::SeqCst), 1, "the same view: not asked again");
        assert_eq!(d.full_guide().albedo, vec![[0.5; 3]; 32 * 24]);
        let moved = viewport(&format!("{EYE_VIEW} -vp 0.25 0 0"), 32, 24);
        d.set_view(moved);
        d.add(&samples[..50]);
        d.render();
        assert_eq!(asked.load(Ordering::SeqCst), 2, "a new view: asked once more");
        assert_eq!(d.full_guide().albedo, vec![[0.75; 3]; 32 * 24]);
        // Without a source the guide has no albedo, and OIDN a constant one.
        assert!(d.inner.guide().albedo.is_empty());
    }
}
