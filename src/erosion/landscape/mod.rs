//! Landscape evolution over geological time: uplift, river incision by the stream-power law and
//! hillslope diffusion on a region's grid (the same grid, cell areas and lengths on the ellipsoid
//! and the same folding across face edges as the hydraulic model), after FastScape (Braun &
//! Willett 2013) and fastscapelib, which the tests compare it with.
//!
//! One step of Δt years, as fastscapelib's examples order it: the cells that are not base level
//! rise by U·Δt (along a brush path, by its mask); the uplifted surface is routed ([`flow`], by
//! steepest descent, drainage area optionally by multiple flow directions); rivers incise it
//! implicitly and, with a deposition coefficient G, lay sediment down (ξ-q, [`spl`]); the result
//! diffuses implicitly ([`diffusion`]). The change of every cell is kept in
//! fixed point (the hydraulic model's volume unit), so the budgets (uplifted, eroded, deposited,
//! out through base level) add up to the state to the last unit, and the CPU path is the
//! reference, deterministic bit for bit.

pub mod diffusion;
pub mod drainage;
pub mod flow;
pub mod spl;

use serde::{Deserialize, Serialize};

use super::grid::Grid;

/// The parameters of a stream-power run, as a project records them.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct LandscapeParams {
    /// Rock uplift U, m/yr: uniform, or along a run's brush path scaled by its mask (1 within
    /// half the radius, fading to 0 at the radius); base level does not rise.
    pub uplift_m_per_year: f64,
    /// Erodibility K of E = K·A^m·S^n (A in m², S in m/m, E in m/yr).
    pub k: f64,
    /// The drainage-area exponent m, in (0, 1].
    pub m: f64,
    /// The slope exponent n, in [0.5, 4].
    pub n: f64,
    /// Hillslope diffusivity K_d, m²/yr (0: none).
    #[serde(default)]
    pub kd_m2_per_year: f64,
    /// The ξ-q deposition coefficient G (Davy & Lague 2009): rivers lay down G·Qs/A of the
    /// sediment flux Qs they carry, per year; 0: detachment-limited (no deposition).
    #[serde(default)]
    pub deposition: f64,
    /// How drainage area is accumulated: `d8` (to the steepest of 8 neighbours; the default) or
    /// `mfd` (shared among every lower neighbour, Freeman 1991). Incision follows the steepest
    /// neighbour either way.
    #[serde(default, skip_serializing_if = "flow::Routing::is_d8")]
    pub routing: flow::Routing,
    /// The simulated time, years.
    pub years: f64,
    /// The time step, years (the last step is shorter when `years` is not a multiple).
    pub dt_years: f64,
}

impl Default for LandscapeParams {
    /// Defaults that grow a recognisable river network on a region of a few hundred cells across
    /// at tens to hundreds of metres per cell: 1 mm/yr of uplift, K = 2·10⁻⁵ with m = 0.45 and
    /// n = 1 (a concavity of 0.45, the commonest in Whipple & Tucker's compilation), K_d =
    /// 0.01 m²/yr, 2 Myr in 10 kyr steps.
    fn default() -> LandscapeParams {
        LandscapeParams {
            uplift_m_per_year: 1e-3,
            k: 2e-5,
            m: 0.45,
            n: 1.0,
            kd_m2_per_year: 0.01,
            deposition: 0.0,
            routing: flow::Routing::D8,
            years: 2e6,
            dt_years: 1e4,
        }
    }
}

/// A parameter outside its range: the field (as the flag names it without `--`) and the problem.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
#[error("{field}: {problem}")]
pub struct LandscapeError {
    /// The field.
    pub field: &'static str,
    /// What is wrong with its value.
    pub problem: String,
}

/// The most steps one run may take.
pub const MAX_STEPS: u64 = 1_000_000;

impl LandscapeParams {
    /// Checks every value; the first out of range is named.
    pub fn check(&self) -> Result<(), LandscapeError> {
        let bad = |field: &'static str, problem: String| Err(LandscapeError { field, problem });
        let finite = |v: f64| v.is_finite();
        if !(finite(self.uplift_m_per_year) && self.uplift_m_per_year.abs() <= 0.1) {
            return bad("uplift_m_per_year", format!("{} is outside −0.1 … 0.1 m/yr", self.uplift_m_per_year));
        }
        if !(finite(self.k) && self.k >= 0.0 && self.k <= 1.0) {
            return bad("k", format!("{} is outside 0 … 1", self.k));
        }
        if !(self.m > 0.0 && self.m <= 1.0) {
            return bad("m", format!("{} is outside (0, 1]", self.m));
        }
        if !(self.n >= 0.5 && self.n <= 4.0) {
            return bad("n", format!("{} is outside 0.5 … 4", self.n));
        }
        if !(finite(self.kd_m2_per_year) && self.kd_m2_per_year >= 0.0 && self.kd_m2_per_year <= 1e3) {
            return bad("kd_m2_per_year", format!("{} is outside 0 … 1000 m²/yr", self.kd_m2_per_year));
        }
        if !(finite(self.deposition) && (0.0..=100.0).contains(&self.deposition)) {
            return bad("deposition", format!("{} is outside 0 … 100", self.deposition));
        }
        if !(finite(self.years) && self.years > 0.0) {
            return bad("years", format!("{} must be a positive number of years", self.years));
        }
        if !(finite(self.dt_years) && self.dt_years > 0.0) {
            return bad("dt_years", format!("{} must be a positive number of years", self.dt_years));
        }
        if self.dt_years > self.years {
            return bad("dt_years", format!("{} is longer than the run's {} years", self.dt_years, self.years));
        }
        if self.steps() > MAX_STEPS {
            return bad(
                "dt_years",
                format!("{} years in steps of {} is more than {MAX_STEPS} steps", self.years, self.dt_years),
            );
        }
        Ok(())
    }

