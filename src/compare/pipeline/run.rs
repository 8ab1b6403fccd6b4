//! Running a co-registration pipeline: the samples and the stable mask, each step fitted to what
//! the steps before it left (Nuth & Kääb's shift, or a bias), and the statistics before and after
//! each step and over the whole area.

use super::{Attribute, CoregOptions, Coregistration, Correction, FIT_QUADS, HELD_BYTES, Step, StepResult, step_name};
use crate::compare::CompareError;
use crate::compare::bias::{Binned, Polynomial, Sinusoids, vertical};
use crate::compare::coreg::{NuthKaabOptions, NuthKaabRun, RefSample, differences, nuth_kaab, reference_samples};
use crate::compare::mosaic::{Interpolation, Mosaic};
use crate::compare::sample::{fit_quads, held_samples_fit, memory_budget, operand_scene, overlap_quads};
use crate::compare::spill::{NO_CLASS, Record};
use crate::compare::stable::Stable;
use crate::compare::stats::Stats;
use crate::compare::streamed::held_stats;
use crate::compare::whole_area::{At, Stand, WholeArea, sample_attributes, whole_area_stats};
use crate::ecm::QuadId;
use crate::ecm::grid::spacing_m;
use crate::geodesy::geodetic_from_ecef;
use crate::layers::Operand;
use crate::layers::correction::{Bias, Frame};
use crate::maths::median;
use crate::project::Project;
use crate::scene::Scene;
use rayon::prelude::*;

