//! Terrain data for the renderer: which quads have data (known up front from the stores), the
//! asynchronous loader (worker threads that fetch raw source tiles per dataset and quad from the
//! stores, upsampled from an ancestor below a dataset's finest level, and compute static maps),
//! and the bounded CPU cache (least recently used, byte budget) the loader fills. The loader
//! composes nothing: composition is the GPU's (`compose`).
//!
//! Nothing here blocks a frame: the renderer asks for what it wants, takes whatever has arrived
//! since the last frame, and draws what it has.

use std::collections::{HashMap, HashSet, VecDeque};
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};

use super::dataset::DatasetInfo;
use crate::ecm::geometry::{MapCache, StaticMaps};
use crate::ecm::grid::{GRID, upsample};
use crate::ecm::{CubeProjection, QuadId};
use crate::geodesy::Ellipsoid;
use crate::store::{Store, StoreError};

/// Samples along a quad edge, in the store and on the GPU.
pub const SAMPLES: u32 = GRID;

/// One dataset's raw heights at one quad (a source tile), with what bounds need.
#[derive(Debug)]
pub struct QuadHeights {
    /// 257² heights, row by row from the south, NaN where the dataset has no data.
    pub grid: Vec<f32>,
    /// Lowest and highest height with data, metres.
    pub range_m: (f32, f32),
    /// Largest difference between neighbouring samples along the quad's edges, metres: how far
    /// a coarser neighbour's edge can stray from this one's (sizes the skirt).
    pub edge_roughness_m: f32,
    /// The height ranges of its 8 × 8-cell blocks (patch bounds read them).
    pub blocks: std::sync::Arc<super::block_ranges::BlockRanges>,
}

impl QuadHeights {
    /// Heights from a composed grid.
    pub fn new(grid: Vec<f32>) -> QuadHeights {
        let n = SAMPLES as usize;
        let (mut lo, mut hi) = (f32::INFINITY, f32::NEG_INFINITY);
        for &h in grid.iter().filter(|h| !h.is_nan()) {
            lo = lo.min(h);
            hi = hi.max(h);
        }
        // The four edges: south and north rows, west and east columns.
        let mut rough = 0f32;
        for (start, step) in [(0, 1), ((n - 1) * n, 1), (0, n), (n - 1, n)] {
            for k in 1..n {
                let d = (grid[start + k * step] - grid[start + (k - 1) * step]).abs();
                if d.is_finite() {
                    rough = rough.max(d);
                }
            }
        }
        if lo > hi {
            (lo, hi) = (0.0, 0.0);
        }
        let blocks = std::sync::Arc::new(super::block_ranges::BlockRanges::new(&grid));
        QuadHeights { grid, range_m: (lo, hi), edge_roughness_m: rough, blocks }
    }

    fn bytes(&self) -> usize {
        self.grid.len() * 4
    }
}

/// What the loader is asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum DataKey {
    /// A dataset's raw heights at a quad (the dataset's index in the scene).
    Source(u32, QuadId),
    /// A dataset's distances to its no-data edge at a quad, metres, for feathers of one edge
    /// level (`layers::edge`): the dataset, the quad, the edge level.
    Edge(u32, QuadId, u8),
    /// The static maps of a canonical quad.
    Maps(QuadId),
    /// An edit layer's deltas at a quad: the layer's uid (low 32 bits), the quad, the raster's
    /// generation (a tile of an older raster is another key). Made by the scene, not loaded.
    Edit(u32, QuadId, u32),
}

impl std::fmt::Display for DataKey {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            DataKey::Source(_, q) => write!(f, "quad {q}"),
            DataKey::Edge(_, q, level) => write!(f, "no-data edge distances at quad {q} (edge level {level})"),
            DataKey::Maps(q) => write!(f, "static maps of quad {q}"),
            DataKey::Edit(_, q, _) => write!(f, "edit deltas at quad {q}"),
        }
    }
}

impl DataKey {
    /// The dataset a source or edge tile belongs to.
    pub fn dataset(self) -> Option<u32> {
        match self {
            DataKey::Source(d, _) | DataKey::Edge(d, _, _) => Some(d),
            DataKey::Maps(_) | DataKey::Edit(..) => None,
        }
    }
}

