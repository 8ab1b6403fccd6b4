//! The uncertainty of a mean elevation change and of a volume change (Hugonnet et al. 2022, the
//! workflow of `xdem.spatialstats`), on the samples of a comparison (B's grid at one level, each
//! weighted by its cell's area on the ellipsoid):
//!
//! 1. **Heteroscedasticity.** On stable terrain, the NMAD of dh = A − B in 10 × 10 bins of B's
//!    slope and maximal curvature (bin edges at the deciles of each, so every bin is populated;
//!    xDEM's default is equal-width bins, which leave the heavy tail of curvature in a few) and a
//!    model fitted to it: σ² = σ₀² + (k_s · tan slope)² + (k_c · curvature)², by non-negative
//!    weighted least squares on the bins' NMAD² (a base error, a horizontal error that grows
//!    with slope, a resolution error that grows with curvature: errors that add in quadrature).
//! 2. **Standardisation.** z = dh / σ(slope, curvature); |z| beyond 7 NMADs left out; the model
//!    scaled by NMAD(z) (xDEM's `two_step_standardization`).
//! 3. **Spatial correlation.** The empirical variogram of z and a sum of up to two spherical
//!    models ([`super::variogram`]).
//! 4. **Propagation.** Over the area (every sample with data, or those a layer or polygons
//!    select): the mean dh (area-weighted), its 1σ = mean σ / √N_eff with N_eff of a disk of the
//!    area's size (xDEM's `spatial_error_propagation` with a numeric area), and the volume change
//!    mean dh × area with 1σ = σ_mean × area.
//!
//! Steps 1–3 hold their samples, so they are fitted on at most [`FIT_QUADS`] quads: all of them
//! when there are no more, else those first in hash order (spread at random over the overlap,
//! each whole, so the variogram keeps its short lags). Step 4 runs over every sample, 16 quads at
//! a time, in sample order: memory stays bounded however many samples the area has (10⁸ at
//! finer levels) and the area, mean and volume are the same as from every sample held.

use serde::Serialize;

use super::CompareError;
use super::bias::nonnegative_least_squares;
use super::coreg::{RefSample, differences, reference_samples};
use super::mosaic::{Interpolation, Mosaic};
use super::pipeline::stable_mask;
use super::sample::{fit_quads, operand_scene, overlap_quads};
use super::stable::Stable;
use super::stats::weighted_quantile;
use super::variogram::{Spherical, VariogramBin, empirical, fit, neff_disk};
use crate::ecm::QuadId;
use crate::ecm::grid::spacing_m;
use crate::geodesy::GeoBox;
use crate::layers::Operand;
use crate::layers::correction::Frame;
use crate::project::Project;
use crate::scene::Scene;

/// Bins along each explanatory variable.
const BINS: usize = 10;
/// Samples a bin needs for its NMAD to count (xDEM's `min_count`).
const MIN_COUNT: u64 = 100;
/// Most quads the error model and the variogram are fitted on (3.1·10⁶ samples, ≈ 1.2 GB held).
pub const FIT_QUADS: usize = 48;
/// Quads the area's sums read at once.
const CHUNK: usize = 16;
/// Standardised values beyond this many NMADs are outliers (xDEM's `fac_spread_outliers`).
const OUTLIER_NMADS: f64 = 7.0;

/// What to propagate and where.
#[derive(Clone, Debug, Default)]
pub struct UncertaintyOptions {
    /// The level (default: the comparison's).
    pub level: Option<u8>,
    /// Only inside this box.
    pub region: Option<GeoBox>,
    /// Where the error model is fitted (default: everywhere).
    pub stable: Option<Stable>,
    /// The area of the mean and volume (default: every sample with data): a layer's coverage, or
    /// inside polygons.
    pub area: Option<Stable>,
    /// Keep the samples the model was fitted on (for checks against xDEM).
    pub keep_samples: bool,
    /// Most quads the model is fitted on (default [`FIT_QUADS`]; 0 counts as 1).
    pub fit_quads: Option<usize>,
    /// Counts the quads of the area summed (and stops when cancelled).
    pub watch: Option<std::sync::Arc<crate::progress::Watch>>,
}

