//! [`CliError`]: what a command could not do. A command's own checks of its options are
//! [`CliError::Usage`]; everything else is the library's error, kept whole, so that `terrafuse`
//! prints the cause chain (the file, the layer, the field, then what SQLite, GDAL or the file
//! system said).

use std::path::PathBuf;

use crate::Invalid;

/// What a command could not do.
#[derive(Debug, thiserror::Error)]
pub enum CliError {
    /// An option or argument that cannot be used, in words that name it.
    #[error("{0}")]
    Usage(String),
    /// A value that breaks a rule (a project's field, a camera, a region).
    #[error(transparent)]
    Invalid(#[from] Invalid),
    /// A project file.
    #[error(transparent)]
    Project(#[from] crate::project::ProjectError),
    /// Opening or composing the layers.
    #[error(transparent)]
    Scene(#[from] crate::scene::SceneError),
    /// A store, an import or an export.
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    /// A tile the loader could not give.
    #[error(transparent)]
    Load(#[from] crate::scene::loader::LoadError),
    /// The GPU.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// An export (boxed: it carries the project's path beside its cause).
    #[error(transparent)]
    Export(Box<crate::export::ExportError>),
    /// A layer.
    #[error(transparent)]
    Layer(#[from] crate::layers::LayerError),
    /// A stroke.
    #[error(transparent)]
    Stroke(#[from] crate::edit::StrokeError),
    /// A camera flight.
    #[error(transparent)]
    Flight(#[from] crate::scene::flight::FlightError),
    /// An erosion run.
    #[error(transparent)]
    Erosion(#[from] crate::erosion::layer::OperationError),
    /// Landscape-evolution parameters.
    #[error(transparent)]
    Landscape(#[from] crate::erosion::landscape::LandscapeError),
    /// Erosion parameters.
    #[error(transparent)]
    Params(#[from] crate::erosion::params::ParamError),
    /// A comparison.
    #[error(transparent)]
    Compare(#[from] crate::compare::CompareError),
    /// A shard plan, or a file it names.
    #[error(transparent)]
    Plan(#[from] crate::plan::PlanError),
    /// A replay.
    #[error(transparent)]
    Replay(#[from] crate::replay::ReplayError),
    /// A colour map.
    #[error(transparent)]
    Colour(#[from] crate::colour::ColourError),
    /// A box of degrees.
    #[error(transparent)]
    Box(#[from] crate::geodesy::BoxError),
    /// A body or a geodetic value.
    #[error(transparent)]
    Geodesy(#[from] crate::geodesy::GeodesyError),
    /// A face, quad or projection.
    #[error(transparent)]
    Ecm(#[from] crate::ecm::EcmError),
    /// A file the command reads or writes.
    #[error("{}: {what}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: &'static str,
        /// Why it failed.
        #[source]
        source: std::io::Error,
    },
    /// A JSON report could not be made.
    #[error("cannot write JSON")]
    Json(#[from] serde_json::Error),
    /// Something a callback or device reported.
    #[error(transparent)]
    Failed(#[from] crate::errors::Failure),
    /// A program the command ran (a shard, `sbatch`) that failed, with what it said.
    #[error("{0}")]
    Run(String),
    /// An error with what the command was doing (the project, the layer, the output file).
    #[error("{context}")]
    Within {
        /// What the command was doing, in words that name the file or layer.
        context: String,
        /// What went wrong there.
        #[source]
        source: Box<CliError>,
    },
}

/// Names what a command was doing when an error happened, keeping the error as the cause.
pub trait Within<T> {
    /// The error under `context` (`p.json`, `layer 'dem'`, `out.csv: cannot write`).
    fn within(self, context: impl std::fmt::Display) -> Result<T, CliError>;
}

impl<T, E: Into<CliError>> Within<T> for Result<T, E> {
    fn within(self, context: impl std::fmt::Display) -> Result<T, CliError> {
        self.map_err(|e| CliError::Within { context: context.to_string(), source: Box::new(e.into()) })
    }
}

impl From<String> for CliError {
    fn from(problem: String) -> CliError {
        CliError::Usage(problem)
    }
}

impl From<&str> for CliError {
    fn from(problem: &str) -> CliError {
        CliError::Usage(problem.into())
    }
}

impl CliError {
    /// A file that could not be read or written.
    pub fn file(path: impl Into<PathBuf>, what: &'static str) -> impl FnOnce(std::io::Error) -> CliError {
        let path = path.into();
        move |source| CliError::File { path, what, source }
    }
}

/// Names what a command was doing when a foreign error (I/O, a child process) happened, keeping
/// that error as the cause.
pub trait Context<T> {
    /// The error under `what`.
    fn context(self, what: impl std::fmt::Display) -> Result<T, CliError>;
    /// The error under the text `what` makes (only made on failure).
    fn with_context<D: std::fmt::Display>(self, what: impl FnOnce() -> D) -> Result<T, CliError>;
}

impl<T, E: std::error::Error + Send + Sync + 'static> Context<T> for Result<T, E> {
    fn context(self, what: impl std::fmt::Display) -> Result<T, CliError> {
        self.map_err(|e| CliError::Within {
            context: what.to_string(),
            source: Box::new(CliError::Failed(Box::new(e))),
        })
    }

    fn with_context<D: std::fmt::Display>(self, what: impl FnOnce() -> D) -> Result<T, CliError> {
        self.map_err(|e| CliError::Within {
            context: what().to_string(),
            source: Box::new(CliError::Failed(Box::new(e))),
        })
    }
}

impl From<crate::export::ExportError> for CliError {
    fn from(e: crate::export::ExportError) -> CliError {
        CliError::Export(Box::new(e))
    }
}
