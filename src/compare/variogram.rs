//! The spatial correlation of errors (Hugonnet et al. 2022, as `xdem.spatialstats`): an empirical
//! variogram of standardised differences on the ellipsoid, a sum of up to two spherical models
//! fitted to it, and the number of effective samples of a mean over an area.
//!
//! - [`empirical`]: every pair among 3 000 samples (as xDEM's `pdist_point`), and 1 000 of them
//!   each with every sample within 16 spacings (the short lags such a pool misses), drawn
//!   deterministically: the samples first in PCG hash order. Lags are chord distances
//!   between the samples' ECEF points (the geodesic to 10⁻⁶ at 40 km), binned from √2 spacings
//!   growing by √2 (xDEM's bins); γ per bin is Dowd's robust estimator, 2γ = 2.198 · median(|Δz|)²,
//!   each pair weighted by the product of its samples' cell areas.
//! - [`fit`]: γ(h) = Σ cₖ · sph(h / rₖ), sph(x) = 1.5x − 0.5x³ below 1 and 1 beyond, by least
//!   squares over the bins: each pair of ranges on a log grid with the sills by non-negative least
//!   squares, then each range refined by golden-section search with the other held.
//! - [`neff_disk`]: N_eff = sill / SE² with SE² the covariance averaged over a disk of the area
//!   (Rolstad et al. 2009; xDEM's `neff_circular_approx_theoretical`, exact for spherical models).

use glam::DVec3;
use serde::Serialize;

use crate::maths::first_in_hash_order;

/// Samples paired with each other (4.5·10⁶ pairs).
const POOL: usize = 3000;
/// Samples paired with every sample near them.
const CENTRES: usize = 1000;
/// What near is, in sample spacings.
const NEAR_SPACINGS: f64 = 16.0;
/// Pairs a bin needs to count.
const MIN_PAIRS: u64 = 30;

/// One bin of an empirical variogram (field names are the JSON's).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct VariogramBin {
    /// The bin's upper lag, metres.
    pub lag_m: f64,
    /// γ, in the squared unit of the values.
    pub gamma: f64,
    /// Pairs in it.
    pub pairs: u64,
}

/// One spherical model (field names are the JSON's).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Spherical {
    /// Range, metres.
    pub range_m: f64,
    /// Partial sill.
    pub psill: f64,
}

/// A sum of spherical models.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct VariogramModel {
    /// Shortest range first.
    pub models: Vec<Spherical>,
}

fn sph(h: f64, range_m: f64) -> f64 {
    let x = h / range_m;
    if x >= 1.0 { 1.0 } else { 1.5 * x - 0.5 * x * x * x }
}

impl VariogramModel {
    /// γ(h).
    pub fn gamma(&self, h: f64) -> f64 {
        self.models.iter().map(|m| m.psill * sph(h, m.range_m)).sum()
    }

    /// The total sill.
    pub fn sill(&self) -> f64 {
        self.models.iter().map(|m| m.psill).sum()
    }
}

/// The empirical variogram of `z` at points `p` (ECEF) with weights `w` (cell areas), on a grid of
/// mean spacing `spacing_m`, up to `max_lag_m`. Non-finite values are left out.
pub fn empirical(p: &[DVec3], z: &[f64], w: &[f64], spacing_m: f64, max_lag_m: f64) -> Vec<VariogramBin> {
    let valid: Vec<usize> = (0..z.len()).filter(|&k| z[k].is_finite()).collect();
    let mut edges = Vec::new();
    let mut edge = std::f64::consts::SQRT_2 * spacing_m;
    while edge < max_lag_m {
        edges.push(edge);
        edge *= std::f64::consts::SQRT_2;
    }
    edges.push(max_lag_m);
    // Samples in hash order: the pool and the centres are the first ones.
    let order = first_in_hash_order(&valid, POOL.max(CENTRES));
    let centres = &order[..order.len().min(CENTRES)];
    let pool = &order[..order.len().min(POOL)];
    let near_m = NEAR_SPACINGS * spacing_m;
    // A uniform grid over the samples (in the frame of their mean direction) for the near query.
    let mean = valid.iter().map(|&k| p[k]).sum::<DVec3>() / valid.len().max(1) as f64;
    let up = mean.normalize_or_zero();
    let east = DVec3::Z.cross(up).normalize_or(DVec3::X);
    let north = up.cross(east);
    let cell =
        |q: DVec3| (((q - mean).dot(east) / near_m).floor() as i64, ((q - mean).dot(north) / near_m).floor() as i64);
    let mut grid: std::collections::HashMap<(i64, i64), Vec<usize>> = std::collections::HashMap::new();
    for &k in &valid {
        grid.entry(cell(p[k])).or_default().push(k);
    }
    let bin_of = |d: f64| edges.partition_point(|&e| e < d);
    // Per bin: (|Δz|, weight).
    let mut per_bin: Vec<Vec<(f64, f64)>> = vec![Vec::new(); edges.len()];
    // Every pair of the pool (xDEM's `pdist_point` draws its pairs so), then each centre with every
    // sample near it, for the short lags a pool this sparse misses.
    for (i, &a) in pool.iter().enumerate() {
        for &k in &pool[i + 1..] {
            let d = (p[k] - p[a]).length();
            if d <= max_lag_m {
                per_bin[bin_of(d)].push(((z[k] - z[a]).abs(), w[k] * w[a]));
            }
        }
    }
    for &c in centres {
        let (ci, cj) = cell(p[c]);
        for di in -1..=1 {
            for dj in -1..=1 {
                for &k in grid.get(&(ci + di, cj + dj)).map_or(&[][..], Vec::as_slice) {
                    let d = (p[k] - p[c]).length();
                    if k != c && d <= near_m {
                        per_bin[bin_of(d)].push(((z[k] - z[c]).abs(), w[k] * w[c]));
                    }
                }
            }
        }
    }
    per_bin
        .into_iter()
        .zip(edges)
        .filter(|(pairs, _)| pairs.len() as u64 >= MIN_PAIRS)
        .map(|(mut pairs, lag_m)| {
            pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
            let median = super::stats::weighted_quantile(&pairs, 0.5);
            VariogramBin { lag_m, gamma: 0.5 * 2.198 * median * median, pairs: pairs.len() as u64 }
        })
        .collect()
}