/// The error model of dh (field names are the JSON's: scripts rely on them).
#[derive(Clone, Debug, Serialize)]
pub struct Heteroscedasticity {
    /// Slope bin edges, degrees.
    pub slope_edges_deg: Vec<f64>,
    /// Maximal curvature bin edges, 100/m.
    pub max_curvature_edges: Vec<f64>,
    /// The NMAD of dh per bin, metres, `[slope bin][curvature bin]` (null: under 100 samples).
    pub nmad_m: Vec<Vec<Option<f64>>>,
    /// Stable samples per bin.
    pub count: Vec<Vec<u64>>,
    /// The model's base error σ₀, metres.
    pub base_m: f64,
    /// Its slope term k_s, metres per unit of tan slope.
    pub slope_m: f64,
    /// Its curvature term k_c, metres per 100/m.
    pub curvature_m: f64,
    /// The factor the model was scaled by (NMAD of the standardised dh).
    pub scale: f64,
}

impl Heteroscedasticity {
    /// σ of dh at a slope (degrees) and maximal curvature (100/m; NaN: taken as 0), metres.
    pub fn sigma_m(&self, slope_deg: f64, max_curvature: f64) -> f64 {
        let t = slope_deg.to_radians().tan();
        let k = if max_curvature.is_finite() { max_curvature } else { 0.0 };
        self.scale * (self.base_m.powi(2) + (self.slope_m * t).powi(2) + (self.curvature_m * k).powi(2)).sqrt()
    }
}

/// The spatial correlation of the standardised dh (field names are the JSON's).
#[derive(Clone, Debug, Serialize)]
pub struct Variogram {
    /// The fitted spherical models (ranges and partial sills), shortest range first.
    pub models: Vec<Spherical>,
    /// The empirical variogram.
    pub bins: Vec<VariogramBin>,
}

/// One sample, for checks against xDEM.
#[derive(Clone, Debug, Serialize)]
pub struct UncertaintySample {
    /// East and north metres in the tangent frame at the samples' centroid.
    pub east_m: f64,
    /// North.
    pub north_m: f64,
    /// A − B, metres (NaN: no data).
    pub dh_m: f64,
    /// B's slope, degrees.
    pub slope_deg: f64,
    /// B's maximal curvature, 100/m.
    pub max_curvature: f64,
    /// The cell's area, m².
    pub area_m2: f64,
    /// On stable terrain.
    pub stable: bool,
    /// In the area.
    pub in_area: bool,
}

/// The uncertainty of the mean dh and the volume change over an area (field names are the
/// JSON's `uncertainty`: scripts rely on them).
#[derive(Clone, Debug, Serialize)]
pub struct Uncertainty {
    /// The level worked at.
    pub level: u8,
    /// Its mean sample spacing, metres.
    pub spacing_m: f64,
    /// Where the model was fitted (absent: everywhere).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub stable: Option<String>,
    /// Stable samples the model was fitted on (with data and curvature, outliers left out).
    pub stable_count: u64,
    /// Quads of the overlap (the area's mean and volume are over all of them).
    pub quad_count: u64,
    /// Quads the model and the variogram were fitted on.
    pub fit_quad_count: u64,
    /// The area (absent: every sample with data).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub area: Option<String>,
    /// Its size, m² (the cells with data in it).
    pub area_m2: f64,
    /// Area-weighted mean dh over it, metres.
    pub mean_dh_m: f64,
    /// Its 1σ, metres.
    pub mean_dh_sigma_m: f64,
    /// mean dh × area, m³.
    pub volume_m3: f64,
    /// Its 1σ, m³.
    pub volume_sigma_m3: f64,
    /// The mean σ of dh over the area, metres.
    pub mean_error_m: f64,
    /// Effective samples of the area.
    pub effective_samples: f64,
    /// The error model.
    pub heteroscedasticity: Heteroscedasticity,
    /// The spatial correlation.
    pub variogram: Variogram,
    /// The samples, when asked for.
    #[serde(skip)]
    pub samples: Vec<UncertaintySample>,
}

