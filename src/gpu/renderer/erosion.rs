//! Erosion layers in the renderer: a run prepared on the terrain the layer sees, its progress
//! shown on the layer while it runs (provisional tiles), water depth or sediment draped over the
//! terrain while it runs, the finished run recorded, and undo and redo. The run itself (CPU
//! reference or GPU kernels) belongs to the caller, which steps it a few steps per frame.
//!
//! The drape reuses the difference overlay: three layers the renderer alone holds (never the
//! project), on top of the stack while a run shows it: a hidden delta layer holding the field
//! (NaN where there is none), a hidden constant 0, and a difference layer drawing field − 0 with
//! the diverging colour map over the field's range.

use super::*;
use crate::edit::EditRaster;
use crate::erosion::layer::{self, Outcome};
use crate::erosion::operation::Operation;
use crate::erosion::region::Region;
use crate::erosion::sim::Run;
use crate::gpu::erosion::{ErosionKernel, GpuRun};
use crate::layers::{DifferenceStyle, ErosionLayer, LayerPayload, Operand};

/// The drape's layers: the field, the zero it is drawn against, the difference drawn.
const LIVE_FIELD: &str = "erosion-live-field";
const LIVE_ZERO: &str = "erosion-live-zero";
const LIVE_DRAWN: &str = "erosion-live-overlay";

impl Renderer {
    /// Erosion layer `index`'s spec and raster (an error for any other layer).
    fn erosion_layer(&self, index: usize) -> Result<(LayerSpec, EditRaster), LayerError> {
        let layer = self
            .scene
            .stack
            .layers
            .get(index)
            .ok_or_else(|| LayerError::field("?", "index", format!("{index} is not a layer of the stack")))?;
        if layer.spec.as_erosion().is_none() {
            return Err(LayerError::field(
                &layer.spec.name,
                "kind",
                format!("{} is not an erosion layer", layer.spec.kind().name()),
            ));
        }
        let raster = self
            .scene
            .edits
            .get(&layer.uid)
            .map(|r| (**r).clone())
            .ok_or_else(|| LayerError::field(&layer.spec.name, "runs", "the erosion layer was not built".into()))?;
        Ok((layer.spec.clone(), raster))
    }

    /// A run of `op` on erosion layer `index` before its first step: the region, the run on the
    /// CPU, and the layer's raster it starts from.
    pub fn prepare_erosion(&self, index: usize, op: &Operation) -> Result<(Region, Run, EditRaster), LayerError> {
        let (spec, mut raster) = self.erosion_layer(index)?;
        let below = self
            .scene
            .below(index)
            .map_err(|e| LayerError::caused(&spec.name, "runs", "the layers below cannot be read", e))?;
        let applied = spec.applied_runs().len();
        let (region, run) = layer::prepare(&mut raster, applied, op, &|q| Ok(below.heights_cpu(q)?))
            .map_err(|e| LayerError { layer: spec.name.clone(), field: e.field, problem: e.problem, cause: e.cause })?;
        Ok((region, run, raster))
    }

    /// `run` on the GPU, when the adapter is a hardware one (else None: the CPU reference runs).
    pub fn erosion_on_gpu(&self, run: &Run) -> Option<Result<GpuRun, GpuError>> {
        let kernel: &std::sync::Arc<ErosionKernel> = self.erosion_kernel.as_ref()?;
        Some(GpuRun::new(&self.device, &self.queue, kernel.clone(), run))
    }

    /// Shows a run in progress on erosion layer `index`: the layer holds `base` (its raster
    /// before the run) plus the change `run` has made so far; only the region's quads are
    /// recomposed.
    pub fn show_erosion(&mut self, index: usize, base: &EditRaster, region: &Region, run: &Run) {
        let mut raster = base.clone();
        raster.apply_tiles(usize::MAX, layer::tiles_with(base, region, run));
        raster.clear_history();
        self.scene.set_edit(index, raster);
        self.cache.plans.clear();
    }

    /// Puts erosion layer `index` back as it was before a run (`base`), the run discarded.
    pub fn discard_erosion(&mut self, index: usize, base: EditRaster) {
        self.scene.set_edit(index, base);
        self.cache.plans.clear();
    }

