//! The CPU reference of an erosion step: shallow water on eight virtual pipes (Mei, Decaudin & Hu
//! 2007) with the fixes of `REFERENCES.md`, sediment carried in flux form, dissolving and
//! deposition by a capacity that grows with speed, slope and depth, and thermal sliding beyond a
//! talus angle. Two passes per step, gather-only, as the GPU's two kernels will be:
//!
//! 1. **outflows** (per cell, from the state at the step's start): each pipe's flux, less its
//!    friction, accelerated by the difference of water surface heights,
//!    f ← max(0, f·(1 − k_f·Δt) + Δt·g·c·Δh/l) with c the pipe's
//!    cross-section (its weight × the cell's width across it × the water depth), then all scaled
//!    by K = min(1, water / (Σf·Δt)) so that a cell never sends more than it holds (scaling, not
//!    clamping: no water is made); the volumes sent, in whole units, floored; the sediment sent
//!    with them, in proportion (flux form, upwind); soil sliding to lower neighbours beyond the
//!    talus angle.
//! 2. **update** (per cell): what it sent subtracted and what its neighbours sent it added (each
//!    transfer is one integer that one cell loses exactly as the other gains); velocity from the
//!    net flow over the mean depth, desingularised on thin sheets ([`DESINGULARISE_M`]);
//!    capacity; dissolving or deposition; evaporation; rain.
//!
//! Volumes are integers: water, suspended sediment and the terrain's change per cell in units of
//! [`Grid::unit_m3`] (10 µm of depth on the smallest cell), so water and soil are conserved
//! **exactly**, by construction: the budgets (rain in, evaporation and border or sink outflow
//! out) explain every unit. The float parts (fluxes, velocities, capacities) are f64, computed in
//! the same order whatever the thread count: the same inputs give the same result bit for bit.
//! Rain, evaporation, dissolving, deposition and the water sent through each pipe are rounded to
//! whole units without bias by a seeded dither ([`super::dither`]): thin sheets of water still
//! flow, and small rates still act.
//! A cell holds at most [`MAX_UNITS`] of each (1 342 m of depth on the smallest cell): beyond it
//! water and soil spill out of the run and are counted as outflow, so that the GPU's i32 sums
//! cannot overflow.
//!
//! The time step is the one asked for, or less where the CFL bound requires:
//! Δt ≤ CFL · l_min / (|v|_max + √(g·d_max)).

// The pipe loops index several per-pipe arrays by the pipe's number, as the WGSL kernels will.
#![allow(clippy::needless_range_loop)]

use rayon::prelude::*;

use super::dither;
use super::grid::{Grid, MAX_UNITS, PIPES};
use super::params::{Border, Params};

/// The depth below which the speed estimate is desingularised, metres (Kurganov & Petrova
/// 2007): |v| = √2·d·q / √(d⁴ + max(d⁴, ε⁴)) with q the discharge per unit width, which is q/d
/// for d ≫ ε and goes to 0 with d instead of blowing up as q/d does on thin sheets that still
/// carry the flux of deeper moments (dividing by a vanishing depth gave 25–40 m/s on 0.1 mm
/// sheets, and the CFL bound shrank the step for nothing; transfers never exceed what a cell
/// holds whatever the speed, so the speed only sets capacities and the step).
pub const DESINGULARISE_M: f64 = 1e-3;

/// |v| from the discharge per unit width `q` (m²/s) over the depth `d` (m), desingularised.
pub fn speed_m_s(q: f64, d: f64) -> f64 {
    let d4 = d.powi(4);
    let denominator = (d4 + d4.max(DESINGULARISE_M.powi(4))).sqrt();
    if denominator > 0.0 { std::f64::consts::SQRT_2 * d * q / denominator } else { 0.0 }
}

/// The state of a run.
#[derive(Clone, Debug, PartialEq)]
pub struct State {
    /// Water per cell, units.
    pub water: Vec<i64>,
    /// Suspended sediment per cell, units.
    pub sediment: Vec<i64>,
    /// The terrain's change per cell, units (height change = units × unit_m3 / area).
    pub soil: Vec<i64>,
    /// Per cell, the flux through each pipe, m³/s.
    pub flux_m3_s: Vec<[f64; 8]>,
    /// Per cell, the speed of its water, m/s (for the next step's CFL bound).
    pub speed_m_s: Vec<f64>,
}