/// The best non-negative sills for ranges `r`, and the sum of squared residuals over the bins.
fn best_sills(bins: &[VariogramBin], r: &[f64]) -> (Vec<f64>, f64) {
    let rows: Vec<(Vec<f64>, f64, f64)> =
        bins.iter().map(|b| (r.iter().map(|&rk| sph(b.lag_m, rk)).collect(), b.gamma, 1.0)).collect();
    super::bias::nonnegative_least_squares(&rows).unwrap_or((vec![0.0; r.len()], f64::INFINITY))
}

/// Fits a sum of up to two spherical models to the bins (at least three); a model whose sill
/// comes out 0 is dropped.
pub fn fit(bins: &[VariogramBin]) -> Option<VariogramModel> {
    if bins.len() < 3 {
        return None;
    }
    let (lo, hi) = (bins[0].lag_m.ln(), bins[bins.len() - 1].lag_m.ln());
    let grid: Vec<f64> = (0..40).map(|k| (lo + (hi - lo) * f64::from(k) / 39.0).exp()).collect();
    let mut best = (vec![grid[0], grid[0]], f64::INFINITY);
    for (i, &r1) in grid.iter().enumerate() {
        for &r2 in &grid[i..] {
            let res = best_sills(bins, &[r1, r2]).1;
            if res < best.1 {
                best = (vec![r1, r2], res);
            }
        }
    }
    let mut r = best.0;
    for _ in 0..3 {
        for k in 0..2 {
            let cost = |x: f64| {
                let mut with = r.clone();
                with[k] = x.exp();
                best_sills(bins, &with).1
            };
            r[k] = super::bias::golden_section((r[k] / 1.5).ln(), (r[k] * 1.5).ln(), cost).exp();
        }
    }
    let (c, _) = best_sills(bins, &r);
    let mut models: Vec<Spherical> =
        r.iter().zip(&c).filter(|(_, c)| **c > 0.0).map(|(&range_m, &psill)| Spherical { range_m, psill }).collect();
    models.sort_by(|a, b| a.range_m.total_cmp(&b.range_m));
    (!models.is_empty()).then_some(VariogramModel { models })
}

/// The number of effective samples of a mean over an area of `area_m2`, taken as a disk: the
/// sill over the covariance averaged over the disk (for a spherical model of range a and sill c
/// and the disk's radius L: c·(1 − L/a + (L/a)³/5) for L ≤ a, c·a²/(5L²) beyond).
pub fn neff_disk(model: &VariogramModel, area_m2: f64) -> f64 {
    let l = (area_m2 / std::f64::consts::PI).sqrt();
    let se2: f64 = model
        .models
        .iter()
        .map(|m| {
            let x = l / m.range_m;
            if x <= 1.0 { m.psill * (1.0 - x + x * x * x / 5.0) } else { m.psill / (5.0 * x * x) }
        })
        .sum();
    if se2 > 0.0 { model.sill() / se2 } else { f64::INFINITY }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_known_sum_of_two_spherical_models_is_fitted_back() {
        let truth = VariogramModel {
            models: vec![Spherical { range_m: 300.0, psill: 0.6 }, Spherical { range_m: 5000.0, psill: 0.4 }],
        };
        let mut lag = 42.0;
        let mut bins = Vec::new();
        while lag < 40_000.0 {
            bins.push(VariogramBin { lag_m: lag, gamma: truth.gamma(lag), pairs: 1000 });
            lag *= std::f64::consts::SQRT_2;
        }
        let m = fit(&bins).unwrap();
        assert_eq!(m.models.len(), 2, "{m:?}");
        for (a, b) in m.models.iter().zip(&truth.models) {
            assert!((a.range_m / b.range_m - 1.0).abs() < 0.01, "{m:?}");
            assert!((a.psill - b.psill).abs() < 0.01, "{m:?}");
        }
    }

    #[test]
    fn the_effective_samples_follow_rolstads_disk_formulas() {
        let m = VariogramModel { models: vec![Spherical { range_m: 1000.0, psill: 2.0 }] };
        // A disk of radius L = 2a: SE² = c·a²/(5L²) = c/20, so N_eff = 20.
        let area = std::f64::consts::PI * 2000.0 * 2000.0;
        assert!((neff_disk(&m, area) - 20.0).abs() < 1e-9);
        // L = a/2: SE² = c·(1 − 1/2 + 1/40), N_eff = 1/0.525.
        let area = std::f64::consts::PI * 500.0 * 500.0;
        assert!((neff_disk(&m, area) - 1.0 / 0.525).abs() < 1e-9);
    }
}
