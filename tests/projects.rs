//! Every project in `projects/` and `tests/projects/` is a test of its own (adding a project adds
//! a test): copied into `projects/NAME/` under Cargo's test output folder (`CARGO_TARGET_TMPDIR`) with its sources made absolute and its stores
//! there (rebuilt when the import code or the layers change), replayed on the CPU with
//! `terrafuse replay --check` (every recorded check must hold, bit for bit; a project with an
//! edit or erosion layer must record at least one check of it), and each of its named views
//! rendered headless from the replayed scene (lavapipe in CI) and looked at: a picture with the
//! body in it, not the background alone.
//!
//! A second trial per project shows that every recorded check can fail: for each check, what it
//! reads is changed and the check must then report a mismatch, naming what changed. A check of a
//! layer of strokes or runs: its last operation undone, one parameter of it changed, one more
//! added. A check of the stack (placed by a view or a region): the same for the newest operation
//! it reads (the newest whose undoing it sees), else a visible layer moved up a metre; a stack
//! check that sees none of these passes whatever its layers hold and fails the trial. After every
//! layer's last operation is undone and redone, every check holds again.

mod common;

use std::path::{Path, PathBuf};
use std::time::Duration;

use libtest_mimic::{Arguments, Failed, Trial};
use terrafuse::erosion::operation::Operation;
use terrafuse::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, Renderer};
use terrafuse::layers::LayerSpec;
use terrafuse::project::{Project, checks};
use terrafuse::replay::{self, Engine, digest};

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
            let mutated = file.clone();
            trials.push(Trial::test(format!("{folder}/{name}"), move || replay_and_render(&file)));
            trials.push(Trial::test(format!("{folder}/{name}: every check can fail"), move || {
                every_check_can_fail(&mutated)
            }));
        }
    }
    assert!(trials.len() >= 6, "the sample projects are there");
    libtest_mimic::run(&args, trials).exit();
}

