//! The GPU side: wgpu device (headless or a window's), quad selection, the asynchronous data
//! caches, and the terrain pipelines that mirror the CPU references in [`crate::ecm::geometry`]
//! and [`crate::colour`].

pub mod brush;
pub mod camera;
pub mod compose;
mod compute;
pub mod context;
pub mod data;
pub mod erosion;
mod quads;
pub mod renderer;
pub mod scene;
pub mod select;
pub mod shaders;
pub mod shifted;
mod slots;
pub mod targets;
mod terrain;
mod uniforms;

pub use camera::Camera;
pub use context::{GpuContext, GpuError};
pub use renderer::{ComposeCounters, FrameStats, Renderer};
pub use scene::Scene;
pub use targets::{DrawMode, FrameTargets, ID_FORMAT, IMAGE_FORMAT, RenderedImage, SURFACE_FORMAT};
pub use terrain::{MESH_EDGE, TRIANGLES_PER_QUAD};
pub use uniforms::QuadInstance;
