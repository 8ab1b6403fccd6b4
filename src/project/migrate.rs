//! Older project files, brought to the current version one step at a time: [`STEPS`] holds
//! one function per version, each taking a file of that version to the next, and each is tested
//! on a file of its version kept in `tests/fixtures/` (`moon-lola-v1.json`, `erzurum-erosion-v2.json`).
//! A file of a newer version than this build's is refused, never read in part.

use crate::errors::AtField;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::{FORMAT, Invalid, VERSION};
use crate::layers::{LayerSpec, SourceSpec};

/// One dataset of a version-1 project (read for migration only).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
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
        let mut layer = LayerSpec::dataset(&self.name, self.store);
        if let Some(d) = layer.as_dataset_mut() {
            d.dataset = self.dataset;
            d.source = self.source;
        }
        layer
    }
}
/// The steps: `STEPS[k]` takes a file of version k + 1 to version k + 2.
pub const STEPS: [Step; 3] = [v1_to_v2, v2_to_v3, v3_to_v4];

/// One migration step: a file's top-level object, changed in place.
pub type Step = fn(&mut serde_json::Map<String, serde_json::Value>) -> Result<(), Invalid>;

/// The format and version fields, read without building the rest.
#[derive(Deserialize)]
struct Header {
    #[serde(default)]
    format: Option<serde_json::Value>,
    #[serde(default)]
    version: Option<serde_json::Value>,
}

/// Checks the format and returns the file's version (1 to [`VERSION`]).
pub fn header(text: &str) -> Result<u32, Invalid> {
    if !text.trim_start().starts_with('{') {
        let what = if text.trim().is_empty() { "the file is empty" } else { "it does not start with '{'" };
        return Err(format!("not valid JSON for a project: a project file is a JSON object and {what}").into());
    }
    let header: Header = serde_json::from_str(text).map_err(|e| {
        // Where in the project the text stops being JSON: the field, from the typed parse.
        let mut de = serde_json::Deserializer::from_str(text);
        match serde_path_to_error::deserialize::<_, super::Project>(&mut de) {
            Err(located) if located.path().to_string() != "." => format!("not valid JSON: {}: {e}", located.path()),
            _ => format!("not valid JSON: {e}"),
        }
    })?;
    match header.format.as_ref().map(|f| f.as_str()) {
        Some(Some(FORMAT)) => {}
        Some(Some(other)) => return Err(format!("format: '{other}' is not '{FORMAT}'").into()),
        Some(None) => return Err(format!("format: must be the string \"{FORMAT}\"").into()),
        None => return Err(format!("format: no \"format\": \"{FORMAT}\" field: not a Terrafuse project").into()),
    }
    let version = header.version.ok_or("version: no \"version\" field")?;
    let version = version.as_u64().ok_or_else(|| format!("version: {version} is not a whole number"))?;
    if version > u64::from(VERSION) || version == 0 {
        return Err(format!(
            "version: {version} is not supported: this build reads versions 1 to {VERSION}; a newer Terrafuse wrote it?"
        )
        .into());
    }
    Ok(version as u32)
}

/// A JSON document walked only to refuse a key given twice in one object: the migration's
/// JSON tree would keep the last silently, where the typed parse of a current file refuses it.
struct UniqueKeys;

impl<'de> Deserialize<'de> for UniqueKeys {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<UniqueKeys, D::Error> {
        deserializer.deserialize_any(UniqueKeysVisitor)
    }
}

struct UniqueKeysVisitor;

impl<'de> serde::de::Visitor<'de> for UniqueKeysVisitor {
    type Value = UniqueKeys;

