//! A region of the planet as one erosion grid: the samples of a level over a box of one face's
//! global sample indices, the box allowed to run past the face's edges (the indices are folded
//! onto the adjacent faces with the store's fold, so the grid is contiguous across a face edge;
//! beyond a cube corner there is no sample and the cell is a no-data sink). Cell lengths are the
//! chords to the next samples on the ellipsoid, areas their products; terrain heights come from
//! the caller (the composed elevation below the erosion layer, per quad).

use std::collections::HashMap;

use glam::DVec3;

use super::grid::Grid;
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;
use crate::layers::stack::sample_point;
use crate::store::grid::{GRID, TILE, fold_sample, quad_of_sample};

/// A box of global sample indices of one face at one level (it may run past the face's edges).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// The face whose index space the box is in.
    pub face: Face,
    /// The level of the samples.
    pub level: u8,
    /// The first sample along x (may be negative: on the adjacent face).
    pub i0: i64,
    /// The first sample along y.
    pub j0: i64,
    /// Samples along x.
    pub width: usize,
    /// Samples along y.
    pub height: usize,
}

/// Where one cell of a region lives: its folded face, sample indices there, and its quad.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellAt {
    /// The quad holding the sample.
    pub quad: QuadId,
    /// The sample's column in the quad's 257² grid.
    pub i: u32,
    /// Its row.
    pub j: u32,
}

impl Region {
    /// The region of a quad and `ring` quads around it (in the quad's face's index space).
    pub fn around(quad: QuadId, ring: u32) -> Region {
        let tile = i64::from(TILE);
        let r = i64::from(ring) * tile;
        let side = (2 * i64::from(ring) + 1) * tile;
        Region {
            face: quad.face,
            level: quad.level,
            i0: i64::from(quad.x) * tile - r,
            j0: i64::from(quad.y) * tile - r,
            width: side as usize,
            height: side as usize,
        }
    }

    /// Cell (x, y)'s sample (None beyond a cube corner).
    pub fn cell(&self, x: usize, y: usize) -> Option<CellAt> {
        let (f, i, j) = fold_sample(self.face, self.level, self.i0 + x as i64, self.j0 + y as i64)?;
        let (quad, i, j) = quad_of_sample(f, self.level, i, j);
        Some(CellAt { quad, i, j })
    }

    /// The quads the region's cells read.
    pub fn quads(&self) -> Vec<QuadId> {
        let mut quads: Vec<QuadId> = (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .filter_map(|(x, y)| self.cell(x, y).map(|c| c.quad))
            .collect();
        quads.sort();
        quads.dedup();
        quads
    }

    /// The region's grid: lengths and areas from the cells' points on `ellipsoid`, terrain from
    /// `heights(quad)` (257² heights, NaN where no data; errors passed through).
    pub fn grid(
        &self,
        ellipsoid: &Ellipsoid,
        heights: &dyn Fn(QuadId) -> Result<Vec<f32>, String>,
    ) -> Result<Grid, String> {
        let mut tiles: HashMap<QuadId, Vec<f32>> = HashMap::new();
        for q in self.quads() {
            let t = heights(q)?;
            if t.len() != (GRID * GRID) as usize {
                return Err(format!("the heights of {q} have {} samples, not {}", t.len(), GRID * GRID));
            }
            tiles.insert(q, t);
        }
        // Points one sample beyond the box on the +x and +y sides too, for the last lengths.
        let (w, h) = (self.width, self.height);
        let point = |x: usize, y: usize| -> Option<DVec3> {
            let c = self.cell(x, y)?;
            Some(sample_point(ellipsoid, c.quad, GRID, c.i, c.j).0)
        };
        let mut points = Vec::with_capacity((w + 1) * (h + 1));
        for y in 0..=h {
            for x in 0..=w {
                points.push(point(x, y));
            }
        }
        let at = |x: usize, y: usize| points[y * (w + 1) + x];
        let n = w * h;
        let (mut base, mut dx, mut dy) = (vec![f64::NAN; n], vec![0.0; n], vec![0.0; n]);
        // The level's mean spacing stands in where a neighbour is missing (beyond a corner).
        let mean = crate::store::grid::spacing_m(ellipsoid, self.level);
        for y in 0..h {
            for x in 0..w {
                let k = y * w + x;
                let p = at(x, y);
                dx[k] = match (p, at(x + 1, y)) {
                    (Some(a), Some(b)) => (b - a).length(),
                    _ => mean,
                };
                dy[k] = match (p, at(x, y + 1)) {
                    (Some(a), Some(b)) => (b - a).length(),
                    _ => mean,
                };
                if let Some(c) = self.cell(x, y) {
                    base[k] = f64::from(tiles[&c.quad][c.j as usize * GRID as usize + c.i as usize]);
                }
            }
        }
        let area_m2 = dx.iter().zip(&dy).map(|(a, b)| a * b).collect();
        Ok(Grid {
            width: w,
            height: h,
            base_m: base,
            area_m2,
            dx_m: dx,
            dy_m: dy,
            rain_mask: None,
            erosion_mask: None,
            hardness: None,
            pipe_weight: super::grid::PIPE_WEIGHT,
        })
    }
}
