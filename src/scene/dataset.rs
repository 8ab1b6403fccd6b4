//! A dataset as the scene reads it: its store, which quads hold its tiles (known up front), its
//! height range and body, and the shift a co-registration gave it.

use std::collections::HashSet;
use std::path::PathBuf;

use crate::ecm::QuadId;
use crate::geodesy::Ellipsoid;
use crate::store::{Store, StoreError};

/// One dataset the renderer reads.
#[derive(Clone, Debug)]
pub struct DatasetInfo {
    /// Its store.
    pub store: PathBuf,
    /// Its name in the store.
    pub dataset: String,
    /// Finest level.
    pub finest_level: u8,
    /// Quads with data, per level 0 ..= finest.
    pub present: Vec<HashSet<QuadId>>,
    /// Height range over its finest level, metres.
    pub range_m: (f64, f64),
    /// The body of its store.
    pub body: Ellipsoid,
    /// Moved east and north by this much, metres (see `shifted`; the layer's `shift_m`).
    pub shift_m: [f64; 2],
}

impl DatasetInfo {
    /// Reads what a store's dataset covers.
    pub fn open(store_path: &std::path::Path, dataset: &str) -> Result<DatasetInfo, StoreError> {
        let store = Store::open_read_only(store_path)?;
        let record = store.resolve_dataset(Some(dataset))?;
        let finest = record.settings.finest_level;
        let present = (0..=finest).map(|l| store.data_quads(&record.name, l)).collect::<Result<Vec<_>, _>>()?;
        let range_m = store.height_range(&record.name, finest)?.unwrap_or((0.0, 0.0));
        Ok(DatasetInfo {
            store: store_path.to_path_buf(),
            dataset: record.name,
            finest_level: finest,
            present,
            range_m,
            body: *store.body(),
            shift_m: [0.0, 0.0],
        })
    }

    /// Whether the dataset has a tile at `quad`.
    pub fn has(&self, quad: QuadId) -> bool {
        self.present.get(quad.level as usize).is_some_and(|s| s.contains(&quad))
    }

    /// The quad whose tile gives this dataset's heights at `quad`: the quad itself up to the
    /// dataset's finest level, below it the ancestor at the finest level (upsampled).
    pub fn source_quad(&self, quad: QuadId) -> QuadId {
        quad.ancestor_at(self.finest_level)
    }

    /// Whether the dataset has heights at `quad`, its own or upsampled from the finest level.
    pub fn covers(&self, quad: QuadId) -> bool {
        self.has(self.source_quad(quad))
    }
}
