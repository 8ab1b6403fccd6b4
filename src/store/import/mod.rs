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

use crate::errors::AtField;
use std::collections::HashSet;
use std::path::{Path, PathBuf};

use crate::Invalid;
use std::str::FromStr;
use std::time::Instant;

use gdal::spatial_ref::{CoordTransform, SpatialRef};

mod levels;
pub(super) use levels::LevelWriter;

use super::StoreError;
use super::gpkg::{DatasetRecord, DatasetSettings, SourceProvenance, Store, check_dataset_name, face_proj, utc_now};
use super::lattice::{LatticeStats, Transform};
use super::read::GridReader;
pub use super::resample::Resampling;
use super::resample::{Plan, Worker, average_quad, footprint, resample_quad};
use super::source::{SourceInfo, SourceReader};
use super::watch::ImportWatch;
use crate::ecm::grid::{self, GRID, spacing_m};
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;

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
    type Err = Invalid;
    fn from_str(s: &str) -> Result<Self, Invalid> {
        match s {
            "unspecified" => Ok(VerticalDatum::Unspecified),
            "ellipsoidal" | "ellipsoid" => Ok(VerticalDatum::Ellipsoidal),
            "egm96" => Ok(VerticalDatum::Geoid { model: "EGM96".into(), grid: "egm96_15.gtx".into() }),
            "egm2008" => Ok(VerticalDatum::Geoid { model: "EGM2008".into(), grid: "egm08_25.gtx".into() }),
            other => match other.strip_prefix("geoid:") {
                Some(path) if !path.is_empty() => {
                    let p = Path::new(path);
                    let grid = std::fs::canonicalize(p).at_field(format_args!("geoid grid {path}"))?;
                    Ok(VerticalDatum::Geoid {
                        model: format!("geoid grid {path}"),
                        grid: grid.to_string_lossy().into_owned(),
                    })
                }
                _ => Err(format!(
                    "unknown vertical datum '{s}': use ellipsoidal, egm96, egm2008, geoid:GRIDFILE or unspecified"
                )
                .into()),
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
    type Err = Invalid;
    fn from_str(s: &str) -> Result<Self, Invalid> {
        if s == "auto" {
            return Ok(LevelChoice::Auto);
        }
        match s.parse::<u8>() {
            Ok(l) if l <= crate::ecm::MAX_LEVEL => Ok(LevelChoice::Level(l)),
            _ => Err(format!("level '{s}' is not auto or a level 0–30").into()),
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
    /// How sample positions in the sources are computed.
    pub transform: Transform,
    /// Vertical datum of the source heights.
    pub vertical: VerticalDatum,
    /// Memory budget in bytes (GDAL cache, windows, tiles in flight).
    pub memory_budget: u64,
    /// Worker threads (default: all cores).
    pub threads: Option<usize>,
    /// Draw a progress bar (on a terminal).
    pub progress: bool,
    /// Report progress to, and take a cancel from, another thread (e.g. a window).
    pub watch: Option<std::sync::Arc<ImportWatch>>,
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
    /// How sample positions were found (lattices per spacing, exact quads or blocks, split
    /// quads, the largest error measured at a lattice cell's centre).
    pub lattice: super::lattice::LatticeSummary,
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

fn geoid_transform(grid: &str, source: &Path) -> Result<CoordTransform, StoreError> {
    let proj = |e| StoreError::caused(source, format!("geoid grid {grid}"), e);
    let from = SpatialRef::from_proj4(&format!("+proj=longlat +datum=WGS84 +geoidgrids={grid} +vunits=m +no_defs"))
        .map_err(proj)?;
    // The target must be 3-D (ellipsoidal height): to a 2-D CRS PROJ drops the vertical step.
    let to = SpatialRef::from_epsg(4979).map_err(proj)?;
    let mut from = from;
    let mut to = to;
    from.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    to.set_axis_mapping_strategy(gdal::spatial_ref::AxisMappingStrategy::TraditionalGisOrder);
    let t = CoordTransform::new(&from, &to).map_err(proj)?;
    // A grid that PROJ cannot find either fails here or leaves heights unchanged.
    let (mut x, mut y, mut z) = ([0.0], [0.0], [0.0]);
    t.transform_coords(&mut x, &mut y, &mut z).map_err(proj)?;
    if !(z[0].is_finite() && z[0] != 0.0) {
        return Err(StoreError::new(source, format!("PROJ found no geoid grid {grid}")));
    }
    Ok(t)
}

/// What an import decided before touching a store: the sources checked, the dataset's name,
/// level and settings, and how to resample.
pub(in crate::store) struct Prepared {
    pub(in crate::store) infos: Vec<SourceInfo>,
    pub(in crate::store) name: String,
    pub(in crate::store) level: u8,
    pub(in crate::store) plan: Plan,
    pub(in crate::store) settings: DatasetSettings,
    pub(in crate::store) provenance: Vec<SourceProvenance>,
    pub(in crate::store) vertical_text: String,
    pub(in crate::store) threads: usize,
    pub(in crate::store) budget: u64,
}

/// Runs an import. See the module documentation for the steps.
pub fn import(opts: &ImportOptions) -> Result<ImportReport, StoreError> {
    let prepared = prepare(opts)?;
    if let Some(report) = already_complete(&opts.store, &opts.body, &prepared)? {
        return Ok(report);
    }
    let mut store = open_dataset(&opts.store, &opts.body, &prepared)?;
    let body = *store.body();
    let mut report = ImportReport {
        dataset: prepared.name.clone(),
        finest_level: prepared.level,
        vertical_datum: prepared.vertical_text.clone(),
        ..Default::default()
    };
    let pool = worker_pool(&opts.store, prepared.threads)?;
    let mut levels =
        LevelWriter::new(&mut store, &prepared.name, &pool, prepared.budget, opts.progress, opts.watch.as_deref());

    // 3. The finest level from the sources.
    let start = Instant::now();
    let candidates = candidates(&prepared, &body)?;
    let (written, finished, computed) = finest_level(&mut levels, &prepared, &body, candidates)?;
    report.levels.push((prepared.level, written, finished));
    report.finest_samples = computed as u64 * u64::from(GRID * GRID);
    report.seconds_finest = start.elapsed().as_secs_f64();
    report.lattice = prepared.plan.lattice.summary();

    // 4. The pyramid.
    let start = Instant::now();
    if !opts.finest_only {
        report.levels.extend(pyramid(&mut levels, &opts.store, prepared.level)?);
        levels.store.mark_complete(&prepared.name)?;
    }
    report.seconds_pyramid = start.elapsed().as_secs_f64();
    report.peak_rss_bytes = peak_rss_bytes();
    Ok(report)
}

/// Step 1: checks every source and decides the dataset's name, level and settings, without
/// touching the store.
pub(in crate::store) fn prepare(opts: &ImportOptions) -> Result<Prepared, StoreError> {
    if opts.sources.is_empty() {
        return Err(StoreError::new(&opts.store, "no source rasters given"));
    }
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
        .map_err(|e| StoreError::caused(&opts.store, "cannot set the GDAL cache", e))?;
    let plan = Plan {
        supersample,
        resampling: opts.resampling,
        transform: opts.transform,
        lattice: LatticeStats::default(),
        window_cap_bytes: (budget / (4 * threads as u64)) as usize,
        geoid_grid: geoid_grid.clone(),
    };
    let settings = DatasetSettings {
        sources: infos.iter().map(|i| i.path.to_string_lossy().into_owned()).collect(),
        finest_level: level,
        resampling: opts.resampling.name().into(),
        supersample,
        transform: opts.transform.name().into(),
        vertical_datum: vertical_text.clone(),
        geoid_grid,
    };
    let provenance: Vec<SourceProvenance> = infos.iter().map(provenance).collect::<Result<_, _>>()?;
    Ok(Prepared { infos, name, level, plan, settings, provenance, vertical_text, threads, budget })
}

/// The report of an import that has nothing to do: the store holds the dataset, complete, from
/// the same sources and settings. An existing store is read read-only here, so that a refusal
/// leaves it byte for byte.
pub(in crate::store) fn already_complete(
    path: &Path,
    body: &Ellipsoid,
    p: &Prepared,
) -> Result<Option<ImportReport>, StoreError> {
    if !path.exists() {
        return Ok(None);
    }
    let existing = Store::open_read_only(path)?;
    check_body(path, existing.body(), body)?;
    Ok(match existing.dataset(&p.name)? {
        Some(d)
            if d.completed.is_some()
                && d.settings.same_samples(&p.settings)
                && same_files(&d.sources, &p.provenance) =>
        {
            Some(ImportReport {
                dataset: p.name.clone(),
                finest_level: p.level,
                vertical_datum: p.vertical_text.clone(),
                already_complete: true,
                peak_rss_bytes: peak_rss_bytes(),
                ..Default::default()
            })
        }
        _ => None,
    })
}

/// Refuses a store of another body.
pub(in crate::store) fn check_body(path: &Path, found: &Ellipsoid, wanted: &Ellipsoid) -> Result<(), StoreError> {
    if found.a_m() != wanted.a_m() || found.b_m() != wanted.b_m() {
        return Err(StoreError::new(
            path,
            format!("is a store of body {found}, not {wanted}: use another store for this body"),
        ));
    }
    Ok(())
}

/// Step 2: opens or creates the store and registers the dataset, or resumes it when the store has it
/// from the same sources and settings.
pub(in crate::store) fn open_dataset(path: &Path, body: &Ellipsoid, p: &Prepared) -> Result<Store, StoreError> {
    let mut store = if path.exists() { Store::open(path)? } else { Store::create(path, body)? };
    check_body(path, store.body(), body)?;
    let name = &p.name;
    match store.dataset(name)? {
        Some(existing)
            if !existing.settings.same_samples(&p.settings) || !same_files(&existing.sources, &p.provenance) =>
        {
            return Err(StoreError::new(
                path,
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
                    SpatialRef::from_proj4(&face_proj(body, f))
                        .and_then(|s| s.to_wkt())
                        .map_err(|e| StoreError::caused(path, "PROJ has no QSC CRS", e))
                })
                .collect::<Result<_, _>>()?;
            let wkt: [String; 6] = wkt.try_into().expect("six faces");
            let record = DatasetRecord {
                name: name.clone(),
                settings: p.settings.clone(),
                sources: p.provenance.clone(),
                created: utc_now(),
                completed: None,
            };
            store.add_dataset(&record, &wkt)?;
        }
    }
    Ok(store)
}

/// The worker threads of an import.
pub(in crate::store) fn worker_pool(path: &Path, threads: usize) -> Result<rayon::ThreadPool, StoreError> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| StoreError::caused(path, "cannot start worker threads", e))
}

/// Step 3a: the quads of the finest level the sources may cover (each source's footprint).
pub(in crate::store) fn candidates(p: &Prepared, body: &Ellipsoid) -> Result<HashSet<QuadId>, StoreError> {
    let mut candidates = HashSet::new();
    for info in &p.infos {
        candidates.extend(footprint(&SourceReader::new(info, body)?, body, p.level)?);
    }
    Ok(candidates)
}

/// Step 3b: resamples the given quads of the finest level that no earlier run finished. Returns
/// the tiles with data written, the quads an earlier run had finished and those computed now.
pub(in crate::store) fn finest_level(
    levels: &mut LevelWriter,
    p: &Prepared,
    body: &Ellipsoid,
    candidates: HashSet<QuadId>,
) -> Result<(u64, u64, usize), StoreError> {
    levels.run(
        p.level,
        candidates,
        || {
            let readers = p.infos.iter().map(|i| SourceReader::new(i, body)).collect::<Result<Vec<_>, _>>()?;
            let geoid = match &p.plan.geoid_grid {
                Some(g) => Some(geoid_transform(g, &p.infos[0].path)?),
                None => None,
            };
            Ok(Worker { readers, geoid })
        },
        |w: &mut Worker, q| resample_quad(w, body, &p.plan, q),
    )
}

/// Step 4: the coarser levels down to 0, each from the level below in the store. Returns per level
/// the tiles written and those an earlier run had finished.
pub(in crate::store) fn pyramid(
    levels: &mut LevelWriter,
    path: &Path,
    finest: u8,
) -> Result<Vec<(u8, u64, u64)>, StoreError> {
    let name = levels.dataset;
    let mut out = Vec::new();
    for parent_level in (0..finest).rev() {
        let children = levels.store.data_quads(name, parent_level + 1)?;
        let parents: HashSet<QuadId> = children.iter().filter_map(|q| q.parent()).collect();
        let (written, finished, _) = levels.run(
            parent_level,
            parents,
            || GridReader::new(Store::open_read_only(path)?, name),
            |r: &mut GridReader, q| average_quad(r, q),
        )?;
        out.push((parent_level, written, finished));
    }
    Ok(out)
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
            match geoid_transform(grid, &infos[0].path) {
                Ok(_) => (format!("ellipsoidal: converted from {model} geoid heights with PROJ grid {grid}"), Some(grid.clone())),
                Err(why) => (
                    format!(
                        "{model} geoid heights, NOT converted to ellipsoidal heights: grid {grid} is not available \
                         ({}); install proj-data or pass --vertical-datum geoid:FILE",
                        crate::errors::chain(&why)
                    ),
                    None,
                ),
            }
        }
    })
}

fn provenance(info: &SourceInfo) -> Result<SourceProvenance, StoreError> {
    let meta = std::fs::metadata(&info.path).map_err(|e| StoreError::caused(&info.path, "cannot read", e))?;
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

pub(in crate::store) fn same_files(a: &[SourceProvenance], b: &[SourceProvenance]) -> bool {
    a.len() == b.len()
        && a.iter()
            .zip(b)
            .all(|(x, y)| x.path == y.path && x.file_bytes == y.file_bytes && x.modified_unix_s == y.modified_unix_s)
}