/// Co-registers layer `a` onto layer `b` of a project by the pipeline of `opts`.
pub fn coregister(project: &Project, a: &str, b: &str, opts: &CoregOptions) -> Result<Coregistration, CompareError> {
    check_request(a, b, opts)?;
    crate::compare::phase(&opts.watch, "samples", 0);
    let (scene, _) = Scene::open(project)?;
    let alone = |name: &str| operand_scene(&scene, project, &Operand::Layer(name.into()));
    let (scene_a, scene_b) = (alone(a)?, alone(b)?);
    let (level, quads, fitted) = pipeline_quads(&scene_a, &scene_b, opts)?;
    let ellipsoid = scene_b.ellipsoid;
    let curvature = opts.pipeline.contains(&Step::TerrainBias(Attribute::MaxCurvature));
    let reference = reference_samples(&scene_b, &fitted, opts.region, curvature)?;
    refuse_if_apart(&reference)?;
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
    let quad_outline = subset.then(|| outline_of(&quads, &frame, &ellipsoid));
    let mut mosaic = Mosaic::new(scene_a.clone(), level, Interpolation::Bicubic);
    let mut raw = differences(&mut mosaic, &reference, 0.0, 0.0)?;
    // Kept for the whole area's `before` only where it is not the first step's.
    let raw_before = (!stable.iter().all(|&s| s) && !subset).then(|| raw.clone());
    let (mut shift, mut up) = ((0.0, 0.0), 0.0);
    let mut bias = vec![0.0; reference.len()];
    let (mut iterations, mut converged) = (0u32, true);
    let mut steps = Vec::new();
    let mut stands = Vec::new();
    for step in &opts.pipeline {
        crate::compare::phase(&opts.watch, &step_name(step), 0);
        crate::compare::tick(&opts.watch, 0)?;
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
        let (mut moves, mut step_converged) = (None, None);
        let correction = match *step {
            Step::NuthKaab => {
                let stand = Stand { shift, up };
                let sample = (&reference[..], &stable[..]);
                let (c, run, stand, stats) =
                    nuth_kaab_step(&mut mosaic, sample, &bias, (&raw, stand), before.take(), &opts.nuth_kaab)?;
                before = Some(stats);
                iterations += run.moves.len() as u32;
                converged &= run.converged;
                (moves, step_converged) = (Some(run.moves), Some(run.converged));
                raw = run.dh;
                (shift, up) = (stand.shift, stand.up);
                c
            }
            _ => {
                let fit = BiasFit {
                    set: fit_set(residual(&raw, up, &bias), &stable, &reference),
                    at: &at,
                    quad_outline: quad_outline.as_deref(),
                    origin_deg,
                    spacing_m: spacing_m(&ellipsoid, level),
                };
                let c = fit_bias(*step, &fit)?;
                if let Correction::Vertical { up_m } = c {
                    up += up_m;
                }
                c
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
    let scratch = opts.scratch.clone().unwrap_or_else(|| project.resolve(std::path::Path::new(".")));
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
    let sampled = Sampled { reference: &reference, raw_before: raw_before.as_deref(), subset };
    let (before, after) = overall_stats(&area, &sampled, &steps, &stands, residual_at(&raw, up, &bias))?;
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

/// The pipeline's samples for the overall statistics: the reference samples, dh before any step
/// where some samples are not stable, and whether the fit read only some quads.
struct Sampled<'a> {
    reference: &'a [RefSample],
    raw_before: Option<&'a [Option<f64>]>,
    subset: bool,
}

/// Over every sample, before the pipeline and after it: the first step's `before` and the last
/// one's `after` where every sample is stable, else computed over all of them (`after`: the
/// residual at each sample); fitted on some quads, the pipeline replayed over every quad.
fn overall_stats(
    area: &WholeArea,
    sampled: &Sampled,
    steps: &[StepResult],
    stands: &[Stand],
    after: impl Fn(usize) -> Option<f64> + Sync,
) -> Result<(Stats, Stats), CompareError> {
    Ok(match (steps.first(), steps.last(), sampled.raw_before) {
        _ if sampled.subset => {
            let bias = |k: usize, a: &At| steps[k].correction.bias(a);
            crate::compare::phase(area.watch, "whole area", area.quads.len());
            whole_area_stats(area, stands, &bias)?
        }
        (_, _, Some(raw_before)) => {
            let all = vec![true; sampled.reference.len()];
            (stable_stats(|k| raw_before[k], sampled.reference, &all), stable_stats(after, sampled.reference, &all))
        }
        (Some(first), Some(last), None) => (first.before.clone(), last.after.clone()),
        _ => (Stats::empty(0), Stats::empty(0)), // no step: refused above
    })
}

/// The level the pipeline works at (`--level`, else the finest both layers have), every quad of
/// the overlap there, and the quads the fit reads (`--fit-quads`), refused where those quads'
/// samples would not fit in memory.
fn pipeline_quads(
    scene_a: &Scene,
    scene_b: &Scene,
    opts: &CoregOptions,
) -> Result<(u8, Vec<QuadId>, Vec<QuadId>), CompareError> {
    let (finest, _) = overlap_quads(scene_a, scene_b, None, opts.region).map(|(l, q)| (l, q.len()))?;
    let (level, quads) = overlap_quads(scene_a, scene_b, Some(opts.level.unwrap_or(finest)), opts.region)?;
    let fitted = fit_quads(&quads, opts.fit_quads.unwrap_or(FIT_QUADS));
    held_samples_fit("co-registration", level, fitted.len(), HELD_BYTES, memory_budget())?;
    Ok((level, quads, fitted))
}

/// Refuses two layers without a reference sample in common.
fn refuse_if_apart(reference: &[RefSample]) -> Result<(), CompareError> {
    if reference.is_empty() {
        return Err(CompareError::Option { option: "A, B".into(), problem: "the layers do not overlap".into() });
    }
    Ok(())
}

/// Refuses a co-registration of a layer onto itself, or with no step.
fn check_request(a: &str, b: &str, opts: &CoregOptions) -> Result<(), CompareError> {
    if a == b {
        return Err(CompareError::Option {
            option: "--to".into(),
            problem: format!("'{a}' co-registered onto itself"),
        });
    }
    if opts.pipeline.is_empty() {
        return Err(CompareError::Option { option: "--pipeline".into(), problem: "names no step".into() });
    }
    Ok(())
}

/// One Nuth & Kääb step from where the steps before left A (`left`: dh at the shift so far, and
/// that stand), its `before` statistics computed beside the fit where no step left them: the
/// correction it makes, the fit (A's dh after it among them), where A stands after it, and the
/// statistics before it.
fn nuth_kaab_step(
    mosaic: &mut Mosaic,
    sample: (&[RefSample], &[bool]),
    bias: &[f64],
    left: (&[Option<f64>], Stand),
    before: Option<Stats>,
    opts: &NuthKaabOptions,
) -> Result<(Correction, NuthKaabRun, Stand, Stats), CompareError> {
    let ((reference, stable), (raw, stand)) = (sample, left);
    let prior: Vec<f64> = bias.iter().map(|b| b - stand.up).collect();
    let fit = || nuth_kaab(mosaic, reference, stable, &prior, stand.shift, raw, opts);
    let stats = || before.unwrap_or_else(|| stable_stats(residual_at(raw, stand.up, bias), reference, stable));
    let (run, before) = rayon::join(fit, stats);
    let run = run?;
    let left: Vec<f64> = residual(&run.dh, 0.0, bias).zip(stable).filter_map(|(d, &s)| d.filter(|_| s)).collect();
    let up = -median(left);
    let correction = Correction::NuthKaab {
        east_m: run.east_m - stand.shift.0,
        north_m: run.north_m - stand.shift.1,
        up_m: up - stand.up,
    };
    let stand = Stand { shift: (run.east_m, run.north_m), up };
    Ok((correction, run, stand, before))
}

/// Every quad's outline (3 × 3 points each) as east and north metres in `frame`.
fn outline_of(quads: &[QuadId], frame: &Frame, ellipsoid: &crate::geodesy::Ellipsoid) -> Vec<[f64; 2]> {
    quads
        .iter()
        .flat_map(|q| (0..9).map(move |k| (*q, k % 3, k / 3)))
        .map(|(q, i, j)| frame.local(crate::ecm::points::sample_point(ellipsoid, q, 3, i, j).0))
        .map(|(e, n)| [e, n])
        .collect()
}

/// What a bias step is fitted to: the stable samples' residuals after the steps before it
/// (index, dh, weight), where each sample stands, and the extent the bias holds beyond.
struct BiasFit<'a> {
    set: Vec<(usize, f64, f64)>,
    at: &'a [At],
    /// Every quad's outline where the fit read only some of them (the samples' places otherwise).
    quad_outline: Option<&'a [[f64; 2]]>,
    origin_deg: [f64; 2],
    spacing_m: f64,
}

/// Fits one step that corrects a bias (a vertical offset, a deramp, a terrain or a directional
/// bias) to what the steps before it left.
fn fit_bias(step: Step, fit: &BiasFit) -> Result<Correction, CompareError> {
    let (set, at, origin_deg) = (&fit.set, fit.at, fit.origin_deg);
    let outline = |at: &[At]| -> Vec<[f64; 2]> {
        fit.quad_outline.map_or_else(|| at.iter().map(|a| [a.east_m, a.north_m]).collect(), <[_]>::to_vec)
    };
    let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
    Ok(match step {
        Step::NuthKaab => {
            return Err(CompareError::Option {
                option: "--pipeline".into(),
                problem: "nuth_kaab fits a shift, not a bias".into(),
            });
        }
        Step::Vertical => {
            let m = vertical(&dh, &w);
            if !m.is_finite() {
                return Err(too_few("vertical"));
            }
            Correction::Vertical { up_m: -m }
        }
        Step::Deramp(order) => {
            let e: Vec<f64> = set.iter().map(|s| at[s.0].east_m / 1000.0).collect();
            let n: Vec<f64> = set.iter().map(|s| at[s.0].north_m / 1000.0).collect();
            let p = Polynomial::fit(order, &e, &n, &dh, &w).ok_or_else(|| too_few("deramp"))?;
            // Held beyond the overlap's box, not extrapolated.
            let (lo, hi) = bounds(outline(at).iter().map(|p| [p[0] / 1000.0, p[1] / 1000.0]));
            let box_km = [lo[0], lo[1], hi[0], hi[1]];
            Correction::Bias(Bias::Deramp { origin_deg, order, coefficients: p.coefficients, box_km })
        }
        Step::TerrainBias(attribute) => {
            let set: Vec<&(usize, f64, f64)> =
                set.iter().filter(|s| at[s.0].attribute(attribute).is_finite()).collect();
            let x: Vec<f64> = set.iter().map(|s| at[s.0].attribute(attribute)).collect();
            let (dh, w): (Vec<f64>, Vec<f64>) = set.iter().map(|s| (s.1, s.2)).unzip();
            let b = Binned::fit(&x, &dh, &w, crate::compare::bias::BINS).ok_or_else(|| too_few("terrain_bias"))?;
            Correction::Bias(Bias::TerrainBias { attribute, bins: b.bins })
        }
        Step::Directional(azimuth_deg) => {
            let (s, c) = azimuth_deg.to_radians().sin_cos();
            let x: Vec<f64> = set.iter().map(|k| at[k.0].east_m * s + at[k.0].north_m * c).collect();
            let extent = x.iter().fold(0.0f64, |m, v| m.max(v.abs())) * 2.0;
            let bins = ((extent / (4.0 * fit.spacing_m)) as usize).clamp(100, 1000);
            let fit = Sinusoids::fit(&x, &dh, &w, bins).ok_or_else(|| too_few("directional"))?;
            let (lo, hi) = bounds(outline(at).iter().map(|p| [p[0] * s + p[1] * c; 2]));
            Correction::Bias(Bias::Directional {
                origin_deg,
                azimuth_deg,
                offset_m: fit.offset_m,
                sinusoids: fit.sinusoids,
                range_m: [lo[0], hi[0]],
            })
        }
    })
}

/// The refusal of a step that has too few samples to fit.
fn too_few(what: &str) -> CompareError {
    CompareError::Option {
        option: "--pipeline".into(),
        problem: format!("{what}: too few stable samples with data on both sides to fit it"),
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
pub(in crate::compare) fn centroid_deg(ellipsoid: &crate::geodesy::Ellipsoid, reference: &[RefSample]) -> [f64; 2] {
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
pub(in crate::compare) fn stable_mask(
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
