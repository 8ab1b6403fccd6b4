//! The bias models of a co-registration pipeline, fitted to the differences dh = A − B on stable
//! terrain and subtracted from A (evaluated as a layer's `correction` evaluates them,
//! [`crate::layers::correction`]): pure functions of samples, deterministic (sums in sample order,
//! medians by selection, no random starts).
//!
//! - [`vertical`]: the weighted median of dh (xDEM's `VerticalShift`).
//! - [`Polynomial`]: a polynomial of order 1–3 in local east and north kilometres, by weighted
//!   least squares (xDEM's `Deramp(poly_order)`, which fits the same terms in pixel coordinates).
//! - [`Binned`]: the weighted median of dh in equal-width bins of an attribute of B, applied by
//!   linear interpolation between bin centres and held constant beyond them (xDEM's `TerrainBias`
//!   with `bin_apply_method="linear"`).
//! - [`Sinusoids`]: a sum of up to three sinusoids of the distance along an azimuth, fitted to the
//!   binned medians one wavelength at a time by a periodogram search (xDEM's `DirectionalBias`,
//!   which fits the same sum with a global optimiser).

use serde::{Deserialize, Serialize};

use super::stats::weighted_quantile;
pub use crate::layers::correction::{MAX_SINUSOIDS, Sinusoid};
use crate::layers::correction::{binned_at, polynomial_at, polynomial_terms, sinusoids_at};

/// The weighted median of `dh` (weights `w`); NaN for no samples.
pub fn vertical(dh: &[f64], w: &[f64]) -> f64 {
    let mut sorted: Vec<(f64, f64)> = dh.iter().copied().zip(w.iter().copied()).collect();
    sorted.sort_by(|a, b| a.0.total_cmp(&b.0));
    weighted_quantile(&sorted, 0.5)
}

/// A polynomial in local east and north kilometres about an origin: Σ c_k · e^i · n^j over the
/// terms i + j ≤ order, in the order of [`Polynomial::terms`].
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Polynomial {
    /// The order, 1–3.
    pub order: u8,
    /// The coefficients, metres per km^(i + j), in the order of `terms`.
    pub coefficients: Vec<f64>,
}

impl Polynomial {
    /// The exponents (i of east, j of north) of each term: by total degree, then falling i.
    pub fn terms(order: u8) -> Vec<[u8; 2]> {
        polynomial_terms(order)
    }

    /// Fits the polynomial of `order` to dh at (east, north) kilometres by weighted least squares;
    /// None when the samples do not determine it (fewer than its terms, or all on a line).
    pub fn fit(order: u8, east_km: &[f64], north_km: &[f64], dh: &[f64], w: &[f64]) -> Option<Polynomial> {
        let terms = Polynomial::terms(order);
        let m = terms.len();
        let mut normal = vec![vec![0.0; m]; m];
        let mut rhs = vec![0.0; m];
        let mut row = vec![0.0; m];
        for k in 0..dh.len() {
            for (r, t) in row.iter_mut().zip(&terms) {
                *r = east_km[k].powi(i32::from(t[0])) * north_km[k].powi(i32::from(t[1]));
            }
            for a in 0..m {
                rhs[a] += w[k] * row[a] * dh[k];
                for b in 0..m {
                    normal[a][b] += w[k] * row[a] * row[b];
                }
            }
        }
        let coefficients = solve(normal, rhs)?;
        Some(Polynomial { order, coefficients })
    }

    /// The value at (east, north) kilometres.
    pub fn at(&self, east_km: f64, north_km: f64) -> f64 {
        polynomial_at(self.order, &self.coefficients, east_km, north_km)
    }
}

/// Solves the symmetric system by Gaussian elimination with partial pivoting; None when singular
/// (a pivot under 10⁻¹² of the largest diagonal).
pub(super) fn solve(mut a: Vec<Vec<f64>>, mut b: Vec<f64>) -> Option<Vec<f64>> {
    let m = b.len();
    let scale = (0..m).map(|i| a[i][i].abs()).fold(0.0, f64::max);
    if scale <= 0.0 {
        return None;
    }
    for col in 0..m {
        let pivot = (col..m).max_by(|&x, &y| a[x][col].abs().total_cmp(&a[y][col].abs()))?;
        if a[pivot][col].abs() < 1e-12 * scale {
            return None;
        }
        a.swap(col, pivot);
        b.swap(col, pivot);
        let (top, rest) = a.split_at_mut(col + 1);
        let pivot_row = &top[col];
        for (r, row) in rest.iter_mut().enumerate() {
            let f = row[col] / pivot_row[col];
            for (x, p) in row[col..].iter_mut().zip(&pivot_row[col..]) {
                *x -= f * p;
            }
            b[col + 1 + r] -= f * b[col];
        }
    }
    let mut x = vec![0.0; m];
    for r in (0..m).rev() {
        let s: f64 = (r + 1..m).map(|c| a[r][c] * x[c]).sum();
        x[r] = (b[r] - s) / a[r][r];
    }
    Some(x)
}

