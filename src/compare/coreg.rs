//! Co-registration of layer A onto layer B by Nuth & Kääb (2011), on the ellipsoid.
//!
//! Where A is B displaced by s (A(p) = B(p − s)), dh = A − B ≈ −∇B·s, so with B's slope α and
//! aspect ψ (the azimuth of its downhill direction), dh / tan α = s_e·sin ψ + s_n·cos ψ: a cosine of
//! the aspect, a·cos(b − ψ) + c, linear in (s_n, s_e, c). Each iteration samples A at every sample
//! p of B moved by the correction found so far (in the local east-north plane at p, metres on the
//! ellipsoid), removes the median of dh (the vertical bias), takes the median of dh / tan α in 72
//! aspect bins (robust to outliers), fits the cosine by least squares over the bins, and moves the
//! correction by the displacement found. It stops when a step is under `tolerance_px` of a sample
//! spacing or after `max_iterations`. Samples with slopes under `min_slope_deg` (where dh / tan α
//! is mostly noise), no data on either side, or outside the region are left out.
//!
//! The result moves A by (east_m, north_m) and raises it by up_m: A′(p) = A(p − c) + up.

use crate::maths::median;
use glam::DVec3;
use rayon::prelude::*;
use serde::Serialize;

use super::CompareError;
use super::mosaic::Mosaic;
use super::sample::{gradient, operand_scene, overlap_quads, quad_points};
use super::stats::{Diff, Stats, stats};
use crate::ecm::QuadId;
use crate::geodesy::GeoBox;
use crate::layers::Operand;
use crate::project::Project;
use crate::scene::Scene;
use crate::scene::shifted::{local_axes, locate};
use crate::store::grid::{GRID, spacing_m};

/// Samples along a quad edge.
const N: usize = GRID as usize;
/// Aspect bins of the fit.
const BINS: usize = 72;
/// Samples a bin needs to enter the fit.
const MIN_PER_BIN: usize = 10;

/// How to co-register.
#[derive(Clone, Debug)]
pub struct CoregOptions {
    /// The level (default: one finer than the finest level of the coarser dataset. A is sampled
    /// between its samples by bilinear interpolation, which smooths it; at the data's own level B
    /// is not, and the unequal smoothing biases the fit. On a grid twice as fine three samples of
    /// B in four are bilinear interpolations too, so both sides are smoothed alike: measured on
    /// a synthetic shift, 0.12 m error instead of 0.38 m, where keeping only every other sample
    /// of the finer grid gives 0.38 m again; BENCHMARKS.md).
    pub level: Option<u8>,
    /// Only inside this box: west, south, east, north, degrees.
    pub region: Option<GeoBox>,
    /// Most iterations.
    pub max_iterations: u32,
    /// Stop when a step is under this fraction of a sample spacing.
    pub tolerance_px: f64,
    /// Leave out samples flatter than this, degrees.
    pub min_slope_deg: f64,
}

impl Default for CoregOptions {
    fn default() -> CoregOptions {
        CoregOptions { level: None, region: None, max_iterations: 10, tolerance_px: 0.001, min_slope_deg: 1.0 }
    }
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
    /// Move A east by this much, metres (local frame of each sample).
    pub east_m: f64,
    /// Move A north by this much, metres.
    pub north_m: f64,
    /// Raise A by this much, metres.
    pub up_m: f64,
    /// Iterations made.
    pub iterations: u32,
    /// Whether the last step was under the tolerance.
    pub converged: bool,
    /// Each iteration's step: east, north (metres) and the vertical bias removed.
    pub steps: Vec<[f64; 3]>,
    /// Statistics of A − B before (cell-area weighted).
    pub before: Stats,
    /// Statistics of A′ − B after.
    pub after: Stats,
}

/// A sample of the reference.
#[derive(Clone, Copy)]
struct RefSample {
    p: DVec3,
    b: f64,
    /// Its quad and grid position there (the mosaic's level is B's sampling level).
    quad: QuadId,
    u: f64,
    v: f64,
    /// Grid units per metre east and north: (du, dv) = to_grid · (de, dn), from the grid's
    /// central differences at the sample.
    to_grid: [[f64; 2]; 2],
    tan_slope: f64,
    aspect: f64,
    area: f64,
}

