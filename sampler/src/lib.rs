//! The holodeck sampler: scenes, the ray casters, the path tracer, and the
//! sampler worker that traces the beams a server hands out. Turning rays
//! into radiance and distance is its job; the worker's one connection
//! (blocking, through `holodeck_protocol::wire`) is its only socket.
//!
//! * `accel` — the ray casters behind one trait: kd-tree, wide BVH, packets, reordering, Embree (feature `embree`).
//! * `beam` — which rays of a beam to trace (viewpoint proximity, batches) and how a traced ray becomes a record.
//! * `error` — errors of scene import, generation and description files.
//! * `geom` — rays, boxes, the watertight ray/triangle test, robust offsets.
//! * `ooc` — out-of-core scene files (`.hds`): build, blocks, cache, fetchers, traversal with LOD voxels.
//! * `render` — the direct reference renderer and its denoiser buffers (albedo, normals).
//! * `scene` — scenes: import (OBJ, PLY, glTF, Radiance with its patterns), generation, TOML files, textures, materials.
//! * `shade` — BSDFs, lights, the sky, and the path tracer (`Tracer`).
//! * `worker` — the sampler's side of the wire: connect, prove the scene, trace packets.

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
pub use shade::{Caster, FirstHits, FirstSurface, Reorder, Rng, Sample, TraceOptions, Tracer};
