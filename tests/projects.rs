//! Every project in `projects/` and `tests/projects/` is a test of its own (adding a project adds
//! a test): copied into `projects/NAME/` under Cargo's test output folder (`CARGO_TARGET_TMPDIR`) with its sources made absolute and its stores
//! there (rebuilt when the import code or the layers change), replayed on the CPU with
//! `terrafuse replay --check` (every recorded check must hold, bit for bit; a project with an
//! edit or erosion layer must record at least one check of it), and each of its named views
//! rendered headless from the replayed scene (lavapipe in CI) and looked at: a picture with the
//! body in it, not the background alone.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use libtest_mimic::{Arguments, Failed, Trial};
use terrafuse::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, Renderer};
use terrafuse::project::Project;
use terrafuse::replay::{self, Engine};

fn main() {
    let args = Arguments::from_args();
    let mut trials = Vec::new();
    for folder in ["projects", "tests/projects"] {
        let mut files: Vec<PathBuf> = std::fs::read_dir(common::repo_path(folder))
            .expect("the projects folder")
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.extension().is_some_and(|e| e == "json"))
            .collect();
        files.sort();
        for file in files {
            let name = file.file_stem().unwrap().to_string_lossy().into_owned();
            trials.push(Trial::test(format!("{folder}/{name}"), move || replay_and_render(&file)));
        }
    }
    assert!(trials.len() >= 6, "the sample projects are there");
    libtest_mimic::run(&args, trials).exit();
}

/// The project copied into its output folder: sources absolute, stores in a folder of
/// [`common::store_dir`], small GPU pools.
fn copy_into_out(file: &Path) -> Result<PathBuf, Failed> {
    let name = file.file_stem().unwrap().to_string_lossy().into_owned();
    let dir = common::out_path(&format!("projects/{name}"));
    std::fs::create_dir_all(&dir)?;
    let mut p = Project::load(file)?;
    let stores = common::store_dir(&dir, &name, &serde_json::to_string(&p.layers)?);
    let base = p.base_dir.clone();
    for data in p.layers.iter_mut().filter_map(|l| l.as_dataset_mut()) {
        data.store = stores.join(data.store.file_name().unwrap());
        if let Some(source) = &mut data.source {
            source.files = source.files.iter().map(|f| base.join(f)).collect();
        }
    }
    if let Some(f) = &mut p.visuals.colour_map.file {
        *f = base.join(&*f);
    }
    p.detail.gpu_cache_mib = 256;
    let path = dir.join(format!("{name}.json"));
    p.save(&path)?;
    Ok(path)
}

fn replay_and_render(file: &Path) -> Result<(), Failed> {
    let path = copy_into_out(file)?;
    let project = Project::load(&path)?;
    // The replay through the command line, as a user runs it.
    let out = common::terrafuse(&["replay", path.to_str().unwrap(), "--check", "--json"], "");
    let stderr = String::from_utf8_lossy(&out.stderr);
    let report: serde_json::Value =
        serde_json::from_slice(&out.stdout).map_err(|e| format!("replay printed no JSON ({e}): {stderr}"))?;
    if !out.status.success() || report["passed"] != true {
        return Err(format!("replay --check failed: {report:#}\n{stderr}").into());
    }
    let checks = report["checks"].as_array().ok_or("no checks array")?;
    if checks.iter().any(|c| c["ok"] != true) {
        return Err(format!("a check failed: {checks:?}").into());
    }
    for layer in project.layers.iter().filter(|l| l.holds_deltas()) {
        if !project.checks.values().any(|c| c.layer.as_deref() == Some(layer.name.as_str()) && c.digest.is_some()) {
            return Err(format!("layer '{}' is rebuilt but no recorded check covers it", layer.name).into());
        }
    }
    if project.checks.is_empty() {
        return Err("the project records no checks: add some and run terrafuse replay --record".into());
    }
    // Each named view, rendered from the replayed scene.
    let replayed = replay::replay(&project, Engine::Cpu)?;
    let ctx = GpuContext::headless().map_err(|e| format!("a GPU adapter (lavapipe in CI): {e}"))?;
    let mut renderer = Renderer::new(&ctx, replayed.scene, IMAGE_FORMAT)?;
    let background = project.visuals.background;
    let dir = path.parent().unwrap();
    for (view, camera) in &project.views {
        let stats = renderer.settle(camera, 240, 180, Duration::from_secs(120));
        if stats.pending > 0 || !stats.errors.is_empty() {
            return Err(format!("view '{view}' did not settle: {stats:?}").into());
        }
        let image = renderer.render_image(DrawMode::Colour)?;
        image.write_png(&dir.join(format!("{view}.png")))?;
        let terrain = image.rgba.chunks_exact(4).filter(|p| p[..3] != background[..3]).count();
        let share = terrain as f64 / (240.0 * 180.0);
        if share < 0.05 {
            return Err(format!("view '{view}': only {:.1}% of the picture shows the body", share * 100.0).into());
        }
    }
    Ok(())
}
