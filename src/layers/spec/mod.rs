//! The layer stack as a project file holds it: one [`LayerSpec`] per layer, bottom to top.
//!
//! ```json
//! { "name": "srtm", "kind": "dataset", "store": "stores/e.gpkg", "blend": "over",
//!   "extent": { "box": [40.0, 39.2, 40.8, 40.0] }, "feather_m": 5000 }
//! { "name": "detail", "kind": "procedural", "blend": "add",
//!   "noise": { "type": "fbm", "seed": 7, "amplitude_m": 30, "wavelength_m": 2000, "octaves": 8 } }
//! { "name": "sea", "kind": "constant", "height_m": 0, "blend": "max" }
//! { "name": "dh", "kind": "difference", "of": ["srtm", ["copernicus", "detail"]],
//!   "style": { "percentile": 98, "isolines_m": 5 } }
//! ```
//!
//! Every layer has the common fields ([`LayerSpec`]) and its kind's own ([`LayerPayload`]: `store`,
//! `dataset`, `source`, `shift_m`, `feather_edge_m`, `correction` for datasets, `height_m` for constants,
//! `noise` for procedural layers, `of` and `style` for differences, `strokes` for edit layers,
//! `runs` for erosion layers), so a constant with strokes cannot be written down; a file that
//! has one is refused by name when it is read ([`file`]). [`LayerSpec::check`] checks what a type
//! cannot: ranges, limits, and the blend mode a kind needs.

mod check;
mod file;
mod history;

use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::LayerError;

/// What a layer is.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum LayerKind {
    /// A dataset of a tile store.
    Dataset,
    /// Procedural noise on the ellipsoid.
    Procedural,
    /// One height everywhere (a sea level, a datum plane).
    Constant,
    /// A − B of two operands, drawn over the terrain with a diverging colour map; changes no
    /// height (see [`DifferenceStyle`]).
    Difference,
    /// Height deltas brushed by recorded strokes (`crate::edit`), blended with `add`.
    Edit,
    /// The change of height made by recorded erosion runs (`crate::erosion`), blended with `add`.
    Erosion,
}

impl LayerKind {
    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            LayerKind::Dataset => "dataset",
            LayerKind::Procedural => "procedural",
            LayerKind::Constant => "constant",
            LayerKind::Difference => "difference",
            LayerKind::Edit => "edit",
            LayerKind::Erosion => "erosion",
        }
    }
}

/// How a layer folds into the running height h (v its value, α its coverage).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum BlendMode {
    /// h = v where h has no data, else h + α(v − h).
    #[default]
    Over,
    /// h + α·v where h has data (detail, offsets); nothing where it has none.
    Add,
    /// h + α(min(h, v) − h); h = v where h has no data.
    Min,
    /// h + α(max(h, v) − h); h = v where h has no data.
    Max,
    /// Consecutive `mean` layers form one group: Σ wᵢαᵢvᵢ / Σ wᵢαᵢ, applied with `over` at the
    /// group's coverage max αᵢ.
    Mean,
}

impl BlendMode {
    /// Every mode, in the order the GUI lists them.
    pub const ALL: [BlendMode; 5] = [BlendMode::Over, BlendMode::Add, BlendMode::Min, BlendMode::Max, BlendMode::Mean];

    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            BlendMode::Over => "over",
            BlendMode::Add => "add",
            BlendMode::Min => "min",
            BlendMode::Max => "max",
            BlendMode::Mean => "mean",
        }
    }
}

/// Where a layer applies: a longitude/latitude box or polygon, degrees. Edges are straight in
/// longitude and latitude (a box's edges follow parallels and meridians).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case", deny_unknown_fields)]
pub enum ExtentSpec {
    /// `[west, south, east, north]`, degrees (GDAL's xmin, ymin, xmax, ymax order); east < west
    /// crosses the antimeridian.
    Box([f64; 4]),
    /// `[[lon, lat], …]`, degrees, at least three vertices, closed implicitly (GeoJSON order).
    /// Longitudes may run past ±180 to cross the antimeridian continuously.
    Polygon(Vec<[f64; 2]>),
}