    /// Steps of the run.
    pub fn steps(&self) -> u64 {
        (self.years / self.dt_years).ceil().max(1.0) as u64
    }
}

/// What a run has moved, in volume units of the grid (see [`Grid::unit_m3`]).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct LandscapeBudget {
    /// Rock uplifted into the region.
    pub uplifted: i64,
    /// Taken by incision and by diffusion where it lowers.
    pub eroded: i64,
    /// Raised by deposition and by diffusion where it raises.
    pub deposited: i64,
    /// Left through base level: eroded − deposited.
    pub outflow: i64,
}

/// A stream-power run on a grid.
#[derive(Clone, Debug)]
pub struct Evolution {
    /// The grid (its `base_m` the terrain at the start).
    pub grid: Grid,
    /// The base-level cells (held).
    pub base: Vec<bool>,
    /// The parameters.
    pub params: LandscapeParams,
    /// Each cell's change of height since the start, in volume units.
    pub change: Vec<i64>,
    /// The budgets.
    pub budget: LandscapeBudget,
    /// Steps taken.
    pub steps: u64,
    /// Years simulated.
    pub years: f64,
    /// The routing of the last step (None before the first).
    pub flow: Option<flow::Flow>,
    unit_m3: f64,
    /// With deposition: the sediment that entered each cell over the last step, m³.
    sediment_in: Vec<f64>,
    /// The last step's length, years.
    last_dt: f64,
}

impl Evolution {
    /// A run of `params` on `grid`, checked.
    pub fn new(grid: Grid, params: LandscapeParams) -> Result<Evolution, LandscapeError> {
        params.check()?;
        if grid.is_empty() {
            return Err(LandscapeError { field: "region", problem: "the grid has no cells".into() });
        }
        let base = flow::base_level(&grid);
        let unit_m3 = grid.unit_m3();
        let n = grid.len();
        Ok(Evolution {
            grid,
            base,
            params,
            change: vec![0; n],
            budget: LandscapeBudget::default(),
            steps: 0,
            years: 0.0,
            flow: None,
            unit_m3,
            sediment_in: Vec::new(),
            last_dt: 0.0,
        })
    }

    /// The volume one unit stands for, m³.
    pub fn unit_m3(&self) -> f64 {
        self.unit_m3
    }

    /// Height now, metres (NaN: no data).
    pub fn height_m(&self, i: usize) -> f64 {
        self.grid.base_m[i] + self.change[i] as f64 * self.unit_m3 / self.grid.area_m2[i]
    }

    /// Every cell's height now, metres.
    pub fn heights_m(&self) -> Vec<f64> {
        (0..self.grid.len()).map(|i| self.height_m(i)).collect()
    }

    /// Every cell's change of height since the start, metres (NaN: no data).
    pub fn delta_m(&self) -> Vec<f64> {
        (0..self.grid.len())
            .map(|i| {
                if self.grid.base_m[i].is_nan() {
                    f64::NAN
                } else {
                    self.change[i] as f64 * self.unit_m3 / self.grid.area_m2[i]
                }
            })
            .collect()
    }

    /// Whether every step has been taken.
    pub fn done(&self) -> bool {
        self.steps >= self.params.steps()
    }

    /// Volume units for a change of height `dh_m` of cell `i` (rounded to the nearest).
    fn units(&self, i: usize, dh_m: f64) -> i64 {
        (dh_m * self.grid.area_m2[i] / self.unit_m3).round() as i64
    }

