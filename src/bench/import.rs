//! `terrafuse bench import`: our import of the finest level against gdalwarp into the same grid,
//! with throughput, peak memory and the difference between the two.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::cli::{lattice_line, store_difference};
use crate::ecm::Face;
use crate::ecm::grid::{self, TILE};
use crate::store::gpkg::{Store, face_proj};
use crate::store::import::peak_rss_bytes;
use crate::store::lattice::Transform;
use crate::store::{GridReader, ImportOptions, ImportReport, StoreError, import};

/// `terrafuse bench import`: our import of the finest level against gdalwarp into the same
/// grid (pixel centres on our samples), with throughput, peak memory and their difference.
pub fn bench_import(opts: &ImportOptions, work: &Path, threads: usize) -> Result<String, StoreError> {
    std::fs::create_dir_all(work).map_err(|e| StoreError::new(work, e.to_string()))?;
    // Ours twice: positions on the lattice (the default) and exact.
    let run = |transform: Transform| -> Result<(ImportReport, f64, PathBuf), StoreError> {
        let store_path = work.join(format!("bench-{}.gpkg", transform.name()));
        let _ = std::fs::remove_file(&store_path);
        let mut opts = opts.clone();
        opts.store = store_path.clone();
        opts.finest_only = true;
        opts.progress = false;
        opts.threads = Some(threads);
        opts.transform = transform;
        let t = Instant::now();
        let report = import(&opts)?;
        Ok((report, t.elapsed().as_secs_f64(), store_path))
    };
    let (report, ours_s, store_path) = run(Transform::Lattice)?;
    let ours_rss = peak_rss_bytes();
    let (_, exact_s, exact_path) = run(Transform::Exact)?;
    let level = report.finest_level;
    let store = Store::open_read_only(&store_path)?;
    let quads = store.finished_quads(&report.dataset, level)?;
    let ours_samples = quads.len() as u64 * u64::from(TILE * TILE);
    let (lattice_mean, lattice_max, lattice_n, data_differs) =
        store_difference(&store, &Store::open_read_only(&exact_path)?, &report.dataset, level)?;

    let mut rows = Vec::new();
    for (label, mode) in
        [("gdalwarp (default -et 0.125)", WarpMode::Default), ("gdalwarp -et 0 (exact)", WarpMode::Exact)]
    {
        let c = warp_comparison(
            &store,
            &report.dataset,
            level,
            &opts.sources,
            opts.resampling.name(),
            mode,
            threads,
            work,
            &Face::ALL,
        )?;
        rows.push((label, c.seconds, c.pixels, (c.mean_m * c.compared as f64, c.max_m, c.compared)));
    }
    let warp_rss = children_peak_rss_bytes();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "bench import: {} → level {level} ({} quads, {threads} threads)",
        opts.sources[0].display(),
        quads.len()
    );
    let _ = writeln!(
        out,
        "{:<30} {:>9} {:>14} {:>13} {:>10} {:>22}",
        "tool", "seconds", "output samples", "M samples/s", "peak MiB", "|lattice − it| mean/max m"
    );
    let mib = |b: u64| b as f64 / (1u64 << 20) as f64;
    for (label, secs, diff) in [
        ("terrafuse (lattice, default)", ours_s, "-".to_owned()),
        ("terrafuse --transform exact", exact_s, format!("{lattice_mean:.2e} / {lattice_max:.2e}")),
    ] {
        let _ = writeln!(
            out,
            "{label:<30} {secs:>9.3} {ours_samples:>14} {:>13.3} {:>10.0} {diff:>22}",
            ours_samples as f64 / secs / 1e6,
            mib(ours_rss),
        );
    }
    for (label, secs, pixels, (sum, max, n)) in &rows {
        let _ = writeln!(
            out,
            "{:<30} {:>9.3} {:>14} {:>13.3} {:>10.0} {:>22}",
            label,
            secs,
            pixels,
            *pixels as f64 / secs / 1e6,
            mib(warp_rss),
            format!("{:.2e} / {:.2e}", sum / (*n).max(1) as f64, max)
        );
    }
    let _ = write!(out, "{}", lattice_line(&report));
    let _ = writeln!(out, "lattice vs exact: {lattice_n} samples compared, {data_differs} where only one has data");
    let _ = writeln!(out, "throughput ratio terrafuse lattice / exact: {:.2}", exact_s / ours_s);
    for (label, secs, pixels, _) in &rows {
        let ratio = (ours_samples as f64 / ours_s) / (*pixels as f64 / secs);
        let _ = writeln!(out, "throughput ratio terrafuse lattice / {label}: {ratio:.2}");
    }
    let _ = writeln!(out, "anchor: Lambers & Kolb 2012 preprocessed SRTM at ≈0.9 M samples/s with 8 threads");
    Ok(out)
}

/// How gdalwarp is run.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum WarpMode {
    /// Its default approximate transformer (`-et 0.125`), an uncompressed GeoTIFF (the store's
    /// tiles are uncompressed too: the like-for-like output).
    Default,
    /// The exact transformer (`-et 0`).
    Exact,
}

/// gdalwarp's resampling of the same sources into the same grid as a dataset level (per face,
/// the bounding box of the dataset's quads, pixel centres on its samples), and how far the
/// dataset's samples are from it.
#[derive(Clone, Debug)]
pub struct WarpComparison {
    /// gdalwarp's wall time, seconds.
    pub seconds: f64,
    /// Pixels gdalwarp wrote.
    pub pixels: u64,
    /// Samples where both have data.
    pub compared: u64,
    /// Mean |ours − gdalwarp|, metres.
    pub mean_m: f64,
    /// 99th percentile, metres.
    pub p99_m: f64,
    /// Largest, metres.
    pub max_m: f64,
}