/// Which fractal.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum NoiseType {
    /// Fractional Brownian motion: Σ gainᵏ·n(P·lacunarityᵏ/λ), values in ±amplitude·Σ gainᵏ.
    #[default]
    Fbm,
    /// Ridged multifractal (Musgrave): Σ gainᵏ·wₖ(1 − |nₖ|)², wₖ₊₁ = clamp(2·wₖ(1 − |nₖ|)², 0, 1);
    /// values in [0, amplitude·Σ gainᵏ] (ridges raise the terrain).
    Ridged,
}

/// Where procedural detail goes.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum DetailWhere {
    /// Every octave everywhere.
    #[default]
    Everywhere,
    /// Only octaves finer than the data below: an octave of wavelength λ has weight
    /// 1 − clamp(λ/s − 1, 0, 1), with s the sample spacing of the finest dataset that gave the
    /// running height its value (all octaves where there is no data).
    BeyondData,
}

/// Procedural noise, a function of the position on the ellipsoid (not of the quad).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct NoiseSpec {
    /// `fbm` or `ridged`.
    #[serde(rename = "type", default)]
    pub noise_type: NoiseType,
    /// Seed: different seeds give unrelated noise.
    #[serde(default)]
    pub seed: u32,
    /// Amplitude of the first octave, metres.
    pub amplitude_m: f64,
    /// Wavelength of the first octave, metres.
    pub wavelength_m: f64,
    /// Octaves.
    #[serde(default = "default_octaves")]
    pub octaves: u32,
    /// Wavelength ratio between octaves (> 1).
    #[serde(default = "default_lacunarity")]
    pub lacunarity: f64,
    /// Amplitude ratio between octaves (0 < gain < 1).
    #[serde(default = "default_gain")]
    pub gain: f64,
    /// Where the detail goes.
    #[serde(rename = "where", default)]
    pub placement: DetailWhere,
}

fn default_octaves() -> u32 {
    8
}

fn default_lacunarity() -> f64 {
    2.0
}

fn default_gain() -> f64 {
    0.5
}

/// One side of a difference or a comparison: a layer alone (its value wherever it has data, its
/// own scale, offset, shift, valid range and extent; shown, `over`, whatever the project's
/// visibility) or a composed group (the listed layers folded bottom to top in the stack's order by
/// their own blend modes and opacities, shown).
///
/// In files a layer is its name and a group a list of names: `"srtm"`, `["srtm", "detail"]`. On
/// the command line a group is its names joined by `+` (`srtm+detail`).
#[derive(Clone, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(untagged)]
pub enum Operand {
    /// One layer alone.
    Layer(String),
    /// Several layers composed.
    Group(Vec<String>),
}

impl Operand {
    /// From the command line's form: `NAME`, or `NAME+NAME+…` for a group (a layer whose name
    /// contains `+` is taken whole when `known` has it).
    pub fn parse(text: &str, known: &dyn Fn(&str) -> bool) -> Operand {
        if known(text) || !text.contains('+') {
            Operand::Layer(text.to_string())
        } else {
            Operand::Group(text.split('+').map(|n| n.trim().to_string()).collect())
        }
    }

    /// The layer names it reads.
    pub fn names(&self) -> Vec<&str> {
        match self {
            Operand::Layer(n) => vec![n.as_str()],
            Operand::Group(names) => names.iter().map(String::as_str).collect(),
        }
    }

    /// Its command-line form.
    pub fn label(&self) -> String {
        self.names().join("+")
    }
}

impl std::fmt::Display for Operand {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(&self.label())
    }
}

