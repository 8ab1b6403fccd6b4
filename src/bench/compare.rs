//! `terrafuse bench compare`: the time of the comparison statistics and of co-registration on the
//! bundled Erzurum pair and on a synthetic 4096² pair with a known shift, beside xDEM's time on
//! the same data in the same run (its rasters warped to a transverse Mercator centred on the area,
//! as the tests do), and both tools' co-registration error against the known shift; and on the
//! Erzurum pair the bias-correction pipelines and the uncertainty beside xDEM's, with their peak
//! memory ([`super::pipelines`]), and comparisons of 10⁷–10⁸ samples held in memory and
//! spilled ([`super::compare_large`]).

use super::harness::timed;
use crate::cli::CliError;
use crate::cli::Context;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use crate::compare::{CompareOptions, CoregOptions, compare, coregister};
use crate::geodesy::Ellipsoid;
use crate::layers::{NoiseSpec, NoiseType, noise};
use crate::project::Project;
use crate::store::export::RasterSpec;

/// What to measure.
#[derive(Clone, Debug)]
pub struct CompareBenchSettings {
    /// The Erzurum comparison project (`projects/erzurum-compare.json`).
    pub project: PathBuf,
    /// Where the synthetic pair, its stores and the tables go.
    pub out: PathBuf,
    /// The synthetic rasters' edge, pixels (4096 by default).
    pub size: usize,
    /// The Python with xDEM (`.venv-ref/bin/python`); skipped with a note when missing.
    pub python: PathBuf,
    /// The folder of `xdem_bench.py`.
    pub reference_dir: PathBuf,
}

/// Warps a pair of rasters (reference, moved; each from → to) to the transverse Mercator centred at
/// (lat, lon) with `spacing_m` square pixels, bilinear: the reference onto its own extent, the
/// moved raster onto the reference's grid (xDEM's workflows want both on one grid).
fn warp_pair_tm(pair: [(&Path, &Path); 2], lat: f64, lon: f64, spacing_m: f64) -> Result<(), CliError> {
    let [(ref_from, ref_to), (moved_from, moved_to)] = pair;
    warp_tm(ref_from, ref_to, lat, lon, spacing_m, &[])?;
    let ds = gdal::Dataset::open(ref_to).context(ref_to.display())?;
    let gt = ds.geo_transform().context(ref_to.display())?;
    let (w, h) = ds.raster_size();
    let te = [gt[0], gt[3] + h as f64 * gt[5], gt[0] + w as f64 * gt[1], gt[3]].map(|v| v.to_string());
    warp_tm(moved_from, moved_to, lat, lon, spacing_m, &te)
}

/// Warps a raster to the transverse Mercator centred at (lat, lon), `spacing_m` pixels, bilinear;
/// onto the extent `te` (xmin, ymin, xmax ymax) where given.
fn warp_tm(from: &Path, to: &Path, lat: f64, lon: f64, spacing_m: f64, te: &[String]) -> Result<(), CliError> {
    let tm = format!("+proj=tmerc +lon_0={lon} +lat_0={lat} +k=1 +ellps=WGS84 +units=m");
    let tr = format!("{spacing_m}");
    let mut command = std::process::Command::new("gdalwarp");
    command.args(["-q", "-overwrite", "-t_srs", &tm, "-tr", &tr, &tr, "-r", "bilinear", "-dstnodata", "-9999"]);
    if !te.is_empty() {
        command.arg("-te").args(te);
    }
    let status = command
        .args(["-ot", "Float32"])
        .arg(from)
        .arg(to)
        .status()
        .context("gdalwarp (install gdal-bin: scripts/install-deps)")?;
    if status.success() { Ok(()) } else { Err(format!("gdalwarp {} failed", from.display()).into()) }
}

/// xDEM's statistics and Nuth & Kääb on two rasters, or why not.
fn xdem(settings: &CompareBenchSettings, reference: &Path, moved: &Path) -> Result<serde_json::Value, CliError> {
    if !settings.python.exists() {
        return Err(format!("{} is missing (scripts/install-deps makes it)", settings.python.display()).into());
    }
    let out = std::process::Command::new(&settings.python)
        .arg(settings.reference_dir.join("xdem_bench.py"))
        .arg(reference)
        .arg(moved)
        .output()
        .map_err(CliError::file(&settings.python, "cannot run"))?;
    if !out.status.success() {
        return Err(String::from_utf8_lossy(&out.stderr).into_owned().into());
    }
    Ok(serde_json::from_slice(&out.stdout)?)
}