    /// One step (the last one shorter when the run's years are not a multiple of Δt).
    pub fn step(&mut self) {
        let p = &self.params;
        let dt = p.dt_years.min(p.years - self.years).max(0.0);
        let law = spl::StreamPower { k: p.k, m: p.m, n: p.n };
        let kd = p.kd_m2_per_year;
        let n = self.grid.len();
        // Uplift, in whole units (scaled by the brush's mask where the run has one).
        let mask = |i: usize| self.grid.erosion_mask.as_ref().map_or(1.0, |m| m[i]);
        let uplift: Vec<i64> = (0..n)
            .map(|i| {
                if self.base[i] || self.grid.base_m[i].is_nan() {
                    0
                } else {
                    self.units(i, p.uplift_m_per_year * mask(i) * dt)
                }
            })
            .collect();
        let mut heights: Vec<f64> =
            (0..n).map(|i| self.height_m(i) + uplift[i] as f64 * self.unit_m3 / self.grid.area_m2[i]).collect();
        let uplifted = heights.clone();
        let mut routing = flow::route(&self.grid, &heights, &self.base);
        let spread =
            (p.routing == flow::Routing::Mfd).then(|| flow::Spread::of(&self.grid, &routing.flooded_m, &self.base));
        if let Some(spread) = &spread {
            let own: Vec<f64> = (0..n).map(|i| if heights[i].is_nan() { 0.0 } else { self.grid.area_m2[i] }).collect();
            routing.area_m2 = spread.accumulate(&own);
        }
        // What rivers laid down on each cell, metres (none without deposition).
        let settled = if p.deposition > 0.0 {
            // The last step's sediment, scaled to this step's length, is the first guess.
            let scale = if self.last_dt > 0.0 { dt / self.last_dt } else { 0.0 };
            self.sediment_in.iter_mut().for_each(|v| *v *= scale);
            let sediment = spl::Sediment { spread: spread.as_ref(), inflow: &mut self.sediment_in };
            spl::incise_and_deposit(&routing, &self.grid.area_m2, &mut heights, law, dt, p.deposition, sediment)
        } else {
            spl::incise(&routing, &mut heights, law, dt);
            Vec::new()
        };
        let diffused = diffusion::diffuse(&self.grid, &self.base, &heights, kd, dt);
        for i in 0..n {
            if self.grid.base_m[i].is_nan() {
                continue;
            }
            // The net fall, split into what was taken (incision, diffusion where it lowers) and
            // what was laid down (by rivers, by diffusion where it raises): eroded − deposited
            // is the fall to the unit.
            let lowered = self.units(i, uplifted[i] - diffused[i]);
            let laid = settled.get(i).map_or(0, |d| self.units(i, *d));
            self.change[i] += uplift[i] - lowered;
            self.budget.uplifted += uplift[i];
            if lowered + laid >= 0 {
                self.budget.eroded += lowered + laid;
                self.budget.deposited += laid;
            } else {
                self.budget.deposited -= lowered;
            }
        }
        self.budget.outflow = self.budget.eroded - self.budget.deposited;
        self.flow = Some(routing);
        self.last_dt = dt;
        self.steps += 1;
        self.years += dt;
    }

    /// Takes every step left.
    pub fn run_to_end(&mut self) {
        while !self.done() {
            self.step();
        }
    }

    /// The state's total change less what the budgets explain, in units (0 when every unit is
    /// accounted for).
    pub fn unexplained(&self) -> i64 {
        let total: i64 = self.change.iter().sum();
        total - (self.budget.uplifted - self.budget.eroded + self.budget.deposited)
    }
}

/// A surface without closed depressions for benchmarks and tests: rising `rise_m` per cell away
/// from the nearest border, with seeded roughness of under half a cell's rise (so that every cell
/// has one clearly steepest way down and two routings of it agree).
pub fn tent(width: usize, height: usize, rise_m: f64) -> Vec<f64> {
    (0..width * height)
        .map(|i| {
            let (x, y) = (i % width, i / width);
            let edge = x.min(y).min(width - 1 - x).min(height - 1 - y) as f64;
            // Every value distinct (2⁻³² steps), so no two slopes tie.
            let roughness = f64::from(crate::maths::pcg((i as u32).wrapping_mul(2_654_435_761))) / 4_294_967_296.0;
            rise_m * (edge + 0.45 * roughness)
        })
        .collect()
}

/// What a finished run did, for reports.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LandscapeOutcome {
    /// Years simulated.
    pub simulated_years: f64,
    /// Rock uplifted into the region, m³.
    pub uplifted_m3: f64,
    /// Material removed, m³.
    pub eroded_m3: f64,
    /// Material laid down, m³.
    pub deposited_m3: f64,
    /// Material that left through base level, m³.
    pub outflow_m3: f64,
    /// The state's change the budgets do not explain, over the material moved.
    pub unexplained_rel: f64,
}

/// A year, seconds (Julian).
pub const YEAR_S: f64 = 365.25 * 86_400.0;

impl Evolution {
    /// The run's figures.
    pub fn outcome(&self) -> LandscapeOutcome {
        let unit = self.unit_m3;
        let b = self.budget;
        LandscapeOutcome {
            simulated_years: self.years,
            uplifted_m3: b.uplifted as f64 * unit,
            eroded_m3: b.eroded as f64 * unit,
            deposited_m3: b.deposited as f64 * unit,
            outflow_m3: b.outflow as f64 * unit,
            unexplained_rel: self.unexplained().abs() as f64 / (b.uplifted + b.eroded).max(1) as f64,
        }
    }
}

#[cfg(test)]
mod tests;