/// The project copied into its output folder (`projects/NAME`, or `projects/NAME-SUFFIX`):
/// sources absolute, stores in a folder of [`common::store_dir`], small GPU pools.
fn copy_into_out(file: &Path, suffix: &str) -> Result<PathBuf, Failed> {
    let name = file.file_stem().unwrap().to_string_lossy().into_owned();
    let dir = common::out_path(&format!("projects/{name}{suffix}"));
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
    let path = copy_into_out(file, "")?;
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

/// A project changed as one mutation says.
struct Mutation {
    what: String,
    project: Project,
}

/// What layer `index` of `p` holds: `n` operations in effect (0: none, or not a layer of
/// operations).
fn in_effect(p: &Project, index: usize) -> usize {
    let l = &p.layers[index];
    if l.holds_deltas() { l.applied_strokes().len() + l.applied_runs().len() } else { 0 }
}

/// Operation `op` of layer `index` (a layer of strokes or runs): one parameter of it changed (a
/// stroke's strength, a run's steps or years halved), and it added again at the end (a run
/// shorter).
fn changes_of(p: &Project, index: usize, op: usize) -> Vec<Mutation> {
    let name = p.layers[index].name.clone();
    let with = |f: &dyn Fn(&mut LayerSpec)| {
        let mut q = p.clone();
        f(&mut q.layers[index]);
        q
    };
    let shorter = |op: &mut Operation, by: f64| match &mut op.stream_power {
        Some(sp) => {
            sp.years = (sp.years / by).max(sp.dt_years);
            op.steps = sp.steps();
        }
        None => op.steps = ((op.steps as f64 / by) as u64).max(1),
    };
    if p.layers[index].as_edit().is_some() {
        vec![
            Mutation {
                what: format!("layer '{name}': stroke {op}'s strength changed"),
                project: with(&|l| {
                    let s = &mut l.as_edit_mut().unwrap().strokes[op];
                    s.strength = if s.tool.strength_in_metres() { s.strength * 1.5 + 1.0 } else { s.strength * 0.5 };
                }),
            },
            Mutation {
                what: format!("layer '{name}': stroke {op} drawn once more"),
                project: with(&|l| {
                    let again = l.applied_strokes()[op].clone();
                    l.record_stroke(again).unwrap();
                }),
            },
        ]
    } else {
        vec![
            Mutation {
                what: format!("layer '{name}': run {op}'s steps halved"),
                project: with(&|l| shorter(&mut l.as_erosion_mut().unwrap().runs[op], 2.0)),
            },
            Mutation {
                what: format!("layer '{name}': run {op} once more (shorter)"),
                project: with(&|l| {
                    let mut again = l.applied_runs()[op].clone();
                    shorter(&mut again, 10.0);
                    l.record_run(again).unwrap();
                }),
            },
        ]
    }
}

/// `p` with layer `index`'s last `n` operations undone.
fn undone(p: &Project, index: usize, n: usize) -> Project {
    let mut q = p.clone();
    q.layers[index].move_applied(Some(n), None).unwrap();
    q
}

/// The replays made so far, by the project's JSON: a mutation that several checks see is
/// replayed once.
#[derive(Default)]
struct Replays(std::collections::HashMap<String, replay::Replayed>);

impl Replays {
    /// Whether check `name` reports a mismatch on `p` (and, with its inputs recorded, names what
    /// changed: else an error).
    fn breaks(&mut self, p: &Project, name: &str) -> Result<bool, Failed> {
        let key = serde_json::to_string(p)?;
        if !self.0.contains_key(&key) {
            let replayed = replay::replay(p, Engine::Cpu)?;
            self.0.insert(key.clone(), replayed);
        }
        let check = &p.checks[name];
        let got = replay::evaluate(&self.0[&key].scene, p, name, check)?;
        if digest::compare(check, &got).is_ok() {
            return Ok(false);
        }
        if check.inputs.is_empty() {
            return Err(format!("check '{name}' records no inputs: record it again").into());
        }
        if checks::changed_inputs(&check.inputs, &checks::inputs(p, check)).is_empty() {
            return Err(format!("check '{name}' fails but its inputs do not say what changed").into());
        }
        Ok(true)
    }
}

/// The mutations check `name` must see: for a layer of operations it names, the last one
/// undone, changed and added again; for the stack, the same for the newest operation it reads;
/// for a layer without operations (or a stack that reads no operation), a layer moved up 1 m.
fn mutations_for(replays: &mut Replays, p: &Project, name: &str) -> Result<Vec<Mutation>, Failed> {
    let check = &p.checks[name];
    let index_of = |layer: &str| p.layers.iter().position(|l| l.name == layer);
    let shown: Vec<usize> = match &check.layer {
        Some(layer) => vec![index_of(layer).ok_or_else(|| format!("check '{name}': no layer '{layer}'"))?],
        None => (0..p.layers.len()).rev().filter(|k| p.layers[*k].visible && p.layers[*k].opacity > 0.0).collect(),
    };
    for &index in &shown {
        let n = in_effect(p, index);
        // The newest operation the check reads: the fewest undone that it sees (a check of the
        // layer itself must see the last).
        let tries = if check.layer.is_some() { n.min(1) } else { n };
        for k in 1..=tries {
            let without = undone(p, index, k);
            if replays.breaks(&without, name)? {
                let mut out = vec![Mutation {
                    what: format!("layer '{}': its last {k} operations undone", p.layers[index].name),
                    project: without,
                }];
                out.extend(changes_of(p, index, n - k));
                return Ok(out);
            }
        }
        if check.layer.is_some() && n > 0 {
            return Err(format!("check '{name}' still passes with the last operation of its layer undone").into());
        }
    }
    for &index in &shown {
        if !p.layers[index].gives_heights() {
            continue;
        }
        let mut q = p.clone();
        q.layers[index].offset_m += 1.0;
        if replays.breaks(&q, name)? {
            return Ok(Vec::new());
        }
    }
    Err(format!("check '{name}' passes whatever its layers hold (no operation undone, no layer moved, changes it)")
        .into())
}

/// Every check fails when what it reads changes, naming what changed; every layer's last
/// operation undone and redone gives the project back as it was (which the other trial replays).
fn every_check_can_fail(file: &Path) -> Result<(), Failed> {
    let path = copy_into_out(file, "-mutated")?;
    let project = Project::load(&path)?;
    if project.checks.is_empty() {
        return Err("no check to mutate".into());
    }
    let mut replays = Replays::default();
    let mut problems = Vec::new();
    for name in project.checks.keys() {
        match mutations_for(&mut replays, &project, name) {
            Ok(mutations) => {
                for m in mutations {
                    if !replays.breaks(&m.project, name)? {
                        problems.push(format!("check '{name}' still passes with {}", m.what));
                    }
                }
            }
            Err(e) => problems.push(e.message().unwrap_or("failed").to_string()),
        }
    }
    let mut redone = project.clone();
    for layer in redone.layers.iter_mut().filter(|l| l.holds_deltas() && l.operations() > 0) {
        layer.move_applied(Some(1), None)?;
        layer.move_applied(None, Some(1))?;
    }
    if redone != project {
        problems.push("undoing and redoing the last operations does not give the project back".into());
    }
    if !problems.is_empty() {
        return Err(problems.join("\n").into());
    }
    Ok(())
}
