//! The display: what the user sees and what gets computed next.
//!
//! A display turns a view into beam requests ([`request`]), turns the samples
//! that come back into per-pixel estimates ([`store`], shared by every
//! driver) and an image with a [`Driver`] (the CPU quadtree here; GPU
//! drivers elsewhere), and maps radiance to display values ([`tonemap`]).
//! Drivers know no sockets and no files: the headless client and
//! `holodeck pict` feed them. The GPU drivers ([`voronoi`], [`mesh`]) draw
//! through [`gpu`], on a real GPU or on Mesa's software Vulkan.
//!
//! * `client` — the connection to a server: handshake, beam requests, samples.
//! * `command` — the walkthrough's commands, as keys and as text lines.
//! * `compare` — the yardstick: FLIP, SSIM, relative errors, light kept per region.
//! * `denoise` — the denoisers after reconstruction: à-trous (CPU, GPU), OIDN (feature `oidn`).
//! * `driver` — the `Driver` trait every image representation implements.
//! * `gather` — samples that arrive a beam at a time, batched for a driver.
//! * `geometry` — scene triangles for the Voronoi driver's depth pass, simplified to a budget.
//! * `gpu` — the wgpu device, render targets and view uniforms the GPU drivers share.
//! * `image_io` — Radiance `.hdr` and PNG pictures read and written.
//! * `mesh` — the spherical Delaunay mesh driver (paper 2.4.5).
//! * `motion` — a held button or finger as motion steps (the window's and the web page's).
//! * `navigate` — the paper's input model as view arithmetic (the window's and the web page's).
//! * `output` — writing frames.
//! * `project` — world points to pixels and back.
//! * `quadtree` — the image-plane quadtree driver (paper 2.4.3).
//! * `request` — a viewport's beam requests (paper 2.4.2).
//! * `sample` — decoded rays with their world hit points.
//! * `sphere` — the Delaunay triangulation on the view sphere.
//! * `splat` — point splatting, the benchmark baseline.
//! * `stats` — what a driver has seen and done (`DriverStats`).
//! * `status` — the walkthrough's status line (the window's and the web page's).
//! * `store` — the sample store: one running estimate per pixel, shared by every driver.
//! * `tonemap` — radiance to display values.
//! * `viewport` — a view and its frame size, checked; why a driver refuses one.
//! * `voronoi` — the Voronoi-cone driver (paper 2.4.4).
//! * `window` — the interactive walkthrough window (feature `window`).

#[cfg(feature = "native")]
pub mod client;
pub mod command;
#[cfg(feature = "native")]
pub mod compare;
pub mod denoise;
pub mod driver;
pub mod gaps;
pub mod gather;
pub mod geometry;
pub mod gpu;
pub mod image_io;
pub mod mesh;
pub mod motion;
pub mod navigate;
pub mod output;
pub mod project;
pub mod quadtree;
pub mod request;
pub mod sample;
pub mod sphere;
pub mod splat;
pub mod stats;
pub mod status;
pub mod store;
#[cfg(test)]
pub(crate) mod testkit;
pub mod tonemap;
pub mod viewport;
pub mod voronoi;
#[cfg(feature = "window")]
pub mod window;

pub use driver::{Driver, DriverError, DriverStats, Viewport, MAX_VIEWPORT_PIXELS};
pub use sample::{Sample, SampleDecoder};
pub use store::EstimatorOptions;

/// The drivers this crate has, by name.
pub const DRIVERS: &[&str] = &["quadtree", "splat", "voronoi", "mesh"];

/// The drivers that draw on a GPU (or Mesa's software Vulkan).
pub const GPU_DRIVERS: &[&str] = &["voronoi", "mesh"];

/// What a driver is made with beyond its name and viewport.
#[derive(Clone, Copy, Debug, Default)]
pub struct DriverSetup<'a> {
    /// How pixels combine rays.
    pub options: EstimatorOptions,
    /// The scene's simplified geometry, for the drivers that cull by it
    /// (the Voronoi driver); the others ignore it.
    pub geometry: Option<&'a geometry::Geometry>,
}

/// Makes the driver called `name` (see [`DRIVERS`]).
pub fn new_driver(name: &str, viewport: Viewport) -> Result<Box<dyn Driver>, DriverError> {
    new_driver_with(name, viewport, EstimatorOptions::default())
}

/// [`new_driver`] with pixels that combine rays as `options` say.
pub fn new_driver_with(
    name: &str,
    viewport: Viewport,
    options: EstimatorOptions,
) -> Result<Box<dyn Driver>, DriverError> {
    make_driver(
        name,
        viewport,
        DriverSetup {
            options,
            geometry: None,
        },
    )
}

/// Makes the driver called `name` as `setup` says. The GPU drivers open
/// the process's shared [`gpu::GpuContext`] and fail with
/// [`DriverError::Gpu`] (saying what to install) where there is none.
pub fn make_driver(name: &str, viewport: Viewport, setup: DriverSetup<'_>) -> Result<Box<dyn Driver>, DriverError> {
    let options = setup.options;
    match name {
        "quadtree" => Ok(Box::new(quadtree::QuadtreeDriver::with_options(viewport, options))),
        "splat" => Ok(Box::new(splat::SplatDriver::with_options(viewport, options))),
        "voronoi" => {
            let gpu = gpu::GpuContext::shared().map_err(|e| DriverError::Gpu(e.to_string()))?;
            Ok(Box::new(voronoi::VoronoiDriver::new(
                gpu,
                viewport,
                options,
                setup.geometry,
            )))
        }
        "mesh" => {
            let gpu = gpu::GpuContext::shared().map_err(|e| DriverError::Gpu(e.to_string()))?;
            Ok(Box::new(mesh::MeshDriver::new(gpu, viewport, options)))
        }
        _ => Err(DriverError::Unknown(name.to_string())),
    }
}