/// How a difference layer is drawn. The range is symmetric: dh = ±range maps to the ends of the
/// diverging colour map (red below zero, blue above, white at zero, as xDEM plots dh); without a
/// `range_m` it is the `percentile` of |dh| over the operands' overlap (computed by the tools
/// that open the project: [`crate::compare::difference_range`]).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DifferenceStyle {
    /// Half the colour map's span, metres (absent: from `percentile`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<f64>,
    /// Percentile of |dh| that sets the range when `range_m` is absent (0–100, default 98).
    #[serde(default = "default_percentile")]
    pub percentile: f64,
    /// Isolines of dh at ±k × this many metres, k ≥ 1 (0: none; zero is the map's white).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub isolines_m: f64,
}

fn default_percentile() -> f64 {
    98.0
}

impl Default for DifferenceStyle {
    fn default() -> DifferenceStyle {
        DifferenceStyle { range_m: None, percentile: default_percentile(), isolines_m: 0.0 }
    }
}

/// Where a dataset's store comes from when it is not there yet: the source files to import.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SourceSpec {
    /// DEM files (relative to the project file).
    pub files: Vec<PathBuf>,
    /// Finest level to import (default: the level that matches the source's resolution).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub max_level: Option<u8>,
    /// Vertical datum of the source: `ellipsoidal` (default), `egm96`, `egm2008`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub vertical_datum: Option<String>,
}

/// One layer of the stack: the fields every layer has, and its kind's own ([`LayerPayload`]).
///
/// In files the kind's fields sit beside the common ones, tagged by `kind`; a field of another
/// kind is refused by name ([`file`]). `scale`, `offset_m` and `valid_range_m` shape the value of
/// every kind that gives heights; a difference gives none and keeps them at the identity.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct LayerSpec {
    /// Unique within the project.
    pub name: String,
    /// Hidden layers cost nothing and change nothing.
    #[serde(default = "yes")]
    pub visible: bool,
    /// How the layer folds into the heights below.
    #[serde(default)]
    pub blend: BlendMode,
    /// 0–1.
    #[serde(default = "one")]
    pub opacity: f64,
    /// Weight in a `mean` group (≥ 0).
    #[serde(default = "one")]
    pub weight: f64,
    /// Raw value × scale + offset (datum and unit fixes).
    #[serde(default = "one")]
    pub scale: f64,
    /// Metres added after scaling.
    #[serde(default)]
    pub offset_m: f64,
    /// Values (after scale and offset) outside `[min, max]` metres are no data.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub valid_range_m: Option<[f64; 2]>,
    /// Where the layer applies (default: everywhere).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub extent: Option<ExtentSpec>,
    /// Fade-in distance inside the extent's edge, metres on the ellipsoid.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub feather_m: f64,
    /// What the layer is, with its kind's own fields.
    #[serde(flatten)]
    pub payload: LayerPayload,
}

/// A layer's kind and the fields only that kind has. What each kind answers to the consumers
/// (where it reaches, how fine its detail goes, what its value reads) is in [`super::kind`].
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
#[serde(tag = "kind", rename_all = "snake_case")]
pub enum LayerPayload {
    /// A dataset of a tile store.
    Dataset(DatasetLayer),
    /// Procedural noise on the ellipsoid.
    Procedural(ProceduralLayer),
    /// One height everywhere (a sea level, a datum plane).
    Constant(ConstantLayer),
    /// A − B of two operands, drawn over the terrain with a diverging colour map; changes no
    /// height.
    Difference(DifferenceLayer),
    /// Height deltas brushed by recorded strokes (`crate::edit`), blended with `add`.
    Edit(EditLayer),
    /// The change of height made by recorded erosion runs (`crate::erosion`), blended with `add`.
    Erosion(ErosionLayer),
}

