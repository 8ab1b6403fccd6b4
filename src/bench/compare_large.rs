//! The large comparisons of `terrafuse bench compare`: the Erzurum pair compared far below its
//! data's level, so that there are 10⁷–10⁸ samples, with the differences held in memory and spilled
//! to a scratch file (`--memory-samples`), and with the uncertainty (its model fitted on at most 48
//! quads, its area summed over every sample), each run a process of its own so that its peak
//! resident memory is its own.

use crate::cli::Context;
use std::fmt::Write as _;
use std::path::Path;
use std::process::Command;

use super::pipelines::run_measured;
use crate::cli::CliError;

/// The runs: a label, and the arguments after `compare PROJECT blurred srtm --json`.
const RUNS: [(&str, &[&str]); 4] = [
    ("level 12, held in memory", &["--level", "12", "--memory-samples", "1000000000"]),
    ("level 12, spilled", &["--level", "12"]),
    ("level 13, west 0.4°, spilled", &["--level", "13", "--region", "40.0,39.0,40.4,40.0"]),
    ("level 12, spilled, --uncertainty", &["--level", "12", "--uncertainty"]),
];

/// The procedural pair of `bench compare-size --procedural`, written to `dir`: on the Moon,
/// `terrain` (fBm: 2 octaves, 2 km, 300 km) and `error` added on it (fBm: 1 octave, 5 m, 20 km),
/// so that `terrain+error` against `terrain` compares a synthetic DEM with a known error field
/// everywhere on the body, at any level (no dataset bounds it).
pub(super) fn noise_pair(dir: &Path) -> Result<std::path::PathBuf, CliError> {
    let layer = |name: &str, blend: &str, seed: u32, amplitude_m: f64, wavelength_m: f64, octaves: u32| {
        serde_json::json!({
            "name": name, "visible": true, "blend": blend, "opacity": 1.0, "weight": 1.0, "scale": 1.0,
            "offset_m": 0.0, "kind": "procedural",
            "noise": { "type": "fbm", "seed": seed, "amplitude_m": amplitude_m, "wavelength_m": wavelength_m,
                       "octaves": octaves, "lacunarity": 2.0, "gain": 0.5, "where": "everywhere" }
        })
    };
    let mut project = crate::project::Project::new("moon");
    for l in [layer("terrain", "over", 11, 2000.0, 300_000.0, 2), layer("error", "add", 12, 5.0, 20_000.0, 1)] {
        project.layers.push(serde_json::from_value(l)?);
    }
    std::fs::create_dir_all(dir).map_err(CliError::file(dir, "cannot create the folder"))?;
    let path = dir.join("noise-pair.json");
    project.save(&path)?;
    Ok(path)
}

/// `bench compare-size`: layers `a` and `b` of `project` compared at each of `levels`, each in a
/// process of its own (spilled as `compare` spills by default): samples, seconds, nanoseconds a
/// sample, peak resident memory, median and NMAD.
pub(super) fn size_table(project: &Path, [a, b]: [&str; 2], levels: &[u8]) -> Result<String, CliError> {
    let exe = std::env::current_exe().context("this program's path")?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<6} {:>13} {:>9} {:>12} {:>10} {:>20} {:>16}",
        "level", "samples", "seconds", "ns a sample", "peak MiB", "median m", "NMAD m"
    );
    for &level in levels {
        let mut command = Command::new(&exe);
        command.arg("compare").arg(project).args([a, b, "--json", "--level", &level.to_string()]);
        let (json, seconds, peak) = run_measured(command)?;
        let v: serde_json::Value = serde_json::from_str(&json)?;
        let number = |field: &str| v[field].as_f64().unwrap_or(f64::NAN);
        let samples = v["count"].as_u64().unwrap_or(0) + v["nodata_count"].as_u64().unwrap_or(0);
        let _ = writeln!(
            out,
            "{level:<6} {samples:>13} {seconds:>9.1} {:>12.1} {:>10.0} {:>20.12} {:>16.10}",
            seconds * 1e9 / samples.max(1) as f64,
            peak as f64 / 1048576.0,
            number("median_m"),
            number("nmad_m"),
        );
    }
    Ok(out)
}

/// The table: samples, seconds, peak memory and the median and NMAD of each run.
pub(super) fn large_table(project: &Path) -> Result<String, CliError> {
    let exe = std::env::current_exe().context("this program's path")?;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:<34} {:>11} {:>9} {:>10} {:>20} {:>16} {:>12}",
        "comparison (Erzurum pair)", "samples", "seconds", "peak MiB", "median m", "NMAD m", "σ mean m"
    );
    for (label, args) in RUNS {
        let mut command = Command::new(&exe);
        command.arg("compare").arg(project).args(["blurred", "srtm", "--json"]).args(args);
        let (json, seconds, peak) = run_measured(command)?;
        let v: serde_json::Value = serde_json::from_str(&json)?;
        let number = |field: &str| v[field].as_f64().unwrap_or(f64::NAN);
        let _ = writeln!(
            out,
            "{label:<34} {:>11} {seconds:>9.1} {:>10.0} {:>20.12} {:>16.10} {:>12}",
            v["count"],
            peak as f64 / 1048576.0,
            number("median_m"),
            number("nmad_m"),
            v["uncertainty"]["mean_dh_sigma_m"].as_f64().map_or("-".into(), |s| format!("{s:.4}"))
        );
    }
    Ok(out)
}
