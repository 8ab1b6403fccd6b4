//! `terrafuse replay`: rebuilds every edit and erosion layer of a project from its operations,
//! prints a digest per layer and the time; `--check` compares the project's recorded checks and
//! fails naming the check and the first differing tile; `--record` writes them (atomically).
//! `--gpu` rebuilds on the GPU and, with `--check`, compares each layer with the CPU reference
//! within its stated tolerance (the digests are checked on the CPU replay: they are bit for bit).

use super::args::EngineArgs;
use super::{CliError, Feedback, WaitArgs, Within};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::time::Instant;

use crate::gpu::GpuContext;
use crate::project::{CheckSpec, Project, checks};
use crate::replay::{self, Engine, Replayed, digest};

/// What `terrafuse replay` was asked.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ReplayRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// Compare with the digests recorded in the project's "checks"; exit 1 on a mismatch.
    #[arg(long)]
    pub check: bool,
    /// Write the digests of the project's checks into it (from the CPU reference).
    #[arg(long, conflicts_with_all = ["check", "gpu"])]
    pub record: bool,
    /// --gpu (with --check, each layer is compared with the CPU reference within its stated
    /// tolerance) or --cpu (the default).
    #[command(flatten)]
    pub engine: EngineArgs,
    /// Print JSON (project, engine, layers[name, kind, operations, tiles, digest, seconds],
    /// checks[name, digest, expected, ok, first_differing_tile], seconds, passed).
    #[arg(long)]
    pub json: bool,
    /// With --record: how long to wait for another process changing the project.
    #[command(flatten)]
    pub wait: WaitArgs,
}

/// What it found: the report, and whether every check held.
pub struct ReplayOutcome {
    /// Text or JSON.
    pub report: String,
    /// False when a check failed (the command exits non-zero).
    pub passed: bool,
}

/// Runs `terrafuse replay`.
pub fn replay_command(request: &ReplayRequest, fb: &mut Feedback) -> Result<ReplayOutcome, CliError> {
    let t = Instant::now();
    let path = &request.project;
    if request.record && request.engine.gpu {
        return Err("--record: digests are recorded from the CPU reference (bit for bit); drop --gpu".into());
    }
    // Recording changes the project: it is held from before it is read until it is saved.
    let (mut project, held) = if request.record {
        let (project, held) = super::feedback::change(path, "terrafuse replay --record", &request.wait, fb)?;
        (project, Some(held))
    } else {
        (Project::load(path)?, None)
    };
    let ctx = if request.engine.gpu { Some(GpuContext::headless().within("--gpu")?) } else { None };
    let engine = ctx.as_ref().map_or(Engine::Cpu, Engine::Gpu);
    let fail =
        |e: replay::ReplayError| CliError::Within { context: path.display().to_string(), source: Box::new(e.into()) };
    let replayed = replay::replay_watched(&project, engine, fb.watch).map_err(fail)?;
    // The CPU reference, when the GPU replayed and something is to be checked against it.
    let cpu = if request.engine.gpu && request.check {
        Some(replay::replay(&project, Engine::Cpu).map_err(fail)?)
    } else {
        None
    };
    let reference = cpu.as_ref().unwrap_or(&replayed);

    let mut layers = Vec::new();
    let mut passed = true;
    for layer in &replayed.layers {
        let mut row = serde_json::json!({
            "name": layer.name, "kind": layer.kind.name(), "operations": layer.operations,
            "tiles": layer.digests.tiles.len(), "digest": digest::hex(layer.digests.total),
            "range_m": [layer.range_m.0, layer.range_m.1], "seconds": layer.seconds,
        });
        if let Some(cpu) = &cpu {
            let (difference, tolerance) = gpu_against_cpu(&project, &replayed, cpu, layer.index);
            let ok = difference <= tolerance;
            passed &= ok;
            row["gpu_vs_cpu_m"] = serde_json::json!(difference);
            row["tolerance_m"] = serde_json::json!(tolerance);
            row["within_tolerance"] = serde_json::json!(ok);
        }
        layers.push(row);
    }
    let mut checks = Vec::new();
    let mut recorded = 0;
    for (name, check) in project.checks.clone() {
        let got = replay::evaluate(&reference.scene, &project, &name, &check).within(path.display())?;
        let mut row = serde_json::json!({
            "name": name, "layer": check.layer, "digest": digest::hex(got.total), "tiles": got.tiles.len(),
        });
        let inputs = checks::inputs(&project, &check);
        if request.check {
            let result = digest::compare(&check, &got);
            passed &= result.is_ok();
            row["expected"] = serde_json::json!(check.digest);
            row["ok"] = serde_json::json!(result.is_ok());
            if let Err(m) = result {
                let changed = checks::changed_inputs(&check.inputs, &inputs);
                row["problem"] = serde_json::json!(mismatch_text(&m, &check, &changed, path));
                row["changed_since_recorded"] = serde_json::json!(changed);
                if let digest::Mismatch::Differs { first_tile, .. } = m {
                    row["first_differing_tile"] = serde_json::json!(first_tile);
                }
            }
        }
        if request.record {
            let entry = project.checks.get_mut(&name).expect("the check is there");
            if digest::compare(entry, &got).is_err() || entry.inputs != inputs {
                got.record(entry);
                entry.inputs = inputs;
                recorded += 1;
            }
        }
        checks.push(row);
    }
    if let Some(held) = held.as_ref().filter(|_| recorded > 0) {
        held.save(&project)?;
    }
    let seconds = t.elapsed().as_secs_f64();
    let report = if request.json {
        let mut j = serde_json::json!({
            "project": path.display().to_string(), "engine": engine.name(), "open_seconds": replayed.open_seconds,
            "layers": layers, "checks": checks, "seconds": seconds, "passed": passed,
        });
        if request.record {
            j["recorded"] = serde_json::json!(recorded);
        }
        format!("{}\n", serde_json::to_string_pretty(&j)?)
    } else {
        text_report(path, &engine, &replayed, &layers, &checks, request, recorded, seconds)
    };
    Ok(ReplayOutcome { report, passed })
}

