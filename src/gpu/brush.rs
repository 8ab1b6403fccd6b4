//! The GPU rasteriser of brush strokes: `shaders/edit/stroke.wgsl`, one dispatch per stroke over
//! the tiles it touches, read back into the edit raster (which stays the cache the renderer
//! uploads from). It agrees with the CPU reference ([`crate::edit::kernel::apply_to_tile`])
//! within [`GPU_TOLERANCE`], not bit for bit: replay checks against the CPU. Smooth reads the
//! terrain on its ring from each tile's grid extended by a margin from its neighbours; tiles whose
//! ring reaches across a face edge, or wider than [`MAX_MARGIN`] samples, go to the CPU reference.
//!
//! Every position the kernel sees is relative to its tile's origin O (the tile's centre sample),
//! cast from f64: the tile's exact points (every 1 to 8 samples, at most [`LATTICE_M`] apart,
//! every sample at a face's centre), and the stroke's dab centres.

use super::codes;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::compute::{compute_pipeline, read_mapped, readback_buffer, shader_module, storage_buffer, storage_layout};
use super::context::{GpuContext, GpuError};
use super::terrain::bind_buffers;
use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::ecm::points::sample_point;
use crate::edit::kernel::{CpuRasteriser, Rasteriser, StrokeJob, window};
use crate::edit::terrain::Target;
use crate::edit::{Falloff, Stroke, Tool};
use crate::errors::Failure;
use crate::geodesy::Ellipsoid;
use crate::layers::noise;

const N: usize = GRID as usize;
/// Largest distance between a tile's exact points, metres: the surface sags below the chord
/// between two by d²/8R, 0.26 mm on the Moon and 0.07 mm on Earth.
const LATTICE_M: f64 = 60.0;
/// `NO_DIAGONAL` in stroke.wgsl.
const NO_DIAGONAL: i32 = -2_147_483_647;
const WORKGROUP: u32 = 16;
/// Tiles per dispatch (the δ and below buffers are 264 KB per tile).
const TILES_PER_DISPATCH: usize = 256;

/// How far the GPU's δ may be from the CPU reference's, as a fraction of the stroke's scale (the
/// largest of its strength in metres and the |δ| and |goal| involved) times its dab count. The
/// f32 fold rounds by 6·10⁻⁸ of the running value per dab; the interpolated positions are within
/// 4 mm of the exact ones (measured over whole tiles at levels 9 and 14, face centres, edges and
/// corners included), which moves a weight by at most 3·4 mm / 2r. Measured on lavapipe: 9·10⁻⁷
/// (tests/brush.rs).
pub const GPU_TOLERANCE: f64 = 1e-5;

/// One tile (`Tile` in stroke.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct StrokeTile {
    pub(super) window: [u32; 4],
    pub(super) head: [u32; 4],
    pub(super) cell: [u32; 4],
    pub(super) frac: [f32; 4],
    pub(super) params: [f32; 4],
    pub(super) ramp_a: [f32; 4],
    pub(super) ramp_b: [f32; 4],
    pub(super) lat: [u32; 4],
    pub(super) diag: [i32; 4],
    pub(super) origin: [f32; 4],
    pub(super) ext_grid: [u32; 4],
}

const _: () = assert!(std::mem::size_of::<StrokeTile>() == 16 * 11);

/// The largest margin of a tile's extended H grid (smooth), samples: a ring wider than this (a
/// brush of more than about 500 sample spacings) is smoothed by the CPU reference.
const MAX_MARGIN: u32 = 256;

/// The margin a smoothing ring of `ring_m` needs around a tile at `level`, samples (QSC's sample
/// spacing stays above half the level's mean).
fn ring_margin(e: &crate::geodesy::Ellipsoid, level: u8, ring_m: f64) -> u32 {
    (ring_m / (0.5 * crate::ecm::grid::spacing_m(e, level))).ceil() as u32 + 2
}

/// The step between a tile's exact points, in samples: the largest of 8, 4, 2 with the points at
/// most [`LATTICE_M`] apart; 1 (every sample exact) at the face's centre, where QSC's four
/// sectors meet in a point no interpolation follows.
fn lattice_step(e: &crate::geodesy::Ellipsoid, q: QuadId) -> u32 {
    let half = (1u32 << q.level) / 2;
    let at_centre = q.level == 0 || ((half - 1..=half).contains(&q.x) && (half - 1..=half).contains(&q.y));
    if at_centre {
        return 1;
    }
    let spacing = crate::ecm::grid::spacing_m(e, q.level);
    [8, 4, 2].into_iter().find(|s| f64::from(*s) * spacing <= LATTICE_M).unwrap_or(1)
}