/// Propagates the errors of A − B to the mean and volume change over an area.
pub fn uncertainty(
    project: &Project,
    a: &str,
    b: &str,
    opts: &UncertaintyOptions,
) -> Result<Uncertainty, CompareError> {
    let (scene, _) = Scene::open(project)?;
    let alone = |name: &str| operand_scene(&scene, project, &Operand::Layer(name.into()));
    let (scene_a, scene_b) = (alone(a)?, alone(b)?);
    let (level, quads) = overlap_quads(&scene_a, &scene_b, opts.level, opts.region)?;
    let ellipsoid = scene_b.ellipsoid;
    let fitted = fit_quads(&quads, opts.fit_quads.unwrap_or(FIT_QUADS));
    let reference = reference_samples(&scene_b, &fitted, opts.region, true)?;
    if reference.is_empty() {
        return Err(CompareError::Option { option: "A, B".into(), problem: "the layers do not overlap".into() });
    }
    let stable = stable_mask(&scene, project, &fitted, &reference, opts.stable.as_ref())?;
    let in_area = area_mask(&scene, project, opts.area.as_ref(), &fitted, &reference)?;
    let dh = unshifted_differences(&scene_a, level, &reference)?;
    let slope: Vec<f64> = reference.iter().map(|r| r.tan_slope().atan().to_degrees()).collect();
    let curvature: Vec<f64> = reference.iter().map(|r| f64::from(r.max_curvature)).collect();

    // 1. The binned NMAD and its model, on stable samples with dh and a curvature; 2. dh
    // standardised by it, outliers out, the model rescaled.
    let fit_set: Vec<usize> =
        (0..reference.len()).filter(|&k| stable[k] && dh[k].is_finite() && curvature[k].is_finite()).collect();
    let on = Fitted { reference: &reference, fit_set: &fit_set, dh: &dh, slope: &slope, curvature: &curvature };
    let mut model = error_model(&on)?;
    let z = standardised(&on, &mut model)?;

    // 3. The variogram of z, up to the diagonal of the samples' extent.
    let spacing = spacing_m(&ellipsoid, level);
    let frame = Frame::at(&ellipsoid, super::pipeline::centroid_deg(&ellipsoid, &reference));
    let local: Vec<(f64, f64)> = reference.iter().map(|r| frame.local(r.p)).collect();
    let (lo, hi) = local.iter().fold(([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]), |(lo, hi), &(e, n)| {
        ([lo[0].min(e), lo[1].min(n)], [hi[0].max(e), hi[1].max(n)])
    });
    let max_lag = (hi[0] - lo[0]).hypot(hi[1] - lo[1]);
    let points: Vec<glam::DVec3> = reference.iter().map(|r| r.p).collect();
    let weights: Vec<f64> = reference.iter().map(|r| r.area).collect();
    let bins = empirical(&points, &z, &weights, spacing, max_lag);
    let correlation = fit(&bins).ok_or_else(|| too_few("the variogram"))?;

    // 4. The mean, the volume and their errors over the area: every sample, in sample order.
    let mut sums = AreaSums::default();
    if fitted.len() == quads.len() {
        sums.add(&reference, &in_area, &dh, &model);
    } else {
        super::phase(&opts.watch, "area", quads.len());
        for chunk in quads.chunks(CHUNK) {
            super::tick(&opts.watch, chunk.len())?;
            let reference = reference_samples(&scene_b, chunk, opts.region, true)?;
            let in_area = area_mask(&scene, project, opts.area.as_ref(), chunk, &reference)?;
            let dh = unshifted_differences(&scene_a, level, &reference)?;
            sums.add(&reference, &in_area, &dh, &model);
        }
    }
    if sums.count == 0 {
        return Err(CompareError::Option {
            option: "--area".into(),
            problem: "holds no sample with data on both sides".into(),
        });
    }
    let area_m2 = sums.area_m2;
    let (mean_dh_m, mean_error_m) = (sums.dh_area / area_m2, sums.sigma_area / area_m2);
    let neff = neff_disk(&correlation, area_m2);
    let mean_dh_sigma_m = mean_error_m / neff.sqrt();
    let samples = if opts.keep_samples {
        (0..reference.len())
            .map(|k| UncertaintySample {
                east_m: local[k].0,
                north_m: local[k].1,
                dh_m: dh[k],
                slope_deg: slope[k],
                max_curvature: curvature[k],
                area_m2: reference[k].area,
                stable: stable[k],
                in_area: in_area[k],
            })
            .collect()
    } else {
        Vec::new()
    };
    Ok(Uncertainty {
        level,
        spacing_m: spacing,
        stable: opts.stable.as_ref().map(Stable::describe),
        stable_count: z.iter().filter(|v| v.is_finite()).count() as u64,
        quad_count: quads.len() as u64,
        fit_quad_count: fitted.len() as u64,
        area: opts.area.as_ref().map(Stable::describe_area),
        area_m2,
        mean_dh_m,
        mean_dh_sigma_m,
        volume_m3: mean_dh_m * area_m2,
        volume_sigma_m3: mean_dh_sigma_m * area_m2,
        mean_error_m,
        effective_samples: neff,
        heteroscedasticity: model,
        variogram: Variogram { models: correlation.models.clone(), bins },
        samples,
    })
}

