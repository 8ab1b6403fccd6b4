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

use super::flow::Flow;

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
        let f = law.k * dt_years * flow.area_m2[i].powf(law.m) / flow.distance_m[i].powf(law.n);
        let new = level + drop_after(delta0, f, law.n);
        eroded[i] = heights[i] - new;
        heights[i] = new;
    }
    eroded
}
