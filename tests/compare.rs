//! `terrafuse compare` as a user runs it on the bundled Erzurum pair (the SRTM tile and its
//! blurred and shifted copy), its statistics checked against xDEM and numpy on the very samples
//! it compared (`--samples`), a closed form through the whole pipeline, and bad input.

mod common;

use std::path::{Path, PathBuf};

use common::{repo_path, sample_project, terrafuse};
use terrafuse::compare::{CompareOptions, Weighting, compare};
use terrafuse::layers::{BlendMode, LayerSpec, Operand};
use terrafuse::project::Project;

fn project() -> PathBuf {
    sample_project("erzurum-compare", &common::out_path("compare"))
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
    let dir = common::out_path("compare");
    // The last run holds no difference in memory: they are spilled and read back in passes.
    for (options, key) in [(&["--unweighted"][..], "samples"), (&[], "area"), (&["--memory-samples", "0"], "area")] {
        let csv = dir.join(format!("samples-{key}.csv"));
        let mut args =
            vec!["compare", p.to_str().unwrap(), "blurred", "srtm", "--json", "--samples", csv.to_str().unwrap()];
        args.extend(options);
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
fn a_comparison_larger_than_memory_holds_gives_the_same_statistics_from_its_scratch_file() {
    let p = Project::load(&project()).unwrap();
    let scratch = common::out_path("compare-scratch");
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch).unwrap();
    for weighting in [Weighting::Area, Weighting::Samples] {
        let held = compare(&p, "blurred", "srtm", &CompareOptions { weighting, ..CompareOptions::default() }).unwrap();
        let opts = CompareOptions {
            weighting,
            memory_samples: 0,
            scratch: Some(scratch.clone()),
            ..CompareOptions::default()
        };
        let spilled = compare(&p, "blurred", "srtm", &opts).unwrap();
        assert!(held.stats.count > 900_000);
        // Sums in the same order: the same bits. Quantiles: exact order statistics whose
        // positions are summed in another order.
        let (a, b) = (&spilled.stats, &held.stats);
        assert_eq!((a.count, a.nodata_count), (b.count, b.nodata_count));
        for (name, x, y) in [("mean", a.mean_m, b.mean_m), ("std", a.std_m, b.std_m), ("rmse", a.rmse_m, b.rmse_m)] {
            assert_eq!(x.to_bits(), y.to_bits(), "{name}");
        }
        assert_eq!((a.min_m, a.max_m), (b.min_m, b.max_m));
        assert_eq!(spilled.area_km2.to_bits(), held.area_km2.to_bits());
        for (name, x, y) in [
            ("median", a.median_m, b.median_m),
            ("nmad", a.nmad_m, b.nmad_m),
            ("le90", a.le90_m, b.le90_m),
            ("p90_abs", a.p90_abs_m, b.p90_abs_m),
        ] {
            close(name, x, y);
        }
        assert_eq!(spilled.histogram.count, held.histogram.count);
        for (s, h) in spilled.by_slope.iter().zip(&held.by_slope) {
            assert_eq!(s.stats.count, h.stats.count);
            close("class median", s.stats.median_m, h.stats.median_m);
            close("class nmad", s.stats.nmad_m, h.stats.nmad_m);
        }
    }
    // The scratch file is gone once the statistics are made.
    assert_eq!(std::fs::read_dir(&scratch).unwrap().count(), 0);
    // A scratch folder that cannot be written is named.
    let missing = scratch.join("no such folder");
    let opts = CompareOptions { memory_samples: 0, scratch: Some(missing), ..CompareOptions::default() };
    let err = compare(&p, "blurred", "srtm", &opts).unwrap_err().to_string();
    assert!(err.contains("no such folder") && err.contains("scratch file"), "{err}");
}

#[test]
fn a_layer_offset_by_5_m_differs_by_exactly_5_m_everywhere() {
    // Closed form through the whole pipeline: the same dataset, once with offset_m 5.
    let mut p = Project::load(&project()).unwrap();
    let srtm = p.layers.iter().find(|l| l.name == "srtm").unwrap().clone();
    p.layers.push(LayerSpec { name: "raised".into(), offset_m: 5.0, ..srtm.with_dataset_name("srtm") });
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
fn a_group_of_layers_compares_as_it_composes() {
    // srtm + a 7 m constant added on it, composed as a group, minus srtm alone: 7 m everywhere.
    let mut p = Project::load(&project()).unwrap();
    p.layers.push(LayerSpec { blend: BlendMode::Add, visible: false, ..LayerSpec::constant("bump", 7.0) });
    let opts = CompareOptions { level: Some(8), ..CompareOptions::default() };
    let c = compare(&p, "srtm+bump", "srtm", &opts).unwrap();
    assert_eq!((c.a.as_str(), c.b.as_str()), ("srtm+bump", "srtm"));
    assert!(c.stats.count > 50_000);
    for v in [c.stats.mean_m, c.stats.median_m, c.stats.min_m, c.stats.max_m] {
        assert!((v - 7.0).abs() < 1e-3, "{v}");
    }
    let e = compare(&p, "srtm+nope", "srtm", &opts).unwrap_err().to_string();
    assert!(e.contains("layer 'nope' is not in the project"), "{e}");
}

#[test]
fn a_difference_layer_draws_blue_where_a_is_higher_and_red_where_lower_over_its_percentile_range() {
    // The same tile raised by 40 m, minus the tile: dh = +40 m everywhere, so the 98th percentile
    // of |dh| is 40 m and every pixel of terrain shows the map's blue end (then the other way
    // round, red). Hillshade darkens both, the hue stays.
    let dir = common::out_path("compare-difference");
    let mut p = Project::load(&sample_project("erzurum-compare", &dir)).unwrap();
    let srtm = p.layers.iter().find(|l| l.name == "srtm").unwrap().clone();
    p.layers = vec![
        srtm.clone(),
        LayerSpec { name: "raised".into(), offset_m: 40.0, visible: false, ..srtm.with_dataset_name("srtm") },
    ];
    p.visuals.isolines.enabled = false;
    p.comparison = Default::default();
    for (a, b, blue) in [("raised", "srtm", true), ("srtm", "raised", false)] {
        let mut q = p.clone();
        q.layers.push(LayerSpec::difference("dh", Operand::Layer(a.into()), Operand::Layer(b.into())));
        let path = dir.join(format!("dh-{a}.json"));
        q.save(&path).unwrap();
        let out = dir.join(format!("dh-{a}.png"));
        let report = run(&[
            "render",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--width",
            "240",
            "--height",
            "160",
        ]);
        assert!(report.contains(&format!("difference 'dh' ({a} - {b}): red -40.00 m")), "{report}");
        assert!(report.contains("(the 98th percentile of |dh|)"), "{report}");
        let image = image::open(&out).unwrap().to_rgba8();
        // Not the sky, not the ground beyond the tile (no data).
        let (sky, nodata) = (q.visuals.background, q.visuals.colour_map.nodata_colour);
        let terrain: Vec<_> = image.pixels().filter(|px| px.0 != sky && px.0 != nodata).collect();
        assert!(terrain.len() > 240 * 160 / 2, "{} terrain pixels", terrain.len());
        let right = terrain.iter().filter(|px| if blue { px[2] > px[0] + 20 } else { px[0] > px[2] + 20 }).count();
        let wrong: Vec<_> =
            terrain.iter().filter(|px| !(if blue { px[2] > px[0] + 20 } else { px[0] > px[2] + 20 })).take(8).collect();
        assert_eq!(right, terrain.len(), "every terrain pixel {}: {wrong:?}", if blue { "blue" } else { "red" });
    }
    // An operand that names no layer is refused on load, naming the file, the layer and the field.
    let mut bad = p.clone();
    bad.layers.push(LayerSpec::difference("dh", Operand::Layer("raised".into()), Operand::Layer("nope".into())));
    let path = dir.join("bad.json");
    std::fs::write(&path, serde_json::to_string_pretty(&bad).unwrap()).unwrap();
    let out = terrafuse(
        &["render", path.to_str().unwrap(), "--out", common::out_path("compare/x.png").to_str().unwrap()],
        "",
    );
    let e = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(e.contains("bad.json") && e.contains("layers[2]: layer 'dh': of: operand B names 'nope'"), "{e}");
}

#[test]
fn a_saved_swipe_or_profile_that_names_no_layer_is_refused_on_load() {
    let mut p = Project::load(&project()).unwrap();
    p.comparison.swipes.get_mut("blurred-srtm").unwrap().b = "gone".into();
    let bad = common::out_path("compare/bad-swipe.json");
    p.save(&bad).unwrap_err(); // save checks too, and refuses
    let text = std::fs::read_to_string(project()).unwrap().replace(r#""b": "srtm""#, r#""b": "gone""#);
    std::fs::write(&bad, text).unwrap();
    let e = Project::load(&bad).unwrap_err().to_string();
    assert!(e.contains("comparison.swipes.blurred-srtm: layer 'gone' is not in the project"), "{e}");
}

#[test]
fn bad_input_is_refused_by_name() {
    let p = project();
    let p = p.to_str().unwrap();
    for (args, expected) in [
        (
            vec!["compare", p, "nope", "srtm"],
            "layer 'nope' is not in the project (its layers: srtm, blurred, blurred - srtm)",
        ),
        (vec!["compare", p, "blurred - srtm", "srtm"], "blurred - srtm: is a difference layer: it draws A − B"),
        (vec!["compare", p, "srtm", "srtm"], "'srtm' compared with itself"),
        (
            vec!["compare", p, "blurred", "srtm", "--region", "40,39.5,41"],
            "--region: '40,39.5,41' is not WEST,SOUTH,EAST,NORTH in degrees (four numbers)",
        ),
        (
            vec!["compare", p, "blurred", "srtm", "--region", "40,39.9,41,39.5"],
            "--region: south 39.9 and north 39.5 must be latitudes",
        ),
        // A box in the LAT,LON order: valid, but where neither dataset has data.
        (
            vec!["compare", p, "blurred", "srtm", "--region", "39.4,40.2,39.7,40.5"],
            "--region: 39.4,40.2,39.7,40.5: no sample inside",
        ),
        (
            vec!["coregister", p, "blurred", "--to", "srtm", "--region", "40,95,41,96"],
            "--region: south 95 and north 96",
        ),
        (vec!["compare", p, "blurred", "srtm", "--level", "20"], "--level: 20 is more than 4 levels below"),
        (
            vec!["coregister", p, "blurred", "--to", "srtm", "--pipeline", "nuth_kaab,deramp:5"],
            "--pipeline: 'deramp:5': the order must be 1, 2 or 3",
        ),
        (
            vec!["compare", p, "blurred", "srtm", "--uncertainty", "--area", "glaciers.geojson"],
            "glaciers.geojson: no such file (and no layer of that name in the project)",
        ),
        (vec!["compare", p, "blurred", "srtm", "--area", "srtm"], "--uncertainty"),
        (
            vec!["coregister", p, "blurred", "--to", "srtm", "--stable", "glaciers.geojson"],
            "glaciers.geojson: no such file (and no layer of that name in the project)",
        ),
        (
            vec![
                "coregister",
                p,
                "blurred",
                "--to",
                "srtm",
                "--pipeline",
                "deramp:1,terrain_bias:max_curvature",
                "--apply",
            ],
            "--apply: terrain_bias:max_curvature cannot be stored in a layer: a layer's terrain bias reads only its own elevation",
        ),
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

/// The local east and north metres of a shift of (dlon, dlat) degrees at a latitude on WGS84.
fn metres_of_degrees(dlon: f64, dlat: f64, lat_deg: f64) -> (f64, f64) {
    let (a, f) = (6_378_137.0f64, 1.0 / 298.257_223_563);
    let e2 = f * (2.0 - f);
    let s = lat_deg.to_radians().sin();
    let n = a / (1.0 - e2 * s * s).sqrt();
    let m = a * (1.0 - e2) / (1.0 - e2 * s * s).powf(1.5);
    (dlon.to_radians() * n * lat_deg.to_radians().cos(), dlat.to_radians() * m)
}

#[test]
fn a_known_shift_is_recovered_at_least_as_closely_as_xdem_recovers_it() {
    // The SRTM tile moved by 0.0004° east and 0.0003° south (34 m and 33 m, a third of a pixel):
    // the correction to find is the opposite. Both tools work on the same 0.4° × 0.4° box around
    // 40.42°E 39.6°N, xDEM on both rasters warped (bilinear, 90 m) to a transverse Mercator
    // centred there (so its x and y are east and north at the centre, scale 1); the expected
    // shift is taken at the centre (a shift in degrees varies by ±0.1 m in metres over the box).
    let dir = common::out_path("compare/shift");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let source = repo_path("projects/data/earth_srtm3_demcompare_N39E040.tif");
    let (ref_tif, moved_tif) = (dir.join("ref.tif"), dir.join("moved.tif"));
    std::fs::copy(&source, &ref_tif).unwrap();
    let ullr = ["40.0004", "39.9997", "40.8337333333333", "39.1663666666667"];
    common::run_tool(
        "gdal_translate",
        &[&["-q", "-a_ullr"][..], &ullr, &[ref_tif.to_str().unwrap(), moved_tif.to_str().unwrap()]].concat(),
        "",
    );
    let project = r#"{"format": "terrafuse-project", "version": 2, "body": "wgs84", "layers": [
        {"name": "ref", "kind": "dataset", "store": "ref.gpkg", "source": {"files": ["ref.tif"]}},
        {"name": "moved", "kind": "dataset", "store": "moved.gpkg", "source": {"files": ["moved.tif"]}}]}"#;
    let p = dir.join("shift.json");
    std::fs::write(&p, project).unwrap();
    let ours: serde_json::Value = serde_json::from_str(&run(&[
        "coregister",
        p.to_str().unwrap(),
        "moved",
        "--to",
        "ref",
        "--region",
        "40.22,39.4,40.62,39.8",
        "--json",
    ]))
    .unwrap();
    let (e, n) = metres_of_degrees(-0.0004, 0.0003, 39.6);
    let ours_error = (ours["east_m"].as_f64().unwrap() - e).hypot(ours["north_m"].as_f64().unwrap() - n);
    assert!(ours["converged"].as_bool().unwrap());

    for name in ["ref", "moved"] {
        warp_to_local_tm(&dir, name);
    }
    let python = repo_path(".venv-ref/bin/python");
    let out = std::process::Command::new(&python)
        .arg(repo_path("tests/reference/xdem_nuth_kaab.py"))
        .arg(dir.join("ref_tm.tif"))
        .arg(dir.join("moved_tm.tif"))
        .output()
        .unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let xdem: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let xdem_error = (xdem["shift_x"].as_f64().unwrap() - e).hypot(xdem["shift_y"].as_f64().unwrap() - n);
    println!(
        "known correction east {e:.3} m north {n:.3} m; Terrafuse {:.3} {:.3} (error {ours_error:.3} m), xDEM {:.3} {:.3} (error {xdem_error:.3} m)",
        ours["east_m"], ours["north_m"], xdem["shift_x"], xdem["shift_y"]
    );
    assert!(ours_error <= xdem_error, "Terrafuse errs by {ours_error} m, xDEM by {xdem_error} m");
    // At the data's level, A read bicubically between its samples (bilinearly it errs by 0.38 m
    // there: BENCHMARKS.md).
    assert!(ours_error < 0.1, "{ours_error} m");

    // Applied, the layer moves: A′ − B is noise where A − B was tens of metres.
    let before: serde_json::Value =
        serde_json::from_str(&run(&["compare", p.to_str().unwrap(), "moved", "ref", "--json"])).unwrap();
    run(&["coregister", p.to_str().unwrap(), "moved", "--to", "ref", "--region", "40.22,39.4,40.62,39.8", "--apply"]);
    let saved = Project::load(&p).unwrap();
    let shift = saved.layers[1].shift_m();
    assert!((shift[0] - ours["east_m"].as_f64().unwrap()).abs() < 1e-9, "{shift:?}");
    let after: serde_json::Value =
        serde_json::from_str(&run(&["compare", p.to_str().unwrap(), "moved", "ref", "--json"])).unwrap();
    let (nmad_before, nmad_after) = (before["nmad_m"].as_f64().unwrap(), after["nmad_m"].as_f64().unwrap());
    println!("NMAD before {nmad_before:.3} m, after applying {nmad_after:.3} m");
    assert!(nmad_before > 5.0 && nmad_after < 1.0, "{nmad_before} → {nmad_after}");
}

/// Warps `DIR/NAME.tif` (bilinear, 90 m) to a transverse Mercator centred at 40.42°E 39.6°N, so
/// its x and y are east and north at the centre, scale 1: `DIR/NAME_tm.tif`, for xDEM.
fn warp_to_local_tm(dir: &Path, name: &str) {
    let tm = "+proj=tmerc +lon_0=40.42 +lat_0=39.6 +k=1 +ellps=WGS84 +units=m";
    let (from, to) = (dir.join(format!("{name}.tif")), dir.join(format!("{name}_tm.tif")));
    common::run_tool(
        "gdalwarp",
        &[
            "-q",
            "-overwrite",
            "-t_srs",
            tm,
            "-tr",
            "90",
            "90",
            "-te",
            "-17000",
            "-22000",
            "17000",
            "22000",
            "-r",
            "bilinear",
            "-dstnodata",
            "-9999",
            "-ot",
            "Float32",
            from.to_str().unwrap(),
            to.to_str().unwrap(),
        ],
        "",
    );
}

/// Runs a script of tests/reference in `.venv-ref` and reads the JSON it prints.
fn reference_script(script: &str, args: &[&str]) -> serde_json::Value {
    let out = std::process::Command::new(repo_path(".venv-ref/bin/python"))
        .arg(repo_path(&format!("tests/reference/{script}")))
        .args(args)
        .output()
        .unwrap();
    assert!(out.status.success(), "{script}: {}", String::from_utf8_lossy(&out.stderr));
    if out.stdout.is_empty() {
        return serde_json::Value::Null;
    }
    serde_json::from_slice(&out.stdout).unwrap()
}

#[test]
fn a_known_ramp_and_elevation_bias_are_recovered_and_the_ramp_agrees_with_xdems_deramp() {
    // The SRTM tile with a plane of 0.5 m/km east and −0.3 m/km north (and 2 m at 40.42°E
    // 39.6°N) added, and a copy with 1 cm per metre of elevation above 2000 m added.
    let dir = common::out_path("compare/pipeline");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let source = repo_path("projects/data/earth_srtm3_demcompare_N39E040.tif");
    std::fs::copy(&source, dir.join("ref.tif")).unwrap();
    let (c0, ge, gn) = (2.0, 0.5, -0.3);
    let biased = |name: &str, bias: [f64; 5]| {
        let out = dir.join(format!("{name}.tif"));
        let args: Vec<String> = [source.to_str().unwrap(), out.to_str().unwrap(), "40.42", "39.6"]
            .iter()
            .map(|s| s.to_string())
            .chain(bias.iter().map(|v| v.to_string()))
            .collect();
        reference_script("biased_copy.py", &args.iter().map(String::as_str).collect::<Vec<_>>());
    };
    biased("ramp", [c0, ge, gn, 0.0, 0.0]);
    biased("elev", [0.0, 0.0, 0.0, 0.01, 2000.0]);
    let project = r#"{"format": "terrafuse-project", "version": 2, "body": "wgs84", "layers": [
        {"name": "ref", "kind": "dataset", "store": "ref.gpkg", "source": {"files": ["ref.tif"]}},
        {"name": "ramp", "kind": "dataset", "store": "ramp.gpkg", "source": {"files": ["ramp.tif"]}},
        {"name": "elev", "kind": "dataset", "store": "elev.gpkg", "source": {"files": ["elev.tif"]}}]}"#;
    let p = dir.join("pipeline.json");
    std::fs::write(&p, project).unwrap();
    let region = "40.22,39.4,40.62,39.8";
    let coreg = |a: &str, pipeline: &str| -> serde_json::Value {
        let out = run(&[
            "coregister",
            p.to_str().unwrap(),
            a,
            "--to",
            "ref",
            "--region",
            region,
            "--pipeline",
            pipeline,
            "--json",
        ]);
        serde_json::from_str(&out).unwrap()
    };

    // The ramp: its gradient to 0.2 %, its value at the frame's origin to 1 cm, nothing left.
    let ramp = coreg("ramp", "deramp:1");
    let step = &ramp["steps"][0];
    assert_eq!(step["name"], "deramp");
    let c: Vec<f64> = step["coefficients"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let origin = [step["origin_deg"][0].as_f64().unwrap(), step["origin_deg"][1].as_f64().unwrap()];
    let (e0, n0) = metres_of_degrees(origin[0] - 40.42, origin[1] - 39.6, 39.6);
    let at_origin = c0 + ge * e0 / 1000.0 + gn * n0 / 1000.0;
    println!("deramp: {c:?} about {origin:?}; known {at_origin:.4} {ge} {gn}");
    assert!((c[1] - ge).abs() < 0.002 * ge.abs() && (c[2] - gn).abs() < 0.002 * gn.abs(), "{c:?}");
    assert!((c[0] - at_origin).abs() < 0.01, "{} vs {at_origin}", c[0]);
    assert!(ramp["after"]["nmad_m"].as_f64().unwrap() < 0.02, "{}", ramp["after"]);
    assert!(ramp["before"]["nmad_m"].as_f64().unwrap() > 1.0, "{}", ramp["before"]);

    // The elevation bias: every bin's median within half a bin's bias of the law, nothing left.
    // Bins are by A's elevation h_A = h + 0.01·(h − 2000), so the law in h_A is
    // 0.01·(h_A − 2000) / 1.01.
    let elev = coreg("elev", "terrain_bias:elevation");
    let bins = elev["steps"][0]["bins"].as_array().unwrap();
    let width = bins[1][0].as_f64().unwrap() - bins[0][0].as_f64().unwrap();
    for b in bins {
        let (h, bias) = (b[0].as_f64().unwrap(), b[1].as_f64().unwrap());
        assert!((bias - 0.01 * (h - 2000.0) / 1.01).abs() <= 0.01 * width * 0.5 + 1e-3, "bin at {h} m: {bias}");
    }
    let (before, after) =
        (elev["steps"][0]["before"]["nmad_m"].as_f64().unwrap(), elev["after"]["nmad_m"].as_f64().unwrap());
    println!("terrain_bias:elevation: {} bins of {width:.1} m, NMAD {before:.3} → {after:.4} m", bins.len());
    assert!(before > 1.0 && after < 0.02, "{before} → {after}");

    // xDEM's TerrainBias("elevation") on the same pair warped to the local transverse Mercator:
    // the correction at four reference elevations h (ours is binned by A's elevation
    // h_A = h + 0.01·(h − 2000), xDEM's by B's, so compared at the same h): ours within 3 cm of
    // the law, within 10 cm of xDEM's (which is up to 7 cm off the law at 2800 m: it fits by
    // B's elevation and applies by the corrected DEM's), and less NMAD left than xDEM leaves.
    for name in ["ref", "elev"] {
        warp_to_local_tm(&dir, name);
    }
    let heights = [1600.0, 2000.0, 2400.0, 2800.0];
    let list = heights.map(|h| h.to_string()).join(",");
    let x = reference_script(
        "xdem_terrain_bias.py",
        &[dir.join("ref_tm.tif").to_str().unwrap(), dir.join("elev_tm.tif").to_str().unwrap(), &list],
    );
    let ours_bins: Vec<[f64; 2]> = bins.iter().map(|b| [b[0].as_f64().unwrap(), b[1].as_f64().unwrap()]).collect();
    for (k, h) in heights.iter().enumerate() {
        let ours = terrafuse::layers::correction::binned_at(&ours_bins, h + 0.01 * (h - 2000.0));
        let theirs = x["bias_at"][k].as_f64().unwrap();
        println!(
            "terrain bias at {h} m: Terrafuse {ours:+.4} m, xDEM {theirs:+.4} m, law {:+.4} m",
            0.01 * (h - 2000.0)
        );
        assert!((ours - 0.01 * (h - 2000.0)).abs() < 0.03, "at {h} m: ours {ours}");
        assert!((ours - theirs).abs() < 0.1, "at {h} m: ours {ours}, xDEM {theirs}");
    }
    let theirs = x["nmad_after"].as_f64().unwrap();
    println!("NMAD after: Terrafuse {after:.4} m, xDEM {theirs:.4} m ({:.2} s)", x["seconds"]);
    assert!(after <= theirs, "Terrafuse leaves {after} m, xDEM {theirs} m");

    // Outlines of unstable terrain: a polygon over the box's western half is left out (its
    // samples get the same bias, so the plane is found from the eastern half alone).
    let outlines = dir.join("unstable.geojson");
    std::fs::write(
        &outlines,
        r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry":
        {"type": "Polygon", "coordinates": [[[40.2, 39.3], [40.42, 39.3], [40.42, 39.9], [40.2, 39.9], [40.2, 39.3]]]}}]}"#,
    )
    .unwrap();
    let out = run(&[
        "coregister",
        p.to_str().unwrap(),
        "ramp",
        "--to",
        "ref",
        "--region",
        region,
        "--pipeline",
        "deramp:1",
        "--stable",
        outlines.to_str().unwrap(),
        "--json",
    ]);
    let east_only: serde_json::Value = serde_json::from_str(&out).unwrap();
    let (stable, all) = (east_only["stable_count"].as_u64().unwrap(), ramp["stable_count"].as_u64().unwrap());
    assert!(stable > all * 4 / 10 && stable < all * 6 / 10, "{stable} of {all}");
    assert!(east_only["stable"].as_str().unwrap().contains("unstable.geojson"));
    let c2 = &east_only["steps"][0]["coefficients"];
    assert!((c2[1].as_f64().unwrap() - ge).abs() < 0.004 * ge, "{c2}");
    assert!(east_only["after"]["nmad_m"].as_f64().unwrap() < 0.03, "{}", east_only["after"]);

    // xDEM's Deramp(1) on the same pair warped to a local transverse Mercator: the same gradient
    // within 1 % (both near the known one; the warp's bilinear smoothing is the same on both).
    for name in ["ref", "ramp"] {
        warp_to_local_tm(&dir, name);
    }
    let x = reference_script(
        "xdem_deramp.py",
        &[dir.join("ref_tm.tif").to_str().unwrap(), dir.join("ramp_tm.tif").to_str().unwrap(), "1"],
    );
    let (xe, xn) = (
        (x["east_10km"].as_f64().unwrap() - x["centre"].as_f64().unwrap()) / 10.0,
        (x["north_10km"].as_f64().unwrap() - x["centre"].as_f64().unwrap()) / 10.0,
    );
    println!(
        "gradient m/km: known {ge} {gn}, Terrafuse {:.5} {:.5}, xDEM {xe:.5} {xn:.5} ({:.2} s)",
        c[1], c[2], x["seconds"]
    );
    assert!((c[1] - xe).abs() < 0.01 * ge.abs() && (c[2] - xn).abs() < 0.01 * gn.abs(), "xDEM {xe} {xn}");
    assert!((x["centre"].as_f64().unwrap() - c0).abs() < 0.05, "xDEM at the centre: {}", x["centre"]);
}

