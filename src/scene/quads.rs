//! The data side of quad selection: per-quad geometry and bounds (cached under the height range
//! they were computed for), readiness and refinability, borrowed from the renderer's parts.

use std::collections::HashMap;
use std::sync::Arc;

use glam::DVec3;

use super::Scene;
use super::block_ranges::BlockRanges;
use super::loader::QuadHeights;
use super::patches::{
    DATA_LEVELS_UP, PATCH_CELLS, PATCHES_PER_EDGE, STRIDES, StrideBoxes, data_sample, levels_drawn_at,
};
use super::select::{QuadInfo, QuadSource};
use super::slots::SlotPool;
use crate::ecm::geometry::{FlatRule, HeightRange, MapSymmetry, QuadBounds, QuadGeometry};
use crate::ecm::{CubeProjection, QuadId};
use crate::layers::{MaskPlan, QuadPlan, ValueSource, noise, range_bound};

/// Quads without data are split down to this level at most: there the chord between two samples
/// is within millimetres of the ellipsoid on Earth-sized bodies.
const NODATA_MAX_LEVEL: u8 = 6;
/// Samples per edge of the coarse geometry that bounds a quad.
const BOUND_SAMPLES: u32 = 17;

/// The flat rule of a body and height range, fitted once per process (the fit scans thousands
/// of quads).
pub(crate) fn flat_rule_for(ellipsoid: &crate::geodesy::Ellipsoid, heights: HeightRange) -> FlatRule {
    type Key = (u64, u64, u64, u64);
    static RULES: std::sync::Mutex<Vec<(Key, FlatRule)>> = std::sync::Mutex::new(Vec::new());
    let key = (ellipsoid.a_m().to_bits(), ellipsoid.b_m().to_bits(), heights.min_m.to_bits(), heights.max_m.to_bits());
    let mut rules = RULES.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, rule)) = rules.iter().find(|(k, _)| *k == key) {
        return *rule;
    }
    let rule = FlatRule::fit(ellipsoid, CubeProjection::Qsc, FlatRule::DEFAULT_TOLERANCE_M, heights);
    rules.push((key, rule));
    rule
}

/// The heights the terrain may reach: the body's range, widened by the exaggerated data.
pub(crate) fn exaggerated_range(scene: &Scene, exaggeration: f64) -> HeightRange {
    let heights = HeightRange::for_body(&scene.ellipsoid);
    HeightRange {
        min_m: heights.min_m.min(scene.range_m.0 * exaggeration),
        max_m: heights.max_m.max(scene.range_m.1 * exaggeration),
    }
}

/// A quad's 64 patches' boxes at each stride (row-major), shared with the frame that draws them.
pub(crate) type PatchBoxes = Arc<Vec<StrideBoxes>>;

/// Per-quad geometry, plans and bounds kept for selection and per-frame values.
#[derive(Default)]
pub(crate) struct QuadCache {
    pub(crate) geometry: HashMap<QuadId, QuadGeometry>,
    pub(crate) infos: HashMap<QuadId, ((f32, f32), QuadInfo)>,
    /// Per quad, what composing it reads (dropped when the stack changes).
    pub(crate) plans: HashMap<QuadId, Arc<QuadPlan>>,
    /// Per loaded source tile (dataset, quad): its height ranges and edge roughness.
    pub(crate) tile_ranges: HashMap<(u32, QuadId), TileSummary>,
    /// Tile summaries noted so far (patch ranges computed before the last one may be stale).
    pub(crate) tiles_noted: u64,
    /// Per drawn quad, its 64 patches' boxes at each stride, under the height ranges they were
    /// computed for and what those were read from (tiles noted, plan stamp, exaggeration).
    pub(crate) patches: HashMap<QuadId, PatchCacheEntry>,
}

/// A drawn quad's patch boxes, the ranges they hold and the key those were computed under.
pub(crate) type PatchCacheEntry = ((u64, u64, u64), Vec<PatchRanges>, PatchBoxes);

/// What bounds need of a loaded source tile.
pub(crate) struct TileSummary {
    /// Lowest and highest height with data, metres.
    pub(crate) range_m: (f32, f32),
    /// Largest step between neighbouring samples along the edges, metres.
    pub(crate) edge_roughness_m: f32,
    /// The ranges of its 8 × 8-cell blocks.
    pub(crate) blocks: Arc<BlockRanges>,
}

