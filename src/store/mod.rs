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
pub mod grid;
pub mod import;
pub mod lattice;
pub mod merge;
pub mod read;
pub mod resample;
pub mod shard;
pub mod source;
pub mod tile;
pub mod watch;

use std::fmt;
use std::path::{Path, PathBuf};

pub use gpkg::Store;
pub use import::{ImportOptions, ImportReport, LevelChoice, Resampling, VerticalDatum, import};
pub use read::GridReader;
pub use watch::{ImportProgress, ImportWatch};

/// A store error: the file concerned and what is wrong, in words.
#[derive(Debug, Clone, PartialEq)]
pub struct StoreError {
    /// The file (a store, a source raster or an output).
    pub path: PathBuf,
    /// The problem.
    pub problem: String,
}

impl StoreError {
    /// An error about a file.
    pub fn new(path: &Path, problem: impl Into<String>) -> StoreError {
        StoreError { path: path.to_owned(), problem: problem.into() }
    }
}

impl fmt::Display for StoreError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}: {}", self.path.display(), self.problem)
    }
}

impl std::error::Error for StoreError {}