#[test]
fn the_erzurum_pair_is_three_and_five_pixels_apart_as_demcompare_finds() {
    // demcompare's own answer for its pair: 3 pixels east and 5 north (3″ pixels: 71.5 m east and
    // 92.6 m north at 39.6°N). On a central box of the tile.
    let p = project();
    let c: serde_json::Value = serde_json::from_str(&run(&[
        "coregister",
        p.to_str().unwrap(),
        "blurred",
        "--to",
        "srtm",
        "--region",
        "40.3,39.45,40.6,39.75",
        "--json",
    ]))
    .unwrap();
    let (px_e, px_n) = metres_of_degrees(1.0 / 1200.0, 1.0 / 1200.0, 39.6);
    let (east_px, north_px) = (c["east_m"].as_f64().unwrap() / px_e, c["north_m"].as_f64().unwrap() / px_n);
    println!("blurred onto srtm: east {east_px:.3} px, north {north_px:.3} px, {} iterations", c["iterations"]);
    assert!((east_px - 3.0).abs() < 0.1 && (north_px + 5.0).abs() < 0.1, "{east_px} {north_px}");
    let (before, after) = (c["before"]["nmad_m"].as_f64().unwrap(), c["after"]["nmad_m"].as_f64().unwrap());
    assert!(after < before / 10.0, "NMAD {before} → {after}");
    // Bad input: the reference itself, an unknown layer.
    let out = terrafuse(&["coregister", p.to_str().unwrap(), "srtm", "--to", "srtm"], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("'srtm' co-registered onto itself"));
    let out = terrafuse(&["coregister", p.to_str().unwrap(), "blurred", "--to", "nope"], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("layer 'nope' is not in the project"));
}

