//! Helpers shared by the integration tests: running the independent reference tools.

#![allow(dead_code)]

use std::io::Write;
use std::path::PathBuf;
use std::process::{Command, Output, Stdio};

/// A path inside the repository.
pub fn repo_path(relative: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR")).join(relative)
}

/// Where a test writes `name` (a file or a folder): under Cargo's folder for integration tests'
/// output (`CARGO_TARGET_TMPDIR`), never in the source tree; its parent folders are made.
pub fn out_path(name: &str) -> PathBuf {
    let path = std::path::Path::new(env!("CARGO_TARGET_TMPDIR")).join(name);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent).unwrap();
    }
    path
}

/// A fresh, empty folder `name` under [`out_path`] (what a previous run left there is removed).
pub fn scratch(name: &str) -> PathBuf {
    let dir = out_path(name);
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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

/// The code an import's result depends on: a store made by other code is stale.
const IMPORT_CODE: [&str; 16] = [
    include_str!("../../src/store/import/mod.rs"),
    include_str!("../../src/store/import/levels.rs"),
    include_str!("../../src/store/resample.rs"),
    include_str!("../../src/store/lattice.rs"),
    include_str!("../../src/ecm/face.rs"),
    include_str!("../../src/store/source.rs"),
    include_str!("../../src/store/gpkg.rs"),
    include_str!("../../src/ecm/grid.rs"),
    include_str!("../../src/ecm/area_mean.rs"),
    include_str!("../../src/store/tile.rs"),
    include_str!("../../src/store/read.rs"),
    include_str!("../../src/ecm/projection.rs"),
    include_str!("../../src/ecm/quad.rs"),
    include_str!("../../src/geodesy/mod.rs"),
    include_str!("../../src/geodesy/ellipsoid.rs"),
    include_str!("../../Cargo.lock"),
];

/// The folder under `dir` for the stores of `key` made from `settings` (the layers' specs as
/// JSON) by this build's import code: `stores-<key>-<digest>`, the digest over both. The key's
/// folders of other digests (made by older code or other settings) are removed, so that no test
/// reads a store an older build left behind.
pub fn store_dir(dir: &std::path::Path, key: &str, settings: &str) -> PathBuf {
    let mut d = terrafuse::edit::cache::Digest::default();
    for code in IMPORT_CODE {
        d = d.with(code.as_bytes());
    }
    let prefix = format!("stores-{key}-");
    let name = format!("{prefix}{:016x}", d.with(settings.as_bytes()).value());
    if let Ok(entries) = std::fs::read_dir(dir) {
        for e in entries.flatten() {
            let file = e.file_name().to_string_lossy().into_owned();
            // Only this key's folders: `stores-erzurum-` must not take `stores-erzurum-erosion-…`.
            let digest =
                file.strip_prefix(&prefix).filter(|d| d.len() == 16 && d.bytes().all(|b| b.is_ascii_hexdigit()));
            if digest.is_some() && file != name {
                let _ = std::fs::remove_dir_all(e.path());
            }
        }
    }
    dir.join(name)
}

/// The sample project `projects/NAME.json` rewritten into `dir`: its store in a folder of
/// [`store_dir`] there, source paths absolute, only the global Moon grid, small GPU pools; its
/// datasets are imported here (once per folder, import code and settings).
pub fn sample_project(name: &str, dir: &std::path::Path) -> PathBuf {
    use terrafuse::project::Project;
    use terrafuse::scene::Scene;
    static LOCK: std::sync::OnceLock<std::sync::Mutex<()>> = std::sync::OnceLock::new();
    let _guard = LOCK.get_or_init(Default::default).lock().unwrap_or_else(|p| p.into_inner());
    let mut p = Project::load(&repo_path(&format!("projects/{name}.json"))).unwrap();
    let stores = store_dir(dir, name, &serde_json::to_string(&p.layers).unwrap());
    for d in p.layers.iter_mut().filter_map(|l| l.as_dataset_mut()) {
        d.store = stores.join(format!("{name}.gpkg"));
        if let Some(s) = &mut d.source {
            s.files = s.files.iter().map(|f| repo_path("projects").join(f)).collect();
        }
    }
    // Keep the tests light: the global Moon grid only, no procedural detail, small GPU pools.
    // Difference, edit and erosion layers stay (the sample sessions).
    use terrafuse::layers::LayerKind;
    p.layers.retain(|d| {
        d.name != "lola_north"
            && matches!(d.kind(), LayerKind::Dataset | LayerKind::Difference | LayerKind::Edit | LayerKind::Erosion)
    });
    p.detail.gpu_cache_mib = 256;
    // The checks hold the whole project's digests (tests/projects.rs verifies them); tests change
    // these copies' layers.
    p.checks.clear();
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(format!("{name}.json"));
    p.save(&path).unwrap();
    Scene::open(&Project::load(&path).unwrap()).unwrap();
    path
}
