//! Project files that survive anything: saves killed at random moments, bad files refused with
//! the file, the field and the problem, a fuzzed loader that never panics, and large operation
//! logs.

mod common;

use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use common::{repo_path, terrafuse};
use proptest::prelude::*;
use terrafuse::edit::{Falloff, Stroke, Tool};
use terrafuse::layers::LayerSpec;
use terrafuse::project::Project;

/// A Moon project with an edit layer of `n` strokes (no store: it loads without opening one).
fn project_of_strokes(n: usize) -> Project {
    let mut p = Project::new("moon");
    let mut edit = LayerSpec::edit("sculpt");
    edit.as_edit_mut().unwrap().strokes = (0..n)
        .map(|k| Stroke {
            tool: if k % 3 == 0 { Tool::Lower } else { Tool::Raise },
            radius_m: 2000.0 + (k % 7) as f64 * 100.0,
            strength: 5.0,
            falloff: Falloff::Smooth,
            spacing: 0.25,
            level: 8,
            path: (0..4).map(|j| [(k % 89) as f64 * 0.01 + j as f64 * 0.003, (k / 89) as f64 * 0.01]).collect(),
            seed: k as u32,
            height_m: None,
        })
        .collect();
    p.layers.push(edit);
    p
}

#[test]
fn saves_killed_at_random_moments_leave_the_old_or_the_new_project() {
    // `terrafuse project upgrade A --out T` and `… B --out T` in turn, each killed after a
    // random delay within a run's length: T is A or B every time (never cut short, never a mix),
    // and the kills that hit a write leave only a temporary file, which the next save removes.
    let dir = common::scratch("project-files/killed");
    let (a, b, target) = (dir.join("a.json"), dir.join("b.json"), dir.join("t.json"));
    let small = project_of_strokes(20_000);
    let mut large = small.clone();
    let more = project_of_strokes(20_001).layers[0].strokes()[20_000..].to_vec();
    large.layers[0].as_edit_mut().unwrap().strokes.extend(more);
    small.save(&a).unwrap();
    large.save(&b).unwrap();
    small.save(&target).unwrap();
    let upgrade = |from: &Path| {
        Command::new(env!("CARGO_BIN_EXE_terrafuse"))
            .args(["project", "upgrade", from.to_str().unwrap(), "--out", target.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap()
    };
    // How long a whole run takes here.
    let t = Instant::now();
    assert!(upgrade(&a).wait().unwrap().success());
    let run = t.elapsed();
    let mut rng = rand::rng();
    let (mut kills, mut mid_write) = (0, 0);
    for k in 0..300 {
        let mut child = upgrade(if k % 2 == 0 { &b } else { &a });
        if k % 4 == 3 {
            // Every fourth: kill as soon as the save's temporary file shows, so that some kills
            // land while it writes however short the write is against the process's start (a
            // random delay alone missed it 168 times running on a loaded machine).
            let t = Instant::now();
            let writing = || {
                std::fs::read_dir(&dir)
                    .map(|d| {
                        d.filter_map(Result::ok).any(|e| e.file_name().to_string_lossy().starts_with(".t.json.tmp-"))
                    })
                    .unwrap_or(false)
            };
            while child.try_wait().unwrap().is_none() && !writing() && t.elapsed() < run * 3 {
                std::thread::sleep(Duration::from_micros(200));
            }
        } else {
            let delay = run.mul_f64(rand::Rng::random_range(&mut rng, 0.05..1.1));
            std::thread::sleep(delay.min(Duration::from_secs(10)));
        }
        if child.try_wait().unwrap().is_none() {
            child.kill().unwrap();
            kills += 1;
        }
        child.wait().unwrap();
        let orphans = terrafuse::files::orphans(&dir, "t.json");
        mid_write += usize::from(!orphans.is_empty());
        let loaded = Project::load(&target).unwrap_or_else(|e| panic!("after kill {k}: {e}"));
        let n = loaded.layers[0].strokes().len();
        assert!(n == 20_000 || n == 20_001, "after kill {k}: {n} strokes");
        assert!(
            loaded.layers[0].strokes()[..20_000] == small.layers[0].strokes()[..],
            "after kill {k}: strokes differ"
        );
        if mid_write >= 5 && kills >= 20 {
            break;
        }
    }
    eprintln!("{kills} runs killed, {mid_write} of them while writing (a run takes {run:?})");
    assert!(mid_write >= 1, "no kill landed while a save was writing ({kills} kills)");
    // The next save removes what the killed ones left.
    small.save(&target).unwrap();
    assert!(terrafuse::files::orphans(&dir, "t.json").is_empty());
}

/// A version-3 project with `body`, these layers (JSON) and views.
fn with_layers(body: &str, layers: &str) -> String {
    format!(r#"{{"format": "terrafuse-project", "version": 4, "body": "{body}", "layers": [{layers}]}}"#)
}

#[test]
fn bad_project_files_are_refused_naming_the_file_the_field_and_the_problem() {
    let dir = common::scratch("project-files/bad");
    let sample = std::fs::read_to_string(repo_path("projects/moon-brushing.json")).unwrap();
    let erosion = std::fs::read_to_string(repo_path("tests/fuzz/corpus/erosion.json")).unwrap();
    let edit_of = |stroke: &str| {
        with_layers("moon", &format!(r#"{{"name": "e", "kind": "edit", "blend": "add", "strokes": [{stroke}]}}"#))
    };
    let stroke = r#"{"tool": "raise", "radius_m": 2000, "strength": 5, "level": 8, "path": [[0, 0]]}"#;
    let cases: Vec<(&str, String, &str)> = vec![
        (
            "truncated",
            sample[..sample.find("\"strokes\"").unwrap() + 200].to_string(),
            "not valid JSON: layers[1].strokes[",
        ),
        ("not-json", "<?xml version=\"1.0\"?><project/>".into(), "not valid JSON"),
        ("empty", String::new(), "not valid JSON"),
        ("array", "[1, 2]".into(), "a project file is a JSON object"),
        (
            "wrong-type",
            sample.replace("\"radius_m\": 20000.0", "\"radius_m\": \"wide\""),
            "layers[1].strokes[0].radius_m: invalid type: string",
        ),
        ("nan", sample.replace("\"radius_m\": 20000.0", "\"radius_m\": NaN"), "layers[1].strokes[0].radius_m"),
        ("infinite", sample.replace("\"radius_m\": 20000.0", "\"radius_m\": 1e999"), "number out of range"),
        ("radius-of-1e10", with_layers("r=1e10", ""), "body: a semi-major axis of 10000000000.0 m is outside"),
        ("negative-radius", edit_of(&stroke.replace("2000", "-5")), "layers[0]: layer 'e': strokes[0].radius_m"),
        (
            "stroke-beyond-180",
            edit_of(&stroke.replace("[[0, 0]]", "[[0, 420]]")),
            "strokes[0].path: point 0 [0, 420] is not [lat, lon] in degrees (latitude within ±90, longitude within ±180)",
        ),
        (
            "camera-beyond-180",
            sample.replace("\"lon\": 45.0", "\"lon\": 405.0"),
            "camera longitude 405 is outside [-180, 180]",
        ),
        (
            "unknown-colour-map",
            sample.replace("\"preset\": \"viridis\"", "\"preset\": \"virdis\""),
            "visuals.colour_map.preset: 'virdis' is not a colour map (did you mean 'viridis'?)",
        ),
        (
            "a-billion-applied",
            with_layers(
                "moon",
                &format!(
                    r#"{{"name": "e", "kind": "edit", "blend": "add", "applied": 1000000000, "strokes": [{stroke}]}}"#
                ),
            ),
            "applied: 1000000000 is past the 1 strokes",
        ),
        (
            "a-billion-steps",
            erosion.replacen("\"steps\": 80", "\"steps\": 1000000000", 1),
            "layers[1]: layer 'erosion': runs[0].steps: 1000000000",
        ),
        (
            "correction-of-a-constant",
            with_layers(
                "moon",
                r#"{"name": "c", "kind": "constant", "height_m": 0, "correction": [{"name": "terrain_bias", "attribute": "elevation", "bins": [[0, 0], [1, 1]]}]}"#,
            ),
            "layer 'c': correction: is not a field of a constant layer",
        ),
        (
            "ramp-with-too-many-coefficients",
            with_layers(
                "moon",
                r#"{"name": "d", "kind": "dataset", "store": "d.gpkg", "correction": [{"name": "deramp", "origin_deg": [0, 0], "order": 1, "coefficients": [1, 2, 3, 4], "box_km": [-1, -1, 1, 1]}]}"#,
            ),
            "layers[0]: layer 'd': correction: deramp:1: has 4 coefficients, its order has 3 terms",
        ),
        (
            "unknown-bias",
            with_layers(
                "moon",
                r#"{"name": "d", "kind": "dataset", "store": "d.gpkg", "correction": [{"name": "tilt", "deg": 3}]}"#,
            ),
            "layers[0].correction[0].name: unknown variant `tilt`, expected one of `deramp`, `terrain_bias`, `directional`",
        ),
        (
            "absurd-opacity",
            with_layers("moon", r#"{"name": "c", "kind": "constant", "height_m": 0, "opacity": 7}"#),
            "layers[0]: layer 'c': opacity: 7 must lie in [0, 1]",
        ),
        (
            "absurd-level",
            edit_of(&stroke.replace("\"level\": 8", "\"level\": 200")),
            "strokes[0].level: 200 must be at most",
        ),
        (
            "unknown-field",
            sample.replace("\"falloff\": \"smooth\",", "\"falloff\": \"smooth\", \"fallof\": 1,"),
            "layers[1].strokes[0].fallof: unknown field `fallof`",
        ),
        ("newer-version", sample.replace("\"version\": 4", "\"version\": 5"), "version: 5 is not supported"),
        (
            "unknown-difference-operand",
            with_layers(
                "moon",
                r#"{"name": "c", "kind": "constant", "height_m": 0}, {"name": "d", "kind": "difference", "of": ["c", "nowhere"]}"#,
            ),
            "nowhere",
        ),
        (
            "difference-cycle",
            with_layers(
                "moon",
                r#"{"name": "c", "kind": "constant", "height_m": 0}, {"name": "d", "kind": "difference", "of": ["c", "d"]}"#,
            ),
            "layers[1]",
        ),
        (
            "duplicate-layer",
            with_layers(
                "moon",
                r#"{"name": "c", "kind": "constant", "height_m": 0}, {"name": "c", "kind": "constant", "height_m": 1}"#,
            ),
            "layers[1]: layer 'c' is listed twice",
        ),
        (
            "bad-check",
            sample.replace("\"level\": 6,\n      \"view\": \"corner\"", "\"level\": 6,\n      \"view\": \"nowhere\""),
            "checks.corner.view: 'nowhere' is not one of the views",
        ),
    ];
    for (name, text, expected) in &cases {
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, text).unwrap();
        let e = Project::load(&path).expect_err(name).to_string();
        assert!(e.starts_with(&path.display().to_string()), "{name}: the file is named: {e}");
        assert!(e.contains(expected), "{name}: expected '{expected}' in: {e}");
        // The command line says the same and exits 1, without a panic.
        let out = terrafuse(&["project", "check", path.to_str().unwrap()], "");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(expected) && !stderr.contains("panicked"), "{name}: {stderr}");
    }
    // Files the project names: a store that is not there with no source, a source that is not
    // there, a store of another body.
    let missing = with_layers("moon", r#"{"name": "g", "kind": "dataset", "store": "nowhere.gpkg"}"#);
    let no_source = with_layers(
        "moon",
        r#"{"name": "g", "kind": "dataset", "store": "nowhere.gpkg", "source": {"files": ["missing.tif"]}}"#,
    );
    let earth_store = common::sample_project("erzurum", &common::out_path("project-files/earth"));
    let earth = Project::load(&earth_store).unwrap();
    let store = earth.layers[0].as_dataset().unwrap().store.clone();
    let other_body =
        with_layers("moon", &format!(r#"{{"name": "srtm", "kind": "dataset", "store": "{}"}}"#, store.display()));
    for (name, text, expected) in [
        ("missing-store", missing, "layers[0].store: "),
        ("missing-source", no_source, "layers[0].source.files[0]: "),
        ("store-of-another-body", other_body, "holds tiles on wgs84"),
    ] {
        let path = dir.join(format!("{name}.json"));
        std::fs::write(&path, &text).unwrap();
        let out = terrafuse(&["project", "check", path.to_str().unwrap()], "");
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(1), "{name}: {stderr}");
        assert!(stderr.contains(&path.display().to_string()) && stderr.contains(expected), "{name}: {stderr}");
        // Opening it to render says the same (and imports nothing).
        let png = dir.join(format!("{name}.png"));
        let out = terrafuse(
            &["render", path.to_str().unwrap(), "--out", png.to_str().unwrap(), "--camera", "0,0,1e6,0,-90"],
            "",
        );
        assert!(!out.status.success() && !png.exists(), "{name}");
    }
    // A file too large to be a project is refused before it is read (a sparse file: no disk).
    let huge = dir.join("huge.json");
    std::fs::File::create(&huge).unwrap().set_len(600 << 20).unwrap();
    let e = Project::load(&huge).unwrap_err().to_string();
    assert!(e.contains("a project file is at most"), "{e}");
}

#[test]
fn a_log_of_ten_thousand_strokes_saves_and_loads_back_the_same() {
    let dir = common::scratch("project-files/large");
    let p = project_of_strokes(10_000);
    let path = dir.join("large.json");
    p.save(&path).unwrap();
    let q = Project::load(&path).unwrap();
    assert!(q.layers == p.layers, "the strokes read back bit for bit");
    let out = terrafuse(&["project", "check", path.to_str().unwrap()], "");
    assert!(String::from_utf8_lossy(&out.stdout).contains("10000 of 10000 strokes applied"));
}

/// The files the fuzzer starts from: the kept corpus (the sample projects are copied there).
fn corpus() -> Vec<(String, String)> {
    let mut files = Vec::new();
    for folder in ["tests/fuzz/corpus", "projects", "tests/projects", "tests/fixtures"] {
        let Ok(entries) = std::fs::read_dir(repo_path(folder)) else { continue };
        for e in entries.flatten() {
            let path = e.path();
            if path.extension().is_some_and(|x| x == "json") {
                files.push((path.display().to_string(), std::fs::read_to_string(&path).unwrap()));
            }
        }
    }
    files.sort();
    files
}

/// Loading never panics; a file that loads is valid, and saving it gives one that loads the same.
fn loads_or_refuses(text: &str) -> Result<(), TestCaseError> {
    match Project::parse(text) {
        Ok(p) => {
            p.check().map_err(|e| TestCaseError::fail(format!("loaded but invalid: {e}")))?;
            let again = Project::parse(&serde_json::to_string(&p).unwrap())
                .map_err(|e| TestCaseError::fail(format!("saved, it does not load again: {e}")))?;
            prop_assert_eq!(again, p);
        }
        Err(e) => prop_assert!(!e.to_string().is_empty()),
    }
    Ok(())
}

#[test]
fn the_kept_regression_cases_are_refused_or_load_without_a_panic() {
    // tests/fuzz/regressions: inputs that once found a problem; `bad-*` must be refused.
    let dir = repo_path("tests/fuzz/regressions");
    let mut seen = 0;
    for e in std::fs::read_dir(&dir).unwrap().flatten() {
        let text = std::fs::read_to_string(e.path()).unwrap();
        let name = e.file_name().to_string_lossy().into_owned();
        let result = std::panic::catch_unwind(|| Project::parse(&text));
        let result = result.unwrap_or_else(|_| panic!("{name}: the loader panicked"));
        if name.starts_with("bad-") {
            assert!(result.is_err(), "{name} loaded");
        }
        seen += 1;
    }
    assert!(seen >= 5, "the regression cases are there");
}

/// A mutation of a JSON text: where and what.
#[derive(Clone, Debug)]
enum Mutation {
    /// Cut it short.
    Truncate(usize),
    /// Replace one byte.
    Byte(usize, u8),
    /// Put a token in.
    Insert(usize, &'static str),
    /// Replace the k-th number with another.
    Number(usize, &'static str),
    /// Delete a span.
    Delete(usize, usize),
}

const TOKENS: [&str; 12] =
    ["{", "}", "[", "]", ",", ":", "\"", "null", "true", "-", "1e999", "\"layers\": [{\"name\": \"x\"}],"];
const NUMBERS: [&str; 10] =
    ["0", "-1", "1e308", "-1e308", "1e10", "4294967296", "18446744073709551616", "0.5", "-0.0", "1e-320"];

fn mutation() -> impl Strategy<Value = Mutation> {
    prop_oneof![
        any::<usize>().prop_map(Mutation::Truncate),
        (any::<usize>(), any::<u8>()).prop_map(|(at, b)| Mutation::Byte(at, b)),
        (any::<usize>(), prop::sample::select(&TOKENS[..])).prop_map(|(at, t)| Mutation::Insert(at, t)),
        (any::<usize>(), prop::sample::select(&NUMBERS[..])).prop_map(|(k, n)| Mutation::Number(k, n)),
        (any::<usize>(), 1usize..64).prop_map(|(at, n)| Mutation::Delete(at, n)),
    ]
}

fn apply(text: &str, m: &Mutation) -> String {
    let mut bytes = text.as_bytes().to_vec();
    let at = |k: usize, len: usize| if len == 0 { 0 } else { k % len };
    match *m {
        Mutation::Truncate(k) => bytes.truncate(at(k, bytes.len())),
        Mutation::Byte(k, b) => {
            let i = at(k, bytes.len());
            if let Some(x) = bytes.get_mut(i) {
                *x = b;
            }
        }
        Mutation::Insert(k, t) => {
            let i = at(k, bytes.len() + 1);
            bytes.splice(i..i, t.bytes());
        }
        Mutation::Number(k, n) => {
            let starts: Vec<usize> = (0..bytes.len())
                .filter(|&i| {
                    bytes[i].is_ascii_digit()
                        && (i == 0 || !bytes[i - 1].is_ascii_alphanumeric() && bytes[i - 1] != b'.')
                })
                .collect();
            if !starts.is_empty() {
                let s = starts[k % starts.len()];
                let e = (s..bytes.len())
                    .find(|&i| !(bytes[i].is_ascii_digit() || b".eE+-".contains(&bytes[i])))
                    .unwrap_or(bytes.len());
                bytes.splice(s..e, n.bytes());
            }
        }
        Mutation::Delete(k, n) => {
            let i = at(k, bytes.len());
            bytes.drain(i..(i + n).min(bytes.len()));
        }
    }
    String::from_utf8_lossy(&bytes).into_owned()
}

proptest! {
    #![proptest_config(ProptestConfig {
        // PROPTEST_CASES raises it for a long local run.
        cases: std::env::var("PROPTEST_CASES").ok().and_then(|n| n.parse().ok()).unwrap_or(5000),
        failure_persistence: Some(Box::new(proptest::test_runner::FileFailurePersistence::Direct(
            concat!(env!("CARGO_MANIFEST_DIR"), "/tests/fuzz/loader.proptest-regressions"),
        ))),
        ..ProptestConfig::default()
    })]

    /// One to three mutations of a corpus file: the loader refuses or loads a valid project, never
    /// panics.
    #[test]
    fn the_loader_survives_mutated_projects(pick in any::<usize>(), mutations in prop::collection::vec(mutation(), 1..4)) {
        let files = corpus();
        let (_, text) = &files[pick % files.len()];
        let mut text = text.clone();
        for m in &mutations {
            text = apply(&text, m);
        }
        loads_or_refuses(&text)?;
    }
}

#[test]
fn replay_check_passes_as_recorded_and_names_the_layer_and_first_differing_tile() {
    let dir = common::scratch("project-files/replay");
    let path = dir.join("session.json");
    let mut p = Project::new("moon");
    p.layers.push(LayerSpec::constant("datum", -1000.0));
    let mut edit = project_of_strokes(3).layers.remove(0);
    for (k, s) in edit.as_edit_mut().unwrap().strokes.iter_mut().enumerate() {
        s.path = vec![[0.05 * k as f64, 20.0], [0.05 * k as f64 + 0.02, 20.03]];
    }
    p.layers.push(edit);
    p.checks
        .insert("sculpt".into(), terrafuse::project::CheckSpec { layer: Some("sculpt".into()), ..Default::default() });
    p.save(&path).unwrap();
    let replay = |args: &[&str]| terrafuse(&[&["replay", path.to_str().unwrap()][..], args].concat(), "");
    // Not recorded yet: --check fails and says how to record.
    let out = replay(&["--check"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&out.stdout).contains("no digest recorded"));
    let out = replay(&["--record"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let recorded = Project::load(&path).unwrap().checks["sculpt"].clone();
    assert!(recorded.digest.is_some() && recorded.tiles.len() >= 2, "{recorded:?}");
    let out = replay(&["--check"]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stdout));
    // Twice the same, bit for bit.
    let digest = |o: &std::process::Output| -> String {
        let j: serde_json::Value = serde_json::from_slice(&o.stdout).unwrap();
        j["layers"][0]["digest"].as_str().unwrap().to_string()
    };
    assert_eq!(digest(&replay(&["--json"])), digest(&replay(&["--json"])));

    // One tile's recorded digest changed: that tile is named.
    let mut tampered = Project::load(&path).unwrap();
    let (quad, _) = tampered.checks["sculpt"].tiles.iter().nth(1).map(|(q, d)| (q.clone(), d.clone())).unwrap();
    tampered.checks.get_mut("sculpt").unwrap().tiles.insert(quad.clone(), "0000000000000000".into());
    tampered.checks.get_mut("sculpt").unwrap().digest = Some("0000000000000001".into());
    tampered.save(&path).unwrap();
    let out = replay(&["--check"]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(1), "{text}");
    assert!(
        text.contains("check 'sculpt' (layer 'sculpt')")
            && text.contains(&format!("first differing tile {quad} (1 differ)")),
        "{text}"
    );

    // A stroke changed after recording: the replay differs from the record, named.
    let mut changed = p.clone();
    changed.checks.insert("sculpt".into(), recorded);
    changed.layers[1].as_edit_mut().unwrap().strokes[2].strength += 1.0;
    changed.save(&path).unwrap();
    let out = replay(&["--check", "--json"]);
    assert_eq!(out.status.code(), Some(1));
    let j: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(j["passed"], false);
    assert_eq!(j["checks"][0]["ok"], false);
    assert!(j["checks"][0]["first_differing_tile"].is_string(), "{j:#}");
    // --record and --gpu do not go together (the record is the CPU reference's).
    assert!(!replay(&["--record", "--gpu"]).status.success());
}