/// Where water and soil went, in units, since the run began.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Budget {
    /// Water the run started with ([`super::params::Start`]).
    pub start_water: i64,
    /// Rain added.
    pub rain_in: i64,
    /// Water evaporated.
    pub evaporated: i64,
    /// Water that left through an open border or into a sink.
    pub water_out: i64,
    /// Sediment that left with it.
    pub soil_out: i64,
}

/// One step's figures.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StepReport {
    /// The step taken, seconds.
    pub dt_s: f64,
    /// The CFL bound at the step's start, seconds (∞ without water).
    pub cfl_bound_s: f64,
    /// The largest water speed after the step, m/s.
    pub max_speed_m_s: f64,
    /// The largest water depth after the step, metres.
    pub max_depth_m: f64,
}

/// An erosion run on a grid.
#[derive(Clone, Debug)]
pub struct Run {
    /// The grid.
    pub grid: Grid,
    /// The parameters.
    pub params: Params,
    /// The state.
    pub state: State,
    /// The budget so far.
    pub budget: Budget,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time, seconds.
    pub simulated_s: f64,
    /// The dither's seed (see [`super::dither`]).
    pub seed: u32,
    /// The smallest and largest step taken, seconds ((∞, 0) before the first).
    pub dt_range_s: (f64, f64),
    unit_m3: f64,
}

/// What one cell sends through each pipe in a step, units.
#[derive(Clone, Copy, Debug, Default)]
struct Outflow {
    water: [i64; 8],
    sediment: [i64; 8],
    soil: [i64; 8],
}

impl Run {
    /// A run on `grid` (dry, nothing moved yet). The parameters are checked.
    pub fn new(grid: Grid, params: Params) -> Result<Run, super::params::ParamError> {
        params.check()?;
        let n = grid.len();
        let unit_m3 = grid.unit_m3();
        let water = match params.start {
            super::params::Start::Dry => vec![0; n],
            super::params::Start::Steady => super::start::steady_water_units(&grid, &params, unit_m3),
        };
        let budget = Budget { start_water: water.iter().sum(), ..Budget::default() };
        Ok(Run {
            state: State {
                water,
                sediment: vec![0; n],
                soil: vec![0; n],
                flux_m3_s: vec![[0.0; 8]; n],
                speed_m_s: vec![0.0; n],
            },
            grid,
            params,
            budget,
            steps: 0,
            simulated_s: 0.0,
            seed: 0,
            dt_range_s: (f64::INFINITY, 0.0),
            unit_m3,
        })
    }

    /// The run with the dither drawn from `seed` (an operation's seed; see [`super::dither`]).
    pub fn with_seed(mut self, seed: u64) -> Run {
        self.seed = super::dither::fold_seed(seed);
        self
    }

    /// An unbiased whole number of units for `x` units (x ≥ 0), drawn for this step, cell and
    /// stream.
    fn round(&self, x: f64, i: usize, stream: u32) -> i64 {
        (x + super::dither::uniform(self.seed, self.steps as u32, i as u32, stream)).floor() as i64
    }

    /// The volume of one unit, m³.
    pub fn unit_m3(&self) -> f64 {
        self.unit_m3
    }

    /// The terrain height of cell `i` now, metres (NaN for a no-data cell).
    pub fn height_m(&self, i: usize) -> f64 {
        self.grid.base_m[i] + self.state.soil[i] as f64 * self.unit_m3 / self.grid.area_m2[i]
    }

    /// The water depth of cell `i`, metres.
    pub fn depth_m(&self, i: usize) -> f64 {
        self.state.water[i] as f64 * self.unit_m3 / self.grid.area_m2[i]
    }

    /// The terrain's change per cell, metres (0 at no-data cells).
    pub fn delta_m(&self) -> Vec<f64> {
        (0..self.grid.len()).map(|i| self.state.soil[i] as f64 * self.unit_m3 / self.grid.area_m2[i]).collect()
    }

    /// Water and soil (terrain change + sediment) held now, units.
    pub fn totals(&self) -> (i64, i64) {
        let water = self.state.water.iter().sum();
        let soil = self.state.soil.iter().sum::<i64>() + self.state.sediment.iter().sum::<i64>();
        (water, soil)
    }

