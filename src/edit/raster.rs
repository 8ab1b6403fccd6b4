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
//! Undo recomputes only the quads the undone strokes touched, from the strokes before them.

use std::collections::{BTreeMap, BTreeSet};

use glam::DVec3;
use rayon::prelude::*;

use super::dabs::dab_centres;
use super::stroke::{Stroke, Tool};
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;
use crate::layers::noise;
use crate::layers::stack::{quad_ball, sample_point};
use crate::store::grid::GRID;

const N: usize = GRID as usize;

/// A stroke that cannot be rasterised: its index, the field and the problem.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("strokes[{index}]: {field}: {problem}")]
pub struct StrokeError {
    /// The stroke's index in the layer.
    pub index: usize,
    /// The field.
    pub field: String,
    /// What is wrong.
    pub problem: String,
}

/// One dab, ready to apply.
#[derive(Clone, Copy, Debug)]
struct Dab {
    centre: DVec3,
}

/// The raster.
#[derive(Clone, Debug, PartialEq)]
pub struct EditRaster {
    /// The body.
    pub ellipsoid: Ellipsoid,
    /// The level of the tiles.
    pub level: u8,
    /// δ per touched quad, 257² row by row from the south, metres.
    pub tiles: BTreeMap<QuadId, Vec<f32>>,
}

impl EditRaster {
    /// An empty raster at `level`.
    pub fn new(ellipsoid: Ellipsoid, level: u8) -> EditRaster {
        EditRaster { ellipsoid, level, tiles: BTreeMap::new() }
    }

    /// The raster of `strokes`, at the finest of their levels (each checked; the tools that read
    /// the terrain below are refused until they are rasterised).
    pub fn build(ellipsoid: Ellipsoid, strokes: &[Stroke]) -> Result<EditRaster, StrokeError> {
        // Every stroke checked before any is rasterised (a bad level must not set the raster's).
        for (index, stroke) in strokes.iter().enumerate() {
            stroke.check(ellipsoid.a_m()).map_err(|(f, p)| StrokeError { index, field: f.into(), problem: p })?;
        }
        let level = strokes.iter().map(|s| s.level).max().unwrap_or(0);
        let mut raster = EditRaster::new(ellipsoid, level);
        for (index, stroke) in strokes.iter().enumerate() {
            raster.apply(index, stroke)?;
        }
        Ok(raster)
    }

    /// Applies one stroke (`index` names it in errors); returns the quads it touched.
    pub fn apply(&mut self, index: usize, stroke: &Stroke) -> Result<BTreeSet<QuadId>, StrokeError> {
        let (dabs, quads) = self.footprint(index, stroke)?;
        let tiles: Vec<(QuadId, Vec<f32>)> = quads
            .par_iter()
            .map(|q| {
                let mut tile = self.tiles.get(q).cloned().unwrap_or_else(|| vec![0.0; N * N]);
                apply_to_tile(&self.ellipsoid, *q, &mut tile, stroke, &dabs);
                (*q, tile)
            })
            .collect();
        self.tiles.extend(tiles);
        Ok(quads)
    }

    /// Undoes back to `strokes[..keep]` after `strokes[keep..]` were applied: the quads those
    /// touched are recomputed from the kept strokes; every other tile stays as it is.
    pub fn undo_to(&mut self, strokes: &[Stroke], keep: usize) -> Result<(), StrokeError> {
        let mut touched = BTreeSet::new();
        for (index, stroke) in strokes.iter().enumerate().skip(keep) {
            touched.extend(self.footprint(index, stroke)?.1);
        }
        let kept: Vec<(Vec<DVec3>, BTreeSet<QuadId>)> = strokes[..keep]
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
                        let dabs: Vec<Dab> = centres.iter().map(|&centre| Dab { centre }).collect();
                        let t = tile.get_or_insert_with(|| vec![0.0; N * N]);
                        apply_to_tile(&self.ellipsoid, *q, t, stroke, &dabs);
                    }
                }
                (*q, tile)
            })
            .collect();
        for (q, tile) in rebuilt {
            match tile {
                Some(t) => self.tiles.insert(q, t),
                None => self.tiles.remove(&q),
            };
        }
        Ok(())
    }

    /// A stroke's dabs and the quads of the raster's level within reach of one of them.
    fn footprint(&self, index: usize, stroke: &Stroke) -> Result<(Vec<Dab>, BTreeSet<QuadId>), StrokeError> {
        let err = |field: &str, problem: String| StrokeError { index, field: field.into(), problem };
        stroke.check(self.ellipsoid.a_m()).map_err(|(f, p)| err(f, p))?;
        if stroke.tool.reads_terrain() {
            return Err(err(
                "tool",
                format!(
                    "{} reads the terrain below the edit layer and is not rasterised yet (issue #14)",
                    stroke.tool.name()
                ),
            ));
        }
        if stroke.level > self.level {
            return Err(err("level", format!("{} is finer than the raster's level {}", stroke.level, self.level)));
        }
        let centres = dab_centres(&self.ellipsoid, stroke).map_err(|p| err("path", p))?;
        let dabs: Vec<Dab> = centres.into_iter().map(|centre| Dab { centre }).collect();
        let mut quads = BTreeSet::new();
        let all: Vec<usize> = (0..dabs.len()).collect();
        for face in Face::ALL {
            self.reach(QuadId::root(face), &dabs, &all, stroke.radius_m, &mut quads);
        }
        Ok((dabs, quads))
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
}

/// Folds one stroke's dabs, in order, into a tile: each sample in f64 from its stored f32 value,
/// rounded to f32 once at the end.
fn apply_to_tile(ellipsoid: &Ellipsoid, quad: QuadId, tile: &mut [f32], stroke: &Stroke, dabs: &[Dab]) {
    let r = stroke.radius_m;
    let wavelength = r / 2.0;
    for (k, value) in tile.iter_mut().enumerate() {
        let (p, _, _) = sample_point(ellipsoid, quad, GRID, (k % N) as u32, (k / N) as u32);
        let mut delta = f64::from(*value);
        let mut touched = false;
        for dab in dabs {
            let d = (p - dab.centre).length();
            if d >= r {
                continue;
            }
            touched = true;
            let w = stroke.falloff.weight(d / r);
            delta = match stroke.tool {
                Tool::Raise => delta + stroke.strength * w,
                Tool::Lower => delta - stroke.strength * w,
                Tool::Noise => delta + stroke.strength * w * noise::octave_at(p, wavelength, stroke.seed),
                Tool::Restore => delta * (1.0 - stroke.strength * w),
                Tool::Smooth | Tool::Flatten | Tool::Ramp => delta,
            };
        }
        if touched {
            *value = delta as f32;
        }
    }
}
