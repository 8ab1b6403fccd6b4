//! Brushing (issue #14): edit layers built from recorded strokes. A stroke is an operation (tool,
//! radius, strength, falloff, spacing, level, path, seed) that rebuilds the same height deltas bit
//! for bit, not a change to a raster that happens to be on screen.
//!
//! - [`stroke`]: strokes as project files hold them, the tools and the falloff formulas;
//! - [`dabs`]: dabs along a stroke's path by arc length on the ellipsoid;
//! - [`raster`]: the CPU reference rasteriser: sparse tiles of deltas at the strokes' level,
//!   deterministic whatever the thread count or quad order; undo by recomputing only the quads
//!   the undone strokes touched.
//!
//! Not built yet (see issue #14): the `edit` layer kind in the stack and its GPU rasteriser, the
//! tools that read the terrain below (smooth, flatten, ramp), the pyramid of area means for far
//! views, `terrafuse brush` and the workstation's brush tools.

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
