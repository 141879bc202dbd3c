//! Shading: materials' scattering (BSDFs), lights, the sky, and the path
//! tracer that combines them into radiance estimates.

pub mod bsdf;
pub mod lights;
mod measured;
pub mod microfacet;
mod path;
pub mod rng;
pub mod sampling;
pub mod sky;
mod surface;
pub mod tracer;
pub mod wavefront;

pub use rng::Rng;
pub use tracer::{batch_seed, FirstHits, FirstSurface, Sample, SeededRay, TraceOptions, Tracer};
pub use wavefront::Reorder;
