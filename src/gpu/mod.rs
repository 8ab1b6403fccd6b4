//! The GPU side: what talks to wgpu. The device (headless or a window's), the frame targets, the
//! terrain, compose, brush, erosion and terrain-attribute pipelines that mirror their CPU references, and the
//! renderer that draws a [`crate::scene::Scene`].

pub mod attributes;
pub mod brush;
pub mod codes;
pub mod compose;
mod compute;
pub mod context;
pub mod editing;
pub mod erosion;
mod layout;
mod patch_errors;
pub mod pops;
pub mod renderer;
pub mod shaders;
pub mod shading;
pub mod targets;
mod terrain;
mod uniforms;

pub use context::{GpuContext, GpuError};
pub use editing::Editor;
pub use renderer::{ComposeCounters, FrameStats, Renderer};
pub use targets::{
    DrawMode, FrameTargets, ID_FORMAT, IMAGE_FORMAT, PROBE_ORIGIN, PROBE_SUBSAMPLES, RenderedImage, SURFACE_FORMAT,
};
pub use uniforms::QuadInstance;
