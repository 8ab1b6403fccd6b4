//! How a layer is read from a project file: every field of every kind side by side, tagged by
//! `kind` (the flat form files have always had), read in one pass and then turned into the typed
//! [`LayerSpec`]. A field of another kind is refused by name ("layer 'sea': strokes: is not a
//! field of a constant layer") rather than by serde's generic "unknown field".
//!
//! Why not serde's internally tagged enum: it buffers the whole layer in an intermediate tree
//! before it can look at `kind` (a 10⁵-stroke edit layer twice in memory), and its refusal of a
//! misplaced field lists the kind's fields without saying which kind the layer is.

use std::path::PathBuf;

use serde::Deserialize;

use super::{
    BlendMode, ConstantLayer, DatasetLayer, DifferenceLayer, DifferenceStyle, EditLayer, ErosionLayer, ExtentSpec,
    LayerKind, LayerPayload, LayerSpec, NoiseSpec, Operand, ProceduralLayer, SourceSpec,
};
use crate::layers::LayerError;

/// One layer as a file holds it.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct LayerRecord {
    name: String,
    kind: LayerKind,
    #[serde(default = "super::yes")]
    visible: bool,
    #[serde(default)]
    blend: BlendMode,
    #[serde(default = "super::one")]
    opacity: f64,
    #[serde(default = "super::one")]
    weight: f64,
    #[serde(default = "super::one")]
    scale: f64,
    #[serde(default)]
    offset_m: f64,
    #[serde(default)]
    valid_range_m: Option<[f64; 2]>,
    #[serde(default)]
    extent: Option<ExtentSpec>,
    #[serde(default)]
    feather_m: f64,
    // The kinds' own fields.
    #[serde(default)]
    feather_edge_m: Option<f64>,
    #[serde(default)]
    shift_m: Option<[f64; 2]>,
    #[serde(default)]
    correction: Option<Vec<crate::layers::correction::Bias>>,
    #[serde(default)]
    store: Option<PathBuf>,
    #[serde(default)]
    dataset: Option<String>,
    #[serde(default)]
    source: Option<SourceSpec>,
    #[serde(default)]
    height_m: Option<f64>,
    #[serde(default)]
    noise: Option<NoiseSpec>,
    #[serde(default)]
    of: Option<[Operand; 2]>,
    #[serde(default)]
    style: Option<DifferenceStyle>,
    #[serde(default)]
    strokes: Option<Vec<crate::edit::Stroke>>,
    #[serde(default)]
    applied: Option<usize>,
    #[serde(default)]
    runs: Option<Vec<crate::erosion::operation::Operation>>,
}

impl LayerKind {
    /// The fields only this kind has (beside the common ones).
    pub fn own_fields(self) -> &'static [&'static str] {
        match self {
            LayerKind::Dataset => &["store", "dataset", "source", "shift_m", "feather_edge_m", "correction"],
            LayerKind::Procedural => &["noise"],
            LayerKind::Constant => &["height_m"],
            LayerKind::Difference => &["of", "style"],
            LayerKind::Edit => &["strokes", "applied"],
            LayerKind::Erosion => &["runs", "applied"],
        }
    }
}

impl TryFrom<LayerRecord> for LayerSpec {
    type Error = LayerError;

    fn try_from(r: LayerRecord) -> Result<LayerSpec, LayerError> {
        let kind = r.kind;
        // A dataset's shift and edge feather at zero are what older files wrote for every kind.
        let present = [
            ("store", r.store.is_some()),
            ("dataset", r.dataset.is_some()),
            ("source", r.source.is_some()),
            ("shift_m", r.shift_m.is_some_and(|s| s != [0.0, 0.0])),
            ("feather_edge_m", r.feather_edge_m.is_some_and(|f| f != 0.0)),
            ("correction", r.correction.as_ref().is_some_and(|c| !c.is_empty())),
            ("height_m", r.height_m.is_some()),
            ("noise", r.noise.is_some()),
            ("of", r.of.is_some()),
            ("style", r.style.is_some()),
            ("strokes", r.strokes.as_ref().is_some_and(|s| !s.is_empty())),
            ("applied", r.applied.is_some()),
            ("runs", r.runs.as_ref().is_some_and(|s| !s.is_empty())),
        ];
        let name = r.name.clone();
        let wrong = |field: &str| LayerError::field(&name, field, format!("is not a field of a {} layer", kind.name()));
        if let Some((field, _)) = present.iter().find(|(field, set)| *set && !kind.own_fields().contains(field)) {
            return Err(wrong(field));
        }
        let missing =
            |field: &str, what: &str| LayerError::field(&name, field, format!("a {} layer needs {what}", kind.name()));
        let payload = match kind {
            LayerKind::Dataset => LayerPayload::Dataset(DatasetLayer {
                store: r.store.ok_or_else(|| missing("store", "its store"))?,
                dataset: r.dataset,
                source: r.source,
                shift_m: r.shift_m.unwrap_or([0.0, 0.0]),
                feather_edge_m: r.feather_edge_m.unwrap_or(0.0),
                correction: r.correction.unwrap_or_default(),
            }),
            LayerKind::Procedural => LayerPayload::Procedural(ProceduralLayer {
                noise: r.noise.ok_or_else(|| missing("noise", "its noise settings"))?,
            }),
            LayerKind::Constant => LayerPayload::Constant(ConstantLayer {
                height_m: r.height_m.ok_or_else(|| missing("height_m", "its height"))?,
            }),
            LayerKind::Difference => LayerPayload::Difference(DifferenceLayer {
                of: r.of.ok_or_else(|| missing("of", "its operands [A, B]"))?,
                style: r.style.unwrap_or_default(),
            }),
            LayerKind::Edit => {
                LayerPayload::Edit(EditLayer { strokes: r.strokes.unwrap_or_default(), applied: r.applied })
            }
            LayerKind::Erosion => {
                LayerPayload::Erosion(ErosionLayer { runs: r.runs.unwrap_or_default(), applied: r.applied })
            }
        };
        Ok(LayerSpec {
            name: r.name,
            visible: r.visible,
            blend: r.blend,
            opacity: r.opacity,
            weight: r.weight,
            scale: r.scale,
            offset_m: r.offset_m,
            valid_range_m: r.valid_range_m,
            extent: r.extent,
            feather_m: r.feather_m,
            payload,
        })
    }
}
