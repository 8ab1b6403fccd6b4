//! The scene's CPU reference of composition: quads composed from their layers' tiles on the
//! caller's threads (export, comparison, benchmarks and tests), the renderer's GPU pass's twin.

use std::collections::HashMap;

use rayon::prelude::*;

use super::loader::{DataKey, EdgeFields, QuadHeights, read_tile};
use super::{Composed, Grid, Scene, SceneError};
use crate::Invalid;
use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::layers::{LayerTiles, compose_difference, compose_quad};
use crate::store::Store;

impl Scene {
    /// Composes quads with the CPU reference, reading their source and edge tiles here (on the
    /// caller's thread pool, quads in parallel): for export, comparison, benchmarks and tests.
    pub fn compose_cpu(&self, quads: &[QuadId]) -> Result<HashMap<QuadId, Vec<f32>>, SceneError> {
        Ok(self.compose_cpu_of(quads, false)?.into_iter().map(|(q, (h, _))| (q, h)).collect())
    }

    /// [`Scene::compose_cpu`], with the drawn difference layer's A − B where the quad's plan has
    /// one (the CPU reference of the overlay pool).
    pub fn compose_cpu_with_difference(&self, quads: &[QuadId]) -> Result<HashMap<QuadId, Composed>, SceneError> {
        self.compose_cpu_of(quads, true)
    }

    fn compose_cpu_of(&self, quads: &[QuadId], difference: bool) -> Result<HashMap<QuadId, Composed>, SceneError> {
        let fields = EdgeFields::default();
        // Quads in parallel, each worker with its own open stores (at least 4 quads a worker, so
        // the stores are not opened for every quad); every quad is composed alone, so the result
        // is the same on any number of threads.
        quads
            .par_iter()
            .with_min_len(4)
            .map_init(
                || self.datasets.iter().map(|_| None).collect::<Vec<Option<Store>>>(),
                |stores, &quad| -> Result<(QuadId, Composed), SceneError> {
                    let mut plan = self.plan(quad);
                    if !difference {
                        // Heights only: the difference's operands are not read.
                        plan.difference = None;
                    }
                    // Per planned layer (the heights', then the difference's): its raw and edge tiles.
                    let mut tiles: Vec<(Option<Grid>, Option<Grid>)> = Vec::with_capacity(plan.layers.len());
                    for l in plan.all_layers() {
                        let mut read = |key| self.read_layer_tile(key, stores, &fields).map(|t| t.grid);
                        tiles.push(match self.layer_tiles(l.index, quad) {
                            Some((source, edge)) => (Some(read(source)?), edge.map(&mut read).transpose()?),
                            None => (None, None),
                        });
                    }
                    let layer_tiles =
                        |k: usize| LayerTiles { raw: tiles[k].0.as_deref(), edge_m: tiles[k].1.as_deref() };
                    let heights = compose_quad(&self.stack, &plan, &layer_tiles);
                    let offset = plan.layers.len();
                    let difference = plan
                        .difference
                        .as_ref()
                        .map(|d| compose_difference(&self.stack, d, &|k| layer_tiles(offset + k)));
                    Ok((quad, (heights, difference)))
                },
            )
            .collect()
    }

    /// A tile a layer reads: a dataset's from its store, an edit layer's from its raster.
    pub fn read_layer_tile(
        &self,
        key: DataKey,
        stores: &mut [Option<Store>],
        fields: &EdgeFields,
    ) -> Result<QuadHeights, SceneError> {
        if let DataKey::Edit(uid, quad, _) = key {
            let raster = self
                .stack
                .layers
                .iter()
                .find(|l| l.uid as u32 == uid)
                .and_then(|l| self.edits.get(&l.uid))
                .ok_or_else(|| Invalid(format!("no edit layer reads {key}")))?;
            return Ok(QuadHeights::new(raster.grid(quad).unwrap_or_else(|| vec![0.0; (GRID * GRID) as usize])));
        }
        Ok(read_tile(key, &self.datasets, stores, fields)?)
    }

    /// One quad's composed heights by the CPU reference (NaN where no layer has data).
    pub fn heights_cpu(&self, quad: QuadId) -> Result<Vec<f32>, SceneError> {
        self.compose_cpu(&[quad])?.remove(&quad).ok_or_else(|| Invalid(format!("{quad} was not composed")).into())
    }
}
