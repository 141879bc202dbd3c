//! Shading: materials' scattering (BSDFs), lights, the sky, and the path
//! tracer that combines them into radiance estimates.

pub mod bsdf;
pub mod lights;
pub mod microfacet;
pub mod rng;
pub mod sampling;
pub mod sky;
pub mod tracer;

pub use rng::Rng;
pub use tracer::{FirstHits, Sample, TraceOptions, Tracer};
