//! `terrafuse bench erosion`: cell-steps per second of the erosion step on square grids (the CPU
//! reference and the GPU kernels), the bytes each step moves, and the error
//! against the step size (the same simulated time with Δt, Δt/2 and Δt/4: the largest difference
//! of the final terrain from the Δt/4 run) beside the time each took.

use super::harness::timed;
use crate::cli::CliError;
use std::fmt::Write as _;

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

/// What `terrafuse bench erosion` runs.
#[derive(Clone, Debug)]
pub struct ErosionBenchSettings {
    /// Grid sizes, cells a side.
    pub sizes: Vec<usize>,
    /// Steps timed per grid.
    pub steps: u64,
    /// The largest grid the CPU reference runs (larger ones: the GPU only).
    pub cpu_max: usize,
    /// Also time the GPU kernels.
    pub gpu: bool,
    /// The device's memory bandwidth, GB/s (for the share of it a step reaches), if known.
    pub bandwidth_gbs: Option<f64>,
}

fn wet_run(n: usize) -> Result<Run, CliError> {
    let grid = Grid::flat_patch(n, n, 10.0, terrain(n, 10.0));
    let params = Params { border: Border::Open, ..Params::unscaled("rain", EARTH_G).ok_or("no preset")? };
    Ok(Run::new(grid, params)?)
}

/// Runs the benchmark; returns the report.
pub fn bench_erosion(settings: &ErosionBenchSettings) -> Result<String, CliError> {
    let mut out = String::new();
    let threads = rayon::current_num_threads();
    let steps = settings.steps;
    let gpu = if settings.gpu { Some(crate::gpu::GpuContext::headless()?) } else { None };
    let _ = writeln!(
        out,
        "terrafuse bench erosion: preset rain on 10 m cells, open borders, {steps} steps per grid after 20 to wet it; CPU reference ({threads} threads){}",
        gpu.as_ref().map(|g| format!(", GPU {}", g.describe())).unwrap_or_default()
    );
    // CPU: per cell and step the two passes read and write water, sediment, soil (i64), 8 fluxes
    // (f64), speed (f64), and the 8 × 3 transfers (i64) written by the first pass and read by
    // the second. GPU: `BYTES_PER_CELL_STEP` (i32 and f32, neighbours' reads from cache).
    let cpu_bytes = (3 * 8 + 8 * 8 + 8) * 2 + 24 * 8 * 2;
    let gpu_bytes = crate::gpu::erosion::BYTES_PER_CELL_STEP;
    let _ = writeln!(
        out,
        "grid      device   cell-steps/s   ns per cell-step   bytes per cell-step   GB/s moved   share of the bandwidth"
    );
    let kernel = match &gpu {
        Some(g) => Some(std::sync::Arc::new(crate::gpu::erosion::ErosionKernel::new(&g.device)?)),
        None => None,
    };
    for &n in &settings.sizes {
        let cell_steps = (n * n) as f64 * steps as f64;
        let row = |out: &mut String, device: &str, s: f64, bytes: u64| {
            let rate = cell_steps / s;
            let gbs = rate * bytes as f64 / 1e9;
            let share = settings.bandwidth_gbs.map_or("—".to_string(), |b| format!("{:.1} %", 100.0 * gbs / b));
            let _ = writeln!(
                out,
                "{n:>5}²   {device:<6}   {rate:>12.3e}   {:>16.2}   {bytes:>19}   {gbs:>10.1}   {share}",
                s * 1e9 / cell_steps
            );
        };
        if n <= settings.cpu_max {
            let mut run = wet_run(n)?;
            for _ in 0..20 {
                run.step();
            }
            let ((), s) = timed(|| {
                for _ in 0..steps {
                    run.step();
                }
            });
            row(&mut out, "cpu", s, cpu_bytes);
        }
        if let (Some(g), Some(k)) = (&gpu, &kernel) {
            let run = wet_run(n)?;
            let mut gr = match crate::gpu::erosion::GpuRun::new(&g.device, &g.queue, k.clone(), &run) {
                Ok(r) => r,
                Err(e) => {
                    let _ = writeln!(out, "{n:>5}²   gpu      not run: {}", crate::errors::chain(&e));
                    continue;
                }
            };
            gr.step(20)?;
            gr.wait()?;
            let (done, s) = timed(|| -> Result<(), CliError> {
                gr.step(steps as u32)?;
                gr.wait()?;
                Ok(())
            });
            done?;
            row(&mut out, "gpu", s, gpu_bytes);
        }
    }
    // The error against the step size: 60 s simulated on 128² with Δt = 0.2, 0.1 and 0.05 s.
    let n = 128;
    let mut finals = Vec::new();
    let _ = writeln!(out, "step size (128², 60 s simulated): Δt, steps, seconds, max |Δh − Δh(Δt/4)| m");
    for dt in [0.2, 0.1, 0.05] {
        let grid = Grid::flat_patch(n, n, 10.0, terrain(n, 10.0));
        let params = Params { dt_s: dt, border: Border::Open, ..Params::unscaled("rain", EARTH_G).ok_or("no preset")? };
        let mut run = Run::new(grid, params)?;
        let ((), s) = timed(|| {
            while run.simulated_s < 60.0 - 1e-9 {
                run.step();
            }
        });
        finals.push((dt, run.steps, s, run.delta_m()));
    }
    let reference = finals.last().ok_or("no run")?.3.clone();
    for (dt, steps, s, delta) in &finals {
        let worst = delta.iter().zip(&reference).fold(0f64, |m, (a, b)| m.max((a - b).abs()));
        let _ = writeln!(out, "  Δt {dt:.2} s: {steps} steps, {s:.2} s, {worst:.3e} m");
    }
    resolution_rows(&mut out)?;
    Ok(out)
}

