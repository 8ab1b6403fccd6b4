//! `terrafuse bench shards`: a sharded import run with 1, 2, 4… shard processes at once against
//! one process, the merge and the pyramid timed apart, and a projection to a cluster from the
//! measured costs.

use super::harness::timed;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::Command;

use crate::cli::CliError;
use crate::cli::Context;

type Result<T> = std::result::Result<T, CliError>;

/// Returns a failed run's message.
macro_rules! bail {
    ($($arg:tt)*) => {
        return Err(CliError::Run(format!($($arg)*)))
    };
}

use crate::ecm::grid::{GRID, spacing_m};
use crate::store::Store;
use crate::store::merge::{MergeOptions, merge};
use crate::store::shard::Manifest;

/// What `terrafuse bench shards` is given.
#[derive(Clone, Debug)]
pub struct ShardBenchSettings {
    /// The source raster.
    pub source: PathBuf,
    /// The body.
    pub body: String,
    /// The level.
    pub level: String,
    /// Shard counts to run, each with all its shards at once.
    pub shards: Vec<usize>,
    /// Threads per shard process.
    pub threads: usize,
    /// Work folder.
    pub work: PathBuf,
    /// Nodes and cores per node of the cluster projected to.
    pub nodes: usize,
    /// Cores per node.
    pub cores: usize,
    /// Output samples of the projected import (default: SRTM 3″, 872 tiles of 6000², at its
    /// level).
    pub projected_samples: f64,
}

fn run_ok(cmd: &mut Command) -> Result<String> {
    let out = cmd.output().with_context(|| format!("cannot run {:?}", cmd.get_program()))?;
    if !out.status.success() {
        bail!("{:?} failed: {}", cmd, String::from_utf8_lossy(&out.stderr));
    }
    Ok(String::from_utf8_lossy(&out.stdout).into_owned())
}

/// Runs the benchmark and returns its report.
pub fn bench_shards(s: &ShardBenchSettings, progress: &mut dyn FnMut(&str)) -> Result<String> {
    let exe = std::env::current_exe().context("cannot find this terrafuse executable")?;
    std::fs::create_dir_all(&s.work).with_context(|| format!("{}: cannot create", s.work.display()))?;
    let src = s.source.to_string_lossy().into_owned();
    let threads = s.threads.to_string();
    let mut out = String::new();

    // One process, the reference.
    let single = s.work.join("single.gpkg");
    let _ = std::fs::remove_file(&single);
    progress("one process…");
    let (summary, single_s) = timed(|| {
        run_ok(Command::new(&exe).args(["import", &src, "--body", &s.body, "--max-level", &s.level]).args([
            "--store",
            &single.to_string_lossy(),
            "--threads",
            &threads,
            "--quiet",
        ]))
    });
    let summary = summary?;
    let store = Store::open_read_only(&single)?;
    let d = store.resolve_dataset(None)?;
    let level = d.settings.finest_level;
    let finest_quads = store.finished_quads(&d.name, level)?.len();
    let samples = finest_quads as f64 * f64::from(GRID * GRID);
    let body = *store.body();
    let _ = writeln!(
        out,
        "bench shards: {} → level {level} ({:.1} m), {finest_quads} quads, {:.1} M samples; {} thread(s) per process",
        s.source.display(),
        spacing_m(&body, level),
        samples / 1e6,
        s.threads
    );
    let finest_line = summary.lines().find(|l| l.starts_with("finest level")).unwrap_or("").to_owned();
    let _ = writeln!(out, "one process: {single_s:.2} s in all ({finest_line})");
    let _ = writeln!(
        out,
        "{:>6} {:>9} {:>10} {:>10} {:>9} {:>9} {:>12} {:>10}",
        "shards", "plan s", "shards s", "merge s", "pyramid s", "total s", "M samples/s", "speed-up"
    );
    let mut per_sample_cpu = f64::NAN;
    let mut merge_per_tile = f64::NAN;
    let mut pyramid_per_tile = f64::NAN;
    for &n in &s.shards {
        let dir = s.work.join(format!("shards-{n}"));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).map_err(CliError::file(&dir, "cannot create"))?;
        let manifest = dir.join("plan.json");
        progress(&format!("{n} shards…"));
        let (planned, plan_s) = timed(|| {
            run_ok(Command::new(&exe).args(["import", &src, "--body", &s.body, "--max-level", &s.level]).args([
                "--plan",
                &manifest.to_string_lossy(),
                "--shards",
                &n.to_string(),
            ]))
        });
        planned?;
        Manifest::load(&manifest)?;
        let (ran, shards_s) = timed(|| -> Result<()> {
            let children: Vec<_> = (0..n)
                .map(|i| {
                    Command::new(&exe)
                        .args(["import", "--manifest", &manifest.to_string_lossy(), "--shard", &i.to_string()])
                        .args(["--store", &dir.join(format!("part-{i}.gpkg")).to_string_lossy(), "--threads", &threads])
                        .arg("--quiet")
                        .stdout(std::process::Stdio::null())
                        .spawn()
                })
                .collect::<std::result::Result<_, _>>()
                .context("cannot start a shard")?;
            for mut c in children {
                if !c.wait().context("a shard did not finish")?.success() {
                    bail!("a shard of {} failed", manifest.display());
                }
            }
            Ok(())
        });
        ran?;
        let parts: Vec<PathBuf> = (0..n).map(|i| dir.join(format!("part-{i}.gpkg"))).collect();
        let merged = dir.join("merged.gpkg");
        let r = merge(&MergeOptions { store: merged, parts, threads: Some(s.threads), progress: false, watch: None })?;
        let total = plan_s + shards_s + r.seconds_merge + r.seconds_pyramid;
        let _ = writeln!(
            out,
            "{n:>6} {plan_s:>9.2} {shards_s:>10.2} {:>10.2} {:>9.2} {total:>9.2} {:>12.2} {:>10.2}",
            r.seconds_merge,
            r.seconds_pyramid,
            samples / shards_s / 1e6,
            single_s / total
        );
        if n == 1 {
            per_sample_cpu = shards_s * s.threads as f64 / samples;
        }
        let tiles: u64 = r.merged.iter().map(|m| m.1).sum();
        merge_per_tile = r.seconds_merge / tiles.max(1) as f64;
        let pyramid_tiles: u64 = r.levels.iter().map(|l| l.1).sum();
        pyramid_per_tile = r.seconds_pyramid * s.threads as f64 / pyramid_tiles.max(1) as f64;
    }
    projection(&mut out, s, per_sample_cpu, merge_per_tile, pyramid_per_tile);
    Ok(out)
}