    /// What the budget does not explain, units: (water, soil). Zero by construction; the tests
    /// hold the run to it.
    pub fn unexplained(&self) -> (i64, i64) {
        let (water, soil) = self.totals();
        let b = &self.budget;
        (water - (b.start_water + b.rain_in - b.evaporated - b.water_out), soil + b.soil_out)
    }

    /// The CFL bound on the step at the current state, seconds (∞ when nothing moves).
    pub fn cfl_bound_s(&self) -> f64 {
        let g = self.params.gravity_m_s2;
        // The depth rain adds this step counts too (it is there before the next outflows).
        let rain = self.params.rain_m_s * self.params.dt_s;
        let mut bound = f64::INFINITY;
        for i in 0..self.grid.len() {
            let d = self.depth_m(i) + rain;
            let speed = self.state.speed_m_s[i] + (g * d).sqrt();
            if speed > 0.0 {
                let l = self.grid.dx_m[i].min(self.grid.dy_m[i]);
                bound = bound.min(self.params.cfl * l / speed);
            }
        }
        bound
    }

    /// One step.
    pub fn step(&mut self) -> StepReport {
        let cfl_bound_s = self.cfl_bound_s();
        let dt = self.params.dt_s.min(cfl_bound_s);
        let outflows: Vec<(Outflow, [f64; 8])> =
            (0..self.grid.len()).into_par_iter().map(|i| self.outflow(i, dt)).collect();
        let updates: Vec<(i64, i64, i64, f64, Budget)> =
            (0..self.grid.len()).into_par_iter().map(|i| self.update(i, dt, &outflows)).collect();
        let mut report = StepReport { dt_s: dt, cfl_bound_s, max_speed_m_s: 0.0, max_depth_m: 0.0 };
        // Fixed-order reduction (integers: exact whatever the order anyway).
        for (i, ((water, sediment, soil, speed, budget), (_, flux))) in updates.into_iter().zip(outflows).enumerate() {
            self.state.water[i] = water;
            self.state.sediment[i] = sediment;
            self.state.soil[i] = soil;
            self.state.speed_m_s[i] = speed;
            self.state.flux_m3_s[i] = flux;
            self.budget.rain_in += budget.rain_in;
            self.budget.evaporated += budget.evaporated;
            self.budget.water_out += budget.water_out;
            self.budget.soil_out += budget.soil_out;
            report.max_speed_m_s = report.max_speed_m_s.max(speed);
        }
        report.max_depth_m = (0..self.grid.len()).map(|i| self.depth_m(i)).fold(0.0, f64::max);
        self.steps += 1;
        self.simulated_s += dt;
        self.dt_range_s = (self.dt_range_s.0.min(dt), self.dt_range_s.1.max(dt));
        report
    }