#[test]
fn a_profile_follows_the_geodesic_as_geographiclib_computes_it_and_samples_every_visible_layer() {
    let p = project();
    let csv = common::out_path("compare/profile.csv");
    let report = run(&[
        "profile",
        p.to_str().unwrap(),
        "--from",
        "39.3,40.1",
        "--to",
        "39.85,40.75",
        "--samples",
        "201",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(report.contains("201 samples at level 9") && report.contains("composed"), "{report}");
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(lines.next().unwrap(), "distance_m,lat_deg,lon_deg,srtm,composed"); // blurred is hidden
    let rows: Vec<Vec<f64>> = lines.map(|l| l.split(',').map(|v| v.parse().unwrap()).collect()).collect();
    assert_eq!(rows.len(), 201);
    // The line's length and points against GeographicLib's GeodSolve (inverse, then direct).
    let inverse = common::run_tool("GeodSolve", &["-i", "-p", "9"], "39.3 40.1 39.85 40.75\n");
    let v: Vec<f64> = inverse.split_whitespace().map(|x| x.parse().unwrap()).collect();
    let (azimuth, length) = (v[0], v[2]);
    assert!((rows[200][0] - length).abs() < 1e-3, "length {} against GeodSolve {length}", rows[200][0]);
    let input: String = rows.iter().map(|r| format!("39.3 40.1 {azimuth} {}\n", r[0])).collect();
    let direct = common::run_tool("GeodSolve", &["-p", "9"], &input);
    for (row, line) in rows.iter().zip(direct.lines()) {
        let g: Vec<f64> = line.split_whitespace().map(|x| x.parse().unwrap()).collect();
        assert!((row[1] - g[0]).abs() < 1e-8 && (row[2] - g[1]).abs() < 1e-8, "{row:?} against {line}");
    }
    // With SRTM the only visible layer, the composed stack is SRTM.
    let with_data = rows.iter().filter(|r| !r[3].is_nan()).count();
    assert!(with_data > 190, "{with_data}");
    for r in &rows {
        assert!(r[3].is_nan() && r[4].is_nan() || (r[3] - r[4]).abs() < 1e-3, "{r:?}");
        assert!(r[3].is_nan() || (1000.0..3500.0).contains(&r[3]), "{r:?}");
    }
    // The line saved in the project is the same line.
    let saved_csv = common::out_path("compare/profile-saved.csv");
    run(&[
        "profile",
        p.to_str().unwrap(),
        "--line",
        "across",
        "--samples",
        "201",
        "--csv",
        saved_csv.to_str().unwrap(),
    ]);
    assert_eq!(std::fs::read_to_string(&saved_csv).unwrap(), text);
    let out = terrafuse(&["profile", p.to_str().unwrap(), "--line", "nope"], "");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("--line nope: not a profile line of the project (saved: across)")
    );
    let out = terrafuse(&["profile", p.to_str().unwrap(), "--from", "95,40", "--to", "39,40"], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("--from: 95,40 is not a latitude, longitude"));
}

#[test]
fn a_swiped_render_shows_a_left_of_the_line_and_b_right_of_it() {
    let p = project();
    let dir = common::out_path("compare");
    let render = |name: &str, extra: &[&str]| {
        let out = dir.join(format!("{name}.png"));
        let mut args =
            vec!["render", p.to_str().unwrap(), "--out", out.to_str().unwrap(), "--width", "320", "--height", "240"];
        args.extend_from_slice(extra);
        let report = run(&args);
        (image::open(&out).unwrap().to_rgba8(), report)
    };
    let (swiped, report) = render("swipe", &["--swipe", "blurred,srtm,0.25"]);
    assert!(report.contains("swipe: 'blurred' left of 25 % of the width, 'srtm' right of it"), "{report}");
    // Right of the line: exactly the plain render of srtm (the project shows srtm; blurred and
    // the difference layer hidden here).
    let mut shown = Project::load(&p).unwrap();
    for l in &mut shown.layers {
        l.visible = l.name == "srtm";
    }
    let plain_project = dir.join("plain.json");
    shown.save(&plain_project).unwrap();
    let plain_out = dir.join("plain.png");
    run(&[
        "render",
        plain_project.to_str().unwrap(),
        "--out",
        plain_out.to_str().unwrap(),
        "--width",
        "320",
        "--height",
        "240",
    ]);
    let plain = image::open(&plain_out).unwrap().to_rgba8();
    let (w, h) = plain.dimensions();
    let split = (0.25 * f64::from(w)).round() as u32;
    let (mut same, mut different) = (0, 0);
    for y in 0..h {
        for x in 0..w {
            if x > split + 1 {
                assert_eq!(swiped.get_pixel(x, y), plain.get_pixel(x, y), "({x}, {y}) right of the line");
            } else if x + 1 < split {
                if swiped.get_pixel(x, y) == plain.get_pixel(x, y) { same += 1 } else { different += 1 }
            } else {
                assert_eq!(swiped.get_pixel(x, y).0, [255, 255, 255, 255], "the line at ({x}, {y})");
            }
        }
    }
    assert!(different > same, "left of the line should show the blurred layer: {different} differ, {same} same");
    // The swipe saved in the project, with its view.
    let (saved, report) = render("saved", &["--swipe", "blurred-srtm"]);
    assert!(report.contains("swipe: 'blurred' left of 50 % of the width, 'srtm' right of it"), "{report}");
    assert_eq!(saved.dimensions(), (w, h));
    let out = terrafuse(
        &[
            "render",
            p.to_str().unwrap(),
            "--out",
            common::out_path("compare/x.png").to_str().unwrap(),
            "--swipe",
            "blurred,nope",
        ],
        "",
    );
    assert!(String::from_utf8_lossy(&out.stderr).contains("--swipe blurred,nope: layer 'nope' is not in the project"));
}

#[test]
fn the_difference_raster_agrees_with_gdals_difference_of_the_sources() {
    // `terrafuse export --difference blurred,srtm` over a box against the two source rasters
    // warped by gdalwarp (bilinear) to the same grid and subtracted with numpy. Both sides are
    // EGM96 heights turned ellipsoidal by the same geoid, which cancels in the difference.
    let p = project();
    let dir = common::out_path("compare/difference");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let ours = dir.join("dh.tif");
    let box_args = ["--crs", "EPSG:4326", "--bounds", "40.2,39.4,40.6,39.8", "--resolution", "0.001"];
    let report = run(&[
        &["export", p.to_str().unwrap(), ours.to_str().unwrap()][..],
        &box_args,
        &["--difference", "blurred,srtm", "--compose", "cpu"],
    ]
    .concat());
    assert!(report.contains("400×400 pixels"), "{report}");
    for (name, file) in [("a", "earth_srtm3_blurred_shifted_N39E040.tif"), ("b", "earth_srtm3_demcompare_N39E040.tif")]
    {
        let out = dir.join(format!("{name}.tif"));
        common::run_tool(
            "gdalwarp",
            &[
                "-q",
                "-overwrite",
                "-te",
                "40.2",
                "39.4",
                "40.6",
                "39.8",
                "-tr",
                "0.001",
                "0.001",
                "-r",
                "bilinear",
                "-ot",
                "Float32",
                "-dstnodata",
                "nan",
                repo_path(&format!("projects/data/{file}")).to_str().unwrap(),
                out.to_str().unwrap(),
            ],
            "",
        );
    }
    let script = format!(
        "import rasterio, numpy as np\n\
         r = lambda n: rasterio.open('{d}/' + n).read(1).astype(float)\n\
         ours, gdal = r('dh.tif'), r('a.tif') - r('b.tif')\n\
         ok = np.isfinite(ours) & np.isfinite(gdal)\n\
         d = ours[ok] - gdal[ok]\n\
         print(ok.sum(), np.isfinite(gdal).sum(), np.mean(d), np.median(np.abs(d)), np.mean(ours[ok]), np.mean(gdal[ok]))\n",
        d = dir.display()
    );
    let out = std::process::Command::new(repo_path(".venv-ref/bin/python")).args(["-c", &script]).output().unwrap();
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let v: Vec<f64> = String::from_utf8_lossy(&out.stdout).split_whitespace().map(|x| x.parse().unwrap()).collect();
    println!(
        "difference raster against GDAL: {} of {} pixels, mean {:.3} m, median |Δ| {:.3} m; means {:.3} / {:.3} m",
        v[0], v[1], v[2], v[3], v[4], v[5]
    );
    assert!(v[0] >= 0.99 * v[1], "ours has data at {} of GDAL's {} pixels", v[0], v[1]);
    assert!(v[2].abs() < 0.5 && v[3] < 3.0, "mean {} m, median |Δ| {} m", v[2], v[3]);
}

/// A fresh folder `compare/FOLDER` with the project `FOLDER.json` of two layers: `ref`, the
/// bundled SRTM tile, and `name`, a copy with the biases `tests/reference/biased_copy.py` adds
/// (its arguments after LON0 LAT0, which are 40.42°E 39.6°N). The folder and the project.
fn biased_pair(folder: &str, name: &str, bias: &[&str]) -> (PathBuf, PathBuf) {
    let dir = common::out_path(&format!("compare/{folder}"));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let source = repo_path("projects/data/earth_srtm3_demcompare_N39E040.tif");
    std::fs::copy(&source, dir.join("ref.tif")).unwrap();
    let out = dir.join(format!("{name}.tif"));
    let mut args = vec![source.to_str().unwrap(), out.to_str().unwrap(), "40.42", "39.6"];
    args.extend_from_slice(bias);
    reference_script("biased_copy.py", &args);
    let p = dir.join(format!("{folder}.json"));
    let project = format!(
        r#"{{"format": "terrafuse-project", "version": 2, "body": "wgs84", "layers": [
        {{"name": "ref", "kind": "dataset", "store": "ref.gpkg", "source": {{"files": ["ref.tif"]}}}},
        {{"name": "{name}", "kind": "dataset", "store": "{name}.gpkg", "source": {{"files": ["{name}.tif"]}}}}]}}"#
    );
    std::fs::write(&p, project).unwrap();
    (dir, p)
}

