//! Co-registration as a pipeline of bias corrections (`terrafuse coregister --pipeline`), as
//! xDEM chains `NuthKaab() + Deramp(…)`: each step is fitted to what the steps before it left of
//! dh = A − B on stable terrain and taken off A, in the order given.
//!
//! A corrected is A′(p) = A(p − c) + up − Σ bias_k(p): Nuth & Kääb moves A by c (east, north
//! metres) and sets the vertical offset `up` (the median it removes); `vertical` adds to `up`;
//! `deramp`, `terrain_bias` and `directional` are functions of the reference sample p (its
//! position in a local east-north frame at the samples' centroid, B's slope or maximal curvature
//! there, or A's elevation there as the steps before left it) summed into the bias. A terrain
//! bias by elevation is binned by A's corrected elevation rather than B's (xDEM fits it by the
//! reference's and applies it by the DEM's own, which differ by dh: 0.1 m at 10 m of dh and
//! 1 cm/m), because that is what the layer reads when it applies the correction, so the fit's
//! statistics are what the corrected layer shows. A Nuth & Kääb step after others fits the shift
//! with their biases already taken off, so their order matters as it does in xDEM.
//!
//! The statistics of each step are over the stable samples; those of the whole run over every
//! sample (as `compare` counts them).

use serde::Serialize;

mod run;

pub use run::coregister;
pub(super) use run::{centroid_deg, stable_mask};

use super::CompareError;
use super::coreg::NuthKaabOptions;
use super::stable::Stable;
use super::stats::Stats;
use super::whole_area::At;
use crate::geodesy::GeoBox;
pub use crate::layers::correction::Attribute;
use crate::layers::correction::Bias;
use crate::layers::{LayerError, LayerSpec};

/// Most quads a co-registration's steps are fitted on (1.7·10⁷ samples; the Erzurum tile at its
/// default level has 35).
pub const FIT_QUADS: usize = 256;

/// Bytes a reference sample takes at the peak of a run, with a margin (measured: 1 606 MiB for
/// 5.35·10⁶ samples on the Erzurum pair at level 10 with the whole-area residuals of `--stable`,
/// ≈ 307 bytes a sample).
const HELD_BYTES: usize = 330;

/// One step of a pipeline, as `--pipeline` names it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Step {
    /// `nuth_kaab`: the horizontal shift and vertical offset (Nuth & Kääb 2011).
    NuthKaab,
    /// `vertical`: the median offset.
    Vertical,
    /// `deramp:ORDER`: a polynomial of order 1–3 in local east and north.
    Deramp(u8),
    /// `terrain_bias:ATTRIBUTE`: dh binned by an attribute of B.
    TerrainBias(Attribute),
    /// `directional:AZIMUTH`: a sum of sinusoids along an azimuth, degrees clockwise from north.
    Directional(f64),
}

/// What makes a text not a step of `--pipeline`.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum StepError {
    /// A step that needs an argument has none.
    #[error("'{step}' needs {what} ('{step}:…')")]
    NeedsArgument {
        /// The step's name.
        step: String,
        /// What it needs.
        what: &'static str,
    },
    /// A deramp's order that is not 1, 2 or 3.
    #[error("'{0}': the order must be 1, 2 or 3")]
    Order(String),
    /// A terrain bias over something that is not an attribute it bins by.
    #[error("'{0}' is not an attribute (elevation, max_curvature or slope)")]
    Attribute(String),
    /// A directional bias's azimuth that is not a number.
    #[error("'{0}': the azimuth must be a number of degrees")]
    Azimuth(String),
    /// No such step.
    #[error("'{0}' is not a step (nuth_kaab, vertical, deramp:ORDER, terrain_bias:ATTRIBUTE, directional:AZIMUTH)")]
    Unknown(String),
    /// An argument given to a step that takes none.
    #[error("'{0}' takes no argument")]
    TakesNoArgument(String),
}

impl Step {
    /// Parses one step (`deramp:2`, `terrain_bias:elevation`, `directional:30` …).
    pub fn parse(text: &str) -> Result<Step, StepError> {
        let (name, arg) = match text.split_once(':') {
            Some((n, a)) => (n.trim(), Some(a.trim())),
            None => (text.trim(), None),
        };
        let need = |what: &'static str| arg.ok_or_else(|| StepError::NeedsArgument { step: name.into(), what });
        let step = match name {
            "nuth_kaab" => Step::NuthKaab,
            "vertical" => Step::Vertical,
            "deramp" => match need("an order 1–3")?.parse::<u8>() {
                Ok(order @ 1..=3) => Step::Deramp(order),
                _ => return Err(StepError::Order(text.into())),
            },
            "terrain_bias" => Step::TerrainBias(match need("an attribute")? {
                "elevation" => Attribute::Elevation,
                "max_curvature" => Attribute::MaxCurvature,
                "slope" => Attribute::Slope,
                other => return Err(StepError::Attribute(other.into())),
            }),
            "directional" => match need("an azimuth in degrees")?.parse::<f64>() {
                Ok(az) if az.is_finite() => Step::Directional(az.rem_euclid(360.0)),
                _ => return Err(StepError::Azimuth(text.into())),
            },
            other => return Err(StepError::Unknown(other.into())),
        };
        if arg.is_some() && matches!(step, Step::NuthKaab | Step::Vertical) {
            return Err(StepError::TakesNoArgument(name.into()));
        }
        Ok(step)
    }

