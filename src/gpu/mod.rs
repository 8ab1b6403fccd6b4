//! The GPU side: wgpu device (headless or a window's), quad selection, the asynchronous data
//! caches, and the terrain pipelines that mirror the CPU references in [`crate::ecm::geometry`]
//! and [`crate::colour`].

pub mod camera;
pub mod data;
pub mod renderer;
pub mod scene;
pub mod select;
pub mod shaders;

pub use camera::Camera;
pub use renderer::{DrawMode, FrameStats, FrameTargets, GpuContext, IMAGE_FORMAT, RenderedImage, Renderer};
pub use scene::Scene;
