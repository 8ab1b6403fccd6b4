//! Comparing two layers of a project: the differences A − B over their overlap at a
//! level of the cube map, each sample weighted by the true area of its cell on the ellipsoid, with
//! the reference's slope, and their statistics (`stats`).
//!
//! - [`stats`]: weighted statistics, histogram and slope classes (the JSON of `terrafuse compare`);
//! - [`streamed`]: the same of more differences than memory holds, read in passes;
//! - [`spill`]: differences that can be read again in order: held, or spilled to a scratch file;
//! - [`pipeline`]: co-registration as a pipeline of bias corrections (`coregister --pipeline`);
//! - [`coreg`]: its Nuth & Kääb step on the ellipsoid, and the reference's samples;
//! - [`bias`]: the other steps' models (vertical, deramp, terrain bias, directional);
//! - [`stable`]: where the corrections are fitted (a layer's coverage, or outlines left out);
//! - [`uncertainty`]: the error model, its spatial correlation ([`variogram`]) and the 1σ of a
//!   mean elevation change and a volume change (Hugonnet et al. 2022);
//! - [`profile`]: every visible layer's elevation along a geodesic;
//! - `whole_area`: a pipeline fitted on some quads, replayed over every sample for the area's
//!   statistics;
//! - [`attribute_range`]: the range of a terrain attribute over some quads (a colour ramp's);
//! - [`sample`]: the overlap's samples: each layer composed alone with the CPU reference, cell areas
//!   and slopes on the ellipsoid.

pub mod attribute_range;
pub mod bias;
pub mod coreg;
mod mosaic;
pub mod pipeline;
pub mod profile;
mod quad_geometry;
pub mod sample;
pub mod sharded;
pub mod spill;
pub mod stable;
pub mod stats;
pub mod streamed;
pub mod uncertainty;
pub mod variogram;
mod whole_area;

pub use attribute_range::attribute_range;
pub use coreg::NuthKaabOptions;
pub use pipeline::{CoregOptions, Coregistration, Step, coregister};
pub use profile::{Profile, ProfileOptions, profile};
pub use sample::{
    CompareOptions, Comparison, Weighting, compare, compare_operands, difference_range, open_operand, operand,
};
pub use stable::Stable;
pub use stats::{Diff, Histogram, SlopeClass, Stats};
pub use uncertainty::{Uncertainty, UncertaintyOptions, uncertainty};

/// A comparison that cannot be made, in words that name the layer, option or file.
#[derive(Debug, thiserror::Error)]
pub enum CompareError {
    /// A layer named on the command line is not in the project.
    #[error("layer '{name}' is not in the project (its layers: {known})")]
    NoLayer {
        /// The name asked for.
        name: String,
        /// The project's layers.
        known: String,
    },
    /// An option's value cannot be used.
    #[error("{option}: {problem}")]
    Option {
        /// The option, as the command line spells it.
        option: String,
        /// What is wrong.
        problem: String,
    },
    /// A file named on the command line cannot be used.
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// What is wrong.
        problem: String,
    },
    /// A shard plan, or a file it names.
    #[error(transparent)]
    Plan(#[from] crate::plan::PlanError),
    /// Opening or reading the layers failed.
    #[error(transparent)]
    Open(#[from] crate::scene::SceneError),
    /// A project value (its body) breaks a rule.
    #[error(transparent)]
    Invalid(#[from] crate::Invalid),
    /// The comparison was asked to stop (its watch cancelled).
    #[error("the comparison was cancelled")]
    Cancelled(#[from] crate::progress::Cancelled),
}

/// Counts `n` more quads done on `watch` (if any); `Err(Cancelled)` once it was cancelled.
pub(crate) fn tick(watch: &Option<std::sync::Arc<crate::progress::Watch>>, n: usize) -> Result<(), CompareError> {
    if let Some(w) = watch {
        w.check()?;
        w.advance_by(n as u64);
    }
    Ok(())
}

/// Starts a phase of `total` quads on `watch` (if any).
pub(crate) fn phase(watch: &Option<std::sync::Arc<crate::progress::Watch>>, name: &str, total: usize) {
    if let Some(w) = watch {
        w.start_phase(name, total as u64);
    }
}
