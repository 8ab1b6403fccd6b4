//! Terrain data for the renderer: which quads have data (known up front from the stores), the
//! asynchronous loader (worker threads that fetch raw source tiles per dataset and quad from the
//! stores, upsampled from an ancestor below a dataset's finest level, and compute static maps),
//! and the bounded CPU cache (least recently used, byte budget) the loader fills. The loader
//! composes nothing: composition is the GPU's (`compose`).
//!
//! Nothing here blocks a frame: the renderer asks for what it wants, takes whatever has arrived
//! since the last frame, and draws what it has.

use std::collections::{HashMap, HashSet, VecDeque};
use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender};
use std::sync::{Arc, Condvar, Mutex};

use crate::ecm::geometry::{MapCache, StaticMaps};
use crate::ecm::{CubeProjection, QuadId};
use crate::geodesy::Ellipsoid;
use crate::store::grid::GRID;
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
        QuadHeights { grid, range_m: (lo, hi), edge_roughness_m: rough }
    }

    fn bytes(&self) -> usize {
        self.grid.len() * 4
    }
}

/// One dataset the renderer reads.
#[derive(Clone, Debug)]
pub struct DatasetInfo {
    /// Its store.
    pub store: PathBuf,
    /// Its name in the store.
    pub dataset: String,
    /// Finest level.
    pub finest_level: u8,
    /// Quads with data, per level 0 ..= finest.
    pub present: Vec<HashSet<QuadId>>,
    /// Height range over its finest level, metres.
    pub range_m: (f64, f64),
    /// The body of its store.
    pub body: Ellipsoid,
    /// Moved east and north by this much, metres (see `shifted`; the layer's `shift_m`).
    pub shift_m: [f64; 2],
}

impl DatasetInfo {
    /// Reads what a store's dataset covers.
    pub fn open(store_path: &std::path::Path, dataset: &str) -> Result<DatasetInfo, StoreError> {
        let store = Store::open_read_only(store_path)?;
        let record = store.resolve_dataset(Some(dataset))?;
        let finest = record.settings.finest_level;
        let present = (0..=finest).map(|l| store.data_quads(&record.name, l)).collect::<Result<Vec<_>, _>>()?;
        let range_m = store.height_range(&record.name, finest)?.unwrap_or((0.0, 0.0));
        Ok(DatasetInfo {
            store: store_path.to_path_buf(),
            dataset: record.name,
            finest_level: finest,
            present,
            range_m,
            body: *store.body(),
            shift_m: [0.0, 0.0],
        })
    }

    /// Whether the dataset has a tile at `quad`.
    pub fn has(&self, quad: QuadId) -> bool {
        self.present.get(quad.level as usize).is_some_and(|s| s.contains(&quad))
    }

    /// The quad whose tile gives this dataset's heights at `quad`: the quad itself up to the
    /// dataset's finest level, below it the ancestor at the finest level (upsampled).
    pub fn source_quad(&self, quad: QuadId) -> QuadId {
        let mut q = quad;
        while q.level > self.finest_level {
            q = q.parent().expect("a quad below level 0 has a parent");
        }
        q
    }

    /// Whether the dataset has heights at `quad`, its own or upsampled from the finest level.
    pub fn covers(&self, quad: QuadId) -> bool {
        self.has(self.source_quad(quad))
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
    let mut at = quad;
    while at.level > level {
        at = at.parent().expect("a quad below level 0 has a parent");
    }
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

/// The heights of `quad` bilinearly interpolated from the grid of its ancestor `source` (both
/// corner-inclusive 257² grids); NaN where a sample with weight has no data.
pub fn upsample(grid: &[f32], source: QuadId, quad: QuadId) -> Vec<f32> {
    let n = SAMPLES as usize;
    let k = quad.level - source.level;
    let scale = 1.0 / f64::from(1u32 << k);
    let (ox, oy) = (f64::from(quad.x - (source.x << k)), f64::from(quad.y - (source.y << k)));
    let cells = f64::from(SAMPLES - 1);
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        let v = (oy * cells + j as f64) * scale;
        for i in 0..n {
            let u = (ox * cells + i as f64) * scale;
            out.push(bilinear(grid, u, v) as f32);
        }
    }
    out
}

/// Bilinear interpolation in a 257² grid at grid coordinates (u, v) ∈ [0, 256]² (NaN where a
/// sample with weight has none; a sample with weight 0 is not read).
pub fn bilinear(grid: &[f32], u: f64, v: f64) -> f64 {
    let n = SAMPLES as usize;
    let (i0, j0) = ((u.floor() as usize).min(n - 2), (v.floor() as usize).min(n - 2));
    let (fu, fv) = (u - i0 as f64, v - j0 as f64);
    let mut h = 0.0;
    for (di, dj, w) in
        [(0, 0, (1.0 - fu) * (1.0 - fv)), (1, 0, fu * (1.0 - fv)), (0, 1, (1.0 - fu) * fv), (1, 1, fu * fv)]
    {
        if w > 0.0 {
            h += w * f64::from(grid[(j0 + dj) * n + i0 + di]);
        }
    }
    h
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
