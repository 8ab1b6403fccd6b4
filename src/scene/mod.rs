//! The CPU side of what is drawn, with no GPU in it: a project opened for rendering ([`Scene`]:
//! the body, the layer stack with its datasets' coverage, importing a dataset from its listed
//! sources when its store lacks it, the colour ramp, the settings), the camera, the quad
//! selection, the asynchronous tile loader and its cache. The renderer in [`crate::gpu`] draws a
//! scene; `compare`, `replay` and the command line read one without a device.

pub mod block_ranges;
pub mod camera;
mod compose_cpu;
pub mod dataset;
pub mod flight;
pub mod loader;
mod operand;
pub mod patch_error;
pub mod patches;
pub(crate) mod quads;
pub mod select;
pub mod shifted;
pub(crate) mod slots;

pub use camera::Camera;

use std::collections::HashMap;
use std::sync::Arc;

use crate::colour::Ramp;
use crate::ecm::QuadId;
use crate::edit::EditRaster;
use crate::files::lock::Lock;
use crate::geodesy::Ellipsoid;
use crate::layers::{LayerSpec, QuadPlan, Stack};
use crate::progress::Watch;
use crate::project::{ColourMapSpec, DetailSpec, Project, Visuals};
use crate::store::{ImportOptions, LevelChoice, Resampling, Store, StoreError, VerticalDatum};
use crate::{Invalid, colour::ColourError, edit::StrokeError, erosion::layer::OperationError, layers::LayerError};
use dataset::DatasetInfo;
use loader::DataKey;

