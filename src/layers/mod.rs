//! The layer stack (DESIGN.md, "The layer stack"): how elevation reaches the vertex stage. A
//! project's layers run bottom to top; per sample each gives a value and a coverage and a blend
//! mode folds it into the running height. Everything here is a CPU reference in plain Rust
//! (rayon), written to read like the GPU kernels in `shaders/compose/` and
//! `shaders/shared/noise.wgsl`; nothing here knows about the GPU.
//!
//! - [`spec`]: the layers as the project file holds them: common fields and one payload per kind;
//! - [`kind`]: what each kind answers to the consumers (its value's source, its detail level);
//! - [`stack`]: the stack in memory, each layer's identity and revision, per-quad plans (which
//!   layers a quad reads, their masks, its cache stamp);
//! - [`extent`]: extents and feathered masks in metres on the ellipsoid;
//! - [`correction`]: a dataset's bias corrections (ramps, binned and directional biases);
//! - [`edge`]: distances to a dataset's own no-data edge, for `feather_edge_m`;
//! - [`noise`]: fBm and ridged multifractal on the ECEF position, with a split f64/f32 lattice;
//! - [`compose`]: the blend formulas, per-sample and per-quad composition, height bounds.

pub mod compose;
pub mod correction;
pub mod edge;
pub mod extent;
pub mod kind;
pub mod noise;
pub mod spec;
pub mod stack;

pub use compose::{DataAt, LayerTiles, compose_difference, compose_quad, compose_sample, fold, range_bound};
pub use kind::{ValueSource, default_level};
pub use spec::{
    BlendMode, ConstantLayer, DatasetLayer, DetailWhere, DifferenceLayer, DifferenceStyle, EditLayer, ErosionLayer,
    ExtentSpec, LayerKind, LayerPayload, LayerSpec, NoiseSpec, NoiseType, Operand, ProceduralLayer, SourceSpec,
};
pub use stack::{DifferencePlan, Layer, MaskPlan, PlannedLayer, QuadPlan, Stack};

/// A layer that cannot be used, naming the layer, the field and the problem.
#[derive(Debug, Clone, thiserror::Error)]
#[error("layer '{layer}': {field}: {problem}")]
pub struct LayerError {
    /// The layer's name.
    pub layer: String,
    /// The field (e.g. `opacity`, `noise.octaves`).
    pub field: String,
    /// What is wrong.
    pub problem: String,
    /// What failed under it (a store, the terrain below, a stroke), if anything did.
    #[source]
    pub cause: Option<crate::errors::SharedFailure>,
}

impl LayerError {
    /// An error about one field of one layer.
    pub fn field(layer: &str, field: &str, problem: String) -> LayerError {
        LayerError { layer: layer.into(), field: field.into(), problem, cause: None }
    }

    /// A field's problem found by a check, as one layer's error.
    pub fn of_field(layer: &str, p: crate::errors::FieldProblem) -> LayerError {
        LayerError { layer: layer.into(), field: p.field, problem: p.problem, cause: None }
    }

    /// A failure under one field of one layer: `problem` says what could not be done, `cause`
    /// why.
    pub fn caused(layer: &str, field: &str, problem: &str, cause: impl Into<crate::errors::Failure>) -> LayerError {
        LayerError {
            layer: layer.into(),
            field: field.into(),
            problem: problem.into(),
            cause: Some(cause.into().into()),
        }
    }
}

/// Two errors are equal when they name the same layer, field and problem, and both have a cause
/// or neither has.
impl PartialEq for LayerError {
    fn eq(&self, other: &LayerError) -> bool {
        (&self.layer, &self.field, &self.problem, self.cause.is_some())
            == (&other.layer, &other.field, &other.problem, other.cause.is_some())
    }
}

#[cfg(test)]
mod tests;
