//! An edit layer's raster: its height deltas δ as sparse 257² tiles at one level (the finest of its
//! strokes' levels), built from the strokes in order. The raster is a cache of the strokes: the
//! same strokes give the same tiles bit for bit whatever the thread count or the order quads are
//! computed in, because each tile is a pure function of the strokes (each sample's value is folded
//! through the dabs in order, in f64, and rounded to f32 once per stroke), and a tile touched by no
//! stroke is absent (δ = 0).
//!
//! Sample positions are the exact (f64) points of the quad's grid on the ellipsoid, so a sample on
//! an edge shared by two quads of a face gets the same value in both; across a cube face edge the
//! two quads' points agree to rounding (≈ 10⁻⁹ m), and so do their values.
//!
//! Undo restores the quads the undone strokes touched from their before-images, or recomputes
//! them from the strokes before (see [`EditRaster::undo_to`]). Smooth, flatten and ramp read the
//! terrain under the layer through a [`Below`] (see [`super::terrain`]).

use std::collections::{BTreeMap, BTreeSet};

use rayon::prelude::*;

use super::dabs::dab_centres;
use super::kernel::{CpuRasteriser, Dab, Rasteriser, StrokeJob, apply_to_tile};
use super::pyramid::Pyramid;
use super::stroke::Stroke;
use super::terrain::{Below, KeptBelow, Snapshot, Target, smooth_ring_m};
use crate::ecm::grid::GRID;
use crate::ecm::points::quad_ball;
use crate::ecm::{Face, QuadId};
use crate::errors::SharedFailure;
use crate::geodesy::Ellipsoid;
use crate::progress::Watch;

const N: usize = GRID as usize;

/// A stroke that cannot be rasterised: its index, the field and the problem.
#[derive(Debug, Clone, thiserror::Error)]
#[error("strokes[{index}]: {field}: {problem}")]
pub struct StrokeError {
    /// The stroke's index in the layer.
    pub index: usize,
    /// The field.
    pub field: String,
    /// What is wrong.
    pub problem: String,
    /// What failed under it (reading the terrain below, the rasteriser), if anything did.
    #[source]
    pub cause: Option<SharedFailure>,
}

/// The raster. Two rasters are equal when their tiles are, bit for bit (not their generations).
#[derive(Clone)]
pub struct EditRaster {
    /// The body.
    pub ellipsoid: Ellipsoid,
    /// The level of the tiles.
    pub level: u8,
    /// δ per touched quad, 257² row by row from the south, metres.
    pub tiles: BTreeMap<QuadId, Vec<f32>>,
    /// The coarser levels' area means, made on demand.
    pub(super) pyramid: Pyramid,
    /// Bumped by every change.
    pub generation: u32,
    /// Per quad of the raster's level, the generation that last changed it (see
    /// [`EditRaster::stamp`]).
    stamps: std::collections::HashMap<QuadId, u32>,
    /// The stamp of quads no change has reached since the raster was made.
    floor: u32,
    /// The latest strokes' before-images (stroke index, each touched quad's tile before it), so
    /// that undoing them restores tiles instead of recomputing them; the oldest are dropped past
    /// [`HISTORY_BYTES`] (undo then recomputes).
    history: std::collections::VecDeque<(usize, BeforeImages)>,
    history_bytes: usize,
}

/// The tiles one stroke touched as they were before it (None: no tile yet).
type BeforeImages = Vec<(QuadId, Option<Vec<f32>>)>;

/// Memory the undo history may hold.
pub const HISTORY_BYTES: usize = 256 << 20;

/// Equal tiles (bit for bit) at the same level on the same body; generations and undo histories
/// are not compared.
impl PartialEq for EditRaster {
    fn eq(&self, other: &EditRaster) -> bool {
        let bits = |t: &Vec<f32>| t.iter().map(|v| v.to_bits()).collect::<Vec<_>>();
        self.ellipsoid == other.ellipsoid
            && self.level == other.level
            && self.tiles.len() == other.tiles.len()
            && self.tiles.iter().zip(&other.tiles).all(|((q, a), (p, b))| q == p && bits(a) == bits(b))
    }
}

