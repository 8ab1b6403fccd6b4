//! The layer stack's side of the renderer: keeping composed heights current (a quad is
//! recomposed when its plan's stamp differs from its slot's), layer edits, the composition
//! counters, and composing or reading heights on demand for tools and tests.

use super::*;
use crate::gpu::compose::ComposePools;
use crate::scene::loader::EdgeFields;

impl Renderer {
    /// Replaces layer `index`'s settings (its identity stays, its revision is bumped): the
    /// resident quads it touches are recomposed from the next prepared frame on, and no others.
    /// A dataset layer keeps its store and dataset (a different one needs the scene reopened).
    pub fn update_layer(&mut self, index: usize, spec: LayerSpec) -> Result<(), LayerError> {
        let Some(old) = self.scene.stack.layers.get(index) else {
            return Err(LayerError::field(&spec.name, "index", format!("{index} is not a layer of the stack")));
        };
        let store = |s: &LayerSpec| s.as_dataset().map(|d| (d.store.clone(), s.store_dataset().to_string()));
        if store(&old.spec) != store(&spec) || old.spec.kind() != spec.kind() {
            return Err(LayerError::field(
                &spec.name,
                "store",
                "a layer's kind, store and dataset are fixed once open".into(),
            ));
        }
        let shifted = old.spec.shift_m() != spec.shift_m();
        let restroked = (old.spec.strokes(), old.spec.applied()) != (spec.strokes(), spec.applied());
        let name = spec.name.clone();
        self.scene.stack.set(index, spec)?;
        if restroked {
            self.scene.attach_edit(index).map_err(|e| LayerError::caused(&name, "strokes", "cannot be applied", e))?;
        }
        if shifted {
            // Other tiles: the dataset under its new shift (the loader learns of it).
            let before = self.scene.datasets.len();
            self.scene
                .reattach_shifted(index)
                .map_err(|e| LayerError::caused(&name, "shift_m", "cannot be read", e))?;
            if self.scene.datasets.len() != before {
                self.loader = Loader::start(self.scene.datasets.clone(), self.scene.ellipsoid, loader_threads());
            }
        }
        self.cache.plans.clear();
        Ok(())
    }

    /// Inserts a constant, procedural, difference or edit layer at `index` (0: bottom); the quads
    /// it touches are recomposed. Dataset layers need their store opened with the scene (reopen
    /// the project, or [`Renderer::insert_dataset_layer`]).
    pub fn insert_layer(&mut self, index: usize, spec: LayerSpec) -> Result<(), LayerError> {
        if spec.is_data() {
            return Err(LayerError::field(
                &spec.name,
                "kind",
                "a dataset layer is added to the project file and opened with it".into(),
            ));
        }
        let edit = spec.holds_deltas();
        let name = spec.name.clone();
        self.scene.stack.insert(index, spec)?;
        if edit && let Err(e) = self.scene.attach_edit(index) {
            let _ = self.scene.stack.remove(index);
            return Err(LayerError::caused(&name, "strokes", "cannot be applied", e));
        }
        self.cache.plans.clear();
        Ok(())
    }

    /// Inserts a dataset layer at `index` (0: bottom) reading `info` (opened off the frame's
    /// thread: [`crate::scene::open_dataset`]); the quads it touches are composed anew, and
    /// the loader restarts to read a dataset the scene did not have.
    pub fn insert_dataset_layer(
        &mut self,
        index: usize,
        spec: LayerSpec,
        info: crate::scene::dataset::DatasetInfo,
    ) -> Result<(), GpuError> {
        let before = self.scene.datasets.len();
        self.scene.insert_dataset_layer(index, spec, info)?;
        if self.scene.datasets.len() != before {
            self.loader = Loader::start(self.scene.datasets.clone(), self.scene.ellipsoid, loader_threads());
        }
        self.cache.plans.clear();
        Ok(())
    }

    /// Removes layer `index`; the quads it touched are recomposed.
    pub fn remove_layer(&mut self, index: usize) -> Result<(), LayerError> {
        if index >= self.scene.stack.layers.len() {
            return Err(LayerError::field("?", "index", format!("{index} is not a layer of the stack")));
        }
        let layer = self.scene.stack.remove(index)?;
        self.scene.dataset_of.remove(&layer.uid);
        self.scene.edits.remove(&layer.uid);
        self.cache.plans.clear();
        Ok(())
    }

    /// Moves layer `from` to position `to` (0: bottom); the quads both touch are recomposed.
    pub fn move_layer(&mut self, from: usize, to: usize) {
        self.scene.stack.move_layer(from, to);
        self.cache.plans.clear();
    }

