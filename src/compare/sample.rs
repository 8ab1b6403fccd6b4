//! The samples of a comparison: operands A and B each composed on its own (a layer alone as the
//! project sets it: scale, offset, valid range, extent; shown, `over`, opacity 1; or a group of
//! layers composed by their own blend modes) with the CPU reference on the quads of one level where
//! the datasets among them have tiles; per sample the difference A − B,
//! the area of its cell on the ellipsoid and the slope of B.
//!
//! Each quad's samples i, j ∈ 0..256 are counted, the one whose cell [i, i + 1] × [j, j + 1] it is
//! (as the store's tiles own them), so shared quad edges count once. A cell's area is exact: QSC is
//! equal-area on the sphere, so each cell covers the same solid angle, times the ellipsoid's area
//! per solid angle at the cell's centre ([`cell_area_m2`](crate::ecm::points::cell_area_m2)); on the Moon every weight is the same,
//! on an ellipsoid they differ a little, and `weight_ratio` reports by how much (largest over
//! smallest). (The quadrilateral of a cell's corners, used before, missed by up to 5 % next to a
//! face's centre, where QSC's cells bend.)
//!
//! The slope of B at a sample is measured in the tangent plane (`quad_geometry`).

use std::collections::{BTreeSet, HashSet};
use std::path::PathBuf;

use rayon::prelude::*;
use serde::Serialize;

use super::CompareError;
use super::quad_geometry::{cell_area, lon_lat, quad_points, slope_deg};
use super::spill::{NO_CLASS, Record, Records, Spill};
use super::stats::{Diff, HISTOGRAM_BINS, Histogram, SLOPE_CLASSES_DEG, SlopeClass, Stats, slope_class};
use super::streamed::{Streamed, held_stats, streamed_stats};
use crate::ecm::QuadId;
use crate::ecm::grid::{GRID, spacing_m};
use crate::ecm::points::quad_ball;
use crate::geodesy::GeoBox;
use crate::layers::{LayerSpec, Operand};
use crate::project::Project;
use crate::scene::Scene;
use crate::scene::dataset::DatasetInfo;

/// Samples along a quad edge.
const N: usize = GRID as usize;
/// Most quads a comparison reads at its default level where that level is finer than the
/// datasets' own (an edit, erosion or procedural detail below it, or no dataset at all): the
/// default steps back to a coarser level past it, never below the datasets' finest. A level given
/// explicitly, or the datasets' own finest, is read whatever its size: memory stays bounded
/// (`memory_samples`, the scratch file) and the time grows with the samples.
pub const DEFAULT_QUADS: usize = 4096;
/// Most quads one process lists (their list, ≈ 40 bytes a quad, is what it holds whatever the
/// samples; 2²⁴ quads are 1.1·10¹² samples, days of work on one machine).
pub const LIST_QUADS: usize = 1 << 24;
/// Quads composed at once (memory: 2 × 264 kB each).
const CHUNK: usize = 16;
/// Most differences a comparison holds in memory by default (≈ 1.2 GB at the peak of the
/// statistics, 72 bytes a difference).
pub const MEMORY_SAMPLES: usize = 1 << 24;

/// How samples are weighted.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Weighting {
    /// By the area of each sample's cell on the ellipsoid.
    Area,
    /// Each sample counts once (as xDEM and demcompare count pixels).
    Samples,
}

/// What to compare and how.
#[derive(Clone, Debug)]
pub struct CompareOptions {
    /// The cube map level (default: the coarser dataset's finest level, or finer where an edit,
    /// erosion or procedural layer on either side adds detail below it; see `overlap_quads`).
    pub level: Option<u8>,
    /// Only inside this box (east < west crosses ±180°).
    pub region: Option<GeoBox>,
    /// Sample weights.
    pub weighting: Weighting,
    /// Slope class edges, degrees.
    pub slope_classes_deg: Vec<f64>,
    /// Keep every sample (for `--samples`).
    pub keep_samples: bool,
    /// Most differences held in memory: a comparison that may have more spills them to a
    /// scratch file and reads them back in passes (see [`streamed`](super::streamed)), so its
    /// memory stays bounded (the samples kept for `keep_samples` aside).
    pub memory_samples: usize,
    /// Where that scratch file goes (default: the project's folder).
    pub scratch: Option<PathBuf>,
    /// Counts the quads compared (and stops the comparison when cancelled).
    pub watch: Option<std::sync::Arc<crate::progress::Watch>>,
}

