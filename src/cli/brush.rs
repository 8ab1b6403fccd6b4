//! `terrafuse brush`: appends a stroke to an edit layer of a project (or moves its undo position)
//! and saves the project atomically, so brushing sessions can be scripted and checked. The stroke
//! is checked and rasterised before anything is written: a refused stroke leaves the file as it was.

use super::edit_target::{ChangeArgs, Holds, target_layer};
use super::{CliError, Feedback, Within};
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::ecm::grid::spacing_m;
use crate::edit::{Falloff, Stroke, Tool};
use crate::errors::FieldProblem;
use crate::project::Project;
use crate::scene::{Edits, Scene};

/// What `terrafuse brush` was asked.
#[derive(clap::Args, Clone, Debug, Default)]
pub struct BrushRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// The edit layer.
    #[arg(long)]
    pub layer: String,
    /// raise, lower, smooth, flatten, ramp, noise or restore.
    #[arg(long)]
    pub tool: Option<String>,
    /// Brush radius on the surface, metres.
    #[arg(long = "radius-m", allow_negative_numbers = true)]
    pub radius_m: Option<f64>,
    /// Metres per dab (raise, lower, noise).
    #[arg(long = "strength-m", allow_hyphen_values = true)]
    pub strength_m: Option<f64>,
    /// A fraction 0–1 per dab (restore and the tools that read the terrain).
    #[arg(long, allow_negative_numbers = true)]
    pub strength: Option<f64>,
    /// The path: LAT,LON;LAT,LON;… degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub path: Option<String>,
    /// smooth, linear, spherical or tip.
    #[arg(long)]
    pub falloff: Option<String>,
    /// Dab spacing, a fraction of the radius (default 0.25).
    #[arg(long, allow_negative_numbers = true)]
    pub spacing: Option<f64>,
    /// The level it is rasterised at (default: the coarsest with samples at most a tenth of
    /// the radius apart).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Noise seed.
    #[arg(long, allow_negative_numbers = true)]
    pub seed: Option<u32>,
    /// Flatten: the height to flatten to, metres above the ellipsoid (default: the terrain's
    /// under the path's first point, before the stroke).
    #[arg(long = "height-m", allow_hyphen_values = true)]
    pub height_m: Option<f64>,
    /// Undo this many strokes (no stroke).
    #[arg(long, allow_negative_numbers = true)]
    pub undo: Option<usize>,
    /// Redo this many strokes (no stroke).
    #[arg(long, allow_negative_numbers = true)]
    pub redo: Option<usize>,
    /// --create, --max-tiles, --wait.
    #[command(flatten)]
    pub change: ChangeArgs,
}

fn parse_path(text: &str) -> Result<Vec<[f64; 2]>, CliError> {
    text.split(';')
        .filter(|p| !p.trim().is_empty())
        .enumerate()
        .map(|(k, p)| {
            let v: Vec<f64> = p
                .split(',')
                .map(|x| x.trim().parse::<f64>())
                .collect::<Result<_, _>>()
                .map_err(|_| CliError::Usage(format!("--path: point {k} '{p}' is not LAT,LON in degrees")))?;
            match v.as_slice() {
                [lat, lon] => Ok([*lat, *lon]),
                _ => Err(format!("--path: point {k} '{p}' is not LAT,LON in degrees").into()),
            }
        })
        .collect()
}

fn named<T: Copy>(what: &str, name: &str, all: &[T], name_of: fn(T) -> &'static str) -> Result<T, CliError> {
    all.iter().copied().find(|t| name_of(*t) == name).ok_or_else(|| {
        format!("--{what} {name}: not one of {}", all.iter().map(|t| name_of(*t)).collect::<Vec<_>>().join(", ")).into()
    })
}

/// Runs the command; returns the report. The request is checked against the project before the
/// command waits for another that holds it (a bad flag is refused at once), then again once the
/// project is held (locked) from before it is read until the stroke is saved: a refused stroke
/// leaves the project and its stores as they were.
pub fn brush_command(request: &BrushRequest, fb: &mut Feedback) -> Result<String, CliError> {
    let path = &request.project;
    if request.change.wait.duration()? > std::time::Duration::ZERO {
        change_of(&mut Project::load(path)?, request)?;
    }
    let (mut project, held) = super::feedback::change(path, "terrafuse brush", &request.change.wait, fb)?;
    let (index, mut out) = change_of(&mut project, request)?;
    // Rasterised before saving, with the project's layers (smooth, flatten and ramp read the
    // terrain below): a stroke that cannot be is refused and nothing is written.
    let t = std::time::Instant::now();
    let (scene, report) =
        Scene::open_watched(&project, Edits::Cached, fb.watch).within(format_args!("layer '{}'", request.layer))?;
    for line in report.imported.iter().chain(&report.edits) {
        let _ = writeln!(out, "{line}");
    }
    let raster =
        scene.stack.layers.get(index).and_then(|l| scene.edits.get(&l.uid)).ok_or("the edit layer was not built")?;
    let (lo, hi) = raster.range_m();
    let _ = writeln!(
        out,
        "rebuilt from {} strokes in {:.2} s: {} tiles at level {}, deltas {lo:.3} … {hi:.3} m",
        project.layers[index].applied_strokes().len(),
        t.elapsed().as_secs_f64(),
        raster.tiles.len(),
        raster.level
    );
    held.save(&project)?;
    let _ = writeln!(out, "saved {}", path.display());
    Ok(out)
}

