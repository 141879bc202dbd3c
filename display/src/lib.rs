//! The display: what the user sees and what gets computed next.
//!
//! A display turns a view into beam requests ([`request`]), turns the samples
//! that come back into per-pixel estimates ([`store`], shared by every
//! driver) and an image with a [`Driver`] (the CPU quadtree here; GPU
//! drivers elsewhere), and maps radiance to display values ([`tonemap`]).
//! Drivers know no sockets and no files: the headless client and
//! `holodeck pict` feed them.

pub mod client;
pub mod compare;
pub mod driver;
pub mod image_io;
pub mod output;
pub mod project;
pub mod quadtree;
pub mod request;
pub mod sample;
pub mod sphere;
pub mod splat;
pub mod store;
#[cfg(test)]
pub(crate) mod testkit;
pub mod tonemap;

pub use driver::{Driver, DriverError, DriverStats, Viewport, MAX_VIEWPORT_PIXELS};
pub use sample::{Sample, SampleDecoder};
pub use store::EstimatorOptions;

/// The drivers this crate has, by name.
pub const DRIVERS: &[&str] = &["quadtree", "splat"];

/// The drivers that need a GPU front end, which this crate does not have.
pub const GPU_DRIVERS: &[&str] = &["voronoi", "mesh"];

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
    match name {
        "quadtree" => Ok(Box::new(quadtree::QuadtreeDriver::with_options(viewport, options))),
        "splat" => Ok(Box::new(splat::SplatDriver::with_options(viewport, options))),
        _ if GPU_DRIVERS.contains(&name) => Err(DriverError::NeedsGpu(name.to_string())),
        _ => Err(DriverError::Unknown(name.to_string())),
    }
}