/// Where the face's diagonals cross a tile, in its samples: [i − j on the main one, i + j on the
/// other] (NO_DIAGONAL where one does not).
fn diagonals(q: QuadId) -> [i32; 4] {
    let tile = 256i64;
    let (x, y) = (i64::from(q.x) * tile, i64::from(q.y) * tile);
    let main = y - x; // i − j = y − x on the main diagonal (global x + i = y + j)
    let other = (tile << q.level) - x - y; // global (x + i) + (y + j) = 256·2^level
    let fit = |v: i64| if (-2 * tile..=2 * tile).contains(&v) { v as i32 } else { NO_DIAGONAL };
    [fit(main), fit(other), 0, 0]
}

fn v4(v: DVec3, w: f64) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w as f32]
}

/// The stroke kernel, compiled for a device.
pub struct StrokeKernel {
    pipeline: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
    /// Per tile its origin, lattice step and exact points (they never change; at most
    /// [`KEPT_LATTICES`] kept).
    lattices: std::sync::Mutex<std::collections::HashMap<QuadId, std::sync::Arc<Lattice>>>,
}

/// Tiles whose exact points are kept (about 1 MB each at step 1, 17 KB at step 8).
const KEPT_LATTICES: usize = 1024;

/// A tile's origin O, the step between its exact points and the points relative to O.
struct Lattice {
    origin: DVec3,
    step: u32,
    points: Vec<[f32; 4]>,
}

impl Lattice {
    fn of(e: &crate::geodesy::Ellipsoid, q: QuadId) -> Lattice {
        let (origin, _, _) = sample_point(e, q, GRID, 128, 128);
        let step = lattice_step(e, q);
        let m = 256 / step + 1;
        let mut points = Vec::with_capacity((m * m) as usize);
        for j in 0..m {
            for i in 0..m {
                points.push(v4(sample_point(e, q, GRID, i * step, j * step).0 - origin, 0.0));
            }
        }
        Lattice { origin, step, points }
    }
}

/// The kernel with the device and queue it runs on: a [`Rasteriser`].
pub struct GpuRasteriser<'a> {
    device: &'a wgpu::Device,
    queue: &'a wgpu::Queue,
    kernel: &'a StrokeKernel,
}

impl StrokeKernel {
    /// Compiles the kernel.
    pub fn new(device: &wgpu::Device) -> Result<StrokeKernel, GpuError> {
        let module = shader_module(device, "edit/stroke.wgsl")?;
        let layout = storage_layout(device, "stroke", &[true, true, true, true, false, true]);
        let pipeline = compute_pipeline(device, "stroke", &layout, &module, "apply_stroke");
        Ok(StrokeKernel { pipeline, layout, lattices: Default::default() })
    }

    /// The rasteriser on a device and queue (the kernel's device).
    pub fn on<'a>(&'a self, device: &'a wgpu::Device, queue: &'a wgpu::Queue) -> GpuRasteriser<'a> {
        GpuRasteriser { device, queue, kernel: self }
    }

    /// The rasteriser on a context's device.
    pub fn on_context<'a>(&'a self, gpu: &'a GpuContext) -> GpuRasteriser<'a> {
        self.on(&gpu.device, &gpu.queue)
    }
}

