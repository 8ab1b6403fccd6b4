//! [`GuiError`]: what the workstation could not do, shown to the user in the status line or a
//! dialog. It keeps the library's error whole (a caller can match it) and displays it with its
//! causes, as the command line prints them: the workstation is where the chain ends.

use crate::errors::chain;

/// What the workstation could not do.
#[derive(Debug, thiserror::Error)]
pub enum GuiError {
    /// A request the workstation itself refuses, in words.
    #[error("{0}")]
    Message(String),
    /// A value that breaks a rule.
    #[error("{}", chain(.0))]
    Invalid(crate::Invalid),
    /// A project file.
    #[error("{}", chain(.0))]
    Project(crate::project::ProjectError),
    /// Opening or composing the layers.
    #[error("{}", chain(.0))]
    Scene(crate::scene::SceneError),
    /// A store, an import or a plan.
    #[error("{}", chain(.0))]
    Store(crate::store::StoreError),
    /// The GPU.
    #[error("{}", chain(.0))]
    Gpu(crate::gpu::GpuError),
    /// A layer, a stroke or a run.
    #[error("{}", chain(.0))]
    Layer(crate::layers::LayerError),
    /// Erosion parameters.
    #[error("{}", chain(.0))]
    Params(crate::erosion::params::ParamError),
    /// A comparison.
    #[error("{}", chain(.0))]
    Compare(crate::compare::CompareError),
    /// A camera flight's path.
    #[error("{}", chain(.0))]
    Flight(crate::scene::flight::FlightError),
    /// A box around the view.
    #[error("{}", chain(.0))]
    Box(crate::geodesy::BoxError),
    /// A failure below, kept whole with its causes.
    #[error("{}", chain(&**.0))]
    Failure(crate::errors::Failure),
    /// What the workstation was doing when an error below stopped it, with that error.
    #[error("{context}: {source}")]
    Within {
        /// What was being done.
        context: String,
        /// The error.
        source: Box<GuiError>,
    },
    /// A file the workstation reads or writes.
    #[error("{}: {what}: {source}", path.display())]
    File {
        /// The file.
        path: std::path::PathBuf,
        /// What was being done.
        what: &'static str,
        /// Why it failed.
        source: std::io::Error,
    },
}

macro_rules! from {
    ($($variant:ident($type:ty)),* $(,)?) => {
        $(impl From<$type> for GuiError {
            fn from(e: $type) -> GuiError {
                GuiError::$variant(e)
            }
        })*
    };
}

from!(
    Invalid(crate::Invalid),
    Project(crate::project::ProjectError),
    Scene(crate::scene::SceneError),
    Store(crate::store::StoreError),
    Gpu(crate::gpu::GpuError),
    Layer(crate::layers::LayerError),
    Params(crate::erosion::params::ParamError),
    Compare(crate::compare::CompareError),
    Flight(crate::scene::flight::FlightError),
    Box(crate::geodesy::BoxError),
    Failure(crate::errors::Failure),
);

impl From<std::io::Error> for GuiError {
    fn from(e: std::io::Error) -> GuiError {
        GuiError::Failure(Box::new(e))
    }
}

impl From<serde_json::Error> for GuiError {
    fn from(e: serde_json::Error) -> GuiError {
        GuiError::Failure(Box::new(e))
    }
}

impl From<String> for GuiError {
    fn from(message: String) -> GuiError {
        GuiError::Message(message)
    }
}

impl From<&str> for GuiError {
    fn from(message: &str) -> GuiError {
        GuiError::Message(message.into())
    }
}

impl GuiError {
    /// A file that could not be read or written.
    pub fn file(path: impl Into<std::path::PathBuf>, what: &'static str) -> impl FnOnce(std::io::Error) -> GuiError {
        let path = path.into();
        move |source| GuiError::File { path, what, source }
    }
}

/// A result whose error stops something the workstation was doing: that, with the error as its
/// cause (`context: error`).
pub trait Within<T> {
    /// The error under `context`.
    fn within(self, context: impl std::fmt::Display) -> Result<T, GuiError>;
}

impl<T, E: Into<GuiError>> Within<T> for Result<T, E> {
    fn within(self, context: impl std::fmt::Display) -> Result<T, GuiError> {
        self.map_err(|e| GuiError::Within { context: context.to_string(), source: Box::new(e.into()) })
    }
}