    /// Parses `--pipeline`'s comma-separated steps.
    pub fn parse_list(text: &str) -> Result<Vec<Step>, CompareError> {
        let steps: Result<Vec<Step>, StepError> = text.split(',').map(Step::parse).collect();
        let problem = |problem: String| CompareError::Option { option: "--pipeline".into(), problem };
        let steps = steps.map_err(|e| problem(e.to_string()))?;
        if steps.is_empty() {
            return Err(problem("names no step".into()));
        }
        Ok(steps)
    }
}

/// How to co-register.
#[derive(Clone, Debug)]
pub struct CoregOptions {
    /// The level (default: the finest level of the coarser dataset, the data's own). A is read
    /// between its samples by bicubic interpolation (`compare::mosaic`); bilinear
    /// interpolation would flatten it there and not at B's samples, an unequal smoothing that
    /// biases the fit (on a synthetic shift 0.38 m at the data's level, which is why this was one
    /// level finer, 0.12 m, with four times the samples; bicubic at the data's level: 0.08 m;
    /// BENCHMARKS.md).
    pub level: Option<u8>,
    /// Only inside this box: west, south, east, north, degrees.
    pub region: Option<GeoBox>,
    /// The steps, in order (default: Nuth & Kääb alone).
    pub pipeline: Vec<Step>,
    /// Where the corrections are fitted (default: everywhere).
    pub stable: Option<Stable>,
    /// How Nuth & Kääb iterates.
    pub nuth_kaab: NuthKaabOptions,
    /// Most quads the steps are fitted on (default [`FIT_QUADS`]); with more, the whole area's
    /// statistics are made by replaying the pipeline over every sample (see
    /// [`whole_area`](super::whole_area)).
    pub fit_quads: Option<usize>,
    /// Where that replay's scratch files go (default: the project's folder).
    pub scratch: Option<std::path::PathBuf>,
    /// Says which step runs (and stops the co-registration between steps and quads when
    /// cancelled).
    pub watch: Option<std::sync::Arc<crate::progress::Watch>>,
}

impl Default for CoregOptions {
    fn default() -> CoregOptions {
        CoregOptions {
            level: None,
            region: None,
            pipeline: vec![Step::NuthKaab],
            stable: None,
            nuth_kaab: NuthKaabOptions::default(),
            fit_quads: None,
            scratch: None,
            watch: None,
        }
    }
}

/// A step's fitted correction (field names are the JSON's: scripts rely on them): a move and
/// raise of A, or a bias taken off it (as a layer's `correction` stores it).
#[derive(Clone, Debug, PartialEq, Serialize)]
#[serde(tag = "name", rename_all = "snake_case")]
pub enum Correction {
    /// Moves A east and north and raises it (metres).
    NuthKaab {
        /// East, metres.
        east_m: f64,
        /// North, metres.
        north_m: f64,
        /// Up, metres.
        up_m: f64,
    },
    /// Raises A (metres).
    Vertical {
        /// Up, metres.
        up_m: f64,
    },
    /// A bias of position or of the terrain (deramp, terrain_bias, directional; its own `name`).
    #[serde(untagged)]
    Bias(Bias),
}

impl At {
    fn attribute(&self, attribute: Attribute) -> f64 {
        match attribute {
            Attribute::Elevation => self.elevation_m,
            Attribute::Slope => self.slope_deg,
            Attribute::MaxCurvature => self.max_curvature,
        }
    }
}

impl Correction {
    /// The bias at a sample (0 for the steps that move or raise A).
    pub(super) fn bias(&self, at: &At) -> f64 {
        match self {
            Correction::NuthKaab { .. } | Correction::Vertical { .. } => 0.0,
            Correction::Bias(b) => b.at(at.east_m, at.north_m, |a| at.attribute(a)),
        }
    }
}

/// One step of a run (field names are the JSON's: scripts rely on them).
#[derive(Clone, Debug, Serialize)]
pub struct StepResult {
    /// The correction fitted (its `name` is the step's).
    #[serde(flatten)]
    pub correction: Correction,
    /// Nuth & Kääb's iterations: each step east, north (metres) and the vertical bias removed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub moves: Option<Vec<[f64; 3]>>,
    /// Nuth & Kääb: whether the last step was under the tolerance.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub converged: Option<bool>,
    /// Statistics of dh on stable terrain before the step.
    pub before: Stats,
    /// And after it.
    pub after: Stats,
}

