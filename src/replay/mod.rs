//! Replay: every edit and erosion layer of a project rebuilt from its operations (strokes and
//! runs, in order, up to the undo position), bottom to top, each reading the layers below as
//! they were rebuilt; a digest per layer; and the project's checks ([`crate::project::checks`])
//! evaluated against what was rebuilt.
//!
//! On the CPU ([`Engine::Cpu`]) every step is the deterministic reference: a replay gives the
//! same digests bit for bit on any machine, which is what the recorded checks hold. On the GPU
//! ([`Engine::Gpu`]) strokes go through the stroke kernel and runs through the erosion kernels;
//! their tiles agree with the CPU's within each operation's stated tolerance, summed over the
//! layer's operations ([`gpu_tolerance_m`]), not bit for bit.

pub mod digest;
pub mod place;

use std::sync::Arc;
use std::time::Instant;

use crate::edit::kernel::CpuRasteriser;
use crate::edit::raster::EditRaster;
use crate::erosion::layer::CpuStepper;
use crate::gpu::GpuContext;
use crate::layers::{LayerKind, LayerPayload, LayerSpec, Operand};
use crate::progress::Watch;
use crate::project::checks::CheckTarget;
use crate::project::{CheckSpec, Project};
use crate::scene::Edits;
use crate::scene::Scene;

pub use digest::{Digests, Mismatch};

/// Where the operations run.
#[derive(Clone, Copy)]
pub enum Engine<'a> {
    /// The CPU reference (bit for bit).
    Cpu,
    /// The GPU kernels on this device.
    Gpu(&'a GpuContext),
}

impl Engine<'_> {
    /// `cpu` or `gpu`.
    pub fn name(&self) -> &'static str {
        match self {
            Engine::Cpu => "cpu",
            Engine::Gpu(_) => "gpu",
        }
    }
}