/// The samples an error model is fitted on: the stable ones with dh and a curvature (`fit_set`,
/// indices into the others), and per reference sample its dh, slope (degrees) and maximal
/// curvature.
struct Fitted<'a> {
    reference: &'a [RefSample],
    fit_set: &'a [usize],
    dh: &'a [f64],
    slope: &'a [f64],
    curvature: &'a [f64],
}

/// The binned NMAD of dh by slope and curvature deciles, and its model σ² = a² + (b·tan α)² +
/// (c·κ)² fitted by non-negative least squares over the bins of at least MIN_COUNT samples.
fn error_model(on: &Fitted) -> Result<Heteroscedasticity, CompareError> {
    let Fitted { reference, fit_set, dh, slope, curvature } = *on;
    let deciles = |v: &[f64]| -> Vec<f64> {
        let mut sorted: Vec<(f64, f64)> = fit_set.iter().map(|&k| (v[k], reference[k].area)).collect();
        sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut edges: Vec<f64> = (0..=BINS).map(|q| weighted_quantile(&sorted, q as f64 / BINS as f64)).collect();
        edges.dedup();
        edges
    };
    let (slope_edges, curvature_edges) = (deciles(slope), deciles(curvature));
    if fit_set.len() < MIN_COUNT as usize || slope_edges.len() < 2 || curvature_edges.len() < 2 {
        return Err(too_few("the error model"));
    }
    let bin = |edges: &[f64], x: f64| edges.partition_point(|&e| e <= x).clamp(1, edges.len() - 1) - 1;
    let (ns, nc) = (slope_edges.len() - 1, curvature_edges.len() - 1);
    let mut groups: Vec<Vec<usize>> = vec![Vec::new(); ns * nc];
    for &k in fit_set {
        groups[bin(&slope_edges, slope[k]) * nc + bin(&curvature_edges, curvature[k])].push(k);
    }
    let mut nmad_m = vec![vec![None; nc]; ns];
    let mut count = vec![vec![0u64; nc]; ns];
    let mut rows = Vec::new();
    for (g, members) in groups.iter().enumerate() {
        let (i, j) = (g / nc, g % nc);
        count[i][j] = members.len() as u64;
        if (members.len() as u64) < MIN_COUNT {
            continue;
        }
        let nmad = weighted_nmad(members.iter().map(|&k| (dh[k], reference[k].area)));
        nmad_m[i][j] = Some(nmad);
        let mean = |f: &dyn Fn(usize) -> f64| members.iter().map(|&k| f(k)).sum::<f64>() / members.len() as f64;
        let t2 = mean(&|k| slope[k].to_radians().tan().powi(2));
        let k2 = mean(&|k| curvature[k].powi(2));
        rows.push((vec![1.0, t2, k2], nmad * nmad, members.len() as f64));
    }
    let (c, _) = nonnegative_least_squares(&rows).ok_or_else(|| too_few("the error model"))?;
    Ok(Heteroscedasticity {
        slope_edges_deg: slope_edges,
        max_curvature_edges: curvature_edges,
        nmad_m,
        count,
        base_m: c[0].sqrt(),
        slope_m: c[1].sqrt(),
        curvature_m: c[2].sqrt(),
        scale: 1.0,
    })
}

