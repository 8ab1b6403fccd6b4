//! An erosion run as a project keeps it: the region, level, parameters, steps and seed (and for
//! the erosion brush, the path it localises rain and erosion to). The erosion layer's heights
//! are a cache of its operations, rebuilt from them when missing or stale.
//!
//! ```json
//! { "region": [41.2, 39.85, 41.35, 39.95], "level": 10, "steps": 400, "seed": 1,
//!   "preset": "rain", "params": { "rain_m_s": 0.0001, … } }
//! { "region": [41.2, 39.85, 41.35, 39.95], "level": 9, "steps": 200, "model": "stream-power",
//!   "stream_power": { "uplift_m_per_year": 0.001, "k": 2e-5, "m": 0.45, "n": 1.0,
//!                     "kd_m2_per_year": 0.01, "years": 2000000.0, "dt_years": 10000.0 } }
//! ```

use serde::{Deserialize, Serialize};

use super::landscape::LandscapeParams;
use super::params::Params;
use crate::errors::FieldProblem;
use crate::geodesy::GeoBox;

/// One erosion run.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Operation {
    /// The box asked for, degrees: `[west, south, east, north]` (a project of version 3 or
    /// older held `[lat_min, lon_min, lat_max, lon_max]`, migrated on load); the run covers it
    /// rounded out to whole quads of `level` (see [`super::region::Region::from_box`]).
    pub region: GeoBox,
    /// The level whose samples are the run's cells (every operation of a layer has the same).
    pub level: u8,
    /// Steps (each the asked Δt or less, by the CFL bound).
    pub steps: u64,
    /// The dither's seed.
    #[serde(default)]
    pub seed: u64,
    /// The preset the parameters started from (a label; `params` holds every value).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// The model: `hydraulic` (virtual pipes, seconds of rain; the default) or `stream-power`
    /// (landscape evolution over geological time).
    #[serde(default, skip_serializing_if = "Model::is_hydraulic")]
    pub model: Model,
    /// The hydraulic model's parameters (a stream-power run has none: the rain preset stands in).
    #[serde(default = "Params::standard", skip_serializing_if = "Params::is_standard")]
    pub params: Params,
    /// A stream-power run's parameters (with `"model": "stream-power"`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stream_power: Option<LandscapeParams>,
    /// The erosion brush's path: rain and erosion fade out beyond `radius_m` of it (outside,
    /// cells are sinks: what flows there leaves the run, counted). In a stream-power run the
    /// path is where the rock rises: uplift fades out the same way, and rivers run on over the
    /// whole region.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brush: Option<BrushPath>,
    /// Where the run was made: `cpu` (the reference, bit for bit reproducible) or `gpu` (within
    /// its stated tolerance of it). A rebuild from the operation runs the CPU reference.
    #[serde(default)]
    pub device: Device,
}

/// Which erosion model a run uses.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "kebab-case")]
pub enum Model {
    /// Virtual pipes: water, sediment and thermal slumping over seconds to hours.
    #[default]
    Hydraulic,
    /// Uplift, stream-power incision and hillslope diffusion over thousands to millions of years.
    StreamPower,
}

impl Model {
    /// Whether it is the default model (not written to the project).
    pub fn is_hydraulic(&self) -> bool {
        *self == Model::Hydraulic
    }

    /// The name the command line and the project use.
    pub fn name(self) -> &'static str {
        match self {
            Model::Hydraulic => "hydraulic",
            Model::StreamPower => "stream-power",
        }
    }
}

/// Where a run was made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Device {
    /// The CPU reference.
    #[default]
    Cpu,
    /// The GPU kernels.
    Gpu,
}

/// The erosion brush's path.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct BrushPath {
    /// Points, `[lat, lon]` degrees.
    pub points: Vec<[f64; 2]>,
    /// Radius, metres (full strength within half of it, smoothly to none at it).
    pub radius_m: f64,
}

/// The most steps one operation may take.
pub const MAX_STEPS: u64 = 10_000_000;

impl Operation {
    /// Checks the fields a run does not check itself.
    pub fn check(&self) -> Result<(), FieldProblem> {
        let bad = |field: &str, problem: String| Err(FieldProblem::new(field, problem));
        match (self.model, &self.stream_power) {
            (Model::StreamPower, None) => return bad("stream_power", "a stream-power run needs its parameters".into()),
            (Model::Hydraulic, Some(_)) => {
                return bad("model", "stream_power parameters are given but the model is hydraulic".into());
            }
            (Model::StreamPower, Some(p)) => {
                p.check().map_err(|e| FieldProblem::new(e.field, e.problem).under("stream_power"))?;
                if self.steps != p.steps() {
                    return bad(
                        "steps",
                        format!("{} differs from the {} steps of years / dt_years", self.steps, p.steps()),
                    );
                }
            }
            (Model::Hydraulic, None) => {}
        }
        if !(1..=MAX_STEPS).contains(&self.steps) {
            return bad("steps", format!("{} is outside 1 … {MAX_STEPS}", self.steps));
        }
        if self.level > 24 {
            return bad("level", format!("{} is finer than 24 (sub-millimetre cells on the Earth)", self.level));
        }
        self.params
            .check()
            .map_err(|e| FieldProblem::new(e.field, format!("{} is outside {}", e.value, e.range)).under("params"))?;
        if let Some(b) = &self.brush {
            if !(b.radius_m.is_finite() && b.radius_m > 0.0) {
                return bad("brush.radius_m", format!("{} must be a positive distance in metres", b.radius_m));
            }
            if b.points.is_empty() {
                return bad("brush.points", "the brush's path has no point".into());
            }
            if let Some([lat, lon]) = b
                .points
                .iter()
                .find(|p| !(p[0].is_finite() && p[1].is_finite() && p[0].abs() <= 90.0 && p[1].abs() <= 180.0))
            {
                return bad(
                    "brush.points",
                    format!("[{lat}, {lon}] is not [lat, lon] in degrees (latitude within ±90, longitude within ±180)"),
                );
            }
        }
        Ok(())
    }
}
