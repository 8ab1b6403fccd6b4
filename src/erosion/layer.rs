//! The erosion layer: its operations applied in order to a raster of height changes (the same
//! sparse 257² tiles as an edit layer's, [`EditRaster`], at the operations' level). Each run
//! reads the terrain below the layer plus the changes of the runs before it over its region,
//! erodes it (on the CPU reference or the GPU, through a [`Stepper`]) and adds the change of
//! height to the region's tiles. A sample shared by two quads (their common edge, across a face
//! edge too) gets the one value of the cell that holds it, so the tiles meet without a crack.

use std::collections::{BTreeSet, HashMap};
use std::time::Instant;

use glam::DVec3;

use super::grid::Grid;
use super::landscape::Evolution;
use super::operation::{BrushPath, Model, Operation};
use super::region::Region;
use super::sim::Run;
use crate::ecm::grid::{GRID, TILE, fold_sample, intervals_per_face_edge};
use crate::ecm::points::sample_point;
use crate::ecm::{Face, QuadId};
use crate::edit::EditRaster;
use crate::edit::terrain::{Below, KeptBelow};
use crate::errors::{Failure, SharedFailure};
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};
use crate::maths::{segment_distance_m, smoothstep};
use crate::progress::Watch;

const N: usize = GRID as usize;

/// What takes a run's steps: the CPU reference or the GPU.
pub trait Stepper {
    /// `cpu` or `gpu`.
    fn device(&self) -> super::operation::Device;
    /// The run after `steps` more steps, counted on `watch` as they are taken; stops with
    /// [`crate::progress::Cancelled`] as the error when `watch` is cancelled.
    fn run(&self, run: Run, steps: u64, watch: &Watch) -> Result<Run, Failure>;
}

/// The CPU reference.
pub struct CpuStepper;

impl Stepper for CpuStepper {
    fn device(&self) -> super::operation::Device {
        super::operation::Device::Cpu
    }

    fn run(&self, mut run: Run, steps: u64, watch: &Watch) -> Result<Run, Failure> {
        for _ in 0..steps {
            watch.check()?;
            run.step();
            watch.advance();
        }
        Ok(run)
    }
}

/// An operation that cannot be run: its index, the field and the problem.
#[derive(Debug, Clone, thiserror::Error)]
#[error("runs[{index}]: {field}: {problem}")]
pub struct OperationError {
    /// The operation's index in the layer.
    pub index: usize,
    /// The field.
    pub field: String,
    /// What is wrong.
    pub problem: String,
    /// What failed under it (reading the terrain below, the device), if anything did.
    #[source]
    pub cause: Option<SharedFailure>,
}

/// What a run did.
#[derive(Clone, Debug)]
pub struct Outcome {
    /// The region it ran on.
    pub region: Region,
    /// Steps taken.
    pub steps: u64,
    /// Simulated time, seconds.
    pub simulated_s: f64,
    /// The smallest and largest step taken (the CFL bound's work), seconds.
    pub dt_range_s: (f64, f64),
    /// The step asked for, seconds.
    pub dt_asked_s: f64,
    /// Water the budget does not explain, over the water that entered.
    pub water_unexplained_rel: f64,
    /// Soil the budget does not explain, over the soil moved.
    pub soil_unexplained_rel: f64,
    /// Water that left through open borders and sinks, m³.
    pub water_out_m3: f64,
    /// Soil that left with it, m³.
    pub soil_out_m3: f64,
    /// Rain that fell, m³.
    pub rain_m3: f64,
    /// Water the run started with (its rain at steady state, or 0), m³.
    pub start_water_m3: f64,
    /// Sediment the water still carries when the run stops (neither laid down nor gone out; not
    /// part of the terrain), m³.
    pub suspended_m3: f64,
    /// The terrain's change of volume, m³: Σ Δh × cell area over the region (exact: the fixed
    /// point's units of soil taken or laid), negative where material left the region.
    pub volume_change_m3: f64,
    /// Terrain removed where the run lowered it, m³ (≥ 0).
    pub eroded_m3: f64,
    /// Terrain laid down where the run raised it, m³ (≥ 0).
    pub deposited_m3: f64,
    /// Wall-clock time of the run (not counting reading the terrain), seconds.
    pub seconds: f64,
    /// The smallest and largest change of height, metres.
    pub range_m: (f64, f64),
    /// A stream-power run's figures (None for a hydraulic one).
    pub landscape: Option<super::landscape::LandscapeOutcome>,
    /// The quads whose tiles changed.
    pub quads: BTreeSet<QuadId>,
}

