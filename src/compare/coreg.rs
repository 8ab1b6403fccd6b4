//! The Nuth & Kääb (2011) step of a co-registration pipeline, on the ellipsoid, and the
//! reference's samples every step fits on (position, slope, aspect, maximal curvature, area).
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

use super::CompareError;
use super::mosaic::Mosaic;
use super::quad_geometry::{axes_at, cell_area, gradient, lon_lat, quad_points};
use super::sample::in_region;
use crate::ecm::QuadId;
use crate::ecm::grid::{GRID, spacing_m};
use crate::geodesy::GeoBox;
use crate::scene::Scene;
use crate::scene::shifted::locate;

/// Samples along a quad edge.
const N: usize = GRID as usize;
/// Aspect bins of the fit.
const BINS: usize = 72;
/// Samples a bin needs to enter the fit.
const MIN_PER_BIN: usize = 10;
/// Stable samples the iterations fit on at most (xDEM's `NuthKaab` subsamples 5·10⁵ too): the
/// first in PCG hash order, so the run is the same every time; the differences it returns are
/// over every sample.
pub const FIT_SAMPLES: usize = 500_000;

/// How Nuth & Kääb iterates.
#[derive(Clone, Copy, Debug)]
pub struct NuthKaabOptions {
    /// Most iterations.
    pub max_iterations: u32,
    /// Stop when a step is under this fraction of a sample spacing.
    pub tolerance_px: f64,
    /// Leave out samples flatter than this, degrees.
    pub min_slope_deg: f64,
}

impl Default for NuthKaabOptions {
    fn default() -> NuthKaabOptions {
        NuthKaabOptions { max_iterations: 10, tolerance_px: 0.001, min_slope_deg: 1.0 }
    }
}

/// What Nuth & Kääb found.
#[derive(Clone, Debug)]
pub(super) struct NuthKaabRun {
    /// The move of A, east and north metres (the start plus every step).
    pub east_m: f64,
    /// North.
    pub north_m: f64,
    /// Each iteration's step: east, north (metres) and the vertical bias removed.
    pub moves: Vec<[f64; 3]>,
    /// Whether the last step was under the tolerance.
    pub converged: bool,
    /// A(p − c) − B at every reference sample for the move found.
    pub dh: Vec<Option<f64>>,
}

/// A sample of the reference: 88 bytes, millions of them held at once (B's height and the
/// curvature are f32 as B's grid is; the grid axes f32, 10⁻⁶ m on a 500 m move).
#[derive(Clone, Copy)]
pub(super) struct RefSample {
    pub p: DVec3,
    /// The cell's area, m².
    pub area: f64,
    /// B's gradient east and north, metres per metre (its slope and aspect are computed from it
    /// where a step reads them: the aspect only for the samples Nuth & Kääb fits on).
    gradient: [f64; 2],
    /// Grid units per metre east and north: (du, dv) = to_grid · (de, dn), from the grid's
    /// central differences at the sample.
    to_grid: [[f32; 2]; 2],
    /// B there, metres (B's grid value).
    pub b: f32,
    /// B's maximal curvature (Shary 1995, as xDEM's `max_curvature`), 100/m; NaN where a
    /// neighbour has no data.
    pub max_curvature: f32,
    /// Its quad and grid position there (the mosaic's level is B's sampling level): sample
    /// (i, j) of the quad's 257² grid.
    pub quad: QuadId,
    pub i: u16,
    pub j: u16,
}

const _: () = assert!(std::mem::size_of::<RefSample>() == 88);

impl RefSample {
    /// The tangent of B's slope.
    pub fn tan_slope(&self) -> f64 {
        let [e, n] = self.gradient;
        (e * e + n * n).sqrt()
    }

    /// B's aspect: the azimuth of its downhill direction, radians.
    fn aspect(&self) -> f64 {
        let [e, n] = self.gradient;
        (-e).atan2(-n)
    }
}