impl std::fmt::Debug for EditRaster {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        // The tiles' quads, not their 66 049 values each.
        f.debug_struct("EditRaster")
            .field("level", &self.level)
            .field("tiles", &self.tiles.keys().collect::<Vec<_>>())
            .field("generation", &self.generation)
            .finish()
    }
}

impl EditRaster {
    /// An empty raster at `level`.
    pub fn new(ellipsoid: Ellipsoid, level: u8) -> EditRaster {
        EditRaster {
            ellipsoid,
            level,
            tiles: BTreeMap::new(),
            pyramid: Pyramid::default(),
            generation: 0,
            stamps: Default::default(),
            floor: 0,
            history: Default::default(),
            history_bytes: 0,
        }
    }

    /// A raster of saved tiles (a cache read back: [`super::cache`]).
    pub fn from_tiles(ellipsoid: Ellipsoid, level: u8, tiles: BTreeMap<QuadId, Vec<f32>>) -> EditRaster {
        let mut raster = EditRaster::new(ellipsoid, level);
        raster.put(tiles.into_iter().map(|(q, t)| (q, Some(t))).collect());
        raster
    }

    /// The raster of `strokes`, at the finest of their levels (each checked first); `below` gives
    /// the terrain under the layer to the strokes that read it (see [`super::terrain`]).
    pub fn build(ellipsoid: Ellipsoid, strokes: &[Stroke], below: &Below) -> Result<EditRaster, StrokeError> {
        EditRaster::build_with(ellipsoid, strokes, below, &CpuRasteriser, &Watch::default())
    }

    /// [`EditRaster::build`] with another rasteriser (the GPU's), the strokes counted on `watch`
    /// (phase `strokes`) and stopped between strokes when it is cancelled.
    pub fn build_with(
        ellipsoid: Ellipsoid,
        strokes: &[Stroke],
        below: &Below,
        rasteriser: &dyn Rasteriser,
        watch: &Watch,
    ) -> Result<EditRaster, StrokeError> {
        // Every stroke checked before any is rasterised (a bad level must not set the raster's).
        for (index, stroke) in strokes.iter().enumerate() {
            stroke.check(ellipsoid.a_m()).map_err(|e| StrokeError {
                index,
                field: e.field,
                problem: e.problem,
                cause: None,
            })?;
        }
        let level = strokes.iter().map(|s| s.level).max().unwrap_or(0);
        let mut raster = EditRaster::new(ellipsoid, level);
        let kept = KeptBelow::new(below);
        watch.start_phase("strokes", strokes.len() as u64);
        for (index, stroke) in strokes.iter().enumerate() {
            watch.check().map_err(|e| StrokeError {
                index,
                field: "strokes".into(),
                problem: "the rebuild was cancelled".into(),
                cause: Some(std::sync::Arc::new(e)),
            })?;
            raster.apply_with(index, stroke, &|q| kept.get(q), rasteriser)?;
            watch.advance();
        }
        Ok(raster)
    }

    /// Applies one stroke (`index` names it in errors; `below`: the terrain under the layer, read
    /// by smooth, flatten and ramp) with the CPU reference; returns the quads it touched.
    pub fn apply(&mut self, index: usize, stroke: &Stroke, below: &Below) -> Result<BTreeSet<QuadId>, StrokeError> {
        self.apply_with(index, stroke, below, &CpuRasteriser)
    }

    /// [`EditRaster::apply`] with another rasteriser (the GPU's: its tiles agree with the CPU
    /// reference's within its stated tolerance, not bit for bit).
    pub fn apply_with(
        &mut self,
        index: usize,
        stroke: &Stroke,
        below: &Below,
        rasteriser: &dyn Rasteriser,
    ) -> Result<BTreeSet<QuadId>, StrokeError> {
        let (dabs, quads) = self.footprint(index, stroke)?;
        // What the stroke reads is taken before it writes anything.
        let (target, snapshot) = self.read_terrain(index, stroke, &dabs, below)?;
        let mut tiles: Vec<(QuadId, Vec<f32>)> =
            quads.iter().map(|q| (*q, self.tiles.get(q).cloned().unwrap_or_else(|| vec![0.0; N * N]))).collect();
        let job = StrokeJob { ellipsoid: &self.ellipsoid, stroke, dabs: &dabs, target, snapshot: snapshot.as_ref() };
        rasteriser.rasterise(&job, &mut tiles).map_err(|e| StrokeError {
            index,
            field: "rasteriser".into(),
            problem: "failed".into(),
            cause: Some(e.into()),
        })?;
        self.apply_tiles(index, tiles);
        Ok(quads)
    }