#[test]
fn an_applied_pipeline_is_what_compare_export_and_replay_see() {
    // The SRTM tile with a plane of 0.5 m/km east and −0.3 m/km north and 1 cm per metre of
    // elevation above 2000 m, corrected by `--apply`: the layer then holds the ramp and the
    // elevation bias, and every consumer sees the corrected layer (compare's NMAD falls as the
    // co-registration said, the GPU's export and replay agree with the CPU reference).
    let (dir, p) = biased_pair("applied", "both", &["2", "0.5", "-0.3", "0.01", "2000"]);
    let (project, region) = (p.to_str().unwrap(), "40.22,39.4,40.62,39.8");
    let nmad = |json: &str| serde_json::from_str::<serde_json::Value>(json).unwrap()["nmad_m"].as_f64().unwrap();
    let before = nmad(&run(&["compare", project, "both", "ref", "--region", region, "--json"]));

    // A terrain bias by slope cannot be stored: refused before anything is computed or saved.
    let refused = terrafuse(
        &["coregister", project, "both", "--to", "ref", "--pipeline", "deramp:1,terrain_bias:slope", "--apply"],
        "",
    );
    let says = String::from_utf8_lossy(&refused.stderr);
    assert!(!refused.status.success() && says.contains("terrain_bias:slope cannot be stored in a layer"), "{says}");

    // (Nuth & Kääb first would read the elevation bias as a shift: 1.2 m left; see the docs.)
    let pipeline = "deramp:1,terrain_bias:elevation";
    let coreg: serde_json::Value = serde_json::from_str(&run(&[
        "coregister",
        project,
        "both",
        "--to",
        "ref",
        "--region",
        region,
        "--pipeline",
        pipeline,
        "--apply",
        "--json",
    ]))
    .unwrap();
    let saved = Project::load(&p).unwrap();
    let both = saved.layers[1].as_dataset().unwrap();
    let names: Vec<String> = both.correction.iter().map(|b| b.step_name()).collect();
    assert_eq!(names, ["deramp:1", "terrain_bias:elevation"]);
    let after = nmad(&run(&["compare", project, "both", "ref", "--region", region, "--json"]));
    let reported = coreg["after"]["nmad_m"].as_f64().unwrap();
    println!("applied {pipeline}: compare's NMAD {before:.3} m → {after:.4} m; coregister reported {reported:.4} m");
    assert!(before > 1.0, "{before}");
    // What compare sees is what the co-registration reported (the same level; A read bicubically
    // there, the applied layer's composition bilinearly: the same within 1 cm). One pass of the two steps leaves ≈ 1.1 m: the plane,
    // fitted first, takes up part of the elevation bias where height trends across the box
    // (repeating the pair converges: docs/comparison.md).
    assert!(after < before / 5.0 && (after - reported).abs() < 0.01, "{after} m, reported {reported} m");

    // Export on the GPU and on the CPU reference: the same heights to f32 rounding.
    let export = |on: &str| -> Vec<f32> {
        let tif = dir.join(format!("both-{on}.tif"));
        run(&[
            "export",
            project,
            tif.to_str().unwrap(),
            "--crs",
            "EPSG:4326",
            "--bounds",
            "40.3,39.5,40.5,39.7",
            "--resolution",
            "0.002",
            "--compose",
            on,
        ]);
        let raw = tif.with_extension("raw");
        common::run_tool("gdal_translate", &["-q", "-of", "ENVI", tif.to_str().unwrap(), raw.to_str().unwrap()], "");
        std::fs::read(&raw).unwrap().chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect()
    };
    let (gpu, cpu) = (export("gpu"), export("cpu"));
    let worst = gpu
        .iter()
        .zip(&cpu)
        .filter(|(g, c)| !c.is_nan() && !g.is_nan())
        .map(|(g, c)| (g - c).abs())
        .fold(0.0, f32::max);
    assert_eq!(gpu.iter().filter(|v| v.is_nan()).count(), cpu.iter().filter(|v| v.is_nan()).count());
    println!("export GPU − CPU: worst {worst:.2e} m");
    assert!(worst < 0.01, "{worst} m");

    // Replay: a check of the corrected layer composed alone, recorded on the CPU, holds bit for
    // bit on the CPU and within its tolerance on the GPU.
    let mut json: serde_json::Value = serde_json::from_str(&std::fs::read_to_string(&p).unwrap()).unwrap();
    json["checks"] =
        serde_json::json!({"corrected": {"layer": "both", "level": 9, "region": [40.35, 39.55, 40.45, 39.65]}});
    std::fs::write(&p, serde_json::to_string_pretty(&json).unwrap()).unwrap();
    run(&["replay", project, "--record"]);
    run(&["replay", project, "--check"]);
    run(&["replay", project, "--gpu", "--check"]);
}