/// dh standardised by the model (NaN off the fit set and for outliers past OUTLIER_NMADS), the
/// model's scale set to the NMAD of what is left, by which z is divided.
fn standardised(on: &Fitted, model: &mut Heteroscedasticity) -> Result<Vec<f64>, CompareError> {
    let Fitted { reference, fit_set, dh, slope, curvature } = *on;
    let mut z: Vec<f64> = vec![f64::NAN; reference.len()];
    for &k in fit_set {
        z[k] = dh[k] / model.sigma_m(slope[k], curvature[k]);
    }
    let spread = weighted_nmad(fit_set.iter().map(|&k| (z[k], reference[k].area)));
    for v in z.iter_mut() {
        if v.abs() > OUTLIER_NMADS * spread {
            *v = f64::NAN;
        }
    }
    let scale = weighted_nmad(fit_set.iter().filter(|&&k| z[k].is_finite()).map(|&k| (z[k], reference[k].area)));
    if !(scale.is_finite() && scale > 0.0) {
        return Err(too_few("the error model"));
    }
    z.iter_mut().for_each(|v| *v /= scale);
    model.scale = scale;
    Ok(z)
}

/// The refusal of a fit that has too few samples.
fn too_few(what: &str) -> CompareError {
    CompareError::Option {
        option: "--uncertainty".into(),
        problem: format!("too few stable samples with data on both sides to fit {what}"),
    }
}

/// Which reference samples are in the area (all without one).
fn area_mask(
    scene: &Scene,
    project: &Project,
    area: Option<&Stable>,
    quads: &[QuadId],
    reference: &[RefSample],
) -> Result<Vec<bool>, CompareError> {
    match area {
        None => Ok(vec![true; reference.len()]),
        Some(area) => area.select(scene, project, quads, reference, true),
    }
}

/// A − B at every reference sample, A unmoved (NaN: no data), from A composed on their quads.
fn unshifted_differences(scene_a: &Scene, level: u8, reference: &[RefSample]) -> Result<Vec<f64>, CompareError> {
    let mut mosaic = Mosaic::new(scene_a.clone(), level, Interpolation::Bilinear);
    Ok(differences(&mut mosaic, reference, 0.0, 0.0)?.iter().map(|d| d.unwrap_or(f64::NAN)).collect())
}

/// The area's sums, in sample order: its samples with data on both sides, their area, and their
/// dh and σ times the area.
#[derive(Default)]
struct AreaSums {
    count: u64,
    area_m2: f64,
    dh_area: f64,
    sigma_area: f64,
}

impl AreaSums {
    fn add(&mut self, reference: &[RefSample], in_area: &[bool], dh: &[f64], model: &Heteroscedasticity) {
        for (k, r) in reference.iter().enumerate() {
            if !(in_area[k] && dh[k].is_finite()) {
                continue;
            }
            let slope_deg = r.tan_slope().atan().to_degrees();
            self.count += 1;
            self.area_m2 += r.area;
            self.dh_area += dh[k] * r.area;
            self.sigma_area += model.sigma_m(slope_deg, f64::from(r.max_curvature)) * r.area;
        }
    }
}

/// The weighted NMAD: 1.4826 × the weighted median of |x − weighted median|.
fn weighted_nmad(values: impl Iterator<Item = (f64, f64)>) -> f64 {
    let mut sorted: Vec<(f64, f64)> = values.collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    let median = weighted_quantile(&sorted, 0.5);
    let mut deviations: Vec<(f64, f64)> = sorted.iter().map(|&(x, w)| ((x - median).abs(), w)).collect();
    deviations.sort_by(|a, b| a.0.total_cmp(&b.0));
    1.4826 * weighted_quantile(&deviations, 0.5)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_error_model_grows_with_slope_and_curvature_in_quadrature() {
        let h = Heteroscedasticity {
            slope_edges_deg: vec![],
            max_curvature_edges: vec![],
            nmad_m: vec![],
            count: vec![],
            base_m: 1.0,
            slope_m: 4.0,
            curvature_m: 2.0,
            scale: 1.5,
        };
        assert!((h.sigma_m(0.0, 0.0) - 1.5).abs() < 1e-12);
        // tan 45° = 1: √(1 + 16 + 4·0.25) = √18.
        assert!((h.sigma_m(45.0, 0.5) - 1.5 * 18f64.sqrt()).abs() < 1e-12);
        assert_eq!(h.sigma_m(0.0, f64::NAN), h.sigma_m(0.0, 0.0));
        assert!((weighted_nmad([(1.0, 1.0), (2.0, 1.0), (3.0, 1.0)].into_iter()) - 1.4826).abs() < 1e-12);
    }
}