/// Weighted least squares of y ≈ Σ c_k · x_k with every c_k ≥ 0 (`rows`: the x_k, y, weight), for
/// a few unknowns: every subset of them free and the rest at 0, the feasible solution with the
/// least residual. The coefficients and that residual; None when no subset is solvable.
pub(super) fn nonnegative_least_squares(rows: &[(Vec<f64>, f64, f64)]) -> Option<(Vec<f64>, f64)> {
    let m = rows.first()?.0.len();
    let mut best: Option<(Vec<f64>, f64)> = None;
    for mask in 1..(1u32 << m) {
        let free: Vec<usize> = (0..m).filter(|k| mask & (1 << k) != 0).collect();
        let mut normal = vec![vec![0.0; free.len()]; free.len()];
        let mut rhs = vec![0.0; free.len()];
        for (x, y, w) in rows {
            for (i, &fi) in free.iter().enumerate() {
                rhs[i] += w * x[fi] * y;
                for (j, &fj) in free.iter().enumerate() {
                    normal[i][j] += w * x[fi] * x[fj];
                }
            }
        }
        let Some(sol) = solve(normal, rhs) else { continue };
        if sol.iter().any(|&c| c < 0.0) {
            continue;
        }
        let mut c = vec![0.0; m];
        for (i, &fi) in free.iter().enumerate() {
            c[fi] = sol[i];
        }
        let residual: f64 =
            rows.iter().map(|(x, y, w)| w * (y - x.iter().zip(&c).map(|(x, c)| x * c).sum::<f64>()).powi(2)).sum();
        if best.as_ref().is_none_or(|b| residual < b.1) {
            best = Some((c, residual));
        }
    }
    best
}

/// Bins of a binned correction (xDEM's `TerrainBias` default).
pub const BINS: usize = 100;
/// Samples a bin needs to count.
pub const MIN_PER_BIN: usize = 10;

/// A correction binned by an attribute: the weighted median of dh per bin, at the bin's centre.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Binned {
    /// (attribute at the bin's centre, the median dh there, metres), bins with enough samples,
    /// ascending.
    pub bins: Vec<[f64; 2]>,
}

impl Binned {
    /// Fits the median of dh in `bins` equal-width bins of `x` over its range; None with fewer
    /// than two bins of [`MIN_PER_BIN`] samples.
    pub fn fit(x: &[f64], dh: &[f64], w: &[f64], bins: usize) -> Option<Binned> {
        let (lo, hi) = x.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
        if hi.partial_cmp(&lo) != Some(std::cmp::Ordering::Greater) {
            return None;
        }
        let width = (hi - lo) / bins as f64;
        let mut groups: Vec<Vec<(f64, f64)>> = vec![Vec::new(); bins];
        for k in 0..x.len() {
            let b = (((x[k] - lo) / width) as usize).min(bins - 1);
            groups[b].push((dh[k], w[k]));
        }
        let bins: Vec<[f64; 2]> = groups
            .into_iter()
            .enumerate()
            .filter(|(_, g)| g.len() >= MIN_PER_BIN)
            .map(|(b, mut g)| {
                g.sort_by(|p, q| p.0.total_cmp(&q.0));
                [lo + (b as f64 + 0.5) * width, weighted_quantile(&g, 0.5)]
            })
            .collect();
        (bins.len() >= 2).then_some(Binned { bins })
    }

    /// The correction at `x`: linear between bin centres, the end bins' values beyond them.
    pub fn at(&self, x: f64) -> f64 {
        binned_at(&self.bins, x)
    }
}

/// Wavelengths searched per sinusoid, log-spaced from two bins to the whole extent.
const WAVELENGTHS: usize = 400;
/// A sinusoid is kept only if it removes at least this share of the binned variance left.
const MIN_GAIN: f64 = 0.05;

/// A sum of sinusoids of the distance along an azimuth, and a constant.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Sinusoids {
    /// The constant, metres.
    pub offset_m: f64,
    /// The sinusoids, strongest first.
    pub sinusoids: Vec<Sinusoid>,
}