/// The same terrain (the benchmark's waves and tilt, sampled at cell centres) over 1280 m at
/// 20, 10 and 5 m cells, 120 s of the `rain` preset: each finer run's change of height,
/// averaged over the 20 m cells, against the 20 m run's (correlation, RMS difference over the
/// 20 m run's RMS), and the volumes eroded and deposited.
fn resolution_rows(out: &mut String) -> Result<(), CliError> {
    let _ = writeln!(
        out,
        "resolution (1280 m square, 120 s of rain): cells, grid, steps, seconds, eroded m³, deposited m³, vs 20 m: correlation, RMS diff / RMS"
    );
    let side = 1280.0;
    let mut coarse: Option<Vec<f64>> = None;
    for cell in [20.0, 10.0, 5.0] {
        let n = (side / cell) as usize;
        let base: Vec<f64> = (0..n * n)
            .map(|k| {
                let (x, y) = (((k % n) as f64 + 0.5) * cell, ((k / n) as f64 + 0.5) * cell);
                0.1 * x + 50.0 * (x / 300.0).sin() * (y / 400.0).cos()
            })
            .collect();
        let params =
            Params { dt_s: 0.1, border: Border::Open, ..Params::unscaled("rain", EARTH_G).ok_or("no preset")? };
        let mut run = Run::new(Grid::flat_patch(n, n, cell, base), params)?;
        let ((), run_s) = timed(|| {
            while run.simulated_s < 120.0 - 1e-9 {
                run.step();
            }
        });
        let delta = run.delta_m();
        let area = cell * cell;
        let eroded: f64 = delta.iter().filter(|d| **d < 0.0).map(|d| -d * area).sum();
        // (+ 0.0: an empty sum is −0.0.)
        let deposited: f64 = delta.iter().filter(|d| **d > 0.0).map(|d| d * area).sum::<f64>() + 0.0;
        // Averaged over the 20 m cells.
        let f = (20.0 / cell) as usize;
        let m = n / f;
        let blocks: Vec<f64> = (0..m * m)
            .map(|b| {
                let (bx, by) = (b % m, b / m);
                let mut sum = 0.0;
                for j in 0..f {
                    for i in 0..f {
                        sum += delta[(by * f + j) * n + bx * f + i];
                    }
                }
                sum / (f * f) as f64
            })
            .collect();
        let versus = match &coarse {
            None => {
                coarse = Some(blocks);
                "—".to_string()
            }
            Some(c) => {
                let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
                let (ma, mb) = (mean(c), mean(&blocks));
                let cov: f64 = c.iter().zip(&blocks).map(|(a, b)| (a - ma) * (b - mb)).sum();
                let va: f64 = c.iter().map(|a| (a - ma).powi(2)).sum();
                let vb: f64 = blocks.iter().map(|b| (b - mb).powi(2)).sum();
                let rms = (c.iter().map(|a| a * a).sum::<f64>() / c.len() as f64).sqrt();
                let diff = (c.iter().zip(&blocks).map(|(a, b)| (a - b).powi(2)).sum::<f64>() / c.len() as f64).sqrt();
                format!("{:.3}, {:.2}", cov / (va * vb).sqrt(), diff / rms)
            }
        };
        let _ = writeln!(
            out,
            "  {cell:>4} m   {n}²   {}   {:.1}   {eroded:.2}   {deposited:.2}   {versus}",
            run.steps, run_s
        );
    }
    Ok(())
}
