//! `terrafuse analyze cutoff` and `terrafuse bench accuracy` as a user runs them: the table, the
//! CSV that scripts read, the plot, and clear errors for bad options.

mod common;

use std::process::{Command, Output};

fn terrafuse(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_terrafuse")).args(args).output().expect("terrafuse runs")
}

#[test]
fn the_cutoff_table_lists_every_level_and_the_rule_holds_on_it() {
    let out = terrafuse(&["analyze", "cutoff", "--body", "mars", "--max-level", "24", "--samples", "9"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = String::from_utf8(out.stdout).unwrap();
    let rows: Vec<Vec<&str>> = text
        .lines()
        .map(|l| l.split_whitespace().collect::<Vec<_>>())
        .filter(|c| c.len() == 12 && c[0].parse::<u8>().is_ok())
        .collect();
    assert_eq!(rows.len(), 25, "{text}");
    let mut flat_levels = 0;
    for r in &rows {
        let (tolerance, flat_error): (f64, f64) = (r[6].parse().unwrap(), r[9].parse().unwrap());
        assert!(flat_error < tolerance, "level {}: flat error {flat_error} ≥ tolerance {tolerance}", r[0]);
        flat_levels += usize::from(r[7] != "-");
    }
    assert!(flat_levels >= 1, "{text}");
    // Level 1: 24 maps without sharing, 2 with it.
    assert_eq!((rows[1][10], rows[1][11]), ("24", "2"));
}

#[test]
fn bench_accuracy_writes_the_csv_and_the_plot() {
    let dir = common::scratch("bench-accuracy");
    let (csv, png) = (dir.join("accuracy.csv"), dir.join("accuracy.png"));
    let out = terrafuse(&[
        "bench",
        "accuracy",
        "--bodies",
        "moon,a=6378137,b=6356752.314245",
        "--levels",
        "3,15,25",
        "--distances",
        "1,1e5",
        "--trials",
        "2",
        "--vertices",
        "8",
        "--samples",
        "65",
        "--no-timing",
        "--csv",
        csv.to_str().unwrap(),
        "--plot",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let text = std::fs::read_to_string(&csv).unwrap();
    let mut lines = text.lines();
    assert_eq!(
        lines.next(),
        Some("approach,body,level,camera_distance_m,max_error_m,rms_error_m,f32_limit_m,ratio_to_limit")
    );
    let rows: Vec<Vec<String>> = lines.map(|l| l.split(',').map(str::to_string).collect()).collect();
    // 2 bodies × 3 levels × 2 distances × 6 approaches.
    assert_eq!(rows.len(), 72);
    for r in &rows {
        let v: Vec<f64> = r[3..].iter().map(|x| x.parse().unwrap()).collect();
        assert!(v.iter().all(|x| x.is_finite() && *x >= 0.0) && v[2] <= v[1], "{r:?}");
        if r[0] == "ecm" {
            assert!(v[4] <= 2.0, "ECM above 2× the f32 limit: {r:?}");
        }
    }
    let names: std::collections::BTreeSet<&str> = rows.iter().map(|r| r[0].as_str()).collect();
    assert_eq!(
        names.into_iter().collect::<Vec<_>>(),
        ["ecm", "ecm-cutoff", "ecm-paper", "linear-camera-relative", "naive-f32", "sphere"]
    );
    let image = image::open(&png).expect("the plot is a PNG");
    assert_eq!((image.width(), image.height()), (1120, 1000));
    // Not a blank canvas: lines in several colours.
    let rgb = image.to_rgb8();
    let coloured = rgb.pixels().filter(|p| p[0].abs_diff(p[1]) > 40 || p[1].abs_diff(p[2]) > 40).count();
    assert!(coloured > 2000, "{coloured} coloured pixels");
}

#[test]
fn bad_bench_options_are_refused_with_a_message() {
    for (args, expected) in [
        (vec!["bench", "accuracy", "--levels", "0-31"], "level 31"),
        (vec!["bench", "accuracy", "--distances", "1,-5"], "-5"),
        (vec!["bench", "accuracy", "--bodies", "pluto"], "pluto"),
        (vec!["analyze", "cutoff", "--tolerance-m", "0"], "tolerance"),
    ] {
        let out = terrafuse(&args);
        assert!(!out.status.success(), "{args:?} succeeded");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(err.contains(expected), "{args:?}: {err}");
    }
    // A folder that cannot be made (its parent is a file).
    let dir = common::scratch("bench-unwritable");
    std::fs::write(dir.join("file"), b"x").unwrap();
    let csv = dir.join("file/a.csv");
    let out = terrafuse(&[
        "bench",
        "accuracy",
        "--levels",
        "3",
        "--distances",
        "10",
        "--trials",
        "1",
        "--samples",
        "9",
        "--no-timing",
        "--csv",
        csv.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("a.csv"));
}
