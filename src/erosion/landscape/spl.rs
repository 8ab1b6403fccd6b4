//! River incision by the stream-power law, E = K·A^m·S^n, solved implicitly along the routing
//! (Braun & Willett 2013): cells are taken receiver first, so the receiver's new height is known
//! when its donor's is solved, and the step is stable for any Δt.
//!
//! For a cell i draining to r over a distance d, with F = K·Δt·A^m / d^n and δ₀ = h_i − h_r
//! (h_r already updated), the new drop δ solves δ − δ₀ + F·δ^n = 0: for n = 1,
//! δ = δ₀ / (1 + F); otherwise by Newton's method from δ₀ (the function is increasing and convex
//! on (0, δ₀] for n > 1, so the iterates decrease monotonically to the root). A cell not above
//! its receiver (one routed out of a depression or across a flat) does not incise, as in
//! fastscapelib's `SPLEroder`. The CPU path is the reference.
//!
//! With deposition (the ξ-q model of Davy & Lague 2009, as Yuan et al. 2019 solve it and
//! fastscapelib-fortran runs it), ∂h/∂t = U − K·A^m·S^n + (G/A)·Qs, where Qs is the sediment flux
//! through the cell: what the cell and everything upstream of it lose net, ∫(U − ∂h/∂t) dA. The
//! flux depends on the new heights upstream, which the receiver-first order solves after the
//! cell, so the step is iterated (Gauss–Seidel): heights receiver first with the fluxes of the
//! last pass, then the fluxes donor first from the new heights, until no height moves by more
//! than a micrometre. With the cell's own loss inside Qs the equation stays implicit in it:
//! with c = G·a/A (a the cell's own area) and V the flux entering from its donors over the step,
//! the drop solves δ − δ₀' + F/(1 + c)·δ^n = 0 with δ₀' = δ₀ + G·V/(A·(1 + c)). At steady state
//! under uniform uplift Qs = U·A, so rivers must cut (1 + G)·U: slopes steepen by (1 + G)^(1/n),
//! Yuan et al.'s closed form, which the tests check.

use super::flow::{Flow, Spread};

/// The stream-power parameters of one step.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct StreamPower {
    /// Erodibility K, in m^(1−2m)/yr (for n = 1).
    pub k: f64,
    /// The area exponent m.
    pub m: f64,
    /// The slope exponent n.
    pub n: f64,
}

impl StreamPower {
    /// F = K·Δt·A^m / d^n of cell `i` draining along `flow`.
    pub fn factor(&self, flow: &Flow, i: usize, dt_years: f64) -> f64 {
        let d = flow.distance_m[i];
        let dn = if self.n == 1.0 { d } else { d.powf(self.n) };
        self.k * dt_years * flow.area_m2[i].powf(self.m) / dn
    }
}

/// The drop δ that solves δ − δ₀ + F·δ^n = 0 on (0, δ₀].
pub fn drop_after(delta0: f64, f: f64, n: f64) -> f64 {
    if n == 1.0 {
        return delta0 / (1.0 + f);
    }
    let mut delta = delta0;
    for _ in 0..100 {
        let g = delta - delta0 + f * delta.powf(n);
        let slope = 1.0 + n * f * delta.powf(n - 1.0);
        let next = (delta - g / slope).max(delta * 1e-3);
        if (next - delta).abs() <= 1e-12 * delta0 {
            return next;
        }
        delta = next;
    }
    delta
}

/// Incises `heights` for `dt_years` along `flow`; returns each cell's incision, metres (≥ 0).
pub fn incise(flow: &Flow, heights: &mut [f64], law: StreamPower, dt_years: f64) -> Vec<f64> {
    let mut eroded = vec![0.0; heights.len()];
    for &i in &flow.order {
        let r = flow.receiver[i];
        if r == i {
            continue;
        }
        // Not above its receiver (routed out of a depression or across a flat): no incision.
        let level = heights[r];
        let delta0 = heights[i] - level;
        if delta0 <= 0.0 {
            continue;
        }
        let new = level + drop_after(delta0, law.factor(flow, i, dt_years), law.n);
        eroded[i] = heights[i] - new;
        heights[i] = new;
    }
    eroded
}

/// The most Gauss–Seidel passes of one step with deposition.
pub const DEPOSITION_PASSES: usize = 200;

/// The sediment of one step with deposition: how it is routed, and what entered each cell over
/// the last step (the next step's first guess).
pub struct Sediment<'a> {
    /// With multiple flow directions, their shares (sediment follows the water, so that
    /// Qs = U·A at steady state); None: down the receivers.
    pub spread: Option<&'a Spread>,
    /// The sediment that entered each cell from its donors over the step, m³: the last step's
    /// on entry (scaled by the caller to this step's length; zeros at first), this step's on
    /// return.
    pub inflow: &'a mut Vec<f64>,
}

/// Incises `heights` for `dt_years` along `flow` with ξ-q deposition of coefficient `g`
/// (`cell_area_m2`: each cell's own area); returns what settled on each cell, metres (G·V/A of
/// the flux V through it over the step; its incision is the fall of its height plus that).
pub fn incise_and_deposit(
    flow: &Flow,
    cell_area_m2: &[f64],
    heights: &mut [f64],
    law: StreamPower,
    dt_years: f64,
    g: f64,
    sediment: Sediment,
) -> Vec<f64> {
    let start = heights.to_vec();
    let inflow = sediment.inflow;
    inflow.resize(heights.len(), 0.0);
    // F of every cell, once for all passes.
    let mut factor = vec![0.0; heights.len()];
    for &i in &flow.order {
        if flow.receiver[i] != i {
            factor[i] = law.factor(flow, i, dt_years);
        }
    }
    for pass in 1..=DEPOSITION_PASSES {
        let mut moved = 0f64;
        for &i in &flow.order {
            let r = flow.receiver[i];
            if r == i {
                continue;
            }
            let a = flow.area_m2[i];
            let c = g * cell_area_m2[i] / a;
            let raise = g * inflow[i] / (a * (1.0 + c));
            let level = heights[r];
            let delta0 = start[i] + raise - level;
            let new = if delta0 <= 0.0 || start[i] <= level {
                // Not above its receiver: no incision, only what settles.
                start[i] + raise
            } else {
                level + drop_after(delta0, factor[i] / (1.0 + c), law.n)
            };
            moved = moved.max((new - heights[i]).abs());
            heights[i] = new;
        }
        inflow.fill(0.0);
        let out = |i: usize, inflow: &[f64]| (inflow[i] + (start[i] - heights[i]) * cell_area_m2[i]).max(0.0);
        match sediment.spread {
            None => {
                for &i in flow.order.iter().rev() {
                    let r = flow.receiver[i];
                    if r != i {
                        inflow[r] += out(i, inflow);
                    }
                }
            }
            Some(spread) => {
                for &i in &spread.order {
                    let here = out(i, inflow);
                    for &(j, w) in spread.shares(i) {
                        inflow[j] += here * w;
                    }
                }
            }
        }
        if pass > 1 && moved <= 1e-6 {
            break;
        }
    }
    (0..heights.len())
        .map(|i| {
            if flow.receiver[i] == i {
                return 0.0;
            }
            let through = (inflow[i] + (start[i] - heights[i]) * cell_area_m2[i]).max(0.0);
            g * through / flow.area_m2[i]
        })
        .collect()
}
