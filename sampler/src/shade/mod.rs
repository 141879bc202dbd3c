//! Shading: materials' scattering (BSDFs), lights, the sky, and the path
//! tracer that combines them into radiance estimates.
//!
//! * `bsdf`, `microfacet`, `measured` (BRDF tables' two ways) — how materials scatter.
//! * `cast` — the tracer's one ray caster ([`Caster`]): wide BVH, kd-tree, another library's, or a scene file.
//! * `estimate` — the estimator's entry points: one ray, rays in turn, seeded batches.
//! * `hit` — a hit as shading needs it.
//! * `lights`, `sky` — area lights and the sky with its sun, sampled for next-event estimation.
//! * `options` — the estimator's settings ([`TraceOptions`], [`Reorder`], [`FirstHits`]).
//! * `path` — one path's steps (shading a hit, the next ray, shadow rays).
//! * `rng`, `sampling` — random streams and the warps that turn them into directions.
//! * `surface` — textures, patterns and alpha masks at a hit.
//! * `tracer` — [`Tracer`]: a scene with its caster, and the geometric queries of the estimator.
//! * `wavefront` — paths stepped together, each segment's rays sorted.

pub mod bsdf;
mod cast;
mod estimate;
mod hit;
pub mod lights;
mod measured;
pub mod microfacet;
mod options;
mod path;
pub mod rng;
pub mod sampling;
pub mod sky;
mod surface;
mod tracer;
mod wavefront;

pub use cast::Caster;
pub use estimate::{batch_seed, Sample, SeededRay};
pub use options::{last_level_cache_bytes, FirstHits, Reorder, TraceOptions, AUTO_MIN_PATHS};
pub use rng::Rng;
pub use tracer::{FirstSurface, Tracer};
