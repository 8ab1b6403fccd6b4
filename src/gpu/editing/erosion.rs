//! Erosion layers in the editing session: a run prepared on the terrain the layer sees, its
//! progress shown on the layer while it runs (provisional tiles), water depth or sediment draped
//! over the terrain while it runs, the finished run recorded, and undo and redo. The run itself
//! (CPU reference or GPU kernels) belongs to the caller, which steps it a few steps per frame.
//!
//! The drape reuses the difference overlay: three layers the session alone adds (never the
//! project), on top of the stack while a run shows it: a hidden delta layer holding the field
//! (NaN where there is none), a hidden constant 0, and a difference layer drawing field − 0 with
//! the diverging colour map over the field's range.

use super::{Editor, layer_at};
use crate::edit::EditRaster;
use crate::erosion::layer::{self, Outcome};
use crate::erosion::operation::Operation;
use crate::erosion::region::Region;
use crate::erosion::sim::Run;
use crate::gpu::context::GpuError;
use crate::gpu::erosion::GpuRun;
use crate::gpu::renderer::Renderer;
use crate::layers::{DifferenceStyle, ErosionLayer, LayerError, LayerPayload, LayerSpec, Operand};
use crate::progress::Watch;
use crate::scene::Scene;

/// The drape's layers: the field, the zero it is drawn against, the difference drawn.
const LIVE_FIELD: &str = "erosion-live-field";
const LIVE_ZERO: &str = "erosion-live-zero";
const LIVE_DRAWN: &str = "erosion-live-overlay";

/// Erosion layer `index`'s spec and raster (an error for any other layer).
fn erosion_layer(scene: &Scene, index: usize) -> Result<(LayerSpec, EditRaster), LayerError> {
    let layer = layer_at(scene, index)?;
    if layer.spec.as_erosion().is_none() {
        return Err(LayerError::field(
            &layer.spec.name,
            "kind",
            format!("{} is not an erosion layer", layer.spec.kind().name()),
        ));
    }
    let raster = scene
        .edits
        .get(&layer.uid)
        .map(|r| (**r).clone())
        .ok_or_else(|| LayerError::field(&layer.spec.name, "runs", "the erosion layer was not built".into()))?;
    Ok((layer.spec.clone(), raster))
}

impl Editor {
    /// A run of `op` on erosion layer `index` before its first step: the region, the run on the
    /// CPU, and the layer's raster it starts from.
    pub fn prepare_erosion(
        &self,
        r: &Renderer,
        index: usize,
        op: &Operation,
    ) -> Result<(Region, Run, EditRaster), LayerError> {
        let (spec, mut raster) = erosion_layer(r.scene(), index)?;
        let below = r
            .scene()
            .below(index)
            .map_err(|e| LayerError::caused(&spec.name, "runs", "the layers below cannot be read", e))?;
        let applied = spec.applied_runs().len();
        let (region, run) = layer::prepare(&mut raster, applied, op, &|q| Ok(below.heights_cpu(q)?))
            .map_err(|e| LayerError { layer: spec.name.clone(), field: e.field, problem: e.problem, cause: e.cause })?;
        Ok((region, run, raster))
    }

    /// `run` on the GPU, when the adapter is a hardware one (else None: the CPU reference runs).
    pub fn erosion_on_gpu(&self, run: &Run) -> Option<Result<GpuRun, GpuError>> {
        let kernel = self.erosion_kernel.as_ref()?;
        Some(GpuRun::new(&self.device, &self.queue, kernel.clone(), run))
    }

    /// Shows a run in progress on erosion layer `index`: `raster` is its raster before the run
    /// plus the change made so far (see `EditRaster::warm` for making it on the run's thread);
    /// only the quads it changed are recomposed.
    pub fn show_erosion(&self, r: &mut Renderer, index: usize, raster: EditRaster) {
        r.with_scene(|s| s.set_edit(index, raster));
    }

    /// Puts erosion layer `index` back as it was before a run (`base`), the run discarded.
    pub fn discard_erosion(&self, r: &mut Renderer, index: usize, base: EditRaster) {
        r.with_scene(|s| s.set_edit(index, base));
    }

    /// Records a finished run on erosion layer `index`: runs past the undo position are dropped,
    /// `op` (with the steps taken) is appended, and its change is added to `base`. Returns the
    /// layer's new spec (for the project) and what the run did.
    #[allow(clippy::too_many_arguments)]
    pub fn commit_erosion(
        &self,
        r: &mut Renderer,
        index: usize,
        mut op: Operation,
        mut base: EditRaster,
        region: Region,
        run: &Run,
        seconds: f64,
    ) -> Result<(LayerSpec, Outcome), LayerError> {
        let (mut spec, _) = erosion_layer(r.scene(), index)?;
        let applied = spec.applied_runs().len();
        op.steps = run.steps;
        op.check().map_err(|e| LayerError::of_field(&spec.name, e.under(format_args!("runs[{applied}]"))))?;
        let outcome = layer::finish(&mut base, applied, region, run, seconds);
        spec.record_run(op)?;
        r.with_scene(|s| {
            s.set_edit(index, base);
            s.stack.set_runs(index, spec.runs().to_vec(), None);
        });
        Ok((spec, outcome))
    }

