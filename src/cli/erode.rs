//! `terrafuse erode`: runs erosion headless on a region of a project (the box rounded out to
//! whole quads of the level), appends the run to an erosion layer (made on top when missing) or
//! moves its undo position, caches the layer's change of height beside the project and saves the
//! project atomically. A run that cannot be made leaves the file as it was.

use super::args::EngineArgs;
use super::edit_target::{ChangeArgs, Holds, target_layer};
use super::{CliError, Feedback, Within};
use crate::errors::AtField;
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::Arc;

use crate::erosion::layer::{CpuStepper, Outcome, Stepper};
use crate::erosion::operation::{Device, Model, Operation};
use crate::erosion::params::{Params, gravity_of_body};
use crate::gpu::GpuContext;
use crate::gpu::erosion::{ErosionKernel, GpuStepper};
use crate::project::Project;
use crate::project::editing::Held;
use crate::scene::{Edits, Scene};

/// Where `terrafuse erode` runs.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ErodeOn {
    /// The GPU when the adapter is a real one, else the CPU reference.
    #[default]
    Auto,
    /// The CPU reference (bit for bit reproducible).
    Cpu,
    /// The GPU (lavapipe too, when that is the only adapter).
    Gpu,
}

/// What `terrafuse erode` was asked.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct ErodeRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// The erosion layer.
    #[arg(long)]
    pub layer: String,
    /// The box: WEST,SOUTH,EAST,NORTH degrees (west > east crosses the antimeridian).
    #[arg(long, allow_hyphen_values = true)]
    pub region: Option<String>,
    /// The level whose samples are the cells (default: the coarsest with 512 cells along the
    /// box's north–south side, as the workstation chooses).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Steps (each the preset's Δt or less, by the CFL bound; hydraulic only: a stream-power run
    /// takes years / dt-years steps).
    #[arg(long, allow_negative_numbers = true)]
    pub steps: Option<u64>,
    /// hydraulic (virtual pipes over seconds of rain; the default) or stream-power (uplift,
    /// river incision and hillslope diffusion over geological time).
    #[arg(long, value_parser = ["hydraulic", "stream-power"])]
    pub model: Option<String>,
    /// Stream power: the simulated time, years (default 2e6).
    #[arg(long, allow_hyphen_values = true)]
    pub years: Option<f64>,
    /// Stream power: the time step, years (default 1e4; the implicit solver is stable for any).
    #[arg(long = "dt-years", allow_hyphen_values = true)]
    pub dt_years: Option<f64>,
    /// Stream power: rock uplift, m/yr (default 1e-3), uniform over the region.
    #[arg(long = "uplift-m-per-year", allow_hyphen_values = true)]
    pub uplift_m_per_year: Option<f64>,
    /// Stream power: erodibility K of E = K·A^m·S^n (default 2e-5).
    #[arg(long, allow_hyphen_values = true)]
    pub k: Option<f64>,
    /// Stream power: the drainage-area exponent m, in (0, 1] (default 0.45).
    #[arg(long, allow_hyphen_values = true)]
    pub m: Option<f64>,
    /// Stream power: the slope exponent n (default 1).
    #[arg(long, allow_hyphen_values = true)]
    pub n: Option<f64>,
    /// Stream power: hillslope diffusivity, m²/yr (default 0.01).
    #[arg(long = "kd-m2-per-year", allow_hyphen_values = true)]
    pub kd_m2_per_year: Option<f64>,
    /// Stream power: the ξ-q deposition coefficient G (0 = detachment-limited, the default).
    #[arg(long, allow_hyphen_values = true)]
    pub deposition: Option<f64>,
    /// Stream power: drainage area by d8 (steepest neighbour; the default) or mfd (shared among
    /// every lower neighbour, Freeman 1991).
    #[arg(long, value_parser = ["d8", "mfd"])]
    pub routing: Option<String>,
    /// rain, river, thermal or gentle (default rain).
    #[arg(long)]
    pub preset: Option<String>,
    /// Overrides a parameter: FIELD=VALUE (repeatable), e.g. rain_m_s=2e-5, border=closed.
    #[arg(long)]
    pub set: Vec<String>,
    /// The seed of the rounding dither.
    #[arg(long, allow_negative_numbers = true)]
    pub seed: Option<u64>,
    /// --gpu or --cpu (the default without a hardware GPU).
    #[command(flatten)]
    pub engine: EngineArgs,
    /// Print JSON (steps, simulated_s, water_unexplained_rel, soil_unexplained_rel,
    /// water_out_m3, soil_out_m3, seconds, …).
    #[arg(long)]
    pub json: bool,
    /// Undo this many runs (no run).
    #[arg(long, allow_negative_numbers = true)]
    pub undo: Option<usize>,
    /// Redo this many runs (no run).
    #[arg(long, allow_negative_numbers = true)]
    pub redo: Option<usize>,
    /// --create, --max-tiles, --wait.
    #[command(flatten)]
    pub change: ChangeArgs,
}