impl GpuRasteriser<'_> {
    /// The tile's lattice of ellipsoid points, kept between strokes (the kept ones dropped
    /// together past KEPT_LATTICES).
    fn lattice(&self, e: &Ellipsoid, q: QuadId) -> std::sync::Arc<Lattice> {
        let kept = self.kernel.lattices.lock().expect("not poisoned").get(&q).cloned();
        kept.unwrap_or_else(|| {
            let made = std::sync::Arc::new(Lattice::of(e, q));
            let mut all = self.kernel.lattices.lock().expect("not poisoned");
            if all.len() >= KEPT_LATTICES {
                all.clear();
            }
            all.insert(q, made.clone());
            made
        })
    }

    /// One dispatch over a chunk of tiles; their δ replaced by the kernel's.
    fn dispatch(&self, job: &StrokeJob, tiles: &mut [(QuadId, Vec<f32>)]) -> Result<(), GpuError> {
        let e = job.ellipsoid;
        let stroke = job.stroke;
        let (tool, falloff) = codes_of(stroke);
        let wavelength = stroke.radius_m / 2.0;
        let (flat, ramp) = match job.target {
            Target::Flatten { height_m } => (height_m, None),
            Target::Ramp { a, b, height_a_m, height_b_m } => (0.0, Some((a, b, height_a_m, height_b_m))),
            _ => (0.0, None),
        };
        let reads_below = stroke.tool.reads_terrain();
        let ring = match job.target {
            Target::Smooth { ring_m } => Some(ring_m),
            _ => None,
        };
        let mut ext: Vec<f32> = Vec::new();
        let mut heads = Vec::with_capacity(tiles.len());
        let mut lattice: Vec<[f32; 4]> = Vec::new();
        let mut dabs: Vec<[f32; 4]> = Vec::with_capacity(tiles.len() * job.dabs.len());
        let mut below: Vec<f32> = Vec::new();
        let mut delta: Vec<f32> = Vec::with_capacity(tiles.len() * N * N);
        for (q, tile) in tiles.iter() {
            let tile_lattice = self.lattice(e, *q);
            let (origin, step) = (tile_lattice.origin, tile_lattice.step);
            let lat = [lattice.len() as u32, step, 256 / step + 1, 0];
            lattice.extend_from_slice(&tile_lattice.points);
            let first = dabs.len() as u32;
            dabs.extend(job.dabs.iter().map(|d| v4(d.centre - origin, 0.0)));
            let [i0, i1, j0, j1] = window(e, *q, job.dabs, stroke.radius_m);
            let (cell, frac) = noise::lattice_origin(origin, wavelength);
            let (ra, rb) = ramp.map_or(([0.0; 4], [0.0; 4]), |(a, b, ha, hb)| (v4(a - origin, ha), v4(b - origin, hb)));
            heads.push(StrokeTile {
                window: [i0 as u32, i1 as u32, j0 as u32, j1 as u32],
                head: [first, job.dabs.len() as u32, tool, falloff],
                cell: [cell[0], cell[1], cell[2], stroke.seed],
                frac: [frac[0] as f32, frac[1] as f32, frac[2] as f32, wavelength as f32],
                params: [stroke.radius_m as f32, stroke.strength as f32, flat as f32, 0.0],
                ramp_a: ra,
                ramp_b: rb,
                lat,
                diag: diagonals(*q),
                origin: v4(origin, e.a_m() * e.a_m() / (e.b_m() * e.b_m())),
                ext_grid: ring.map_or([0; 4], |ring_m| ring_grid(job, *q, ring_m, &mut ext)),
            });
            if reads_below {
                let s = job.snapshot.expect("flatten and ramp have a snapshot");
                below.extend((0..N * N).map(|k| {
                    let b = s.sample(*q, k) - f64::from(tile[k]);
                    if b.is_finite() { b as f32 } else { -3.0e37 }
                }));
            }
            delta.extend_from_slice(tile);
        }
        let device = self.device;
        let storage = |label: &str, bytes: &[u8], extra| storage_buffer(device, label, bytes, extra);
        let none = wgpu::BufferUsages::empty();
        let heads_buffer = storage("stroke tiles", bytemuck::cast_slice(&heads), none);
        let lattice_buffer = storage("stroke lattice", bytemuck::cast_slice(&lattice), none);
        let dabs_buffer = storage("stroke dabs", bytemuck::cast_slice(&dabs), none);
        let below_buffer = storage("stroke below", bytemuck::cast_slice(&below), none);
        let delta_buffer = storage("stroke delta", bytemuck::cast_slice(&delta), wgpu::BufferUsages::COPY_SRC);
        let ext_buffer = storage("stroke ext", bytemuck::cast_slice(&ext), none);
        let bytes = (delta.len() * 4) as u64;
        let read = readback_buffer(device, "stroke read", bytes);
        let bind = bind_buffers(
            device,
            &self.kernel.layout,
            "stroke",
            &[&heads_buffer, &lattice_buffer, &dabs_buffer, &below_buffer, &delta_buffer, &ext_buffer],
        );
        let mut encoder = device.create_command_encoder(&Default::default());
        {
            let mut pass = encoder
                .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("stroke"), timestamp_writes: None });
            pass.set_pipeline(&self.kernel.pipeline);
            pass.set_bind_group(0, &bind, &[]);
            let groups = (N as u32).div_ceil(WORKGROUP);
            pass.dispatch_workgroups(groups, groups, tiles.len() as u32);
        }
        encoder.copy_buffer_to_buffer(&delta_buffer, 0, &read, 0, bytes);
        self.queue.submit([encoder.finish()]);
        let values: Vec<f32> = read_mapped(device, &read)?;
        for (k, (_, tile)) in tiles.iter_mut().enumerate() {
            tile.copy_from_slice(&values[k * N * N..(k + 1) * N * N]);
        }
        Ok(())
    }
}