/// Moves A onto B by Nuth & Kääb from a start (east, north metres), where A − B is `at_start`
/// (every reference sample's, as [`differences`] gives them), fitting on the samples `stable`
/// keeps (at most [`FIT_SAMPLES`] of them), with `prior` (a bias per sample, metres) taken off dh
/// first; the differences it returns are over every sample.
pub(super) fn nuth_kaab(
    mosaic: &mut Mosaic,
    reference: &[RefSample],
    stable: &[bool],
    prior: &[f64],
    start: (f64, f64),
    at_start: &[Option<f64>],
    opts: &NuthKaabOptions,
) -> Result<NuthKaabRun, CompareError> {
    let spacing = spacing_m(&mosaic.ellipsoid(), mosaic.level());
    let min_tan = opts.min_slope_deg.to_radians().tan();
    let (mut c_e, mut c_n) = start;
    let mut moves = Vec::new();
    let mut converged = false;
    // The samples fitted on: the stable ones, at most FIT_SAMPLES of them.
    let mut fit: Vec<usize> = (0..reference.len()).filter(|&k| stable[k]).collect();
    if fit.len() > FIT_SAMPLES {
        fit = crate::maths::first_in_hash_order_ascending(&fit, FIT_SAMPLES);
    }
    let subset: Vec<RefSample> = fit.iter().map(|&k| reference[k]).collect();
    let prior: Vec<f64> = fit.iter().map(|&k| prior[k]).collect();
    let mut dh: Vec<Option<f64>> = fit.iter().map(|&k| at_start[k]).collect();
    let kept =
        |dh: &[Option<f64>]| -> Vec<Option<f64>> { dh.iter().zip(&prior).map(|(d, p)| d.map(|d| d - p)).collect() };
    // Each sample's slope and aspect bin (None where it is too flat or has no aspect).
    let binned: Vec<Option<(f64, usize)>> = subset
        .par_iter()
        .map(|r| {
            let (tan_slope, aspect) = (r.tan_slope(), r.aspect());
            if tan_slope < min_tan || !aspect.is_finite() {
                return None;
            }
            let turn = aspect.rem_euclid(std::f64::consts::TAU) / std::f64::consts::TAU;
            Some((tan_slope, ((turn * BINS as f64) as usize).min(BINS - 1)))
        })
        .collect();
    for _ in 0..opts.max_iterations.max(1) {
        let here = kept(&dh);
        let bias = median(here.iter().flatten().copied().collect());
        // dh / tan α per aspect bin.
        let mut bins: Vec<Vec<f64>> = vec![Vec::new(); BINS];
        for (d, b) in here.iter().zip(&binned) {
            if let (Some(d), Some((tan_slope, bin))) = (d, b) {
                bins[*bin].push((d - bias) / tan_slope);
            }
        }
        let (s_e, s_n) = fit_cosine(bins).ok_or_else(|| CompareError::Option {
            option: "A, B".into(),
            problem: "too few sloping samples with data on both sides to fit a shift".into(),
        })?;
        // A now sits s from B: move it back by s.
        c_e -= s_e;
        c_n -= s_n;
        moves.push([-s_e, -s_n, bias]);
        dh = differences(mosaic, &subset, c_e, c_n)?;
        if s_e.hypot(s_n) < opts.tolerance_px * spacing {
            converged = true;
            break;
        }
    }
    let dh = differences(mosaic, reference, c_e, c_n)?;
    Ok(NuthKaabRun { east_m: c_e, north_m: c_n, moves, converged, dh })
}