/// The east and north metres of (dlon, dlat) degrees at a latitude on WGS84.
fn metres_of_degrees(dlon: f64, dlat: f64, lat_deg: f64) -> (f64, f64) {
    let e = Ellipsoid::WGS84;
    let s = lat_deg.to_radians().sin();
    let n = e.a_m() / (1.0 - e.e2() * s * s).sqrt();
    let m = e.a_m() * (1.0 - e.e2()) / (1.0 - e.e2() * s * s).powf(1.5);
    (dlon.to_radians() * n * lat_deg.to_radians().cos(), dlat.to_radians() * m)
}

/// Writes a synthetic DEM (fBm of the position on the ellipsoid, 3″ pixels from 40°E 40°N) and
/// the same moved by (dlon, dlat) degrees.
fn synthetic_pair(dir: &Path, size: usize, dlon: f64, dlat: f64) -> Result<(PathBuf, PathBuf), CliError> {
    let e = Ellipsoid::WGS84;
    let pixel = 1.0 / 1200.0;
    let terrain = NoiseSpec {
        noise_type: NoiseType::Fbm,
        seed: 11,
        amplitude_m: 600.0,
        wavelength_m: 40_000.0,
        octaves: 10,
        lacunarity: 2.0,
        gain: 0.5,
        placement: Default::default(),
    };
    let weights = vec![1.0; terrain.octaves as usize];
    let data: Vec<f32> = (0..size * size)
        .map(|k| {
            let (col, row) = ((k % size) as f64 + 0.5, (k / size) as f64 + 0.5);
            let (lon, lat) = (40.0 + col * pixel, 40.0 - row * pixel);
            let p = crate::geodesy::ecef_from_geodetic(
                &e,
                crate::geodesy::Geodetic { lat_rad: lat.to_radians(), lon_rad: lon.to_radians(), height_m: 0.0 },
            );
            (1500.0 + noise::noise_at(&terrain, p, &weights)) as f32
        })
        .collect();
    let extent = size as f64 * pixel;
    let mut paths = Vec::new();
    for (name, (dx, dy)) in [("synthetic_ref.tif", (0.0, 0.0)), ("synthetic_moved.tif", (dlon, dlat))] {
        let path = dir.join(name);
        let spec = RasterSpec::new(
            "EPSG:4326",
            [40.0 + dx, 40.0 - extent + dy, 40.0 + extent + dx, 40.0 + dy],
            (pixel, pixel),
            &path,
        )?;
        spec.write(&path, &[("TERRAFUSE_SYNTHETIC", "fBm, 600 m, 40 km, 10 octaves".into())], data.clone())?;
        paths.push(path);
    }
    Ok((paths[0].clone(), paths[1].clone()))
}

/// Runs the benchmark; returns the report (also written to OUT/compare.txt).
pub fn bench_compare(settings: &CompareBenchSettings) -> Result<String, CliError> {
    std::fs::create_dir_all(&settings.out).map_err(CliError::file(&settings.out, "cannot create"))?;
    // Absolute, since the synthetic project names its rasters from its own folder.
    let out_dir = std::fs::canonicalize(&settings.out).map_err(CliError::file(&settings.out, "cannot resolve"))?;
    let settings = &CompareBenchSettings { out: out_dir, ..settings.clone() };
    let mut report = String::new();
    let _ = writeln!(
        report,
        "terrafuse bench compare ({} cores)",
        std::thread::available_parallelism().map_or(1, |n| n.get())
    );
    let _ = writeln!(
        report,
        "{:<34} {:>10} {:>9} {:>9} {:>10} {:>10} {:>10} {:>9}",
        "pair", "samples", "stats s", "coreg s", "east m", "north m", "error m", "NMAD m"
    );
    erzurum_rows(settings, &mut report)?;
    synthetic_rows(settings, &mut report)?;
    let path = settings.out.join("compare.txt");
    crate::files::write_atomic(&path, report.as_bytes()).map_err(CliError::file(path, "cannot write"))?;
    Ok(report)
}