/// The raster of `ops` in order (each checked first), by the CPU reference.
pub fn build(ellipsoid: Ellipsoid, ops: &[Operation], below: &Below) -> Result<EditRaster, OperationError> {
    build_with(ellipsoid, ops, below, &CpuStepper, &Watch::default())
}

/// [`build`] with another stepper (the GPU's), each run's steps counted on `watch` (a phase a
/// run) and stopped when it is cancelled.
pub fn build_with(
    ellipsoid: Ellipsoid,
    ops: &[Operation],
    below: &Below,
    stepper: &dyn Stepper,
    watch: &Watch,
) -> Result<EditRaster, OperationError> {
    let level = ops.first().map_or(0, |o| o.level);
    let mut raster = EditRaster::new(ellipsoid, level);
    let kept = KeptBelow::new(below);
    for (index, op) in ops.iter().enumerate() {
        apply(&mut raster, index, op, &|q| kept.get(q), stepper, watch)?;
    }
    Ok(raster)
}

/// Runs `op` (the layer's operation `index`) and adds its change of height to `raster`, keeping
/// the tiles it replaced for undo. Its steps are counted on `watch` (phase `run N`); a cancel
/// stops it between steps with the error's field `steps` and leaves `raster` as it was.
pub fn apply(
    raster: &mut EditRaster,
    index: usize,
    op: &Operation,
    below: &Below,
    stepper: &dyn Stepper,
    watch: &Watch,
) -> Result<Outcome, OperationError> {
    let cancelled = |e: Failure| OperationError {
        index,
        field: "steps".into(),
        problem: "the run was cancelled".into(),
        cause: Some(e.into()),
    };
    if let Some(params) = op.stream_power.as_ref().filter(|_| op.model == Model::StreamPower) {
        let (region, grid) = prepare_grid(raster, index, op, below)?;
        let t = Instant::now();
        let mut run = Evolution::new(grid, params.clone()).map_err(|e| OperationError {
            index,
            field: format!("stream_power.{}", e.field),
            problem: e.problem,
            cause: None,
        })?;
        watch.start_phase(&format!("run {index}"), params.steps());
        while !run.done() {
            watch.check().map_err(|e| cancelled(e.into()))?;
            run.step();
            watch.advance();
        }
        return Ok(finish_landscape(raster, index, region, &run, t.elapsed().as_secs_f64()));
    }
    let (region, run) = prepare(raster, index, op, below)?;
    let t = Instant::now();
    watch.start_phase(&format!("run {index}"), op.steps);
    let run = stepper.run(run, op.steps, watch).map_err(|e| {
        if e.is::<crate::progress::Cancelled>() {
            return cancelled(e);
        }
        OperationError { index, field: "device".into(), problem: "the run failed".into(), cause: Some(e.into()) }
    })?;
    Ok(finish(raster, index, region, &run, t.elapsed().as_secs_f64()))
}

/// The run of `op` before its first step: its region, and the grid of the terrain below the
/// layer plus the runs before it (`raster`), with the brush's masks. `raster` moves to the
/// operation's level when it has no tiles yet.
pub fn prepare(
    raster: &mut EditRaster,
    index: usize,
    op: &Operation,
    below: &Below,
) -> Result<(Region, Run), OperationError> {
    let err = |field: &str, problem: String| OperationError { index, field: field.into(), problem, cause: None };
    if op.model != Model::Hydraulic {
        return Err(err("model", format!("{} runs are taken whole (`apply`), not step by step", op.model.name())));
    }
    let (region, grid) = prepare_grid(raster, index, op, below)?;
    let run = Run::new(grid, op.params.clone()).map_err(|p| err(&format!("params.{}", p.field), p.to_string()))?;
    Ok((region, run.with_seed(op.seed)))
}