#[test]
fn the_uncertainty_of_a_mean_change_agrees_with_xdems_spatial_statistics() {
    // The bundled pair, co-registered (so dh is what is left after the shift: the blur), over
    // the 0.3° box the pipeline tests use.
    use terrafuse::compare::{UncertaintyOptions, uncertainty};
    let dir = common::out_path("compare/uncertainty");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let p = sample_project("erzurum-compare", &dir);
    let region = "40.3,39.45,40.6,39.75";
    run(&["coregister", p.to_str().unwrap(), "blurred", "--to", "srtm", "--region", region, "--apply"]);
    let project = Project::load(&p).unwrap();
    let opts = UncertaintyOptions {
        region: Some(region.parse::<terrafuse::geodesy::GeoBox>().unwrap()),
        keep_samples: true,
        ..UncertaintyOptions::default()
    };
    let u = uncertainty(&project, "blurred", "srtm", &opts).unwrap();
    let h = &u.heteroscedasticity;
    let mut csv = String::from("east_m,north_m,dh_m,slope_deg,max_curvature,area_m2,stable,in_area,sigma_m\n");
    for s in &u.samples {
        csv += &format!(
            "{},{},{},{},{},{},{},{},{}\n",
            s.east_m,
            s.north_m,
            s.dh_m,
            s.slope_deg,
            s.max_curvature,
            s.area_m2,
            u8::from(s.stable),
            u8::from(s.in_area),
            h.sigma_m(s.slope_deg, s.max_curvature)
        );
    }
    let (samples, model) = (dir.join("samples.csv"), dir.join("model.json"));
    std::fs::write(&samples, csv).unwrap();
    std::fs::write(&model, serde_json::to_string(&u).unwrap()).unwrap();
    let lags = [500.0, 2000.0, 8000.0];
    let disks_m2 = [2.5e5, 1e6, 4e6];
    let list = |v: &[f64]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>().join(",");
    let x = reference_script(
        "xdem_uncertainty.py",
        &[samples.to_str().unwrap(), model.to_str().unwrap(), &list(&lags), &list(&disks_m2)],
    );
    println!(
        "mean dh {:+.3} ± {:.4} m (xDEM's σ {:.4} m), volume {:+.3e} ± {:.3e} m³ over {:.1} km²; mean error {:.3} m \
         (xDEM's model {:.3} m); N_eff {:.1} (xDEM {:.1}); xDEM {:.1} s",
        u.mean_dh_m,
        u.mean_dh_sigma_m,
        x["sigma_mean_m"].as_f64().unwrap(),
        u.volume_m3,
        u.volume_sigma_m3,
        u.area_m2 / 1e6,
        u.mean_error_m,
        x["mean_error_m"].as_f64().unwrap(),
        u.effective_samples,
        x["neff"].as_f64().unwrap(),
        x["seconds"].as_f64().unwrap()
    );
    println!("variogram: ours {:?}, xDEM {}", u.variogram.models, x["models"]);

    // The binned NMAD: the same samples in the same bins, area-weighted here, counted by xDEM
    // (the cells' areas differ by < 0.1 % in the box): within 2 %.
    let mut compared = 0;
    for (i, row) in h.nmad_m.iter().enumerate() {
        for (j, ours) in row.iter().enumerate() {
            if let (Some(ours), Some(theirs)) = (ours, x["nmad_m"][i][j].as_f64()) {
                assert!((ours / theirs - 1.0).abs() < 0.02, "bin {i},{j}: {ours} vs xDEM {theirs}");
                compared += 1;
            }
        }
    }
    assert!(compared >= 50, "{compared} bins compared");
    // The error models (a quadrature model here, xDEM's interpolated table) over the area: 10 %.
    let theirs = x["mean_error_m"].as_f64().unwrap();
    assert!((u.mean_error_m / theirs - 1.0).abs() < 0.1, "mean error {} vs xDEM {theirs}", u.mean_error_m);
    // The empirical variograms (the same lag bins; our pairs drawn by hash, xDEM's at random)
    // within 10 % wherever both have 1000 pairs.
    let empirical = x["empirical"].as_array().unwrap();
    for bin in &u.variogram.bins {
        let theirs = empirical.iter().find(|r| (r[0].as_f64().unwrap() / bin.lag_m - 1.0).abs() < 1e-6);
        if let Some(r) = theirs.filter(|r| r[2].as_u64().unwrap() >= 1000 && bin.pairs >= 1000) {
            let g = r[1].as_f64().unwrap();
            assert!((bin.gamma / g - 1.0).abs() < 0.1, "γ at {} m: {} vs xDEM {g}", bin.lag_m, bin.gamma);
        }
    }
    // The fitted models (each to its own empirical variogram) at three lags within 10 %, and the
    // σ of a mean over disks of 0.25, 1 and 4 km² (xDEM's neff_circular_approx_numerical, the same
    // mean error): within 10 %. Over the whole 858 km² box the σ hangs on the long range, which
    // these data hardly fix (xDEM's own fits to random draws of pairs give 11–34 km and a σ of
    // 0.38–1.05 m; docs/comparison.md): printed above, not asserted.
    let ours_model = terrafuse::compare::variogram::VariogramModel { models: u.variogram.models.clone() };
    for (k, lag) in lags.iter().enumerate() {
        let (a, b) = (ours_model.gamma(*lag), x["gamma_at"][k].as_f64().unwrap());
        assert!((a / b - 1.0).abs() < 0.1, "γ({lag} m): {a} vs xDEM {b}");
    }
    let in_area = u.samples.iter().filter(|s| s.in_area && s.dh_m.is_finite());
    let (sum, n) = in_area.fold((0.0, 0usize), |(sum, n), s| (sum + h.sigma_m(s.slope_deg, s.max_curvature), n + 1));
    for (k, area) in disks_m2.iter().enumerate() {
        let ours = sum / n as f64 / terrafuse::compare::variogram::neff_disk(&ours_model, *area).sqrt();
        let theirs = x["sigma_disks_m"][k].as_f64().unwrap();
        println!("σ of a mean over {:.2} km²: {ours:.4} m, xDEM {theirs:.4} m", area / 1e6);
        assert!((ours / theirs - 1.0).abs() < 0.1, "σ over {area} m²: {ours} vs xDEM {theirs}");
    }
    // The command line: `--uncertainty --json` adds the object scripts read; `--area` polygons
    // keep their inside (a 0.1° box in the middle here).
    let outline = dir.join("glacier.geojson");
    std::fs::write(
        &outline,
        r#"{"type": "FeatureCollection", "features": [{"type": "Feature", "properties": {}, "geometry":
        {"type": "Polygon", "coordinates": [[[40.4, 39.55], [40.5, 39.55], [40.5, 39.65], [40.4, 39.65], [40.4, 39.55]]]}}]}"#,
    )
    .unwrap();
    let json: serde_json::Value = serde_json::from_str(&run(&[
        "compare",
        p.to_str().unwrap(),
        "blurred",
        "srtm",
        "--region",
        region,
        "--uncertainty",
        "--area",
        outline.to_str().unwrap(),
        "--json",
    ]))
    .unwrap();
    let v = &json["uncertainty"];
    for field in ["mean_dh_m", "mean_dh_sigma_m", "volume_m3", "volume_sigma_m3", "area_m2"] {
        assert!(v[field].as_f64().is_some(), "{field}: {v}");
    }
    assert!(v["variogram"]["models"][0]["range_m"].as_f64().is_some() && v["heteroscedasticity"]["nmad_m"].is_array());
    // 0.1° × 0.1° at 39.6°N: 8.6 km × 11.1 km.
    let km2 = v["area_m2"].as_f64().unwrap() / 1e6;
    assert!((km2 - 95.2).abs() < 2.0, "{km2} km²");
    assert!(v["area"].as_str().unwrap().contains("inside the polygons of"));

    // The volume is the mean times the area, and its σ the mean's.
    assert!((u.volume_m3 - u.mean_dh_m * u.area_m2).abs() <= 1e-6 * u.volume_m3.abs().max(1.0));
    assert!((u.volume_sigma_m3 - u.mean_dh_sigma_m * u.area_m2).abs() <= 1e-6 * u.volume_sigma_m3);
}

