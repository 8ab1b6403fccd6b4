//! `terrafuse import`: any GDAL raster onto the cube map's sample grid, in parallel over tiles,
//! streaming the source in windows, into the store in transactions that a rerun resumes.
//!
//! 1. Every source is checked (size, georeferencing, CRS, body, data) before the store is touched.
//! 2. The finest level: [`grid::level_for_resolution`] of the finest source, unless told.
//! 3. Candidate quads at that level: the quads under a grid of source points (spaced ≤ ¼ quad)
//!    and their neighbours; each is resampled (per sample: face point → geodetic, f64 → source
//!    pixel through PROJ → bilinear, cubic or nearest), and kept only if it has data.
//! 4. Coarser levels down to 0: each sample the area mean of its cell on the level below
//!    (weights ¼ ½ ¼ per axis on the corner grid, the exact area of the child cells it covers),
//!    ignoring no data, no data where less than half the cell has data.

use std::collections::HashSet;
use std::path::{Path, PathBuf};
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::sync_channel;
use std::time::Instant;

use gdal::spatial_ref::{CoordTransform, SpatialRef};
use indicatif::{ProgressBar, ProgressStyle};
use rayon::prelude::*;

use super::StoreError;
use super::gpkg::{DatasetRecord, DatasetSettings, SourceProvenance, Store, check_dataset_name, face_proj, utc_now};
use super::grid::{self, GRID, TILE, face_xy, spacing_m};
use super::read::GridReader;
use super::source::{SourceInfo, SourceReader, Window};
use super::tile::QuadGrid;
use crate::ecm::{CubeProjection, Edge, Face, FacePoint, QuadId};
use crate::geodesy::Ellipsoid;

/// How a sample is interpolated from the source pixels around it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resampling {
    /// Bilinear over the 2×2 pixel centres around the point (weights renormalised over pixels
    /// with data, as gdalwarp does).
    Bilinear,
    /// Cubic convolution (Keys, a = −0.5) over 4×4; bilinear where one of them has no data.
    Cubic,
    /// The nearest pixel.
    Nearest,
}

impl Resampling {
    /// The name used on the command line and in the store.
    pub fn name(self) -> &'static str {
        match self {
            Resampling::Bilinear => "bilinear",
            Resampling::Cubic => "cubic",
            Resampling::Nearest => "nearest",
        }
    }
}

impl FromStr for Resampling {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "bilinear" => Ok(Resampling::Bilinear),
            "cubic" => Ok(Resampling::Cubic),
            "nearest" => Ok(Resampling::Nearest),
            _ => Err(format!("unknown resampling '{s}': use bilinear, cubic or nearest")),
        }
    }
}

/// The vertical datum of the source heights, and so what the import does with them.
#[derive(Clone, Debug, PartialEq)]
pub enum VerticalDatum {
    /// Not declared: heights are stored as they are and the store says so.
    Unspecified,
    /// Already heights above the body's ellipsoid.
    Ellipsoidal,
    /// Heights above a geoid given by a PROJ grid (a name on PROJ's search path, such as
    /// `egm96_15.gtx`, or a file): converted to ellipsoidal heights when the grid is found.
    Geoid {
        /// Geoid model name, for the record.
        model: String,
        /// The grid.
        grid: String,
    },
}

impl FromStr for VerticalDatum {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "unspecified" => Ok(VerticalDatum::Unspecified),
            "ellipsoidal" | "ellipsoid" => Ok(VerticalDatum::Ellipsoidal),
            "egm96" => Ok(VerticalDatum::Geoid { model: "EGM96".into(), grid: "egm96_15.gtx".into() }),
            "egm2008" => Ok(VerticalDatum::Geoid { model: "EGM2008".into(), grid: "egm08_25.gtx".into() }),
            other => match other.strip_prefix("geoid:") {
                Some(path) if !path.is_empty() => {
                    let p = Path::new(path);
                    let grid = std::fs::canonicalize(p).map_err(|e| format!("geoid grid {path}: {e}"))?;
                    Ok(VerticalDatum::Geoid {
                        model: format!("geoid grid {path}"),
                        grid: grid.to_string_lossy().into_owned(),
                    })
                }
                _ => Err(format!(
                    "unknown vertical datum '{s}': use ellipsoidal, egm96, egm2008, geoid:GRIDFILE or unspecified"
                )),
            },
        }
    }
}

/// The finest level: from the source resolution, or given.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum LevelChoice {
    /// [`grid::level_for_resolution`] of the finest source.
    Auto,
    /// This level.
    Level(u8),
}

