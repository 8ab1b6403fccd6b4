//! A patch's geometric error δ at each stride: the largest vertical distance, in metres, between
//! the data under the patch and the surface the patch's mesh draws at that stride, made monotone
//! (a coarser stride never claims a smaller error than a finer one). The first brick of selecting
//! geometry by projected error (issue 50): a patch needs a finer stride while δ · f / d, its error
//! projected at distance d with focal length f pixels, exceeds the pixel error allowed.
//!
//! The mesh is the one `gpu::terrain::patch_indices` draws: each cell of the stride's grid cut
//! along the diagonal from its (0, 0) corner to its (1, 1) corner, linear on each triangle.
//!
//! These errors are against the quad's own samples. A quad drawn coarser than its data's finest
//! level also misses the finer samples; the error the selection needs adds theirs level by level
//! (each level's error saturated with its children's, as Lindstrom & Pascucci's nested errors
//! are), which is the next step, on the GPU as the quads compose.

use super::patches::{PATCH_CELLS, PATCHES_PER_EDGE, STRIDES};
use crate::ecm::grid::GRID;

/// The height of a cell's mesh at (u, v) ∈ [0, 1]² in the cell: the corners' heights `h00` (the
/// cell's origin), `h10` (+u), `h01` (+v), `h11`, on the triangle (00, 10, 11) where u ≥ v and
/// (00, 11, 01) where u < v.
pub fn mesh_height(h00: f64, h10: f64, h01: f64, h11: f64, u: f64, v: f64) -> f64 {
    if u >= v { h00 + u * (h10 - h00) + v * (h11 - h10) } else { h00 + v * (h01 - h00) + u * (h11 - h01) }
}

/// δ of the patch at column `px`, row `py` (each 0 … 7) of a quad whose data are `heights`
/// (257² samples, row by row from the south; NaN: no data, left out) at each of [`STRIDES`],
/// metres: `vertex(stride, i, j)` is the height the mesh at that stride draws at sample (i, j) of
/// the quad (its own sample, or an ancestor's where coarser strides read coarser data).
pub fn patch_errors(heights: &[f32], px: u32, py: u32, vertex: &dyn Fn(u32, u32, u32) -> f64) -> [f64; STRIDES.len()] {
    let mut errors = [0f64; STRIDES.len()];
    for (k, &s) in STRIDES.iter().enumerate() {
        let worst = stride_error(heights, px, py, s, vertex);
        errors[k] = if k == 0 { worst } else { worst.max(errors[k - 1]) };
    }
    errors
}

/// The largest vertical miss of the patch's mesh at `stride` alone (not made monotone): what a
/// patch drawn at that stride shows wrong. Arguments as for [`patch_errors`].
pub fn stride_error(heights: &[f32], px: u32, py: u32, stride: u32, vertex: &dyn Fn(u32, u32, u32) -> f64) -> f64 {
    debug_assert_eq!(heights.len(), (GRID * GRID) as usize);
    let (i0, j0, s) = (px * PATCH_CELLS, py * PATCH_CELLS, stride);
    let mut worst = 0f64;
    for cj in (0..PATCH_CELLS).step_by(s as usize) {
        for ci in (0..PATCH_CELLS).step_by(s as usize) {
            let (a, b) = (i0 + ci, j0 + cj);
            let corners = [vertex(s, a, b), vertex(s, a + s, b), vertex(s, a, b + s), vertex(s, a + s, b + s)];
            if corners.iter().any(|h| !h.is_finite()) {
                continue;
            }
            let [h00, h10, h01, h11] = corners;
            for dj in 0..=s {
                for di in 0..=s {
                    let h = f64::from(heights[((b + dj) * GRID + a + di) as usize]);
                    if !h.is_finite() {
                        continue;
                    }
                    let (u, v) = (f64::from(di) / f64::from(s), f64::from(dj) / f64::from(s));
                    worst = worst.max((h - mesh_height(h00, h10, h01, h11, u, v)).abs());
                }
            }
        }
    }
    worst
}

