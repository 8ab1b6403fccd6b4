//! The composition of a quad's heights from its plan: the CPU reference of
//! `shaders/compose/compose.wgsl` (keep in sync), in f64, deterministic (each sample alone; rows
//! in parallel with rayon, which changes no result).
//!
//! Per sample each planned layer gives a value v (raw × scale + offset, less a dataset's bias
//! corrections ([`super::correction`]); no data where the raw value is NaN or v is outside
//! `valid_range_m`) and a coverage α = opacity × extent mask × edge
//! mask (datasets fading in from their no-data edge, [`edge`]); a
//! layer with α = 0 at a sample leaves it unchanged. The running height h starts as no data and
//! each layer folds in by its blend mode ([`fold`]); consecutive `mean` layers are gathered and
//! applied together with `over` at the group's largest coverage.

use glam::DVec3;
use rayon::prelude::*;

use super::kind::ValueSource;
use super::spec::BlendMode;
use super::stack::{DifferencePlan, MaskPlan, QuadPlan, SAMPLES, Stack};
use super::{edge, noise};
use crate::ecm::points::sample_point;

/// The running state at a sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Running {
    /// Height, metres (NaN: no data yet).
    pub h: f64,
    /// Sample spacing of the finest dataset that contributed to h, metres (∞: none).
    pub data_spacing_m: f64,
    /// The share of h that comes from datasets, 0–1 (each layer that folds in with coverage α
    /// replaces that share of it: c ← (1 − α)·c + α·[the layer is a dataset]).
    pub data_coverage: f64,
}

impl Running {
    /// No data.
    pub const EMPTY: Running = Running { h: f64::NAN, data_spacing_m: f64::INFINITY, data_coverage: 0.0 };
}

/// Folds a value v with coverage α (> 0) into h: the blend formulas of the README, with
/// h + α(x − h) computed as (1 − α)·h + α·x so that α = 1 gives x exactly (on the GPU in f32 too).
pub fn fold(h: f64, blend: BlendMode, v: f64, alpha: f64) -> f64 {
    match blend {
        BlendMode::Over | BlendMode::Mean => {
            if h.is_nan() {
                v
            } else {
                (1.0 - alpha) * h + alpha * v
            }
        }
        BlendMode::Add => {
            if h.is_nan() {
                h
            } else {
                h + alpha * v
            }
        }
        BlendMode::Min => {
            if h.is_nan() {
                v
            } else {
                (1.0 - alpha) * h + alpha * h.min(v)
            }
        }
        BlendMode::Max => {
            if h.is_nan() {
                v
            } else {
                (1.0 - alpha) * h + alpha * h.max(v)
            }
        }
    }
}

/// What one layer gives at one sample: value and coverage (coverage 0: nothing).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LayerSample {
    /// Metres, after scale and offset.
    pub value: f64,
    /// α = opacity × mask (0 where the layer has no data).
    pub alpha: f64,
}

/// Where a sample is: its exact point, longitude and latitude.
#[derive(Clone, Copy, Debug)]
pub struct SamplePoint {
    /// ECEF metres.
    pub ecef: DVec3,
    /// Radians.
    pub lon_rad: f64,
    /// Radians.
    pub lat_rad: f64,
}

/// What a dataset layer's tiles hold at a sample.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct DataAt {
    /// The raw value (NaN: no data).
    pub raw: f64,
    /// The distance to the dataset's no-data edge, metres (∞ where the layer has no edge
    /// feather; see [`super::edge`]).
    pub edge_m: f64,
}

impl DataAt {
    /// A raw value, far from any edge.
    pub fn raw(raw: f64) -> DataAt {
        DataAt { raw, edge_m: f64::INFINITY }
    }
}

/// The tiles a planned dataset layer reads at a quad (257², row by row from the south).
#[derive(Clone, Copy, Debug, Default)]
pub struct LayerTiles<'a> {
    /// Raw heights (None: not a dataset, or no data).
    pub raw: Option<&'a [f32]>,
    /// Distances to the no-data edge, metres (None: no edge feather).
    pub edge_m: Option<&'a [f32]>,
}