impl Sinusoids {
    /// Fits the sum to the weighted medians of dh in `bins` bins of x (metres along the azimuth):
    /// each sinusoid at the wavelength (a periodogram over [`WAVELENGTHS`] candidates, refined by
    /// golden-section search) that removes most of what the ones before left, every wavelength
    /// found so far refined again with the others held, all amplitudes, phases and the constant
    /// by least squares together; a sinusoid that removes under 5 % of what is left ends the
    /// search. None with fewer than eight bins of data.
    pub fn fit(x: &[f64], dh: &[f64], w: &[f64], bins: usize) -> Option<Sinusoids> {
        let binned = Binned::fit(x, dh, w, bins)?;
        let (xs, ys): (Vec<f64>, Vec<f64>) = binned.bins.iter().map(|b| (b[0], b[1])).unzip();
        if xs.len() < 8 {
            return None;
        }
        let span = xs[xs.len() - 1] - xs[0];
        let bin = span / (bins as f64 - 1.0);
        let mut wavelengths: Vec<f64> = Vec::new();
        let mut fit = linear_fit(&xs, &ys, &wavelengths)?;
        for _ in 0..MAX_SINUSOIDS {
            let left = residual(&xs, &ys, &wavelengths, &fit);
            let cost = |l: f64| {
                let mut with = wavelengths.clone();
                with.push(l);
                linear_fit(&xs, &ys, &with).map_or(f64::INFINITY, |f| residual(&xs, &ys, &with, &f))
            };
            let (lo, hi) = ((2.0 * bin).ln(), (2.0 * span).ln());
            let grid: Vec<f64> =
                (0..WAVELENGTHS).map(|k| (lo + (hi - lo) * k as f64 / (WAVELENGTHS - 1) as f64).exp()).collect();
            let costs: Vec<f64> = grid.iter().map(|&l| cost(l)).collect();
            let best = (0..grid.len()).min_by(|&a, &b| costs[a].total_cmp(&costs[b]))?;
            let (a, b) = (grid[best.saturating_sub(1)], grid[(best + 1).min(grid.len() - 1)]);
            let l = golden_section(a, b, cost);
            if left - cost(l) < MIN_GAIN * left {
                break;
            }
            wavelengths.push(l);
            // Each wavelength again with the others held, within 3 %: one found alone is pulled
            // off by the ones not yet fitted.
            for k in 0..wavelengths.len() {
                let l = wavelengths[k];
                let cost = |l: f64| {
                    let mut with = wavelengths.clone();
                    with[k] = l;
                    linear_fit(&xs, &ys, &with).map_or(f64::INFINITY, |f| residual(&xs, &ys, &with, &f))
                };
                wavelengths[k] = golden_section(0.97 * l, 1.03 * l, cost);
            }
            fit = linear_fit(&xs, &ys, &wavelengths)?;
        }
        let sinusoids = wavelengths
            .iter()
            .enumerate()
            .map(|(k, &l)| {
                let (s, c) = (fit[1 + 2 * k], fit[2 + 2 * k]);
                Sinusoid { wavelength_m: l, amplitude_m: s.hypot(c), phase_rad: c.atan2(s) }
            })
            .collect();
        Some(Sinusoids { offset_m: fit[0], sinusoids })
    }

    /// The value at x metres along the azimuth.
    pub fn at(&self, x: f64) -> f64 {
        sinusoids_at(self.offset_m, &self.sinusoids, x)
    }
}

/// Least squares of y = c + Σ (s_k sin + c_k cos)(2πx/λ_k): [c, s_1, c_1, s_2, c_2, …].
fn linear_fit(x: &[f64], y: &[f64], wavelengths: &[f64]) -> Option<Vec<f64>> {
    let m = 1 + 2 * wavelengths.len();
    let mut normal = vec![vec![0.0; m]; m];
    let mut rhs = vec![0.0; m];
    for (&xi, &yi) in x.iter().zip(y) {
        let row = basis(xi, wavelengths);
        for a in 0..m {
            rhs[a] += row[a] * yi;
            for b in 0..m {
                normal[a][b] += row[a] * row[b];
            }
        }
    }
    solve(normal, rhs)
}

fn basis(x: f64, wavelengths: &[f64]) -> Vec<f64> {
    let mut row = vec![1.0];
    for l in wavelengths {
        let a = std::f64::consts::TAU * x / l;
        row.extend([a.sin(), a.cos()]);
    }
    row
}

fn residual(x: &[f64], y: &[f64], wavelengths: &[f64], fit: &[f64]) -> f64 {
    x.iter()
        .zip(y)
        .map(|(&xi, &yi)| {
            let model: f64 = basis(xi, wavelengths).iter().zip(fit).map(|(b, c)| b * c).sum();
            (yi - model).powi(2)
        })
        .sum()
}

