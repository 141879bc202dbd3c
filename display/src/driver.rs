//! The driver abstraction every image representation implements: samples go
//! in (with world hit points, so they reproject into any view), a view is set,
//! and a frame of linear radiance comes out.

use holodeck_protocol::Picture;

use crate::sample::Sample;
pub use crate::stats::DriverStats;
use crate::store::SampleStore;
pub use crate::viewport::{DriverError, Viewport, MAX_VIEWPORT_PIXELS};

/// An image representation (`Send`, so that a display may fill it on one
/// thread while it decodes on others).
pub trait Driver: Send {
    /// A short name ("quadtree").
    fn name(&self) -> &'static str;
    /// Its sample store, which the provided methods below delegate to.
    fn store(&self) -> &dyn SampleStore;
    /// The same, to change.
    fn store_mut(&mut self) -> &mut dyn SampleStore;
    /// Draws the current frame, linear radiance, top row first.
    fn render(&mut self) -> Picture;
    /// In a web page, a GPU driver's frame is read back from the GPU only
    /// after the page returns to the browser: while this is true,
    /// [`Driver::render`] gave the last frame read back, and should be
    /// called again soon for the new one. Always false natively.
    fn frame_pending(&self) -> bool {
        false
    }
    /// Adds samples; they appear in the next frame.
    fn add(&mut self, samples: &[Sample]) {
        self.store_mut().add(samples)
    }
    /// Adds the stored rays of whole beams, decoded by `decoder`, in
    /// chunks: the same as [`Driver::add`] once per chunk with every record
    /// decoded, in order, but faster (see [`crate::store::Store::add_beams`]).
    fn add_beams(
        &mut self,
        decoder: &crate::SampleDecoder,
        chunks: &[&[(holodeck_protocol::BeamKey, &[holodeck_protocol::RayRecord])]],
    ) {
        self.store_mut().add_beams(decoder, chunks)
    }
    /// [`Driver::add_beams`], but only pixels that have no estimate yet take
    /// rays (see [`crate::store::Store::add_beams_where_empty`]).
    fn add_beams_where_empty(
        &mut self,
        decoder: &crate::SampleDecoder,
        chunks: &[&[(holodeck_protocol::BeamKey, &[holodeck_protocol::RayRecord])]],
    ) {
        self.store_mut().add_beams_where_empty(decoder, chunks)
    }
    /// [`Driver::add`], but only pixels that have no estimate yet take
    /// samples (see [`crate::store::Store::add_where_empty`]).
    fn add_where_empty(&mut self, samples: &[Sample]) {
        self.store_mut().add_where_empty(samples)
    }
    /// Which pixels of the frame have no estimate, row-major, top row first.
    fn empty_pixels(&self) -> Vec<bool> {
        self.store().empty_pixels()
    }
    /// How long adding rays took so far, by stage.
    fn insert_times(&self) -> crate::stats::InsertTimes {
        self.store().insert_times()
    }
    /// Changes the view (and frame size): samples are reprojected.
    fn set_view(&mut self, viewport: Viewport) {
        self.store_mut().set_view(viewport)
    }
    /// The current viewport.
    fn viewport(&self) -> &Viewport {
        self.store().viewport()
    }
    /// Counters.
    fn stats(&self) -> DriverStats {
        self.store().stats()
    }
    /// Forgets every sample.
    fn clear(&mut self) {
        self.store_mut().clear()
    }
    /// Heap bytes held: bounded by the frame size, not by the rays received.
    fn heap_bytes(&self) -> usize {
        self.store().heap_bytes()
    }
    /// The sample store's part of [`Driver::heap_bytes`], by what holds it
    /// (the rest is the driver's own: what it draws with).
    fn store_heap_parts(&self) -> crate::store::HeapParts {
        self.store().heap_parts()
    }
    /// The world point seen at pixel (`col`, `row`) (top row first), or
    /// `None` where the frame shows sky or nothing near that pixel.
    fn point_at(&self, col: u32, row: u32) -> Option<glam::DVec3> {
        self.store().point_near(col, row, crate::store::POINT_REACH)
    }
    /// How many more rays each pixel wants for `density` rays per pixel on
    /// average, spent where they reduce the error most (row-major, top row
    /// first); see [`crate::store::Store::needs`].
    fn needs(&self, density: f32) -> Vec<f32> {
        self.store().needs(density)
    }
    /// What the denoiser needs besides the frame: each pixel's depth,
    /// normal and noise (see [`crate::denoise`]).
    fn guide(&self) -> crate::denoise::Guide {
        self.store().guide()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{new_driver, GPU_DRIVERS};
    use holodeck_protocol::View;

    #[test]
    fn drivers_are_made_by_name_and_others_refused_by_kind() {
        let viewport = Viewport::new(View::default(), 4, 3).unwrap();
        let d = new_driver("splat", viewport.clone()).unwrap();
        assert_eq!((d.name(), d.viewport().width), ("splat", 4));
        assert!(GPU_DRIVERS.contains(&"mesh"));
        let e = new_driver("crayon", viewport).err().unwrap();
        assert_eq!(e, DriverError::Unknown("crayon".into()));
        assert!(e.to_string().contains("quadtree, splat"), "{e}");
    }
}