/// The bundled Erzurum pair: Terrafuse's statistics and co-registration beside xDEM's on the
/// same pair warped to a transverse Mercator grid, then the pipelines and the large comparisons.
fn erzurum_rows(settings: &CompareBenchSettings, report: &mut String) -> Result<(), CliError> {
    let project = Project::load(&settings.project)?;
    let (c, stats_s) = timed(|| compare(&project, "blurred", "srtm", &CompareOptions::default()));
    let c = c?;
    let (r, coreg_s) = timed(|| coregister(&project, "blurred", "srtm", &CoregOptions::default()));
    let r = r?;
    let _ = writeln!(
        report,
        "{:<34} {:>10} {:>9.2} {:>9.2} {:>10.3} {:>10.3} {:>10} {:>9.3}",
        "Erzurum, Terrafuse", c.stats.count, stats_s, coreg_s, r.east_m, r.north_m, "-", c.stats.nmad_m
    );
    let data = |name: &str| project.resolve(Path::new(&format!("data/{name}")));
    let (ref_tm, moved_tm) = (settings.out.join("erzurum_ref_tm.tif"), settings.out.join("erzurum_moved_tm.tif"));
    let (srtm, blurred) = (data("earth_srtm3_demcompare_N39E040.tif"), data("earth_srtm3_blurred_shifted_N39E040.tif"));
    warp_pair_tm([(&srtm, &ref_tm), (&blurred, &moved_tm)], 39.6, 40.42, 90.0)?;
    // The same pair at Terrafuse's sample spacing: as many samples for xDEM as Terrafuse reads.
    let (ref_fine, moved_fine) =
        (settings.out.join("erzurum_ref_fine.tif"), settings.out.join("erzurum_moved_fine.tif"));
    warp_pair_tm([(&srtm, &ref_fine), (&blurred, &moved_fine)], 39.6, 40.42, r.spacing_m)?;
    xdem_row(report, "Erzurum", "Erzurum, xDEM (tmerc 90 m)".into(), xdem(settings, &ref_tm, &moved_tm), None);
    // The pipelines and the uncertainty, each in a process of its own (peak memory).
    report.push_str(&super::pipelines::pipelines_table(&super::pipelines::PipelineBench {
        project: &settings.project,
        python: &settings.python,
        reference_dir: &settings.reference_dir,
        reference_tm: &ref_tm,
        moved_tm: &moved_tm,
        fine: (&ref_fine, &moved_fine, r.spacing_m),
    })?);
    // Comparisons of 10⁷–10⁸ samples, held in memory and spilled.
    report.push_str(&super::compare_large::large_table(&settings.project)?);
    Ok(())
}

