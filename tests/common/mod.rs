//! Helpers shared by the integration tests: running the independent reference tools.

#![allow(dead_code)]

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

/// A path inside the repository.
pub fn repo_path(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// Runs `program args…` with `input` on stdin and returns its status, stdout and stderr. A
/// program that exits before reading its input (a refused argument) is not an error here.
pub fn run_piped(program: &str, args: &[&str], input: &str) -> std::io::Result<Output> {
    let mut child =
        Command::new(program).args(args).stdin(Stdio::piped()).stdout(Stdio::piped()).stderr(Stdio::piped()).spawn()?;
    let mut stdin = child.stdin.take().expect("stdin is piped");
    let text = input.to_string();
    let writer = std::thread::spawn(move || {
        let _ = stdin.write_all(text.as_bytes());
    });
    let output = child.wait_with_output()?;
    writer.join().expect("writer thread");
    Ok(output)
}

/// Runs the `terrafuse` binary of this build with `stdin` as input.
pub fn terrafuse(args: &[&str], stdin: &str) -> Output {
    run_piped(env!("CARGO_BIN_EXE_terrafuse"), args, stdin).expect("terrafuse runs")
}

/// Runs `program args…` with `input` on stdin and returns stdout. Panics with a message that
/// says how to install the tool when it is missing, and shows stderr when it fails.
pub fn run_tool(program: &str, args: &[&str], input: &str) -> String {
    let output = run_piped(program, args, input).unwrap_or_else(|e| {
        panic!("cannot run {program} ({e}); install the reference tools with scripts/install-deps")
    });
    assert!(output.status.success(), "{program} {args:?} failed: {}", String::from_utf8_lossy(&output.stderr));
    String::from_utf8(output.stdout).expect("tool prints UTF-8")
}

/// Parses whitespace-separated numbers of every non-comment line.
pub fn parse_rows(text: &str) -> Vec<Vec<f64>> {
    text.lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| l.split_whitespace().map(|f| f.parse::<f64>().unwrap_or(f64::NAN)).collect())
        .collect()
}

/// The system Python with Debian's mpmath (python3-mpmath), not a user's virtual environment.
pub const PYTHON: &str = "/usr/bin/python3";

/// The sample project `projects/NAME.json` rewritten into `dir`: its store there, source paths
/// absolute, only the global Moon grid, small GPU pools; its datasets are imported here (once
/// per folder and test run).
pub fn sample_project(name: &str, dir: &std::path::Path) -> PathBuf {
    use terrafuse::gpu::Scene;
    use terrafuse::project::Project;
    static LOCK: std::sync::OnceLock<std::sync::Mutex<()>> = std::sync::OnceLock::new();
    let _guard = LOCK.get_or_init(Default::default).lock().unwrap_or_else(|p| p.into_inner());
    let mut p = Project::load(&repo_path(&format!("projects/{name}.json"))).unwrap();
    for d in &mut p.layers {
        if d.store.is_some() {
            d.store = Some(dir.join(format!("{name}.gpkg")));
        }
        if let Some(s) = &mut d.source {
            s.files = s.files.iter().map(|f| repo_path("projects").join(f)).collect();
        }
    }
    // Keep the tests light: the global Moon grid only, no procedural detail, small GPU pools.
    // Difference, edit and erosion layers stay (the sample sessions).
    use terrafuse::layers::LayerKind;
    p.layers.retain(|d| {
        d.name != "lola_north"
            && matches!(d.kind, LayerKind::Dataset | LayerKind::Difference | LayerKind::Edit | LayerKind::Erosion)
    });
    p.detail.gpu_cache_mib = 256;
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.json"));
    p.save(&path).unwrap();
    Scene::open(&Project::load(&path).unwrap()).unwrap();
    path
}