/// A tile the loader could not give.
#[derive(Debug, thiserror::Error)]
pub enum LoadError {
    /// The store could not be read.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A key whose data are made by the scene, not read from a store (static maps, edit deltas).
    #[error("{0} is made by the scene, not read from a store")]
    NotStored(DataKey),
}

/// What the loader sends back.
pub enum Loaded {
    /// A source or edge tile (or a read error, named).
    Tile(DataKey, Result<Arc<QuadHeights>, LoadError>),
    /// Static maps.
    Maps(QuadId, Arc<StaticMaps>),
}

struct Queue {
    pending: VecDeque<DataKey>,
    in_flight: HashSet<DataKey>,
    stop: bool,
}

/// Worker threads reading heights and computing maps, most wanted first.
pub struct Loader {
    queue: Arc<(Mutex<Queue>, Condvar)>,
    results: Receiver<Loaded>,
    workers: Vec<std::thread::JoinHandle<()>>,
}

/// Most requests kept waiting; older wishes are dropped when a frame asks for new ones.
const MAX_PENDING: usize = 256;

impl Loader {
    /// Starts `threads` workers over the datasets.
    pub fn start(datasets: Arc<Vec<DatasetInfo>>, ellipsoid: Ellipsoid, threads: usize) -> Loader {
        let queue = Arc::new((
            Mutex::new(Queue { pending: VecDeque::new(), in_flight: HashSet::new(), stop: false }),
            Condvar::new(),
        ));
        let (tx, rx) = std::sync::mpsc::channel();
        let maps = Arc::new(MapCache::new());
        let fields = Arc::new(EdgeFields::default());
        let workers = (0..threads.max(1))
            .map(|k| {
                let (queue, tx, datasets, maps) = (queue.clone(), tx.clone(), datasets.clone(), maps.clone());
                let fields = fields.clone();
                std::thread::Builder::new()
                    .name(format!("terrafuse-loader-{k}"))
                    .spawn(move || worker(&queue, &tx, &datasets, &ellipsoid, &maps, &fields))
                    .expect("spawning a loader thread")
            })
            .collect();
        Loader { queue, results: rx, workers }
    }

    /// Replaces the waiting requests with `keys` (most wanted first); keys already being loaded
    /// are not asked twice.
    pub fn request(&self, keys: &[DataKey]) {
        let (lock, cv) = &*self.queue;
        let mut q = lock.lock().unwrap_or_else(|p| p.into_inner());
        q.pending.clear();
        for key in keys.iter().take(MAX_PENDING) {
            if !q.in_flight.contains(key) && !q.pending.contains(key) {
                q.pending.push_back(*key);
            }
        }
        cv.notify_all();
    }

    /// Whatever has arrived.
    pub fn drain(&self) -> Vec<Loaded> {
        self.results.try_iter().collect()
    }

    /// Waits up to `timeout` for one result (the command line uses it; a frame never does).
    pub fn wait(&self, timeout: std::time::Duration) -> Option<Loaded> {
        self.results.recv_timeout(timeout).ok()
    }

    /// Requests waiting or being worked on.
    pub fn busy(&self) -> usize {
        let q = self.queue.0.lock().unwrap_or_else(|p| p.into_inner());
        q.pending.len() + q.in_flight.len()
    }
}

impl Drop for Loader {
    fn drop(&mut self) {
        let (lock, cv) = &*self.queue;
        lock.lock().unwrap_or_else(|p| p.into_inner()).stop = true;
        cv.notify_all();
        for w in self.workers.drain(..) {
            let _ = w.join();
        }
    }
}