impl TileSummary {
    pub(crate) fn of(tile: &QuadHeights) -> TileSummary {
        TileSummary { range_m: tile.range_m, edge_roughness_m: tile.edge_roughness_m, blocks: tile.blocks.clone() }
    }
}

/// A patch's height range (exaggerated metres) at each stride: what it draws there.
pub(crate) type PatchRanges = [(f32, f32); STRIDES.len()];

/// How far the 257² surface between the coarse bounding samples may bulge out of the box of
/// those samples: the sagitta of a coarse cell's diagonal on the most curved part of the
/// ellipsoid, with half again for safety.
fn sag_pad_m(ellipsoid: &crate::geodesy::Ellipsoid, edge_m: f64) -> f64 {
    let cell = edge_m / f64::from(BOUND_SAMPLES - 1) * std::f64::consts::SQRT_2;
    let r_min = ellipsoid.b_m() * ellipsoid.b_m() / ellipsoid.a_m();
    1.5 * cell * cell / (8.0 * r_min)
}

/// The data side of selection, borrowing the renderer's parts.
pub(crate) struct Source<'a> {
    pub(crate) scene: &'a Scene,
    pub(crate) cache: &'a mut QuadCache,
    pub(crate) heights: &'a SlotPool,
    pub(crate) maps: &'a SlotPool,
    pub(crate) flat: &'a FlatRule,
    pub(crate) exaggeration: f64,
}

impl QuadCache {
    pub(crate) fn geometry(&mut self, scene: &Scene, quad: QuadId) -> &QuadGeometry {
        self.geometry
            .entry(quad)
            .or_insert_with(|| QuadGeometry::compute(&scene.ellipsoid, CubeProjection::Qsc, quad, BOUND_SAMPLES))
    }

    /// The quad's 64 patches' boxes at each stride, for the heights each draws there
    /// ([`QuadCache::patch_ranges`]), cached under those ranges.
    pub(crate) fn patch_bounds(
        &mut self,
        scene: &Scene,
        plan: &QuadPlan,
        exaggeration: f64,
        edge_m: f64,
    ) -> PatchBoxes {
        let quad = plan.quad;
        let key = (self.tiles_noted, plan.stamp, exaggeration.to_bits());
        if let Some((k, _, b)) = self.patches.get(&quad)
            && *k == key
        {
            return b.clone();
        }
        let ranges = self.patch_ranges(scene, plan, exaggeration);
        if let Some((k, r, b)) = self.patches.get_mut(&quad)
            && *r == ranges
        {
            *k = key;
            return b.clone();
        }
        let pad = sag_pad_m(&scene.ellipsoid, edge_m);
        let g = self.geometry(scene, quad);
        let per_stride: Vec<Vec<QuadBounds>> = (0..STRIDES.len())
            .map(|k| {
                let r: Vec<(f64, f64)> = ranges.iter().map(|p| (f64::from(p[k].0), f64::from(p[k].1))).collect();
                super::patches::patch_bounds(g, &r, pad)
            })
            .collect();
        let boxes: Vec<StrideBoxes> = (0..ranges.len()).map(|n| std::array::from_fn(|k| per_stride[k][n])).collect();
        let boxes = Arc::new(boxes);
        self.patches.insert(quad, (key, ranges, boxes.clone()));
        boxes
    }

