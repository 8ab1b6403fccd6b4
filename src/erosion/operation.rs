//! An erosion run as a project keeps it: the region, level, parameters, steps and seed (and for
//! the erosion brush, the path it localises rain and erosion to). The erosion layer's heights
//! are a cache of its operations, rebuilt from them when missing or stale.
//!
//! ```json
//! { "region": [41.2, 39.85, 41.35, 39.95], "level": 10, "steps": 400, "seed": 1,
//!   "preset": "rain", "params": { "rain_m_s": 0.0001, … } }
//! ```

use serde::{Deserialize, Serialize};

use super::params::Params;
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
    /// The parameters.
    pub params: Params,
    /// The erosion brush's path: rain and erosion fade out beyond `radius_m` of it (outside,
    /// cells are sinks: what flows there leaves the run, counted).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub brush: Option<BrushPath>,
    /// Where the run was made: `cpu` (the reference, bit for bit reproducible) or `gpu` (within
    /// its stated tolerance of it). A rebuild from the operation runs the CPU reference.
    #[serde(default)]
    pub device: Device,
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
    /// Checks the fields a run does not check itself: (field, problem).
    pub fn check(&self) -> Result<(), (String, String)> {
        let bad = |field: &str, problem: String| Err((field.to_string(), problem));
        if !(1..=MAX_STEPS).contains(&self.steps) {
            return bad("steps", format!("{} is outside 1 … {MAX_STEPS}", self.steps));
        }
        if self.level > 24 {
            return bad("level", format!("{} is finer than 24 (sub-millimetre cells on the Earth)", self.level));
        }
        self.params
            .check()
            .map_err(|e| (format!("params.{}", e.field), format!("{} is outside {}", e.value, e.range)))?;
        if let Some(b) = &self.brush {
            if !(b.radius_m.is_finite() && b.radius_m > 0.0) {
                return bad("brush.radius_m", format!("{} must be a positive distance in metres", b.radius_m));
            }
            if b.points.is_empty() {
                return bad("brush.points", "the brush's path has no point".into());
            }
            if let Some(p) = b.points.iter().find(|p| !(p[0].is_finite() && p[1].is_finite() && p[0].abs() <= 90.0)) {
                return bad("brush.points", format!("{p:?} is not [lat, lon] in degrees"));
            }
        }
        Ok(())
    }
}