fn projection(out: &mut String, s: &ShardBenchSettings, per_sample: f64, merge_tile: f64, pyramid_tile: f64) {
    let cores = (s.nodes * s.cores) as f64;
    let samples = s.projected_samples;
    let tiles = samples / f64::from(GRID * GRID);
    // Tiles with data per level fall by 4 each level up: the pyramid has a third of the finest.
    let pyramid_tiles = tiles / 3.0;
    let finest_min = samples * per_sample / cores / 60.0;
    let merge_min = tiles * merge_tile / 60.0;
    let pyramid_min = pyramid_tiles * pyramid_tile / s.cores as f64 / 60.0;
    // SRTM 3″ is 58 GiB of source (the paper's figure), read once by the shards over the
    // shared file system; 5 GB/s aggregate is assumed here, not measured.
    let read_min = 58.0 * f64::from(1u32 << 30) / 5e9 / 60.0;
    let _ = writeln!(
        out,
        "measured: {:.0} ns of CPU per finest-level sample, {:.2} ms per tile merged, {:.1} ms of CPU per pyramid tile",
        per_sample * 1e9,
        merge_tile * 1e3,
        pyramid_tile * 1e3
    );
    let _ = writeln!(
        out,
        "projection: {samples:.1e} samples ({tiles:.0} finest tiles) on {} nodes × {} cores: shards {finest_min:.1} min \
         (compute; reading 58 GiB of sources at an assumed 5 GB/s: {read_min:.1} min), merge {merge_min:.1} min (one node, \
         serial), pyramid {pyramid_min:.1} min (one node, {} cores): {:.1} min in all",
        s.nodes,
        s.cores,
        s.cores,
        finest_min.max(read_min) + merge_min + pyramid_min
    );
    let limit = if merge_min + pyramid_min > finest_min.max(read_min) {
        "the merge and the pyramid, serial on one node"
    } else {
        "the shards"
    };
    let one_node = samples * per_sample / s.cores as f64 / 60.0 + pyramid_min;
    let _ = writeln!(out, "limited by: {limit}; one process on one {}-core node: {one_node:.1} min", s.cores);
}

/// SRTM 3″ as the paper imported it: 872 tiles of 6000 × 6000 pixels (≈ 3.1·10¹⁰ samples).
pub const SRTM_SAMPLES: f64 = 872.0 * 6000.0 * 6000.0;