    /// The heights each of a quad's 64 patches draws at each stride (exaggerated metres): at
    /// stride 2^k the composed data of its own level, of the level k up and of the level k + 1 up
    /// ([`levels_drawn_at`]), each bounded by interval arithmetic through the plan with the
    /// dataset layers' ranges read from the blocks of those levels' tiles under the patch, and 0
    /// where a sample may have no data (drawn at height 0).
    pub(crate) fn patch_ranges(&self, scene: &Scene, plan: &QuadPlan, exaggeration: f64) -> Vec<PatchRanges> {
        let quad = plan.quad;
        let up_max = DATA_LEVELS_UP.min(u32::from(quad.level));
        let patches = PATCHES_PER_EDGE * PATCHES_PER_EDGE;
        (0..patches)
            .map(|n| {
                let (i0, j0) = ((n % PATCHES_PER_EDGE) * PATCH_CELLS, (n / PATCHES_PER_EDGE) * PATCH_CELLS);
                let (i1, j1) = (i0 + PATCH_CELLS, j0 + PATCH_CELLS);
                // The composed range of the data `up` levels up under the patch.
                let at_level = |up: u32| -> (f64, f64) {
                    let up = up.min(up_max);
                    let gaps = std::cell::Cell::new(false);
                    let layer_range = |k: usize| -> (f64, f64) {
                        let index = plan.layers[k].index;
                        let layer = &scene.stack.layers[index];
                        let Some(d) = scene.dataset_of_layer(index) else { return layer.value_range_m() };
                        let (a, ai0, aj0) = data_sample(quad, i0, j0, up);
                        let (_, ai1, aj1) = data_sample(quad, i1, j1, up);
                        let Some(tile) = self.tile_ranges.get(&(d as u32, a)) else {
                            gaps.set(true);
                            return layer.value_range_m();
                        };
                        let span = tile.blocks.over((ai0, ai1), (aj0, aj1));
                        gaps.set(gaps.get() || span.gaps);
                        match span.range_m {
                            Some((lo, hi)) => layer.value_range_from_raw_m((f64::from(lo), f64::from(hi))),
                            None => (1.0, 0.0), // no sample with data: nothing to bound
                        }
                    };
                    let composed = range_bound(&scene.stack, plan, &layer_range);
                    let covered = !gaps.get() && plan.layers.iter().any(|p| surely_covers(scene, p));
                    match composed {
                        Some((lo, hi)) if covered => (lo, hi),
                        Some((lo, hi)) => (lo.min(0.0), hi.max(0.0)),
                        None => (0.0, 0.0),
                    }
                };
                let levels: Vec<(f64, f64)> = (0..STRIDES.len() as u32).map(at_level).collect();
                std::array::from_fn(|k| {
                    let (lo, hi) = levels_drawn_at(k)
                        .map(|j| levels[j])
                        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (l, h)| (a.min(l), b.max(h)));
                    let (lo, hi) = (lo * exaggeration, hi * exaggeration);
                    ((lo.min(hi)) as f32, (hi.max(lo)) as f32)
                })
            })
            .collect()
    }

    /// Keeps what bounds need of a loaded source tile of dataset `d` at `quad`.
    pub(crate) fn note_tile(&mut self, d: u32, quad: QuadId, tile: &QuadHeights) {
        self.tile_ranges.insert((d, quad), TileSummary::of(tile));
        self.tiles_noted += 1;
    }

    /// The quad's plan (cached until the stack changes).
    pub(crate) fn plan(&mut self, scene: &Scene, quad: QuadId) -> Arc<QuadPlan> {
        self.plans.entry(quad).or_insert_with(|| Arc::new(scene.plan(quad))).clone()
    }

    /// The value range of the plan's k-th layer at its quad: a dataset's loaded tile's, else the
    /// layer's own bound.
    fn layer_range(&self, scene: &Scene, plan: &QuadPlan, k: usize) -> (f64, f64) {
        let index = plan.layers[k].index;
        let layer = &scene.stack.layers[index];
        if let Some(d) = scene.dataset_of_layer(index)
            && let Some(t) = self.tile_ranges.get(&(d as u32, plan.quad))
        {
            return layer.value_range_from_raw_m((f64::from(t.range_m.0), f64::from(t.range_m.1)));
        }
        layer.value_range_m()
    }

    /// The height range a quad may span (interval arithmetic through its plan, with the loaded
    /// tiles' ranges where known), with 0 (where no-data samples are drawn), exaggerated.
    pub(crate) fn range(&self, scene: &Scene, plan: &QuadPlan, exaggeration: f64) -> (f32, f32) {
        let (lo, hi) = range_bound(&scene.stack, plan, &|k| self.layer_range(scene, plan, k)).unwrap_or((0.0, 0.0));
        // No-data samples are drawn at height 0, so 0 is always in the range.
        ((lo.min(0.0) * exaggeration) as f32, (hi.max(0.0) * exaggeration) as f32)
    }

    /// A bound on the height difference between neighbouring samples along the quad's edges,
    /// metres (sizes the skirt): the sum over the plan's layers of what each can change there:
    /// a dataset its tile's edge roughness (its range before the tile arrives), noise its
    /// slope bound over one sample, a dataset's corrections their change over one sample, a
    /// feathered mask its value span × the mask's slope.
    pub(crate) fn roughness(&self, scene: &Scene, plan: &QuadPlan, spacing_m: f64) -> f64 {
        let mut total = 0.0;
        for (k, planned) in plan.layers.iter().enumerate() {
            let layer = &scene.stack.layers[planned.index];
            let spec = &layer.spec;
            let (lo, hi) = self.layer_range(scene, plan, k);
            total += match (spec.value_source(), scene.dataset_of_layer(planned.index)) {
                (ValueSource::StoreTile, Some(d)) => self
                    .tile_ranges
                    .get(&(d as u32, plan.quad))
                    .map_or(hi - lo, |t| f64::from(t.edge_roughness_m) * spec.scale.abs()),
                (ValueSource::Noise(n), _) => noise::noise_change_bound_m(n, spacing_m) * spec.scale.abs(),
                // Deltas may step anywhere within their span (a stroke's edge, a channel).
                (ValueSource::Deltas, _) if hi >= lo => hi - lo,
                _ => 0.0,
            } * spec.opacity;
            // A dataset's corrections change between samples too.
            total += layer.correction.step_bound_m(spacing_m, hi - lo) * spec.opacity;
            if let (MaskPlan::Partial(_), true) = (&planned.mask, spec.feather_m > 0.0) {
                total += (hi - lo).abs().max(hi.abs()) * (1.5 * spacing_m / spec.feather_m).min(1.0);
            }
        }
        total
    }
}