/// δ of every patch of a quad at every stride, row by row from the south (64 patches), with the
/// mesh drawing the quad's own samples at every stride.
pub fn quad_errors(heights: &[f32]) -> Vec<[f64; STRIDES.len()]> {
    let own = |_: u32, i: u32, j: u32| f64::from(heights[(j * GRID + i) as usize]);
    (0..PATCHES_PER_EDGE)
        .flat_map(|py| (0..PATCHES_PER_EDGE).map(move |px| (px, py)))
        .map(|(px, py)| patch_errors(heights, px, py, &own))
        .collect()
}

/// An error of `delta_m` metres seen at `distance_m` with a focal length of `focal_px` pixels,
/// in pixels.
pub fn projected_px(delta_m: f64, distance_m: f64, focal_px: f64) -> f64 {
    delta_m * focal_px / distance_m.max(1e-9)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn grid_of(h: impl Fn(f64, f64) -> f64) -> Vec<f32> {
        (0..GRID)
            .flat_map(|j| (0..GRID).map(move |i| (i, j)))
            .map(|(i, j)| h(f64::from(i), f64::from(j)) as f32)
            .collect()
    }

    #[test]
    fn a_tilted_plane_is_drawn_exactly_at_every_stride() {
        let errors = quad_errors(&grid_of(|i, j| 1000.0 + 3.0 * i - 2.0 * j));
        assert!(errors.iter().flatten().all(|e| *e < 1e-3), "{errors:?}");
    }

    #[test]
    fn a_parabola_is_off_by_a_s_squared_over_4_at_stride_s() {
        // h = a·i² (i in samples): linear between vertices s apart, its largest miss is a·s²/4,
        // midway (a sample there from stride 2 on; stride 1 draws every sample, δ = 0); the
        // diagonal does not matter for a height that varies along i alone. Heights to 3.3 km in
        // f32: within a millimetre.
        let a = 0.05;
        let errors = quad_errors(&grid_of(|i, _| a * i * i));
        for patch in &errors {
            for (k, &s) in STRIDES.iter().enumerate() {
                let expected = if s == 1 { 0.0 } else { a * f64::from(s * s) / 4.0 };
                assert!((patch[k] - expected).abs() < 1e-3, "stride {s}: {} against {expected}", patch[k]);
            }
        }
    }

    #[test]
    fn errors_grow_with_the_stride_and_no_data_is_left_out() {
        // A rough surface with a hole: δ is monotone over the strides and finite.
        let mut heights = grid_of(|i, j| (i * 0.7).sin() * 40.0 + (j * 1.3).cos() * 15.0 + 0.01 * i * j);
        for k in 0..2000 {
            heights[k * 13] = f32::NAN;
        }
        for patch in quad_errors(&heights) {
            assert!(patch.iter().all(|e| e.is_finite()));
            assert!(patch.windows(2).all(|w| w[1] >= w[0]), "{patch:?}");
        }
    }

    #[test]
    fn the_mesh_height_is_each_corners_at_the_corners_and_linear_on_each_triangle() {
        let (h00, h10, h01, h11) = (1.0, 5.0, -2.0, 7.0);
        for (u, v, h) in [(0.0, 0.0, h00), (1.0, 0.0, h10), (0.0, 1.0, h01), (1.0, 1.0, h11)] {
            assert_eq!(mesh_height(h00, h10, h01, h11, u, v), h);
        }
        // On the diagonal both triangles agree.
        for t in [0.25, 0.5, 0.75] {
            assert!((mesh_height(h00, h10, h01, h11, t, t) - (h00 + t * (h11 - h00))).abs() < 1e-12);
        }
        assert!((projected_px(2.0, 1000.0, 1000.0) - 2.0).abs() < 1e-12);
    }
}
