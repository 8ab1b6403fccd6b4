//! Runs `terrafuse bench …`: each benchmark's tables go to the report, its progress to
//! standard error.

use std::path::PathBuf;

use crate::cli::CliError;
use crate::cli::Console;
use crate::cli::args::parse_numbers;
use crate::cli::bench_args::{Bench, BenchAccuracyArgs, BenchImportArgs, BenchShardsArgs};
use crate::geodesy::Ellipsoid;

/// Runs a benchmark; its tables go to the report, its progress to standard error.
pub fn run(bench: Bench, c: &mut Console) -> Result<u8, CliError> {
    match bench {
        Bench::Replay { strokes, steps, log_strokes, gpu, out } => {
            let settings = super::ReplayBenchSettings { strokes, steps, log_strokes, gpu, out };
            let out = &mut *c.out;
            super::bench_replay(&settings, &mut |part| {
                let _ = write!(out, "{part}").and_then(|()| out.flush());
            })?;
        }
        Bench::Erosion { sizes, steps, cpu_max, gpu, bandwidth_gbs } => {
            let settings = super::ErosionBenchSettings { sizes, steps, cpu_max, gpu, bandwidth_gbs };
            c.print(super::bench_erosion(&settings)?)?;
        }
        Bench::BrushLatency { project, rounds, width, height } => {
            c.print(super::bench_brush_latency(&project, rounds, width, height)?)?;
        }
        Bench::Brush { strokes, level, gpu } => c.print(super::bench_brush(strokes, level, gpu)?)?,
        Bench::CompareSize { project, a, b, levels, procedural, out } => {
            if let Some(l) = levels.iter().find(|&&l| l > crate::ecm::MAX_LEVEL) {
                return Err(format!("--levels: {l} is past the finest level, {}", crate::ecm::MAX_LEVEL).into());
            }
            let table = if procedural {
                let pair = super::compare_large::noise_pair(&out)?;
                super::compare_large::size_table(&pair, ["terrain+error", "terrain"], &levels)?
            } else {
                super::compare_large::size_table(&project, [&a, &b], &levels)?
            };
            std::fs::create_dir_all(&out).map_err(CliError::file(&out, "cannot create the folder"))?;
            let path = out.join("compare-size.txt");
            crate::files::write_atomic(&path, table.as_bytes()).map_err(CliError::file(&path, "cannot write"))?;
            c.print(table)?;
        }
        Bench::Compare { project, size, out } => {
            if !(64..=16384).contains(&size) {
                return Err(format!("--size {size} must lie within 64–16384 pixels").into());
            }
            let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
            let settings = super::CompareBenchSettings {
                project,
                out,
                size,
                python: root.join(".venv-ref/bin/python"),
                reference_dir: root.join("tests/reference"),
            };
            c.print(super::bench_compare(&settings)?)?;
        }
        Bench::Landscape { sizes, steps, out } => {
            if sizes.iter().any(|s| !(3..=8192).contains(s)) || steps == 0 {
                return Err("--sizes must lie within 3–8192 cells and --steps be at least 1".into());
            }
            let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
            let settings = super::LandscapeBenchSettings {
                sizes,
                steps,
                python: root.join(".venv-ref/bin/python"),
                script: root.join("tests/reference/fastscape_run.py"),
                out: out.clone(),
            };
            let table = super::bench_landscape(&settings)?;
            c.print(format_args!("{table}wrote {}\n", out.join("landscape.csv").display()))?;
        }
        Bench::Compose { project, quads, repeats, out } => {
            if quads == 0 || repeats == 0 {
                return Err("--quads and --repeats must be at least 1".into());
            }
            let settings = super::ComposeBenchSettings { project, quads, repeats, out: out.clone() };
            let (_, report) = super::bench_compose(&settings)?;
            c.print(format_args!("{report}wrote {}\n", out.join("compose.csv").display()))?;
        }
        Bench::Render { projects, thresholds, pixel_errors, width, height, frames, out } => {
            if !thresholds.iter().all(|t| t.is_finite() && *t > 0.0) {
                return Err("--thresholds must be positive".into());
            }
            if !pixel_errors.iter().all(|t| t.is_finite() && *t > 0.0) {
                return Err("--pixel-errors must be positive".into());
            }
            let settings = super::RenderBenchSettings {
                projects,
                thresholds,
                pixel_errors,
                width,
                height,
                frames,
                out: out.clone(),
            };
            let (rows, report) = super::bench_render(&settings)?;
            c.print(&report)?;
            let (csv, png) = super::write_render_bench(&out, &rows)?;
            c.print(format_args!("wrote {} and {}\n", csv.display(), png.display()))?;
        }
        Bench::Shards(args) => run_shards(args, c)?,
        Bench::Import { import } => run_import(&import, c)?,
        Bench::Accuracy(args) => run_accuracy(args, c)?,
    }
    Ok(0)
}