/// Holds a new stroke to the budget (`--max-tiles`, else the project's): its own footprint at
/// the level the layer will be rasterised at (the finest of its strokes'), and, when the stroke
/// is finer than the layer's strokes so far, the whole layer's rebuilt at its level.
fn check_footprint(
    ellipsoid: &crate::geodesy::Ellipsoid,
    applied: &[Stroke],
    stroke: &Stroke,
    budget: (Option<u64>, u64),
) -> Result<(), CliError> {
    let layer_level = applied.iter().map(|s| s.level).max();
    let level = layer_level.map_or(stroke.level, |l| l.max(stroke.level));
    let own = stroke.footprint_tiles(ellipsoid, level).within("--path")?;
    super::edit_target::check_budget_of(budget, own, &format!("the stroke at level {level}"))?;
    if let Some(was) = layer_level.filter(|l| *l < stroke.level) {
        let mut all = own;
        for s in applied {
            all += s.footprint_tiles(ellipsoid, level).within("the layer's strokes")?;
        }
        let what = format!(
            "the layer rasterised again at the stroke's level {level} (its {} strokes so far are at level {was} or coarser; a layer holds every stroke at the finest level of any)",
            applied.len()
        );
        super::edit_target::check_budget_of(budget, all, &what)?;
    }
    Ok(())
}

/// The change the request makes to `project` (its edit layer's new stroke, or its undo position
/// moved), every value checked; the layer's index and what to report.
fn change_of(project: &mut Project, request: &BrushRequest) -> Result<(usize, String), CliError> {
    let undo_or_redo = match (request.undo, request.redo, &request.tool) {
        (Some(_), None, None) | (None, Some(_), None) => true,
        (None, None, Some(_)) => false,
        _ => return Err("give either --tool with its stroke, or --undo N, or --redo N".into()),
    };
    let ellipsoid = project.ellipsoid()?;
    let mut out = String::new();
    let index = target_layer(project, &request.layer, Holds::Strokes, request.change.create, &mut out)?;
    if undo_or_redo {
        let spec = &mut project.layers[index];
        let to = spec.move_applied(request.undo, request.redo)?;
        let done = if request.undo.is_some() { "undone" } else { "redone" };
        let _ = writeln!(out, "layer '{}': {done} to {to} of {} strokes", spec.name, spec.strokes().len());
        return Ok((index, out));
    }
    let tool = request.tool.as_deref().unwrap_or_default();
    let stroke = stroke_of(request, tool, ellipsoid.a_m(), &ellipsoid)?;
    let budget = (request.change.max_tiles, project.detail.max_edit_tiles);
    check_footprint(&ellipsoid, project.layers[index].applied_strokes(), &stroke, budget)?;
    let dabs = crate::edit::dabs::dab_centres(&ellipsoid, &stroke).within("--path")?;
    let spec = &mut project.layers[index];
    let dropped = spec.record_stroke(stroke.clone())?;
    let _ = writeln!(
        out,
        "layer '{}': stroke {} ({}, radius {} m, strength {}, {} falloff, {} dabs, level {}){}",
        spec.name,
        spec.strokes().len() - 1,
        stroke.tool.name(),
        stroke.radius_m,
        stroke.strength,
        stroke.falloff.name(),
        dabs.len(),
        stroke.level,
        if dropped > 0 { format!("; {dropped} undone strokes dropped") } else { String::new() }
    );
    Ok((index, out))
}

fn stroke_of(
    request: &BrushRequest,
    tool: &str,
    body_radius_m: f64,
    ellipsoid: &crate::geodesy::Ellipsoid,
) -> Result<Stroke, CliError> {
    let tool = named("tool", tool, &Tool::ALL, Tool::name)?;
    let falloff = match &request.falloff {
        Some(f) => named("falloff", f, &Falloff::ALL, Falloff::name)?,
        None => Falloff::Smooth,
    };
    let radius_m = request.radius_m.ok_or("--radius-m: a stroke needs its radius in metres")?;
    let strength = match (tool.strength_in_metres(), request.strength_m, request.strength) {
        (true, Some(s), None) | (false, None, Some(s)) => s,
        (true, _, _) => {
            return Err(format!("--strength-m: {} takes its strength in metres per dab", tool.name()).into());
        }
        (false, _, _) => return Err(format!("--strength: {} takes its strength as a fraction 0–1", tool.name()).into()),
    };
    let path = parse_path(request.path.as_deref().ok_or("--path: a stroke needs its path LAT,LON;LAT,LON;…")?)?;
    let level = match request.level {
        Some(l) => l,
        None => (0..=crate::edit::stroke::MAX_LEVEL)
            .find(|l| spacing_m(ellipsoid, *l) <= radius_m.abs() / 10.0)
            .unwrap_or(crate::edit::stroke::MAX_LEVEL),
    };
    let stroke = Stroke {
        tool,
        radius_m,
        strength,
        falloff,
        spacing: request.spacing.unwrap_or(0.25),
        level,
        path,
        seed: request.seed.unwrap_or(0),
        height_m: request.height_m,
    };
    stroke.check(body_radius_m).map_err(|FieldProblem { field, problem }| {
        let flag = match field.as_str() {
            "radius_m" => "--radius-m",
            "strength" if tool.strength_in_metres() => "--strength-m",
            "strength" => "--strength",
            "spacing" => "--spacing",
            "level" => "--level",
            "path" => "--path",
            "height_m" => "--height-m",
            other => other,
        };
        format!("{flag}: {problem}")
    })?;
    Ok(stroke)
}