impl Default for CompareOptions {
    fn default() -> CompareOptions {
        CompareOptions {
            level: None,
            region: None,
            weighting: Weighting::Area,
            slope_classes_deg: SLOPE_CLASSES_DEG.to_vec(),
            keep_samples: false,
            memory_samples: MEMORY_SAMPLES,
            scratch: None,
            watch: None,
        }
    }
}

/// One sample of the comparison.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Sample {
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// A − B, metres.
    pub dh_m: f64,
    /// The cell's area, m².
    pub area_m2: f64,
    /// B's slope, degrees (NaN where it has no neighbour with data).
    pub slope_deg: f64,
}

/// The result (field names are the JSON's: scripts rely on them).
#[derive(Clone, Debug, Serialize)]
pub struct Comparison {
    /// Layer A.
    pub a: String,
    /// Layer B (the reference: slopes are its).
    pub b: String,
    /// The level compared.
    pub level: u8,
    /// Mean sample spacing at that level, metres.
    pub spacing_m: f64,
    /// How samples are weighted.
    pub weighting: Weighting,
    /// The area compared (cells with both A and B), km².
    pub area_km2: f64,
    /// Largest over smallest cell area among the compared samples.
    pub weight_ratio: f64,
    /// The statistics.
    #[serde(flatten)]
    pub stats: Stats,
    /// The histogram of dh.
    pub histogram: Histogram,
    /// The statistics per slope class of B.
    pub by_slope: Vec<SlopeClass>,
    /// Every sample, when asked for.
    #[serde(skip)]
    pub samples: Vec<Sample>,
}

/// The quads of `level` where a dataset has tiles (below its finest level, the descendants of its
/// finest tiles).
pub(super) fn quads_at(info: &DatasetInfo, level: u8) -> HashSet<QuadId> {
    let from = level.min(info.finest_level);
    let mut quads: HashSet<QuadId> = info.present.get(from as usize).cloned().unwrap_or_default();
    for _ in from..level {
        quads = quads.iter().filter_map(|q| q.children()).flatten().collect();
    }
    quads
}

/// The project's layer called `name` (not a difference layer: those have no heights).
fn height_layer<'a>(project: &'a Project, name: &str) -> Result<&'a LayerSpec, CompareError> {
    let Some(spec) = project.layers.iter().find(|l| l.name == name) else {
        let known = project.layers.iter().map(|l| l.name.as_str()).collect::<Vec<_>>().join(", ");
        return Err(CompareError::NoLayer { name: name.into(), known });
    };
    if !spec.gives_heights() {
        return Err(CompareError::Option {
            option: name.into(),
            problem: "is a difference layer: it draws A − B and has no heights to compare".into(),
        });
    }
    Ok(spec)
}

/// An operand as the command line names it (`NAME`, or `NAME+NAME…` for a composed group).
pub fn operand(project: &Project, text: &str) -> Operand {
    Operand::parse(text, &|name| project.layers.iter().any(|l| l.name == name))
}

/// Opens an operand: a layer alone (shown, `over`, opacity 1, its other settings as the project
/// has them), or a group's layers in the project's order, shown, with their own blend modes and
/// opacities (the stack's `operand_layers` reads the same).
///
/// The whole project is opened and the other layers hidden (see [`operand_scene`]).
pub fn open_operand(project: &Project, operand: &Operand) -> Result<Scene, CompareError> {
    let (scene, _) = Scene::open(project)?;
    operand_scene(&scene, project, operand)
}

/// An operand's scene from the project's scene, already open ([`Scene::of_operand`]), its names
/// checked first: each a layer of the project with heights.
pub fn operand_scene(scene: &Scene, project: &Project, operand: &Operand) -> Result<Scene, CompareError> {
    for name in &operand.names() {
        height_layer(project, name)?;
    }
    scene.of_operand(operand).map_err(|e| CompareError::Open(e.into()))
}

/// Compares `a` with `b` (the reference) of a project: each a layer or a composed group
/// (`NAME+NAME…`, see [`operand`]).
pub fn compare(project: &Project, a: &str, b: &str, opts: &CompareOptions) -> Result<Comparison, CompareError> {
    compare_operands(project, &operand(project, a), &operand(project, b), opts)
}