impl ErodeRequest {
    /// Where it runs, from `--gpu` and `--cpu`.
    pub fn on(&self) -> ErodeOn {
        match (self.engine.gpu, self.engine.cpu) {
            (true, _) => ErodeOn::Gpu,
            (_, true) => ErodeOn::Cpu,
            _ => ErodeOn::Auto,
        }
    }
}

/// The preset `name` on the project's body with `set` overrides applied (`FIELD=VALUE`).
pub fn params_of(preset: &str, body: &str, set: &[String]) -> Result<Params, CliError> {
    let params = Params::preset(preset, gravity_of_body(body))
        .ok_or_else(|| format!("--preset {preset}: not one of {}", Params::PRESETS.join(", ")))?;
    let mut value = serde_json::to_value(&params)?;
    // Fields left out when they hold their default are still there to be set.
    if let Some(object) = value.as_object_mut() {
        object.entry("start").or_insert_with(|| serde_json::Value::String("dry".into()));
    }
    for item in set {
        let (field, text) = item.split_once('=').ok_or_else(|| format!("--set '{item}': not FIELD=VALUE"))?;
        let object = value.as_object_mut().ok_or("parameters are not an object")?;
        if !object.contains_key(field) {
            let fields: Vec<&String> = object.keys().collect();
            return Err(format!("--set {field}: no such parameter (one of {fields:?})").into());
        }
        let v = text
            .parse::<f64>()
            .ok()
            .and_then(serde_json::Number::from_f64)
            .map_or_else(|| serde_json::Value::String(text.to_string()), serde_json::Value::Number);
        if object[field].is_number() && !v.is_number() {
            return Err(format!("--set {field}: '{text}' is not a number").into());
        }
        if object[field].is_string() && !v.is_string() {
            return Err(format!("--set {field}: '{text}' is not one of its words (see docs/erosion.md)").into());
        }
        object.insert(field.to_string(), v);
    }
    let fields = set.iter().map(|s| s.split('=').next().unwrap_or("")).collect::<Vec<_>>().join(", ");
    let params: Params = serde_json::from_value(value).at_field(format_args!("--set {fields}"))?;
    params.check().map_err(|e| CliError::Usage(format!("--set {}: {} is outside {}", e.field, e.value, e.range)))?;
    Ok(params)
}