impl FromStr for LevelChoice {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        if s == "auto" {
            return Ok(LevelChoice::Auto);
        }
        match s.parse::<u8>() {
            Ok(l) if l <= crate::ecm::MAX_LEVEL => Ok(LevelChoice::Level(l)),
            _ => Err(format!("level '{s}' is not auto or a level 0–30")),
        }
    }
}

/// Everything an import needs.
#[derive(Clone, Debug)]
pub struct ImportOptions {
    /// Source rasters, in priority order (where they overlap, the first with data wins).
    pub sources: Vec<PathBuf>,
    /// The store (created if missing).
    pub store: PathBuf,
    /// The body.
    pub body: Ellipsoid,
    /// Dataset name (default: the first source's file stem).
    pub name: Option<String>,
    /// Finest level.
    pub level: LevelChoice,
    /// Interpolation at the finest level.
    pub resampling: Resampling,
    /// Vertical datum of the source heights.
    pub vertical: VerticalDatum,
    /// Memory budget in bytes (GDAL cache, windows, tiles in flight).
    pub memory_budget: u64,
    /// Worker threads (default: all cores).
    pub threads: Option<usize>,
    /// Draw a progress bar (on a terminal).
    pub progress: bool,
    /// Stop after this many tiles of the finest level (for benchmarks of the resampling alone).
    pub finest_only: bool,
}

/// What an import did.
#[derive(Clone, Debug, Default)]
pub struct ImportReport {
    /// Dataset name.
    pub dataset: String,
    /// Finest level.
    pub finest_level: u8,
    /// Per level: tiles with data written now, and tiles (with or without data) an earlier
    /// interrupted run had finished.
    pub levels: Vec<(u8, u64, u64)>,
    /// Samples resampled from the source (257² per finest-level quad computed now).
    pub finest_samples: u64,
    /// Seconds spent on the finest level and on the coarser ones.
    pub seconds_finest: f64,
    /// Seconds spent on the pyramid.
    pub seconds_pyramid: f64,
    /// The vertical datum recorded.
    pub vertical_datum: String,
    /// The dataset was already complete: nothing was done.
    pub already_complete: bool,
    /// Peak resident memory of the process, bytes.
    pub peak_rss_bytes: u64,
}

/// Peak resident set size of this process (VmHWM), bytes.
pub fn peak_rss_bytes() -> u64 {
    std::fs::read_to_string("/proc/self/status")
        .ok()
        .and_then(|s| {
            s.lines().find(|l| l.starts_with("VmHWM:")).and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok())
        })
        .map_or(0, |kb| kb * 1024)
}

struct Plan {
    supersample: u32,
    resampling: Resampling,
    window_cap_bytes: usize,
    geoid_grid: Option<String>,
}

/// One worker's handles: a reader per source, and the geoid transform.
struct Worker {
    readers: Vec<SourceReader>,
    geoid: Option<CoordTransform>,
}

fn geoid_transform(grid: &str) -> Result<CoordTransform, String> {
    let from = SpatialRef::from_proj4(&format!("+proj=longlat +datum=WGS84 +geoidgrids={grid} +vunits=m +no_defs"))
        .map_err(|e| e.to_string())?;
    // The target must be 3-D (ellipsoidal height): to a 2-D CRS PROJ drops the vertical step.
    let to = SpatialRef::from_epsg(4979).map_err(|e| e.to_string())?;
    let mut from = from;
    let mut to = to;
    from.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    to.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&from, &to).map_err(|e| e.to_string())?;
    // A grid that PROJ cannot find either fails here or leaves heights unchanged.
    let (mut x, mut y, mut z) = ([0.0], [0.0], [0.0]);
    t.transform_coords(&mut x, &mut y, &mut z).map_err(|e| e.to_string())?;
    if !(z[0].is_finite() && z[0] != 0.0) {
        return Err(format!("PROJ found no geoid grid {grid}"));
    }
    Ok(t)
}

