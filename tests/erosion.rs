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
            let jitter = f64::from(terrafuse::maths::pcg(i as u32) % 1000) / 1000.0;
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
    let params = Params { border: Border::Open, ..Params::unscaled("rain", EARTH_G).unwrap() };
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
    let params = Params {
        rain_m_s: 1e-2,
        evaporation_per_s: 0.0,
        border: Border::Open,
        ..Params::unscaled("rain", EARTH_G).unwrap()
    };
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
    let params = Params { border: Border::Open, ..Params::unscaled("river", EARTH_G).unwrap() };
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

#[test]
fn a_time_scaled_preset_starts_steady_on_the_gpu_as_on_the_cpu_and_cuts_alike() {
    // The `river` preset starts with its rain's steady-state water, computed on the host and
    // uploaded with the state: the GPU's budget counts it as the CPU's does, and after 300 steps
    // both have cut alike.
    let ctx = context();
    let grid = Grid::flat_patch(48, 48, 30.0, rough(48, 48, 25.0));
    let params = Params { border: Border::Open, ..Params::preset("river", EARTH_G).unwrap() };
    let mut cpu = Run::new(grid, params).unwrap().with_seed(4);
    assert!(cpu.budget.start_water > 0);
    let mut gpu = gpu_run(&ctx, &cpu);
    for _ in 0..300 {
        cpu.step();
    }
    gpu.step(300).unwrap();
    let g = gpu.download().unwrap().clone();
    assert_eq!(g.budget.start_water, cpu.budget.start_water);
    assert_eq!(g.unexplained(), (0, 0), "{:?}", g.budget);
    assert_eq!(cpu.unexplained(), (0, 0));
    let moved = |run: &Run| run.delta_m().iter().map(|v| v.abs()).sum::<f64>() / run.grid.len() as f64;
    let (c, q) = (moved(&cpu), moved(&g));
    assert!(c > 1e-3 && (c - q).abs() <= 0.05 * c, "mean |Δh|: CPU {c} GPU {q}");
}

fn erode(args: &[&str]) -> std::process::Output {
    common::terrafuse(&[&["erode"], args].concat(), "")
}

#[test]
fn the_erzurum_session_replays_bit_for_bit_and_reopens_from_its_cache() {
    use terrafuse::layers::LayerKind;
    use terrafuse::project::Project;
    use terrafuse::scene::Scene;
    let dir = common::out_path("erosion-sample");
    let _ = std::fs::remove_dir_all(&dir);
    // Opening the sample built its erosion layer from its two runs and cached it.
    let path = common::sample_project("erzurum-erosion", &dir);
    let project = Project::load(&path).unwrap();
    let index = project.layers.iter().position(|l| l.kind() == LayerKind::Erosion).expect("the sample's erosion layer");
    assert_eq!(project.layers[index].runs().len(), 2);
    let (cached, report) = Scene::open(&project).unwrap();
    assert!(report.edits.iter().any(|l| l.contains("2 runs read from")), "{:?}", report.edits);
    let raster = |s: &Scene| s.edits[&s.stack.layers[index].uid].clone();
    let from_cache = raster(&cached);
    // Rebuilt from the runs without the cache: the same tiles, bit for bit (the CPU reference).
    let mut fresh = Scene::open(&project).unwrap().0;
    fresh.edit_cache_dir = None;
    fresh.attach_edit(index).unwrap();
    let rebuilt = raster(&fresh);
    assert!(*rebuilt == *from_cache, "a rebuild differs from the cache");
    // Four quads of level 10 changed, by metres on the steep slopes; the layer is composed into the
    // terrain: the sum over the stack differs from the dataset alone there.
    assert_eq!(rebuilt.level, 10);
    assert_eq!(rebuilt.tiles.len(), 4);
    let (lo, hi) = rebuilt.range_m();
    assert!(lo < -1.0 && hi > 1.0, "{lo} … {hi} m");
    let q = *rebuilt.tiles.keys().next().unwrap();
    let with = cached.heights_cpu(q).unwrap();
    let without = cached.below(index).unwrap().heights_cpu(q).unwrap();
    let tile = rebuilt.tile(q).unwrap();
    for k in (0..with.len()).step_by(97) {
        assert!(
            (with[k] - (without[k] + tile[k])).abs() < 1e-3,
            "sample {k}: {} vs {} + {}",
            with[k],
            without[k],
            tile[k]
        );
    }
}