/// The region of `op` and its grid: the terrain below the layer plus the runs before it, with
/// the brush's masks.
fn prepare_grid(
    raster: &mut EditRaster,
    index: usize,
    op: &Operation,
    below: &Below,
) -> Result<(Region, Grid), OperationError> {
    let err = |field: &str, problem: String| OperationError { index, field: field.into(), problem, cause: None };
    op.check().map_err(|e| err(&e.field, e.problem))?;
    if raster.level != op.level && !raster.tiles.is_empty() {
        return Err(err(
            "level",
            format!("{} differs from the layer's {} (one erosion layer erodes at one level)", op.level, raster.level),
        ));
    }
    if raster.level != op.level {
        let mut fresh = EditRaster::new(raster.ellipsoid, op.level);
        fresh.succeed(raster);
        *raster = fresh;
    }
    let e = raster.ellipsoid;
    let region = Region::from_box(&e, op.region, op.level).map_err(|p| err("region", p.0))?;
    // The terrain as the run finds it: below the layer, plus the runs before.
    let heights = |q: QuadId| -> Result<Vec<f32>, Failure> {
        let mut h = below(q)?;
        if let Some(d) = raster.tile(q) {
            for (h, d) in h.iter_mut().zip(d) {
                *h += d;
            }
        }
        Ok(h)
    };
    let mut grid = region.grid(&e, &heights).map_err(|e| OperationError {
        index,
        field: "terrain below".into(),
        problem: "cannot be read".into(),
        cause: Some(e.into()),
    })?;
    // A box where the stack has no data (often one given in the wrong order) changes nothing.
    if grid.base_m.iter().all(|h| h.is_nan()) {
        return Err(err(
            "region",
            format!("the layers below have no data in {} (WEST,SOUTH,EAST,NORTH): nothing to erode", op.region),
        ));
    }
    if let Some(brush) = &op.brush {
        let mask = brush_mask(&e, &region, brush);
        grid.rain_mask = Some(mask.clone());
        grid.erosion_mask = Some(mask);
    }
    Ok((region, grid))
}

/// The tiles of `raster` over `region` with the change of height `run` has made so far added
/// (what the layer would hold if the run stopped now).
pub fn tiles_with(raster: &EditRaster, region: &Region, run: &Run) -> Vec<(QuadId, Vec<f32>)> {
    let base = |q: QuadId| raster.tile(q).map_or_else(|| vec![0.0f32; N * N], <[f32]>::to_vec);
    let add = |t: f32, d: f64| if d.is_finite() { (f64::from(t) + d) as f32 } else { t };
    tiles_of(&raster.ellipsoid, region, &run.delta_m(), &base, &add)
}

/// One value per cell of `region` as a raster at the region's level (NaN cells: no data): what
/// the workstation drapes over the terrain while a run goes on (water depth, sediment).
pub fn field_raster(e: Ellipsoid, region: &Region, values: &[f64]) -> EditRaster {
    let base = |_: QuadId| vec![f32::NAN; N * N];
    let put = |t: f32, v: f64| if v.is_finite() { v as f32 } else { t };
    EditRaster::from_tiles(e, region.level, tiles_of(&e, region, values, &base, &put).into_iter().collect())
}

