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
//! Every layer has the common fields; the kind-specific ones (`store`, `dataset`, `source` for
//! datasets, `height_m` for constants, `noise` for procedural layers, `of` and `style` for
//! differences) are refused on other kinds, so a misplaced field is an error rather than silently
//! ignored. A difference layer changes no height, so it refuses the fields that shape one.

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

    /// Whether the layer's heights are deltas kept in a raster made from its recorded operations
    /// (edit and erosion layers).
    pub fn holds_deltas(self) -> bool {
        matches!(self, LayerKind::Edit | LayerKind::Erosion)
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

/// One layer of the stack.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LayerSpec {
    /// Unique within the project.
    pub name: String,
    /// `dataset`, `procedural` or `constant`.
    pub kind: LayerKind,
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
    /// Dataset: fades the layer in from the dataset's own no-data edge over this distance on
    /// the surface, metres (0: no fade; see [`super::edge`]).
    #[serde(default, skip_serializing_if = "is_zero")]
    pub feather_edge_m: f64,
    /// Dataset: moves the layer east and north by this much, metres in each sample's local frame
    /// (what `terrafuse coregister --apply` writes): the value at p is the dataset's at p − shift.
    #[serde(default, skip_serializing_if = "is_zero_pair")]
    pub shift_m: [f64; 2],
    /// Dataset: the tile store (GeoPackage), relative to the project file.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub store: Option<PathBuf>,
    /// Dataset: its name in the store (default: `name`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dataset: Option<String>,
    /// Dataset: sources to import from when the store lacks it.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub source: Option<SourceSpec>,
    /// Constant: the height, metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_m: Option<f64>,
    /// Procedural: the noise.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub noise: Option<NoiseSpec>,
    /// Difference: the operands A and B (the layer draws A − B).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub of: Option<[Operand; 2]>,
    /// Difference: how dh is drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub style: Option<DifferenceStyle>,
    /// Edit: the strokes, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub strokes: Vec<crate::edit::Stroke>,
    /// Edit and erosion: the undo position: `strokes[..applied]` (or `runs[..applied]`) are in
    /// effect (absent: all of them); the rest can be redone until a new one replaces them.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub applied: Option<usize>,
    /// Erosion: the runs, in order.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub runs: Vec<crate::erosion::operation::Operation>,
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

impl LayerSpec {
    /// A dataset layer with the defaults.
    pub fn dataset(name: &str, store: impl Into<PathBuf>) -> LayerSpec {
        LayerSpec { store: Some(store.into()), ..LayerSpec::bare(name, LayerKind::Dataset) }
    }

    /// A constant layer with the defaults.
    pub fn constant(name: &str, height_m: f64) -> LayerSpec {
        LayerSpec { height_m: Some(height_m), ..LayerSpec::bare(name, LayerKind::Constant) }
    }

    /// A procedural layer with the defaults (blend `add`).
    pub fn procedural(name: &str, noise: NoiseSpec) -> LayerSpec {
        LayerSpec { noise: Some(noise), blend: BlendMode::Add, ..LayerSpec::bare(name, LayerKind::Procedural) }
    }

    /// A difference layer A − B with the default style.
    pub fn difference(name: &str, a: Operand, b: Operand) -> LayerSpec {
        LayerSpec {
            of: Some([a, b]),
            style: Some(DifferenceStyle::default()),
            ..LayerSpec::bare(name, LayerKind::Difference)
        }
    }

    /// An empty edit layer (blend `add`).
    pub fn edit(name: &str) -> LayerSpec {
        LayerSpec { blend: BlendMode::Add, ..LayerSpec::bare(name, LayerKind::Edit) }
    }

    /// An empty erosion layer (blend `add`).
    pub fn erosion(name: &str) -> LayerSpec {
        LayerSpec { blend: BlendMode::Add, ..LayerSpec::bare(name, LayerKind::Erosion) }
    }

    /// An erosion layer's runs in effect (those before its undo position).
    pub fn applied_runs(&self) -> &[crate::erosion::operation::Operation] {
        &self.runs[..self.applied.unwrap_or(self.runs.len()).min(self.runs.len())]
    }

    /// How many of an edit or erosion layer's operations there are.
    pub fn operations(&self) -> usize {
        self.strokes.len() + self.runs.len()
    }

    /// Moves an edit or erosion layer's undo position back by `undo` or forward by `redo` of its
    /// operations (strokes or runs); returns how many are in effect after it. The errors name the
    /// command-line flag.
    pub fn move_applied(&mut self, undo: Option<usize>, redo: Option<usize>) -> Result<usize, String> {
        let total = self.operations();
        let what = if self.kind == LayerKind::Erosion { "runs" } else { "strokes" };
        let applied = self.applied.unwrap_or(total).min(total);
        let to = match (undo, redo) {
            (Some(n), None) => {
                applied.checked_sub(n).ok_or_else(|| format!("--undo {n}: only {applied} {what} are applied"))?
            }
            (None, Some(n)) if applied + n <= total => applied + n,
            (None, Some(n)) => return Err(format!("--redo {n}: only {} {what} can be redone", total - applied)),
            _ => return Err("give either --undo N or --redo N".into()),
        };
        self.applied = (to < total).then_some(to);
        Ok(to)
    }

    /// An edit layer's strokes in effect (those before its undo position).
    pub fn applied_strokes(&self) -> &[crate::edit::Stroke] {
        &self.strokes[..self.applied.unwrap_or(self.strokes.len()).min(self.strokes.len())]
    }

    /// A difference layer's style (the default where the file has none).
    pub fn difference_style(&self) -> DifferenceStyle {
        self.style.clone().unwrap_or_default()
    }

    fn bare(name: &str, kind: LayerKind) -> LayerSpec {
        LayerSpec {
            name: name.into(),
            kind,
            visible: true,
            blend: BlendMode::Over,
            opacity: 1.0,
            weight: 1.0,
            scale: 1.0,
            offset_m: 0.0,
            valid_range_m: None,
            extent: None,
            feather_m: 0.0,
            feather_edge_m: 0.0,
            shift_m: [0.0, 0.0],
            store: None,
            dataset: None,
            source: None,
            height_m: None,
            noise: None,
            of: None,
            style: None,
            strokes: Vec::new(),
            applied: None,
            runs: Vec::new(),
        }
    }

    /// The dataset's name inside its store.
    pub fn store_dataset(&self) -> &str {
        self.dataset.as_deref().unwrap_or(&self.name)
    }

    /// Checks what serde cannot: ranges, and that each kind has its fields and no other kind's.
    /// `radius_m` is the body's semi-major axis (it bounds the finest noise wavelength).
    pub fn check(&self, radius_m: f64) -> Result<(), LayerError> {
        let bad = |field: &str, problem: String| Err(LayerError::field(&self.name, field, problem));
        if self.name.trim().is_empty() {
            return bad("name", "must not be empty".into());
        }
        if !(0.0..=1.0).contains(&self.opacity) {
            return bad("opacity", format!("{} must lie in [0, 1]", self.opacity));
        }
        if !(self.weight.is_finite() && self.weight >= 0.0) {
            return bad("weight", format!("{} must be a finite number ≥ 0", self.weight));
        }
        if !self.scale.is_finite() {
            return bad("scale", format!("{} must be finite", self.scale));
        }
        if !self.offset_m.is_finite() {
            return bad("offset_m", format!("{} must be finite", self.offset_m));
        }
        if let Some([lo, hi]) = self.valid_range_m
            && !(lo <= hi && !lo.is_nan() && !hi.is_nan())
        {
            return bad("valid_range_m", format!("[{lo}, {hi}] must be increasing"));
        }
        if !(self.feather_m.is_finite() && self.feather_m >= 0.0) {
            return bad("feather_m", format!("{} must be a distance ≥ 0 in metres", self.feather_m));
        }
        if self.feather_m > 0.0 && self.extent.is_none() {
            return bad("feather_m", "feathers the extent's edge, but the layer has no extent".into());
        }
        if let Some(extent) = &self.extent {
            check_extent(extent).map_err(|p| LayerError::field(&self.name, "extent", p))?;
        }
        let widest = super::edge::quad_width_m(radius_m, 0);
        if !(self.feather_edge_m.is_finite() && self.feather_edge_m >= 0.0 && self.feather_edge_m <= widest) {
            return bad(
                "feather_edge_m",
                format!(
                    "{} must be a distance in metres from 0 to {widest:.0} (a level-0 quad's width)",
                    self.feather_edge_m
                ),
            );
        }
        if !(self.shift_m.iter().all(|v| v.is_finite() && v.abs() <= MAX_SHIFT_M)) {
            return bad(
                "shift_m",
                format!("{:?} must be [east, north] in metres, each within ±{MAX_SHIFT_M}", self.shift_m),
            );
        }
        if self.shift_m != [0.0, 0.0] && self.kind != LayerKind::Dataset {
            return bad("shift_m", format!("moves a dataset; a {} layer has none to move", self.kind.name()));
        }
        if self.feather_edge_m > 0.0 && self.kind != LayerKind::Dataset {
            return bad(
                "feather_edge_m",
                format!("fades a dataset in from its no-data edge; a {} layer has none", self.kind.name()),
            );
        }
        let wrong_kind = |field: &str| {
            Err(LayerError::field(&self.name, field, format!("is not a field of a {} layer", self.kind.name())))
        };
        let dataset = self.kind == LayerKind::Dataset;
        if !dataset && self.store.is_some() {
            return wrong_kind("store");
        }
        if !dataset && self.dataset.is_some() {
            return wrong_kind("dataset");
        }
        if !dataset && self.source.is_some() {
            return wrong_kind("source");
        }
        if self.kind != LayerKind::Constant && self.height_m.is_some() {
            return wrong_kind("height_m");
        }
        if self.kind != LayerKind::Procedural && self.noise.is_some() {
            return wrong_kind("noise");
        }
        let difference = self.kind == LayerKind::Difference;
        if !difference && self.of.is_some() {
            return wrong_kind("of");
        }
        if !difference && self.style.is_some() {
            return wrong_kind("style");
        }
        let edit = self.kind == LayerKind::Edit;
        if !edit && !self.strokes.is_empty() {
            return wrong_kind("strokes");
        }
        if self.strokes.len() > MAX_STROKES {
            return bad(
                "strokes",
                format!("{} strokes; an edit layer holds at most {MAX_STROKES}", self.strokes.len()),
            );
        }
        if self.runs.len() > MAX_RUNS {
            return bad("runs", format!("{} runs; an erosion layer holds at most {MAX_RUNS}", self.runs.len()));
        }
        let erosion = self.kind == LayerKind::Erosion;
        if !erosion && !self.runs.is_empty() {
            return wrong_kind("runs");
        }
        if !self.kind.holds_deltas() && self.applied.is_some() {
            return wrong_kind("applied");
        }
        if erosion {
            if self.blend != BlendMode::Add {
                return bad(
                    "blend",
                    format!("{}: an erosion layer holds changes of height and blends with add", self.blend.name()),
                );
            }
            if let Some(k) = self.applied
                && k > self.runs.len()
            {
                return bad("applied", format!("{k} is past the {} runs", self.runs.len()));
            }
            for (k, run) in self.runs.iter().enumerate() {
                run.check().map_err(|(f, p)| LayerError::field(&self.name, &format!("runs[{k}].{f}"), p))?;
                if run.level != self.runs[0].level {
                    return bad(
                        &format!("runs[{k}].level"),
                        format!(
                            "{} differs from runs[0]'s {} (one erosion layer erodes at one level)",
                            run.level, self.runs[0].level
                        ),
                    );
                }
            }
        }
        if edit {
            if self.blend != BlendMode::Add {
                return bad(
                    "blend",
                    format!("{}: an edit layer holds height deltas and blends with add", self.blend.name()),
                );
            }
            if let Some(k) = self.applied
                && k > self.strokes.len()
            {
                return bad("applied", format!("{k} is past the {} strokes", self.strokes.len()));
            }
            for (k, stroke) in self.strokes.iter().enumerate() {
                stroke
                    .check(radius_m)
                    .map_err(|(f, p)| LayerError::field(&self.name, &format!("strokes[{k}].{f}"), p))?;
            }
        }
        if difference {
            // A difference changes no height: the fields that shape one do not apply.
            let unused = [
                ("blend", self.blend != BlendMode::Over),
                ("weight", self.weight != 1.0),
                ("scale", self.scale != 1.0),
                ("offset_m", self.offset_m != 0.0),
                ("valid_range_m", self.valid_range_m.is_some()),
                ("extent", self.extent.is_some()),
            ];
            if let Some((field, _)) = unused.iter().find(|(_, set)| *set) {
                return wrong_kind(field);
            }
        }
        match self.kind {
            LayerKind::Dataset if self.store.is_none() => bad("store", "a dataset layer needs its store".into()),
            LayerKind::Constant => match self.height_m {
                Some(h) if h.is_finite() => Ok(()),
                Some(h) => bad("height_m", format!("{h} must be finite")),
                None => bad("height_m", "a constant layer needs its height".into()),
            },
            LayerKind::Procedural => match &self.noise {
                Some(n) => {
                    check_noise(n, radius_m).map_err(|(f, p)| LayerError::field(&self.name, &format!("noise.{f}"), p))
                }
                None => bad("noise", "a procedural layer needs its noise settings".into()),
            },
            LayerKind::Dataset | LayerKind::Edit | LayerKind::Erosion => Ok(()),
            LayerKind::Difference => {
                let Some(of) = &self.of else {
                    return bad("of", "a difference layer needs its operands [A, B]".into());
                };
                for (side, operand) in ["A", "B"].iter().zip(of) {
                    let names = operand.names();
                    if names.is_empty() || names.iter().any(|n| n.trim().is_empty()) {
                        return bad("of", format!("operand {side} '{operand}' names no layer"));
                    }
                }
                if of[0] == of[1] {
                    return bad("of", format!("A and B are both '{}': the difference would be 0", of[0]));
                }
                let style = self.difference_style();
                if let Some(r) = style.range_m
                    && !(r.is_finite() && r > 0.0)
                {
                    return bad("style.range_m", format!("{r} must be a positive height in metres"));
                }
                if !(style.percentile > 0.0 && style.percentile <= 100.0) {
                    return bad("style.percentile", format!("{} must lie in (0, 100]", style.percentile));
                }
                if !(style.isolines_m.is_finite() && style.isolines_m >= 0.0) {
                    return bad("style.isolines_m", format!("{} must be an interval ≥ 0 in metres", style.isolines_m));
                }
                Ok(())
            }
        }
    }
}

fn check_extent(extent: &ExtentSpec) -> Result<(), String> {
    let lat_ok = |lat: f64| (-90.0..=90.0).contains(&lat);
    match extent {
        ExtentSpec::Box([w, s, e, n]) => {
            if ![w, s, e, n].iter().all(|v| v.is_finite()) {
                return Err("box values must be finite".into());
            }
            if !(lat_ok(*s) && lat_ok(*n) && s < n) {
                return Err(format!("box south {s} and north {n} must lie in [-90, 90] with south < north"));
            }
            if !((-360.0..=360.0).contains(w) && (-360.0..=360.0).contains(e)) || w == e {
                return Err(format!("box west {w} and east {e} must be distinct longitudes in degrees"));
            }
            Ok(())
        }
        ExtentSpec::Polygon(ring) => {
            if ring.len() < 3 {
                return Err(format!("a polygon needs at least 3 vertices, not {}", ring.len()));
            }
            for (k, [lon, lat]) in ring.iter().enumerate() {
                if !(lon.is_finite() && lat_ok(*lat) && (-540.0..=540.0).contains(lon)) {
                    return Err(format!("vertex {k} [{lon}, {lat}] is not a [lon, lat] pair in degrees"));
                }
            }
            Ok(())
        }
    }
}

fn check_noise(n: &NoiseSpec, radius_m: f64) -> Result<(), (&'static str, String)> {
    if !(n.amplitude_m.is_finite() && n.amplitude_m >= 0.0) {
        return Err(("amplitude_m", format!("{} must be a height ≥ 0 in metres", n.amplitude_m)));
    }
    if !(n.wavelength_m.is_finite() && n.wavelength_m > 0.0) {
        return Err(("wavelength_m", format!("{} must be a positive length in metres", n.wavelength_m)));
    }
    if !(1..=MAX_OCTAVES).contains(&n.octaves) {
        return Err(("octaves", format!("{} must lie in 1..={MAX_OCTAVES}", n.octaves)));
    }
    if !(n.lacunarity.is_finite() && n.lacunarity > 1.0 && n.lacunarity <= 16.0) {
        return Err(("lacunarity", format!("{} must lie in (1, 16]", n.lacunarity)));
    }
    if !(n.gain.is_finite() && n.gain > 0.0 && n.gain < 1.0) {
        return Err(("gain", format!("{} must lie in (0, 1)", n.gain)));
    }
    let finest = n.wavelength_m / n.lacunarity.powi(n.octaves as i32 - 1);
    if finest < radius_m * MIN_WAVELENGTH_OF_RADIUS {
        return Err((
            "octaves",
            format!(
                "the finest octave's wavelength {finest:.3e} m is below {:.3e} m (the body's radius / 2³⁰)",
                radius_m * MIN_WAVELENGTH_OF_RADIUS
            ),
        ));
    }
    Ok(())
}