/// Runs the command; returns the report (text or JSON). The project is held (locked) from
/// before it is read until the run is saved; every value is checked, and the run's footprint
/// held to the budget, before the layers are opened or a step is taken.
pub fn erode_command(request: &ErodeRequest, fb: &mut Feedback) -> Result<String, CliError> {
    let path = &request.project;
    // Checked before waiting for another process that holds the project: a bad flag is refused
    // at once; then again on the project as it is once held.
    if request.change.wait.duration()? > std::time::Duration::ZERO {
        change_of(&mut Project::load(path)?, request)?;
    }
    let (mut project, held) = super::feedback::change(path, "terrafuse erode", &request.change.wait, fb)?;
    let (index, mut out, op) = change_of(&mut project, request)?;
    let Some(mut op) = op else {
        return finish(&project, &held, index, out, fb);
    };
    let applied = project.layers[index].applied_runs().len();
    let (landscape, model) = (op.stream_power.clone(), op.model);
    // The layer as it stands (its runs in effect), opened and built or read from its cache.
    project.layers[index].drop_undone();
    let (mut scene, report) =
        Scene::open_watched(&project, Edits::Cached, fb.watch).within(format_args!("layer '{}'", request.layer))?;
    for line in report.imported.iter().chain(&report.edits) {
        let _ = writeln!(out, "{line}");
    }
    let gpu = match request.on() {
        _ if landscape.is_some() => None,
        ErodeOn::Cpu => None,
        ErodeOn::Gpu => Some(GpuContext::headless().within("--gpu")?),
        ErodeOn::Auto => GpuContext::headless().ok().filter(|c| c.info.device_type != wgpu::DeviceType::Cpu),
    };
    let kernel = match &gpu {
        Some(c) => Some(Arc::new(ErosionKernel::new(&c.device)?)),
        None => None,
    };
    let stepper: Box<dyn Stepper> = match (&gpu, &kernel) {
        (Some(c), Some(k)) => Box::new(GpuStepper { device: &c.device, queue: &c.queue, kernel: k.clone() }),
        _ => Box::new(CpuStepper),
    };
    op.device = if model == Model::StreamPower { Device::Cpu } else { stepper.device() };
    let uid = scene.stack.layers[index].uid;
    let mut raster = scene.edits.get(&uid).map(|r| (**r).clone()).ok_or("the erosion layer was not built")?;
    let below = scene.below(index)?;
    let outcome = crate::erosion::layer::apply(
        &mut raster,
        applied,
        &op,
        &|q| Ok(below.heights_cpu(q)?),
        stepper.as_ref(),
        fb.watch,
    )
    .map_err(|e| CliError::Usage(format!("{}: {}", flag_of(&e.field), e.problem)))?;
    project.layers[index].record_run(op)?;
    scene.stack.set(index, project.layers[index].clone())?;
    scene.set_edit(index, raster);
    let cached = scene.save_edit_cache(index)?;
    held.save(&project)?;
    let device = match (&gpu, model) {
        (Some(g), Model::Hydraulic) => g.describe(),
        _ => "CPU reference".into(),
    };
    if let Some(figures) = &outcome.landscape {
        let report = super::erode_landscape::Report { layer: &request.layer, run: applied, outcome: &outcome, figures };
        return Ok(if request.json {
            report.json(cached.as_deref(), path)
        } else {
            out + &report.text(cached.as_deref(), path)
        });
    }
    if request.json {
        return Ok(json_of(&outcome, &device, cached.as_deref(), path));
    }
    let r = &outcome.region;
    let _ = writeln!(
        out,
        "layer '{}': run {} on {} × {} cells at level {} ({} quads) on the {device}",
        request.layer,
        applied,
        r.width,
        r.height,
        r.level,
        outcome.quads.len()
    );
    let _ = writeln!(
        out,
        "{} steps, {:.3} s simulated, in {:.2} s; steps {:.4} … {:.4} s (asked {} s, the rest by the CFL bound); change of height {:.3} … {:.3} m",
        outcome.steps,
        outcome.simulated_s,
        outcome.seconds,
        outcome.dt_range_s.0,
        outcome.dt_range_s.1,
        outcome.dt_asked_s,
        outcome.range_m.0,
        outcome.range_m.1
    );
    let _ = writeln!(
        out,
        "budgets: water at the start {:.3} m³, rain {:.3} m³, water out {:.3} m³, soil out {:.3} m³, suspended at the end {:.3} m³; terrain eroded {:.3} m³, deposited {:.3} m³, change {:.3} m³; unexplained: water {:.1e}, soil {:.1e} of the total",
        outcome.start_water_m3,
        outcome.rain_m3,
        outcome.water_out_m3,
        outcome.soil_out_m3,
        outcome.suspended_m3,
        outcome.eroded_m3,
        outcome.deposited_m3,
        outcome.volume_change_m3,
        outcome.water_unexplained_rel,
        outcome.soil_unexplained_rel
    );
    if let Some(c) = cached {
        let _ = writeln!(out, "cached {}", c.display());
    }
    let _ = writeln!(out, "saved {}", path.display());
    Ok(out)
}

fn json_of(o: &Outcome, device: &str, cached: Option<&std::path::Path>, path: &std::path::Path) -> String {
    super::erode_report::report_json(
        o,
        device,
        cached,
        path,
        serde_json::json!({
            "simulated_s": o.simulated_s,
            "water_unexplained_rel": o.water_unexplained_rel,
            "soil_unexplained_rel": o.soil_unexplained_rel,
            "water_out_m3": o.water_out_m3,
            "soil_out_m3": o.soil_out_m3,
            "dt_min_s": o.dt_range_s.0,
            "dt_max_s": o.dt_range_s.1,
            "dt_asked_s": o.dt_asked_s,
            "rain_m3": o.rain_m3,
            "start_water_m3": o.start_water_m3,
            "suspended_m3": o.suspended_m3,
            "volume_change_m3": o.volume_change_m3,
            "eroded_m3": o.eroded_m3,
            "deposited_m3": o.deposited_m3,
        }),
    )
}

