//! Older project files, brought to the current version one step at a time.

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::VERSION;
use crate::layers::{LayerSpec, SourceSpec};

/// One dataset of a version-1 project (read for migration only).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DatasetSpec {
    /// The name the project uses for it.
    pub name: String,
    /// The tile store (GeoPackage), relative to the project file.
    pub store: PathBuf,
    /// The dataset's name in the store (default: `name`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Sources to import from when the store lacks the dataset.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceSpec>,
}

impl DatasetSpec {
    /// The version-2 layer: an `over` dataset layer with the same fields.
    pub fn into_layer(self) -> LayerSpec {
        LayerSpec { dataset: self.dataset, source: self.source, ..LayerSpec::dataset(&self.name, self.store) }
    }
}
/// Version 1 → 2: `datasets` (first listed wins) become `over` dataset layers, bottom to top.
pub(super) fn migrate_v1(value: &mut serde_json::Value) -> Result<(), String> {
    let object = value.as_object_mut().ok_or("a project is a JSON object")?;
    if object.contains_key("layers") {
        return Err("a version-1 project has \"datasets\", not \"layers\" (layers are version 2)".into());
    }
    let datasets: Vec<DatasetSpec> = match object.remove("datasets") {
        Some(d) => serde_json::from_value(d).map_err(|e| format!("datasets: {e}"))?,
        None => Vec::new(),
    };
    let layers: Vec<LayerSpec> = datasets.into_iter().rev().map(DatasetSpec::into_layer).collect();
    object.insert("layers".into(), serde_json::to_value(layers).map_err(|e| e.to_string())?);
    object.insert("version".into(), VERSION.into());
    Ok(())
}