/// The layer's value and coverage at a sample; `data` is what a dataset's tiles hold there.
pub fn layer_sample(
    stack: &Stack,
    plan: &QuadPlan,
    k: usize,
    at: &SamplePoint,
    data: DataAt,
    below: &Running,
) -> LayerSample {
    let planned = &plan.layers[k];
    let layer = &stack.layers[planned.index];
    let spec = &layer.spec;
    let base = match spec.value_source() {
        // An edit or erosion layer's tile holds its deltas (0 where no operation reached).
        ValueSource::StoreTile | ValueSource::Deltas => data.raw,
        ValueSource::Constant(h) => h,
        ValueSource::Noise(n) => {
            let mut weights = noise::octave_weights(n, plan.spacing_m, below.data_spacing_m, below.data_coverage);
            weights.truncate(planned.octaves as usize);
            noise::noise_at(n, at.ecef, &weights)
        }
        // Never planned: it changes no height.
        ValueSource::Nothing => f64::NAN,
    };
    let scaled = base * spec.scale + spec.offset_m;
    // A dataset's bias corrections, of its position and its own (scaled) height.
    let value = if layer.correction.is_empty() { scaled } else { scaled - layer.correction.at(at.ecef, scaled) };
    let valid = !value.is_nan() && spec.valid_range_m.is_none_or(|[lo, hi]| value >= lo && value <= hi);
    if !valid {
        return LayerSample { value: 0.0, alpha: 0.0 };
    }
    let mask = match (&planned.mask, &layer.extent) {
        (MaskPlan::Partial(segments), Some(extent)) => {
            extent.mask(extent.contains(at.lon_rad, at.lat_rad), extent.nearest_m(at.ecef, segments))
        }
        _ => 1.0,
    };
    let edge = if spec.is_data() { edge::edge_mask(data.edge_m, spec.feather_edge_m()) } else { 1.0 };
    LayerSample { value, alpha: planned.opacity * mask * edge }
}

/// The composed height at one sample; `data(k)` is what the plan's k-th layer's tiles hold there
/// when it is a dataset (raw NaN where it has no data).
pub fn compose_sample(stack: &Stack, plan: &QuadPlan, at: &SamplePoint, data: &dyn Fn(usize) -> DataAt) -> f64 {
    let mut state = Running::EMPTY;
    // The open mean group: Σ w·α·v, Σ w·α, Σ w·α over its datasets, max α, finest spacing.
    let (mut sum, mut weight, mut data_weight, mut alpha_max, mut group_spacing) = (0.0, 0.0, 0.0, 0.0, f64::INFINITY);
    for k in 0..plan.layers.len() {
        let planned = &plan.layers[k];
        let layer = &stack.layers[planned.index];
        let s = layer_sample(stack, plan, k, at, data(k), &state);
        let dataset = layer.spec.is_data();
        let spacing = if dataset { layer.data_spacing_m } else { f64::INFINITY };
        if planned.blend == BlendMode::Mean {
            if s.alpha > 0.0 {
                let w = layer.spec.weight * s.alpha;
                sum += w * s.value;
                weight += w;
                if dataset {
                    data_weight += w;
                }
                alpha_max = f64::max(alpha_max, s.alpha);
                group_spacing = group_spacing.min(spacing);
            }
            let closes = plan.layers.get(k + 1).is_none_or(|next| next.blend != BlendMode::Mean);
            if closes {
                if weight > 0.0 {
                    apply(&mut state, BlendMode::Over, sum / weight, alpha_max, group_spacing, data_weight / weight);
                }
                (sum, weight, data_weight, alpha_max, group_spacing) = (0.0, 0.0, 0.0, 0.0, f64::INFINITY);
            }
        } else if s.alpha > 0.0 {
            apply(&mut state, planned.blend, s.value, s.alpha, spacing, if dataset { 1.0 } else { 0.0 });
        }
    }
    state.h
}

/// Folds a value into the running state: the height by its blend mode; the data coverage and
/// spacing by the share the layer replaces (all of it where h had no data; none for `add`).
fn apply(state: &mut Running, blend: BlendMode, value: f64, alpha: f64, spacing_m: f64, data_share: f64) {
    let had_data = !state.h.is_nan();
    state.h = fold(state.h, blend, value, alpha);
    if state.h.is_nan() || blend == BlendMode::Add {
        return;
    }
    let a = if had_data { alpha } else { 1.0 };
    state.data_coverage = (1.0 - a) * state.data_coverage + a * data_share;
    if data_share > 0.0 {
        state.data_spacing_m = state.data_spacing_m.min(spacing_m);
    }
}