impl Rasteriser for GpuRasteriser<'_> {
    fn rasterise(&self, job: &StrokeJob, tiles: &mut [(QuadId, Vec<f32>)]) -> Result<(), Failure> {
        let nothing = match job.target {
            Target::Flatten { height_m } => !height_m.is_finite(),
            Target::Ramp { height_a_m, height_b_m, .. } => !(height_a_m.is_finite() && height_b_m.is_finite()),
            _ => false,
        };
        if nothing {
            // No terrain under the target's points: the stroke changes nothing (as on the CPU).
            return Ok(());
        }
        if let Target::Smooth { ring_m } = job.target {
            // Tiles whose ring reaches across a face edge (where the grid's index space bends, so
            // that grid steps from the tile's Jacobian miss the ring) and rings wider than the
            // largest margin: the CPU reference. The rest on the GPU.
            let on_cpu = |q: &QuadId| {
                let m = ring_margin(job.ellipsoid, q.level, ring_m);
                let last = (256i64 << q.level) - 1;
                let (x0, y0) = (i64::from(q.x) * 256 - i64::from(m), i64::from(q.y) * 256 - i64::from(m));
                let (x1, y1) = (x0 + 256 + 2 * i64::from(m), y0 + 256 + 2 * i64::from(m));
                m > MAX_MARGIN || x0 < 0 || y0 < 0 || x1 > last || y1 > last
            };
            let (mut cpu, mut gpu): (Vec<_>, Vec<_>) = tiles.iter_mut().partition(|(q, _)| on_cpu(q));
            let mut cpu_tiles: Vec<(QuadId, Vec<f32>)> = cpu.iter_mut().map(|(q, t)| (*q, std::mem::take(t))).collect();
            CpuRasteriser.rasterise(job, &mut cpu_tiles)?;
            for ((_, t), (_, done)) in cpu.iter_mut().zip(cpu_tiles) {
                *t = done;
            }
            let mut gpu_tiles: Vec<(QuadId, Vec<f32>)> = gpu.iter_mut().map(|(q, t)| (*q, std::mem::take(t))).collect();
            // Smooth's extended grids are large: fewer tiles per dispatch.
            for chunk in gpu_tiles.chunks_mut(32) {
                self.dispatch(job, chunk)?;
            }
            for ((_, t), (_, done)) in gpu.iter_mut().zip(gpu_tiles) {
                *t = done;
            }
            return Ok(());
        }
        for chunk in tiles.chunks_mut(TILES_PER_DISPATCH) {
            self.dispatch(job, chunk)?;
        }
        Ok(())
    }
}

/// The shader's codes of a stroke's tool and falloff.
fn codes_of(stroke: &Stroke) -> (u32, u32) {
    let tool = match stroke.tool {
        Tool::Raise => codes::tool::RAISE,
        Tool::Lower => codes::tool::LOWER,
        Tool::Noise => codes::tool::NOISE,
        Tool::Restore => codes::tool::RESTORE,
        Tool::Flatten => codes::tool::FLATTEN,
        Tool::Ramp => codes::tool::RAMP,
        Tool::Smooth => codes::tool::SMOOTH,
    };
    let falloff = match stroke.falloff {
        Falloff::Smooth => codes::falloff::SMOOTH,
        Falloff::Linear => codes::falloff::LINEAR,
        Falloff::Spherical => codes::falloff::SPHERICAL,
        Falloff::Tip => codes::falloff::TIP,
    };
    (tool, falloff)
}

/// A smoothing tile's heights with the ring's margin around it, appended to `ext` (−3·10³⁷ where
/// none): the tile's record of them (first value, edge, margin, the ring's radius's f32 bits).
fn ring_grid(job: &StrokeJob, q: QuadId, ring_m: f64, ext: &mut Vec<f32>) -> [u32; 4] {
    let s = job.snapshot.expect("smooth has a snapshot");
    let m = ring_margin(job.ellipsoid, q.level, ring_m);
    let edge = GRID + 2 * m;
    let first = ext.len() as u32;
    let (i0, j0) = (i64::from(q.x) * 256 - i64::from(m), i64::from(q.y) * 256 - i64::from(m));
    for b in 0..i64::from(edge) {
        for a in 0..i64::from(edge) {
            let h = s.sample_global(q.face, i0 + a, j0 + b);
            ext.push(if h.is_finite() { h as f32 } else { -3.0e37 });
        }
    }
    [first, edge, m, (ring_m as f32).to_bits()]
}