#[test]
fn a_pipeline_fitted_on_some_quads_is_replayed_over_every_sample() {
    use terrafuse::compare::{CoregOptions, Step, coregister};
    let p = Project::load(&project()).unwrap();
    let scratch = common::out_path("compare-coreg-scratch");
    let _ = std::fs::remove_dir_all(&scratch);
    std::fs::create_dir_all(&scratch).unwrap();
    let pipeline = vec![Step::NuthKaab, Step::Deramp(1)];
    let base = CoregOptions { level: Some(9), pipeline, scratch: Some(scratch.clone()), ..CoregOptions::default() };
    let all = coregister(&p, "blurred", "srtm", &base).unwrap();
    let some = coregister(&p, "blurred", "srtm", &CoregOptions { fit_quads: Some(12), ..base.clone() }).unwrap();
    assert!(all.quad_count > 12 && all.fit_quad_count == all.quad_count);
    assert_eq!((some.quad_count, some.fit_quad_count), (all.quad_count, 12));
    // Before any step: every sample either way, the same moments bit for bit.
    let (a, b) = (&some.before, &all.before);
    assert_eq!(a.count, b.count);
    assert_eq!([a.mean_m, a.std_m, a.rmse_m].map(f64::to_bits), [b.mean_m, b.std_m, b.rmse_m].map(f64::to_bits));
    assert!((a.median_m - b.median_m).abs() < 1e-9 && (a.nmad_m - b.nmad_m).abs() < 1e-9);
    // The shift from a third of the quads within 2 m of the one from all (a 510 m shift), and the
    // replayed pipeline corrects every sample about as well.
    let moved = (some.east_m - all.east_m).hypot(some.north_m - all.north_m);
    assert!(moved < 2.0, "{moved} m apart");
    assert!((some.after.count as f64) > 0.99 * all.after.count as f64);
    assert!(some.after.nmad_m < 1.1 * all.after.nmad_m, "{} vs {}", some.after.nmad_m, all.after.nmad_m);
    assert!(some.after.nmad_m < b.nmad_m / 10.0);
    assert_eq!(std::fs::read_dir(&scratch).unwrap().count(), 0);
    println!(
        "fitted on 12 of {} quads: shift {moved:.3} m from all's, NMAD after {:.3} m (all {:.3} m)",
        all.quad_count, some.after.nmad_m, all.after.nmad_m
    );
}

