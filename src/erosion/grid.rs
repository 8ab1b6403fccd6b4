//! The grid an erosion run works on: cells with their terrain, area and lengths in metres (on the
//! planet, from the ECM geometry of a region of quads; for tests, a flat patch), their masks, and
//! the fixed-point unit of the volumes the run moves.

/// The eight pipes of a cell, as (dx, dy) to the neighbour: east, west, north, south, then the
/// diagonals. Pipe `k`'s opposite is `k ^ 1`.
pub const PIPES: [(i32, i32); 8] = [(1, 0), (-1, 0), (0, 1), (0, -1), (1, 1), (-1, -1), (1, -1), (-1, 1)];

/// The cross-section weight of each pipe, times the width across it (the cell's side for the axis
/// pipes, half the diagonal for the diagonals): the contour lengths of Quinn et al. 1991's
/// multiple-flow-direction routing (diagonal/axis 0.707). Eight pipes share the outflow so that
/// channels do not follow the grid's axes: on a cone the four-fold component of the erosion
/// around it is 0.067 of its mean, against 0.130 with four pipes and 0.080 with the diagonals
/// weighted ½ (`tests.rs`).
pub const PIPE_WEIGHT: [f64; 8] = [1.0; 8];

/// Water depth one volume unit stands for on the smallest cell, metres.
pub const DEPTH_QUANTUM_M: f64 = 1e-5;

/// The largest volume a cell may hold in units (water, sediment, or terrain change either way):
/// 2²⁷ units, 1 342 m of depth on the smallest cell, so that a cell's holding plus what its eight
/// neighbours send it (each at most this) stays within i32, the GPU's integers. A cell that would
/// hold more spills the excess out of the run, counted in the budget (see `sim`).
pub const MAX_UNITS: i64 = 1 << 27;

/// A region's grid, row by row from the south-west.
#[derive(Clone, Debug)]
pub struct Grid {
    /// Cells along x (east on a face's grid).
    pub width: usize,
    /// Cells along y.
    pub height: usize,
    /// Terrain height at the start, metres (NaN: no data; the cell is a sink).
    pub base_m: Vec<f64>,
    /// Cell area, m².
    pub area_m2: Vec<f64>,
    /// Distance to the +x neighbour's centre, metres (the last column's: to the border).
    pub dx_m: Vec<f64>,
    /// Distance to the +y neighbour's centre, metres.
    pub dy_m: Vec<f64>,
    /// Rain mask, 0–1 per cell (None: rain everywhere).
    pub rain_mask: Option<Vec<f64>>,
    /// Erosion mask, 0–1 per cell (None: erodes everywhere; 0: a sink that takes what flows in).
    pub erosion_mask: Option<Vec<f64>>,
    /// Hardness per cell (≥ 1; None: the run's).
    pub hardness: Option<Vec<f64>>,
    /// Each pipe's cross-section weight ([`PIPE_WEIGHT`]; the diagonals' set to 0 gives the
    /// four-pipe model, for comparison).
    pub pipe_weight: [f64; 8],
}

impl Grid {
    /// A flat patch of `width` × `height` square cells `cell_m` on a side with these heights.
    pub fn flat_patch(width: usize, height: usize, cell_m: f64, base_m: Vec<f64>) -> Grid {
        let n = width * height;
        assert_eq!(base_m.len(), n, "one height per cell");
        Grid {
            width,
            height,
            base_m,
            area_m2: vec![cell_m * cell_m; n],
            dx_m: vec![cell_m; n],
            dy_m: vec![cell_m; n],
            rain_mask: None,
            erosion_mask: None,
            hardness: None,
            pipe_weight: PIPE_WEIGHT,
        }
    }

    /// Cells.
    pub fn len(&self) -> usize {
        self.width * self.height
    }

    /// Whether the grid has no cells.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// The volume one unit stands for, m³: [`DEPTH_QUANTUM_M`] of depth on the smallest cell.
    pub fn unit_m3(&self) -> f64 {
        DEPTH_QUANTUM_M * self.area_m2.iter().copied().fold(f64::INFINITY, f64::min)
    }

    /// The neighbour of cell `i` through pipe `k` (None: beyond the border).
    pub fn neighbour(&self, i: usize, k: usize) -> Option<usize> {
        let (x, y) = ((i % self.width) as i64, (i / self.width) as i64);
        let (dx, dy) = PIPES[k];
        let (nx, ny) = (x + i64::from(dx), y + i64::from(dy));
        ((0..self.width as i64).contains(&nx) && (0..self.height as i64).contains(&ny))
            .then(|| ny as usize * self.width + nx as usize)
    }

    /// The length of pipe `k` of cell `i`, metres (centre to centre).
    pub fn pipe_length_m(&self, i: usize, k: usize) -> f64 {
        let (dx, dy) = PIPES[k];
        let lx = if dx == 0 { 0.0 } else { self.dx_m[i] };
        let ly = if dy == 0 { 0.0 } else { self.dy_m[i] };
        (lx * lx + ly * ly).sqrt()
    }

    /// Whether a cell is a sink (no data, or masked out of erosion): what flows in leaves.
    pub fn is_sink(&self, i: usize) -> bool {
        self.base_m[i].is_nan() || self.erosion_mask.as_ref().is_some_and(|m| m[i] <= 0.0)
    }
}