    /// Pass 1 at cell `i`: what it sends through each pipe, and its new fluxes.
    fn outflow(&self, i: usize, dt: f64) -> (Outflow, [f64; 8]) {
        let mut out = Outflow::default();
        let mut flux = [0.0; 8];
        if self.grid.is_sink(i) {
            return (out, flux);
        }
        let g = self.params.gravity_m_s2;
        let grid = &self.grid;
        let h = self.height_m(i);
        let d = self.depth_m(i);
        let open = self.params.border == Border::Open;
        // The neighbour's terrain and water surface (a sink: a dry cell at this cell's terrain
        // height; an open border: a dry cell continuing the slope from the opposite neighbour,
        // never above this cell, so that water runs off a slope as it would beyond the region);
        // None where no pipe runs (a closed border).
        let other = |k: usize| -> Option<(f64, f64)> {
            match grid.neighbour(i, k) {
                Some(n) if !grid.is_sink(n) => {
                    let hn = self.height_m(n);
                    Some((hn, hn + self.depth_m(n)))
                }
                Some(_) => Some((h, h)),
                None if open => {
                    let opposite =
                        grid.neighbour(i, k ^ 1).filter(|n| !grid.is_sink(*n)).map_or(h, |n| self.height_m(n));
                    let beyond = h.min(2.0 * h - opposite);
                    Some((beyond, beyond))
                }
                None => None,
            }
        };
        let mut total_m3 = 0.0;
        for (k, f) in flux.iter_mut().enumerate() {
            let Some((_, surface)) = other(k) else { continue };
            let l = grid.pipe_length_m(i, k);
            let (dx, dy) = PIPES[k];
            let across = match (dx, dy) {
                (0, _) => grid.dx_m[i],
                (_, 0) => grid.dy_m[i],
                _ => 0.5 * l,
            };
            let section = grid.pipe_weight[k] * across * d;
            let kept = self.state.flux_m3_s[i][k] * (1.0 - (self.params.friction_per_s * dt).min(1.0));
            *f = (kept + dt * g * section * (h + d - surface) / l).max(0.0);
            total_m3 += *f * dt;
        }
        let held_m3 = self.state.water[i] as f64 * self.unit_m3;
        if total_m3 > held_m3 {
            let scale = if total_m3 > 0.0 { held_m3 / total_m3 } else { 0.0 };
            for f in &mut flux {
                *f *= scale;
            }
        }
        let water = self.state.water[i];
        let mut sent = 0;
        for k in 0..8 {
            let units = self.round(flux[k] * dt / self.unit_m3, i, dither::PIPE + k as u32);
            out.water[k] = units.clamp(0, water - sent);
            sent += out.water[k];
        }
        if water > 0 {
            // In proportion to the water sent (the GPU in f32: each share is held to what is
            // left, so the shares never sum past the sediment held).
            let sediment = self.state.sediment[i];
            let mut sent = 0;
            for k in 0..8 {
                let share = (i128::from(sediment) * i128::from(out.water[k]) / i128::from(water)) as i64;
                out.sediment[k] = share.min(sediment - sent);
                sent += out.sediment[k];
            }
        }
        // Thermal sliding towards lower neighbours beyond the talus angle.
        let rate = (self.params.thermal_per_s * dt).min(1.0) / self.hardness(i);
        if rate > 0.0 {
            let tan = self.params.talus_deg.to_radians().tan();
            let weights: f64 = grid.pipe_weight.iter().sum();
            for k in 0..8 {
                let Some(n) = grid.neighbour(i, k).filter(|n| !grid.is_sink(*n)) else { continue };
                let excess = h - self.height_m(n) - grid.pipe_length_m(i, k) * tan;
                if excess > 0.0 {
                    let volume_m3 = rate * grid.pipe_weight[k] / weights * 0.5 * excess * grid.area_m2[i];
                    out.soil[k] = (volume_m3 / self.unit_m3).floor().min(MAX_UNITS as f64) as i64;
                }
            }
            // The terrain's change stays within the units a cell may hold, and what it sends
            // within one cell's worth (so that what a cell receives fits the GPU's i32).
            let sum: i64 = out.soil.iter().sum();
            let room = (self.state.soil[i] + MAX_UNITS).clamp(0, MAX_UNITS);
            if sum > room {
                let mut sent = 0;
                for s in &mut out.soil {
                    *s = ((i128::from(*s) * i128::from(room) / i128::from(sum)) as i64).min(room - sent);
                    sent += *s;
                }
            }
        }
        (out, flux)
    }

    fn hardness(&self, i: usize) -> f64 {
        self.grid.hardness.as_ref().map_or(self.params.hardness, |h| h[i].max(1.0))
    }

