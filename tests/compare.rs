//! `terrafuse compare` as a user runs it on the bundled Erzurum pair (the SRTM tile and its
//! blurred and shifted copy), its statistics checked against xDEM and numpy on the very samples
//! it compared (`--samples`), a closed form through the whole pipeline, and bad input.

mod common;

use std::path::{Path, PathBuf};

use common::{repo_path, sample_project, terrafuse};
use terrafuse::compare::{CompareOptions, Weighting, compare};
use terrafuse::layers::LayerSpec;
use terrafuse::project::Project;

fn project() -> PathBuf {
    sample_project("erzurum-compare", &repo_path("tests/out/compare"))
}

fn run(args: &[&str]) -> String {
    let out = terrafuse(args, "");
    assert!(out.status.success(), "terrafuse {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// The reference statistics of a samples CSV (tests/reference/compare_stats.py in the
/// `.venv-ref` that scripts/install-deps makes).
fn reference(samples: &Path) -> serde_json::Value {
    let python = repo_path(".venv-ref/bin/python");
    assert!(python.exists(), "{} is missing: run scripts/install-deps", python.display());
    let script = repo_path("tests/reference/compare_stats.py");
    let out = std::process::Command::new(&python).arg(&script).arg(samples).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    serde_json::from_slice(&out.stdout).unwrap()
}

fn close(field: &str, ours: f64, theirs: f64) {
    let tolerance = 1e-9 * theirs.abs().max(1.0);
    assert!((ours - theirs).abs() <= tolerance, "{field}: ours {ours}, reference {theirs}");
}

#[test]
fn the_erzurum_pair_gives_xdems_statistics_on_the_same_samples_and_area_weighted_ones() {
    let p = project();
    let dir = repo_path("tests/out/compare");
    for (weighting, key) in [("--unweighted", "samples"), ("", "area")] {
        let csv = dir.join(format!("samples-{key}.csv"));
        let mut args =
            vec!["compare", p.to_str().unwrap(), "blurred", "srtm", "--json", "--samples", csv.to_str().unwrap()];
        if !weighting.is_empty() {
            args.push(weighting);
        }
        let ours: serde_json::Value = serde_json::from_str(&run(&args)).unwrap();
        let theirs = reference(&csv);
        let theirs = &theirs[key];
        assert_eq!(ours["count"], theirs["count"]);
        assert!(ours["count"].as_u64().unwrap() > 900_000, "{}", ours["count"]);
        for field in ["mean_m", "median_m", "std_m", "rmse_m", "nmad_m", "min_m", "max_m", "le90_m", "p90_abs_m"] {
            close(field, ours[field].as_f64().unwrap(), theirs[field].as_f64().unwrap());
        }
        // The fields scripts rely on, and their sense.
        for field in ["nodata_count", "histogram", "by_slope", "weight_ratio", "level"] {
            assert!(!ours[field].is_null(), "{field} missing");
        }
        let by_slope: u64 = ours["by_slope"].as_array().unwrap().iter().map(|c| c["count"].as_u64().unwrap()).sum();
        assert!(by_slope <= ours["count"].as_u64().unwrap() && by_slope > 0);
        let histogram: u64 = ours["histogram"]["count"].as_array().unwrap().iter().map(|c| c.as_u64().unwrap()).sum();
        assert_eq!(histogram, ours["count"].as_u64().unwrap());
        // QSC on WGS84: cell areas differ a little (equal-area on the sphere only).
        let ratio = ours["weight_ratio"].as_f64().unwrap();
        assert!(ratio > 1.0 && ratio < 1.05, "weight ratio {ratio}");
        if key == "area" {
            close("area_km2", ours["area_km2"].as_f64().unwrap(), theirs["area_km2"].as_f64().unwrap());
        }
    }
    // The table for people names what it measured.
    let table = run(&["compare", p.to_str().unwrap(), "blurred", "srtm"]);
    assert!(
        table.contains("blurred − srtm at level") && table.contains("NMAD") && table.contains("histogram"),
        "{table}"
    );
}

#[test]
fn a_layer_offset_by_5_m_differs_by_exactly_5_m_everywhere() {
    // Closed form through the whole pipeline: the same dataset, once with offset_m 5.
    let mut p = Project::load(&project()).unwrap();
    let srtm = p.layers.iter().find(|l| l.name == "srtm").unwrap().clone();
    p.layers.push(LayerSpec { name: "raised".into(), dataset: Some("srtm".into()), offset_m: 5.0, ..srtm });
    for weighting in [Weighting::Area, Weighting::Samples] {
        let opts = CompareOptions { level: Some(8), weighting, ..CompareOptions::default() };
        let c = compare(&p, "raised", "srtm", &opts).unwrap();
        assert!(c.stats.count > 50_000);
        for v in [c.stats.mean_m, c.stats.median_m, c.stats.min_m, c.stats.max_m, c.stats.rmse_m] {
            assert!((v - 5.0).abs() < 1e-3, "{v}");
        }
        assert!(c.stats.std_m < 1e-3 && c.stats.nmad_m < 1e-3 && c.stats.le90_m < 1e-3);
    }
}

#[test]
fn bad_input_is_refused_by_name() {
    let p = project();
    let p = p.to_str().unwrap();
    for (args, expected) in [
        (vec!["compare", p, "nope", "srtm"], "layer 'nope' is not in the project (its layers: srtm, blurred)"),
        (vec!["compare", p, "srtm", "srtm"], "'srtm' compared with itself"),
        (vec!["compare", p, "blurred", "srtm", "--region", "40,39.5,41"], "--region 40,39.5,41: give four numbers"),
        (
            vec!["compare", p, "blurred", "srtm", "--region", "40,39.9,41,39.5"],
            "--region: 40,39.9,41,39.5 is not a box",
        ),
        (vec!["compare", p, "blurred", "srtm", "--level", "20"], "--level: 20 is more than 4 levels below"),
    ] {
        let out = terrafuse(&args, "");
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: {err}\n  expected: {expected}");
    }
    // A region inside the tile compares fewer samples.
    let all: serde_json::Value = serde_json::from_str(&run(&["compare", p, "blurred", "srtm", "--json"])).unwrap();
    let part: serde_json::Value =
        serde_json::from_str(&run(&["compare", p, "blurred", "srtm", "--json", "--region", "40.2,39.4,40.5,39.7"]))
            .unwrap();
    let (a, b) = (all["count"].as_u64().unwrap(), part["count"].as_u64().unwrap());
    assert!(b > 0 && b < a / 2, "{b} of {a}");
}
