//! The tile store: a GeoPackage per body with one float32 tile pyramid per dataset and cube face,
//! in the face's QSC CRS, on the ECM geometry's sample grid; import from any GDAL raster,
//! reading back (grids for the renderer, samples, heights) and export through GDAL.
//!
//! - [`grid`]: the sample grid, levels, and folding across face edges.
//! - [`tile`]: a quad's 257² grid and how it is stored (tile + rim).
//! - [`gpkg`]: the GeoPackage file, transactions, provenance.
//! - [`checkpoint`]: the write-ahead log checkpointed on a thread of its own during imports.
//! - [`source`]: a GDAL source, checked and read in windows.
//! - [`import`]: the import pipeline.
//! - [`shard`]: sharded imports: the plan (manifest) and one shard's partial store.
//! - [`merge`]: partial stores merged into a store, and its pyramid built once.
//! - [`lattice`]: sample positions in a source on an interpolated lattice, error measured.
//! - [`resample`]: the import's sampling (footprints, resampling, the pyramid's averages).
//! - [`read`]: reading back.
//! - [`watch`]: an import's progress and cancel switch, for another thread.
//! - [`export`]: GeoTIFF export in any CRS.

pub mod checkpoint;
pub mod export;
pub mod gpkg;
pub mod import;
pub mod lattice;
pub mod merge;
pub mod read;
pub mod resample;
pub mod shard;
pub mod source;
pub mod tile;
pub mod watch;

use std::path::{Path, PathBuf};

pub use gpkg::Store;
pub use import::{ImportOptions, ImportReport, LevelChoice, Resampling, VerticalDatum, import};
pub use read::GridReader;
pub use watch::{ImportProgress, ImportWatch};

/// A store error: the file concerned and what is wrong, in words, with the cause where a library
/// (SQLite, GDAL, the file system) reported one.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    /// The file's content or the request is not what the store needs.
    #[error("{}: {problem}", path.display())]
    Invalid {
        /// The file (a store, a source raster or an output).
        path: PathBuf,
        /// The problem.
        problem: String,
    },
    /// SQLite, GDAL, the file system or JSON failed while doing `what`.
    #[error("{}: {what}", path.display())]
    Failed {
        /// The file.
        path: PathBuf,
        /// What was being done.
        what: String,
        /// The library's error.
        #[source]
        cause: Box<Cause>,
    },
}

/// What a library reported under a [`StoreError::Failed`].
#[derive(Debug, thiserror::Error)]
pub enum Cause {
    /// SQLite.
    #[error(transparent)]
    Sqlite(#[from] rusqlite::Error),
    /// GDAL or PROJ through GDAL.
    #[error(transparent)]
    Gdal(#[from] gdal::errors::GdalError),
    /// The file system.
    #[error(transparent)]
    Io(#[from] std::io::Error),
    /// A JSON record.
    #[error(transparent)]
    Json(#[from] serde_json::Error),
    /// A body's axes.
    #[error(transparent)]
    Geodesy(#[from] crate::geodesy::GeodesyError),
    /// Worker threads.
    #[error(transparent)]
    Threads(#[from] rayon::ThreadPoolBuildError),
    /// A stored tile that cannot be decoded.
    #[error(transparent)]
    Tile(#[from] tile::TileError),
    /// A store error that several workers share (a worker that could not start).
    #[error(transparent)]
    Shared(#[from] std::sync::Arc<StoreError>),
}

impl StoreError {
    /// An error about a file.
    pub fn new(path: &Path, problem: impl Into<String>) -> StoreError {
        StoreError::Invalid { path: path.to_owned(), problem: problem.into() }
    }

    /// A library's failure while doing `what` to a file.
    pub fn caused(path: &Path, what: impl Into<String>, cause: impl Into<Cause>) -> StoreError {
        StoreError::Failed { path: path.to_owned(), what: what.into(), cause: Box::new(cause.into()) }
    }

    /// The file concerned.
    pub fn path(&self) -> &Path {
        match self {
            StoreError::Invalid { path, .. } | StoreError::Failed { path, .. } => path,
        }
    }
}