/// The change the request makes to `project`: the erosion layer's undo position moved (no run),
/// or the run to make (every value checked, its footprint within the budget; not recorded yet).
/// The layer's index, what to report, and the run.
fn change_of(project: &mut Project, request: &ErodeRequest) -> Result<(usize, String, Option<Operation>), CliError> {
    let landscape = super::erode_landscape::params_of(request)?;
    let asked_run =
        request.region.is_some() || request.level.is_some() || request.steps.is_some() || request.years.is_some();
    let undo_or_redo = match (request.undo, request.redo, asked_run) {
        (Some(_), None, false) | (None, Some(_), false) => true,
        (None, None, true) => false,
        _ => {
            return Err(
                "give either --region and --steps (or --years) (and --level) for a run, or --undo N, or --redo N"
                    .into(),
            );
        }
    };
    let region = request.region.as_deref().map(super::geo::parse_box).transpose()?;
    let mut out = String::new();
    let index = target_layer(project, &request.layer, Holds::Runs, request.change.create, &mut out)?;
    if undo_or_redo {
        let total = project.layers[index].runs().len();
        let to = project.layers[index].move_applied(request.undo, request.redo)?;
        let done = if request.undo.is_some() { "undone" } else { "redone" };
        let _ = writeln!(out, "layer '{}': {done} to {to} of {total} runs", request.layer);
        return Ok((index, out, None));
    }
    let region = region.ok_or("--region: a run needs its box")?;
    let ellipsoid = project.ellipsoid()?;
    // Without --level, as the workstation chooses: the layer's level, else the coarsest with 512
    // cells along the box.
    let layer_level = project.layers[index].runs().first().map(|r| r.level);
    let level = match request.level.or(layer_level) {
        Some(level) => level,
        None => crate::erosion::placement::default_level(&ellipsoid, &region),
    };
    let steps = match &landscape {
        Some(p) if request.steps.is_some() => {
            return Err(format!("--steps: a stream-power run takes --years / --dt-years = {} steps", p.steps()).into());
        }
        Some(p) => p.steps(),
        None => request.steps.ok_or("--steps: a run needs its number of steps")?,
    };
    let preset = request.preset.clone().unwrap_or_else(|| "rain".into());
    let params = params_of(&preset, &project.body, &request.set)?;
    let model = if landscape.is_some() { Model::StreamPower } else { Model::Hydraulic };
    let op = Operation {
        region,
        level,
        steps,
        seed: request.seed.unwrap_or(0),
        preset: landscape.is_none().then_some(preset),
        model,
        params: if landscape.is_some() { Params::standard() } else { params },
        stream_power: landscape,
        brush: None,
        device: Device::Cpu,
    };
    // Every check a run makes, before the layers are opened: a refused run costs nothing.
    op.check().map_err(|e| CliError::Usage(format!("{}: {}", flag_of(&e.field), e.problem)))?;
    let placed = crate::erosion::region::Region::from_box(&ellipsoid, region, level).within("--region")?;
    let tiles = (placed.width / 256 * (placed.height / 256)) as f64;
    let what = format!("the run on {} × {} cells at level {level}", placed.width, placed.height);
    super::edit_target::check_budget_of((request.change.max_tiles, project.detail.max_edit_tiles), tiles, &what)?;
    Ok((index, out, Some(op)))
}

/// The flag of an operation's field (`steps` → `--steps`, `params.rain_m_s` → `--set rain_m_s`).
fn flag_of(field: &str) -> String {
    match field {
        "region" => "--region".to_string(),
        "level" => "--level".to_string(),
        "steps" => "--steps".to_string(),
        f if f.starts_with("params.") => format!("--set {}", &f[7..]),
        f if f.starts_with("stream_power.") => super::erode_landscape::flag_of(&f[13..]),
        f => f.to_string(),
    }
}

/// After an undo or redo: the layer rebuilt or read from its cache, the project saved.
fn finish(
    project: &Project,
    held: &Held,
    index: usize,
    mut out: String,
    fb: &mut Feedback,
) -> Result<String, CliError> {
    let (scene, report) = Scene::open_watched(project, Edits::Cached, fb.watch)?;
    for line in report.imported.iter().chain(&report.edits) {
        let _ = writeln!(out, "{line}");
    }
    scene.save_edit_cache(index)?;
    held.save(project)?;
    let _ = writeln!(out, "saved {}", held.path().display());
    Ok(out)
}