/// `terrafuse bench shards`: a sharded import at each number of shards against one process.
fn run_shards(args: BenchShardsArgs, c: &mut Console) -> Result<(), CliError> {
    let BenchShardsArgs { source, body, level, shards, threads, nodes, cores, samples, work } = args;
    let dir = work.clone().unwrap_or_else(crate::cli::default_work_dir);
    let settings = super::ShardBenchSettings {
        source,
        body,
        level,
        shards: shards
            .split(',')
            .map(|n| n.trim().parse::<usize>().map_err(|_| CliError::Usage(format!("--shards: '{n}' is not a number"))))
            .collect::<Result<_, CliError>>()?,
        threads,
        work: dir.clone(),
        nodes,
        cores,
        projected_samples: samples.unwrap_or(super::SRTM_SAMPLES),
    };
    let err = &mut *c.err;
    let report = super::bench_shards(&settings, &mut |line| {
        let _ = writeln!(err, "{line}");
    });
    if work.is_none() {
        let _ = std::fs::remove_dir_all(&dir);
    }
    c.print(report?)?;
    Ok(())
}

/// `terrafuse bench import`: the finest level imported beside gdalwarp's warp of it.
fn run_import(import: &BenchImportArgs, c: &mut Console) -> Result<(), CliError> {
    let work = import.work.clone().unwrap_or_else(crate::cli::default_work_dir);
    let opts = crate::store::ImportOptions {
        sources: vec![import.source.clone()],
        store: work.join("bench-store.gpkg"),
        body: import.body.parse()?,
        name: Some("bench".into()),
        level: import.level.parse()?,
        resampling: crate::store::Resampling::Bilinear,
        transform: crate::store::lattice::Transform::Lattice,
        vertical: crate::store::VerticalDatum::Unspecified,
        memory_budget: 2 << 30,
        threads: Some(import.threads),
        progress: false,
        finest_only: true,
        watch: None,
    };
    let report = super::bench_import(&opts, &work, import.threads.max(1));
    if import.work.is_none() {
        let _ = std::fs::remove_dir_all(&work);
    }
    c.print(report?)?;
    Ok(())
}

/// `terrafuse bench accuracy`: the rendered position's error per approach, body, level and
/// distance, its CSV and plot, and the timings.
fn run_accuracy(args: BenchAccuracyArgs, c: &mut Console) -> Result<(), CliError> {
    let BenchAccuracyArgs {
        bodies,
        levels,
        distances,
        trials,
        vertices,
        seed,
        samples,
        tolerance_m,
        limit_fraction,
        csv,
        plot,
        no_timing,
    } = args;
    let bodies: Vec<Ellipsoid> = split_bodies(&bodies).iter().map(|b| b.parse()).collect::<Result<_, _>>()?;
    if samples < 2 {
        return Err("--samples: a quad needs at least 2 samples per edge".into());
    }
    if !(tolerance_m > 0.0 && limit_fraction >= 0.0) {
        return Err("--tolerance-m must be positive and --limit-fraction 0 or more".into());
    }
    let settings = crate::ecm::accuracy::AccuracySettings {
        levels: parse_levels(&levels)?,
        distances_m: parse_distances(&distances)?,
        trials: trials.max(1),
        random_vertices: vertices,
        seed,
        samples,
        ..Default::default()
    };
    let bench = super::AccuracyBench { bodies: bodies.clone(), settings, tolerance_m, limit_fraction };
    let (report, rows) = super::accuracy_bench(&bench);
    c.print(&report)?;
    super::write_accuracy_outputs(&bench, &rows, &csv, Some(&plot))?;
    c.print(format_args!("\nwrote {} and {}\n", csv.display(), plot.display()))?;
    if !no_timing {
        c.print(super::timing_report(&bodies[0], samples))?;
    }
    Ok(())
}

/// Parses `0-30` or `3,5,7` into levels ≤ 30.
fn parse_levels(text: &str) -> Result<Vec<u8>, CliError> {
    let bad = |_| CliError::from(format!("--levels {text}: give FIRST-LAST or L,L,… (0–30)"));
    let levels: Vec<u8> = if let Some((a, b)) = text.split_once('-') {
        let (a, b): (u8, u8) = (a.trim().parse().map_err(bad)?, b.trim().parse().map_err(bad)?);
        (a..=b).collect()
    } else {
        text.split(',').map(|v| v.trim().parse::<u8>()).collect::<Result<_, _>>().map_err(bad)?
    };
    match levels.iter().find(|&&l| l > crate::ecm::MAX_LEVEL) {
        Some(l) => Err(format!("level {l} is past the deepest level, 30").into()),
        None if levels.is_empty() => Err(format!("no levels in '{text}'").into()),
        None => Ok(levels),
    }
}

/// Parses comma-separated positive distances in metres.
fn parse_distances(text: &str) -> Result<Vec<f64>, CliError> {
    let d = parse_numbers(text, "--distances")?;
    match d.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
        Some(v) => Err(format!("camera distance {v} is not a positive number of metres").into()),
        None => Ok(d),
    }
}

/// Splits a body list at commas that start a new body (`wgs84,moon` but not `a=1,b=2`).
fn split_bodies(text: &str) -> Vec<String> {
    let mut bodies: Vec<String> = Vec::new();
    for part in text.split(',') {
        let starts_new = !part.starts_with("b=") && !part.starts_with("rf=");
        match bodies.last_mut() {
            Some(last) if !starts_new => {
                last.push(',');
                last.push_str(part);
            }
            _ => bodies.push(part.to_string()),
        }
    }
    bodies
}
