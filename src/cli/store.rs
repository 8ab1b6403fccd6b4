//! `terrafuse import`, `terrafuse store info|sample|export` and `terrafuse bench import`.

use super::CliError;
use std::fmt::Write as _;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

use crate::ecm::Face;
use crate::ecm::grid::{self, GRID, TILE};
use crate::store::gpkg::{Store, face_proj};
use crate::store::import::peak_rss_bytes;
use crate::store::lattice::Transform;
use crate::store::{GridReader, ImportOptions, ImportReport, StoreError, import};

/// Parses a memory size: `2GiB`, `512MiB`, `64KiB` or bytes.
pub fn parse_bytes(text: &str) -> Result<u64, CliError> {
    let t = text.trim();
    let (num, unit) = t.split_at(t.find(|c: char| c.is_ascii_alphabetic()).unwrap_or(t.len()));
    let scale = match unit.to_ascii_lowercase().as_str() {
        "" | "b" => 1u64,
        "k" | "kb" | "kib" => 1 << 10,
        "m" | "mb" | "mib" => 1 << 20,
        "g" | "gb" | "gib" => 1 << 30,
        _ => return Err(format!("unknown size unit in '{text}': use B, KiB, MiB or GiB").into()),
    };
    let v: f64 = num.trim().parse().map_err(|_| CliError::Usage(format!("'{text}' is not a size such as 2GiB")))?;
    if !(v.is_finite() && v > 0.0) {
        return Err(format!("'{text}' is not a positive size").into());
    }
    Ok((v * scale as f64) as u64)
}

/// The lines `terrafuse import` prints when it is done.
pub fn import_summary(store: &Path, r: &ImportReport) -> String {
    let mut out = String::new();
    if r.already_complete {
        let _ = writeln!(out, "dataset {} in {} is already complete: nothing to do", r.dataset, store.display());
        return out;
    }
    let _ = writeln!(out, "dataset {} → {} (finest level {})", r.dataset, store.display(), r.finest_level);
    for (level, written, resumed) in &r.levels {
        let resumed = if *resumed > 0 { format!(" ({resumed} finished by an earlier run)") } else { String::new() };
        let _ = writeln!(out, "  level {level:>2}: {written} tiles with data{resumed}");
    }
    let rate = r.finest_samples as f64 / r.seconds_finest.max(1e-9);
    let _ = writeln!(
        out,
        "finest level {:.2} s ({:.2} M samples/s), coarser levels {:.2} s, peak memory {:.0} MiB",
        r.seconds_finest,
        rate / 1e6,
        r.seconds_pyramid,
        r.peak_rss_bytes as f64 / (1u64 << 20) as f64
    );
    let _ = writeln!(out, "heights: {}", r.vertical_datum);
    let _ = write!(out, "{}", lattice_line(r));
    out
}

/// How sample positions were found: quads on each lattice spacing, exact quads, the error.
pub fn lattice_line(r: &ImportReport) -> String {
    let l = &r.lattice;
    let [l16, l8, l4] = l.by_spacing;
    if l16 + l8 + l4 + l.exact == 0 {
        return String::new();
    }
    let split = if l.split > 0 {
        format!(", {} quads split into blocks of 64² and cells of 16² samples ({} cells exact)", l.split, l.exact_cells)
    } else {
        String::new()
    };
    format!(
        "positions: {l16} lattices of 16 samples, {l8} of 8, {l4} of 4, {} quads exact{split}; largest lattice error {:.1e} source pixels (bound {:.0e})\n",
        l.exact,
        l.max_error_px,
        crate::store::lattice::TOLERANCE_PX
    )
}

