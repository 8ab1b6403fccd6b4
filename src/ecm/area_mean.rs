//! The area-mean stencil that makes a level from the one below it: each sample the mean of its
//! cell on the child level, the full-weighting stencil (1 2 1 / 2 4 2 / 1 2 1 in sixteenths),
//! at a cube corner the three faces' quadrants counted once each. The store builds its coarser
//! levels with it and an edit raster its pyramid, so both agree sample for sample.

use super::grid::{GRID, TILE, intervals_per_face_edge};
use super::{Face, QuadId};

/// Child samples an area mean reads per axis: −1 ..= 513 around the quad's two children.
pub const AREA_MEAN_SPAN: usize = 2 * GRID as usize + 1;

/// Fills the region [`area_mean`] reads (`AREA_MEAN_SPAN`², row by row from the south) from
/// `sample(face, level, i, j)`, the child level's global samples (indices off the face are the
/// sampler's to fold).
pub fn fill_area_mean_region(quad: QuadId, region: &mut [f32], sample: &mut dyn FnMut(Face, u8, i64, i64) -> f32) {
    let child = quad.level + 1;
    let (ci0, cj0) = (2 * i64::from(quad.x) * i64::from(TILE), 2 * i64::from(quad.y) * i64::from(TILE));
    let span = AREA_MEAN_SPAN;
    for b in 0..span {
        for a in 0..span {
            region[b * span + a] = sample(quad.face, child, ci0 - 1 + a as i64, cj0 - 1 + b as i64);
        }
    }
}

/// The area means of a quad from its children's samples around it, its 257² samples row by row
/// from the south (the region from [`fill_area_mean_region`]; NaN there and in the result is no
/// data): what the store's coarser levels and an edit raster's pyramid hold.
pub fn area_mean(quad: QuadId, region: &[f32]) -> Vec<f32> {
    let span = AREA_MEAN_SPAN;
    let mut grid = vec![f32::NAN; (GRID * GRID) as usize];
    // Weights in sixteenths: the full-weighting stencil, and at a cube corner (where a cell has
    // three quadrants, one per face) the same quadrants counted once each, so that the three
    // faces compute the same value.
    const FULL: [[f64; 3]; 3] = [[1.0, 2.0, 1.0], [2.0, 4.0, 2.0], [1.0, 2.0, 1.0]];
    let m = intervals_per_face_edge(quad.level);
    for q in 0..GRID as usize {
        for p in 0..GRID as usize {
            let (ca, cb) = (2 * p + 1, 2 * q + 1);
            let (gi, gj) =
                (i64::from(quad.x) * i64::from(TILE) + p as i64, i64::from(quad.y) * i64::from(TILE) + q as i64);
            let corner = (gi == 0 || gi == m) && (gj == 0 || gj == m);
            let mut w = FULL;
            if corner {
                // sx, sy: steps into the face; the stencil row/column index of (−sx, −sy) etc.
                let (ix, iy) = (if gi == 0 { 0 } else { 2 }, if gj == 0 { 0 } else { 2 });
                w[1][1] = 3.0;
                w[iy][1] = 0.0; // (0, −sy): the same point as (−sx, 0), counted once
                w[iy][ix] = 0.0; // beyond the corner: no such point
            }
            let (mut sum, mut weight) = (0.0, 0.0);
            for (db, row) in w.iter().enumerate() {
                for (da, wgt) in row.iter().enumerate() {
                    let v = region[(cb + db - 1) * span + ca + da - 1];
                    if !v.is_nan() && *wgt > 0.0 {
                        sum += wgt * f64::from(v);
                        weight += wgt / 16.0;
                    }
                }
            }
            if weight >= 0.5 {
                grid[q * GRID as usize + p] = (sum / 16.0 / weight) as f32;
            }
        }
    }
    grid
}