    /// Pass 2 at cell `i`: its new water, sediment and soil, its speed, and what it adds to the
    /// budget.
    fn update(&self, i: usize, dt: f64, outflows: &[(Outflow, [f64; 8])]) -> (i64, i64, i64, f64, Budget) {
        let grid = &self.grid;
        let mut budget = Budget::default();
        // What flows in: each neighbour's transfer through its pipe towards this cell.
        let (mut water_in, mut sediment_in, mut soil_in) = (0i64, 0i64, 0i64);
        let (mut flow_x, mut flow_y) = (0.0, 0.0);
        for k in 0..8 {
            if let Some(n) = grid.neighbour(i, k) {
                let back = &outflows[n].0;
                water_in += back.water[k ^ 1];
                sediment_in += back.sediment[k ^ 1];
                soil_in += back.soil[k ^ 1];
                let (dx, dy) = PIPES[k];
                let net = (outflows[i].0.water[k] - back.water[k ^ 1]) as f64;
                flow_x += net * f64::from(dx);
                flow_y += net * f64::from(dy);
            }
        }
        let own = &outflows[i].0;
        let sent_water: i64 = own.water.iter().sum();
        let sent_sediment: i64 = own.sediment.iter().sum();
        let sent_soil: i64 = own.soil.iter().sum();
        if grid.is_sink(i) {
            // Everything that flows in leaves the run here.
            budget.water_out += water_in;
            budget.soil_out += sediment_in + soil_in;
            return (0, 0, 0, 0.0, budget);
        }
        // Through an open border: what went out through pipes with no cell beyond.
        for k in 0..8 {
            if grid.neighbour(i, k).is_none() {
                budget.water_out += own.water[k];
                budget.soil_out += own.sediment[k];
            }
        }
        let before = self.state.water[i];
        let mut water = before - sent_water + water_in;
        let mut sediment = self.state.sediment[i] - sent_sediment + sediment_in;
        let mut soil = self.state.soil[i] - sent_soil + soil_in;
        // Velocity: the net flow through the cell over its mean depth.
        let area = grid.area_m2[i];
        let mean_depth = 0.5 * (before + water) as f64 * self.unit_m3 / area;
        let speed = if dt <= 0.0 {
            0.0
        } else {
            // The discharge per unit width through the cell, m²/s.
            let qx = 0.5 * flow_x * self.unit_m3 / dt / grid.dy_m[i];
            let qy = 0.5 * flow_y * self.unit_m3 / dt / grid.dx_m[i];
            speed_m_s((qx * qx + qy * qy).sqrt(), mean_depth)
        };
        // Capacity (a depth of sediment, at most the water's): speed, slope and depth.
        let slope = self.sin_slope(i).max(self.params.min_slope);
        let capacity_m =
            (self.params.capacity * slope * speed * mean_depth.min(self.params.capacity_depth_m)).min(mean_depth);
        let carried_m = sediment as f64 * self.unit_m3 / area;
        let erodes = grid.erosion_mask.as_ref().map_or(1.0, |m| m[i].clamp(0.0, 1.0));
        if capacity_m > carried_m {
            let rate = (self.params.dissolve_per_s * dt).min(1.0) * erodes / self.hardness(i);
            let taken = self
                .round((capacity_m - carried_m) * rate * area / self.unit_m3, i, dither::DISSOLVE)
                .min(soil + MAX_UNITS)
                .max(0);
            soil -= taken;
            sediment += taken;
        } else {
            let rate = (self.params.deposit_per_s * dt).min(1.0);
            let laid = self
                .round((carried_m - capacity_m) * rate * area / self.unit_m3, i, dither::DEPOSIT)
                .clamp(0, sediment);
            sediment -= laid;
            soil += laid;
        }
        // Evaporation; water gone, its sediment settles.
        let evaporated = self
            .round(water as f64 * (self.params.evaporation_per_s * dt).min(1.0), i, dither::EVAPORATE)
            .clamp(0, water);
        water -= evaporated;
        budget.evaporated += evaporated;
        if water == 0 && sediment > 0 {
            soil += sediment;
            sediment = 0;
        }
        // Rain (for the next step's outflows), within the units a cell may hold.
        let mask = grid.rain_mask.as_ref().map_or(1.0, |m| m[i].clamp(0.0, 1.0));
        let rain = self
            .round(self.params.rain_m_s * dt * mask * area / self.unit_m3, i, dither::RAIN)
            .min(MAX_UNITS - water)
            .max(0);
        water += rain;
        budget.rain_in += rain;
        // Beyond what a cell may hold: water and soil spill out of the run (counted), sediment
        // settles.
        if water > MAX_UNITS {
            budget.water_out += water - MAX_UNITS;
            water = MAX_UNITS;
        }
        if sediment > MAX_UNITS {
            soil += sediment - MAX_UNITS;
            sediment = MAX_UNITS;
        }
        if soil > MAX_UNITS {
            budget.soil_out += soil - MAX_UNITS;
            soil = MAX_UNITS;
        }
        (water, sediment, soil, speed, budget)
    }

    /// sin α of the terrain's slope at cell `i` (central differences; a missing or no-data
    /// neighbour is replaced by the cell itself).
    fn sin_slope(&self, i: usize) -> f64 {
        let grid = &self.grid;
        let h = self.height_m(i);
        let at = |k: usize| grid.neighbour(i, k).filter(|n| !grid.is_sink(*n)).map_or(h, |n| self.height_m(n));
        let gx = (at(0) - at(1)) / (2.0 * grid.dx_m[i]);
        let gy = (at(2) - at(3)) / (2.0 * grid.dy_m[i]);
        let tan = (gx * gx + gy * gy).sqrt();
        tan / (1.0 + tan * tan).sqrt()
    }
}