impl QuadSource for Source<'_> {
    fn info(&mut self, quad: QuadId) -> QuadInfo {
        let plan = self.cache.plan(self.scene, quad);
        let range = self.cache.range(self.scene, &plan, self.exaggeration);
        if let Some((r, info)) = self.cache.infos.get(&quad)
            && *r == range
        {
            return *info;
        }
        let ellipsoid = self.scene.ellipsoid;
        let g = self.cache.geometry(self.scene, quad);
        let q = g.corners_ecef;
        let edge_m =
            [(q[1] - q[0]), (q[2] - q[0]), (q[3] - q[1]), (q[3] - q[2])].iter().map(|v| v.length()).fold(0.0, f64::max);
        let mut bounds = QuadBounds::compute(g, f64::from(range.0), f64::from(range.1));
        bounds.half_extents_m += DVec3::splat(sag_pad_m(&ellipsoid, edge_m));
        let info = QuadInfo { bounds, edge_m };
        self.cache.infos.insert(quad, (range, info));
        info
    }

    fn ready(&self, quad: QuadId) -> bool {
        let stack = &self.scene.stack;
        let has =
            self.cache.plans.get(&quad).map_or_else(|| self.scene.plan(quad).has_data(stack), |p| p.has_data(stack));
        let heights = !has || self.heights.get(quad).is_some();
        let maps = self.flat.is_flat(quad) || self.maps.get(MapSymmetry::of(quad).canonical).is_some();
        heights && maps
    }

    fn refinable(&self, quad: QuadId) -> bool {
        let plan = self.cache.plans.get(&quad).cloned().unwrap_or_else(|| Arc::new(self.scene.plan(quad)));
        let data = match self.scene.finest_level_in(&plan) {
            Some(f) => quad.level < f,
            None => quad.level < NODATA_MAX_LEVEL,
        };
        data || self.scene.stack.refines_below_data(quad) || self.scene.stack.deltas_refine(&plan)
    }
}

/// Whether a planned layer gives a value at every sample of its quad: a full mask and no gaps
/// (a dataset whose tile has none where it is read, a constant or noise) and no valid range that
/// could drop a value.
fn surely_covers(scene: &Scene, planned: &crate::layers::PlannedLayer) -> bool {
    let spec = &scene.stack.layers[planned.index].spec;
    planned.mask == MaskPlan::Full && spec.valid_range_m.is_none() && planned.opacity > 0.0
}