/// Runs gdalwarp (bilinear/cubic/nearest, exact transformer with `-et 0` when `exact`) into the
/// grid of `level` of a dataset and compares. gdalwarp must be on the PATH (gdal-bin).
#[allow(clippy::too_many_arguments)]
pub fn warp_comparison(
    store: &Store,
    dataset: &str,
    level: u8,
    sources: &[PathBuf],
    resampling: &str,
    mode: WarpMode,
    threads: usize,
    work: &Path,
    faces: &[Face],
) -> Result<WarpComparison, StoreError> {
    let body = *store.body();
    let quads = store.data_quads(dataset, level)?;
    let a = body.a_m();
    let dx = 2.0 * a / grid::intervals_per_face_edge(level) as f64;
    let mut reader = GridReader::new(Store::open_read_only(store.path())?, dataset)?;
    let mut diffs: Vec<f64> = Vec::new();
    let (mut seconds, mut pixels) = (0.0, 0u64);
    for &face in faces {
        let on: Vec<_> = quads.iter().filter(|q| q.face == face).collect();
        if on.is_empty() {
            continue;
        }
        let (x0, x1) = (on.iter().map(|q| q.x).min().unwrap_or(0), on.iter().map(|q| q.x).max().unwrap_or(0));
        let (y0, y1) = (on.iter().map(|q| q.y).min().unwrap_or(0), on.iter().map(|q| q.y).max().unwrap_or(0));
        let t = f64::from(TILE) * dx;
        let te = [
            -a + f64::from(x0) * t - dx / 2.0,
            -a + f64::from(y0) * t - dx / 2.0,
            -a + f64::from(x1 + 1) * t - dx / 2.0,
            -a + f64::from(y1 + 1) * t - dx / 2.0,
        ];
        let out = work.join(format!("gdalwarp-{dataset}-{}.tif", face.name()));
        let _ = std::fs::remove_file(&out);
        let mut cmd = Command::new("gdalwarp");
        cmd.args(["-q", "-overwrite", "-r", resampling, "-ot", "Float32", "-dstnodata", "nan", "-multi"])
            .args(["-wo", &format!("NUM_THREADS={threads}"), "-wm", "512"])
            .args(["-t_srs", &face_proj(&body, face)])
            .args(["-te", &te[0].to_string(), &te[1].to_string(), &te[2].to_string(), &te[3].to_string()])
            .args(["-tr", &dx.to_string(), &dx.to_string()]);
        match mode {
            WarpMode::Exact => {
                cmd.args(["-et", "0"]);
            }
            WarpMode::Default => {}
        }
        cmd.args(sources).arg(&out);
        let start = Instant::now();
        let status = cmd.status().map_err(|e| {
            StoreError::new(
                Path::new("gdalwarp"),
                format!("cannot run: {} (install gdal-bin)", crate::errors::chain(&e)),
            )
        })?;
        seconds += start.elapsed().as_secs_f64();
        if !status.success() {
            return Err(StoreError::new(Path::new("gdalwarp"), format!("failed on face {face}")));
        }
        pixels += u64::from(x1 - x0 + 1) * u64::from(y1 - y0 + 1) * u64::from(TILE * TILE);
        let ds = gdal::Dataset::open(&out).map_err(|e| StoreError::new(&out, e.to_string()))?;
        let (w, h) = ds.raster_size();
        let band = ds.rasterband(1).map_err(|e| StoreError::new(&out, e.to_string()))?;
        let data =
            band.read_as::<f32>((0, 0), (w, h), (w, h), None).map_err(|e| StoreError::new(&out, e.to_string()))?;
        let i0 = i64::from(x0) * i64::from(TILE);
        let j_top = i64::from(y1 + 1) * i64::from(TILE) - 1;
        for r in 0..h {
            for c in 0..w {
                let theirs = f64::from(data.data()[r * w + c]);
                let ours = f64::from(reader.sample(face, level, i0 + c as i64, j_top - r as i64)?);
                if theirs.is_finite() && ours.is_finite() {
                    diffs.push((ours - theirs).abs());
                }
            }
        }
        let _ = std::fs::remove_file(&out);
    }
    diffs.sort_by(f64::total_cmp);
    let n = diffs.len();
    let pick = |q: f64| if n == 0 { f64::NAN } else { diffs[((n - 1) as f64 * q).round() as usize] };
    Ok(WarpComparison {
        seconds,
        pixels,
        compared: n as u64,
        mean_m: if n == 0 { f64::NAN } else { diffs.iter().sum::<f64>() / n as f64 },
        p99_m: pick(0.99),
        max_m: pick(1.0),
    })
}

/// Peak resident memory of the largest waited-for child process, bytes.
fn children_peak_rss_bytes() -> u64 {
    // SAFETY: getrusage writes into the struct we pass and reads nothing else.
    let mut usage: libc::rusage = unsafe { std::mem::zeroed() };
    let ok = unsafe { libc::getrusage(libc::RUSAGE_CHILDREN, &mut usage) } == 0;
    if ok { usage.ru_maxrss.max(0) as u64 * 1024 } else { 0 }
}
