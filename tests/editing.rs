//! A project changed from several places at once, and editing commands given bad values: every
//! change is kept or refused, never lost; a refused command leaves the project and its stores as
//! they were, byte for byte; a killed command leaves its lock to the next one.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use clap::Parser;
use proptest::prelude::*;
use terrafuse::files::lock::Lock;
use terrafuse::project::Project;

fn terrafuse(args: &[&str]) -> std::process::Output {
    common::terrafuse(args, "")
}

fn text(out: &std::process::Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// A fresh copy of the Moon brushing sample (its store shared with earlier copies in `dir`).
fn brushing_copy(name: &str) -> PathBuf {
    let dir = common::out_path(&format!("editing/{name}"));
    let path = common::sample_project("moon-brushing", &dir);
    // The sample's own copy is reset for each test: every edit of an earlier run undone.
    let fresh = dir.join("session.json");
    std::fs::copy(&path, &fresh).unwrap();
    fresh
}

/// `terrafuse brush PATH --layer sculpt --tool raise` along `points`, waiting `wait` seconds.
fn raise(path: &Path, points: &str, wait: &str) -> std::process::Output {
    let p = path.to_str().unwrap();
    let stroke = ["--tool", "raise", "--radius-m", "20000", "--strength-m", "100", "--path", points];
    terrafuse(&[&["brush", p, "--layer", "sculpt"][..], &stroke, &["--wait", wait]].concat())
}

fn strokes(path: &Path) -> usize {
    Project::load(path).unwrap().layers.iter().find(|l| l.name == "sculpt").unwrap().strokes().len()
}

#[test]
fn eight_commands_brushing_one_project_at_once_add_eight_strokes() {
    let path = brushing_copy("parallel");
    let n = strokes(&path);
    // Started together; each waits for the one before it.
    let children: Vec<std::process::Child> = (0..8)
        .map(|k| {
            let p = format!("{},40;{},41", k as f64 * 0.5, k as f64 * 0.5);
            Command::new(env!("CARGO_BIN_EXE_terrafuse"))
                .args(["brush", path.to_str().unwrap(), "--layer", "sculpt", "--tool", "raise"])
                .args(["--radius-m", "20000", "--strength-m", "100", "--path", &p, "--wait", "300"])
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let outputs: Vec<_> = children.into_iter().map(|c| c.wait_with_output().unwrap()).collect();
    let mut waited = 0;
    for out in &outputs {
        assert!(out.status.success(), "{}", text(out));
        waited += usize::from(String::from_utf8_lossy(&out.stderr).contains("waiting for terrafuse brush, pid"));
    }
    assert_eq!(strokes(&path), n + 8, "the 8 strokes are all kept");
    assert!(waited > 0, "a command that waited says for whom");
    // And the project replays: every one of them is a stroke of the layer.
    let p = Project::load(&path).unwrap();
    let sculpt = p.layers.iter().find(|l| l.name == "sculpt").unwrap();
    let lats: std::collections::BTreeSet<i64> =
        sculpt.strokes()[n..].iter().map(|s| (s.path[0][0] * 2.0).round() as i64).collect();
    assert_eq!(lats.len(), 8, "each command's own stroke");
}

#[test]
fn a_command_waits_for_the_holder_names_it_and_gives_up_changing_nothing() {
    let path = brushing_copy("held");
    let before = std::fs::read(&path).unwrap();
    let held = Lock::acquire(&path, "a test holding the project", Duration::ZERO, &mut |_| {}).unwrap();
    let t = Instant::now();
    let out = raise(&path, "1,40", "1");
    let said = text(&out);
    assert_eq!(out.status.code(), Some(1), "{said}");
    assert!(t.elapsed() >= Duration::from_secs(1), "it waited");
    assert!(said.contains("waiting for a test holding the project, pid"), "{said}");
    assert!(said.contains("nothing was changed") && said.contains("--wait"), "{said}");
    assert_eq!(std::fs::read(&path).unwrap(), before, "the project is as it was");
    drop(held);
    let out = terrafuse(&["brush", path.to_str().unwrap(), "--layer", "sculpt", "--undo", "1", "--wait", "0"]);
    assert!(out.status.success(), "{}", text(&out));
}

#[test]
fn a_killed_holder_leaves_the_lock_to_the_next_command_and_its_run_unsaved() {
    let path = brushing_copy("killed");
    let n = strokes(&path);
    let before = Project::load(&path).unwrap();
    // A long erosion run on a new layer: killed while it holds the project.
    let mut child = Command::new(env!("CARGO_BIN_EXE_terrafuse"))
        .args(["erode", path.to_str().unwrap(), "--layer", "wear", "--create", "--region", "44,-1,46,1"])
        .args(["--level", "7", "--steps", "1000000", "--cpu"])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let lock = terrafuse::files::lock::lock_path(&path);
    let start = Instant::now();
    while !std::fs::read_to_string(&lock).unwrap_or_default().contains(&format!("pid {}", child.id())) {
        assert!(start.elapsed() < Duration::from_secs(60), "the run never took the lock");
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(500));
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let t = Instant::now();
    let out = raise(&path, "1,40", "20");
    assert!(out.status.success(), "{}", text(&out));
    assert!(!text(&out).contains("waiting for"), "the kernel released the lock with the process: {}", text(&out));
    assert!(t.elapsed() < Duration::from_secs(20));
    let after = Project::load(&path).unwrap();
    assert_eq!(strokes(&path), n + 1);
    assert_eq!(after.layers.len(), before.layers.len(), "the killed run made no layer");
    let dir = path.parent().unwrap();
    let temporaries: Vec<String> = walk(dir).into_keys().filter(|f| f.contains(".tmp-")).collect();
    assert!(temporaries.is_empty(), "half-written files left: {temporaries:?}");
}

#[test]
fn processes_opening_a_fresh_copy_import_its_store_once_and_all_draw_quietly() {
    let dir = common::scratch("editing/fresh-import");
    let mut p = Project::load(&common::repo_path("projects/moon-brushing.json")).unwrap();
    for d in p.layers.iter_mut().filter_map(|l| l.as_dataset_mut()) {
        if let Some(s) = &mut d.source {
            s.files = s.files.iter().map(|f| common::repo_path("projects").join(f)).collect();
        }
    }
    let path = dir.join("fresh.json");
    p.save(&path).unwrap();
    let children: Vec<std::process::Child> = (0..3)
        .map(|k| {
            Command::new(env!("CARGO_BIN_EXE_terrafuse"))
                .args(["render", path.to_str().unwrap(), "--width", "64", "--height", "48", "--out"])
                .arg(dir.join(format!("{k}.png")))
                .env_remove("XDG_RUNTIME_DIR")
                .stdout(std::process::Stdio::piped())
                .stderr(std::process::Stdio::piped())
                .spawn()
                .unwrap()
        })
        .collect();
    let mut imported = 0;
    for c in children {
        let out = c.wait_with_output().unwrap();
        assert!(out.status.success(), "{}", text(&out));
        imported += text(&out).matches("imported").count();
        // No desktop session: nothing about one is printed.
        assert!(!text(&out).contains("XDG_RUNTIME_DIR"), "{}", text(&out));
    }
    assert_eq!(imported, 1, "one import, the others waited for it and read it");
}

/// Every file under `dir` (lock files aside: they hold no data) and its bytes.
fn walk(dir: &Path) -> BTreeMap<String, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap().flatten() {
            let p = e.path();
            let name = p.strip_prefix(dir).unwrap().to_string_lossy().into_owned();
            if p.is_dir() {
                stack.push(p);
            } else if !name.ends_with(".lock") {
                out.insert(name, std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// The `terrafuse` command line, as main.rs parses it.
#[derive(Parser)]
struct Cli {
    #[command(subcommand)]
    command: terrafuse::cli::args::Command,
}

/// Runs a command line in this process; its exit status (2 for a refused parse, like clap's).
fn run_in_process(args: &[String]) -> u8 {
    let cli = match Cli::try_parse_from(std::iter::once("terrafuse".to_string()).chain(args.iter().cloned())) {
        Ok(c) => c,
        Err(_) => return 2,
    };
    let var = |_: &str| None;
    let (mut out, mut err) = (Vec::new(), Vec::new());
    let mut console = terrafuse::cli::Console {
        input: &mut std::io::empty(),
        out: &mut out,
        err: &mut err,
        trace: terrafuse::cli::Trace::Off,
        var: &var,
        progress: false,
    };
    match terrafuse::cli::run(cli.command, &mut console) {
        Ok(code) => code,
        Err(e) => {
            let message = terrafuse::errors::chain(&e);
            assert!(!message.contains("{ ") && !message.contains("Some("), "Rust debug text: {message}");
            1
        }
    }
}

/// Values an editing flag may be given: sensible ones, edges, and nonsense.
const VALUES: &[&str] = &[
    "0",
    "1",
    "3",
    "-1",
    "-5",
    "0.5",
    "1e300",
    "-1e300",
    "nan",
    "inf",
    "",
    "abc",
    "1,2",
    "40.2,39.4,40.27,39.45",
    "44,-1,45,0",
    "200,0,210,1",
    "-180,-90,180,90",
    "1,40",
    "1,40;1,41",
    "-2,420;0,44",
    "95,0",
    "0,0;0,0",
    "raise",
    "smooth",
    "ramp",
    "lower",
    "bogus",
    "sculpt",
    "scuplt",
    "lola_global",
    "rain",
    "river",
    "rain_m_s=2e-5",
    "rain_m_s=-1",
    "20000",
    "500",
    "1e-9",
    "30",
    "4",
];
const BRUSH_FLAGS: &[&str] = &[
    "--layer",
    "--tool",
    "--radius-m",
    "--strength-m",
    "--strength",
    "--path",
    "--level",
    "--spacing",
    "--height-m",
    "--undo",
    "--redo",
    "--max-tiles",
    "--wait",
];
const ERODE_FLAGS: &[&str] =
    &["--layer", "--region", "--level", "--steps", "--preset", "--set", "--seed", "--undo", "--redo", "--max-tiles"];

/// An editing command on `project` with random flags (each given or not, with any value).
fn editing_command(project: String) -> impl Strategy<Value = Vec<String>> {
    let flags = |names: &'static [&'static str]| {
        prop::collection::vec((prop::sample::select(names), prop::sample::select(VALUES)), 0..6)
    };
    let with = |head: Vec<String>, f: Vec<(&str, &str)>| {
        let mut a = head;
        f.into_iter().for_each(|(k, v)| a.extend([k.to_string(), v.to_string()]));
        a
    };
    let p = project.clone();
    let brush = flags(BRUSH_FLAGS).prop_map(move |f| with(vec!["brush".into(), p.clone()], f));
    let p = project.clone();
    let erode = (flags(ERODE_FLAGS), any::<bool>()).prop_map(move |(f, create)| {
        let mut head = vec!["erode".into(), p.clone(), "--cpu".into()];
        if create {
            head.push("--create".into());
        }
        with(head, f)
    });
    let p = project.clone();
    let record = Just(vec!["replay".into(), p, "--record".into(), "--wait".into(), "0".into()]);
    let upgrade = prop::sample::select(VALUES)
        .prop_map(move |w| vec!["project".into(), "upgrade".into(), project.clone(), "--wait".into(), w.into()]);
    prop_oneof![4 => brush, 4 => erode, 1 => record, 1 => upgrade]
}

#[test]
fn editing_commands_refuse_bad_flags_and_change_nothing_when_they_do() {
    // No panic whatever the flags; a command that refuses (any exit but 0) leaves the project and
    // its stores byte for byte as they were.
    let project = brushing_copy("random");
    let dir = project.parent().unwrap().to_path_buf();
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig { cases: 48, ..ProptestConfig::default() });
    runner
        .run(&editing_command(project.to_string_lossy().into_owned()), |args| {
            let before = walk(&dir);
            let code = std::panic::catch_unwind(|| run_in_process(&args));
            prop_assert!(code.is_ok(), "panicked on {args:?}");
            if code.unwrap() != 0 {
                let after = walk(&dir);
                let changed: Vec<&String> =
                    before.keys().chain(after.keys()).filter(|k| before.get(*k) != after.get(*k)).collect();
                prop_assert!(changed.is_empty(), "refused {args:?} but changed {changed:?}");
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn coregister_apply_refuses_bad_flags_and_changes_nothing_when_it_does() {
    // The co-registration that stores its correction in a layer: random operands and flags.
    let dir = common::out_path("editing/coregister");
    let project = common::sample_project("erzurum-compare", &dir);
    let names = prop::sample::select(&["blurred", "srtm", "bogus", "blurred - srtm"][..]);
    let flags = prop::collection::vec(
        (
            prop::sample::select(&["--pipeline", "--level", "--region", "--stable", "--wait"][..]),
            prop::sample::select(
                &[
                    "nuth_kaab",
                    "deramp:1",
                    "deramp:9",
                    "",
                    "bogus",
                    "terrain_bias:slope",
                    "vertical",
                    "-1",
                    "0",
                    "30",
                    "9",
                    "40.2,39.4,40.6,39.8",
                    "200,0,210,1",
                    "srtm",
                    "nan",
                ][..],
            ),
        ),
        0..4,
    );
    let path = project.to_string_lossy().into_owned();
    let strategy = (names.clone(), names, flags).prop_map(move |(a, b, f)| {
        let mut args = vec!["coregister".to_string(), path.clone(), a.to_string(), "--to".into(), b.to_string()];
        args.push("--apply".into());
        f.into_iter().for_each(|(k, v)| args.extend([k.to_string(), v.to_string()]));
        args
    });
    let folder = project.parent().unwrap().to_path_buf();
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig { cases: 12, ..ProptestConfig::default() });
    runner
        .run(&strategy, |args| {
            let before = walk(&folder);
            let code = std::panic::catch_unwind(|| run_in_process(&args));
            prop_assert!(code.is_ok(), "panicked on {args:?}");
            if code.unwrap() != 0 {
                let after = walk(&folder);
                let changed: Vec<&String> =
                    before.keys().chain(after.keys()).filter(|k| before.get(*k) != after.get(*k)).collect();
                prop_assert!(changed.is_empty(), "refused {args:?} but changed {changed:?}");
            }
            Ok(())
        })
        .unwrap();
}