/// `terrafuse store info`: bodies, datasets, levels, tile counts, extents and provenance.
pub fn store_info(path: &Path) -> Result<String, StoreError> {
    let store = Store::open_read_only(path)?;
    let body = store.body();
    let mut out = String::new();
    let _ = writeln!(out, "store {}", path.display());
    let _ = writeln!(out, "body: {body}");
    let datasets = store.datasets()?;
    if datasets.is_empty() {
        let _ = writeln!(out, "no datasets");
    }
    for d in datasets {
        let s = &d.settings;
        let state = match &d.completed {
            Some(t) => format!("complete {t}"),
            None => "INCOMPLETE (import interrupted: run the same import again to finish it)".into(),
        };
        let _ = writeln!(out, "\ndataset {}: {state}", d.name);
        let _ = writeln!(
            out,
            "  imported {} with resampling {}, {} sub-samples per sample",
            d.created,
            s.resampling,
            s.supersample * s.supersample
        );
        let _ = writeln!(out, "  heights: {}", s.vertical_datum);
        let _ = writeln!(out, "  sample positions: {}", s.transform);
        if let Some((plan, shards, merged)) = crate::store::merge::merge_record(path, &d.name)? {
            let _ = writeln!(out, "  merged from plan {}: {merged} of {shards} shards", &plan[..12.min(plan.len())]);
        }
        let _ = writeln!(
            out,
            "  levels 0–{} (finest spacing {:.2} m)",
            s.finest_level,
            grid::spacing_m(body, s.finest_level)
        );
        let _ = writeln!(out, "  level     tiles  per face (front right back left top bottom)");
        for c in store.level_counts(&d.name)? {
            let total: u64 = c.per_face.iter().sum();
            let faces: Vec<String> = c.per_face.iter().map(u64::to_string).collect();
            let _ = writeln!(out, "  {:>5}  {:>8}  {}", c.level, total, faces.join(" "));
        }
        if let Some((lo, hi)) = store.height_range(&d.name, s.finest_level)? {
            let _ = writeln!(out, "  heights {lo:.2} … {hi:.2} m (finest level)");
        }
        for p in &d.sources {
            let _ = writeln!(out, "  source {}", p.path);
            let _ = writeln!(
                out,
                "    {} {}×{} {}, pixel-is-{}, nodata {}, {:.1} m per pixel",
                p.driver,
                p.size.0,
                p.size.1,
                p.data_type,
                p.pixel_convention.to_lowercase(),
                p.nodata.map_or("none".into(), |v| v.to_string()),
                p.resolution_m
            );
            let b = p.bounds_deg;
            let _ = writeln!(out, "    extent lon {:.5} … {:.5}, lat {:.5} … {:.5}", b[0], b[2], b[1], b[3]);
            let _ = writeln!(out, "    CRS {} ({})", crs_name(&p.crs_wkt), p.crs_proj.trim());
        }
    }
    Ok(out)
}

/// "WGS 84 (EPSG:4326)" from a WKT1 text: its name and its top-level authority.
fn crs_name(wkt: &str) -> String {
    let name = wkt.split('"').nth(1).unwrap_or("unnamed CRS").to_owned();
    match wkt.rfind("AUTHORITY[\"") {
        Some(k) if wkt[k..].len() < 40 => {
            let parts: Vec<&str> = wkt[k..].split('"').collect();
            format!("{name}, {}:{}", parts.get(1).unwrap_or(&""), parts.get(3).unwrap_or(&""))
        }
        _ => name,
    }
}

/// `terrafuse store sample`: `lat lon` lines in, heights out (`nan` where there are no data).
/// Returns (points, refused lines).
pub fn sample_lines(
    reader: &mut GridReader,
    level: u8,
    input: impl BufRead,
    mut output: impl Write,
    mut refusals: impl Write,
) -> Result<(u64, u64), StoreError> {
    let (mut n, mut refused) = (0, 0);
    let path = reader.store().path().to_owned();
    let io = |e: std::io::Error| StoreError::caused(&path, "cannot write output", e);
    for (k, line) in input.lines().enumerate() {
        let line = line.map_err(|e| StoreError::new(Path::new("<stdin>"), e.to_string()))?;
        let t = line.trim();
        if t.is_empty() || t.starts_with('#') {
            continue;
        }
        let v: Vec<f64> = t.split_whitespace().take(2).filter_map(|x| x.parse().ok()).collect();
        match v.as_slice() {
            [lat, lon] if lat.abs() <= 90.0 && lon.is_finite() => {
                let h = reader.height_at(lat.to_radians(), lon.to_radians(), level)?;
                if h.is_nan() {
                    writeln!(output, "nan").map_err(io)?;
                } else {
                    writeln!(output, "{h:.4}").map_err(io)?;
                }
                n += 1;
            }
            _ => {
                writeln!(refusals, "line {}: '{t}' is not 'lat lon' in degrees", k + 1).map_err(io)?;
                writeln!(output, "nan").map_err(io)?;
                refused += 1;
            }
        }
    }
    Ok((n, refused))
}

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

/// Mean and largest |a − b| over a level's samples where both stores have data, how many
/// samples that is, and how many have data in one store only.
pub fn store_difference(a: &Store, b: &Store, dataset: &str, level: u8) -> Result<(f64, f64, u64, u64), StoreError> {
    let (mut sum, mut max, mut n, mut one) = (0.0f64, 0.0f64, 0u64, 0u64);
    let mut quads: Vec<_> = a.data_quads(dataset, level)?.union(&b.data_quads(dataset, level)?).copied().collect();
    quads.sort();
    for q in quads {
        let (ga, gb) = (a.read_grid(dataset, q)?, b.read_grid(dataset, q)?);
        let nan = vec![f32::NAN; (GRID * GRID) as usize];
        let (va, vb) = (ga.map_or_else(|| nan.clone(), |g| g.values), gb.map_or(nan, |g| g.values));
        for (x, y) in va.iter().zip(&vb) {
            match (x.is_nan(), y.is_nan()) {
                (false, false) => {
                    let d = f64::from((x - y).abs());
                    sum += d;
                    max = max.max(d);
                    n += 1;
                }
                (true, true) => {}
                _ => one += 1,
            }
        }
    }
    Ok((sum / n.max(1) as f64, max, n, one))
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

/// A default work folder for benchmarks.
pub fn default_work_dir() -> PathBuf {
    std::env::temp_dir().join(format!("terrafuse-bench-{}", std::process::id()))
}
