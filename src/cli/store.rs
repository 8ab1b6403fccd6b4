//! `terrafuse import` and `terrafuse store info|sample|export` (`terrafuse bench import` is in
//! `crate::bench`).

use super::CliError;
use std::fmt::Write as _;
use std::io::{BufRead, Write};
use std::path::{Path, PathBuf};

use crate::ecm::grid::{self, GRID};
use crate::store::gpkg::Store;
use crate::store::{GridReader, ImportReport, StoreError};

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

/// A default work folder for benchmarks.
pub fn default_work_dir() -> PathBuf {
    std::env::temp_dir().join(format!("terrafuse-bench-{}", std::process::id()))
}
