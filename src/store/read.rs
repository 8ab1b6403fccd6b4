//! Reading a dataset back: a quad's 257² grid (what the renderer draws from), grids with borders
//! from the neighbours (across face edges), single samples, and bilinear heights at any point.

use std::collections::HashMap;
use std::sync::Arc;

use super::StoreError;
use super::gpkg::Store;
use super::tile::QuadGrid;
use crate::ecm::grid::{self, GRID, fold_sample, quad_of_sample};
use crate::ecm::{CubeProjection, Face, QuadId};

/// Reads one dataset of a store, keeping recently used grids (at most `capacity`).
pub struct GridReader {
    store: Store,
    dataset: String,
    finest_level: u8,
    cache: HashMap<QuadId, Option<Arc<QuadGrid>>>,
    capacity: usize,
}

impl GridReader {
    /// A reader of a store's dataset (the only one when `dataset` is empty and there is one).
    pub fn new(store: Store, dataset: &str) -> Result<GridReader, StoreError> {
        let record = store.resolve_dataset((!dataset.is_empty()).then_some(dataset))?;
        Ok(GridReader {
            finest_level: record.settings.finest_level,
            dataset: record.name,
            store,
            cache: HashMap::new(),
            capacity: 256,
        })
    }

    /// The store.
    pub fn store(&self) -> &Store {
        &self.store
    }

    /// The dataset's name.
    pub fn dataset(&self) -> &str {
        &self.dataset
    }

    /// The finest level the dataset has.
    pub fn finest_level(&self) -> u8 {
        self.finest_level
    }

    /// A quad's 257² grid (`sample_xy(257, i, j)` order, NaN no data), or `None` where the dataset
    /// has no tile.
    pub fn grid(&mut self, quad: QuadId) -> Result<Option<Arc<QuadGrid>>, StoreError> {
        if let Some(g) = self.cache.get(&quad) {
            return Ok(g.clone());
        }
        if self.cache.len() >= self.capacity {
            self.cache.clear();
        }
        let g = self.store.read_grid(&self.dataset, quad)?.map(Arc::new);
        self.cache.insert(quad, g.clone());
        Ok(g)
    }

    /// Global sample (i, j) of a face at a level; indices off the face are folded onto the
    /// adjacent face. NaN where there is no data or no such point (beyond a cube corner).
    pub fn sample(&mut self, face: Face, level: u8, i: i64, j: i64) -> Result<f32, StoreError> {
        let Some((f, i, j)) = fold_sample(face, level, i, j) else { return Ok(f32::NAN) };
        let (quad, li, lj) = quad_of_sample(f, level, i, j);
        Ok(self.grid(quad)?.map_or(f32::NAN, |g| g.get(li, lj)))
    }

    /// A quad's grid with `border` extra samples on every side from its neighbours (across face
    /// edges too): (257 + 2·border)² values, row by row from the south; `None` where the quad
    /// itself has no tile.
    pub fn grid_with_border(&mut self, quad: QuadId, border: u32) -> Result<Option<Vec<f32>>, StoreError> {
        let Some(own) = self.grid(quad)? else { return Ok(None) };
        let n = (GRID + 2 * border) as usize;
        let (i0, j0) = (i64::from(quad.x) * 256 - i64::from(border), i64::from(quad.y) * 256 - i64::from(border));
        let mut out = vec![f32::NAN; n * n];
        for b in 0..n {
            for a in 0..n {
                let (li, lj) = (a as i64 - i64::from(border), b as i64 - i64::from(border));
                out[b * n + a] = if (0..GRID as i64).contains(&li) && (0..GRID as i64).contains(&lj) {
                    own.get(li as u32, lj as u32)
                } else {
                    self.sample(quad.face, quad.level, i0 + a as i64, j0 + b as i64)?
                };
            }
        }
        Ok(Some(out))
    }

    /// Bilinear height at a geodetic point (radians) from a level's samples; NaN where one of
    /// the four samples around it has no data.
    pub fn height_at(&mut self, lat_rad: f64, lon_rad: f64, level: u8) -> Result<f64, StoreError> {
        let p = CubeProjection::Qsc.face_point_from_geodetic(self.store.body(), lat_rad, lon_rad);
        let m = grid::intervals_per_face_edge(level);
        let (u, v) = ((p.x + 1.0) * 0.5 * m as f64, (p.y + 1.0) * 0.5 * m as f64);
        let (i, j) = ((u.floor() as i64).clamp(0, m - 1), (v.floor() as i64).clamp(0, m - 1));
        let (tx, ty) = (u - i as f64, v - j as f64);
        let mut h = 0.0;
        for (di, dj, w) in
            [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
        {
            if w > 0.0 {
                h += w * f64::from(self.sample(p.face, level, i + di, j + dj)?);
            }
        }
        Ok(h)
    }
}
