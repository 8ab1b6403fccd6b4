//! The data side of quad selection: per-quad geometry and bounds (cached under the height range
//! they were computed for), readiness and refinability, borrowed from the renderer's parts.

use std::collections::HashMap;

use glam::DVec3;

use super::scene::Scene;
use super::select::{QuadInfo, QuadSource};
use super::slots::SlotPool;
use crate::ecm::geometry::{FlatRule, HeightRange, MapSymmetry, QuadBounds, QuadGeometry};
use crate::ecm::{CubeProjection, QuadId};

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

/// Per-quad geometry and bounds kept for selection and per-frame values.
pub(crate) struct QuadCache {
    pub(crate) geometry: HashMap<QuadId, QuadGeometry>,
    pub(crate) infos: HashMap<QuadId, ((f32, f32), QuadInfo)>,
    pub(crate) ranges: HashMap<QuadId, (f32, f32, f32)>,
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

    /// The height range a quad may span (its own once loaded; the datasets' before), with 0
    /// (where no-data samples are drawn), exaggerated.
    pub(crate) fn range(&self, scene: &Scene, quad: QuadId, has_data: bool, exaggeration: f64) -> (f32, f32) {
        let (lo, hi) = match self.ranges.get(&quad) {
            Some(&(lo, hi, _)) => (f64::from(lo), f64::from(hi)),
            None if has_data => scene.range_m,
            None => (0.0, 0.0),
        };
        // No-data samples are drawn at height 0, so 0 is always in the range.
        ((lo.min(0.0) * exaggeration) as f32, (hi.max(0.0) * exaggeration) as f32)
    }
}

impl QuadSource for Source<'_> {
    fn info(&mut self, quad: QuadId) -> QuadInfo {
        let has = self.scene.has_data(quad);
        let range = self.cache.range(self.scene, quad, has, self.exaggeration);
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
        // The 257² surface between the coarse samples bulges by at most the sagitta of a coarse
        // cell's diagonal on the most curved part of the ellipsoid.
        let cell = edge_m / f64::from(BOUND_SAMPLES - 1) * std::f64::consts::SQRT_2;
        let r_min = ellipsoid.b_m() * ellipsoid.b_m() / ellipsoid.a_m();
        bounds.half_extents_m += DVec3::splat(1.5 * cell * cell / (8.0 * r_min));
        let info = QuadInfo { bounds, edge_m };
        self.cache.infos.insert(quad, (range, info));
        info
    }

    fn ready(&self, quad: QuadId) -> bool {
        let heights = !self.scene.has_data(quad) || self.heights.get(quad).is_some();
        let maps = self.flat.is_flat(quad) || self.maps.get(MapSymmetry::of(quad).canonical).is_some();
        heights && maps
    }

    fn refinable(&self, quad: QuadId) -> bool {
        match self.scene.finest_level_at(quad) {
            Some(f) => quad.level < f,
            None => quad.level < NODATA_MAX_LEVEL,
        }
    }
}
