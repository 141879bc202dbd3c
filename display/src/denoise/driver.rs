//! Any driver with a denoiser after it: every frame it draws is cleaned
//! before it is shown, so displays (pictures, the window, headless runs)
//! take a denoised driver as they take any other.

use holodeck_protocol::Picture;

use super::{Denoiser, Guide};
use crate::{Driver, DriverStats, Sample, Viewport};

/// A driver whose frames pass through a denoiser.
pub struct Denoised {
    inner: Box<dyn Driver>,
    denoiser: Denoiser,
    /// The denoiser failed once (OIDN refusing a device, say): frames are
    /// shown as drawn from then on, and the failure was logged.
    failed: bool,
}

impl Denoised {
    /// `inner`'s frames cleaned by `denoiser`.
    pub fn new(inner: Box<dyn Driver>, denoiser: Denoiser) -> Denoised {
        Denoised {
            inner,
            denoiser,
            failed: false,
        }
    }
}

impl Driver for Denoised {
    fn name(&self) -> &'static str {
        self.inner.name()
    }

    fn add(&mut self, samples: &[Sample]) {
        self.inner.add(samples)
    }

    fn set_view(&mut self, viewport: Viewport) {
        self.inner.set_view(viewport)
    }

    fn viewport(&self) -> &Viewport {
        self.inner.viewport()
    }

    fn render(&mut self) -> Picture {
        let picture = self.inner.render();
        if self.failed {
            return picture;
        }
        match self.denoiser.apply(&picture, &self.inner.guide()) {
            Ok(p) => p,
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

    fn clear(&mut self) {
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