    /// Puts the tiles operation `index` made (a stroke, an erosion run), keeping the tiles they
    /// replace for undo.
    pub fn apply_tiles(&mut self, index: usize, tiles: Vec<(QuadId, Vec<f32>)>) {
        let before: BeforeImages = tiles.iter().map(|(q, _)| (*q, self.tiles.get(q).cloned())).collect();
        self.history_bytes += before.iter().map(|(_, t)| t.as_ref().map_or(0, |t| t.len() * 4)).sum::<usize>();
        self.history.push_back((index, before));
        while self.history_bytes > HISTORY_BYTES
            && let Some((_, old)) = self.history.pop_front()
        {
            self.history_bytes -= old.iter().map(|(_, t)| t.as_ref().map_or(0, |t| t.len() * 4)).sum::<usize>();
        }
        self.put(tiles.into_iter().map(|(q, t)| (q, Some(t))).collect());
    }

    /// Undoes operations `keep..top` from their before-images while the history has them;
    /// returns how many operations are in effect after it (`keep` when the history reached).
    pub fn restore_to(&mut self, top: usize, keep: usize) -> usize {
        let mut top = top;
        while top > keep && self.history.back().is_some_and(|(index, _)| *index == top - 1) {
            let (_, before) = self.history.pop_back().expect("checked");
            self.history_bytes -= before.iter().map(|(_, t)| t.as_ref().map_or(0, |t| t.len() * 4)).sum::<usize>();
            self.put(before);
            top -= 1;
        }
        top
    }

    /// Undoes back to `strokes[..keep]` after `strokes[keep..]` were applied: the latest strokes'
    /// tiles are restored from their before-images while the history has them; the quads of the
    /// rest are recomputed from the kept strokes; every other tile stays as it is. When a kept
    /// stroke reads the terrain, what it wrote depends on tiles beyond the undone strokes' quads
    /// as they were before it: the raster is then rebuilt from the kept strokes.
    pub fn undo_to(&mut self, strokes: &[Stroke], keep: usize, below: &Below) -> Result<(), StrokeError> {
        let top = self.restore_to(strokes.len(), keep);
        if top == keep {
            return Ok(());
        }
        // Beyond the history: recomputed (and no history below this point matches any more).
        self.history.clear();
        self.history_bytes = 0;
        if strokes[..keep].iter().any(|s| s.tool.reads_terrain()) {
            let mut rebuilt = EditRaster::new(self.ellipsoid, self.level);
            let kept = KeptBelow::new(below);
            for (index, stroke) in strokes[..keep].iter().enumerate() {
                rebuilt.apply(index, stroke, &|q| kept.get(q))?;
            }
            rebuilt.clear_history();
            rebuilt.succeed(self);
            *self = rebuilt;
            return Ok(());
        }
        let strokes = &strokes[..top];
        let mut touched = BTreeSet::new();
        for (index, stroke) in strokes.iter().enumerate().skip(keep) {
            touched.extend(self.footprint(index, stroke)?.1);
        }
        let kept: Vec<(Vec<glam::DVec3>, BTreeSet<QuadId>)> = strokes[..keep]
            .iter()
            .enumerate()
            .map(|(index, stroke)| {
                self.footprint(index, stroke).map(|(d, q)| (d.iter().map(|d| d.centre).collect(), q))
            })
            .collect::<Result<_, _>>()?;
        let rebuilt: Vec<(QuadId, Option<Vec<f32>>)> = touched
            .par_iter()
            .map(|q| {
                let mut tile: Option<Vec<f32>> = None;
                for (stroke, (centres, quads)) in strokes[..keep].iter().zip(&kept) {
                    if quads.contains(q) {
                        let dabs: Vec<Dab> = centres.iter().map(|&centre| Dab::new(&self.ellipsoid, centre)).collect();
                        let t = tile.get_or_insert_with(|| vec![0.0; N * N]);
                        apply_to_tile(&self.ellipsoid, *q, t, stroke, &dabs, Target::None, None);
                    }
                }
                (*q, tile)
            })
            .collect();
        self.put(rebuilt);
        Ok(())
    }