/// B's samples over the overlap (each quad's cells 0..256 once, as in `sample`), with the local
/// frame, slope and aspect, and B's maximal curvature where `curvature` asks for it (a 6 × 6
/// least-squares fit per sample: a third of the time; NaN without it).
pub(super) fn reference_samples(
    scene_b: &Scene,
    quads: &[QuadId],
    region: Option<GeoBox>,
    curvature: bool,
) -> Result<Vec<RefSample>, CompareError> {
    let e = scene_b.ellipsoid;
    // Room for every sample (pages are only touched as samples are written), so the samples are
    // written in place by both threads, never copied into a growing vector.
    let mut out = Vec::with_capacity(quads.len() * (N - 1) * (N - 1));
    for chunk in quads.chunks(16) {
        let grids = scene_b.compose_cpu(chunk)?;
        for q in chunk {
            let h = &grids[q];
            let points = quad_points(&e, *q);
            // The cells with a sample (B has data there and a gradient, inside the region), with
            // the gradient.
            let cells: Vec<(usize, usize, DVec3)> = (0..N - 1)
                .into_par_iter()
                .flat_map_iter(|j| (0..N - 1).map(move |i| (i, j)))
                .filter_map(|(i, j)| {
                    let outside = region.is_some_and(|_| {
                        let (lon, lat) = lon_lat(&e, points[j * N + i]);
                        !in_region(region, lon, lat)
                    });
                    if h[j * N + i].is_nan() || outside {
                        return None;
                    }
                    gradient(&points, h, i, j).map(|g| (i, j, g))
                })
                .collect();
            out.par_extend(cells.into_par_iter().map(|(i, j, g)| {
                let p = points[j * N + i];
                let (east, north) = axes_at(&e, p);
                // The grid's axes in metres east and north, inverted.
                let (i0, i1) = (i.saturating_sub(1), (i + 1).min(N - 1));
                let (j0, j1) = (j.saturating_sub(1), (j + 1).min(N - 1));
                let axis = |a: usize, b: usize, steps: usize| {
                    let d = (points[b] - points[a]) / steps as f64;
                    (d.dot(east), d.dot(north))
                };
                let (ie, in_) = axis(j * N + i0, j * N + i1, i1 - i0);
                let (je, jn) = axis(j0 * N + i, j1 * N + i, j1 - j0);
                let det = ie * jn - je * in_;
                let to_grid = [[jn / det, -je / det], [-in_ / det, ie / det]].map(|row| row.map(|x| x as f32));
                RefSample {
                    p,
                    area: cell_area(&e, *q, &points, i, j),
                    gradient: [g.dot(east), g.dot(north)],
                    to_grid,
                    b: h[j * N + i],
                    max_curvature: if curvature {
                        max_curvature(&points, h, i, j, east, north) as f32
                    } else {
                        f32::NAN
                    },
                    quad: *q,
                    i: i as u16,
                    j: j as u16,
                }
            }));
        }
    }
    out.shrink_to_fit();
    Ok(out)
}

/// A − B at every reference sample with A moved by (c_e, c_n) metres: A(p − c). The moved point
/// is found in the sample's own quad through the grid's local axes (a shift of d moves it off by
/// the grid's curvature, ≈ d²/2R: 0.02 m for 500 m on Earth, 4·10⁻⁴ of a level-10 sample), and
/// located exactly (inverse projection) only where it leaves that quad.
///
/// Two passes, neither holding a moved point per sample: the first finds the quads the moved
/// points fall in (the samples come grouped by quad, so their own quads are gathered as they
/// change) and composes them; the second reads A at each moved point, each worker keeping the
/// grid of the quad it read last.
pub(super) fn differences(
    mosaic: &mut Mosaic,
    reference: &[RefSample],
    c_e: f64,
    c_n: f64,
) -> Result<Vec<Option<f64>>, CompareError> {
    let ellipsoid = mosaic.ellipsoid();
    let level = mosaic.level();
    let outside = |r: &RefSample| -> Option<(QuadId, f64, f64)> {
        let (east, north) = axes_at(&ellipsoid, r.p);
        locate(&ellipsoid, level, r.p - c_e * east - c_n * north)
    };
    let mut quads: std::collections::BTreeSet<QuadId> = reference
        .par_iter()
        .filter(|r| in_quad(r, c_e, c_n).is_none())
        .filter_map(|r| outside(r).map(|m| m.0))
        .collect();
    // The samples' own quads where they stay in them (the samples come grouped by quad).
    quads.extend(
        reference
            .par_chunks(1 << 12)
            .flat_map_iter(|chunk| {
                let mut last = None;
                chunk.iter().filter(|r| in_quad(r, c_e, c_n).is_some()).filter_map(move |r| {
                    let new = last != Some(r.quad);
                    last = Some(r.quad);
                    new.then_some(r.quad)
                })
            })
            .collect::<Vec<_>>(),
    );
    mosaic.prefetch_quads(&quads.into_iter().collect::<Vec<_>>())?;
    let mosaic = &*mosaic;
    Ok(reference
        .par_iter()
        .map_init(
            || None,
            |read: &mut Option<(QuadId, Option<&[f32]>)>, r| {
                let (q, u, v) = match in_quad(r, c_e, c_n) {
                    Some((u, v)) => (r.quad, u, v),
                    None => outside(r)?,
                };
                let grid = match *read {
                    Some((last, grid)) if last == q => grid,
                    _ => {
                        let grid = mosaic.grid(q);
                        *read = Some((q, grid));
                        grid
                    }
                };
                let a = mosaic.read(grid?, u, v);
                (!a.is_nan()).then_some(a - f64::from(r.b))
            },
        )
        .collect())
}