fn worker(
    queue: &(Mutex<Queue>, Condvar),
    tx: &Sender<Loaded>,
    datasets: &[DatasetInfo],
    ellipsoid: &Ellipsoid,
    maps: &MapCache,
    fields: &EdgeFields,
) {
    // Each worker has its own connections (SQLite handles are not shared between threads).
    let mut stores: Vec<Option<Store>> = datasets.iter().map(|_| None).collect();
    loop {
        let key = {
            let (lock, cv) = queue;
            let mut q = lock.lock().unwrap_or_else(|p| p.into_inner());
            loop {
                if q.stop {
                    return;
                }
                if let Some(key) = q.pending.pop_front() {
                    q.in_flight.insert(key);
                    break key;
                }
                q = cv.wait(q).unwrap_or_else(|p| p.into_inner());
            }
        };
        let result = match key {
            DataKey::Maps(quad) => {
                let symmetry = crate::ecm::geometry::MapSymmetry::of(quad);
                Loaded::Maps(quad, maps.get(ellipsoid, CubeProjection::Qsc, symmetry, SAMPLES))
            }
            tile => Loaded::Tile(tile, read_tile(tile, datasets, &mut stores, fields).map(Arc::new)),
        };
        queue.0.lock().unwrap_or_else(|p| p.into_inner()).in_flight.remove(&key);
        if tx.send(result).is_err() {
            return;
        }
    }
}

/// A source or edge tile, read on this thread (`stores` per dataset, opened when first needed).
pub fn read_tile(
    key: DataKey,
    datasets: &[DatasetInfo],
    stores: &mut [Option<Store>],
    fields: &EdgeFields,
) -> Result<QuadHeights, LoadError> {
    match key {
        DataKey::Source(d, quad) => Ok(read_source(quad, &datasets[d as usize], &mut stores[d as usize])?),
        DataKey::Edge(d, quad, level) => {
            Ok(read_edge(quad, level, &datasets[d as usize], &mut stores[d as usize], fields, d)?)
        }
        DataKey::Maps(_) | DataKey::Edit(..) => Err(LoadError::NotStored(key)),
    }
}

/// A dataset's raw heights at `quad`: its tile there, or below its finest level its tile at the
/// finest level upsampled; all no data where it has no tile.
pub fn read_source(quad: QuadId, dataset: &DatasetInfo, store: &mut Option<Store>) -> Result<QuadHeights, StoreError> {
    let n = (SAMPLES * SAMPLES) as usize;
    if !dataset.covers(quad) {
        return Ok(QuadHeights::new(vec![f32::NAN; n]));
    }
    if store.is_none() {
        *store = Some(Store::open_read_only(&dataset.store)?);
    }
    let s = store.as_ref().expect("opened above");
    if dataset.shift_m != [0.0, 0.0] {
        return Ok(QuadHeights::new(super::shifted::shifted_grid(dataset, s, quad)?));
    }
    let source = dataset.source_quad(quad);
    let grid = match s.read_grid(&dataset.dataset, source)? {
        Some(tile) if source == quad => tile.values,
        Some(tile) => upsample(&tile.values, source, quad),
        None => vec![f32::NAN; n],
    };
    Ok(QuadHeights::new(grid))
}

/// Distance fields computed lately, shared by the loader's workers: one field serves every quad
/// below its quad (keyed by dataset, quad and edge level; the oldest dropped past a count).
#[derive(Default)]
pub struct EdgeFields {
    fields: Mutex<VecDeque<(FieldKey, Arc<Vec<f32>>)>>,
}

/// A field's dataset (tag), quad and edge level.
type FieldKey = (u32, QuadId, u8);

/// Fields kept (each 257² f32, 264 kB).
const EDGE_FIELDS_KEPT: usize = 64;

impl EdgeFields {
    fn get(&self, key: FieldKey) -> Option<Arc<Vec<f32>>> {
        let fields = self.fields.lock().unwrap_or_else(|p| p.into_inner());
        fields.iter().find(|(k, _)| *k == key).map(|(_, f)| f.clone())
    }

    fn put(&self, key: FieldKey, field: Arc<Vec<f32>>) {
        let mut fields = self.fields.lock().unwrap_or_else(|p| p.into_inner());
        if fields.len() >= EDGE_FIELDS_KEPT {
            fields.pop_front();
        }
        fields.push_back((key, field));
    }
}