/// The synthetic pair with a known shift: both tools' shift error, and Nuth & Kääb as a whole
/// workflow.
fn synthetic_rows(settings: &CompareBenchSettings, report: &mut String) -> Result<(), CliError> {
    let (dlon, dlat) = (0.0004, -0.0003);
    let (pair, made_s) = timed(|| synthetic_pair(&settings.out, settings.size, dlon, dlat));
    let (ref_tif, moved_tif) = pair?;
    let side = settings.size as f64 / 1200.0;
    let (lat_c, lon_c) = (40.0 - side / 2.0, 40.0 + side / 2.0);
    let synthetic = format!(
        r#"{{"format": "terrafuse-project", "version": 3, "body": "wgs84", "layers": [
            {{"name": "ref", "kind": "dataset", "store": "synthetic_ref.gpkg", "source": {{"files": ["{}"]}}}},
            {{"name": "moved", "kind": "dataset", "store": "synthetic_moved.gpkg", "source": {{"files": ["{}"]}}}}]}}"#,
        ref_tif.display(),
        moved_tif.display()
    );
    for store in ["synthetic_ref.gpkg", "synthetic_moved.gpkg"] {
        let _ = std::fs::remove_file(settings.out.join(store)); // time a fresh import
    }
    let synthetic_path = settings.out.join("synthetic.json");
    crate::files::write_atomic(&synthetic_path, synthetic.as_bytes())
        .map_err(CliError::file(&synthetic_path, "cannot write"))?;
    let (project, import_s) = timed(|| -> Result<Project, CliError> {
        let project = Project::load(&synthetic_path)?;
        crate::scene::Scene::open(&project)?; // imports both rasters
        Ok(project)
    });
    let project = project?;
    let (c, stats_s) = timed(|| compare(&project, "moved", "ref", &CompareOptions::default()));
    let c = c?;
    let opts = CoregOptions { level: Some(c.level), ..CoregOptions::default() };
    let (r, coreg_s) = timed(|| coregister(&project, "moved", "ref", &opts));
    let r = r?;
    let (e, n) = metres_of_degrees(-dlon, -dlat, lat_c);
    let label = format!("synthetic {0}², Terrafuse (L{1})", settings.size, c.level);
    let _ = writeln!(
        report,
        "{label:<34} {:>10} {:>9.2} {:>9.2} {:>10.3} {:>10.3} {:>10.3} {:>9.3}",
        c.stats.count,
        stats_s,
        coreg_s,
        r.east_m,
        r.north_m,
        (r.east_m - e).hypot(r.north_m - n),
        c.stats.nmad_m
    );
    let (ref_tm, moved_tm) = (settings.out.join("synthetic_ref_tm.tif"), settings.out.join("synthetic_moved_tm.tif"));
    warp_pair_tm([(&ref_tif, &ref_tm), (&moved_tif, &moved_tm)], lat_c, lon_c, 90.0)?;
    let (ref_fine, moved_fine) =
        (settings.out.join("synthetic_ref_fine.tif"), settings.out.join("synthetic_moved_fine.tif"));
    warp_pair_tm([(&ref_tif, &ref_fine), (&moved_tif, &moved_fine)], lat_c, lon_c, r.spacing_m)?;
    let label = format!("synthetic {}², xDEM (tmerc 90 m)", settings.size);
    xdem_row(report, "synthetic", label, xdem(settings, &ref_tm, &moved_tm), Some((e, n)));
    let _ = writeln!(
        report,
        "known correction of the synthetic pair at its centre: east {e:.3} m, north {n:.3} m (made in {made_s:.1} s, imported in {import_s:.1} s); \
         stats: the whole overlap, cell-area weighted; coreg: Nuth & Kääb to 0.001 px (Terrafuse: the whole run, before and after over every sample; xDEM: its fit)"
    );
    // Nuth & Kääb as a whole workflow on the synthetic pair (xDEM's row above times its fit alone).
    report.push_str(&super::pipelines::nuth_kaab_table(
        &super::pipelines::PipelineBench {
            project: &synthetic_path,
            python: &settings.python,
            reference_dir: &settings.reference_dir,
            reference_tm: &ref_tm,
            moved_tm: &moved_tm,
            fine: (&ref_fine, &moved_fine, r.spacing_m),
        },
        &format!("synthetic {}² pair", settings.size),
    )?);
    Ok(())
}

/// xDEM's row of a pair (its shift error against the known correction `truth` where there is
/// one), or why it did not run.
fn xdem_row(
    report: &mut String,
    pair: &str,
    label: String,
    x: Result<serde_json::Value, CliError>,
    truth: Option<(f64, f64)>,
) {
    match x {
        Ok(x) => {
            let num = |k: &str| x[k].as_f64().unwrap_or(f64::NAN);
            let (sx, sy) = (num("shift_x"), num("shift_y"));
            let error = truth.map_or_else(|| "-".to_string(), |(e, n)| format!("{:.3}", (sx - e).hypot(sy - n)));
            let _ = writeln!(
                report,
                "{label:<34} {:>10} {:>9.2} {:>9.2} {:>10.3} {:>10.3} {:>10} {:>9.3}",
                x["count"],
                num("stats_s"),
                num("coreg_s"),
                sx,
                sy,
                error,
                num("nmad_m")
            );
        }
        Err(e) => {
            let _ = writeln!(report, "{pair}, xDEM: not run: {}", crate::errors::chain(&e));
        }
    }
}
