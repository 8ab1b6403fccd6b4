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

use rayon::prelude::*;
use serde::Serialize;

use super::CompareError;
use super::bias::{Binned, Polynomial, Sinusoids, vertical};
use super::coreg::{NuthKaabOptions, RefSample, differences, nuth_kaab, reference_samples};
use super::mosaic::{Interpolation, Mosaic};
use super::sample::{fit_quads, held_samples_fit, memory_budget, operand_scene, overlap_quads};
use super::spill::{NO_CLASS, Record};
use super::stable::Stable;
use super::stats::Stats;
use super::streamed::held_stats;
use super::whole_area::{At, Stand, WholeArea, sample_attributes, whole_area_stats};
use crate::ecm::QuadId;
use crate::ecm::grid::spacing_m;
use crate::geodesy::{GeoBox, geodetic_from_ecef};
pub use crate::layers::correction::Attribute;
use crate::layers::correction::{Bias, Frame};
use crate::layers::{LayerError, LayerSpec, Operand};
use crate::maths::median;
use crate::project::Project;
use crate::scene::Scene;

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

/// Co-registers layer `a` onto layer `b` of a project by the pipeline of `opts`.
pub fn coregister(project: &Project, a: &str, b: &str, opts: &CoregOptions) -> Result<Coregistration, CompareError> {
    if a == b {
        return Err(CompareError::Option {
            option: "--to".into(),
            problem: format!("'{a}' co-registered onto itself"),
        });
    }
    if opts.pipeline.is_empty() {
        return Err(CompareError::Option { option: "--pipeline".into(), problem: "names no step".into() });
    }
    super::phase(&opts.watch, "samples", 0);
    let (scene, _) = Scene::open(project)?;
    let alone = |name: &str| operand_scene(&scene, project, &Operand::Layer(name.into()));
    let (scene_a, scene_b) = (alone(a)?, alone(b)?);
    let (finest, _) = overlap_quads(&scene_a, &scene_b, None, opts.region).map(|(l, q)| (l, q.len()))?;
    let (level, quads) = overlap_quads(&scene_a, &scene_b, Some(opts.level.unwrap_or(finest)), opts.region)?;
    let fitted = fit_quads(&quads, opts.fit_quads.unwrap_or(FIT_QUADS));
    held_samples_fit("co-registration", level, fitted.len(), HELD_BYTES, memory_budget())?;
    let ellipsoid = scene_b.ellipsoid;
    let curvature = opts.pipeline.contains(&Step::TerrainBias(Attribute::MaxCurvature));
    let reference = reference_samples(&scene_b, &fitted, opts.region, curvature)?;
    if reference.is_empty() {
        return Err(CompareError::Option { option: "A, B".into(), problem: "the layers do not overlap".into() });
    }
    let stable = stable_mask(&scene, project, &fitted, &reference, opts.stable.as_ref())?;
    let origin_deg = centroid_deg(&ellipsoid, &reference);
    let frame = Frame::at(&ellipsoid, origin_deg);
    // Each sample's place and attributes, for the steps that fit a bias (none for Nuth & Kääb
    // and a vertical offset, whose corrections do not depend on the place).
    let biased = opts.pipeline.iter().any(|s| !matches!(s, Step::NuthKaab | Step::Vertical));
    let mut at = if biased { sample_attributes(&frame, &reference) } else { Vec::new() };
    // The extent the biases hold beyond (east, north metres): the samples', or, fitted on some
    // quads, every quad's outline.
    let subset = fitted.len() < quads.len();
    let quad_outline: Vec<[f64; 2]> = if subset {
        quads
            .iter()
            .flat_map(|q| (0..9).map(move |k| (*q, k % 3, k / 3)))
            .map(|(q, i, j)| frame.local(crate::ecm::points::sample_point(&ellipsoid, q, 3, i, j).0))
            .map(|(e, n)| [e, n])
            .collect()
    } else {
        Vec::new()
    };
    let outline = |at: &[At]| -> Vec<[f64; 2]> {
        if subset { quad_outline.clone() } else { at.iter().map(|a| [a.east_m, a.north_m]).collect() }
    };
    let everywhere = stable.iter().all(|&s| s);
    let mut mosaic = Mosaic::new(scene_a.clone(), level, Interpolation::Bicubic);
    let mut raw = differences(&mut mosaic, &reference, 0.0, 0.0)?;
    // Kept for the whole area's `before` only where it is not the first step's.
    let raw_before = (!everywhere && !subset).then(|| raw.clone());
    let (mut shift, mut up) = ((0.0, 0.0), 0.0);
    let mut bias = vec![0.0; reference.len()];
    let (mut iterations, mut converged) = (0u32, true);
    let mut steps = Vec::new();
    let mut stands = Vec::new();
    for step in &opts.pipeline {
        super::phase(&opts.watch, &step_name(step), 0);
        super::tick(&opts.watch, 0)?;
        // What the step before left (each step's `after` is the next one's `before`); the first
        // step's computed beside Nuth & Kääb's fit where it is one, else here.
        let mut before = steps.last().map(|s: &StepResult| s.after.clone());
        let stats_now =
            |raw: &[Option<f64>], up: f64, bias: &[f64]| stable_stats(residual_at(raw, up, bias), &reference, &stable);
        if before.is_none() && *step != Step::NuthKaab {
            before = Some(stats_now(&raw, up, &bias));
        }
        // A's elevation as the steps before left it (B + what is left of dh; unknown where A has
        // no data): what a terrain bias by elevation is fitted against, and what the layer reads
        // when it applies one.
        for ((a, r), d) in at.iter_mut().zip(&reference).zip(residual(&raw, up, &bias)) {
            a.elevation_m = d.map_or(f64::NAN, |d| f64::from(r.b) + d);
        }
        let too_few = |what: &str| CompareError::Option {
            option: "--pipeline".into(),
            problem: format!("{what}: too few stable samples with data on both sides to fit it"),
        };
        let (mut moves, mut step_converged) = (None, None);
        let correction = match *step {
            Step::NuthKaab => {
                let prior: Vec<f64> = bias.iter().map(|b| b - up).collect();
                let fit = || nuth_kaab(&mut mosaic, &reference, &stable, &prior, shift, &raw, &opts.nuth_kaab);
                let (run, stats) = rayon::join(fit, || before.take().unwrap_or_else(|| stats_now(&raw, up, &bias)));
                before = Some(stats);
                let run = run?;
                raw = run.dh;
                let left: Vec<f64> =
                    residual(&raw, 0.0, &bias).zip(&stable).filter_map(|(d, &s)| d.filter(|_| s)).collect();
                let new_up = -median(left);
                let c = Correction::NuthKaab {
                    east_m: run.east_m - shift.0,
                    north_m: run.north_m - shift.1,
                    up_m: new_up - up,
                };
                iterations += run.moves.len() as u32;
                converged &= run.converged;
                (moves, step_converged) = (Some(run.moves), Some(run.converged));
                (shift, up) = ((run.east_m, run.north_m), new_up);
                c
            }
            Step::Vertical => {
                let set = fit_set(residual(&raw, up, &bias), &stable, &reference);
                let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
                let m = vertical(&dh, &w);
                if !m.is_finite() {
                    return Err(too_few("vertical"));
                }
                up -= m;
                Correction::Vertical { up_m: -m }
            }
            Step::Deramp(order) => {
                let set = fit_set(residual(&raw, up, &bias), &stable, &reference);
                let e: Vec<f64> = set.iter().map(|s| at[s.0].east_m / 1000.0).collect();
                let n: Vec<f64> = set.iter().map(|s| at[s.0].north_m / 1000.0).collect();
                let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
                let p = Polynomial::fit(order, &e, &n, &dh, &w).ok_or_else(|| too_few("deramp"))?;
                // Held beyond the overlap's box, not extrapolated.
                let (lo, hi) = bounds(outline(&at).iter().map(|p| [p[0] / 1000.0, p[1] / 1000.0]));
                let box_km = [lo[0], lo[1], hi[0], hi[1]];
                Correction::Bias(Bias::Deramp { origin_deg, order, coefficients: p.coefficients, box_km })
            }
            Step::TerrainBias(attribute) => {
                let set: Vec<(usize, f64, f64)> = fit_set(residual(&raw, up, &bias), &stable, &reference)
                    .into_iter()
                    .filter(|s| at[s.0].attribute(attribute).is_finite())
                    .collect();
                let x: Vec<f64> = set.iter().map(|s| at[s.0].attribute(attribute)).collect();
                let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
                let b = Binned::fit(&x, &dh, &w, super::bias::BINS).ok_or_else(|| too_few("terrain_bias"))?;
                Correction::Bias(Bias::TerrainBias { attribute, bins: b.bins })
            }
            Step::Directional(azimuth_deg) => {
                let set = fit_set(residual(&raw, up, &bias), &stable, &reference);
                let (s, c) = azimuth_deg.to_radians().sin_cos();
                let x: Vec<f64> = set.iter().map(|k| at[k.0].east_m * s + at[k.0].north_m * c).collect();
                let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
                let extent = x.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 2.0;
                let bins = ((extent / (4.0 * spacing_m(&ellipsoid, level))) as usize).clamp(100, 1000);
                let fit = Sinusoids::fit(&x, &dh, &w, bins).ok_or_else(|| too_few("directional"))?;
                let (lo, hi) = bounds(outline(&at).iter().map(|p| [p[0] * s + p[1] * c; 2]));
                Correction::Bias(Bias::Directional {
                    origin_deg,
                    azimuth_deg,
                    offset_m: fit.offset_m,
                    sinusoids: fit.sinusoids,
                    range_m: [lo[0], hi[0]],
                })
            }
        };
        for (b, at) in bias.iter_mut().zip(&at) {
            *b += correction.bias(at);
        }
        let after = stable_stats(residual_at(&raw, up, &bias), &reference, &stable);
        let before = before.unwrap_or_else(|| Stats::empty(0)); // set above for every step
        steps.push(StepResult { correction, moves, converged: step_converged, before, after });
        stands.push(Stand { shift, up });
    }
    // Over every sample: the first step's `before` and the last one's `after` where every sample
    // is stable, else computed over all of them; fitted on some quads, the pipeline replayed over
    // every quad.
    let (before, after) = match (steps.first(), steps.last(), &raw_before) {
        _ if subset => {
            let bias = |k: usize, a: &At| steps[k].correction.bias(a);
            let scratch = opts.scratch.clone().unwrap_or_else(|| project.resolve(std::path::Path::new(".")));
            super::phase(&opts.watch, "whole area", quads.len());
            let area = WholeArea {
                watch: &opts.watch,
                scene_a: &scene_a,
                scene_b: &scene_b,
                level,
                quads: &quads,
                region: opts.region,
                curvature,
                frame: &frame,
                scratch: &scratch,
            };
            whole_area_stats(&area, &stands, &bias)?
        }
        (_, _, Some(raw_before)) => {
            let all = vec![true; reference.len()];
            let after = residual_at(&raw, up, &bias);
            (stable_stats(|k| raw_before[k], &reference, &all), stable_stats(after, &reference, &all))
        }
        (Some(first), Some(last), None) => (first.before.clone(), last.after.clone()),
        _ => (Stats::empty(0), Stats::empty(0)), // no step: refused above
    };
    Ok(Coregistration {
        a: a.into(),
        b: b.into(),
        level,
        spacing_m: spacing_m(&ellipsoid, level),
        pipeline: opts.pipeline.iter().map(step_name).collect(),
        east_m: shift.0,
        north_m: shift.1,
        up_m: up,
        iterations,
        converged,
        stable: opts.stable.as_ref().map(Stable::describe),
        stable_count: stable.iter().filter(|&&s| s).count() as u64,
        quad_count: quads.len() as u64,
        fit_quad_count: fitted.len() as u64,
        steps,
        before,
        after,
    })
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

/// The smallest and largest of each coordinate.
fn bounds(points: impl Iterator<Item = [f64; 2]>) -> ([f64; 2], [f64; 2]) {
    points.fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), p| {
        ([lo[0].min(p[0]), lo[1].min(p[1])], [hi[0].max(p[0]), hi[1].max(p[1])])
    })
}