    /// Forgets which stamp every composed slot holds, so that each resident quad is recomposed
    /// when next needed (its sources stay on the GPU): for benchmarks of the kernel.
    pub fn invalidate_composed(&mut self) {
        self.composed.clear();
    }

    /// Waits until the GPU has finished everything submitted (benchmarks time with it).
    pub fn wait_idle(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(format!("the GPU did not finish: {e}")))
    }

    /// What composition has done so far.
    pub fn compose_counters(&self) -> ComposeCounters {
        self.counters
    }

    /// The composed heights of a resident quad, read back from the GPU (NaN where no data), or
    /// `None` when the quad has no composed slot. Waits for the GPU: for tests and tools.
    pub fn read_heights(&self, quad: QuadId) -> Result<Option<Vec<f32>>, GpuError> {
        self.read_slot(&self.heights_buffer, quad)
    }

    /// The drawn difference A − B at a resident quad, read back from the overlay pool (NaN where
    /// either side has no data), or `None` when the quad has no composed slot or no difference is
    /// drawn. Waits for the GPU: for tests and tools.
    pub fn read_difference(&self, quad: QuadId) -> Result<Option<Vec<f32>>, GpuError> {
        if self.overlay_buffer.size() <= 16 {
            return Ok(None);
        }
        self.read_slot(&self.overlay_buffer, quad)
    }

    fn read_slot(&self, buffer: &wgpu::Buffer, quad: QuadId) -> Result<Option<Vec<f32>>, GpuError> {
        let Some(slot) = self.heights_pool.get(quad) else { return Ok(None) };
        let bytes = u64::from(SAMPLES * SAMPLES) * 4;
        let read = crate::gpu::compute::readback_buffer(&self.device, "heights read", bytes);
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, u64::from(slot) * bytes, &read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let values: Vec<f32> = crate::gpu::compute::read_mapped(&self.device, &read)?;
        Ok(Some(values.iter().map(|&v| if v < -1e37 { f32::NAN } else { v }).collect()))
    }

    /// Makes sure a quad's composed heights are current: nothing to do when its slot holds its
    /// plan's stamp; else, once its maps and every source tile it reads are on the GPU, a job
    /// for the batch (source tiles in the CPU cache are uploaded within the frame's budget, the
    /// rest asked of the loader); with `on` the CPU, a job for the CPU reference instead
    /// ([`Renderer::queue_here`]). Returns whether the quad has current heights (or needs none).
    pub(super) fn ensure_heights(
        &mut self,
        quad: QuadId,
        on: ComposeOn,
        batch: &mut ComposeBatch,
        stats: &mut FrameStats,
        requests: &mut Vec<DataKey>,
    ) -> bool {
        let plan = self.cache.plan(&self.scene, quad);
        if !plan.has_data(&self.scene.stack) {
            return true;
        }
        if self.composed.get(&quad) == Some(&plan.stamp) && self.heights_pool.touch(quad, self.frame).is_some() {
            return true;
        }
        if on == ComposeOn::Cpu {
            return self.queue_here(quad, plan, requests);
        }
        let mut ready = self.missing_maps(quad).is_none();
        let mut slots = Vec::with_capacity(plan.layers.len());
        for planned in plan.all_layers() {
            let Some((source, edge)) = self.scene.layer_tiles(planned.index, quad) else {
                slots.push((NO_SLOT, NO_SLOT));
                continue;
            };
            let source = self.tile_slot(source, stats, requests);
            let edge = edge.map_or(Some(NO_SLOT), |key| self.tile_slot(key, stats, requests));
            match (source, edge) {
                (Some(s), Some(e)) => slots.push((s, e)),
                _ => ready = false,
            }
        }
        if !ready {
            return false;
        }
        let Some(height_slot) = self.heights_pool.allocate(quad, self.frame) else { return false };
        let map_slot =
            (!self.flat.is_flat(quad)).then(|| self.maps_pool.get(MapSymmetry::of(quad).canonical)).flatten();
        let geometry = self.reference_corners(quad);
        batch.push(&self.scene.stack, &plan, &geometry, height_slot, map_slot, &|k| slots[k]);
        self.composed.insert(quad, plan.stamp);
        true
    }

    /// The GPU slot of a source or edge tile: resident, or uploaded from the CPU cache within the
    /// frame's budget; else asked of the loader (None).
    fn tile_slot(&mut self, key: DataKey, stats: &mut FrameStats, requests: &mut Vec<DataKey>) -> Option<u32> {
        if let Some(slot) = self.sources_pool.touch(key, self.frame) {
            return Some(slot);
        }
        self.make_edit_tile(key)?;
        if self.cpu.contains(key) && stats.uploads < UPLOADS_PER_FRAME && self.upload(key) {
            stats.uploads += 1;
            return self.sources_pool.get(key);
        }
        if !self.cpu.contains(key) && !requests.contains(&key) {
            requests.push(key);
        }
        None
    }

    /// An edit layer's tile into the CPU cache when `key` is one and it is not there: its deltas
    /// are in memory, so it is made here, within the frame (None: it cannot be made).
    pub(super) fn make_edit_tile(&mut self, key: DataKey) -> Option<()> {
        if let DataKey::Edit(..) = key
            && !self.cpu.contains(key)
        {
            let tile = self.scene.read_layer_tile(key, &mut [], &EdgeFields::default()).ok()?;
            self.cpu.insert(Loaded::Tile(key, Ok(std::sync::Arc::new(tile))));
        }
        Some(())
    }

    /// The quad's corner geometry (the bounding geometry's corners are the exact ones).
    pub(super) fn reference_corners(&mut self, quad: QuadId) -> QuadGeometry {
        self.cache.geometry(&self.scene, quad).clone()
    }

    /// Composes `quads` now, waiting for their maps and source tiles (read on this thread):
    /// for the command line (`export`, `bench compose`) and tests, never for a frame. Returns the
    /// composition's statistics; [`Renderer::read_heights`] then reads each quad back.
    pub fn compose_now(&mut self, quads: &[QuadId]) -> Result<FrameStats, GpuError> {
        self.frame += 1;
        self.ensure_overlay();
        let mut stats = FrameStats::default();
        let mut batch = ComposeBatch::default();
        let mut stores: Vec<Option<crate::store::Store>> = self.scene.datasets.iter().map(|_| None).collect();
        let fields = EdgeFields::default();
        for &quad in quads {
            let canonical = MapSymmetry::of(quad).canonical;
            if !self.flat.is_flat(quad) && self.maps_pool.touch(canonical, self.frame).is_none() {
                let maps = crate::ecm::geometry::MapCache::new().get(
                    &self.scene.ellipsoid,
                    CubeProjection::Qsc,
                    MapSymmetry::of(quad),
                    SAMPLES,
                );
                self.cpu.insert(Loaded::Maps(canonical, maps));
                if !self.upload(DataKey::Maps(canonical)) {
                    return Err(GpuError::Stack(format!("no free map slot for {quad}: compose fewer quads at once")));
                }
            }
            let plan = self.cache.plan(&self.scene, quad);
            for planned in plan.all_layers() {
                let Some((source, edge)) = self.scene.layer_tiles(planned.index, quad) else { continue };
                for key in std::iter::once(source).chain(edge) {
                    if self.sources_pool.touch(key, self.frame).is_some() {
                        continue;
                    }
                    let tile = self.scene.read_layer_tile(key, &mut stores, &fields)?;
                    if let DataKey::Source(d, q) = key {
                        self.cache.note_tile(d, q, &tile);
                    }
                    self.cpu.insert(Loaded::Tile(key, Ok(std::sync::Arc::new(tile))));
                    if !self.upload(key) {
                        return Err(GpuError::Stack(format!(
                            "no free source slot for {quad}: compose fewer quads at once"
                        )));
                    }
                }
            }
            let mut requests = Vec::new();
            stats.uploads = 0; // the budget per frame does not apply here
            if !self.ensure_heights(quad, ComposeOn::Gpu, &mut batch, &mut stats, &mut requests) {
                return Err(GpuError::Stack(format!("{quad} could not be composed (GPU cache full?)")));
            }
        }
        self.submit_composition(&batch, &mut stats);
        Ok(stats)
    }

    /// Records the batch in the frame's statistics and the counters, and submits its dispatch.
    pub(super) fn submit_composition(&mut self, batch: &ComposeBatch, stats: &mut FrameStats) {
        self.compose_queued(stats);
        stats.composed.extend_from_slice(batch.quads());
        stats.layers_read += batch.layers_read;
        self.counters.quads += batch.len() as u64;
        self.counters.layers_read += batch.layers_read as u64;
        if batch.is_empty() {
            return;
        }
        let mut encoder = self.device.create_command_encoder(&Default::default());
        let pools = ComposePools {
            sources: &self.sources_buffer,
            map_o: &self.map_buffers[0],
            heights: &self.heights_buffer,
            overlay: &self.overlay_buffer,
        };
        self.compose.encode(&self.device, &mut encoder, batch, pools);
        self.queue.submit([encoder.finish()]);
    }
}