/// Compares operand `a` with operand `b` (the reference).
pub fn compare_operands(
    project: &Project,
    a: &Operand,
    b: &Operand,
    opts: &CompareOptions,
) -> Result<Comparison, CompareError> {
    if a == b {
        return Err(CompareError::Option { option: "B".into(), problem: format!("'{a}' compared with itself") });
    }
    let (scene, _) = Scene::open(project)?;
    let (scene_a, scene_b) = (operand_scene(&scene, project, a)?, operand_scene(&scene, project, b)?);
    let (level, quads) = overlap_quads(&scene_a, &scene_b, opts.level, opts.region)?;
    let quads = hilbert_ordered(level, quads);
    let ellipsoid = scene_a.ellipsoid;
    let Differenced { diffs, samples, nodata, area: (area_lo, area_hi) } =
        difference_quads(project, &scene_a, &scene_b, &quads, opts)?;
    super::phase(&opts.watch, "statistics", 0);
    if let Some(region) = opts.region
        && diffs.is_empty()
    {
        return Err(CompareError::Option {
            option: "--region".into(),
            problem: format!(
                "{region}: no sample inside has data in both {a} and {b} (the order is WEST,SOUTH,EAST,NORTH)"
            ),
        });
    }
    let Streamed { stats, histogram, by_slope } = diffs.statistics(nodata)?;
    let mut comparison = Comparison {
        a: a.label(),
        b: b.label(),
        level,
        spacing_m: spacing_m(&ellipsoid, level),
        weighting: opts.weighting,
        area_km2: stats.weight_sum / 1e6,
        weight_ratio: if stats.count == 0 { f64::NAN } else { area_hi / area_lo },
        stats,
        histogram,
        by_slope,
        samples,
    };
    if opts.weighting == Weighting::Samples {
        // The area still says what was compared.
        comparison.area_km2 = f64::NAN;
    }
    Ok(comparison)
}

/// A comparison's differences over some quads, as `compare` samples them.
pub(super) struct Differenced<'a> {
    /// The records, held or spilled.
    pub(super) diffs: Differences<'a>,
    /// Every sample, where the options keep them.
    pub(super) samples: Vec<Sample>,
    /// Samples with data on one side only.
    pub(super) nodata: u64,
    /// The least and the largest cell area compared, m² (∞ and 0 without any).
    pub(super) area: (f64, f64),
}

/// The differences of `quads` (in their order, composed [`CHUNK`] at a time, counted on the
/// options' watch).
pub(super) fn difference_quads<'a>(
    project: &Project,
    scene_a: &Scene,
    scene_b: &Scene,
    quads: &[QuadId],
    opts: &'a CompareOptions,
) -> Result<Differenced<'a>, CompareError> {
    let ellipsoid = scene_a.ellipsoid;
    let mut diffs = Differences::new(project, opts, quads.len() * (N - 1) * (N - 1))?;
    let mut samples = Vec::new();
    let mut nodata = 0u64;
    let (mut area_lo, mut area_hi) = (f64::INFINITY, 0f64);
    super::phase(&opts.watch, "quads", quads.len());
    for chunk in quads.chunks(CHUNK) {
        super::tick(&opts.watch, 0)?;
        let grids_a = scene_a.compose_cpu(chunk)?;
        let grids_b = scene_b.compose_cpu(chunk)?;
        for q in chunk {
            let rows = quad_samples(&ellipsoid, *q, &grids_a[q], &grids_b[q], opts.region, opts.keep_samples);
            for row in rows {
                for s in row {
                    match s {
                        None => {}
                        Some(Err(())) => nodata += 1,
                        Some(Ok(s)) => {
                            area_lo = area_lo.min(s.area_m2);
                            area_hi = area_hi.max(s.area_m2);
                            let weight = if opts.weighting == Weighting::Area { s.area_m2 } else { 1.0 };
                            diffs.push(Diff { dh_m: s.dh_m, weight, slope_deg: s.slope_deg })?;
                            if opts.keep_samples {
                                samples.push(s);
                            }
                        }
                    }
                }
            }
        }
        super::tick(&opts.watch, chunk.len())?;
    }
    Ok(Differenced { diffs, samples, nodata, area: (area_lo, area_hi) })
}