    /// Makes this raster's stamps follow `old`'s (the raster it replaces on a layer): every
    /// quad's stamp differs from any `old` gave, so that nothing composed from `old` is taken for
    /// this raster's.
    pub fn succeed(&mut self, old: &EditRaster) {
        let base = old.generation.wrapping_add(1);
        self.generation = self.generation.wrapping_add(base);
        self.floor = self.floor.wrapping_add(base);
        for s in self.stamps.values_mut() {
            *s = s.wrapping_add(base);
        }
        self.pyramid.shift_stamps(base);
    }

    /// A number that changes whenever δ at `quad` (of any level) may have: what renderers key
    /// the composed quad and its uploaded deltas by, so that a stroke recomposes only the quads
    /// it changed.
    pub fn stamp(&self, quad: QuadId) -> u32 {
        if quad.level >= self.level {
            return self.stamps.get(&quad.ancestor_at(self.level)).copied().unwrap_or(self.floor);
        }
        self.pyramid.stamp(quad).unwrap_or(self.floor)
    }

    /// Puts tiles in place (None: removes the quad's) and forgets the coarse means they change.
    fn put(&mut self, changes: Vec<(QuadId, Option<Vec<f32>>)>) {
        self.generation = self.generation.wrapping_add(1);
        let changed: BTreeSet<QuadId> = changes.iter().map(|(q, _)| *q).collect();
        for q in &changed {
            self.stamps.insert(*q, self.generation);
        }
        let mut removed = false;
        for (q, tile) in changes {
            match tile {
                Some(t) => {
                    self.tiles.insert(q, t);
                }
                None => removed |= self.tiles.remove(&q).is_some(),
            }
        }
        if removed {
            self.pyramid.reset(self.tiles.keys().copied(), self.generation);
        } else {
            self.pyramid.add(changed.iter().copied());
            self.pyramid.invalidate(&changed, self.generation);
        }
    }

    /// Forgets the undo history (undo then recomputes: for tests and benchmarks of that path).
    pub fn clear_history(&mut self) {
        self.history.clear();
        self.history_bytes = 0;
    }

    /// A stroke's dabs and the quads of the raster's level within reach of one of them.
    fn footprint(&self, index: usize, stroke: &Stroke) -> Result<(Vec<Dab>, BTreeSet<QuadId>), StrokeError> {
        let err = |field: &str, problem: String| StrokeError { index, field: field.into(), problem, cause: None };
        stroke.check(self.ellipsoid.a_m()).map_err(|e| err(&e.field, e.problem))?;
        if stroke.level > self.level {
            return Err(err("level", format!("{} is finer than the raster's level {}", stroke.level, self.level)));
        }
        let centres = dab_centres(&self.ellipsoid, stroke).map_err(|p| err("path", p.0))?;
        let dabs: Vec<Dab> = centres.into_iter().map(|centre| Dab::new(&self.ellipsoid, centre)).collect();
        let quads = self.within(&dabs, stroke.radius_m);
        Ok((dabs, quads))
    }

    /// The quads of the raster's level within `radius_m` of a dab.
    fn within(&self, dabs: &[Dab], radius_m: f64) -> BTreeSet<QuadId> {
        let mut quads = BTreeSet::new();
        let all: Vec<usize> = (0..dabs.len()).collect();
        for face in Face::ALL {
            self.reach(QuadId::root(face), dabs, &all, radius_m, &mut quads);
        }
        quads
    }