#[test]
fn terrafuse_erode_runs_reports_json_undoes_redoes_and_refuses_bad_input_untouched() {
    let dir = common::out_path("erosion-cli");
    let _ = std::fs::remove_dir_all(&dir);
    let path = common::sample_project("erzurum", &dir);
    let p = path.to_str().unwrap();
    let region = "40.50,39.60,40.53,39.62";
    let out = erode(&[
        p, "--layer", "wash", "--create", "--region", region, "--level", "9", "--steps", "30", "--seed", "4", "--cpu",
        "--json",
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    for field in [
        "steps",
        "simulated_s",
        "water_unexplained_rel",
        "soil_unexplained_rel",
        "water_out_m3",
        "soil_out_m3",
        "seconds",
    ] {
        assert!(v.get(field).is_some_and(|x| x.is_number()), "JSON field {field}: {v}");
    }
    assert_eq!(v["steps"], 30);
    assert_eq!(v["water_unexplained_rel"], 0.0);
    assert_eq!(v["soil_unexplained_rel"], 0.0);
    assert!(v["simulated_s"].as_f64().unwrap() > 0.0 && v["rain_m3"].as_f64().unwrap() > 0.0, "{v}");
    // The box rounded out to whole quads of level 9 (256 cells each).
    let cells = v["cells"].as_array().unwrap();
    assert!(cells.iter().all(|c| c.as_u64().unwrap() % 256 == 0), "{v}");
    let project = terrafuse::project::Project::load(&path).unwrap();
    let layer = project.layers.iter().find(|l| l.name == "wash").unwrap();
    assert_eq!(layer.runs().len(), 1);
    assert_eq!(layer.runs()[0].steps, 30);
    // Undo, then redo: the layer comes back from its cache.
    let undo = erode(&[p, "--layer", "wash", "--undo", "1"]);
    assert!(undo.status.success(), "{}", String::from_utf8_lossy(&undo.stderr));
    let redo = erode(&[p, "--layer", "wash", "--redo", "1"]);
    let text = String::from_utf8_lossy(&redo.stdout);
    assert!(redo.status.success() && text.contains("1 runs read from"), "{text}");
    // Bad input: a clear error naming the flag, and the file untouched.
    let before = std::fs::read(&path).unwrap();
    for (args, expect) in [
        (
            vec!["--region", "40.5,39.7,40.6,39.6", "--level", "9", "--steps", "5"],
            "--region: south 39.7 and north 39.6",
        ),
        // The old LAT,LON order on the Erzurum sample: a valid box, but in Iran, where nothing lies.
        (
            vec!["--region", "39.60,40.50,39.62,40.53", "--level", "9", "--steps", "5"],
            "no data in 39.6,40.5,39.62,40.53",
        ),
        (vec!["--region", "30,30,50,60", "--level", "9", "--steps", "5"], "at most 4096"),
        (vec!["--region", region, "--level", "9", "--steps", "0"], "--steps"),
        (vec!["--region", region, "--level", "9", "--steps", "5", "--set", "rain_m_s=5"], "rain_m_s"),
        (vec!["--region", region, "--level", "9", "--steps", "5", "--set", "colour=1"], "--set colour"),
        (
            vec!["--region", region, "--level", "9", "--steps", "5", "--set", "start=wet"],
            "--set start: unknown variant `wet`",
        ),
        (
            vec!["--region", region, "--level", "9", "--steps", "5", "--set", "capacity=abc"],
            "--set capacity: 'abc' is not a number",
        ),
        (vec!["--region", region, "--level", "9", "--steps", "5", "--preset", "lava"], "--preset lava"),
        (vec!["--region", region, "--level", "10", "--steps", "5"], "--level"),
    ] {
        let out = erode(&[&[p, "--layer", "wash", "--cpu"][..], &args].concat());
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(expect), "{args:?}: {err}");
        assert_eq!(std::fs::read(&path).unwrap(), before, "{args:?} changed the project");
    }
    let wrong = erode(&[p, "--layer", "srtm", "--region", region, "--level", "9", "--steps", "5"]);
    assert!(String::from_utf8_lossy(&wrong.stderr).contains("not an erosion layer"));
}

#[test]
fn a_grid_past_the_binding_limit_runs_in_chunks_as_in_one_and_past_four_chunks_is_refused() {
    // As if the device bound 40 000 bytes: the 3072 cells' arrays of 32 bytes a cell go in three
    // chunks of 1024 cells (a power of two within the limit); the run is the same bit for bit as
    // in one binding. A limit that would need twelve chunks is refused, naming it.
    let ctx = context();
    let grid = Grid::flat_patch(64, 48, 10.0, rough(64, 48, 8.0));
    let params = Params { border: Border::Open, ..Params::unscaled("rain", EARTH_G).unwrap() };
    let start = Run::new(grid, params).unwrap().with_seed(3);
    let kernel = Arc::new(ErosionKernel::new(&ctx.device).unwrap());
    let mut finals = Vec::new();
    for limit in [u64::MAX, 40_000] {
        let mut gpu = GpuRun::with_binding_limit(&ctx.device, &ctx.queue, kernel.clone(), &start, limit).unwrap();
        gpu.step(60).unwrap();
        let run = gpu.download().unwrap().clone();
        assert_eq!(run.unexplained(), (0, 0));
        finals.push(run);
    }
    assert!(finals[0].state.water.iter().any(|w| *w > 0));
    assert!(finals[0].state == finals[1].state, "the chunked run differs");
    assert_eq!(finals[0].budget, finals[1].budget);
    let refused = GpuRun::with_binding_limit(&ctx.device, &ctx.queue, kernel, &start, 32 * 500).err().unwrap();
    assert!(refused.to_string().contains("binds at most 16000 bytes"), "{refused}");
}
