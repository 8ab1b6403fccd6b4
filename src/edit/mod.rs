//! Brushing: edit layers built from recorded strokes. A stroke is an operation (tool,
//! radius, strength, falloff, spacing, level, path, seed) that rebuilds the same height deltas bit
//! for bit, not a change to a raster that happens to be on screen.
//!
//! - [`stroke`]: strokes as project files hold them, the tools and the falloff formulas;
//! - [`dabs`]: dabs along a stroke's path by arc length on the ellipsoid;
//! - [`terrain`]: what smooth, flatten and ramp read (the terrain below the layer and its own
//!   deltas, before the stroke) and their targets;
//! - [`kernel`]: the CPU reference of a stroke on a tile and the `Rasteriser` trait (the GPU's is
//!   `gpu::brush`);
//! - [`raster`]: the edit raster: sparse tiles of deltas at the strokes' level, deterministic
//!   whatever the thread count or quad order; undo from a history of before-images or by
//!   recomputing the touched quads; per-quad stamps;
//! - [`pyramid`]: the coarser levels' area means;
//! - [`cache`]: a raster saved beside its project, keyed by a digest of what it depends on.

pub mod cache;
pub mod dabs;
pub mod kernel;
pub mod pyramid;
pub mod raster;
pub mod stroke;
pub mod terrain;

pub use raster::{EditRaster, StrokeError};
pub use stroke::{Falloff, Stroke, Tool};
pub use terrain::{Below, ellipsoid_below};

#[cfg(test)]
mod tests;
