//! The editing session: what changes an edit or erosion layer while the renderer draws it.
//! Strokes are brushed onto edit layers (on the GPU rasteriser for the provisional strokes shown
//! while dragging, by the CPU reference for the stroke kept), erosion runs are prepared, shown
//! while they run, committed or discarded, and both kinds of layer move their undo position.
//! The [`Renderer`] draws and composes; the [`Editor`] changes its scene through
//! [`Renderer::with_scene`] and returns each layer's new spec for the project.

mod erosion;

use std::sync::Arc;

use super::brush::StrokeKernel;
use super::context::{GpuContext, GpuError};
use super::erosion::ErosionKernel;
use super::renderer::Renderer;
use crate::edit::{EditRaster, Stroke, StrokeError};
use crate::layers::{EditLayer, LayerError, LayerPayload, LayerSpec};
use crate::scene::{Scene, SceneError};

/// The editing session of a renderer's layers: the GPU kernels it may run (on hardware
/// adapters; on a software one the CPU references are faster: BENCHMARKS.md).
pub struct Editor {
    device: wgpu::Device,
    queue: wgpu::Queue,
    /// The GPU stroke rasteriser, used for the strokes shown while dragging.
    stroke_kernel: Option<StrokeKernel>,
    /// The erosion kernels (software adapters run the CPU reference).
    erosion_kernel: Option<Arc<ErosionKernel>>,
}

impl Editor {
    /// An editing session on `ctx`'s device.
    pub fn new(ctx: &GpuContext) -> Result<Editor, GpuError> {
        let hardware = ctx.info.device_type != wgpu::DeviceType::Cpu;
        let stroke_kernel = hardware.then(|| StrokeKernel::new(&ctx.device)).transpose()?;
        let erosion_kernel = hardware.then(|| ErosionKernel::new(&ctx.device).map(Arc::new)).transpose()?;
        Ok(Editor { device: ctx.device.clone(), queue: ctx.queue.clone(), stroke_kernel, erosion_kernel })
    }

    /// Brushes a stroke onto edit layer `index`: strokes past its undo position are dropped (a
    /// new stroke ends redo), the stroke is appended and rasterised into the layer's tiles, and
    /// the quads it touches are recomposed. Returns the layer's new spec (for the project).
    pub fn apply_stroke(&self, r: &mut Renderer, index: usize, stroke: Stroke) -> Result<LayerSpec, LayerError> {
        self.apply_stroke_on(r, index, stroke, false)
    }

    /// [`Editor::apply_stroke`], on the GPU rasteriser when `gpu` and the adapter is hardware
    /// (for the provisional strokes shown while dragging; the stroke kept is rasterised by the
    /// CPU reference, which replay checks against).
    pub fn apply_stroke_on(
        &self,
        r: &mut Renderer,
        index: usize,
        stroke: Stroke,
        gpu: bool,
    ) -> Result<LayerSpec, LayerError> {
        let (spec, mut edit) = edit_spec(r.scene(), index)?;
        let applied = edit.in_effect().len();
        edit.strokes.truncate(applied);
        let ellipsoid = r.scene().ellipsoid;
        let name = spec.name.clone();
        let fail = |e: StrokeError| LayerError::field(&name, "strokes", e.to_string());
        let all = edit.strokes.iter().chain(std::iter::once(&stroke));
        let below = terrain_below(r.scene(), index, all)
            .map_err(|e| LayerError::caused(&name, "strokes", "the layers below cannot be read", e))?;
        let below = |q| below.as_ref().map_or_else(|| crate::edit::ellipsoid_below(q), |s| Ok(s.heights_cpu(q)?));
        let on_gpu = self.stroke_kernel.as_ref().filter(|_| gpu).map(|k| k.on(&self.device, &self.queue));
        r.with_scene(|scene| {
            let raster = raster_mut(scene, index);
            if stroke.level > raster.level {
                // A finer stroke: the raster moves to its level (rebuilt from every stroke).
                let mut all = edit.strokes.clone();
                all.push(stroke.clone());
                let mut finer = EditRaster::build(ellipsoid, &all, &below).map_err(fail)?;
                finer.succeed(raster);
                *raster = finer;
            } else {
                // Checked before anything changes: a refused stroke leaves the raster as it was.
                let rasteriser: &dyn crate::edit::kernel::Rasteriser = match &on_gpu {
                    Some(k) => k,
                    None => &crate::edit::kernel::CpuRasteriser,
                };
                raster.apply_with(applied, &stroke, &below, rasteriser).map_err(fail)?;
            }
            edit.strokes.push(stroke);
            edit.applied = None;
            Ok(finish_edit(scene, index, spec, edit))
        })
    }