/// A dataset's distances to its own no-data edge at `quad` for feathers of edge level
/// `edge_level` (`layers::edge`): the field of the quad's ancestor at the field level, resampled
/// bilinearly below it. `fields` keeps fields for the next quads (`tag` names the dataset in it).
pub fn read_edge(
    quad: QuadId,
    edge_level: u8,
    dataset: &DatasetInfo,
    store: &mut Option<Store>,
    fields: &EdgeFields,
    tag: u32,
) -> Result<QuadHeights, StoreError> {
    let level = crate::layers::edge::field_level(quad.level, edge_level, dataset.finest_level);
    let at = quad.ancestor_at(level);
    let field = match fields.get((tag, at, edge_level)) {
        Some(f) => f,
        None => {
            if store.is_none() {
                *store = Some(Store::open_read_only(&dataset.store)?);
            }
            let s = store.as_ref().expect("opened above");
            let cap = crate::layers::edge::quad_width_m(dataset.body.a_m(), edge_level);
            let tile = |q: QuadId| -> Result<Option<Arc<Vec<f32>>>, StoreError> {
                if !dataset.has(q) {
                    return Ok(None);
                }
                if dataset.shift_m != [0.0, 0.0] {
                    return Ok(Some(Arc::new(super::shifted::shifted_grid(dataset, s, q)?)));
                }
                Ok(s.read_grid(&dataset.dataset, q)?.map(|t| Arc::new(t.values)))
            };
            let f = Arc::new(crate::layers::edge::distance_field(&dataset.body, at, cap, tile)?);
            fields.put((tag, at, edge_level), f.clone());
            f
        }
    };
    let grid = if at == quad { field.as_ref().clone() } else { upsample(&field, at, quad) };
    Ok(QuadHeights::new(grid))
}

/// The CPU cache: heights and maps by key, least recently used dropped past the budget.
pub struct CpuCache {
    budget_bytes: usize,
    used_bytes: usize,
    clock: u64,
    heights: HashMap<DataKey, (Arc<QuadHeights>, u64)>,
    maps: HashMap<QuadId, (Arc<StaticMaps>, u64)>,
}

impl CpuCache {
    /// An empty cache with a budget.
    pub fn new(budget_bytes: usize) -> CpuCache {
        CpuCache { budget_bytes, used_bytes: 0, clock: 0, heights: HashMap::new(), maps: HashMap::new() }
    }

    /// Bytes held.
    pub fn used_bytes(&self) -> usize {
        self.used_bytes
    }

    /// Entries held.
    pub fn len(&self) -> usize {
        self.heights.len() + self.maps.len()
    }

    /// Whether nothing is held.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Stores a loaded item, dropping the least recently used past the budget.
    pub fn insert(&mut self, loaded: Loaded) {
        self.clock += 1;
        match loaded {
            Loaded::Tile(key, Ok(h)) => {
                self.used_bytes += h.bytes();
                if let Some((old, _)) = self.heights.insert(key, (h, self.clock)) {
                    self.used_bytes -= old.bytes();
                }
            }
            Loaded::Tile(_, Err(_)) => {}
            Loaded::Maps(quad, m) => {
                self.used_bytes += m.size_bytes();
                if let Some((old, _)) = self.maps.insert(quad, (m, self.clock)) {
                    self.used_bytes -= old.size_bytes();
                }
            }
        }
        while self.used_bytes > self.budget_bytes {
            let oldest_h = self.heights.iter().min_by_key(|(_, (_, t))| *t).map(|(k, (_, t))| (*t, *k));
            let oldest_m = self.maps.iter().min_by_key(|(_, (_, t))| *t).map(|(k, (_, t))| (*t, DataKey::Maps(*k)));
            let Some((_, key)) = [oldest_h, oldest_m].into_iter().flatten().min_by_key(|(t, _)| *t) else { break };
            match key {
                DataKey::Maps(q) => self.used_bytes -= self.maps.remove(&q).map_or(0, |(m, _)| m.size_bytes()),
                tile => self.used_bytes -= self.heights.remove(&tile).map_or(0, |(h, _)| h.bytes()),
            }
        }
    }