/// A quad's composed 257² heights (row by row from the south, NaN where no data), from the
/// tiles of its planned dataset layers: `tiles(k)` for the plan's k-th layer.
pub fn compose_quad<'a>(stack: &Stack, plan: &QuadPlan, tiles: &dyn Fn(usize) -> LayerTiles<'a>) -> Vec<f32> {
    let n = SAMPLES as usize;
    let tiles: Vec<LayerTiles> = (0..plan.layers.len()).map(tiles).collect();
    // Only masks near an extent's edge, noise and bias corrections read the sample's position: a
    // plan without them (datasets and constants inside or without extents) skips the inverse
    // projection.
    let positioned = plan.layers.iter().any(|l| {
        let layer = &stack.layers[l.index];
        matches!(l.mask, MaskPlan::Partial(_)) || layer.spec.noise().is_some() || !layer.correction.is_empty()
    });
    let mut out = vec![f32::NAN; n * n];
    out.par_chunks_mut(n).enumerate().for_each(|(j, row)| {
        for (i, h) in row.iter_mut().enumerate() {
            let at = if positioned {
                let (ecef, lon_rad, lat_rad) = sample_point(&stack.ellipsoid, plan.quad, SAMPLES, i as u32, j as u32);
                SamplePoint { ecef, lon_rad, lat_rad }
            } else {
                SamplePoint { ecef: DVec3::NAN, lon_rad: f64::NAN, lat_rad: f64::NAN }
            };
            let data = |k: usize| DataAt {
                raw: tiles[k].raw.map_or(f64::NAN, |t| f64::from(t[j * n + i])),
                edge_m: tiles[k].edge_m.map_or(f64::INFINITY, |t| f64::from(t[j * n + i])),
            };
            *h = compose_sample(stack, plan, &at, &data) as f32;
        }
    });
    out
}

/// A quad's difference A − B (257², NaN where either side has no data), each operand composed
/// from its own plan like heights: `tiles(k)` for the k-th layer of A's plan then of B's (k
/// counting on past A's layers), as the GPU's job lists them.
pub fn compose_difference<'a>(
    stack: &Stack,
    plan: &DifferencePlan,
    tiles: &dyn Fn(usize) -> LayerTiles<'a>,
) -> Vec<f32> {
    let offset = plan.a.layers.len();
    let a = compose_quad(stack, &plan.a, tiles);
    let b = compose_quad(stack, &plan.b, &|k| tiles(offset + k));
    // In f32 as the GPU subtracts its f32 heights; NaN on either side stays NaN.
    a.iter().zip(&b).map(|(a, b)| a - b).collect()
}

/// A conservative range of the composed heights of a quad, from each planned layer's value range
/// (`range(k)`, e.g. its source tile's), by interval arithmetic through the blend modes; `None`
/// where no layer can give data. A layer's coverage α lies in [α_lo, opacity], α_lo = opacity
/// where it surely covers every sample (full mask, no data gaps possible), else 0. Over, mean,
/// min and max stay in the hull of h and v (exactly v, min or max at α = 1); add widens h by α·v.
pub fn range_bound(stack: &Stack, plan: &QuadPlan, range: &dyn Fn(usize) -> (f64, f64)) -> Option<(f64, f64)> {
    let mut h: Option<(f64, f64)> = None;
    let mut k = 0;
    while k < plan.layers.len() {
        let planned = &plan.layers[k];
        let layer = &stack.layers[planned.index];
        let spec = &layer.spec;
        let (mut lo, mut hi) = range(k);
        // Tiles may hold no-data gaps; a constant or noise covers every sample.
        let full = planned.mask == MaskPlan::Full && !spec.is_data() && spec.valid_range_m.is_none();
        let (mut a_lo, a_hi) = (if full { planned.opacity } else { 0.0 }, planned.opacity);
        let mut blend = planned.blend;
        if blend == BlendMode::Mean {
            // The group's value lies in the hull of its members; it applies with over.
            let mut j = k + 1;
            while j < plan.layers.len() && plan.layers[j].blend == BlendMode::Mean {
                let (l, u) = range(j);
                (lo, hi) = (lo.min(l), hi.max(u));
                j += 1;
            }
            (a_lo, blend, k) = (0.0, BlendMode::Over, j - 1);
        }
        k += 1;
        if lo > hi || a_hi <= 0.0 {
            continue; // no valid value
        }
        h = match (blend, h) {
            (BlendMode::Add, None) => None,
            (BlendMode::Add, Some((a, b))) => Some((a + (a_lo * lo).min(a_hi * lo), b + (a_lo * hi).max(a_hi * hi))),
            (_, None) => Some((lo, hi)),
            (BlendMode::Min, Some((a, b))) if a_lo >= 1.0 => Some((a.min(lo), b.min(hi))),
            (BlendMode::Max, Some((a, b))) if a_lo >= 1.0 => Some((a.max(lo), b.max(hi))),
            (BlendMode::Over, Some(_)) if a_lo >= 1.0 => Some((lo, hi)),
            (BlendMode::Min, Some((a, b))) => Some((a.min(lo), b)),
            (BlendMode::Max, Some((a, b))) => Some((a, b.max(hi))),
            (_, Some((a, b))) => Some((a.min(lo), b.max(hi))),
        };
    }
    h
}
