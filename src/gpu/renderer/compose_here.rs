//! Composing a frame's quads with the CPU reference: what a renderer on a software adapter does
//! (there the compute pass runs on the same cores, 27× slower for one dataset layer:
//! BENCHMARKS.md). The frame queues a job per quad as the compute pass's batch does, and the
//! jobs are composed in parallel when the frame submits its composition; the heights, and the
//! drawn difference's A − B, go into the same slots the compute pass fills, with the same
//! stand-in where a sample has no data, so that everything downstream (patch errors, the
//! terrain's reads, `read_heights`) is the same on either path.

use std::sync::Arc;

use rayon::prelude::*;

use super::*;
use crate::layers::{LayerTiles, QuadPlan, compose_difference, compose_quad};
use crate::scene::loader::QuadHeights;

/// A planned layer's raw and edge tiles.
type Tiles = (Option<Arc<QuadHeights>>, Option<Arc<QuadHeights>>);

/// One quad to compose on the CPU: its plan, its height slot, its planned layers' tiles.
pub(super) struct CpuJob {
    plan: Arc<QuadPlan>,
    slot: u32,
    tiles: Vec<Tiles>,
}

impl Renderer {
    /// Queues `quad` for composition by its plan once its maps and every tile it reads are in
    /// the CPU cache (the rest asked of the loader). Returns whether it was queued.
    pub(super) fn queue_here(&mut self, quad: QuadId, plan: Arc<QuadPlan>, requests: &mut Vec<DataKey>) -> bool {
        let mut ready = self.missing_maps(quad).is_none();
        let mut tiles: Vec<Tiles> = Vec::with_capacity(plan.layers.len());
        for planned in plan.all_layers() {
            let Some((source, edge)) = self.scene.layer_tiles(planned.index, quad) else {
                tiles.push((None, None));
                continue;
            };
            let source = self.cpu_tile(source, requests);
            let edge = edge.map(|key| self.cpu_tile(key, requests));
            match (source, edge) {
                (Some(s), None) => tiles.push((Some(s), None)),
                (Some(s), Some(Some(e))) => tiles.push((Some(s), Some(e))),
                _ => ready = false,
            }
        }
        if !ready {
            return false;
        }
        let Some(slot) = self.heights_pool.allocate(quad, self.frame) else { return false };
        self.composed.insert(quad, plan.stamp);
        self.cpu_jobs.push(CpuJob { plan, slot, tiles });
        true
    }

    /// Composes the queued jobs (quads in parallel, each alone: the same on any number of
    /// threads), writes their slots and counts them in the frame's statistics.
    pub(super) fn compose_queued(&mut self, stats: &mut FrameStats) {
        let jobs = std::mem::take(&mut self.cpu_jobs);
        let stack = &self.scene.stack;
        let difference = self.overlay_buffer.size() > 16;
        let composed: Vec<(Vec<f32>, Option<Vec<f32>>)> = jobs
            .par_iter()
            .map(|job| {
                let layer_tiles = |k: usize| LayerTiles {
                    raw: job.tiles[k].0.as_deref().map(|t| t.grid.as_slice()),
                    edge_m: job.tiles[k].1.as_deref().map(|t| t.grid.as_slice()),
                };
                let heights = compose_quad(stack, &job.plan, &layer_tiles);
                let offset = job.plan.layers.len();
                let dh = (job.plan.difference.as_ref())
                    .filter(|_| difference)
                    .map(|d| compose_difference(stack, d, &|k| layer_tiles(offset + k)));
                (heights, dh)
            })
            .collect();
        for (job, (heights, dh)) in jobs.iter().zip(&composed) {
            self.write_slot(&self.heights_buffer, job.slot, heights);
            if let Some(dh) = dh {
                self.write_slot(&self.overlay_buffer, job.slot, dh);
            }
            stats.composed.push(job.plan.quad);
            stats.layers_read += job.tiles.len();
            self.counters.quads += 1;
            self.counters.layers_read += job.tiles.len() as u64;
        }
    }

    /// A tile from the CPU cache, or None after asking the loader for it (an edit layer's tile
    /// is made here, from its raster in memory).
    fn cpu_tile(&mut self, key: DataKey, requests: &mut Vec<DataKey>) -> Option<Arc<QuadHeights>> {
        self.make_edit_tile(key)?;
        let tile = self.cpu.tile(key);
        if tile.is_none() && !self.cpu.contains(key) && !requests.contains(&key) {
            requests.push(key);
        }
        tile
    }

    /// Writes a quad's 257² values into `slot` of a pool, NaN as the stand-in the shaders read as
    /// no data.
    fn write_slot(&self, pool: &wgpu::Buffer, slot: u32, values: &[f32]) {
        let stored: Vec<f32> = values.iter().map(|&h| if h.is_nan() { NODATA_STORED } else { h }).collect();
        let offset = u64::from(slot) * u64::from(SAMPLES * SAMPLES) * 4;
        self.queue.write_buffer(pool, offset, bytemuck::cast_slice(&stored));
    }
}