    /// Whether the cache holds `key` (without marking it used).
    pub fn contains(&self, key: DataKey) -> bool {
        match key {
            DataKey::Maps(q) => self.maps.contains_key(&q),
            tile => self.heights.contains_key(&tile),
        }
    }

    /// A source or edge tile, marking it used.
    pub fn tile(&mut self, key: DataKey) -> Option<Arc<QuadHeights>> {
        self.clock += 1;
        let clock = self.clock;
        self.heights.get_mut(&key).map(|(h, t)| {
            *t = clock;
            h.clone()
        })
    }

    /// Maps of a canonical quad, marking them used.
    pub fn maps(&mut self, quad: QuadId) -> Option<Arc<StaticMaps>> {
        self.clock += 1;
        let clock = self.clock;
        self.maps.get_mut(&quad).map(|(m, t)| {
            *t = clock;
            m.clone()
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;

    fn heights(v: f32) -> Arc<QuadHeights> {
        Arc::new(QuadHeights::new(vec![v; (SAMPLES * SAMPLES) as usize]))
    }

    #[test]
    fn the_cpu_cache_stays_within_its_budget_and_drops_the_least_recently_used() {
        let one = (SAMPLES * SAMPLES * 4) as usize;
        let mut cache = CpuCache::new(3 * one);
        let q = |x| QuadId { face: Face::Front, level: 3, x, y: 0 };
        for x in 0..3 {
            cache.insert(Loaded::Tile(DataKey::Source(0, q(x)), Ok(heights(x as f32))));
        }
        assert_eq!(cache.used_bytes(), 3 * one);
        assert!(cache.tile(DataKey::Source(0, q(0))).is_some()); // 0 is now the most recently used
        cache.insert(Loaded::Tile(DataKey::Source(0, q(3)), Ok(heights(3.0))));
        assert_eq!(cache.len(), 3);
        assert!(cache.used_bytes() <= 3 * one);
        assert!(cache.tile(DataKey::Source(0, q(1))).is_none(), "1 was the least recently used");
        assert!(cache.tile(DataKey::Source(0, q(0))).is_some() && cache.tile(DataKey::Source(0, q(3))).is_some());
    }

    #[test]
    fn upsampling_from_an_ancestor_is_bilinear_and_exact_on_shared_samples() {
        let n = SAMPLES as usize;
        // A plane h = 3i + 5j on the ancestor: bilinear interpolation reproduces it exactly.
        let grid: Vec<f32> = (0..n * n).map(|k| (3 * (k % n) + 5 * (k / n)) as f32).collect();
        let source = QuadId { face: Face::Top, level: 2, x: 1, y: 3 };
        let quad = QuadId { face: Face::Top, level: 4, x: 7, y: 14 }; // offset (3, 2) inside the ancestor
        let up = upsample(&grid, source, quad);
        for (i, j) in [(0usize, 0usize), (256, 0), (0, 256), (256, 256), (100, 37)] {
            let (u, v) = ((3.0 * 256.0 + i as f64) / 4.0, (2.0 * 256.0 + j as f64) / 4.0);
            assert_eq!(f64::from(up[j * n + i]), 3.0 * u + 5.0 * v, "({i},{j})");
        }
        let mut holes = grid.clone();
        holes[128 * n + 192] = f32::NAN; // under the quad's sample (0, 0)
        let up = upsample(&holes, source, quad);
        assert!(up[0].is_nan(), "a sample next to no data has none");
        assert!(!up[n * n - 1].is_nan());
    }

    #[test]
    fn heights_know_their_range_and_edge_roughness() {
        let n = SAMPLES as usize;
        let mut grid = vec![100.0f32; n * n];
        grid[5] = 130.0; // on the south edge
        grid[n * 100 + 100] = 5000.0; // inside: not an edge
        grid[n * 7] = f32::NAN;
        let h = QuadHeights::new(grid);
        assert_eq!(h.range_m, (100.0, 5000.0));
        assert_eq!(h.edge_roughness_m, 30.0);
        let empty = QuadHeights::new(vec![f32::NAN; n * n]);
        assert_eq!((empty.range_m, empty.edge_roughness_m), ((0.0, 0.0), 0.0));
    }
}