#[test]
fn an_uncertainty_fitted_on_some_quads_sums_the_area_over_every_sample() {
    use terrafuse::compare::{UncertaintyOptions, uncertainty};
    let p = Project::load(&project()).unwrap();
    let all = uncertainty(&p, "blurred", "srtm", &UncertaintyOptions::default()).unwrap();
    let opts = UncertaintyOptions { fit_quads: Some(8), ..UncertaintyOptions::default() };
    let some = uncertainty(&p, "blurred", "srtm", &opts).unwrap();
    assert!(all.quad_count > 8 && all.fit_quad_count == all.quad_count, "{} quads", all.quad_count);
    assert_eq!((some.quad_count, some.fit_quad_count), (all.quad_count, 8));
    assert!(some.stable_count < all.stable_count / 2, "{} of {}", some.stable_count, all.stable_count);
    // The area, its mean dh and volume: every sample, in the same order, either way.
    for (name, x, y) in [
        ("area", some.area_m2, all.area_m2),
        ("mean dh", some.mean_dh_m, all.mean_dh_m),
        ("volume", some.volume_m3, all.volume_m3),
    ] {
        assert_eq!(x.to_bits(), y.to_bits(), "{name}: {x} vs {y}");
    }
    // The error model from a quarter of the quads, applied over every sample: its mean σ within
    // 15 % of the model fitted on all of them.
    let ratio = some.mean_error_m / all.mean_error_m;
    assert!((ratio - 1.0).abs() < 0.15, "mean error {} vs {}", some.mean_error_m, all.mean_error_m);
    println!(
        "σ of the mean: {:.4} m fitted on 8 of {} quads, {:.4} m on all; mean error {:.3} vs {:.3} m",
        some.mean_dh_sigma_m, all.quad_count, all.mean_dh_sigma_m, some.mean_error_m, all.mean_error_m
    );
}

#[test]
fn a_known_along_track_sinusoid_is_recovered_and_xdems_directional_bias_is_measured_beside_it() {
    // The SRTM tile with 2 m at a 3 km wavelength along 30° added: `directional:30` finds it,
    // and takes it off. xDEM 0.2.3's DirectionalBias on the same pair warped to the local
    // transverse Mercator is run beside it and printed (with its defaults it fits a ≈ 27 km
    // wavelength of ≈ 1 cm at every angle tried and leaves the 2 m: docs/comparison.md).
    let (dir, p) = biased_pair("directional", "wavy", &["0", "0", "0", "0", "0", "2", "3000", "30"]);
    let region = "40.22,39.4,40.62,39.8";
    let json: serde_json::Value = serde_json::from_str(&run(&[
        "coregister",
        p.to_str().unwrap(),
        "wavy",
        "--to",
        "ref",
        "--region",
        region,
        "--pipeline",
        "directional:30",
        "--json",
    ]))
    .unwrap();
    let step = &json["steps"][0];
    let s = &step["sinusoids"][0];
    let (amplitude, wavelength) = (s["amplitude_m"].as_f64().unwrap(), s["wavelength_m"].as_f64().unwrap());
    let (before, after) = (json["before"]["nmad_m"].as_f64().unwrap(), json["after"]["nmad_m"].as_f64().unwrap());
    println!("directional:30: {amplitude:.4} m at {wavelength:.1} m; NMAD {before:.3} → {after:.4} m");
    assert!((amplitude - 2.0).abs() < 0.04, "amplitude {amplitude}");
    assert!((wavelength - 3000.0).abs() < 30.0, "wavelength {wavelength}");
    assert!(before > 1.5 && after < 0.1, "NMAD {before} → {after}");
    for name in ["ref", "wavy"] {
        warp_to_local_tm(&dir, name);
    }
    let x = reference_script(
        "xdem_directional.py",
        &[dir.join("ref_tm.tif").to_str().unwrap(), dir.join("wavy_tm.tif").to_str().unwrap(), "30"],
    );
    println!(
        "xDEM DirectionalBias(angle=60): {} → NMAD {:.3} m ({:.1} s)",
        x["fit_params"], x["nmad_after"], x["seconds"]
    );
    assert!(after < x["nmad_after"].as_f64().unwrap(), "xDEM leaves {}", x["nmad_after"]);
}

/// The statistics two comparisons' JSON must share: counts and quantiles exactly, the moments
/// and the histogram's weights within 10⁻¹² (their sums run in another order).
fn same_statistics(merged: &serde_json::Value, one: &serde_json::Value, what: &str) {
    let exact = ["count", "nodata_count", "median_m", "nmad_m", "le90_m", "p90_abs_m", "min_m", "max_m"];
    let close = ["mean_m", "std_m", "rmse_m", "weight_sum"];
    for field in exact {
        assert_eq!(merged[field], one[field], "{what}: {field}");
    }
    for field in close {
        if one[field].is_null() {
            assert!(merged[field].is_null(), "{what}: {field}");
            continue;
        }
        let (m, o) = (merged[field].as_f64().unwrap(), one[field].as_f64().unwrap());
        assert!((m - o).abs() <= 1e-12 * o.abs().max(1e-300), "{what}: {field} {m} {o}");
    }
}

#[test]
fn a_comparison_cut_into_shards_merges_to_what_one_process_prints() {
    let p = project();
    let ps = p.to_str().unwrap();
    let dir = common::out_path("compare-shards");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let args = ["blurred", "srtm", "--json", "--level", "9"];
    let one: serde_json::Value = serde_json::from_str(&run(&[&["compare", ps][..], &args[..]].concat())).unwrap();
    for shards in [1, 3, 7] {
        let plan = dir.join(format!("plan-{shards}.json"));
        let plan_s = plan.to_str().unwrap();
        let n = shards.to_string();
        let planned = run(&[&["compare", ps][..], &args[..], &["--plan", plan_s, "--shards", n.as_str()]].concat());
        assert!(planned.contains(&format!("in {shards} shards")), "{planned}");
        // Nothing computed yet: the merge names every shard of round 0 and exits 3.
        let waiting = terrafuse(&["merge", plan_s], "");
        assert_eq!(waiting.status.code(), Some(3), "{}", String::from_utf8_lossy(&waiting.stderr));
        let said = String::from_utf8_lossy(&waiting.stderr).into_owned();
        let all: Vec<String> = (0..shards).map(|i| i.to_string()).collect();
        assert!(said.contains(&format!("round 0 waits for shards {}", all.join(","))), "{said}");
        // One shard by hand, run twice: the second does nothing while others are missing (alone,
        // it goes on to the next round).
        assert!(run(&["shard", plan_s, "0"]).contains("wrote its part of round 0"));
        let again = run(&["shard", plan_s, "0"]);
        let expected = if shards == 1 { "wrote its part of round 1" } else { "its part of round 0 is there already" };
        assert!(again.contains(expected), "{again}");
        if shards > 1 {
            // A shard killed while writing leaves at most its temporary file: it counts as nothing.
            let round = dir.join(format!("plan-{shards}.parts/round-000"));
            std::fs::write(round.join(".shard-000001.json.tmp-4000000-0"), b"{\"format\": \"half").unwrap();
            let waiting = terrafuse(&["merge", plan_s], "");
            let said = String::from_utf8_lossy(&waiting.stderr).into_owned();
            let rest: Vec<String> = (1..shards).map(|i| i.to_string()).collect();
            assert_eq!(waiting.status.code(), Some(3), "{said}");
            assert!(said.contains(&format!("round 0 waits for shards {}", rest.join(","))), "{said}");
        }
        let merged: serde_json::Value = serde_json::from_str(&run(&["shards", "run", plan_s, "--jobs", "2"])).unwrap();
        let what = format!("{shards} shards");
        same_statistics(&merged, &one, &what);
        for field in ["a", "b", "level", "spacing_m", "weighting", "weight_ratio"] {
            assert_eq!(merged[field], one[field], "{what}: {field}");
        }
        assert_eq!(merged["histogram"]["count"], one["histogram"]["count"], "{what}");
        assert_eq!(merged["histogram"]["edges_m"], one["histogram"]["edges_m"], "{what}");
        let classes = |v: &serde_json::Value| v["by_slope"].as_array().unwrap().clone();
        for (m, o) in classes(&merged).iter().zip(&classes(&one)) {
            same_statistics(m, o, &format!("{what}, slope class {}", o["min_deg"]));
        }
    }
    // A part of another plan is refused by name; so is a project changed since the plan.
    let (three, seven) = (dir.join("plan-3.parts"), dir.join("plan-7.parts"));
    std::fs::copy(three.join("round-000/shard-000001.json"), seven.join("round-000/shard-000001.json")).unwrap();
    let refused = terrafuse(&["merge", dir.join("plan-7.json").to_str().unwrap()], "");
    let said = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert!(!refused.status.success() && refused.status.code() != Some(3), "{said}");
    assert!(said.contains("shard-000001.json") && said.contains("another plan"), "{said}");
    let copy = dir.join("changed.json");
    std::fs::copy(&p, &copy).unwrap();
    let plan = dir.join("plan-changed.json");
    run(&[&["compare", copy.to_str().unwrap()][..], &args[..], &["--plan", plan.to_str().unwrap(), "--shards", "2"]]
        .concat());
    let text = std::fs::read_to_string(&copy).unwrap();
    std::fs::write(&copy, text + " ").unwrap();
    let refused = terrafuse(&["shard", plan.to_str().unwrap(), "1"], "");
    let said = String::from_utf8_lossy(&refused.stderr).into_owned();
    assert!(
        !refused.status.success() && said.contains("changed.json") && said.contains("changed since the plan"),
        "{said}"
    );
    assert!(!dir.join("plan-changed.parts/round-000").exists(), "a refused shard wrote nothing");
}