/// Runs an import. See the module documentation for the steps.
pub fn import(opts: &ImportOptions) -> Result<ImportReport, StoreError> {
    if opts.sources.is_empty() {
        return Err(StoreError::new(&opts.store, "no source rasters given"));
    }
    // 1. Check every source before touching the store.
    let infos: Vec<SourceInfo> =
        opts.sources.iter().map(|p| SourceInfo::open(p, &opts.body)).collect::<Result<_, _>>()?;
    for info in &infos {
        let r = SourceReader::new(info, &opts.body)?;
        if !(r.any_data_coarse()? || r.any_data_full()?) {
            return Err(StoreError::new(&info.path, "every sample is no data: nothing to import"));
        }
    }
    let name = match &opts.name {
        Some(n) => n.clone(),
        None => default_name(&infos[0].path),
    };
    check_dataset_name(&name).map_err(|m| StoreError::new(&opts.store, m))?;
    let finest_resolution = infos.iter().map(|i| i.resolution_m).fold(f64::INFINITY, f64::min);
    let level = match opts.level {
        LevelChoice::Auto => grid::level_for_resolution(&opts.body, finest_resolution),
        LevelChoice::Level(l) => l,
    };
    // Coarser than the source: average sub-samples over each sample's cell (up to 8×8).
    let supersample = ((spacing_m(&opts.body, level) / finest_resolution / 1.5).ceil() as u32).clamp(1, 8);
    let (vertical_text, geoid_grid) = vertical_record(&opts.vertical, &opts.body, &infos)?;

    let threads = opts.threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get())).max(1);
    let budget = opts.memory_budget.max(256 << 20);
    gdal::config::set_config_option("GDAL_CACHEMAX", &format!("{}", ((budget / 8) >> 20).max(32)))
        .map_err(|e| StoreError::new(&opts.store, format!("cannot set the GDAL cache: {e}")))?;
    let plan = Plan {
        supersample,
        resampling: opts.resampling,
        window_cap_bytes: (budget / (4 * threads as u64)) as usize,
        geoid_grid: geoid_grid.clone(),
    };
    let settings = DatasetSettings {
        sources: infos.iter().map(|i| i.path.to_string_lossy().into_owned()).collect(),
        finest_level: level,
        resampling: opts.resampling.name().into(),
        supersample,
        vertical_datum: vertical_text.clone(),
        geoid_grid,
    };
    let provenance: Vec<SourceProvenance> = infos.iter().map(provenance).collect::<Result<_, _>>()?;

    // 2. Open or create the store; register or resume the dataset.
    // An existing store is checked read-only first, so that a refusal leaves it byte for byte.
    if opts.store.exists() {
        let existing = Store::open_read_only(&opts.store)?;
        let body = existing.body();
        if body.a_m() != opts.body.a_m() || body.b_m() != opts.body.b_m() {
            return Err(StoreError::new(
                &opts.store,
                format!("is a store of body {body}, not {}: use another store for this body", opts.body),
            ));
        }
        if let Some(d) = existing.dataset(&name)?
            && d.completed.is_some()
            && d.settings == settings
            && same_files(&d.sources, &provenance)
        {
            {
                return Ok(ImportReport {
                    dataset: name,
                    finest_level: level,
                    vertical_datum: vertical_text,
                    already_complete: true,
                    peak_rss_bytes: peak_rss_bytes(),
                    ..Default::default()
                });
            }
        }
    }
    let mut store =
        if opts.store.exists() { Store::open(&opts.store)? } else { Store::create(&opts.store, &opts.body)? };
    let body = *store.body();
    let mut report = ImportReport {
        dataset: name.clone(),
        finest_level: level,
        vertical_datum: vertical_text,
        ..Default::default()
    };
    match store.dataset(&name)? {
        Some(existing) if existing.settings != settings || !same_files(&existing.sources, &provenance) => {
            return Err(StoreError::new(
                &opts.store,
                format!(
                    "already has a dataset '{name}' made from other sources or settings; choose another --name (settings there: {})",
                    serde_json::to_string(&existing.settings).unwrap_or_default()
                ),
            ));
        }
        Some(_) => {}
        None => {
            let wkt: Vec<String> = Face::ALL
                .iter()
                .map(|&f| {
                    SpatialRef::from_proj4(&face_proj(&body, f))
                        .and_then(|s| s.to_wkt())
                        .map_err(|e| StoreError::new(&opts.store, format!("PROJ has no QSC CRS: {e}")))
                })
                .collect::<Result<_, _>>()?;
            let wkt: [String; 6] = wkt.try_into().expect("six faces");
            let record = DatasetRecord {
                name: name.clone(),
                settings,
                sources: provenance,
                created: utc_now(),
                completed: None,
            };
            store.add_dataset(&record, &wkt)?;
        }
    }

    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| StoreError::new(&opts.store, format!("cannot start worker threads: {e}")))?;
    let queue = (2 * threads + 4).min((budget / 4 / (600 << 10)).max(4) as usize);

    // 3. The finest level from the sources.
    let start = Instant::now();
    let mut candidates = HashSet::new();
    for info in &infos {
        candidates.extend(footprint(&SourceReader::new(info, &body)?, &body, level)?);
    }
    let mut levels = LevelWriter { store: &mut store, dataset: &name, pool: &pool, queue, progress: opts.progress };
    let (written, finished, computed) = levels.run(
        level,
        candidates,
        || {
            let readers = infos.iter().map(|i| SourceReader::new(i, &body)).collect::<Result<Vec<_>, _>>()?;
            let geoid = match &plan.geoid_grid {
                Some(g) => Some(geoid_transform(g).map_err(|m| StoreError::new(&infos[0].path, m))?),
                None => None,
            };
            Ok(Worker { readers, geoid })
        },
        |w: &mut Worker, q| resample_quad(w, &body, &plan, q),
    )?;
    report.levels.push((level, written, finished));
    report.finest_samples = computed as u64 * u64::from(GRID * GRID);
    report.seconds_finest = start.elapsed().as_secs_f64();

    // 4. The pyramid.
    let start = Instant::now();
    if !opts.finest_only {
        for parent_level in (0..level).rev() {
            let children = levels.store.data_quads(&name, parent_level + 1)?;
            let parents: HashSet<QuadId> = children.iter().filter_map(|q| q.parent()).collect();
            let (written, finished, _) = levels.run(
                parent_level,
                parents,
                || GridReader::new(Store::open_read_only(&opts.store)?, &name),
                |r: &mut GridReader, q| average_quad(r, q),
            )?;
            report.levels.push((parent_level, written, finished));
        }
        levels.store.mark_complete(&name)?;
    }
    report.seconds_pyramid = start.elapsed().as_secs_f64();
    report.peak_rss_bytes = peak_rss_bytes();
    Ok(report)
}

