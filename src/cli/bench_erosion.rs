//! `terrafuse bench erosion`: cell-steps per second of the erosion step on square grids (the CPU
//! reference; the GPU joins when its kernels exist), the bytes each step moves, and the error
//! against the step size (the same simulated time with Δt, Δt/2 and Δt/4: the largest difference
//! of the final terrain from the Δt/4 run) beside the time each took.

use std::fmt::Write as _;
use std::time::Instant;

use crate::erosion::grid::Grid;
use crate::erosion::params::{Border, EARTH_G, Params};
use crate::erosion::sim::Run;

/// Rough terrain for the benchmark: waves of 50 m over a 10 % tilt, metres.
fn terrain(n: usize, cell_m: f64) -> Vec<f64> {
    (0..n * n)
        .map(|k| {
            let (x, y) = ((k % n) as f64 * cell_m, (k / n) as f64 * cell_m);
            0.1 * x + 50.0 * (x / 300.0).sin() * (y / 400.0).cos()
        })
        .collect()
}

/// Runs the benchmark on grids of `sizes` cells a side, `steps` steps each; returns the report.
pub fn bench_erosion(sizes: &[usize], steps: u64) -> Result<String, String> {
    let mut out = String::new();
    let threads = rayon::current_num_threads();
    let _ = writeln!(
        out,
        "terrafuse bench erosion: the CPU reference ({threads} threads), preset rain on 10 m cells, open borders, {steps} steps per grid"
    );
    let _ = writeln!(out, "grid      cell-steps/s   ns per cell-step   bytes per cell-step (state read + written)");
    // Per cell and step the two passes read and write: water, sediment, soil (i64), 8 fluxes (f64),
    // speed (f64), and the 8 × 3 transfers (i64) written by the first pass and read by the second.
    let bytes = (3 * 8 + 8 * 8 + 8) * 2 + 24 * 8 * 2;
    for &n in sizes {
        let grid = Grid::flat_patch(n, n, 10.0, terrain(n, 10.0));
        let params = Params { border: Border::Open, ..Params::preset("rain", EARTH_G).ok_or("no preset")? };
        let mut run = Run::new(grid, params).map_err(|e| e.to_string())?;
        // Wet it first: the timed steps move water.
        for _ in 0..20 {
            run.step();
        }
        let t = Instant::now();
        for _ in 0..steps {
            run.step();
        }
        let s = t.elapsed().as_secs_f64();
        let cell_steps = (n * n) as f64 * steps as f64;
        let _ = writeln!(out, "{n:>5}²   {:>12.3e}   {:>16.1}   {bytes}", cell_steps / s, s * 1e9 / cell_steps);
    }
    // The error against the step size: 60 s simulated on 128² with Δt = 0.2, 0.1 and 0.05 s.
    let n = 128;
    let mut finals = Vec::new();
    let _ = writeln!(out, "step size (128², 60 s simulated): Δt, steps, seconds, max |Δh − Δh(Δt/4)| m");
    for dt in [0.2, 0.1, 0.05] {
        let grid = Grid::flat_patch(n, n, 10.0, terrain(n, 10.0));
        let params = Params { dt_s: dt, border: Border::Open, ..Params::preset("rain", EARTH_G).ok_or("no preset")? };
        let mut run = Run::new(grid, params).map_err(|e| e.to_string())?;
        let t = Instant::now();
        while run.simulated_s < 60.0 - 1e-9 {
            run.step();
        }
        finals.push((dt, run.steps, t.elapsed().as_secs_f64(), run.delta_m()));
    }
    let reference = finals.last().ok_or("no run")?.3.clone();
    for (dt, steps, s, delta) in &finals {
        let worst = delta.iter().zip(&reference).fold(0f64, |m, (a, b)| m.max((a - b).abs()));
        let _ = writeln!(out, "  Δt {dt:.2} s: {steps} steps, {s:.2} s, {worst:.3e} m");
    }
    Ok(out)
}
