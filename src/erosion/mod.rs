//! Hydraulic and thermal erosion, and landscape evolution: the CPU reference of the models, on a grid of cells with their
//! areas and lengths in metres, and the erosion layer built from recorded runs.
//!
//! - [`params`]: the parameters with their units and ranges, presets;
//! - [`grid`]: the grid (terrain, areas, lengths, masks, hardness) and the fixed-point volume
//!   unit;
//! - [`sim`]: the step (two gather-only passes), the CFL bound, exact budgets;
//! - [`region`]: a region of the planet (a box of a face's samples, folded across face edges) as
//!   one grid, with its lengths and areas on the ellipsoid;
//! - [`dither`]: the seeded dither that rounds flows to the fixed point;
//! - [`operation`]: a run as a project records it;
//! - [`layer`]: an erosion layer's raster built from its runs, with budgets and volumes;
//! - [`landscape`]: the second model, landscape evolution over geological time (uplift,
//!   stream-power incision, hillslope diffusion, lakes), on the same grids.
//!
//! The GPU kernels that mirror [`sim`] are `crate::gpu::erosion` (`shaders/erosion/`);
//! `terrafuse erode` and the workstation's *Erosion* section drive them.

/// The version of the model: part of every erosion cache's digest, bumped whenever a change of
/// the model changes what a run makes (so that no cache of an older model is read as current).
pub const MODEL_VERSION: u32 = 3;

pub mod dither;
pub mod grid;
pub mod landscape;
pub mod layer;
pub mod operation;
pub mod params;
pub mod placement;
pub mod region;
pub mod sim;
pub mod start;

pub use grid::Grid;
pub use params::{Border, ParamError, Params};
pub use sim::{Budget, Run, State, StepReport};

#[cfg(test)]
mod tests;