fn default_name(path: &Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    let mut name: String = stem.chars().map(|c| if c.is_ascii_alphanumeric() { c } else { '_' }).take(48).collect();
    if !name.starts_with(|c: char| c.is_ascii_alphabetic()) {
        name.insert(0, 'd');
        name.truncate(48);
    }
    name
}

fn vertical_record(
    v: &VerticalDatum,
    body: &Ellipsoid,
    infos: &[SourceInfo],
) -> Result<(String, Option<String>), StoreError> {
    let declared = infos.iter().find_map(|i| i.vertical_crs.clone());
    Ok(match v {
        VerticalDatum::Unspecified => (
            match declared {
                Some(v) => format!("as in the source, whose CRS declares {v}; not converted"),
                None if body.name() == "wgs84" => "unspecified: heights stored as the source has them (not declared; SRTM-like data are EGM96 geoid heights, not heights above the WGS84 ellipsoid: import with --vertical-datum egm96 to convert them)".to_owned(),
                None => format!("unspecified: heights stored as the source has them (relative to the source's reference surface; body {})", body.name()),
            },
            None,
        ),
        VerticalDatum::Ellipsoidal => (format!("ellipsoidal: heights above the {} ellipsoid", body.name()), None),
        VerticalDatum::Geoid { model, grid } => {
            if body.name() != "wgs84" {
                return Err(StoreError::new(&infos[0].path, format!("a geoid ({model}) is an Earth datum, but the body is {}", body.name())));
            }
            match geoid_transform(grid) {
                Ok(_) => (format!("ellipsoidal: converted from {model} geoid heights with PROJ grid {grid}"), Some(grid.clone())),
                Err(why) => {
                    eprintln!(
                        "warning: {model} grid {grid} is not available ({why}); heights stay {model} geoid heights. Install proj-data or pass --vertical-datum geoid:FILE"
                    );
                    (format!("{model} geoid heights, NOT converted to ellipsoidal heights (grid {grid} not found)"), None)
                }
            }
        }
    })
}

fn provenance(info: &SourceInfo) -> Result<SourceProvenance, StoreError> {
    let meta = std::fs::metadata(&info.path).map_err(|e| StoreError::new(&info.path, e.to_string()))?;
    let modified =
        meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok()).map_or(0, |d| d.as_secs());
    Ok(SourceProvenance {
        path: info.path.to_string_lossy().into_owned(),
        driver: info.driver.clone(),
        size: info.size,
        data_type: info.data_type.clone(),
        crs_wkt: info.crs_wkt.clone(),
        crs_proj: info.crs_proj.clone(),
        nodata: info.nodata,
        pixel_convention: info.pixel_convention.clone(),
        resolution_m: info.resolution_m,
        bounds_deg: info.bounds_deg,
        file_bytes: meta.len(),
        modified_unix_s: modified,
    })
}

fn same_files(a: &[SourceProvenance], b: &[SourceProvenance]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.path == y.path && x.file_bytes == y.file_bytes && x.modified_unix_s == y.modified_unix_s)
}

/// Runs the levels of one import: computes quads in parallel and writes them from this thread.
struct LevelWriter<'a> {
    store: &'a mut Store,
    dataset: &'a str,
    pool: &'a rayon::ThreadPool,
    /// Quads in flight between the workers and the writer.
    queue: usize,
    progress: bool,
}

