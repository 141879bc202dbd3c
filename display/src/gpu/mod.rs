//! The GPU front end the Voronoi and mesh drivers draw with: a wgpu device
//! ([`context`]), headless render targets read back as linear HDR pictures
//! ([`target`]), and the view projection shared by their shaders ([`view`]).
//!
//! Everything runs on a real GPU (Vulkan, Metal, DX12, GL) or on Mesa's
//! software Vulkan (lavapipe) where there is none, so the same drivers and
//! tests run on a laptop, a cluster node and a CI machine.

pub mod build;
pub mod context;
pub mod target;
pub mod view;

pub use context::{GpuContext, GpuError};
pub use target::{Target, TargetKind};
pub use view::ViewUniform;