    fn expecting(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        f.write_str("JSON")
    }
    fn visit_bool<E>(self, _: bool) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_i64<E>(self, _: i64) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_u64<E>(self, _: u64) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_f64<E>(self, _: f64) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_str<E>(self, _: &str) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_unit<E>(self) -> Result<UniqueKeys, E> {
        Ok(UniqueKeys)
    }
    fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut seq: A) -> Result<UniqueKeys, A::Error> {
        while seq.next_element::<UniqueKeys>()?.is_some() {}
        Ok(UniqueKeys)
    }
    fn visit_map<A: serde::de::MapAccess<'de>>(self, mut map: A) -> Result<UniqueKeys, A::Error> {
        let mut keys = std::collections::HashSet::new();
        while let Some(key) = map.next_key::<String>()? {
            if !keys.insert(key.clone()) {
                return Err(serde::de::Error::custom(format!("duplicate field `{key}`")));
            }
            map.next_value::<UniqueKeys>()?;
        }
        Ok(UniqueKeys)
    }
}

/// An older file brought to [`VERSION`], one step at a time.
pub fn to_current(text: &str, version: u32) -> Result<serde_json::Value, Invalid> {
    let mut de = serde_json::Deserializer::from_str(text);
    serde_path_to_error::deserialize::<_, UniqueKeys>(&mut de).map_err(|e| {
        let path = e.path().to_string();
        if path == "." { e.into_inner().to_string() } else { format!("{path}: {}", e.into_inner()) }
    })?;
    let mut value: serde_json::Value = serde_json::from_str(text).at_field("not valid JSON")?;
    let object = value.as_object_mut().ok_or("a project is a JSON object")?;
    for (k, step) in STEPS.iter().enumerate().skip(version as usize - 1) {
        step(object).at_field(format_args!("migrating version {} to {}", k + 1, k + 2))?;
        object.insert("version".into(), (k as u32 + 2).into());
    }
    Ok(value)
}

/// Version 1 → 2: `datasets` (first listed wins) become `over` dataset layers, bottom to top.
fn v1_to_v2(object: &mut serde_json::Map<String, serde_json::Value>) -> Result<(), Invalid> {
    if object.contains_key("layers") {
        return Err("layers: a version-1 project has \"datasets\", not \"layers\" (layers are version 2)".into());
    }
    let datasets: Vec<DatasetSpec> = match object.remove("datasets") {
        Some(d) => serde_json::from_value(d).at_field("datasets")?,
        None => Vec::new(),
    };
    let layers: Vec<LayerSpec> = datasets.into_iter().rev().map(DatasetSpec::into_layer).collect();
    object.insert("layers".into(), serde_json::to_value(layers).map_err(|e| e.to_string())?);
    Ok(())
}

/// Version 3 → 4: one order for every box. An erosion run's `region` was
/// `[lat_min, lon_min, lat_max, lon_max]`; it becomes `[west, south, east, north]` like
/// `comparison` boxes, check regions and extents (GDAL's `-te` order).
fn v3_to_v4(object: &mut serde_json::Map<String, serde_json::Value>) -> Result<(), Invalid> {
    let Some(layers) = object.get_mut("layers").and_then(|l| l.as_array_mut()) else { return Ok(()) };
    for (k, layer) in layers.iter_mut().enumerate() {
        let Some(runs) = layer.get_mut("runs").and_then(|r| r.as_array_mut()) else { continue };
        for (r, run) in runs.iter_mut().enumerate() {
            let Some(region) = run.get_mut("region") else { continue };
            let values: Option<Vec<f64>> = region.as_array().map(|a| a.iter().filter_map(|v| v.as_f64()).collect());
            let [lat0, lon0, lat1, lon1] = values.as_deref().unwrap_or_default() else {
                return Err(format!("layers[{k}].runs[{r}].region: {region} is not four numbers").into());
            };
            *region = serde_json::json!([lon0, lat0, lon1, lat1]);
        }
    }
    Ok(())
}

/// Version 2 → 3: `checks` (expected digests) are new and optional; nothing else changed, so
/// the step only refuses a version-2 file that already has them.
fn v2_to_v3(object: &mut serde_json::Map<String, serde_json::Value>) -> Result<(), Invalid> {
    if object.contains_key("checks") {
        return Err("checks: a version-2 project has no checks (they are version 3)".into());
    }
    Ok(())
}