impl LevelWriter<'_> {
    /// Computes the candidates of a level that no earlier run finished, committing every 32 quads
    /// or every second. Returns the tiles with data written, the quads an earlier run had
    /// finished, and the quads computed now.
    fn run<W, I, F>(
        &mut self,
        level: u8,
        candidates: HashSet<QuadId>,
        init: I,
        compute: F,
    ) -> Result<(u64, u64, usize), StoreError>
    where
        I: Fn() -> Result<W, StoreError> + Sync,
        F: Fn(&mut W, QuadId) -> Result<Option<QuadGrid>, StoreError> + Sync,
    {
        let finished = self.store.finished_quads(self.dataset, level)?;
        let mut todo: Vec<QuadId> = candidates.into_iter().filter(|q| !finished.contains(q)).collect();
        todo.sort();
        let written = self.write(&todo, &format!("level {level}"), init, compute)?;
        Ok((written, finished.len() as u64, todo.len()))
    }

    fn write<W, I, F>(&mut self, todo: &[QuadId], label: &str, init: I, compute: F) -> Result<u64, StoreError>
    where
        I: Fn() -> Result<W, StoreError> + Sync,
        F: Fn(&mut W, QuadId) -> Result<Option<QuadGrid>, StoreError> + Sync,
    {
        let (store, dataset, pool, queue, progress) =
            (&mut *self.store, self.dataset, self.pool, self.queue, self.progress);
        if todo.is_empty() {
            return Ok(0);
        }
        let bar = if progress { ProgressBar::new(todo.len() as u64) } else { ProgressBar::hidden() };
        bar.set_style(
            ProgressStyle::with_template(
                "{prefix:>9} [{bar:32}] {pos}/{len} tiles  {per_sec}  {elapsed} elapsed, ~{eta} left",
            )
            .expect("a valid template")
            .progress_chars("=> "),
        );
        bar.set_prefix(label.to_owned());
        let stop = AtomicBool::new(false);
        let (tx, rx) = sync_channel::<Result<(QuadId, Option<QuadGrid>), StoreError>>(queue);
        let mut written = 0u64;
        let mut failure = None;
        std::thread::scope(|s| {
            let stop = &stop;
            let init = &init;
            let compute = &compute;
            s.spawn(move || {
                pool.install(|| {
                    todo.par_iter().for_each_init(
                        || init().map_err(|e| e.to_string()),
                        |worker, &q| {
                            if stop.load(Ordering::Relaxed) {
                                return;
                            }
                            let result = match worker {
                                Ok(w) => compute(w, q).map(|g| (q, g)),
                                Err(m) => Err(StoreError::new(Path::new(dataset), m.clone())),
                            };
                            if tx.send(result).is_err() {
                                stop.store(true, Ordering::Relaxed);
                            }
                        },
                    );
                });
                drop(tx);
            });
            let mut batch = Vec::new();
            let mut last = Instant::now();
            let flush = |store: &mut Store, batch: &mut Vec<(QuadId, Option<QuadGrid>)>| -> Result<(), StoreError> {
                store.write_quads(dataset, batch)?;
                batch.clear();
                Ok(())
            };
            for msg in rx.iter() {
                match msg {
                    Ok((q, g)) => {
                        written += u64::from(g.is_some());
                        batch.push((q, g));
                        bar.inc(1);
                        if batch.len() >= 32 || last.elapsed().as_secs_f64() > 1.0 {
                            if let Err(e) = flush(store, &mut batch) {
                                failure = Some(e);
                                break;
                            }
                            last = Instant::now();
                        }
                    }
                    Err(e) => {
                        failure = Some(e);
                        break;
                    }
                }
            }
            if failure.is_some() {
                stop.store(true, Ordering::Relaxed);
                drop(rx);
            } else if let Err(e) = flush(store, &mut batch) {
                failure = Some(e);
            }
        });
        bar.finish_and_clear();
        match failure {
            Some(e) => Err(e),
            None => Ok(written),
        }
    }
}