/// What can stop a scene from opening, reading or rebuilding a layer.
#[derive(Debug, thiserror::Error)]
pub enum SceneError {
    /// A project value (its body) or a request that breaks a rule.
    #[error(transparent)]
    Invalid(#[from] Invalid),
    /// The layer stack refuses a layer.
    #[error(transparent)]
    Layer(#[from] LayerError),
    /// A store could not be read or a dataset imported.
    #[error(transparent)]
    Store(#[from] StoreError),
    /// A tile could not be read.
    #[error(transparent)]
    Load(#[from] loader::LoadError),
    /// The colour map.
    #[error(transparent)]
    Colour(#[from] ColourError),
    /// Another process imported into a dataset layer's store for longer than the wait.
    #[error("layer '{layer}'")]
    StoreLock {
        /// The layer.
        layer: String,
        /// Who held the store.
        #[source]
        source: crate::files::lock::LockError,
    },
    /// A dataset layer's store or dataset cannot serve it.
    #[error("layer '{layer}': {problem}")]
    Dataset {
        /// The layer.
        layer: String,
        /// What is wrong.
        problem: String,
    },
    /// A dataset layer's store holds tiles on another body than the project's.
    #[error("layer '{layer}': store: {} holds tiles on {store_body}, but the project's body is {project_body}", store.display())]
    OtherBody {
        /// The layer.
        layer: String,
        /// The store.
        store: std::path::PathBuf,
        /// The store's body.
        store_body: String,
        /// The project's body.
        project_body: String,
    },
    /// A dataset layer's store could not be read.
    #[error("layer '{layer}'")]
    DatasetStore {
        /// The layer.
        layer: String,
        /// Why.
        #[source]
        source: StoreError,
    },
    /// An edit layer's strokes could not be applied.
    #[error("layer '{layer}'")]
    Strokes {
        /// The layer.
        layer: String,
        /// Why.
        #[source]
        source: StrokeError,
    },
    /// An erosion layer's runs could not be replayed.
    #[error("layer '{layer}'")]
    Runs {
        /// The layer.
        layer: String,
        /// Why.
        #[source]
        source: OperationError,
    },
    /// An edit layer's cache could not be written.
    #[error(transparent)]
    Cache(#[from] crate::edit::cache::CacheError),
    /// A folder could not be made.
    #[error("{}: cannot create", path.display())]
    Folder {
        /// The folder.
        path: std::path::PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
}

/// A quad's 257² values.
type Grid = Vec<f32>;

/// A quad's composed heights and, where a difference layer is drawn, its A − B.
pub type Composed = (Grid, Option<Grid>);

/// Everything the renderer needs from a project.
#[derive(Clone, Debug)]
pub struct Scene {
    /// The body.
    pub ellipsoid: Ellipsoid,
    /// The layer stack, bottom to top.
    pub stack: Stack,
    /// The distinct datasets the stack's dataset layers read (one per store and dataset name).
    pub datasets: Arc<Vec<DatasetInfo>>,
    /// Per dataset layer (by its uid), its index in `datasets`.
    pub dataset_of: HashMap<u64, usize>,
    /// Whether composition skips octaves finer than a quad's samples (on by default; off only
    /// to measure what skipping costs).
    pub octave_skipping: bool,
    /// How the terrain looks.
    pub visuals: Visuals,
    /// Level of detail and caches.
    pub detail: DetailSpec,
    /// The colour ramp, resolved against the data's height range.
    pub ramp: Ramp,
    /// Height range over all datasets, metres (0, 0 without data).
    pub range_m: (f64, f64),
    /// Per edit layer (by its uid), its raster of deltas.
    pub edits: HashMap<u64, Arc<EditRaster>>,
    /// Where edit rasters are cached (the project's `stores/`; None: not cached).
    pub edit_cache_dir: Option<std::path::PathBuf>,
}

/// Where [`Scene::open_with`] takes the edit and erosion layers' rasters from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Edits {
    /// Their caches where current, else rebuilt from their operations on the CPU (and cached).
    Cached,
    /// Empty, for a replay to rebuild ([`crate::replay`]).
    Empty,
}

/// What opening a scene did besides opening (imports), for the command line to report.
#[derive(Clone, Debug, Default)]
pub struct OpenReport {
    /// One line per dataset imported from its sources.
    pub imported: Vec<String>,
    /// One line per edit layer: read from its cache, or rebuilt from its strokes (and cached).
    pub edits: Vec<String>,
}

impl Scene {
    /// The dataset a stack layer reads, if it is a dataset layer.
    pub fn dataset_of_layer(&self, index: usize) -> Option<usize> {
        self.dataset_of.get(&self.stack.layers[index].uid).copied()
    }

    /// The tiles stack layer `index` reads at `quad`, if it is a dataset: its source tile, and
    /// where it fades in from its no-data edge, its edge tile; for an edit layer, its deltas.
    pub fn layer_tiles(&self, index: usize, quad: QuadId) -> Option<(DataKey, Option<DataKey>)> {
        let layer = &self.stack.layers[index];
        if let Some(raster) = self.edits.get(&layer.uid) {
            return Some((DataKey::Edit(layer.uid as u32, quad, raster.stamp(quad)), None));
        }
        let d = self.dataset_of_layer(index)? as u32;
        let feather = self.stack.layers[index].spec.feather_edge_m();
        let edge = (feather > 0.0)
            .then(|| DataKey::Edge(d, quad, crate::layers::edge::edge_level(self.ellipsoid.a_m(), feather)));
        Some((DataKey::Source(d, quad), edge))
    }

    /// Whether stack layer `index` has data at `quad` (a dataset's tile there or at an ancestor;
    /// always for layers of other kinds).
    pub fn covers(&self, index: usize, quad: QuadId) -> bool {
        if let Some(raster) = self.edits.get(&self.stack.layers[index].uid) {
            return raster.covers(quad);
        }
        self.dataset_of_layer(index).is_none_or(|d| self.datasets[d].covers(quad))
    }

    /// What composing `quad` reads. Its stamp also holds, per edit layer it reads, that layer's
    /// stamp at the quad: a stroke changes the stamps of the quads it changed only (strokes do
    /// not bump the layer's revision: [`Stack::set_strokes`]).
    pub fn plan(&self, quad: QuadId) -> QuadPlan {
        let mut plan = self.stack.plan(quad, &|i| self.covers(i, quad), self.octave_skipping);
        let stamps: Vec<u64> = plan
            .all_layers()
            .filter_map(|l| self.edits.get(&self.stack.layers[l.index].uid))
            .map(|raster| u64::from(raster.stamp(quad)))
            .collect();
        for s in stamps {
            plan.stamp = (plan.stamp ^ s.wrapping_mul(0x9e37_79b9_7f4a_7c15)).wrapping_mul(0x100_0000_01b3);
        }
        plan
    }

    /// The finest level at which any shown layer adds detail (a dataset's finest stored level,
    /// an edit layer's strokes, an erosion layer's runs, a procedural layer's octaves): what a
    /// request's default level may go down to ([`crate::layers::default_level`]).
    pub fn detail_level(&self) -> Option<u8> {
        self.stack.detail_level(&|_| true)
    }

    /// The datasets that the shown layers read (a hidden layer's bound nothing).
    pub fn shown_datasets(&self) -> Vec<&DatasetInfo> {
        let mut shown: Vec<usize> = (0..self.stack.layers.len())
            .filter(|&i| self.stack.layers[i].active())
            .filter_map(|i| self.dataset_of_layer(i))
            .collect();
        shown.sort_unstable();
        shown.dedup();
        shown.into_iter().map(|d| &self.datasets[d]).collect()
    }

    /// The finest level of the datasets a plan reads, if it reads any.
    pub fn finest_level_in(&self, plan: &QuadPlan) -> Option<u8> {
        plan.datasets(&self.stack).filter_map(|i| self.dataset_of_layer(i)).map(|d| self.datasets[d].finest_level).max()
    }

    /// Opens a project's layers, importing datasets whose store lacks them and that list sources;
    /// edit and erosion layers are read from their caches or rebuilt.
    pub fn open(project: &Project) -> Result<(Scene, OpenReport), SceneError> {
        Scene::open_with(project, Edits::Cached)
    }

    /// [`Scene::open`], with the edit and erosion layers' rasters as `edits` says.
    pub fn open_with(project: &Project, edits: Edits) -> Result<(Scene, OpenReport), SceneError> {
        Scene::open_watched(project, edits, &Watch::default())
    }

    /// [`Scene::open_with`], the strokes and runs of layers rebuilt from their operations
    /// counted on `watch` and stopped when it is cancelled.
    pub fn open_watched(project: &Project, edits: Edits, watch: &Watch) -> Result<(Scene, OpenReport), SceneError> {
        let ellipsoid = project.ellipsoid()?;
        let mut report = OpenReport::default();
        let stack = Stack::new(ellipsoid, &project.layers)?;
        let range_m = stack_range(&stack);
        let visuals = project.visuals.clone();
        let ramp = resolve_ramp(project, &visuals.colour_map, range_m)?;
        let mut scene = Scene {
            ellipsoid,
            stack,
            datasets: Arc::new(Vec::new()),
            dataset_of: HashMap::new(),
            octave_skipping: true,
            visuals,
            detail: project.detail.clone(),
            ramp,
            range_m,
            edits: HashMap::new(),
            edit_cache_dir: Some(project.base_dir.join("stores")),
        };
        for (index, d) in project.layers.iter().enumerate() {
            if d.holds_deltas() {
                match edits {
                    Edits::Cached => report.edits.push(scene.attach_edit_watched(index, watch)?),
                    Edits::Empty => scene.set_edit(index, EditRaster::new(ellipsoid, 0)),
                }
                continue;
            }
            if !d.is_data() {
                continue;
            }
            if let Some(opts) = import_needed(project, d)? {
                // Two processes opening the project at once import its store one after the other:
                // the second finds the dataset complete once the first is done.
                let _lock = Lock::acquire(&opts.store, "terrafuse (importing a dataset)", IMPORT_WAIT, &mut |_| {})
                    .map_err(|source| SceneError::StoreLock { layer: d.name.clone(), source })?;
                let Some(opts) = import_needed(project, d)? else {
                    let info = open_dataset(project, d)?;
                    scene.attach(index, info)?;
                    continue;
                };
                let r = crate::store::import(&opts)?;
                report.imported.push(format!(
                    "imported {} into {} (levels 0–{}, {:.1} s)",
                    opts.sources.iter().map(|f| f.display().to_string()).collect::<Vec<_>>().join(", "),
                    opts.store.display(),
                    r.finest_level,
                    r.seconds_finest + r.seconds_pyramid
                ));
            }
            let info = open_dataset(project, d)?;
            scene.attach(index, info)?;
        }
        scene.range_m = stack_range(&scene.stack);
        scene.ramp = resolve_ramp(project, &scene.visuals.colour_map, scene.range_m)?;
        Ok((scene, report))
    }

    /// Gives edit layer `index` its raster: read from its cache when the cache is current, else
    /// built from its strokes in effect (and cached); records its range. Returns a line saying
    /// which.
    pub fn attach_edit(&mut self, index: usize) -> Result<String, SceneError> {
        self.attach_edit_watched(index, &Watch::default())
    }

    /// [`Scene::attach_edit`], a rebuild counted on `watch` and stopped when it is cancelled.
    pub fn attach_edit_watched(&mut self, index: usize, watch: &Watch) -> Result<String, SceneError> {
        let t = std::time::Instant::now();
        let spec = &self.stack.layers[index].spec;
        let name = spec.name.clone();
        let erosion = spec.as_erosion().is_some();
        let (kind, what) = if erosion { ("erosion", "runs") } else { ("edit", "strokes") };
        let count = if erosion { spec.applied_runs().len() } else { spec.applied_strokes().len() };
        let path = self.edit_cache_path(index);
        if let Some(raster) = path.as_deref().and_then(|p| crate::edit::cache::read(p, self.ellipsoid)) {
            self.set_edit(index, raster);
            return Ok(format!(
                "{kind} layer '{name}': {count} {what} read from {} ({:.2} s)",
                path.as_deref().map(|p| p.display().to_string()).unwrap_or_default(),
                t.elapsed().as_secs_f64()
            ));
        }
        let below = self.below(index)?;
        let layer = &self.stack.layers[index];
        let below = |q| Ok(below.heights_cpu(q)?);
        let raster = if erosion {
            let cpu = crate::erosion::layer::CpuStepper;
            crate::erosion::layer::build_with(self.ellipsoid, layer.spec.applied_runs(), &below, &cpu, watch)
                .map_err(|source| SceneError::Runs { layer: layer.spec.name.clone(), source })?
        } else {
            let cpu = crate::edit::kernel::CpuRasteriser;
            EditRaster::build_with(self.ellipsoid, layer.spec.applied_strokes(), &below, &cpu, watch)
                .map_err(|source| SceneError::Strokes { layer: layer.spec.name.clone(), source })?
        };
        let mut line =
            format!("{kind} layer '{name}': rebuilt from {count} {what} in {:.2} s", t.elapsed().as_secs_f64());
        if let Some(p) = &path {
            match crate::edit::cache::write(p, &raster) {
                Ok(()) => line += &format!(", saved to {}", p.display()),
                Err(e) => line += &format!(" (not cached: {})", crate::errors::chain(&e)),
            }
        }
        self.set_edit(index, raster);
        Ok(line)
    }

    /// Saves edit layer `index`'s raster in its cache unless the cache is current (after strokes
    /// made in the workstation, when the project is saved). Returns the file written, if any.
    pub fn save_edit_cache(&self, index: usize) -> Result<Option<std::path::PathBuf>, SceneError> {
        let (Some(path), Some(raster)) = (self.edit_cache_path(index), self.edits.get(&self.stack.layers[index].uid))
        else {
            return Ok(None);
        };
        if path.exists() {
            return Ok(None);
        }
        crate::edit::cache::write(&path, raster)?;
        Ok(Some(path))
    }

    /// The cache file of edit layer `index` as the layer stands (None: no cache folder).
    fn edit_cache_path(&self, index: usize) -> Option<std::path::PathBuf> {
        let dir = self.edit_cache_dir.as_ref()?;
        let layer = &self.stack.layers[index];
        let strokes = layer.spec.applied_strokes();
        let runs = layer.spec.applied_runs();
        let mut digest = crate::edit::cache::Digest::default()
            .with(if runs.is_empty() { &b"terrafuse edit raster 1"[..] } else { &b"terrafuse erosion raster 1"[..] })
            .with(&self.ellipsoid.a_m().to_le_bytes())
            .with(&self.ellipsoid.b_m().to_le_bytes())
            .with(to_json(&strokes).as_bytes());
        if !runs.is_empty() {
            digest = digest.with(to_json(&runs).as_bytes()).with(&crate::erosion::MODEL_VERSION.to_le_bytes());
        }
        if !runs.is_empty() || strokes.iter().any(|s| s.tool.reads_terrain()) {
            // What they read: the layers below, and the stores their datasets come from.
            for (k, below) in self.stack.layers[..index].iter().enumerate() {
                digest = digest.with(to_json(&below.spec).as_bytes());
                if let Some(d) = self.dataset_of_layer(k) {
                    let meta = std::fs::metadata(&self.datasets[d].store).ok();
                    let len = meta.as_ref().map_or(0, |m| m.len());
                    let modified = meta
                        .and_then(|m| m.modified().ok())
                        .and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok())
                        .map_or(0, |d| d.as_nanos());
                    digest = digest.with(&len.to_le_bytes()).with(&modified.to_le_bytes());
                }
            }
        }
        Some(crate::edit::cache::cache_path(dir, &layer.spec.name, digest.value()))
    }

    /// The scene of the layers below stack layer `index` (it and every layer above hidden): what
    /// an edit layer's smooth, flatten and ramp read, through [`Scene::heights_cpu`].
    pub fn below(&self, index: usize) -> Result<Scene, SceneError> {
        let mut below = self.clone();
        for k in index..below.stack.layers.len() {
            let mut spec = below.stack.layers[k].spec.clone();
            // Hidden, they are never planned; their strokes are not needed.
            spec.visible = false;
            if let Some(edit) = spec.as_edit_mut() {
                *edit = crate::layers::EditLayer::default();
            }
            if let Some(erosion) = spec.as_erosion_mut() {
                *erosion = crate::layers::ErosionLayer::default();
            }
            below.stack.set(k, spec)?;
        }
        Ok(below)
    }

    /// Puts a raster on edit layer `index` (after a stroke, an undo or a redo; its stamps are
    /// made to follow the raster it replaces).
    pub fn set_edit(&mut self, index: usize, mut raster: EditRaster) {
        if let Some(old) = self.edits.get(&self.stack.layers[index].uid) {
            raster.succeed(old);
        }
        self.stack.set_dataset_info(index, raster.range_m(), None);
        self.edits.insert(self.stack.layers[index].uid, Arc::new(raster));
    }

    /// Points dataset layer `index` at its dataset moved by its current `shift_m` (after the
    /// layer's shift changed): the same dataset under another shift is another set of tiles.
    pub fn reattach_shifted(&mut self, index: usize) -> Result<(), SceneError> {
        let d = self.dataset_of_layer(index).ok_or(Invalid::from("the layer reads no dataset"))?;
        let info = self.datasets[d].clone();
        self.attach(index, info)
    }

    /// Inserts a dataset layer at `index` (0: bottom) reading `info` (see [`open_dataset`]).
    pub fn insert_dataset_layer(&mut self, index: usize, spec: LayerSpec, info: DatasetInfo) -> Result<(), SceneError> {
        if !spec.is_data() {
            return Err(SceneError::Dataset {
                layer: spec.name.clone(),
                problem: format!("kind: {} is not a dataset", spec.kind().name()),
            });
        }
        self.stack.insert(index, spec)?;
        if let Err(e) = self.attach(index, info) {
            // Just inserted: no difference reads it yet.
            let _ = self.stack.remove(index);
            return Err(e);
        }
        Ok(())
    }

    /// Attaches an opened dataset to dataset layer `index`: checks its body against the
    /// project's, records its value range and spacing, and shares it with the layers that read
    /// the same store and dataset.
    fn attach(&mut self, index: usize, mut info: DatasetInfo) -> Result<(), SceneError> {
        let name = &self.stack.layers[index].spec.name;
        info.shift_m = self.stack.layers[index].spec.shift_m();
        let store_body = info.body;
        if store_body.a_m() != self.ellipsoid.a_m() || store_body.b_m() != self.ellipsoid.b_m() {
            return Err(SceneError::Dataset {
                layer: name.clone(),
                problem: format!(
                    "{} is on {}, the project on {}",
                    info.store.display(),
                    store_body.name(),
                    self.ellipsoid.name()
                ),
            });
        }
        self.stack.set_dataset_info(index, info.range_m, Some(info.finest_level));
        let same = |o: &DatasetInfo| o.store == info.store && o.dataset == info.dataset && o.shift_m == info.shift_m;
        let k = match self.datasets.iter().position(same) {
            Some(k) => k,
            None => {
                Arc::make_mut(&mut self.datasets).push(info);
                self.datasets.len() - 1
            }
        };
        self.dataset_of.insert(self.stack.layers[index].uid, k);
        Ok(())
    }
}

/// A value as JSON (for digests: what a cache depends on).
fn to_json<T: serde::Serialize + ?Sized>(value: &T) -> String {
    serde_json::to_string(value).unwrap_or_default()
}

/// How long opening a project waits for another process importing the same store.
const IMPORT_WAIT: std::time::Duration = std::time::Duration::from_secs(3600);

/// What importing a dataset layer's sources into its store takes, when the store lacks a
/// complete copy of it (None: nothing to import). Errors name the layer and the store.
pub fn import_needed(project: &Project, d: &LayerSpec) -> Result<Option<ImportOptions>, SceneError> {
    let Some(data) = d.as_dataset() else {
        return Err(SceneError::Dataset {
            layer: d.name.clone(),
            problem: format!("kind: {} is not a dataset", d.kind().name()),
        });
    };
    let store = &data.store;
    let store_path = project.resolve(store);
    let name = d.store_dataset();
    let has = if store_path.exists() {
        let store = Store::open_read_only(&store_path)
            .map_err(|source| SceneError::DatasetStore { layer: d.name.clone(), source })?;
        let body = project.ellipsoid()?;
        if (store.body().a_m(), store.body().b_m()) != (body.a_m(), body.b_m()) {
            return Err(SceneError::OtherBody {
                layer: d.name.clone(),
                store: store_path,
                store_body: store.body().to_string(),
                project_body: body.to_string(),
            });
        }
        store.dataset(name)?.is_some_and(|r| r.completed.is_some())
    } else {
        false
    };
    if has {
        return Ok(None);
    }
    let Some(source) = &data.source else {
        return Err(SceneError::Dataset {
            layer: d.name.clone(),
            problem: format!(
                "{} has no complete dataset '{name}' and the project lists no source to import it from",
                store_path.display()
            ),
        });
    };
    if let Some(dir) = store_path.parent() {
        std::fs::create_dir_all(dir).map_err(|source| SceneError::Folder { path: dir.to_path_buf(), source })?;
    }
    let vertical = match &source.vertical_datum {
        Some(v) => {
            v.parse::<VerticalDatum>().map_err(|e| SceneError::Dataset { layer: d.name.clone(), problem: e.0 })?
        }
        None => VerticalDatum::Ellipsoidal,
    };
    Ok(Some(ImportOptions {
        sources: source.files.iter().map(|f| project.resolve(f)).collect(),
        store: store_path,
        body: project.ellipsoid()?,
        name: Some(name.to_string()),
        level: source.max_level.map_or(LevelChoice::Auto, LevelChoice::Level),
        resampling: Resampling::Bilinear,
        transform: crate::store::lattice::Transform::Lattice,
        vertical,
        memory_budget: 1 << 30,
        threads: None,
        progress: false,
        finest_only: false,
        watch: None,
    }))
}

/// Opens what a dataset layer reads (its store must hold the dataset complete).
pub fn open_dataset(project: &Project, d: &LayerSpec) -> Result<DatasetInfo, SceneError> {
    let store = &d
        .as_dataset()
        .ok_or_else(|| SceneError::Dataset {
            layer: d.name.clone(),
            problem: format!("kind: {} is not a dataset", d.kind().name()),
        })?
        .store;
    let path = project.resolve(store);
    let info = DatasetInfo::open(&path, d.store_dataset())
        .map_err(|source| SceneError::DatasetStore { layer: d.name.clone(), source })?;
    let body = project.ellipsoid()?;
    if (info.body.a_m(), info.body.b_m()) != (body.a_m(), body.b_m()) {
        return Err(SceneError::OtherBody {
            layer: d.name.clone(),
            store: path,
            store_body: info.body.to_string(),
            project_body: body.to_string(),
        });
    }
    Ok(info)
}

/// The heights the visible layers can give, metres: the hull of the active layers' value ranges,
/// widened by what additive layers add ((0, 0) without any).
pub fn stack_range(stack: &Stack) -> (f64, f64) {
    let mut range: Option<(f64, f64)> = None;
    let mut added = (0.0, 0.0);
    for layer in stack.layers.iter().filter(|l| l.active()) {
        let (lo, hi) = layer.value_range_m();
        if lo > hi {
            continue;
        }
        if layer.spec.blend == crate::layers::BlendMode::Add {
            added = (added.0 + lo.min(0.0) * layer.spec.opacity, added.1 + hi.max(0.0) * layer.spec.opacity);
        } else {
            range = Some(range.map_or((lo, hi), |(a, b)| (a.min(lo), b.max(hi))));
        }
    }
    range.map_or((0.0, 0.0), |(a, b)| (a + added.0, b + added.1))
}

/// The colour ramp a colour-map setting names: a user's file (relative to the project) or a
/// preset, over its range or, without one, the data's height range.
pub fn resolve_ramp(project: &Project, cm: &ColourMapSpec, data_range_m: (f64, f64)) -> Result<Ramp, SceneError> {
    let range = if data_range_m.1 > data_range_m.0 { data_range_m } else { (0.0, 1.0) };
    let range = cm.range_m.map_or(cm.by.default_range(range), |[a, b]| (a, b));
    Ok(match &cm.file {
        Some(file) => Ramp::from_file(&project.resolve(file), range, cm.nodata_colour)?,
        None => Ramp::preset(&cm.preset, range, cm.nodata_colour)?,
    })
}