/// Co-registers layer `a` onto layer `b` of a project.
pub fn coregister(project: &Project, a: &str, b: &str, opts: &CoregOptions) -> Result<Coregistration, CompareError> {
    if a == b {
        return Err(CompareError::Option {
            option: "--to".into(),
            problem: format!("'{a}' co-registered onto itself"),
        });
    }
    let (scene, _) = Scene::open(project)?;
    let alone = |name: &str| operand_scene(&scene, project, &Operand::Layer(name.into()));
    let (scene_a, scene_b) = (alone(a)?, alone(b)?);
    let (finest, _) = overlap_quads(&scene_a, &scene_b, None, opts.region).map(|(l, q)| (l, q.len()))?;
    let (level, quads) = overlap_quads(&scene_a, &scene_b, Some(opts.level.unwrap_or(finest + 1)), opts.region)?;
    let ellipsoid = scene_b.ellipsoid;
    let reference = reference_samples(&scene_b, &quads, opts.region)?;
    if reference.is_empty() {
        return Err(CompareError::Option { option: "A, B".into(), problem: "the layers do not overlap".into() });
    }
    let mut mosaic = Mosaic::new(scene_a, level);
    let spacing = spacing_m(&ellipsoid, level);
    let min_tan = opts.min_slope_deg.to_radians().tan();
    let (mut c_e, mut c_n) = (0.0, 0.0);
    let mut steps = Vec::new();
    let mut converged = false;
    let before = differences(&mut mosaic, &reference, 0.0, 0.0)?;
    let mut dh = before.clone();
    for _ in 0..opts.max_iterations.max(1) {
        let bias = median(dh.iter().flatten().copied().collect());
        // dh / tan α per aspect bin.
        let mut bins: Vec<Vec<f64>> = vec![Vec::new(); BINS];
        for (d, r) in dh.iter().zip(&reference) {
            let Some(d) = d else { continue };
            if r.tan_slope < min_tan || !r.aspect.is_finite() {
                continue;
            }
            let turn = r.aspect.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
            bins[((turn * BINS as f64) as usize).min(BINS - 1)].push((d - bias) / r.tan_slope);
        }
        let (s_e, s_n) = fit_cosine(bins).ok_or_else(|| CompareError::Option {
            option: "A, B".into(),
            problem: "too few sloping samples with data on both sides to fit a shift".into(),
        })?;
        // A now sits s from B: move it back by s.
        c_e -= s_e;
        c_n -= s_n;
        steps.push([-s_e, -s_n, bias]);
        dh = differences(&mut mosaic, &reference, c_e, c_n)?;
        if s_e.hypot(s_n) < opts.tolerance_px * spacing {
            converged = true;
            break;
        }
    }
    let up = -median(dh.iter().flatten().copied().collect());
    let diffs = |dh: &[Option<f64>], up: f64| -> Vec<Diff> {
        dh.iter()
            .zip(&reference)
            .filter_map(|(d, r)| {
                d.map(|d| Diff { dh_m: d + up, weight: r.area, slope_deg: r.tan_slope.atan().to_degrees() })
            })
            .collect()
    };
    Ok(Coregistration {
        a: a.into(),
        b: b.into(),
        level,
        spacing_m: spacing,
        east_m: c_e,
        north_m: c_n,
        up_m: up,
        iterations: steps.len() as u32,
        converged,
        steps,
        before: stats(&diffs(&before, 0.0), 0),
        after: stats(&diffs(&dh, up), 0),
    })
}

/// B's samples over the overlap (each quad's cells 0..256 once, as in `sample`), with the local
/// frame, slope and aspect.
fn reference_samples(
    scene_b: &Scene,
    quads: &[QuadId],
    region: Option<GeoBox>,
) -> Result<Vec<RefSample>, CompareError> {
    let e = scene_b.ellipsoid;
    let mut out = Vec::new();
    for chunk in quads.chunks(16) {
        let grids = scene_b.compose_cpu(chunk)?;
        for q in chunk {
            let h = &grids[q];
            let points = quad_points(&e, *q);
            let rows: Vec<Vec<RefSample>> = (0..N - 1)
                .into_par_iter()
                .map(|j| {
                    (0..N - 1)
                        .filter_map(|i| {
                            let k = j * N + i;
                            let (p, lon, lat) = points[k];
                            let b = f64::from(h[k]);
                            if b.is_nan() || !super::sample::in_region(region, lon, lat) {
                                return None;
                            }
                            let (east, north) = local_axes(lon, lat);
                            let g = gradient(&points, h, i, j)?;
                            // The grid's axes in metres east and north, inverted.
                            let (i0, i1) = (i.saturating_sub(1), (i + 1).min(N - 1));
                            let (j0, j1) = (j.saturating_sub(1), (j + 1).min(N - 1));
                            let axis = |a: usize, b: usize, steps: usize| {
                                let d = (points[b].0 - points[a].0) / steps as f64;
                                (d.dot(east), d.dot(north))
                            };
                            let (ie, in_) = axis(j * N + i0, j * N + i1, i1 - i0);
                            let (je, jn) = axis(j0 * N + i, j1 * N + i, j1 - j0);
                            let det = ie * jn - je * in_;
                            let to_grid = [[jn / det, -je / det], [-in_ / det, ie / det]];
                            let (g_e, g_n) = (g.dot(east), g.dot(north));
                            let corner = |di: usize, dj: usize| points[(j + dj) * N + i + di].0;
                            let area = 0.5 * (corner(1, 1) - p).cross(corner(0, 1) - corner(1, 0)).length();
                            Some(RefSample {
                                p,
                                b,
                                quad: *q,
                                u: i as f64,
                                v: j as f64,
                                to_grid,
                                tan_slope: g_e.hypot(g_n),
                                aspect: (-g_e).atan2(-g_n),
                                area,
                            })
                        })
                        .collect()
                })
                .collect();
            out.extend(rows.into_iter().flatten());
        }
    }
    Ok(out)
}