/// A dataset layer's own fields.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct DatasetLayer {
    /// The tile store (GeoPackage), relative to the project file.
    pub store: PathBuf,
    /// Its name in the store (default: the layer's name).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Sources to import from when the store lacks it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceSpec>,
    /// Moves the layer east and north by this much, metres in each sample's local frame (what
    /// `terrafuse coregister --apply` writes): the value at p is the dataset's at p − shift.
    #[serde(default, skip_serializing_if = "is_zero_pair")]
    pub shift_m: [f64; 2],
    /// Fades the layer in from the dataset's own no-data edge over this distance on the
    /// surface, metres (0: no fade; see [`super::edge`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub feather_edge_m: f64,
    /// Bias corrections taken off the layer's value, in order (what `terrafuse coregister
    /// --pipeline … --apply` writes for its deramp, terrain and directional steps; see
    /// docs/comparison.md).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub correction: Vec<super::correction::Bias>,
}

/// A procedural layer's own fields.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct ProceduralLayer {
    /// The noise.
    pub noise: NoiseSpec,
}

/// A constant layer's own fields.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct ConstantLayer {
    /// The height, metres.
    pub height_m: f64,
}

/// A difference layer's own fields.
#[derive(Clone, Debug, PartialEq, Serialize, schemars::JsonSchema)]
pub struct DifferenceLayer {
    /// The operands A and B (the layer draws A − B).
    pub of: [Operand; 2],
    /// How dh is drawn.
    #[serde(default)]
    pub style: DifferenceStyle,
}

/// An edit layer's own fields: its strokes and undo position.
#[derive(Clone, Debug, Default, PartialEq, Serialize, schemars::JsonSchema)]
pub struct EditLayer {
    /// The strokes, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub strokes: Vec<crate::edit::Stroke>,
    /// The undo position: `strokes[..applied]` are in effect (absent: all of them); the rest can
    /// be redone until a new one replaces them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied: Option<usize>,
}

/// An erosion layer's own fields: its runs and undo position.
#[derive(Clone, Debug, Default, PartialEq, Serialize, schemars::JsonSchema)]
pub struct ErosionLayer {
    /// The runs, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub runs: Vec<crate::erosion::operation::Operation>,
    /// The undo position: `runs[..applied]` are in effect (absent: all of them).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied: Option<usize>,
}

impl<'de> Deserialize<'de> for LayerSpec {
    /// Through the flat record of [`file`], so a field of another kind is refused by name.
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<LayerSpec, D::Error> {
        let record = file::LayerRecord::deserialize(deserializer)?;
        LayerSpec::try_from(record).map_err(serde::de::Error::custom)
    }
}

fn yes() -> bool {
    true
}

fn one() -> f64 {
    1.0
}

fn is_zero_pair(v: &[f64; 2]) -> bool {
    *v == [0.0, 0.0]
}

/// Most strokes an edit layer holds: ten times the longest session measured (10⁵ strokes load
/// in about a second; see BENCHMARKS.md).
pub const MAX_STROKES: usize = 1_000_000;

/// Most runs an erosion layer holds.
pub const MAX_RUNS: usize = 10_000;

/// The largest horizontal shift of a layer, metres (co-registration shifts are a few pixels).
pub const MAX_SHIFT_M: f64 = 10_000.0;

fn is_zero(v: &f64) -> bool {
    *v == 0.0
}

/// The finest wavelength procedural noise may have, as a fraction of the semi-major axis: the
/// GPU's lattice indices are 32-bit integers (|P|/λ < 2³¹).
pub const MIN_WAVELENGTH_OF_RADIUS: f64 = 1.0 / (1u64 << 30) as f64;

/// Most octaves a procedural layer may have.
pub const MAX_OCTAVES: u32 = 24;

/// The error for an operation of one kind asked of a layer of another.
fn not_a(name: &str, kind: LayerKind, wanted: &str) -> LayerError {
    LayerError::field(name, "kind", format!("a {} layer is not an {wanted} layer", kind.name()))
}

