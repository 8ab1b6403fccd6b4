//! Hillslope diffusion, ∂h/∂t = K_d·∇²h, by the alternating-direction implicit scheme of Peaceman
//! and Rachford (as fastscapelib's `DiffusionADIEroder`): a half step implicit along x and explicit
//! along y, then one implicit along y and explicit along x, each line a tridiagonal system solved
//! by the Thomas algorithm. Unconditionally stable; base-level cells hold their height. Lengths
//! are the grid's, cell by cell (on the planet they differ slightly from cell to cell).

use crate::erosion::grid::Grid;

/// The second difference along one axis at cell `i`, with the distances to the previous and next
/// cells: (h_next − h_i)/d_next − (h_i − h_prev)/d_prev over the mean distance.
fn coefficients(d_prev: f64, d_next: f64) -> (f64, f64) {
    let mean = 0.5 * (d_prev + d_next);
    (1.0 / (d_prev * mean), 1.0 / (d_next * mean))
}

/// Solves a tridiagonal system in place: `a` below, `b` on, `c` above the diagonal, `d` the right
/// side (overwritten by the solution).
fn thomas(a: &[f64], b: &[f64], c: &mut [f64], d: &mut [f64]) {
    let n = d.len();
    if n == 0 {
        return;
    }
    c[0] /= b[0];
    d[0] /= b[0];
    for i in 1..n {
        let m = b[i] - a[i] * c[i - 1];
        c[i] = if i + 1 < n { c[i] / m } else { 0.0 };
        d[i] = (d[i] - a[i] * d[i - 1]) / m;
    }
    for i in (0..n - 1).rev() {
        d[i] -= c[i] * d[i + 1];
    }
}

/// One half step along an axis: `lines` lines of `len` cells, cell `p` of line `l` at
/// `l·line_stride + p·step`; `spacing(i)` the distance from cell i to the next along the axis,
/// `other(i)` the explicit second difference along the other axis.
#[allow(clippy::too_many_arguments)]
fn half_step(
    heights: &[f64],
    base: &[bool],
    factor: f64,
    (lines, len, line_stride, step): (usize, usize, usize, usize),
    spacing: &[f64],
    other: &dyn Fn(usize) -> f64,
    out: &mut [f64],
) {
    let (mut a, mut b, mut c, mut d) = (vec![0.0; len], vec![1.0; len], vec![0.0; len], vec![0.0; len]);
    for l in 0..lines {
        let cell = |p: usize| l * line_stride + p * step;
        for p in 0..len {
            let i = cell(p);
            if base[i] || p == 0 || p + 1 == len {
                // Held (a cell without data holds 0 in the system, so no NaN spreads through it).
                let held = if heights[i].is_nan() { 0.0 } else { heights[i] };
                (a[p], b[p], c[p], d[p]) = (0.0, 1.0, 0.0, held);
                continue;
            }
            let (w_prev, w_next) = coefficients(spacing[i - step], spacing[i]);
            a[p] = -factor * w_prev;
            c[p] = -factor * w_next;
            b[p] = 1.0 + factor * (w_prev + w_next);
            d[p] = heights[i] + factor * other(i);
        }
        thomas(&a, &b, &mut c, &mut d);
        for (p, v) in d.iter().enumerate() {
            let i = cell(p);
            out[i] = if base[i] || p == 0 || p + 1 == len { heights[i] } else { *v };
        }
    }
}

/// Diffuses `heights` for `dt_years` with diffusivity `kd_m2_per_year`; returns the new heights.
pub fn diffuse(grid: &Grid, base: &[bool], heights: &[f64], kd_m2_per_year: f64, dt_years: f64) -> Vec<f64> {
    if kd_m2_per_year <= 0.0 {
        return heights.to_vec();
    }
    let (w, h) = (grid.width, grid.height);
    let factor = 0.5 * kd_m2_per_year * dt_years;
    let second = |v: &[f64], i: usize, step: usize, spacing: &[f64]| -> f64 {
        let (w_prev, w_next) = coefficients(spacing[i - step], spacing[i]);
        w_next * (v[i + step] - v[i]) - w_prev * (v[i] - v[i - step])
    };
    // Interior cells only (base level holds): their neighbours along both axes exist.
    let along_y = |i: usize| if base[i] { 0.0 } else { second(heights, i, w, &grid.dy_m) };
    let mut half = vec![0.0; heights.len()];
    half_step(heights, base, factor, (h, w, w, 1), &grid.dx_m, &along_y, &mut half);
    let along_x = |i: usize| if base[i] { 0.0 } else { second(&half, i, 1, &grid.dx_m) };
    let mut out = vec![0.0; heights.len()];
    half_step(&half, base, factor, (w, h, 1, w), &grid.dy_m, &along_x, &mut out);
    out
}