/// What is left of `raw` (A − B as A stands) once the offset `up` is added and the biases taken
/// off, sample by sample (None: no data), without holding it.
fn residual<'a>(raw: &'a [Option<f64>], up: f64, bias: &'a [f64]) -> impl Iterator<Item = Option<f64>> + 'a {
    (0..raw.len().min(bias.len())).map(residual_at(raw, up, bias))
}

/// The stable samples with a residual: index, value, weight.
fn fit_set(res: impl Iterator<Item = Option<f64>>, stable: &[bool], reference: &[RefSample]) -> Vec<(usize, f64, f64)> {
    res.enumerate()
        .filter(|(k, d)| stable[*k] && d.is_some())
        .map(|(k, d)| (k, d.unwrap_or(0.0), reference[k].area))
        .collect()
}

/// [`residual`] of one sample.
fn residual_at<'a>(raw: &'a [Option<f64>], up: f64, bias: &'a [f64]) -> impl Fn(usize) -> Option<f64> + Sync + 'a {
    move |k| raw[k].map(|d| d + up - bias[k])
}

/// Statistics of the samples `keep` holds that have a difference (`dh` of a sample's index): a
/// record per sample, made on every thread in sample order (NaN where it is left out).
fn stable_stats(dh: impl Fn(usize) -> Option<f64> + Sync, reference: &[RefSample], keep: &[bool]) -> Stats {
    let records: Vec<Record> = (0..reference.len())
        .into_par_iter()
        .map(|k| Record {
            dh_m: dh(k).filter(|_| keep[k]).unwrap_or(f64::NAN),
            weight: reference[k].area,
            class: NO_CLASS,
        })
        .collect();
    held_stats(&records, 0, &[], 0).stats
}