impl LayerSpec {
    /// A layer of `payload` with the common fields' defaults (blend `add` for the kinds that
    /// add detail or deltas).
    pub fn new(name: &str, payload: LayerPayload) -> LayerSpec {
        let blend = match payload {
            LayerPayload::Procedural(_) | LayerPayload::Edit(_) | LayerPayload::Erosion(_) => BlendMode::Add,
            LayerPayload::Dataset(_) | LayerPayload::Constant(_) | LayerPayload::Difference(_) => BlendMode::Over,
        };
        LayerSpec {
            name: name.into(),
            visible: true,
            blend,
            opacity: 1.0,
            weight: 1.0,
            scale: 1.0,
            offset_m: 0.0,
            valid_range_m: None,
            extent: None,
            feather_m: 0.0,
            payload,
        }
    }

    /// A dataset layer with the defaults.
    pub fn dataset(name: &str, store: impl Into<PathBuf>) -> LayerSpec {
        LayerSpec::new(
            name,
            LayerPayload::Dataset(DatasetLayer {
                store: store.into(),
                dataset: None,
                source: None,
                shift_m: [0.0, 0.0],
                feather_edge_m: 0.0,
                correction: Vec::new(),
            }),
        )
    }

    /// A constant layer with the defaults.
    pub fn constant(name: &str, height_m: f64) -> LayerSpec {
        LayerSpec::new(name, LayerPayload::Constant(ConstantLayer { height_m }))
    }

    /// A procedural layer with the defaults (blend `add`).
    pub fn procedural(name: &str, noise: NoiseSpec) -> LayerSpec {
        LayerSpec::new(name, LayerPayload::Procedural(ProceduralLayer { noise }))
    }

    /// A difference layer A − B with the default style.
    pub fn difference(name: &str, a: Operand, b: Operand) -> LayerSpec {
        LayerSpec::new(
            name,
            LayerPayload::Difference(DifferenceLayer { of: [a, b], style: DifferenceStyle::default() }),
        )
    }

    /// An empty edit layer (blend `add`).
    pub fn edit(name: &str) -> LayerSpec {
        LayerSpec::new(name, LayerPayload::Edit(EditLayer::default()))
    }

    /// An empty erosion layer (blend `add`).
    pub fn erosion(name: &str) -> LayerSpec {
        LayerSpec::new(name, LayerPayload::Erosion(ErosionLayer::default()))
    }

    /// The same dataset layer reading dataset `name` of its store (other kinds unchanged).
    pub fn with_dataset_name(mut self, name: &str) -> LayerSpec {
        if let Some(d) = self.as_dataset_mut() {
            d.dataset = Some(name.into());
        }
        self
    }

    /// The same dataset layer moved by `shift_m` (east, north metres; other kinds unchanged).
    pub fn with_shift_m(mut self, shift_m: [f64; 2]) -> LayerSpec {
        if let Some(d) = self.as_dataset_mut() {
            d.shift_m = shift_m;
        }
        self
    }

    /// The same dataset layer faded in from its no-data edge over `feather_m` metres (other
    /// kinds unchanged).
    pub fn with_feather_edge_m(mut self, feather_m: f64) -> LayerSpec {
        if let Some(d) = self.as_dataset_mut() {
            d.feather_edge_m = feather_m;
        }
        self
    }

    /// What the layer is.
    pub fn kind(&self) -> LayerKind {
        match self.payload {
            LayerPayload::Dataset(_) => LayerKind::Dataset,
            LayerPayload::Procedural(_) => LayerKind::Procedural,
            LayerPayload::Constant(_) => LayerKind::Constant,
            LayerPayload::Difference(_) => LayerKind::Difference,
            LayerPayload::Edit(_) => LayerKind::Edit,
            LayerPayload::Erosion(_) => LayerKind::Erosion,
        }
    }

    /// A dataset layer's own fields.
    pub fn as_dataset(&self) -> Option<&DatasetLayer> {
        match &self.payload {
            LayerPayload::Dataset(d) => Some(d),
            _ => None,
        }
    }