/// The quads at `level` that a source may cover: under a grid of source points spaced at most
/// a quarter quad apart (edges included), with their eight neighbours.
fn footprint(reader: &SourceReader, body: &Ellipsoid, level: u8) -> Result<HashSet<QuadId>, StoreError> {
    let info = reader.info();
    let (w, h) = (info.size.0 as f64, info.size.1 as f64);
    let quad_m = spacing_m(body, level) * f64::from(TILE);
    let step = (quad_m / 4.0 / info.resolution_m).clamp(0.5, f64::MAX);
    let along = |n: f64| -> Vec<f64> {
        let count = (n / step).ceil().max(1.0) as usize;
        (0..=count).map(|k| n * k as f64 / count as f64).collect()
    };
    let (xs, ys) = (along(w), along(h));
    let mut quads = HashSet::new();
    let mut batch = Vec::with_capacity(1 << 16);
    let flush = |batch: &mut Vec<(f64, f64)>, quads: &mut HashSet<QuadId>| {
        for (lon, lat) in reader.lonlat_of_pixels(batch) {
            if lon.is_finite() {
                let p = CubeProjection::Qsc.face_point_from_geodetic(body, lat.to_radians(), lon.to_radians());
                if let Ok(q) = QuadId::containing(p, level) {
                    quads.insert(q);
                }
            }
        }
        batch.clear();
    };
    for &y in &ys {
        for &x in &xs {
            batch.push((x, y));
            if batch.len() == batch.capacity() {
                flush(&mut batch, &mut quads);
            }
        }
    }
    flush(&mut batch, &mut quads);
    if quads.is_empty() {
        return Err(StoreError::new(&info.path, "none of its pixels lies on the body: is its CRS right?"));
    }
    let mut with_neighbours = quads.clone();
    for q in &quads {
        for e in Edge::ALL {
            let n = q.neighbour(e).quad;
            with_neighbours.insert(n);
            for e2 in [Edge::North, Edge::South] {
                if matches!(e, Edge::East | Edge::West) {
                    with_neighbours.insert(n.neighbour(e2).quad);
                }
            }
        }
    }
    Ok(with_neighbours)
}

/// Resamples one quad's 257² grid from the sources (first source with data wins).
fn resample_quad(
    worker: &mut Worker,
    body: &Ellipsoid,
    plan: &Plan,
    quad: QuadId,
) -> Result<Option<QuadGrid>, StoreError> {
    let k = plan.supersample;
    let n = GRID as usize;
    let mut grid = QuadGrid::empty();
    let j0 = i64::from(quad.y) * i64::from(TILE);
    // Rows of samples in bands, each band's positions computed once and read per source.
    let band_rows = (16_384 / (n * (k * k) as usize)).max(1);
    let mut row = 0usize;
    while row < n {
        let rows = band_rows.min(n - row);
        let (lons, lats) = band_positions(body, quad, j0 + row as i64, rows, k);
        let mut values = vec![f64::NAN; rows * n];
        for reader in &worker.readers {
            if values.iter().all(|v| !v.is_nan()) {
                break;
            }
            let (mut fx, mut fy) = (lons.clone(), lats.clone());
            reader.centre_coords(&mut fx, &mut fy);
            fill_from_source(reader, plan, &fx, &fy, 0, rows, n, k, &mut values)?;
        }
        if let Some(t) = &worker.geoid {
            convert_heights(t, body, quad, j0 + row as i64, rows, &mut values);
        }
        for r in 0..rows {
            for i in 0..n {
                grid.values[(row + r) * n + i] = values[r * n + i] as f32;
            }
        }
        row += rows;
    }
    Ok((!grid.is_empty()).then_some(grid))
}

/// Longitudes and latitudes (degrees) of the sub-sample points of `rows` rows of the quad's
/// 257 samples, starting at global row j0; k×k sub-samples per sample, spread over its cell.
fn band_positions(body: &Ellipsoid, quad: QuadId, j0: i64, rows: usize, k: u32) -> (Vec<f64>, Vec<f64>) {
    let n = GRID as usize;
    let i0 = i64::from(quad.x) * i64::from(TILE);
    let mut lons = Vec::with_capacity(rows * n * (k * k) as usize);
    let mut lats = Vec::with_capacity(lons.capacity());
    let m = grid::intervals_per_face_edge(quad.level) as f64;
    let off = |s: u32| (f64::from(s) + 0.5) / f64::from(k) - 0.5;
    for r in 0..rows {
        for i in 0..n {
            for a in 0..k {
                for b in 0..k {
                    let (x, y) = if k == 1 {
                        face_xy(quad.level, i0 + i as i64, j0 + r as i64)
                    } else {
                        let x = -1.0 + 2.0 * ((i0 + i as i64) as f64 + off(b)) / m;
                        let y = -1.0 + 2.0 * ((j0 + r as i64) as f64 + off(a)) / m;
                        (x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0))
                    };
                    let (lat, lon) = CubeProjection::Qsc
                        .geodetic_from_face_point(body, FacePoint { face: quad.face, x, y })
                        .unwrap_or((f64::NAN, f64::NAN));
                    lons.push(lon.to_degrees());
                    lats.push(lat.to_degrees());
                }
            }
        }
    }
    (lons, lats)
}

