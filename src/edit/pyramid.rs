//! The edit raster's coarser levels, so that an edit shows from far away: each sample the area
//! mean of its cell on the level below, with the store's stencil (`ecm::area_mean`,
//! weights ¼ ½ ¼ per axis, across quad and face edges), down from the raster's level one level at
//! a time. A coarse tile is computed when first asked for and kept until a stroke changes a quad
//! it reads; each is a pure function of the raster's tiles, so it is the same whichever order
//! tiles are asked for in.

use std::collections::{BTreeSet, HashMap, HashSet};
use std::sync::{Arc, Mutex};

use crate::ecm::QuadId;
use crate::ecm::area_mean::{AREA_MEAN_SPAN, area_mean, fill_area_mean_region};
use crate::ecm::grid::{GRID, TILE, fold_sample, quad_of_sample};

/// The coarse tiles made so far and the quads above the raster's tiles.
#[derive(Default)]
pub struct Pyramid {
    made: Mutex<HashMap<QuadId, Arc<Vec<f32>>>>,
    /// Every strict ancestor of a raster tile.
    above: HashSet<QuadId>,
    /// Per coarse quad, the raster's generation that last changed what it reads.
    stamps: HashMap<QuadId, u32>,
    /// The stamp of coarse quads not changed since the last reset (None: the raster's floor).
    floor: Option<u32>,
}

impl Clone for Pyramid {
    fn clone(&self) -> Pyramid {
        Pyramid {
            made: Mutex::new(self.made.lock().expect("not poisoned").clone()),
            above: self.above.clone(),
            stamps: self.stamps.clone(),
            floor: self.floor,
        }
    }
}

/// The quad and its eight neighbours at its level (across face edges; fewer at a cube corner).
pub fn with_neighbours(quad: QuadId) -> Vec<QuadId> {
    let (ci, cj) = (i64::from(quad.x) * i64::from(TILE) + 128, i64::from(quad.y) * i64::from(TILE) + 128);
    let mut out = Vec::with_capacity(9);
    for dj in -1..=1i64 {
        for di in -1..=1i64 {
            if let Some((f, i, j)) = fold_sample(quad.face, quad.level, ci + 256 * di, cj + 256 * dj) {
                let q = quad_of_sample(f, quad.level, i, j).0;
                if !out.contains(&q) {
                    out.push(q);
                }
            }
        }
    }
    out
}

impl Pyramid {
    /// Records raster tiles (new ones: their ancestors are above a tile from now on).
    pub fn add(&mut self, tiles: impl IntoIterator<Item = QuadId>) {
        for t in tiles {
            for p in t.ancestors() {
                if !self.above.insert(p) {
                    break;
                }
            }
        }
    }

    /// Starts over from these raster tiles (after tiles were removed at generation `stamp`:
    /// every coarse quad's stamp becomes it).
    pub fn reset(&mut self, tiles: impl IntoIterator<Item = QuadId>, stamp: u32) {
        *self = Pyramid { floor: Some(stamp), ..Pyramid::default() };
        self.add(tiles);
    }

    /// A coarse quad's stamp (None: the raster's floor).
    pub fn stamp(&self, quad: QuadId) -> Option<u32> {
        self.stamps.get(&quad).copied().or(self.floor)
    }

    /// Adds `base` to every stamp (see `EditRaster::succeed`).
    pub fn shift_stamps(&mut self, base: u32) {
        for s in self.stamps.values_mut() {
            *s = s.wrapping_add(base);
        }
        self.floor = self.floor.map(|f| f.wrapping_add(base));
    }

    /// Forgets the coarse tiles that read any of `changed` (raster tiles), level by level (a
    /// coarse quad reads its children and one sample of their neighbours), and stamps them with
    /// the generation that changed them.
    pub fn invalidate(&mut self, changed: &BTreeSet<QuadId>, stamp: u32) {
        let made = self.made.get_mut().expect("not poisoned");
        let mut dirty: BTreeSet<QuadId> = changed.clone();
        while !dirty.is_empty() {
            let mut up = BTreeSet::new();
            for q in &dirty {
                for n in with_neighbours(*q) {
                    if let Some(p) = n.parent() {
                        up.insert(p);
                    }
                }
            }
            for p in &up {
                made.remove(p);
                self.stamps.insert(*p, stamp);
            }
            dirty = up;
        }
    }

    /// Every coarse quad that may have a non-zero mean: the strict ancestors of raster tiles and
    /// their neighbours.
    pub fn coarse_quads(&self) -> BTreeSet<QuadId> {
        self.above.iter().flat_map(|q| with_neighbours(*q)).collect()
    }

    /// Whether a quad coarser than the raster may have a non-zero mean: a raster tile lies under
    /// it or under one of its neighbours.
    pub fn near(&self, quad: QuadId) -> bool {
        with_neighbours(quad).iter().any(|q| self.above.contains(q))
    }

    /// The area means at a quad coarser than the raster's `level` (None: all zero); `tile(q)`
    /// gives the raster's tiles.
    pub fn mean<'a>(
        &self,
        quad: QuadId,
        level: u8,
        tile: &dyn Fn(QuadId) -> Option<&'a [f32]>,
    ) -> Option<Arc<Vec<f32>>> {
        if quad.level >= level || !self.near(quad) {
            return None;
        }
        if let Some(t) = self.made.lock().expect("not poisoned").get(&quad) {
            return Some(t.clone());
        }
        // The children's level: the raster's tiles, or means read through this same function
        // (kept as they are made).
        enum Child<'a> {
            Raster(&'a [f32]),
            Mean(Arc<Vec<f32>>),
        }
        // The region's samples come row by row from a few child quads (at most the quad's four
        // children and a ring of their neighbours): a short list searched from the last one
        // found, not a hash per sample (which made a coarse tile take seconds).
        let mut children: Vec<(QuadId, Option<Child<'a>>)> = Vec::with_capacity(16);
        let mut last = 0usize;
        let mut region = vec![0f32; AREA_MEAN_SPAN * AREA_MEAN_SPAN];
        fill_area_mean_region(quad, &mut region, &mut |face, child_level, i, j| {
            let Some((f, i, j)) = fold_sample(face, child_level, i, j) else { return f32::NAN };
            let (q, li, lj) = quad_of_sample(f, child_level, i, j);
            if children.get(last).is_none_or(|c| c.0 != q) {
                last = match children.iter().position(|c| c.0 == q) {
                    Some(k) => k,
                    None => {
                        let child = if child_level == level {
                            tile(q).map(Child::Raster)
                        } else {
                            self.mean(q, level, tile).map(Child::Mean)
                        };
                        children.push((q, child));
                        children.len() - 1
                    }
                };
            }
            let k = lj as usize * GRID as usize + li as usize;
            match &children[last].1 {
                Some(Child::Raster(t)) => t[k],
                Some(Child::Mean(t)) => t[k],
                None => 0.0,
            }
        });
        let values: Vec<f32> = area_mean(quad, &region).into_iter().map(|v| if v.is_nan() { 0.0 } else { v }).collect();
        let values = Arc::new(values);
        self.made.lock().expect("not poisoned").insert(quad, values.clone());
        Some(values)
    }
}