    /// Records a finished run on erosion layer `index`: runs past the undo position are dropped,
    /// `op` (with the steps taken) is appended, and its change is added to `base`. Returns the
    /// layer's new spec (for the project) and what the run did.
    pub fn commit_erosion(
        &mut self,
        index: usize,
        mut op: Operation,
        mut base: EditRaster,
        region: Region,
        run: &Run,
        seconds: f64,
    ) -> Result<(LayerSpec, Outcome), LayerError> {
        let (mut spec, _) = self.erosion_layer(index)?;
        let applied = spec.applied_runs().len();
        op.steps = run.steps;
        op.check().map_err(|(f, p)| LayerError::field(&spec.name, &format!("runs[{applied}].{f}"), p))?;
        let outcome = layer::finish(&mut base, applied, region, run, seconds);
        spec.record_run(op)?;
        self.scene.set_edit(index, base);
        self.scene.stack.set_runs(index, spec.runs().to_vec(), None);
        self.cache.plans.clear();
        Ok((spec, outcome))
    }

    /// Moves erosion layer `index`'s undo position to `applied` runs (back: restoring the quads
    /// from the undo history or rebuilding; forward: the runs redone by the CPU reference).
    /// Returns the layer's new spec.
    pub fn set_erosion_applied(&mut self, index: usize, applied: usize) -> Result<LayerSpec, LayerError> {
        let (mut spec, mut raster) = self.erosion_layer(index)?;
        let now = spec.applied_runs().len();
        let runs = spec.runs().to_vec();
        if applied > runs.len() {
            return Err(LayerError::field(&spec.name, "applied", format!("{applied} is past the {} runs", runs.len())));
        }
        let below = self
            .scene
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
                layer::apply(&mut raster, k, op, &below, &layer::CpuStepper).map_err(fail)?;
            }
        }
        let applied = (applied < runs.len()).then_some(applied);
        self.scene.set_edit(index, raster);
        self.scene.stack.set_runs(index, runs.clone(), applied);
        spec.payload = LayerPayload::Erosion(ErosionLayer { runs, applied });
        self.cache.plans.clear();
        Ok(spec)
    }

    /// Drapes `field` (a raster of one value per cell of `region`, NaN where none) over the
    /// terrain with the diverging colour map over ±`range_m`, within the region's outline, or
    /// removes the drape (None). The drape's layers are the renderer's alone: the project never
    /// holds them.
    pub fn set_erosion_overlay(&mut self, field: Option<(EditRaster, &Region, f64)>) -> Result<(), LayerError> {
        let find = |r: &Renderer, name: &str| r.scene.stack.layers.iter().position(|l| l.spec.name == name);
        let Some((raster, region, range_m)) = field else {
            // The difference first: it reads the other two.
            for name in [LIVE_DRAWN, LIVE_ZERO, LIVE_FIELD] {
                if let Some(i) = find(self, name) {
                    self.remove_layer(i)?;
                }
            }
            return Ok(());
        };
        let style = DifferenceStyle { range_m: Some(range_m.max(1e-6)), isolines_m: 0.0, ..Default::default() };
        match find(self, LIVE_DRAWN) {
            None => {
                let top = self.scene.stack.layers.len();
                self.insert_layer(top, LayerSpec { visible: false, ..LayerSpec::erosion(LIVE_FIELD) })?;
                // The zero only within the region: beyond it the field has no data, and coarse
                // views (whose means treat a missing tile as 0) draw nothing there.
                let outline = region.outline(&self.scene.ellipsoid);
                let extent = (outline.len() >= 3).then_some(crate::layers::ExtentSpec::Polygon(outline));
                let zero = LayerSpec { visible: false, extent, ..LayerSpec::constant(LIVE_ZERO, 0.0) };
                self.insert_layer(top + 1, zero)?;
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
                self.insert_layer(top + 2, drawn)?;
            }
            Some(i) => {
                let spec = &self.scene.stack.layers[i].spec;
                let old = spec.difference_style().range_m.unwrap_or(0.0);
                // A new range only when it moved by more than a quarter (each recomposes the region).
                if (old - range_m).abs() > 0.25 * old {
                    let mut spec = spec.clone();
                    if let Some(d) = spec.as_difference_mut() {
                        d.style = style;
                    }
                    self.update_layer(i, spec)?;
                }
            }
        }
        let i = find(self, LIVE_FIELD).expect("inserted above");
        self.scene.set_edit(i, raster);
        self.cache.plans.clear();
        Ok(())
    }
}
