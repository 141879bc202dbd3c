//! The holodeck sampler: scenes (import, generation, description files), the
//! kd-tree, the path tracer, and the direct reference renderer. Turning rays
//! into radiance and distance is its whole job; it knows nothing of sockets.

pub mod accel;
pub mod beam;
pub mod error;
pub mod geom;
pub mod ooc;
pub mod render;
pub mod scene;
pub mod shade;
pub mod worker;

pub use accel::KdTree;
pub use error::SceneError;
pub use scene::{Material, Scene, SceneBuilder, Sky, Triangle};
pub use shade::{FirstHits, FirstSurface, Reorder, Rng, Sample, TraceOptions, Tracer};