/// Interpolates the samples of rows r0..r0 + rows (of `n` samples, k² sub-samples each) that
/// are still NaN, reading the source in windows no larger than the plan's cap (halving the band
/// of rows until the window fits).
#[allow(clippy::too_many_arguments)]
fn fill_from_source(
    reader: &SourceReader,
    plan: &Plan,
    fx: &[f64],
    fy: &[f64],
    r0: usize,
    rows: usize,
    n: usize,
    k: u32,
    values: &mut [f64],
) -> Result<(), StoreError> {
    let kk = (k * k) as usize;
    let info = reader.info();
    let width = info.size.0 as f64;
    let range = r0 * n * kk..(r0 + rows) * n * kk;
    let mut xs: Vec<f64> = fx[range.clone()].to_vec();
    let ys = &fy[range];
    // Unwrap the columns of a 360° source around the band's first valid point.
    if info.wraps
        && let Some(&reference) = xs.iter().find(|v| v.is_finite())
    {
        {
            for x in &mut xs {
                *x -= width * ((*x - reference) / width).round();
            }
        }
    }
    let margin = if plan.resampling == Resampling::Cubic { 2 } else { 1 };
    let bound =
        |v: &[f64], f: fn(f64, f64) -> f64, init: f64| v.iter().filter(|x| x.is_finite()).fold(init, |a, &b| f(a, b));
    let (x_min, x_max) = (bound(&xs, f64::min, f64::INFINITY), bound(&xs, f64::max, f64::NEG_INFINITY));
    let (y_min, y_max) = (bound(ys, f64::min, f64::INFINITY), bound(ys, f64::max, f64::NEG_INFINITY));
    if x_min > x_max {
        return Ok(());
    }
    let (c0, c1) = (x_min.floor() as i64 - margin, x_max.floor() as i64 + margin);
    let (rr0, rr1) = (y_min.floor() as i64 - margin, y_max.floor() as i64 + margin);
    let (h, w) = (info.size.1 as i64, info.size.0 as i64);
    if rr1 < 0 || rr0 >= h || (!info.wraps && (c1 < 0 || c0 >= w)) {
        return Ok(());
    }
    let cols = if info.wraps { (c1 - c0 + 1).min(w) } else { c1.min(w - 1) - c0.max(0) + 1 };
    let bytes = (cols.max(1) * (rr1.min(h - 1) - rr0.max(0) + 1).max(1)) as usize * 8;
    if bytes > plan.window_cap_bytes && rows > 1 {
        let half = rows / 2;
        fill_from_source(reader, plan, fx, fy, r0, half, n, k, values)?;
        return fill_from_source(reader, plan, fx, fy, r0 + half, rows - half, n, k, values);
    }
    let win = reader.window(c0, c1, rr0, rr1)?;
    for s in 0..rows * n {
        let target = &mut values[r0 * n + s];
        if !target.is_nan() {
            continue;
        }
        let mut sum = 0.0;
        let mut count = 0u32;
        for sub in 0..kk {
            let v = interpolate(&win, info.size, info.wraps, xs[s * kk + sub], ys[s * kk + sub], plan.resampling);
            if !v.is_nan() {
                sum += v;
                count += 1;
            }
        }
        if 2 * count as usize >= kk.max(1) && count > 0 {
            *target = sum / f64::from(count);
        }
    }
    Ok(())
}

/// Interpolates a window at fractional pixel-centre coordinates (fx, fy). NaN outside the
/// raster's area; within half a pixel of its edge the edge pixels are extended.
pub fn interpolate(win: &Window, size: (usize, usize), wraps: bool, fx: f64, fy: f64, how: Resampling) -> f64 {
    let (w, h) = (size.0 as f64, size.1 as f64);
    if !(fx.is_finite() && fy.is_finite()) || fy < -0.5 || fy > h - 0.5 || (!wraps && (fx < -0.5 || fx > w - 0.5)) {
        return f64::NAN;
    }
    let col = |c: i64| if wraps { c } else { c.clamp(0, size.0 as i64 - 1) };
    let row = |r: i64| r.clamp(0, size.1 as i64 - 1);
    let px = |c: i64, r: i64| win.get(col(c), row(r));
    match how {
        Resampling::Nearest => px((fx + 0.5).floor() as i64, (fy + 0.5).floor() as i64),
        Resampling::Bilinear => bilinear(&px, fx, fy),
        Resampling::Cubic => {
            let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
            let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
            let (wx, wy) = (keys(tx), keys(ty));
            let mut sum = 0.0;
            for (b, wyb) in wy.iter().enumerate() {
                for (a, wxa) in wx.iter().enumerate() {
                    let v = px(x0 - 1 + a as i64, y0 - 1 + b as i64);
                    if v.is_nan() {
                        return bilinear(&px, fx, fy);
                    }
                    sum += wxa * wyb * v;
                }
            }
            sum
        }
    }
}

