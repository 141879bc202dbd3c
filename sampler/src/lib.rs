//! The sampler: beam ray generation and the tracer (scene import, acceleration
//! structure, out-of-core blocks, shading). Nothing is implemented yet; this
//! crate only reserves its place in the workspace.