/// What co-registration found (field names are the JSON's: scripts rely on them).
#[derive(Clone, Debug, Serialize)]
pub struct Coregistration {
    /// The layer moved.
    pub a: String,
    /// The reference.
    pub b: String,
    /// The level worked at.
    pub level: u8,
    /// Its mean sample spacing, metres.
    pub spacing_m: f64,
    /// The steps as asked for.
    pub pipeline: Vec<String>,
    /// Move A east by this much, metres (local frame of each sample; Nuth & Kääb's).
    pub east_m: f64,
    /// Move A north by this much, metres.
    pub north_m: f64,
    /// Raise A by this much, metres (Nuth & Kääb's and `vertical`'s together).
    pub up_m: f64,
    /// Nuth & Kääb's iterations, all its steps together.
    pub iterations: u32,
    /// Whether every Nuth & Kääb step converged (true without one).
    pub converged: bool,
    /// Where stable terrain was taken from (absent: everywhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stable: Option<String>,
    /// Samples on stable terrain (of the quads fitted on).
    pub stable_count: u64,
    /// Quads of the overlap (`before` and `after` are over all of them).
    pub quad_count: u64,
    /// Quads the steps were fitted on (their `before` and `after` are over these).
    pub fit_quad_count: u64,
    /// Each step: its correction and the statistics on stable terrain before and after it.
    pub steps: Vec<StepResult>,
    /// Statistics of A − B over every sample before (cell-area weighted).
    pub before: Stats,
    /// Statistics of A′ − B after the whole pipeline.
    pub after: Stats,
}

impl Coregistration {
    /// The biases the pipeline fitted (its deramp, terrain and directional steps), in order.
    pub fn biases(&self) -> Vec<Bias> {
        let bias = |s: &StepResult| match &s.correction {
            Correction::Bias(b) => Some(b.clone()),
            _ => None,
        };
        self.steps.iter().filter_map(bias).collect()
    }

    /// Writes the result into A's layer: the shift into `shift_m`, the raise into `offset_m`,
    /// the biases after its `correction`. An error naming the field for a layer that is not a
    /// dataset, or a bias a layer cannot hold (a terrain bias by slope or curvature); the spec is
    /// unchanged then.
    pub fn apply_to(&self, spec: &mut LayerSpec) -> Result<(), LayerError> {
        let mut out = spec.clone();
        out.shift_by(self.east_m, self.north_m)?;
        out.offset_m += self.up_m;
        let biases = self.biases();
        if !biases.is_empty() {
            let (name, kind) = (out.name.clone(), out.kind());
            for b in &biases {
                b.check().map_err(|problem| LayerError::field(&name, "correction", problem.to_string()))?;
            }
            let d = out.as_dataset_mut().ok_or_else(|| {
                LayerError::field(&name, "correction", format!("corrects a dataset; a {} layer has none", kind.name()))
            })?;
            d.correction.extend(biases);
        }
        *spec = out;
        Ok(())
    }
}

/// How `--pipeline` spells a step.
pub fn step_name(step: &Step) -> String {
    match step {
        Step::NuthKaab => "nuth_kaab".into(),
        Step::Vertical => "vertical".into(),
        Step::Deramp(order) => format!("deramp:{order}"),
        Step::TerrainBias(a) => format!("terrain_bias:{}", a.name()),
        Step::Directional(az) => format!("directional:{az}"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_parse_as_the_command_line_spells_them_and_bad_ones_say_why() {
        let steps = Step::parse_list("nuth_kaab,vertical,deramp:2,terrain_bias:max_curvature,directional:-30").unwrap();
        assert_eq!(
            steps,
            vec![
                Step::NuthKaab,
                Step::Vertical,
                Step::Deramp(2),
                Step::TerrainBias(Attribute::MaxCurvature),
                Step::Directional(330.0)
            ]
        );
        assert_eq!(steps.iter().map(step_name).collect::<Vec<_>>()[3], "terrain_bias:max_curvature");
        for (bad, says) in [
            ("deramp:4", "the order must be 1, 2 or 3"),
            ("deramp", "needs an order"),
            ("terrain_bias:aspect", "'aspect' is not an attribute"),
            ("directional:north", "the azimuth must be a number"),
            ("vertical:2", "takes no argument"),
            ("nuth-kaab", "'nuth-kaab' is not a step"),
        ] {
            let e = Step::parse_list(bad).unwrap_err().to_string();
            assert!(e.starts_with("--pipeline: ") && e.contains(says), "{bad}: {e}");
        }
    }
}