/// The minimum of `f` on [a, b] by golden-section search (60 steps: the bracket shrinks 10¹²-fold).
pub(super) fn golden_section(mut a: f64, mut b: f64, f: impl Fn(f64) -> f64) -> f64 {
    let g = (5f64.sqrt() - 1.0) / 2.0;
    let (mut c, mut d) = (b - g * (b - a), a + g * (b - a));
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..60 {
        if fc < fd {
            (b, d, fd) = (d, c, fc);
            c = b - g * (b - a);
            fc = f(c);
        } else {
            (a, c, fc) = (c, d, fd);
            d = a + g * (b - a);
            fd = f(d);
        }
    }
    0.5 * (a + b)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 60 × 60 grid of samples 200 m apart, centred on the origin (east, north in km).
    fn grid() -> (Vec<f64>, Vec<f64>) {
        (0..3600).map(|k| (((k % 60) as f64 - 29.5) * 0.2, ((k / 60) as f64 - 29.5) * 0.2)).unzip()
    }

    #[test]
    fn a_known_polynomial_of_each_order_is_recovered_to_rounding() {
        let (e, n) = grid();
        let w = vec![1.0; e.len()];
        for order in 1..=3u8 {
            let truth: Vec<f64> = (0..Polynomial::terms(order).len()).map(|k| 0.7 - 0.3 * k as f64).collect();
            let p = Polynomial { order, coefficients: truth.clone() };
            let dh: Vec<f64> = (0..e.len()).map(|k| p.at(e[k], n[k])).collect();
            let fitted = Polynomial::fit(order, &e, &n, &dh, &w).unwrap();
            for (a, b) in fitted.coefficients.iter().zip(&truth) {
                assert!((a - b).abs() < 1e-9, "order {order}: {:?} vs {truth:?}", fitted.coefficients);
            }
        }
        assert_eq!(Polynomial::terms(2), vec![[0, 0], [1, 0], [0, 1], [2, 0], [1, 1], [0, 2]]);
        // Samples on one line cannot fix a plane.
        assert!(Polynomial::fit(1, &[0.0, 1.0, 2.0], &[0.0; 3], &[1.0; 3], &[1.0; 3]).is_none());
    }

    #[test]
    fn a_binned_bias_follows_a_known_elevation_dependence_and_holds_beyond_its_bins() {
        // dh = 0.01 · (h − 1500) over heights 1000–3000 m, with every 7th sample an outlier.
        let h: Vec<f64> = (0..20_000).map(|k| 1000.0 + 2000.0 * (k as f64 / 19_999.0)).collect();
        let dh: Vec<f64> =
            h.iter().enumerate().map(|(k, h)| if k % 7 == 0 { 50.0 } else { 0.01 * (h - 1500.0) }).collect();
        let b = Binned::fit(&h, &dh, &vec![1.0; h.len()], BINS).unwrap();
        for x in [1200.0, 1500.0, 2222.0, 2900.0] {
            assert!((b.at(x) - 0.01 * (x - 1500.0)).abs() < 0.02, "{x}: {}", b.at(x));
        }
        assert_eq!(b.at(0.0), b.bins[0][1]);
        assert_eq!(b.at(1e6), b.bins[b.bins.len() - 1][1]);
        assert!(Binned::fit(&[1.0; 50], &[0.0; 50], &[1.0; 50], BINS).is_none());
    }

    #[test]
    fn a_directional_bias_of_two_known_sinusoids_is_recovered() {
        // 2 m at 3 km and 0.8 m at 800 m along the axis, plus 0.3 m, on 40 km.
        let x: Vec<f64> = (0..40_000).map(|k| k as f64).collect();
        let truth = |x: f64| {
            0.3 + 2.0 * (std::f64::consts::TAU * x / 3000.0 + 0.4).sin()
                + 0.8 * (std::f64::consts::TAU * x / 800.0 - 1.2).sin()
        };
        let dh: Vec<f64> = x.iter().map(|&x| truth(x)).collect();
        let s = Sinusoids::fit(&x, &dh, &vec![1.0; x.len()], 1000).unwrap();
        assert_eq!(s.sinusoids.len(), 2, "{s:?}");
        assert!((s.sinusoids[0].wavelength_m - 3000.0).abs() < 3.0, "{s:?}");
        assert!((s.sinusoids[0].amplitude_m - 2.0).abs() < 0.02, "{s:?}");
        assert!((s.sinusoids[1].wavelength_m - 800.0).abs() < 1.0, "{s:?}");
        let worst = x.iter().map(|&x| (s.at(x) - truth(x)).abs()).fold(0.0, f64::max);
        assert!(worst < 0.05, "{worst} m");
    }
}