    /// What a run taken whole off the interface thread needs of erosion layer `index`: its spec,
    /// its raster and the layers below it (a scene of their own, for the run's thread).
    pub fn whole_run_inputs(&self, r: &Renderer, index: usize) -> Result<(LayerSpec, EditRaster, Scene), LayerError> {
        let (spec, raster) = erosion_layer(r.scene(), index)?;
        let below = r
            .scene()
            .below(index)
            .map_err(|e| LayerError::caused(&spec.name, "runs", "the layers below cannot be read", e))?;
        Ok((spec, raster, below))
    }

    /// Records a run taken whole (`raster`: the layer with it added, as [`layer::apply`] left it)
    /// on erosion layer `index` whose spec was `spec`. Returns the layer's new spec.
    pub fn commit_whole(
        &self,
        r: &mut Renderer,
        index: usize,
        mut spec: LayerSpec,
        op: Operation,
        raster: EditRaster,
    ) -> Result<LayerSpec, LayerError> {
        spec.record_run(op)?;
        r.with_scene(|s| {
            s.set_edit(index, raster);
            s.stack.set_runs(index, spec.runs().to_vec(), None);
        });
        Ok(spec)
    }

    /// Moves erosion layer `index`'s undo position to `applied` runs (back: restoring the quads
    /// from the undo history or rebuilding; forward: the runs redone by the CPU reference).
    /// Returns the layer's new spec.
    pub fn set_erosion_applied(&self, r: &mut Renderer, index: usize, applied: usize) -> Result<LayerSpec, LayerError> {
        let (mut spec, mut raster) = erosion_layer(r.scene(), index)?;
        let now = spec.applied_runs().len();
        let runs = spec.runs().to_vec();
        if applied > runs.len() {
            return Err(LayerError::field(&spec.name, "applied", format!("{applied} is past the {} runs", runs.len())));
        }
        let below = r
            .scene()
            .below(index)
            .map_err(|e| LayerError::caused(&spec.name, "runs", "the layers below cannot be read", e))?;
        let below = |q| Ok(below.heights_cpu(q)?);
        let fail = |e: layer::OperationError| LayerError {
            layer: spec.name.clone(),
            field: format!("runs[{}].{}", e.index, e.field),
            problem: e.problem,
            cause: e.cause,
        };
        if applied < now {
            layer::undo_to(&mut raster, &runs, now, applied, &below).map_err(fail)?;
        } else {
            for (k, op) in runs.iter().enumerate().take(applied).skip(now) {
                layer::apply(&mut raster, k, op, &below, &layer::CpuStepper, &Watch::default()).map_err(fail)?;
            }
        }
        let applied = (applied < runs.len()).then_some(applied);
        r.with_scene(|s| {
            s.set_edit(index, raster);
            s.stack.set_runs(index, runs.clone(), applied);
        });
        spec.payload = LayerPayload::Erosion(ErosionLayer { runs, applied });
        Ok(spec)
    }

    /// Drapes `field` (a raster of one value per cell of `region`, NaN where none) over the
    /// terrain with the diverging colour map over ±`range_m`, within the region's outline, or
    /// removes the drape (None). The drape's layers are the session's alone: the project never
    /// holds them.
    pub fn set_erosion_overlay(
        &self,
        r: &mut Renderer,
        field: Option<(EditRaster, &Region, f64)>,
    ) -> Result<(), LayerError> {
        let find = |r: &Renderer, name: &str| r.scene().stack.layers.iter().position(|l| l.spec.name == name);
        let Some((raster, region, range_m)) = field else {
            // The difference first: it reads the other two.
            for name in [LIVE_DRAWN, LIVE_ZERO, LIVE_FIELD] {
                if let Some(i) = find(r, name) {
                    r.remove_layer(i)?;
                }
            }
            return Ok(());
        };
        let style = DifferenceStyle { range_m: Some(range_m.max(1e-6)), isolines_m: 0.0, ..Default::default() };
        match find(r, LIVE_DRAWN) {
            None => {
                let top = r.scene().stack.layers.len();
                r.insert_layer(top, LayerSpec { visible: false, ..LayerSpec::erosion(LIVE_FIELD) })?;
                // The zero only within the region: beyond it the field has no data, and coarse
                // views (whose means treat a missing tile as 0) draw nothing there.
                let outline = region.outline(&r.scene().ellipsoid);
                let extent = (outline.len() >= 3).then_some(crate::layers::ExtentSpec::Polygon(outline));
                let zero = LayerSpec { visible: false, extent, ..LayerSpec::constant(LIVE_ZERO, 0.0) };
                r.insert_layer(top + 1, zero)?;
                let mut drawn = LayerSpec {
                    opacity: 0.8,
                    ..LayerSpec::difference(
                        LIVE_DRAWN,
                        Operand::Layer(LIVE_FIELD.into()),
                        Operand::Layer(LIVE_ZERO.into()),
                    )
                };
                if let Some(d) = drawn.as_difference_mut() {
                    d.style = style;
                }
                r.insert_layer(top + 2, drawn)?;
            }
            Some(i) => {
                let spec = &r.scene().stack.layers[i].spec;
                let old = spec.difference_style().range_m.unwrap_or(0.0);
                // A new range only when it moved by more than a quarter (each recomposes the region).
                if (old - range_m).abs() > 0.25 * old {
                    let mut spec = spec.clone();
                    if let Some(d) = spec.as_difference_mut() {
                        d.style = style;
                    }
                    r.update_layer(i, spec)?;
                }
            }
        }
        let i = find(r, LIVE_FIELD).expect("inserted above");
        r.with_scene(|s| s.set_edit(i, raster));
        Ok(())
    }
}