/// Adds a finished run's change of height to `raster` as operation `index` (its before-images
/// kept for undo); `seconds` is the time its steps took.
pub fn finish(raster: &mut EditRaster, index: usize, region: Region, run: &Run, seconds: f64) -> Outcome {
    let tiles = tiles_with(raster, &region, run);
    let mut range = (0f64, 0f64);
    for d in run.delta_m().iter().filter(|d| d.is_finite()) {
        range = (range.0.min(*d), range.1.max(*d));
    }
    let quads: BTreeSet<QuadId> = tiles.iter().map(|(q, _)| *q).collect();
    raster.apply_tiles(index, tiles);
    let unit = run.unit_m3();
    let (water_left, soil_left) = run.unexplained();
    let b = run.budget;
    let moved: i64 =
        run.state.soil.iter().map(|s| s.abs()).sum::<i64>() + run.state.sediment.iter().sum::<i64>() + b.soil_out;
    Outcome {
        region,
        steps: run.steps,
        simulated_s: run.simulated_s,
        dt_range_s: run.dt_range_s,
        dt_asked_s: run.params.dt_s,
        water_unexplained_rel: water_left.abs() as f64 / (b.start_water + b.rain_in).max(1) as f64,
        soil_unexplained_rel: soil_left.abs() as f64 / moved.max(1) as f64,
        water_out_m3: b.water_out as f64 * unit,
        soil_out_m3: b.soil_out as f64 * unit,
        rain_m3: b.rain_in as f64 * unit,
        start_water_m3: b.start_water as f64 * unit,
        suspended_m3: run.state.sediment.iter().sum::<i64>() as f64 * unit,
        volume_change_m3: run.state.soil.iter().sum::<i64>() as f64 * unit,
        eroded_m3: -(run.state.soil.iter().filter(|s| **s < 0).sum::<i64>() as f64) * unit,
        deposited_m3: run.state.soil.iter().filter(|s| **s > 0).sum::<i64>() as f64 * unit,
        seconds,
        range_m: range,
        landscape: None,
        quads,
    }
}

/// Adds a finished stream-power run's change of height to `raster` as operation `index`.
fn finish_landscape(raster: &mut EditRaster, index: usize, region: Region, run: &Evolution, seconds: f64) -> Outcome {
    let delta = run.delta_m();
    let base = |q: QuadId| raster.tile(q).map_or_else(|| vec![0.0f32; N * N], <[f32]>::to_vec);
    let add = |t: f32, d: f64| if d.is_finite() { (f64::from(t) + d) as f32 } else { t };
    let tiles = tiles_of(&raster.ellipsoid, &region, &delta, &base, &add);
    let range = delta.iter().filter(|d| d.is_finite()).fold((0f64, 0f64), |r, d| (r.0.min(*d), r.1.max(*d)));
    let quads: BTreeSet<QuadId> = tiles.iter().map(|(q, _)| *q).collect();
    raster.apply_tiles(index, tiles);
    let figures = run.outcome();
    let year_s = super::landscape::YEAR_S;
    let dt_s = run.params.dt_years * year_s;
    Outcome {
        region,
        steps: run.steps,
        simulated_s: run.years * year_s,
        dt_range_s: (dt_s, dt_s),
        dt_asked_s: dt_s,
        water_unexplained_rel: 0.0,
        soil_unexplained_rel: figures.unexplained_rel,
        water_out_m3: 0.0,
        soil_out_m3: figures.outflow_m3,
        rain_m3: 0.0,
        start_water_m3: 0.0,
        suspended_m3: 0.0,
        volume_change_m3: run.change.iter().sum::<i64>() as f64 * run.unit_m3(),
        eroded_m3: figures.eroded_m3,
        deposited_m3: figures.deposited_m3,
        seconds,
        range_m: range,
        landscape: Some(figures),
        quads,
    }
}

