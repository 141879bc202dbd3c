//! The paper's Voronoi driver (section 2.4.4): every pixel estimate is the
//! apex of a cone drawn by the GPU with depth testing, so each pixel shows
//! the estimate nearest to it and the regions form the Voronoi diagram of
//! the estimates.
//!
//! Cones are instanced triangle fans of 4 to 32 triangles whose reach
//! follows the local density of estimates ([`cones`]). New rays go into
//! the shared [`Store`] and simply add cones: nothing is rebuilt. With the
//! scene's geometry (simplified, see [`crate::geometry`]) the driver first
//! draws its distances from the eye; estimates more than 2% off them are
//! dropped as multidepth, and cones stop where the geometry's depth stops
//! matching theirs, so silhouettes stay sharp.

pub mod cones;
mod pipeline;
#[cfg(test)]
mod tests;

use std::sync::Arc;

use holodeck_protocol::Picture;

use crate::driver::{Driver, Viewport};
use crate::geometry::Geometry;
use crate::gpu::target::{black, downsample, fill_holes};
use crate::gpu::{GpuContext, GpuError};
use crate::splat::Grid;
use crate::store::{EstimatorOptions, Store};
use cones::Cone;
use pipeline::{ConeFrame, ConePipeline};

/// Estimates and cone edges this far from the geometry's depth (a share of
/// it) are culled: the paper's 2%.
pub const DEPTH_TOLERANCE: f32 = 0.02;

/// The GPU Voronoi-cone driver.
#[derive(Debug)]
pub struct VoronoiDriver {
    store: Store<Grid>,
    pipeline: ConePipeline,
    cones: Vec<Cone>,
    /// Cones drawn in the last frame, by fan size.
    by_fan: [u32; 4],
    /// In a web page, the last frame read back: shown while the next one
    /// is on its way from the GPU.
    shown: Option<Picture>,
}

impl VoronoiDriver {
    /// A driver on `gpu` for `viewport`, culling by `geometry` when given.
    pub fn new(
        gpu: Arc<GpuContext>,
        viewport: Viewport,
        options: EstimatorOptions,
        geometry: Option<&Geometry>,
    ) -> VoronoiDriver {
        let pipeline = ConePipeline::new(gpu, geometry);
        if !pipeline.has_geometry() {
            // Once per process: `pict --views` makes a driver per view.
            static SAID: std::sync::Once = std::sync::Once::new();
            SAID.call_once(|| {
                tracing::info!(
                    "voronoi: no scene geometry (--geometry), so estimates are not depth-culled and cones cross silhouettes"
                );
            });
        }
        VoronoiDriver {
            store: Store::new(viewport, Grid::default(), false, options),
            pipeline,
            cones: Vec::new(),
            by_fan: [0; 4],
            shown: None,
        }
    }

    /// True when scene geometry culls estimates.
    pub fn has_geometry(&self) -> bool {
        self.pipeline.has_geometry()
    }

    /// Cones in the last frame by fan size (4, 8, 16 and 32 triangles).
    pub fn cones_by_fan(&self) -> [u32; 4] {
        self.by_fan
    }
}

impl Driver for VoronoiDriver {
    fn name(&self) -> &'static str {
        "voronoi"
    }

    fn store(&self) -> &dyn crate::store::SampleStore {
        &self.store
    }

    fn store_mut(&mut self) -> &mut dyn crate::store::SampleStore {
        &mut self.store
    }

    fn frame_pending(&self) -> bool {
        self.pipeline.pending()
    }

    fn render(&mut self) -> Picture {
        let start = web_time::Instant::now();
        self.store.update_colors();
        let vp = self.store.viewport().clone();
        let sub = self.store.subpixels();
        let (gw, gh) = (vp.width * sub, vp.height * sub);
        self.by_fan = cones::build(
            self.store.entries(),
            self.store.colors(),
            self.store.index(),
            gw,
            gh,
            &mut self.cones,
        );
        let largest = cones::largest_radius(gw, gh);
        let frame = ConeFrame {
            viewport: &vp,
            width: gw,
            height: gh,
            cones: &self.cones,
            by_fan: self.by_fan,
            tolerance: DEPTH_TOLERANCE,
            largest,
        };
        let prepared = start.elapsed();
        match self.pipeline.draw(&frame) {
            Ok(mut rgba) => {
                let drawn = start.elapsed();
                fill_holes(&mut rgba, gw, gh);
                let picture = downsample(&rgba, vp.width, vp.height, sub);
                if cfg!(target_arch = "wasm32") {
                    self.shown = Some(picture.clone());
                }
                tracing::debug!(
                    "voronoi frame: prepared and drawn in {:.1} ms ({:.1} ms on the GPU and reading back), finished in {:.1} ms",
                    drawn.as_secs_f64() * 1e3,
                    (drawn - prepared).as_secs_f64() * 1e3,
                    start.elapsed().as_secs_f64() * 1e3
                );
                picture
            }
            // A web page's frame still on the GPU: the last one meanwhile.
            Err(GpuError::NotReady) => self.shown.clone().unwrap_or_else(|| black(vp.width, vp.height)),
            Err(e) => {
                tracing::error!("voronoi: {e}");
                black(vp.width, vp.height)
            }
        }
    }

    fn heap_bytes(&self) -> usize {
        self.store.heap_bytes() + self.cones.capacity() * std::mem::size_of::<Cone>()
    }
}
