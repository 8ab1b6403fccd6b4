//! Starting a run with the water its rain would hold at steady state.
//!
//! Virtual pipes resolve seconds of flow; water raining on a catchment of kilometres takes hours
//! of simulated time to reach its river, so a run that starts dry spends its first thousands of
//! steps filling the network before rivers carry anything. Starting from the steady state puts
//! the water where the rain would have taken it: the drainage area of each cell by multiple flow
//! directions on the terrain with its closed depressions filled ([`flow::area_mfd`], the
//! stream-power model's routing), the discharge Q = rain × area (less what evaporates on the
//! way: each hop keeps e^(−evaporation × hop length / speed)), the speed at which the pipes'
//! friction balances gravity on the local slope, v = g·S/k_f (S at least `min_slope`), the depth
//! that carries Q across the cell's width at that speed, d = Q / (w·v), at most
//! [`MAX_START_DEPTH_M`], and lakes filled to their spill level on top.

use super::grid::{Grid, MAX_UNITS};
use super::landscape::flow::{self, Spread};
use super::params::Params;

/// The deepest water a cell starts with, metres (rivers on gentle slopes at steady state run
/// deeper than the pipes' linear friction would ever carry them in a run of minutes).
pub const MAX_START_DEPTH_M: f64 = 5.0;

/// The water each cell holds at the start, metres of depth (0 at cells without data and sinks).
pub fn steady_depth_m(grid: &Grid, params: &Params) -> Vec<f64> {
    let n = grid.len();
    let base = flow::base_level(grid);
    let routed = flow::route(grid, &grid.base_m, &base);
    let flooded = &routed.flooded_m;
    let spread = Spread::of(grid, flooded, &base);
    let g = params.gravity_m_s2;
    let friction = params.friction_per_s.max(1e-3);
    let slope = |i: usize| -> f64 {
        let mut steepest: f64 = 0.0;
        for k in 0..8 {
            let Some(j) = grid.neighbour(i, k) else { continue };
            if flooded[j].is_nan() {
                continue;
            }
            let s = (flooded[i] - flooded[j]) / flow::pipe_distance_m(grid, i, j, k);
            steepest = steepest.max(s);
        }
        steepest.max(params.min_slope).max(1e-4)
    };
    let speed: Vec<f64> = (0..n).map(|i| if flooded[i].is_nan() { 0.0 } else { g * slope(i) / friction }).collect();
    // Discharge, m³/s, accumulated down the shares, each hop keeping what does not evaporate.
    let rain = |i: usize| params.rain_m_s * grid.rain_mask.as_ref().map_or(1.0, |m| m[i].clamp(0.0, 1.0));
    let mut discharge: Vec<f64> =
        (0..n).map(|i| if flooded[i].is_nan() { 0.0 } else { rain(i) * grid.area_m2[i] }).collect();
    for &i in &spread.order {
        let here = discharge[i];
        let length = grid.area_m2[i].sqrt();
        let kept = (-params.evaporation_per_s * length / speed[i].max(1e-6)).exp();
        for &(j, w) in spread.shares(i) {
            discharge[j] += here * w * kept;
        }
    }
    (0..n)
        .map(|i| {
            if flooded[i].is_nan() || grid.is_sink(i) || base[i] {
                return 0.0;
            }
            let width = grid.area_m2[i].sqrt();
            let river = (discharge[i] / (width * speed[i])).min(MAX_START_DEPTH_M);
            river + (flooded[i] - grid.base_m[i]).max(0.0)
        })
        .collect()
}

/// [`steady_depth_m`] in whole units of `unit_m3` per cell (within [`MAX_UNITS`]).
pub fn steady_water_units(grid: &Grid, params: &Params, unit_m3: f64) -> Vec<i64> {
    steady_depth_m(grid, params)
        .iter()
        .zip(&grid.area_m2)
        .map(|(d, a)| ((d * a / unit_m3).floor() as i64).clamp(0, MAX_UNITS))
        .collect()
}

#[cfg(test)]
mod tests {
    use super::super::landscape::flow;
    use super::super::params::{EARTH_G, Params, Start};
    use super::super::sim::Run;
    use super::Grid;