fn bilinear(px: &dyn Fn(i64, i64) -> f64, fx: f64, fy: f64) -> f64 {
    let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
    let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
    let mut sum = 0.0;
    let mut weight = 0.0;
    for (dx, dy, wgt) in
        [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
    {
        let v = px(x0 + dx, y0 + dy);
        if !v.is_nan() && wgt > 0.0 {
            sum += wgt * v;
            weight += wgt;
        }
    }
    if weight < 1e-5 { f64::NAN } else { sum / weight }
}

/// Keys' cubic convolution weights (a = −0.5) for the four pixels around a fraction t.
fn keys(t: f64) -> [f64; 4] {
    let a = -0.5;
    let near = |x: f64| ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0;
    let far = |x: f64| ((a * x - 5.0 * a) * x + 8.0 * a) * x - 4.0 * a;
    [far(1.0 + t), near(t), near(1.0 - t), far(2.0 - t)]
}

/// Geoid heights → ellipsoidal heights (h = H + N) through PROJ, at the samples' positions.
fn convert_heights(t: &CoordTransform, body: &Ellipsoid, quad: QuadId, j0: i64, rows: usize, values: &mut [f64]) {
    let (mut xs, mut ys) = band_positions(body, quad, j0, rows, 1);
    let mut zs: Vec<f64> = values.iter().map(|v| if v.is_nan() { 0.0 } else { *v }).collect();
    if t.transform_coords(&mut xs, &mut ys, &mut zs).is_ok() {
        for (v, z) in values.iter_mut().zip(zs) {
            if !v.is_nan() {
                *v = z;
            }
        }
    } else {
        values.iter_mut().for_each(|v| *v = f64::NAN);
    }
}

/// A coarser quad from its level below: each sample the area mean of its cell (weights ¼ ½ ¼
/// per axis over the child samples at and beside it, across quad and face edges), ignoring no
/// data; no data where less than half the cell has data.
pub fn average_quad(reader: &mut GridReader, quad: QuadId) -> Result<Option<QuadGrid>, StoreError> {
    let child = quad.level + 1;
    let (ci0, cj0) = (2 * i64::from(quad.x) * i64::from(TILE), 2 * i64::from(quad.y) * i64::from(TILE));
    let span = 2 * GRID as usize + 1; // child samples −1 ..= 513
    let mut region = vec![f32::NAN; span * span];
    for b in 0..span {
        for a in 0..span {
            region[b * span + a] = reader.sample(quad.face, child, ci0 - 1 + a as i64, cj0 - 1 + b as i64)?;
        }
    }
    let mut grid = QuadGrid::empty();
    // Weights in sixteenths: the full-weighting stencil, and at a cube corner (where a cell has
    // three quadrants, one per face) the same quadrants counted once each, so that the three
    // faces compute the same value.
    const FULL: [[f64; 3]; 3] = [[1.0, 2.0, 1.0], [2.0, 4.0, 2.0], [1.0, 2.0, 1.0]];
    let m = grid::intervals_per_face_edge(quad.level);
    for q in 0..GRID as usize {
        for p in 0..GRID as usize {
            let (ca, cb) = (2 * p + 1, 2 * q + 1);
            let (gi, gj) =
                (i64::from(quad.x) * i64::from(TILE) + p as i64, i64::from(quad.y) * i64::from(TILE) + q as i64);
            let corner = (gi == 0 || gi == m) && (gj == 0 || gj == m);
            let mut w = FULL;
            if corner {
                // sx, sy: steps into the face; the stencil row/column index of (−sx, −sy) etc.
                let (ix, iy) = (if gi == 0 { 0 } else { 2 }, if gj == 0 { 0 } else { 2 });
                w[1][1] = 3.0;
                w[iy][1] = 0.0; // (0, −sy): the same point as (−sx, 0), counted once
                w[iy][ix] = 0.0; // beyond the corner: no such point
            }
            let (mut sum, mut weight) = (0.0, 0.0);
            for (db, row) in w.iter().enumerate() {
                for (da, wgt) in row.iter().enumerate() {
                    let v = region[(cb + db - 1) * span + ca + da - 1];
                    if !v.is_nan() && *wgt > 0.0 {
                        sum += wgt * f64::from(v);
                        weight += wgt / 16.0;
                    }
                }
            }
            if weight >= 0.5 {
                grid.values[q * GRID as usize + p] = (sum / 16.0 / weight) as f32;
            }
        }
    }
    Ok((!grid.is_empty()).then_some(grid))
}