/// A − B at every reference sample with A moved by (c_e, c_n) metres: A(p − c). The moved point
/// is found in the sample's own quad through the grid's local axes (a shift of d moves it off by
/// the grid's curvature, ≈ d²/2R: 0.02 m for 500 m on Earth, 4·10⁻⁴ of a level-10 sample), and
/// located exactly (inverse projection) only where it leaves that quad.
fn differences(
    mosaic: &mut Mosaic,
    reference: &[RefSample],
    c_e: f64,
    c_n: f64,
) -> Result<Vec<Option<f64>>, CompareError> {
    let ellipsoid = mosaic.ellipsoid();
    let level = mosaic.level();
    let moved: Vec<Option<(QuadId, f64, f64)>> = reference
        .par_iter()
        .map(|r| {
            let [[a, b], [c, d]] = r.to_grid;
            let (u, v) = (r.u - a * c_e - b * c_n, r.v - c * c_e - d * c_n);
            if (0.0..=256.0).contains(&u) && (0.0..=256.0).contains(&v) {
                return Some((r.quad, u, v));
            }
            let (lon, lat) = {
                let g = crate::geodesy::geodetic_from_ecef(&ellipsoid, r.p);
                (g.lon_rad, g.lat_rad)
            };
            let (east, north) = local_axes(lon, lat);
            locate(&ellipsoid, level, r.p - c_e * east - c_n * north)
        })
        .collect();
    let quads: std::collections::BTreeSet<QuadId> = moved.iter().flatten().map(|m| m.0).collect();
    mosaic.prefetch_quads(&quads.into_iter().collect::<Vec<_>>())?;
    let mosaic = &*mosaic;
    Ok(moved
        .par_iter()
        .zip(reference)
        .map(|(m, r)| {
            let a = m.map_or(f64::NAN, |(q, u, v)| mosaic.value_at(q, u, v));
            (!a.is_nan()).then_some(a - r.b)
        })
        .collect())
}

/// Fits median(bin) = s_n·cos ψ + s_e·sin ψ + c over the aspect bins with enough samples, by
/// least squares; returns (s_e, s_n), or None with fewer than 3 bins.
fn fit_cosine(bins: Vec<Vec<f64>>) -> Option<(f64, f64)> {
    let mut rows = Vec::new();
    for (k, bin) in bins.into_iter().enumerate() {
        if bin.len() < MIN_PER_BIN {
            continue;
        }
        let psi = (k as f64 + 0.5) / BINS as f64 * std::f64::consts::TAU;
        rows.push((psi.cos(), psi.sin(), median(bin)));
    }
    if rows.len() < 3 {
        return None;
    }
    // Normal equations of [cos ψ, sin ψ, 1] · [s_n, s_e, c] = y.
    let mut m = [[0.0f64; 3]; 3];
    let mut r = [0.0f64; 3];
    for (c, s, y) in rows {
        let x = [c, s, 1.0];
        for i in 0..3 {
            for j in 0..3 {
                m[i][j] += x[i] * x[j];
            }
            r[i] += x[i] * y;
        }
    }
    let solution = solve3(m, r)?;
    Some((solution[1], solution[0]))
}

/// Solves a 3 × 3 system by Cramer's rule (None when singular).
fn solve3(m: [[f64; 3]; 3], r: [f64; 3]) -> Option<[f64; 3]> {
    let det = |a: [[f64; 3]; 3]| {
        a[0][0] * (a[1][1] * a[2][2] - a[1][2] * a[2][1]) - a[0][1] * (a[1][0] * a[2][2] - a[1][2] * a[2][0])
            + a[0][2] * (a[1][0] * a[2][1] - a[1][1] * a[2][0])
    };
    let d = det(m);
    if d.abs() < 1e-12 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut a = m;
        for i in 0..3 {
            a[i][k] = r[i];
        }
        *o = det(a) / d;
    }
    Some(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_cosine_fit_recovers_a_known_shift_from_clean_bins() {
        // dh / tan α = s_e sin ψ + s_n cos ψ + c with s = (12, −7) m and c = 0.4.
        let bins: Vec<Vec<f64>> = (0..BINS)
            .map(|k| {
                let psi = (k as f64 + 0.5) / BINS as f64 * std::f64::consts::TAU;
                vec![12.0 * psi.sin() - 7.0 * psi.cos() + 0.4; MIN_PER_BIN]
            })
            .collect();
        let (e, n) = fit_cosine(bins).unwrap();
        assert!((e - 12.0).abs() < 1e-9 && (n + 7.0).abs() < 1e-9, "{e} {n}");
        assert!(fit_cosine(vec![Vec::new(); BINS]).is_none());
    }
}