#[test]
fn sharded_comparisons_across_the_antimeridian_and_over_a_cube_corner_merge_to_one_process() {
    let dir = common::out_path("compare-shards-regions");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let project = common::sample_project("moon-brushing", &dir);
    let p = project.to_str().unwrap();
    // A box from 170° E to 170° W, and one about the corner of three cube faces (45° E,
    // 35.26° N: the QSC cube's corner).
    for (what, region, faces) in [("antimeridian", "170,-10,-170,10", 1), ("corner", "40,30,50,40", 3)] {
        let args = ["sculpt", "lola_global", "--json", "--level", "5", "--region", region];
        let one: serde_json::Value = serde_json::from_str(&run(&[&["compare", p][..], &args[..]].concat())).unwrap();
        assert!(one["count"].as_u64().unwrap() > 100_000, "{what}: {one}");
        let plan = dir.join(format!("{what}.json"));
        let plan_s = plan.to_str().unwrap();
        run(&[&["compare", p][..], &args[..], &["--plan", plan_s, "--shards", "3"]].concat());
        let planned: serde_json::Value = serde_json::from_slice(&std::fs::read(&plan).unwrap()).unwrap();
        let on: std::collections::BTreeSet<u64> = planned["shards"]
            .as_array()
            .unwrap()
            .iter()
            .flat_map(|s| s.as_array().unwrap().iter().map(|q| q[0].as_u64().unwrap()))
            .collect();
        assert_eq!(on.len(), faces, "{what}: the quads lie on faces {on:?}");
        let merged: serde_json::Value = serde_json::from_str(&run(&["shards", "run", plan_s, "--jobs", "2"])).unwrap();
        same_statistics(&merged, &one, what);
    }
}

#[test]
fn a_procedural_pair_compares_and_exports_in_shards_as_in_one_process() {
    // The pair of `bench compare-size --procedural`: fBm terrain, and an fBm error added on it.
    let dir = common::out_path("compare-shards-procedural");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let layer = |name: &str, blend: &str, seed: u32, amplitude_m: f64, wavelength_m: f64, octaves: u32| {
        serde_json::json!({
            "name": name, "visible": true, "blend": blend, "opacity": 1.0, "weight": 1.0, "scale": 1.0,
            "offset_m": 0.0, "kind": "procedural",
            "noise": { "type": "fbm", "seed": seed, "amplitude_m": amplitude_m, "wavelength_m": wavelength_m,
                       "octaves": octaves, "lacunarity": 2.0, "gain": 0.5, "where": "everywhere" }
        })
    };
    let mut project = terrafuse::project::Project::new("moon");
    for l in [layer("terrain", "over", 11, 2000.0, 300_000.0, 2), layer("error", "add", 12, 5.0, 20_000.0, 1)] {
        project.layers.push(serde_json::from_value(l).unwrap());
    }
    let path = dir.join("noise-pair.json");
    project.save(&path).unwrap();
    let p = path.to_str().unwrap();
    let args = ["terrain+error", "terrain", "--json", "--level", "4", "--region", "10,10,22,22"];
    let one: serde_json::Value = serde_json::from_str(&run(&[&["compare", p][..], &args[..]].concat())).unwrap();
    // The error field: 5 m of fBm, so an NMAD of metres, and 10⁵ samples or more.
    assert!(one["count"].as_u64().unwrap() > 100_000 && one["nmad_m"].as_f64().unwrap() > 0.5, "{one}");
    for shards in [1, 3, 7] {
        let plan = dir.join(format!("plan-{shards}.json"));
        let plan_s = plan.to_str().unwrap();
        run(&[&["compare", p][..], &args[..], &["--plan", plan_s, "--shards", &shards.to_string()]].concat());
        let merged: serde_json::Value = serde_json::from_str(&run(&["shards", "run", plan_s, "--jobs", "2"])).unwrap();
        same_statistics(&merged, &one, &format!("procedural, {shards} shards"));
    }
    // The stack exported in 3 shards: the single export's pixels, bit for bit.
    let grid = ["--crs", "+proj=longlat +R=1737400 +no_defs", "--bounds", "10,10,22,22", "--resolution", "0.05"];
    let (single, sharded, plan) = (dir.join("single.tif"), dir.join("sharded.tif"), dir.join("export.json"));
    run(&[&["export", p, single.to_str().unwrap()][..], &grid[..], &["--compose", "cpu", "--level", "4"]].concat());
    run(&[
        &["export", p, sharded.to_str().unwrap()][..],
        &grid[..],
        &["--compose", "cpu", "--level", "4", "--plan", plan.to_str().unwrap(), "--shards", "3"],
    ]
    .concat());
    run(&["shards", "run", plan.to_str().unwrap(), "--jobs", "2"]);
    let raw = |tif: &Path| {
        let out = tif.with_extension("raw");
        common::run_tool("gdal_translate", &["-q", "-of", "ENVI", tif.to_str().unwrap(), out.to_str().unwrap()], "");
        std::fs::read(out).unwrap()
    };
    assert_eq!(raw(&single), raw(&sharded), "the sharded export equals the single one byte for byte");
}

#[test]
fn by_slope_sets_the_slope_classes_in_one_process_and_in_shards() {
    let p = project();
    let ps = p.to_str().unwrap();
    let dir = common::out_path("compare-by-slope");
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let args = ["blurred", "srtm", "--json", "--level", "8", "--by-slope", "0,10,30,90"];
    let one: serde_json::Value = serde_json::from_str(&run(&[&["compare", ps][..], &args[..]].concat())).unwrap();
    let classes = |v: &serde_json::Value| -> Vec<(f64, f64)> {
        v["by_slope"]
            .as_array()
            .unwrap()
            .iter()
            .map(|c| (c["min_deg"].as_f64().unwrap(), c["max_deg"].as_f64().unwrap()))
            .collect()
    };
    assert_eq!(classes(&one), [(0.0, 10.0), (10.0, 30.0), (30.0, 90.0)]);
    let plan = dir.join("plan.json");
    run(&[&["compare", ps][..], &args[..], &["--plan", plan.to_str().unwrap(), "--shards", "3"]].concat());
    let merged: serde_json::Value =
        serde_json::from_str(&run(&["shards", "run", plan.to_str().unwrap(), "--jobs", "2"])).unwrap();
    for (m, o) in merged["by_slope"].as_array().unwrap().iter().zip(one["by_slope"].as_array().unwrap()) {
        same_statistics(m, o, &format!("slope class {}", o["min_deg"]));
    }
    for bad in ["10,5", "0,x", "0,95"] {
        let o = terrafuse(&["compare", ps, "blurred", "srtm", "--by-slope", bad], "");
        let said = String::from_utf8_lossy(&o.stderr).into_owned();
        assert!(o.status.code() == Some(1) && said.contains(&format!("--by-slope {bad}")), "{said}");
    }
}
