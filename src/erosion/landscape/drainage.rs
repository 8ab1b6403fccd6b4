//! The drainage overlay: where water runs on a terrain, before and after a run. The terrain of a
//! region (the visible stack, read on the region's grid) is routed as a stream-power step routes
//! it ([`flow::route`]: steepest descent across face edges, closed depressions drained through
//! their spill points; drainage area by one or by multiple flow directions), and each cell gets
//! a shade for the diverging colour map: the log of its drainage area, or only the channel
//! network (cells draining at least a threshold area), drawn over the terrain.

use super::flow::{self, Flow, Routing};
use crate::erosion::grid::Grid;

/// What the overlay draws.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Show {
    /// Flow accumulation everywhere: red on divides to blue in the largest river, on a log scale.
    Accumulation,
    /// The channel network only: cells draining at least the threshold, light to dark blue with
    /// the log of their area.
    Channels,
}

/// A region's drainage.
#[derive(Clone, Debug)]
pub struct Drainage {
    /// The routing (its `area_m2` by `routing`).
    pub flow: Flow,
    /// How the area was accumulated.
    pub routing: Routing,
}

impl Drainage {
    /// Routes the grid's terrain (`grid.base_m`).
    pub fn of(grid: &Grid, routing: Routing) -> Drainage {
        let base = flow::base_level(grid);
        let mut flow = flow::route(grid, &grid.base_m, &base);
        if routing == Routing::Mfd {
            flow.area_m2 = flow::area_mfd(grid, &flow.flooded_m, &base);
        }
        Drainage { flow, routing }
    }

    /// Cells draining at least `threshold_m2`.
    pub fn channel_cells(&self, threshold_m2: f64) -> usize {
        self.flow.area_m2.iter().filter(|a| **a >= threshold_m2 && **a > 0.0).count()
    }

    /// The largest drainage area, m².
    pub fn largest_m2(&self) -> f64 {
        self.flow.area_m2.iter().copied().fold(0.0, f64::max)
    }

    /// Each cell's shade in [−1, 1] for the diverging colour map (NaN: not drawn; cells without
    /// data are never drawn). Accumulation: −1 for a cell that drains only itself to +1 for the
    /// largest area, linear in log A. Channels: cells draining at least `threshold_m2`, from
    /// 0.3 at the threshold to 1 at the largest area, linear in log A, and drawn wider as they
    /// grow: one cell more on each side from 10 times the threshold, two from 100 times.
    pub fn shade(&self, grid: &Grid, show: Show, threshold_m2: f64) -> Vec<f64> {
        let shade = self.shade_cells(grid, show, threshold_m2);
        if show == Show::Accumulation {
            return shade;
        }
        let mut wide = shade.clone();
        for i in (0..grid.len()).filter(|&i| shade[i].is_finite()) {
            let reach = (self.flow.area_m2[i] / threshold_m2).log10().floor().clamp(0.0, 2.0) as usize;
            let mut ring = vec![i];
            for _ in 0..reach {
                let next: Vec<usize> =
                    ring.iter().flat_map(|&c| (0..8).filter_map(move |k| grid.neighbour(c, k))).collect();
                for &j in &next {
                    if !grid.base_m[j].is_nan() && (wide[j].is_nan() || wide[j] < shade[i]) {
                        wide[j] = shade[i];
                    }
                }
                ring = next;
            }
        }
        wide
    }

    /// Each cell's own shade (see [`Drainage::shade`]), channels one cell wide.
    fn shade_cells(&self, grid: &Grid, show: Show, threshold_m2: f64) -> Vec<f64> {
        let largest = self.largest_m2();
        let area = &self.flow.area_m2;
        (0..grid.len())
            .map(|i| {
                if grid.base_m[i].is_nan() || area[i] <= 0.0 {
                    return f64::NAN;
                }
                match show {
                    Show::Accumulation => {
                        let own = grid.area_m2[i];
                        let span = (largest / own).ln().max(f64::MIN_POSITIVE);
                        2.0 * ((area[i] / own).ln() / span).clamp(0.0, 1.0) - 1.0
                    }
                    Show::Channels if area[i] < threshold_m2 => f64::NAN,
                    Show::Channels => {
                        let span = (largest / threshold_m2).ln();
                        let t = if span > 0.0 { (area[i] / threshold_m2).ln() / span } else { 1.0 };
                        0.3 + 0.7 * t.clamp(0.0, 1.0)
                    }
                }
            })
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A valley: two slopes falling to a river along the middle column, which falls south.
    fn valley(size: usize) -> Grid {
        let mid = size / 2;
        let heights = (0..size * size)
            .map(|i| {
                let (x, y) = (i % size, i / size);
                10.0 * (x as f64 - mid as f64).abs() + y as f64
            })
            .collect();
        Grid::flat_patch(size, size, 50.0, heights)
    }

    #[test]
    fn the_river_is_the_channel_and_darkens_downstream() {
        let size = 41;
        let grid = valley(size);
        let d = Drainage::of(&grid, Routing::D8);
        let threshold = 20.0 * 2500.0;
        let shade = d.shade(&grid, Show::Channels, threshold);
        let mid = size / 2;
        // The river's cells are drawn, darker downstream; the slopes are not.
        let river: Vec<f64> = (2..size - 1).map(|y| shade[y * size + mid]).collect();
        assert!(river.iter().filter(|s| s.is_finite()).count() > 10, "{river:?}");
        assert!(river.windows(2).all(|w| !w[0].is_finite() || w[1] <= w[0]), "{river:?}");
        assert!(shade[(size / 2) * size + 3].is_nan(), "a hillslope cell is drawn");
        // Accumulation: every cell with data gets a shade, the divides the reddest.
        let acc = d.shade(&grid, Show::Accumulation, threshold);
        assert!(acc.iter().all(|s| (-1.0..=1.0).contains(s)));
        assert_eq!(acc[(size / 2) * size + 1], -1.0);
        assert!((acc.iter().copied().fold(-1.0, f64::max) - 1.0).abs() < 1e-12);
        // Wider downstream: the river's last cells are drawn on their neighbours too.
        assert!(d.channel_cells(threshold) < shade.iter().filter(|s| s.is_finite()).count());
        // (near the outlet the river drains about 1 400 cells, 72 times the threshold: one cell
        // more on each side)
        assert!(shade[3 * size + mid - 1].is_finite() && shade[3 * size + mid + 1].is_finite());
        assert!(shade[3 * size + mid - 2].is_nan());
        assert!(shade[(size - 5) * size + mid - 1].is_nan(), "the river's head is one cell wide");
    }

    #[test]
    fn cells_without_data_are_not_drawn() {
        let mut grid = valley(21);
        grid.base_m[5 * 21 + 5] = f64::NAN;
        let d = Drainage::of(&grid, Routing::Mfd);
        let shade = d.shade(&grid, Show::Accumulation, 1.0);
        assert!(shade[5 * 21 + 5].is_nan());
        assert_eq!(shade.iter().filter(|s| s.is_nan()).count(), 1);
    }
}
