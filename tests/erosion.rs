//! Erosion on the GPU against the CPU reference (lavapipe in CI): the same steps from the same
//! state agree within the stated tolerance; budgets stay exact on the GPU too, under stress; the
//! GPU repeats itself bit for bit; over long runs the two agree in their budgets and terrain
//! statistics.

mod common;

use std::sync::Arc;

use terrafuse::erosion::grid::Grid;
use terrafuse::erosion::params::{Border, EARTH_G, Params};
use terrafuse::erosion::sim::Run;
use terrafuse::gpu::GpuContext;
use terrafuse::gpu::erosion::{ErosionKernel, GPU_TOLERANCE_M, GpuRun};

fn context() -> GpuContext {
    GpuContext::headless().expect("a GPU adapter (lavapipe in CI: scripts/install-deps, WGPU_BACKEND=vulkan)")
}

/// Rough terrain: waves of `amplitude_m` over a tilt, with a deterministic jitter, metres.
fn rough(width: usize, height: usize, amplitude_m: f64) -> Vec<f64> {
    (0..width * height)
        .map(|i| {
            let (x, y) = ((i % width) as f64, (i / width) as f64);
            let jitter = f64::from(terrafuse::erosion::dither::pcg(i as u32) % 1000) / 1000.0;
            0.5 * x + amplitude_m * ((x / 5.0).sin() + (y / 7.0).cos()) + jitter
        })
        .collect()
}

fn gpu_run(ctx: &GpuContext, run: &Run) -> GpuRun {
    let kernel = Arc::new(ErosionKernel::new(&ctx.device).unwrap());
    GpuRun::new(&ctx.device, &ctx.queue, kernel, run).unwrap()
}

fn largest_difference(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).fold(0f64, |m, (x, y)| m.max((x - y).abs()))
}

fn depths(run: &Run) -> Vec<f64> {
    (0..run.grid.len()).map(|i| run.depth_m(i)).collect()
}

#[test]
fn the_gpu_steps_like_the_cpu_reference_and_keeps_every_unit() {
    let ctx = context();
    // Wet the terrain on the CPU first, so that the compared steps move water and soil.
    let grid = Grid::flat_patch(64, 48, 10.0, rough(64, 48, 8.0));
    let params = Params { border: Border::Open, ..Params::preset("rain", EARTH_G).unwrap() };
    let mut cpu = Run::new(grid, params).unwrap().with_seed(5);
    for _ in 0..40 {
        cpu.step();
    }
    let mut gpu = gpu_run(&ctx, &cpu);
    for _ in 0..100 {
        cpu.step();
    }
    gpu.step(100).unwrap();
    let g = gpu.download().unwrap().clone();
    assert_eq!(g.steps, cpu.steps);
    let dh = largest_difference(&g.delta_m(), &cpu.delta_m());
    let dd = largest_difference(&depths(&g), &depths(&cpu));
    let differing = (0..g.grid.len()).filter(|&i| g.state.water[i] != cpu.state.water[i]).count();
    let moving = (0..g.grid.len()).filter(|&i| cpu.state.flux_m3_s[i].iter().any(|f| *f > 0.0)).count();
    eprintln!(
        "after 100 steps: terrain {dh:.3e} m, water {dd:.3e} m apart ({differing} cells' water differs; {moving} cells send water); simulated {} / {} s",
        g.simulated_s, cpu.simulated_s
    );
    assert!(dh <= GPU_TOLERANCE_M && dd <= GPU_TOLERANCE_M, "terrain {dh} m, water {dd} m apart");
    assert!((g.simulated_s - cpu.simulated_s).abs() <= 1e-4 * cpu.simulated_s, "{} {}", g.simulated_s, cpu.simulated_s);
    assert!(g.budget.rain_in > 0);
    assert_eq!(g.unexplained(), (0, 0), "the GPU's budget explains every unit");
}

#[test]
fn the_gpu_conserves_exactly_under_stress_and_repeats_itself_bit_for_bit() {
    let ctx = context();
    // 1000 m cliffs, a no-data hole, a downpour without evaporation, open borders: 3000 steps.
    let (w, h) = (40, 36);
    let mut base = rough(w, h, 20.0);
    for (i, b) in base.iter_mut().enumerate() {
        if (i % w) % 5 == 0 {
            *b += 1000.0;
        }
    }
    base[17 * w + 9] = f64::NAN;
    let grid = Grid::flat_patch(w, h, 30.0, base);
    let params = Params { rain_m_s: 1e-2, evaporation_per_s: 0.0, border: Border::Open, ..Params::preset("rain", EARTH_G).unwrap() };
    let start = Run::new(grid, params).unwrap().with_seed(9);
    let mut finals = Vec::new();
    for _ in 0..2 {
        let mut gpu = gpu_run(&ctx, &start);
        gpu.step(1500).unwrap();
        gpu.download().unwrap();
        gpu.step(1500).unwrap();
        let run = gpu.download().unwrap().clone();
        assert_eq!(run.steps, 3000);
        assert_eq!(run.unexplained(), (0, 0), "{:?}", run.budget);
        assert!(run.state.water.iter().all(|w| *w >= 0) && run.state.sediment.iter().all(|s| *s >= 0));
        assert!((0..run.grid.len()).all(|i| run.grid.base_m[i].is_nan() || run.height_m(i).is_finite()));
        assert!(run.budget.water_out > 0 && run.budget.soil_out > 0, "{:?}", run.budget);
        assert!(run.simulated_s > 0.0 && run.simulated_s < 3000.0 * run.params.dt_s, "the CFL bound was reached");
        finals.push(run.state);
    }
    assert!(finals[0] == finals[1], "two GPU runs of the same inputs differ");
}

#[test]
fn over_long_runs_the_gpu_and_the_cpu_agree_in_budgets_and_terrain_statistics() {
    let ctx = context();
    let grid = Grid::flat_patch(48, 48, 20.0, rough(48, 48, 15.0));
    let params = Params { border: Border::Open, ..Params::preset("river", EARTH_G).unwrap() };
    let mut cpu = Run::new(grid, params).unwrap().with_seed(2);
    let mut gpu = gpu_run(&ctx, &cpu);
    for _ in 0..2000 {
        cpu.step();
    }
    gpu.step(2000).unwrap();
    let g = gpu.download().unwrap().clone();
    let stats = |run: &Run| {
        let d = run.delta_m();
        let moved = d.iter().map(|v| v.abs()).sum::<f64>() / d.len() as f64;
        let (water, _) = run.totals();
        (moved, water as f64, run.budget.rain_in as f64, run.budget.water_out as f64, run.simulated_s)
    };
    let (c, q) = (stats(&cpu), stats(&g));
    eprintln!("CPU (mean |Δh| m, water, rain, out, s) {c:?}\nGPU {q:?}");
    let near = |a: f64, b: f64, rel: f64| (a - b).abs() <= rel * a.abs().max(b.abs());
    assert!(c.0 > 1e-4, "the run moved soil: {c:?}");
    assert!(near(c.0, q.0, 0.05), "mean |Δh|: CPU {} GPU {}", c.0, q.0);
    assert!(near(c.1, q.1, 0.02), "water held: CPU {} GPU {}", c.1, q.1);
    assert!(near(c.2, q.2, 0.01), "rain: CPU {} GPU {}", c.2, q.2);
    assert!(near(c.3, q.3, 0.05), "water out: CPU {} GPU {}", c.3, q.3);
    assert!(near(c.4, q.4, 0.01), "simulated time: CPU {} GPU {}", c.4, q.4);
    assert_eq!(g.unexplained(), (0, 0));
}