    /// Valleys running down a tilted plane (the border ring is base level), 30 m cells, with a
    /// deterministic jitter so that the flow is not symmetric.
    fn valleys(n: usize) -> Grid {
        let mut state = 11u32;
        let heights = (0..n * n)
            .map(|i| {
                state = crate::maths::pcg(state);
                let (x, y) = ((i % n) as f64, (i / n) as f64);
                3.0 * y
                    + 40.0 * (x / 6.0).sin().abs()
                    + 8.0 * (y / 9.0 + x / 13.0).sin()
                    + f64::from(state % 100) / 100.0
            })
            .collect();
        Grid::flat_patch(n, n, 30.0, heights)
    }

    fn channels(grid: &Grid, threshold_cells: f64) -> Vec<bool> {
        let base = flow::base_level(grid);
        let area = flow::route(grid, &grid.base_m, &base).area_m2;
        area.iter().map(|a| *a >= threshold_cells * 900.0).collect()
    }

    #[test]
    fn a_steady_start_puts_each_catchments_rain_in_its_river_and_the_budget_counts_it() {
        let grid = valleys(64);
        let river = channels(&grid, 40.0);
        let params = Params::preset("river", EARTH_G).unwrap();
        assert_eq!(params.start, Start::Steady);
        let mut run = Run::new(grid.clone(), params.clone()).unwrap().with_seed(1);
        let (held, _) = run.totals();
        assert!(held > 0 && run.budget.start_water == held, "{:?} against {held}", run.budget);
        // Rivers start deeper than the slopes they drain.
        let mean = |cells: &mut dyn Iterator<Item = usize>| {
            let (sum, count) = cells.fold((0.0, 0usize), |(s, c), i| (s + run.depth_m(i), c + 1));
            sum / count.max(1) as f64
        };
        let border = flow::base_level(&grid);
        let (in_rivers, elsewhere) = (
            mean(&mut (0..grid.len()).filter(|&i| river[i])),
            mean(&mut (0..grid.len()).filter(|&i| !river[i] && !border[i])),
        );
        assert!(in_rivers > 5.0 * elsewhere, "rivers {in_rivers:.3} m, slopes {elsewhere:.4} m");
        // Close to the steady state: over 300 steps the water held changes far less than a dry
        // start's, which is still filling.
        let mut dry = Run::new(grid, Params { start: Start::Dry, ..params }).unwrap().with_seed(1);
        for _ in 0..300 {
            run.step();
            dry.step();
        }
        assert_eq!(run.unexplained(), (0, 0));
        assert_eq!(dry.unexplained(), (0, 0));
        let (after, _) = run.totals();
        let (dry_after, _) = dry.totals();
        let drift = (after - held).abs() as f64 / held as f64;
        let filling = (held - dry_after) as f64 / held as f64;
        eprintln!(
            "steady start: held {held}, after 300 steps {after} ({drift:.3}); dry start {dry_after} ({filling:.3} short)"
        );
        assert!(drift < 0.5 * filling, "the steady start drifts {drift:.3}, the dry one is {filling:.3} short");
    }

    #[test]
    fn the_time_scaled_river_preset_cuts_its_rivers_and_the_unscaled_one_barely_does() {
        let grid = valleys(64);
        let river = channels(&grid, 40.0);
        let border = flow::base_level(&grid);
        let cut = |params: Params| {
            let mut run = Run::new(grid.clone(), params).unwrap().with_seed(2);
            for _ in 0..300 {
                run.step();
            }
            assert_eq!(run.unexplained(), (0, 0));
            let delta = run.delta_m();
            let mean = |pick: bool| {
                let cells: Vec<f64> =
                    (0..grid.len()).filter(|&i| river[i] == pick && !border[i]).map(|i| -delta[i]).collect();
                cells.iter().sum::<f64>() / cells.len() as f64
            };
            (mean(true), mean(false))
        };
        let (scaled_river, scaled_slopes) = cut(Params::preset("river", EARTH_G).unwrap());
        let (unscaled_river, _) = cut(Params::unscaled("river", EARTH_G).unwrap());
        eprintln!(
            "cut: scaled rivers {scaled_river:.3} m, slopes {scaled_slopes:.4} m; unscaled rivers {unscaled_river:.5} m"
        );
        assert!(
            scaled_river > 0.0 && scaled_river > 5.0 * scaled_slopes.abs(),
            "{scaled_river} against {scaled_slopes}"
        );
        assert!(scaled_river > 20.0 * unscaled_river.abs(), "{scaled_river} against {unscaled_river}");
    }
}