/// The brush's mask per cell: 1 within half the radius of the path, smoothly 0 at the radius.
fn brush_mask(e: &Ellipsoid, region: &Region, brush: &BrushPath) -> Vec<f64> {
    let points: Vec<DVec3> = brush
        .points
        .iter()
        .map(|p| {
            ecef_from_geodetic(e, Geodetic { lat_rad: p[0].to_radians(), lon_rad: p[1].to_radians(), height_m: 0.0 })
        })
        .collect();
    let r = brush.radius_m;
    let mut mask = vec![0.0; region.width * region.height];
    for y in 0..region.height {
        for x in 0..region.width {
            let Some(c) = region.cell(x, y) else { continue };
            let p = sample_point(e, c.quad, GRID, c.i, c.j).0;
            let d = if points.len() == 1 {
                (p - points[0]).length()
            } else {
                points.windows(2).map(|w| segment_distance_m(p, w[0], w[1])).fold(f64::INFINITY, f64::min)
            };
            mask[y * region.width + x] = 1.0 - smoothstep((d - 0.5 * r) / (0.5 * r));
        }
    }
    mask
}

/// The tiles of the region's quads, each from `base` with every one of its 257² samples
/// combined with the value of the cell that holds it (a sample on a face edge, held by the
/// adjacent face's cell, is found by its position).
fn tiles_of(
    e: &Ellipsoid,
    region: &Region,
    values: &[f64],
    base: &dyn Fn(QuadId) -> Vec<f32>,
    combine: &dyn Fn(f32, f64) -> f32,
) -> Vec<(QuadId, Vec<f32>)> {
    let level = region.level;
    let m = intervals_per_face_edge(level);
    let mut by_sample: HashMap<(Face, i64, i64), usize> = HashMap::new();
    let mut on_edges: HashMap<[i64; 3], usize> = HashMap::new();
    let key = |p: DVec3| [(p.x * 100.0).round() as i64, (p.y * 100.0).round() as i64, (p.z * 100.0).round() as i64];
    for y in 0..region.height {
        for x in 0..region.width {
            let Some((f, i, j)) = fold_sample(region.face, level, region.i0 + x as i64, region.j0 + y as i64) else {
                continue;
            };
            let k = y * region.width + x;
            by_sample.insert((f, i, j), k);
            if i == 0 || j == 0 || i == m || j == m {
                let c = region.cell(x, y).expect("folded above");
                on_edges.insert(key(sample_point(e, c.quad, GRID, c.i, c.j).0), k);
            }
        }
    }
    let find_on_edge = |p: DVec3| -> Option<usize> {
        let k = key(p);
        for dx in -1..=1 {
            for dy in -1..=1 {
                for dz in -1..=1 {
                    if let Some(c) = on_edges.get(&[k[0] + dx, k[1] + dy, k[2] + dz]) {
                        return Some(*c);
                    }
                }
            }
        }
        None
    };
    let tile = i64::from(TILE);
    region
        .quads()
        .into_iter()
        .map(|q| {
            let mut t = base(q);
            for j in 0..N {
                for i in 0..N {
                    let (gi, gj) = (i64::from(q.x) * tile + i as i64, i64::from(q.y) * tile + j as i64);
                    let cell = by_sample.get(&(q.face, gi, gj)).copied().or_else(|| {
                        let edge = gi == 0 || gj == 0 || gi == m || gj == m;
                        edge.then(|| find_on_edge(sample_point(e, q, GRID, i as u32, j as u32).0)).flatten()
                    });
                    if let Some(c) = cell {
                        t[j * N + i] = combine(t[j * N + i], values[c]);
                    }
                }
            }
            (q, t)
        })
        .collect()
}

/// Moves an erosion layer's raster from `top` applied operations to `keep`: restored from the
/// before-images while the history has them, else rebuilt from `ops[..keep]` by the CPU
/// reference.
pub fn undo_to(
    raster: &mut EditRaster,
    ops: &[Operation],
    top: usize,
    keep: usize,
    below: &Below,
) -> Result<(), OperationError> {
    if keep <= top && raster.restore_to(top, keep) == keep {
        return Ok(());
    }
    let mut rebuilt = build(raster.ellipsoid, &ops[..keep], below)?;
    rebuilt.clear_history();
    rebuilt.succeed(raster);
    *raster = rebuilt;
    Ok(())
}