    /// Moves edit layer `index`'s undo position to `applied` strokes (back: undo, restoring the
    /// touched quads from the undo history or recomputing them; forward: redo). Returns the
    /// layer's new spec.
    pub fn set_applied(&self, r: &mut Renderer, index: usize, applied: usize) -> Result<LayerSpec, LayerError> {
        let (spec, mut edit) = edit_spec(r.scene(), index)?;
        let now = edit.in_effect().len();
        if applied > edit.strokes.len() {
            return Err(LayerError::field(
                &spec.name,
                "applied",
                format!("{applied} is past the {} strokes", edit.strokes.len()),
            ));
        }
        let name = spec.name.clone();
        let fail = |e: StrokeError| LayerError::field(&name, "strokes", e.to_string());
        let strokes = edit.strokes.clone();
        let below = terrain_below(r.scene(), index, strokes.iter())
            .map_err(|e| LayerError::caused(&name, "strokes", "the layers below cannot be read", e))?;
        let below = |q| below.as_ref().map_or_else(|| crate::edit::ellipsoid_below(q), |s| Ok(s.heights_cpu(q)?));
        r.with_scene(|scene| {
            let raster = raster_mut(scene, index);
            if applied < now {
                raster.undo_to(&strokes[..now], applied, &below).map_err(fail)?;
            } else {
                for (k, stroke) in strokes.iter().enumerate().take(applied).skip(now) {
                    raster.apply(k, stroke, &below).map_err(fail)?;
                }
            }
            edit.applied = (applied < edit.strokes.len()).then_some(applied);
            Ok(finish_edit(scene, index, spec, edit))
        })
    }
}

/// The scene of the layers below edit layer `index`, when one of `strokes` reads the terrain
/// (only those call it: the others need no copy of the scene).
fn terrain_below<'a>(
    scene: &Scene,
    index: usize,
    mut strokes: impl Iterator<Item = &'a Stroke>,
) -> Result<Option<Scene>, SceneError> {
    if strokes.any(|s| s.tool.reads_terrain()) { scene.below(index).map(Some) } else { Ok(None) }
}

/// Layer `index` of the stack, or an error naming the index.
fn layer_at(scene: &Scene, index: usize) -> Result<&crate::layers::stack::Layer, LayerError> {
    scene
        .stack
        .layers
        .get(index)
        .ok_or_else(|| LayerError::field("?", "index", format!("{index} is not a layer of the stack")))
}

/// Edit layer `index`'s spec, its strokes taken out to change (an error for any other layer).
fn edit_spec(scene: &Scene, index: usize) -> Result<(LayerSpec, EditLayer), LayerError> {
    let layer = layer_at(scene, index)?;
    let not_edit =
        || LayerError::field(&layer.spec.name, "kind", format!("{} is not an edit layer", layer.spec.kind().name()));
    if !scene.edits.contains_key(&layer.uid) {
        return Err(not_edit());
    }
    let mut spec = layer.spec.clone();
    let edit = spec.as_edit_mut().map(std::mem::take).ok_or_else(not_edit)?;
    Ok((spec, edit))
}

/// Edit layer `index`'s raster, changed in place (copied first only if another scene shares it).
fn raster_mut(scene: &mut Scene, index: usize) -> &mut EditRaster {
    let uid = scene.stack.layers[index].uid;
    Arc::make_mut(scene.edits.get_mut(&uid).expect("checked by edit_spec"))
}

/// Records edit layer `index`'s strokes in the stack (the raster's per-quad stamps say which
/// quads to recompose) and returns its spec holding them.
fn finish_edit(scene: &mut Scene, index: usize, mut spec: LayerSpec, edit: EditLayer) -> LayerSpec {
    scene.stack.set_strokes(index, edit.strokes.clone(), edit.applied);
    spec.payload = LayerPayload::Edit(edit);
    let uid = scene.stack.layers[index].uid;
    let range = scene.edits[&uid].range_m();
    scene.stack.set_dataset_info(index, range, None);
    spec
}