/// The area-weighted centroid of the samples on the ellipsoid: longitude, latitude, degrees.
pub(super) fn centroid_deg(ellipsoid: &crate::geodesy::Ellipsoid, reference: &[RefSample]) -> [f64; 2] {
    // Summed in fixed chunks, then the chunks' sums in order: the same on any number of threads.
    let chunks: Vec<(glam::DVec3, f64)> = reference
        .par_chunks(1 << 16)
        .map(|c| c.iter().fold((glam::DVec3::ZERO, 0.0), |(s, w), r| (s + r.p * r.area, w + r.area)))
        .collect();
    let (sum, w) = chunks.into_iter().fold((glam::DVec3::ZERO, 0.0), |(s, w), c| (s + c.0, w + c.1));
    let g = geodetic_from_ecef(ellipsoid, sum / w.max(f64::MIN_POSITIVE));
    [g.lon_rad.to_degrees(), g.lat_rad.to_degrees()]
}

/// Which samples are stable: all without `stable`; where a layer has data; or outside outlines.
pub(super) fn stable_mask(
    scene: &Scene,
    project: &Project,
    quads: &[QuadId],
    reference: &[RefSample],
    stable: Option<&Stable>,
) -> Result<Vec<bool>, CompareError> {
    let Some(stable) = stable else { return Ok(vec![true; reference.len()]) };
    let mask = stable.select(scene, project, quads, reference, false)?;
    if !mask.iter().any(|&s| s) {
        return Err(CompareError::Option {
            option: "--stable".into(),
            problem: format!("{} leaves no sample of the overlap as stable terrain", stable.describe()),
        });
    }
    Ok(mask)
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