/// A replay that could not be made, naming what.
#[derive(Debug, thiserror::Error)]
pub enum ReplayError {
    /// The project's layers could not be opened (a store, an import).
    #[error(transparent)]
    Open(#[from] crate::scene::SceneError),
    /// A layer's operations could not be replayed.
    #[error("layer '{layer}'")]
    Layer {
        /// The layer.
        layer: String,
        /// What failed: the terrain below, a stroke or a run.
        #[source]
        source: crate::errors::Failure,
    },
    /// A check could not be evaluated.
    #[error("checks.{check}: {problem}")]
    Check {
        /// The check.
        check: String,
        /// What failed.
        problem: String,
    },
    /// A check's scene could not be composed.
    #[error("checks.{check}")]
    CheckScene {
        /// The check.
        check: String,
        /// Why.
        #[source]
        source: Box<crate::scene::SceneError>,
    },
    /// The GPU kernels could not be made.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
}

/// One edit or erosion layer as the replay rebuilt it.
#[derive(Clone, Debug)]
pub struct LayerReplay {
    /// Its index in the stack (0: bottom).
    pub index: usize,
    /// Its name.
    pub name: String,
    /// Edit or erosion.
    pub kind: LayerKind,
    /// Operations replayed (those before the undo position).
    pub operations: usize,
    /// The digests of its tiles.
    pub digests: Digests,
    /// The smallest and largest change of height, metres.
    pub range_m: (f64, f64),
    /// Wall-clock time of its operations, seconds (not counting reading the layers below).
    pub seconds: f64,
}

/// A replayed project: the scene with every edit and erosion layer rebuilt.
pub struct Replayed {
    /// The scene (datasets open, rebuilt rasters attached).
    pub scene: Scene,
    /// The layers rebuilt, bottom to top.
    pub layers: Vec<LayerReplay>,
    /// Seconds spent opening the project (stores, imports).
    pub open_seconds: f64,
}

/// Rebuilds every edit and erosion layer of `project` on `engine` (caches are neither read nor
/// written).
pub fn replay(project: &Project, engine: Engine) -> Result<Replayed, ReplayError> {
    replay_watched(project, engine, &Watch::default())
}

/// [`replay`], each layer's operations counted on `watch` (a phase per run, or `strokes`) and
/// stopped between operations or steps when it is cancelled.
pub fn replay_watched(project: &Project, engine: Engine, watch: &Watch) -> Result<Replayed, ReplayError> {
    let t = Instant::now();
    let (mut scene, _) = Scene::open_with(project, Edits::Empty)?;
    let open_seconds = t.elapsed().as_secs_f64();
    let mut kernels: Option<(crate::gpu::brush::StrokeKernel, Arc<crate::gpu::erosion::ErosionKernel>)> = None;
    if let Engine::Gpu(ctx) = engine {
        kernels = Some((
            crate::gpu::brush::StrokeKernel::new(&ctx.device)?,
            Arc::new(crate::gpu::erosion::ErosionKernel::new(&ctx.device)?),
        ));
    }
    let mut layers = Vec::new();
    for index in 0..scene.stack.layers.len() {
        let spec = scene.stack.layers[index].spec.clone();
        if !spec.holds_deltas() {
            continue;
        }
        let fail = |e: crate::errors::Failure| ReplayError::Layer { layer: spec.name.clone(), source: e };
        let below = scene.below(index).map_err(|e| fail(e.into()))?;
        let below = |q| Ok(below.heights_cpu(q)?);
        let e = scene.ellipsoid;
        let t = Instant::now();
        // The deltas rebuilt from the operations in effect: runs by the erosion model, strokes
        // by the rasteriser, each on the engine asked for.
        let raster = match (&spec.payload, engine, &kernels) {
            (LayerPayload::Erosion(runs), Engine::Gpu(ctx), Some((_, erosion))) => {
                let stepper =
                    crate::gpu::erosion::GpuStepper { device: &ctx.device, queue: &ctx.queue, kernel: erosion.clone() };
                crate::erosion::layer::build_with(e, runs.in_effect(), &below, &stepper, watch)
                    .map_err(|e| fail(e.into()))
            }
            (LayerPayload::Erosion(runs), ..) => {
                crate::erosion::layer::build_with(e, runs.in_effect(), &below, &CpuStepper, watch)
                    .map_err(|e| fail(e.into()))
            }
            (_, Engine::Gpu(ctx), Some((strokes, _))) => {
                EditRaster::build_with(e, spec.applied_strokes(), &below, &strokes.on_context(ctx), watch)
                    .map_err(|e| fail(e.into()))
            }
            _ => EditRaster::build_with(e, spec.applied_strokes(), &below, &CpuRasteriser, watch)
                .map_err(|e| fail(e.into())),
        }?;
        let seconds = t.elapsed().as_secs_f64();
        layers.push(LayerReplay {
            index,
            name: spec.name.clone(),
            kind: spec.kind(),
            operations: applied(&spec),
            digests: digest::of_tiles(raster.tiles.iter().map(|(q, t)| (*q, t.as_slice()))),
            range_m: raster.range_m(),
            seconds,
        });
        scene.set_edit(index, raster);
    }
    Ok(Replayed { scene, layers, open_seconds })
}

/// How many of a layer's operations (strokes or runs) are in effect.
fn applied(spec: &LayerSpec) -> usize {
    spec.applied_strokes().len() + spec.applied_runs().len()
}

/// Evaluates check `name` on a replayed scene: the digests of what it hashes.
pub fn evaluate(scene: &Scene, project: &Project, name: &str, check: &CheckSpec) -> Result<Digests, ReplayError> {
    let fail = |problem: crate::Invalid| ReplayError::Check { check: name.to_string(), problem: problem.0 };
    let failed = |source| ReplayError::CheckScene { check: name.to_string(), source: Box::new(source) };
    let kinds = |layer: &str| project.layers.iter().find(|l| l.name == layer).map(|l| l.holds_deltas());
    let index_of = |layer: &str| {
        scene
            .stack
            .layers
            .iter()
            .position(|l| l.spec.name == layer)
            .ok_or_else(|| fail(format!("no layer '{layer}'").into()))
    };
    let e = scene.ellipsoid;
    let (layer, quads) = match check.target(&kinds).map_err(fail)? {
        CheckTarget::LayerTiles(layer) => {
            let uid = scene.stack.layers[index_of(layer)?].uid;
            let raster =
                scene.edits.get(&uid).ok_or_else(|| fail(format!("layer '{layer}' was not rebuilt").into()))?;
            return Ok(digest::of_tiles(raster.tiles.iter().map(|(q, t)| (*q, t.as_slice()))));
        }
        CheckTarget::Region { layer, level, region } => (layer, place::region_quads(&e, region, level).map_err(fail)?),
        CheckTarget::View { layer, level, view } => {
            let camera = project.view(Some(view)).map_err(fail)?;
            (layer, place::view_quads(&e, camera, level).map_err(fail)?)
        }
    };
    // A layer is composed alone as every comparison takes it: a layer of deltas over a zero plane,
    // so that its check reads its own deltas (not nothing, as a layer added to no terrain would).
    let alone;
    let scene = match layer {
        Some(layer) => {
            index_of(layer)?;
            alone = scene.of_operand(&Operand::Layer(layer.to_string())).map_err(|e| failed(e.into()))?;
            &alone
        }
        None => scene,
    };
    let composed = scene.compose_cpu(&quads).map_err(failed)?;
    Ok(digest::of_tiles(composed.iter().map(|(q, h)| (*q, h.as_slice()))))
}

/// How far a layer rebuilt on the GPU may be from the CPU reference, metres: the sum over its
/// operations of each one's stated tolerance (errors of successive operations add at most):
/// a stroke's [`crate::gpu::brush::GPU_TOLERANCE`] × scale × dabs, its scale the largest of its
/// strength in metres, the layer's largest |δ| and, for strokes that read the terrain, the
/// largest |height| of the layers below (`below_m`); a run's
/// [`crate::gpu::erosion::GPU_TOLERANCE_M`] per 100 steps begun.
pub fn gpu_tolerance_m(
    ellipsoid: &crate::geodesy::Ellipsoid,
    spec: &LayerSpec,
    cpu: &LayerReplay,
    below_m: f64,
) -> f64 {
    let delta_m = cpu.range_m.0.abs().max(cpu.range_m.1.abs());
    let runs: f64 =
        spec.applied_runs().iter().map(|r| crate::gpu::erosion::GPU_TOLERANCE_M * r.steps.div_ceil(100) as f64).sum();
    let strokes: f64 = spec
        .applied_strokes()
        .iter()
        .map(|s| {
            let strength = if s.tool.strength_in_metres() { s.strength.abs() } else { 0.0 };
            let terrain = if s.tool.reads_terrain() { below_m } else { 0.0 };
            let dabs = crate::edit::dabs::dab_centres(ellipsoid, s).map_or(1, |d| d.len()) as f64;
            crate::gpu::brush::GPU_TOLERANCE * strength.max(delta_m).max(terrain).max(1.0) * dabs
        })
        .sum();
    runs + strokes
}

/// The largest |a − b| over two rasters' tiles, metres (a tile on one side only counts against
/// zeros; NaN against a number is infinite).
pub fn largest_difference_m(a: &EditRaster, b: &EditRaster) -> f64 {
    let zeros = vec![0f32; (crate::ecm::grid::GRID * crate::ecm::grid::GRID) as usize];
    let quads: std::collections::BTreeSet<_> = a.tiles.keys().chain(b.tiles.keys()).collect();
    let mut worst = 0f64;
    for q in quads {
        let (x, y) = (a.tiles.get(q).unwrap_or(&zeros), b.tiles.get(q).unwrap_or(&zeros));
        for (u, v) in x.iter().zip(y) {
            let d = if u.is_nan() && v.is_nan() { 0.0 } else { f64::from(u - v).abs() };
            worst = worst.max(if d.is_nan() { f64::INFINITY } else { d });
        }
    }
    worst
}