    /// A terrain-reading stroke's target and the snapshot of H over every quad it reads (its
    /// dabs' discs, widened by the smoothing ring, and the quads under its target's points);
    /// `(Target::None, None)` for the other tools.
    fn read_terrain(
        &self,
        index: usize,
        stroke: &Stroke,
        dabs: &[Dab],
        below: &Below,
    ) -> Result<(Target, Option<Snapshot>), StrokeError> {
        if !stroke.tool.reads_terrain() {
            return Ok((Target::None, None));
        }
        let ring =
            if stroke.tool == super::Tool::Smooth { smooth_ring_m(&self.ellipsoid, stroke, self.level) } else { 0.0 };
        let mut quads = self.within(dabs, stroke.radius_m + ring);
        let points: Vec<Dab> =
            Target::points(&self.ellipsoid, stroke).into_iter().map(|p| Dab::new(&self.ellipsoid, p)).collect();
        // A target point's quad and, when it lies on a quad's edge, its neighbour's (1 m reach).
        quads.extend(self.within(&points, 1.0));
        let delta = |q: QuadId| self.tiles.get(&q).cloned();
        let snapshot = Snapshot::take(self.ellipsoid, self.level, &quads, &delta, below).map_err(|e| StrokeError {
            index,
            field: "terrain below".into(),
            problem: "cannot be read".into(),
            cause: Some(e.into()),
        })?;
        Ok((Target::of(&self.ellipsoid, stroke, self.level, Some(&snapshot)), Some(snapshot)))
    }

    /// Descends from `quad` to the raster's level through the quads whose ball meets a dab's disc.
    fn reach(&self, quad: QuadId, dabs: &[Dab], near: &[usize], radius_m: f64, out: &mut BTreeSet<QuadId>) {
        let (centre, _, r) = quad_ball(&self.ellipsoid, quad);
        let near: Vec<usize> =
            near.iter().copied().filter(|&k| (dabs[k].centre - centre).length() <= r + radius_m).collect();
        if near.is_empty() {
            return;
        }
        if quad.level >= self.level {
            out.insert(quad);
            return;
        }
        for child in quad.children().into_iter().flatten() {
            self.reach(child, dabs, &near, radius_m, out);
        }
    }

    /// δ at a quad of the raster's level (None: no stroke touched it, δ = 0).
    pub fn tile(&self, quad: QuadId) -> Option<&[f32]> {
        self.tiles.get(&quad).map(Vec::as_slice)
    }

    /// Whether δ may be non-zero somewhere in `quad` (of any level).
    pub fn covers(&self, quad: QuadId) -> bool {
        if quad.level >= self.level {
            return self.tiles.contains_key(&quad.ancestor_at(self.level));
        }
        self.pyramid.near(quad)
    }

    /// δ at the 257² samples of any quad: the raster's own tile at its level, bilinear from the
    /// ancestor's below it, and above it the area means of the level below, level by level (see
    /// [`super::pyramid`]). None where no stroke reached.
    pub fn grid(&self, quad: QuadId) -> Option<Vec<f32>> {
        if !self.covers(quad) {
            return None;
        }
        if quad.level >= self.level {
            let a = quad.ancestor_at(self.level);
            let tile = self.tiles.get(&a)?;
            return Some(if a == quad { tile.clone() } else { crate::ecm::grid::upsample(tile, a, quad) });
        }
        let mean = self.pyramid.mean(quad, self.level, &|q| self.tiles.get(&q).map(Vec::as_slice))?;
        Some(mean.to_vec())
    }

    /// Makes every coarse tile now, so that the thread that draws the raster later only reads
    /// them (a raster built on a worker thread, warmed there).
    pub fn warm(&self) {
        for quad in self.pyramid.coarse_quads() {
            let _ = self.pyramid.mean(quad, self.level, &|q| self.tiles.get(&q).map(Vec::as_slice));
        }
    }

    /// The smallest and largest δ over the tiles, metres ((0, 0) without tiles).
    pub fn range_m(&self) -> (f64, f64) {
        let mut range = (0f64, 0f64);
        for v in self.tiles.values().flatten() {
            range = (range.0.min(f64::from(*v)), range.1.max(f64::from(*v)));
        }
        range
    }
}