/// A comparison's differences, each with its slope class: in memory, or spilled to a scratch file
/// where there may be more than the options hold in memory. Their statistics are made the same
/// way from either ([`streamed_stats`]).
pub(super) enum Differences<'a> {
    Memory(Vec<Record>, &'a [f64]),
    Spilled(Spill, &'a [f64]),
}

impl<'a> Differences<'a> {
    /// Room for at most `most` differences.
    fn new(project: &Project, opts: &'a CompareOptions, most: usize) -> Result<Differences<'a>, CompareError> {
        let classes = &opts.slope_classes_deg[..];
        if classes.len() > usize::from(NO_CLASS) {
            return Err(CompareError::Option {
                option: "slope classes".into(),
                problem: format!("{} class edges: at most {NO_CLASS}", classes.len()),
            });
        }
        if most <= opts.memory_samples {
            return Ok(Differences::Memory(Vec::new(), classes));
        }
        let dir = opts.scratch.clone().unwrap_or_else(|| project.resolve(std::path::Path::new(".")));
        let spill = Spill::create(&dir).map_err(|e| CompareError::File {
            path: dir.clone(),
            problem: format!("cannot create the comparison's scratch file here: {e}"),
        })?;
        Ok(Differences::Spilled(spill, classes))
    }

    fn push(&mut self, d: Diff) -> Result<(), CompareError> {
        match self {
            Differences::Memory(records, classes) => records.push(record(classes, &d)),
            Differences::Spilled(spill, classes) => {
                spill.push(record(classes, &d)).map_err(|e| spill_error(spill, e))?;
            }
        }
        Ok(())
    }

    fn is_empty(&self) -> bool {
        match self {
            Differences::Memory(records, _) => records.is_empty(),
            Differences::Spilled(spill, _) => spill.is_empty(),
        }
    }

    /// The records, to read in passes.
    pub(super) fn into_records(self) -> Result<Box<dyn Records + 'a>, CompareError> {
        Ok(match self {
            Differences::Memory(records, _) => Box::new(records),
            Differences::Spilled(mut spill, _) => {
                spill.finish().map_err(|e| spill_error(&spill, e))?;
                Box::new(spill)
            }
        })
    }

    /// Their statistics, histogram and slope classes.
    fn statistics(self, nodata: u64) -> Result<Streamed, CompareError> {
        match self {
            Differences::Memory(records, classes) => Ok(held_stats(&records, nodata, classes, HISTOGRAM_BINS)),
            Differences::Spilled(mut spill, classes) => {
                spill.finish().map_err(|e| spill_error(&spill, e))?;
                streamed_stats(&spill, nodata, classes, HISTOGRAM_BINS).map_err(|e| spill_error(&spill, e))
            }
        }
    }
}

/// A difference as a record: its slope class among `classes`.
fn record(classes: &[f64], d: &Diff) -> Record {
    Record { dh_m: d.dh_m, weight: d.weight, class: slope_class(classes, d.slope_deg).map_or(NO_CLASS, |k| k as u8) }
}

fn spill_error(spill: &Spill, e: std::io::Error) -> CompareError {
    CompareError::File { path: spill.path().to_path_buf(), problem: format!("the comparison's scratch file: {e}") }
}

/// Refuses, before any work, a run that holds every sample of `quads` at `bytes_each` bytes a
/// sample (co-registration and the uncertainty do; `compare` does not) where they would take more
/// than `budget` bytes: a clear error naming the level rather than a process the system kills.
pub(super) fn held_samples_fit(
    what: &str,
    level: u8,
    quads: usize,
    bytes_each: usize,
    budget: u64,
) -> Result<(), CompareError> {
    let samples = quads as u64 * ((N - 1) * (N - 1)) as u64;
    let need = samples.saturating_mul(bytes_each as u64);
    if need <= budget {
        return Ok(());
    }
    let gib = |b: u64| b as f64 / f64::from(1u32 << 30);
    Err(CompareError::Option {
        option: "--level".into(),
        problem: format!(
            "{what} holds every sample: up to {samples} at level {level} would take ≈ {:.1} GiB, more than the {:.1} GiB \
             three quarters of this machine's memory allow; choose a coarser level or a region (`compare` alone works in \
             bounded memory)",
            gib(need),
            gib(budget)
        ),
    })
}

/// The quads a fit holds the samples of: all of `quads` where they are at most `most`, else the
/// `most` first in PCG hash order (spread at random over the overlap), in their order.
pub(super) fn fit_quads(quads: &[QuadId], most: usize) -> Vec<QuadId> {
    let most = most.max(1);
    if quads.len() <= most {
        return quads.to_vec();
    }
    let mut order = crate::maths::first_in_hash_order(&(0..quads.len()).collect::<Vec<_>>(), most);
    order.sort_unstable();
    order.into_iter().map(|k| quads[k]).collect()
}

/// Three quarters of the machine's physical memory, bytes (unbounded where it cannot be read).
pub(super) fn memory_budget() -> u64 {
    // SAFETY: sysconf only reads system configuration values.
    let (pages, page) = unsafe { (libc::sysconf(libc::_SC_PHYS_PAGES), libc::sysconf(libc::_SC_PAGESIZE)) };
    if pages <= 0 || page <= 0 {
        return u64::MAX;
    }
    (pages as u64).saturating_mul(page as u64) / 4 * 3
}

/// The level to work at and the quads of it that may reach `region` where every dataset among
/// the two scenes has tiles, in order. By default: the coarser dataset's finest level (finer
/// levels would only upsample it), or finer where an edit, erosion or procedural layer on either
/// side adds detail below that (comparing it coarser would smear it), stepped back from there
/// towards the datasets' finest while it has more than [`DEFAULT_QUADS`]. No level is refused for
/// its size.
pub(super) fn overlap_quads(
    scene_a: &Scene,
    scene_b: &Scene,
    level: Option<u8>,
    region: Option<GeoBox>,
) -> Result<(u8, Vec<QuadId>), CompareError> {
    let datasets: Vec<&DatasetInfo> = scene_a.shown_datasets().into_iter().chain(scene_b.shown_datasets()).collect();
    // Without a dataset on either side (constants, noise, deltas) the operands have data
    // everywhere: the overlap is the whole planet, or the region.
    let finest = datasets.iter().map(|d| d.finest_level).min().unwrap_or(0);
    let ellipsoid = &scene_a.ellipsoid;
    let reaches = |q: &QuadId| {
        region.is_none_or(|b| {
            let (_, (lon, lat), radius_m) = quad_ball(ellipsoid, *q);
            b.may_reach(lon.to_degrees(), lat.to_degrees(), (radius_m / ellipsoid.b_m()).to_degrees())
        })
    };
    // The quads at a level; None where they are more than `most`.
    let at = |level: u8, most: usize| -> Option<BTreeSet<QuadId>> {
        if datasets.is_empty() {
            return quads_reaching(level, &reaches, most);
        }
        let mut quads: Option<HashSet<QuadId>> = None;
        for d in &datasets {
            let here = quads_at(d, level);
            quads = Some(match quads {
                None => here,
                Some(q) => q.intersection(&here).copied().collect(),
            });
        }
        let quads: BTreeSet<QuadId> = quads.unwrap_or_default().into_iter().filter(reaches).collect();
        (quads.len() <= most).then_some(quads)
    };
    let (level, quads) = match level {
        Some(level) if level > finest + 4 && !datasets.is_empty() => {
            return Err(CompareError::Option {
                option: "--level".into(),
                problem: format!("{level} is more than 4 levels below the datasets' finest ({finest})"),
            });
        }
        Some(level) => (level, at(level, LIST_QUADS)),
        None => {
            let added = [scene_a, scene_b]
                .iter()
                .filter_map(|s| s.stack.detail_level(&|i| !s.stack.layers[i].spec.is_data()))
                .max()
                .unwrap_or(0);
            let mut level = added.max(finest);
            loop {
                if level == finest {
                    break (level, at(level, LIST_QUADS));
                }
                match at(level, DEFAULT_QUADS) {
                    Some(quads) => break (level, Some(quads)),
                    None => level -= 1,
                }
            }
        }
    };
    let Some(quads) = quads else {
        return Err(CompareError::Option {
            option: "--level".into(),
            problem: format!(
                "more than {LIST_QUADS} quads at level {level} (over 10¹² samples), more than one process lists: choose a coarser level or a region"
            ),
        });
    };
    Ok((level, quads.into_iter().collect()))
}

/// Quads of one level face by face, each face's along a Hilbert curve: the order a comparison
/// reads them in, and the one a sharded comparison's plan cuts into runs (so its shards joined in
/// order read the records one process reads, in the same order).
pub(super) fn hilbert_ordered(level: u8, quads: impl IntoIterator<Item = QuadId>) -> Vec<QuadId> {
    let mut quads: Vec<QuadId> = quads.into_iter().collect();
    quads.sort_by_key(|q| (q.face, crate::store::shard::hilbert_index(level, q.x, q.y)));
    quads
}

/// The quads of `level` for which `reaches` holds, found down the quadtree from the six faces (a
/// quad's children are looked at only where it reaches); None as soon as there are more than
/// `most` (a quad that reaches has a child that does, so a level past it has as many).
fn quads_reaching(level: u8, reaches: &dyn Fn(&QuadId) -> bool, most: usize) -> Option<BTreeSet<QuadId>> {
    let mut quads: Vec<QuadId> =
        crate::ecm::Face::ALL.iter().map(|&face| QuadId { face, level: 0, x: 0, y: 0 }).filter(reaches).collect();
    for _ in 0..level {
        // One past `most` tells that there are more: the list never grows past it.
        quads =
            quads.iter().filter_map(|q| q.children()).flatten().filter(reaches).take(most.saturating_add(1)).collect();
        if quads.len() > most {
            return None;
        }
    }
    Some(quads.into_iter().collect())
}

/// Whether a point (radians) lies in the region (everywhere without one).
pub(super) fn in_region(region: Option<GeoBox>, lon: f64, lat: f64) -> bool {
    region.is_none_or(|b| b.contains(lon.to_degrees(), lat.to_degrees()))
}

/// A sample's outcome: outside the region or both layers (None), no data on one side (Err), or
/// compared.
type Outcome = Option<Result<Sample, ()>>;

/// The samples of one quad, row by row (rows in parallel; the order is kept). Their longitude and
/// latitude are found only where there is a region to test them against or `locate` asks for
/// them (kept samples); else they are NaN (finding them is a fifth of a comparison's time).
fn quad_samples(
    ellipsoid: &crate::geodesy::Ellipsoid,
    quad: QuadId,
    a: &[f32],
    b: &[f32],
    region: Option<GeoBox>,
    locate: bool,
) -> Vec<Vec<Outcome>> {
    let points = quad_points(ellipsoid, quad);

    (0..N - 1)
        .into_par_iter()
        .map(|j| {
            (0..N - 1)
                .map(|i| {
                    let k = j * N + i;
                    let (lon, lat) =
                        if locate || region.is_some() { lon_lat(ellipsoid, points[k]) } else { (f64::NAN, f64::NAN) };
                    if !in_region(region, lon, lat) {
                        return None;
                    }
                    let (va, vb) = (f64::from(a[k]), f64::from(b[k]));
                    match (va.is_nan(), vb.is_nan()) {
                        (true, true) => return None, // outside both: not part of the comparison
                        (true, false) | (false, true) => return Some(Err(())),
                        (false, false) => {}
                    }
                    let area = cell_area(ellipsoid, quad, &points, i, j);
                    Some(Ok(Sample {
                        lon_deg: lon.to_degrees(),
                        lat_deg: lat.to_degrees(),
                        dh_m: va - vb,
                        area_m2: area,
                        slope_deg: slope_deg(&points, b, i, j),
                    }))
                })
                .collect()
        })
        .collect()
}

/// The range a difference layer draws without a `range_m`: the `percentile` of |A − B| over the
/// operands' overlap, area-weighted, at one level coarser than a comparison's default (a quarter
/// of its samples: a colour range, not a statistic). None where the operands do not overlap.
pub fn difference_range(project: &Project, spec: &LayerSpec) -> Result<Option<f64>, CompareError> {
    let Some([a, b]) = spec.as_difference().map(|d| &d.of) else {
        return Err(CompareError::Option { option: spec.name.clone(), problem: "is not a difference layer".into() });
    };
    let (scene, _) = Scene::open(project)?;
    let (scene_a, scene_b) = (operand_scene(&scene, project, a)?, operand_scene(&scene, project, b)?);
    let (finest, _) = overlap_quads(&scene_a, &scene_b, None, None)?;
    let mut level = finest.saturating_sub(1);
    // Coarser still while the overlap has more quads than a default comparison reads: a colour
    // range, not a statistic.
    while level > 0 && overlap_quads(&scene_a, &scene_b, Some(level), None)?.1.len() > DEFAULT_QUADS {
        level -= 1;
    }
    let opts = CompareOptions { level: Some(level), keep_samples: true, ..CompareOptions::default() };
    let c = compare_operands(project, a, b, &opts)?;
    let mut abs: Vec<(f64, f64)> = c.samples.iter().map(|s| (s.dh_m.abs(), s.area_m2)).collect();
    if abs.is_empty() {
        return Ok(None);
    }
    abs.sort_by(|x, y| x.0.total_cmp(&y.0));
    let p = super::stats::weighted_quantile(&abs, spec.difference_style().percentile / 100.0);
    Ok((p > 0.0).then_some(p))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;
    use crate::geodesy::Ellipsoid;

    #[test]
    fn a_run_that_would_hold_more_samples_than_memory_allows_is_refused_by_level() {
        assert!(held_samples_fit("co-registration", 10, 100, 310, u64::MAX).is_ok());
        assert!(held_samples_fit("co-registration", 10, 100, 310, 100 * 65536 * 310).is_ok());
        let e = held_samples_fit("the uncertainty", 12, 1300, 400, 16 << 30).unwrap_err().to_string();
        assert!(e.starts_with("--level: the uncertainty holds every sample: up to 85196800 at level 12"), "{e}");
        assert!(e.contains("31.7 GiB") && e.contains("16.0 GiB") && e.contains("coarser level or a region"), "{e}");
        assert!(memory_budget() > 1 << 28);
    }

    #[test]
    fn a_level_given_is_read_whatever_its_quads_and_only_a_default_steps_back() {
        let mut project = Project::new("moon");
        project.layers = vec![LayerSpec::constant("a", 1.0), LayerSpec::constant("b", 0.0)];
        let (scene, _) = Scene::open(&project).unwrap();
        let [a, b] =
            [operand(&project, "a"), operand(&project, "b")].map(|o| operand_scene(&scene, &project, &o).unwrap());
        // Level 6 of the whole Moon: 6 · 4⁶ quads, six times the default's.
        let (level, quads) = overlap_quads(&a, &b, Some(6), None).unwrap();
        assert_eq!((level, quads.len()), (6, 6 * 4096));
        assert_eq!(quads.iter().collect::<HashSet<_>>().len(), quads.len());
        // Without a dataset the default is level 0; a region keeps the quads that reach it.
        assert_eq!(overlap_quads(&a, &b, None, None).unwrap().0, 0);
        let region = GeoBox::new(10.0, -5.0, 20.0, 5.0).unwrap();
        let (_, inside) = overlap_quads(&a, &b, Some(7), Some(region)).unwrap();
        assert!(inside.len() > 100 && inside.len() < 6 * 4usize.pow(7) / 20, "{}", inside.len());
        // What one process lists stays bounded: the walk stops one quad past `most`.
        assert!(quads_reaching(13, &|_| true, 1000).is_none());
        assert_eq!(quads_reaching(2, &|_| true, 96).map(|q| q.len()), Some(96));
        assert!(quads_reaching(2, &|_| true, 95).is_none());
    }

    #[test]
    fn cells_tile_the_quad_and_their_areas_sum_to_its_area() {
        let e = Ellipsoid::MOON;
        let quad = QuadId::new(Face::Right, 3, 2, 5).unwrap();
        let flat = vec![0f32; N * N];
        let rows = quad_samples(&e, quad, &flat, &flat, None, false);
        let areas: Vec<f64> = rows.iter().flatten().map(|s| s.unwrap().unwrap().area_m2).collect();
        assert_eq!(areas.len(), 256 * 256);
        // QSC is equal-area on the sphere: on the (spherical) Moon every cell has the same area,
        // 4πR² / (6 · 4³ · 256²).
        let expected = 4.0 * std::f64::consts::PI * e.a_m().powi(2) / (6.0 * 64.0 * 65536.0);
        let (lo, hi) = areas.iter().fold((f64::INFINITY, 0f64), |(l, h), &a| (l.min(a), h.max(a)));
        assert!((lo / expected - 1.0).abs() < 1e-4 && (hi / expected - 1.0).abs() < 1e-4, "{lo} {hi} {expected}");
    }
}