/// The grid position (u, v) a reference sample moves to under A's move (c_e, c_n) through its
/// quad's local axes, where it stays in the quad.
fn in_quad(r: &RefSample, c_e: f64, c_n: f64) -> Option<(f64, f64)> {
    let [[a, b], [c, d]] = r.to_grid.map(|row| row.map(f64::from));
    let (u, v) = (f64::from(r.i) - a * c_e - b * c_n, f64::from(r.j) - c * c_e - d * c_n);
    ((0.0..=256.0).contains(&u) && (0.0..=256.0).contains(&v)).then_some((u, v))
}

/// The maximal curvature of B at sample (i, j) (Shary 1995; xDEM's `max_curvature`, 100/m):
/// the quadric z = r x²/2 + s x y + t y²/2 + p x + q y + c fitted by least squares to the sample
/// and its eight neighbours in the tangent plane's east and north metres (so a sheared grid near a
/// cube corner is measured as it lies), then H + √(H² − K) from the mean curvature H and the
/// Gaussian curvature K; 0 where the fit is flat, NaN where a neighbour has no data. On the
/// quad's border the window is the one of the nearest sample inside (its curvature).
fn max_curvature(points: &[DVec3], h: &[f32], i: usize, j: usize, east: DVec3, north: DVec3) -> f64 {
    let (i, j) = (i.clamp(1, N - 2), j.clamp(1, N - 2));
    let centre = points[j * N + i];
    let mut normal = vec![vec![0.0; 6]; 6];
    let mut rhs = vec![0.0; 6];
    for dj in 0..3 {
        for di in 0..3 {
            let k = (j + dj - 1) * N + i + di - 1;
            let z = f64::from(h[k]);
            if z.is_nan() {
                return f64::NAN;
            }
            let d = points[k] - centre;
            let (x, y) = (d.dot(east), d.dot(north));
            let row = [0.5 * x * x, x * y, 0.5 * y * y, x, y, 1.0];
            for a in 0..6 {
                rhs[a] += row[a] * z;
                for b in 0..6 {
                    normal[a][b] += row[a] * row[b];
                }
            }
        }
    }
    let Some(c) = super::bias::solve(normal, rhs) else { return f64::NAN };
    let (r, s, t, p, q) = (c[0], c[1], c[2], c[3], c[4]);
    if p == 0.0 && q == 0.0 {
        return 0.0;
    }
    let w = 1.0 + p * p + q * q;
    let mean = -((1.0 + q * q) * r - 2.0 * p * q * s + (1.0 + p * p) * t) / (2.0 * w.powf(1.5));
    let gauss = (r * t - s * s) / (w * w);
    100.0 * (mean + (mean * mean - gauss).max(0.0).sqrt())
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