    /// A dataset layer's own fields, to change.
    pub fn as_dataset_mut(&mut self) -> Option<&mut DatasetLayer> {
        match &mut self.payload {
            LayerPayload::Dataset(d) => Some(d),
            _ => None,
        }
    }

    /// A procedural layer's noise.
    pub fn noise(&self) -> Option<&NoiseSpec> {
        match &self.payload {
            LayerPayload::Procedural(p) => Some(&p.noise),
            _ => None,
        }
    }

    /// A difference layer's own fields.
    pub fn as_difference(&self) -> Option<&DifferenceLayer> {
        match &self.payload {
            LayerPayload::Difference(d) => Some(d),
            _ => None,
        }
    }

    /// A difference layer's own fields, to change.
    pub fn as_difference_mut(&mut self) -> Option<&mut DifferenceLayer> {
        match &mut self.payload {
            LayerPayload::Difference(d) => Some(d),
            _ => None,
        }
    }

    /// An edit layer's own fields.
    pub fn as_edit(&self) -> Option<&EditLayer> {
        match &self.payload {
            LayerPayload::Edit(e) => Some(e),
            _ => None,
        }
    }

    /// An edit layer's own fields, to change.
    pub fn as_edit_mut(&mut self) -> Option<&mut EditLayer> {
        match &mut self.payload {
            LayerPayload::Edit(e) => Some(e),
            _ => None,
        }
    }

    /// An erosion layer's own fields.
    pub fn as_erosion(&self) -> Option<&ErosionLayer> {
        match &self.payload {
            LayerPayload::Erosion(e) => Some(e),
            _ => None,
        }
    }

    /// An erosion layer's own fields, to change.
    pub fn as_erosion_mut(&mut self) -> Option<&mut ErosionLayer> {
        match &mut self.payload {
            LayerPayload::Erosion(e) => Some(e),
            _ => None,
        }
    }

    /// A dataset layer's horizontal shift, metres east and north (zero for other kinds).
    pub fn shift_m(&self) -> [f64; 2] {
        self.as_dataset().map_or([0.0, 0.0], |d| d.shift_m)
    }

    /// A dataset layer's edge feather, metres (zero for other kinds).
    pub fn feather_edge_m(&self) -> f64 {
        self.as_dataset().map_or(0.0, |d| d.feather_edge_m)
    }

    /// An edit layer's strokes, all of them (none for other kinds).
    pub fn strokes(&self) -> &[crate::edit::Stroke] {
        self.as_edit().map_or(&[], |e| &e.strokes)
    }

    /// An erosion layer's runs, all of them (none for other kinds).
    pub fn runs(&self) -> &[crate::erosion::operation::Operation] {
        self.as_erosion().map_or(&[], |e| &e.runs)
    }

    /// Moves a dataset layer by `east_m`, `north_m` more (a co-registration applied). An error on
    /// any other kind.
    pub fn shift_by(&mut self, east_m: f64, north_m: f64) -> Result<(), LayerError> {
        let (name, kind) = (self.name.clone(), self.kind());
        let d = self.as_dataset_mut().ok_or_else(|| {
            LayerError::field(&name, "shift_m", format!("moves a dataset; a {} layer has none to move", kind.name()))
        })?;
        d.shift_m = [d.shift_m[0] + east_m, d.shift_m[1] + north_m];
        Ok(())
    }

    /// A difference layer's style (the default for other kinds).
    pub fn difference_style(&self) -> DifferenceStyle {
        self.as_difference().map(|d| d.style.clone()).unwrap_or_default()
    }

    /// A dataset layer's dataset name inside its store (the layer's name by default).
    pub fn store_dataset(&self) -> &str {
        self.as_dataset().and_then(|d| d.dataset.as_deref()).unwrap_or(&self.name)
    }
}