/// A check's mismatch in words: the digests, what changed in the project since the check was
/// recorded (or that nothing did), and how to accept the new state.
fn mismatch_text(m: &digest::Mismatch, check: &CheckSpec, changed: &[String], path: &std::path::Path) -> String {
    if *m == digest::Mismatch::NotRecorded {
        return m.to_string();
    }
    let why = if check.inputs.is_empty() {
        "it was recorded without its inputs, so what changed since is not known".to_string()
    } else if changed.is_empty() {
        "the layers and views it reads are as they were when it was recorded, so the same operations now make \
         other heights: a change in Terrafuse, in a store or in a store's source files"
            .to_string()
    } else {
        format!("since it was recorded, {}", changed.join(", "))
    };
    format!("{m}; {why}; if the new state is meant, accept it with `terrafuse replay --record {}`", path.display())
}

/// The largest |GPU − CPU| of layer `index`'s tiles and its tolerance, metres.
fn gpu_against_cpu(project: &Project, gpu: &Replayed, cpu: &Replayed, index: usize) -> (f64, f64) {
    let uid = |r: &Replayed| r.scene.stack.layers[index].uid;
    let (Some(a), Some(b)) = (gpu.scene.edits.get(&uid(gpu)), cpu.scene.edits.get(&uid(cpu))) else {
        return (f64::INFINITY, 0.0);
    };
    let Some(cpu_layer) = cpu.layers.iter().find(|l| l.index == index) else {
        return (f64::INFINITY, 0.0);
    };
    // The largest |height| the layers below can give (what flatten and ramp aim at).
    let (lo, hi) = cpu.scene.below(index).map_or((0.0, 0.0), |s| crate::scene::stack_range(&s.stack));
    let spec = &project.layers[index];
    let tolerance = replay::gpu_tolerance_m(&cpu.scene.ellipsoid, spec, cpu_layer, lo.abs().max(hi.abs()));
    (replay::largest_difference_m(a, b), tolerance)
}

#[allow(clippy::too_many_arguments)]
fn text_report(
    path: &std::path::Path,
    engine: &Engine,
    replayed: &Replayed,
    layers: &[serde_json::Value],
    checks: &[serde_json::Value],
    request: &ReplayRequest,
    recorded: usize,
    seconds: f64,
) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "replay of {} on the {} (opened in {:.2} s)",
        path.display(),
        engine.name(),
        replayed.open_seconds
    );
    if layers.is_empty() {
        let _ = writeln!(out, "no edit or erosion layers to rebuild");
    }
    for l in layers {
        let what = if l["kind"] == "erosion" { "runs" } else { "strokes" };
        let _ = write!(
            out,
            "layer '{}' ({}): {} {what}, {} tiles, digest {}, {:.2} s",
            l["name"].as_str().unwrap_or(""),
            l["kind"].as_str().unwrap_or(""),
            l["operations"],
            l["tiles"],
            l["digest"].as_str().unwrap_or(""),
            l["seconds"].as_f64().unwrap_or(0.0)
        );
        if let (Some(d), Some(t)) = (l["gpu_vs_cpu_m"].as_f64(), l["tolerance_m"].as_f64()) {
            let verdict = if d <= t { "within" } else { "OUTSIDE" };
            let _ = write!(out, "; GPU − CPU at most {d:.3e} m, {verdict} the tolerance {t:.3e} m");
        }
        out.push('\n');
    }
    if request.engine.gpu && request.check && !checks.is_empty() {
        out.push_str("checks, on the CPU reference (bit for bit):\n");
    }
    for c in checks {
        let name = c["name"].as_str().unwrap_or("");
        let of = c["layer"].as_str().map_or_else(|| "the visible stack".to_string(), |l| format!("layer '{l}'"));
        let _ = write!(
            out,
            "check '{name}' ({of}): digest {} over {} tiles",
            c["digest"].as_str().unwrap_or(""),
            c["tiles"]
        );
        if request.check {
            match c["problem"].as_str() {
                None => out.push_str(", as recorded"),
                Some(p) => {
                    let _ = write!(out, ": MISMATCH: {p}");
                }
            }
        }
        out.push('\n');
    }
    if request.check && checks.is_empty() {
        out.push_str("the project records no checks (add some under \"checks\" and run terrafuse replay --record)\n");
    }
    if request.record {
        let _ = writeln!(out, "recorded {recorded} of {} checks in {}", checks.len(), path.display());
    }
    let _ = writeln!(out, "total {seconds:.2} s");
    out
}
