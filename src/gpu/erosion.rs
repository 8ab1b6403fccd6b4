//! The erosion step on the GPU (`shaders/erosion/erosion.wgsl`): three passes per step (outflow,
//! update, reduce) mirroring the CPU reference [`crate::erosion::sim`], with the state resident
//! on the device. Steps are encoded many to a submission and nothing is read back per step: the
//! budgets are reduced on the GPU into 64-bit totals, the CFL bound sets the next step there, and
//! the steps taken are logged. [`GpuRun::download`] reads everything back (blocking);
//! [`GpuRun::request_report`] and [`GpuRun::poll_report`] read the control block without waiting
//! (the workstation's live figures).
//!
//! The GPU works in f32 and i32 where the CPU reference works in f64 and i64: the integer
//! transfers keep water and soil exactly conserved on both (the tests hold both to zero
//! unexplained units), and the terrain they make agrees within [`GPU_TOLERANCE_M`] after a few
//! steps, and in its statistics over long runs.

use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};

use bytemuck::{Pod, Zeroable};

use super::compute::{compute_pipeline_with, shader_module, storage_buffer, storage_layout};
use super::context::GpuError;
use super::terrain::bind_buffers;
use crate::erosion::layer::Stepper;
use crate::erosion::operation::Device;
use crate::erosion::params::Border;
use crate::erosion::sim::{Budget, Run};
use crate::errors::Failure;

/// After a hundred steps from the same state, the GPU's terrain change and water depth agree with
/// the CPU reference's within this, metres: f32 against f64 flips a floored unit (10 µm) here
/// and there, and the flips spread slowly (on lavapipe: 12 of 3 072 cells differ, by 1–2 units,
/// `tests/erosion.rs`; the margin is for devices that fuse multiply-adds).
pub const GPU_TOLERANCE_M: f64 = 5e-4;

/// Cells per workgroup.
const WG: u32 = 256;
/// Workgroups along x of a dispatch (the rest along y).
const GROUPS_X: u32 = 32_768;
/// Steps logged between read-backs (the log is read and restarted when full).
const LOG_STEPS: u32 = 1 << 16;
/// Steps per submission.
const STEPS_PER_SUBMIT: u32 = 64;
/// The chunks each per-cell array may be bound as (the shader's bindings).
pub const CHUNKS: usize = 4;

/// The bytes a step moves per cell at least: the outflow pass reads the state, terrain, masks
/// and fluxes and writes the fluxes, the slope and the 24 transfers; the update pass reads the
/// transfers (its neighbours' from cache), the slope, the state, terrain and masks and writes the
/// state.
pub const BYTES_PER_CELL_STEP: u64 = (16 + 16 + 16 + 32 + 32 + 4 + 96) + (96 + 4 + 16 + 16 + 16 + 16);

/// The run's parameters as the shader lays them out (`Params` in erosion.wgsl; the names are the
/// shader's, and `gpu::layout`'s test checks every offset against it).
#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
pub(super) struct GpuParams {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) n: u32,
    pub(super) groups_x: u32,
    pub(super) seed: u32,
    pub(super) open_border: u32,
    pub(super) groups: u32,
    pub(super) chunk_shift: u32,
    pub(super) unit_m3: f32,
    pub(super) g: f32,
    pub(super) friction: f32,
    pub(super) tan_talus: f32,
    pub(super) thermal: f32,
    pub(super) hardness: f32,
    pub(super) capacity: f32,
    pub(super) capacity_depth_m: f32,
    pub(super) min_slope: f32,
    pub(super) dissolve: f32,
    pub(super) deposit: f32,
    pub(super) evaporation: f32,
    pub(super) rain_m_s: f32,
    pub(super) cfl: f32,
    pub(super) dt_asked: f32,
    pub(super) weight_sum: f32,
    pub(super) weights: [[f32; 4]; 2],
}

/// The control block as the shader lays it out.
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(super) struct Control {
    pub(super) dt: f32,
    pub(super) step: u32,
    pub(super) batch_step: u32,
    pub(super) _pad: u32,
    pub(super) totals: [[u32; 2]; 4],
    pub(super) bound: f32,
    pub(super) max_speed: f32,
    pub(super) max_depth: f32,
    pub(super) _pad2: f32,
}

/// What the GPU's control block says: steps, the budget, the last bound and maxima.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Report {
    /// Steps taken since the run began.
    pub steps: u64,
    /// The budget so far, units.
    pub budget: Budget,
    /// The step the next one will take, seconds.
    pub next_dt_s: f64,
    /// The CFL bound after the last step, seconds.
    pub cfl_bound_s: f64,
    /// The largest water speed after the last step, m/s.
    pub max_speed_m_s: f64,
    /// The largest water depth after the last step, metres.
    pub max_depth_m: f64,
}

/// The compiled kernels: the passes for grids within one binding, and for grids in chunks.
pub struct ErosionKernel {
    layout: wgpu::BindGroupLayout,
    whole: Passes,
    chunked: Passes,
}

/// The three passes' pipelines.
struct Passes {
    outflow: wgpu::ComputePipeline,
    update: wgpu::ComputePipeline,
    reduce: wgpu::ComputePipeline,
}

impl ErosionKernel {
    /// Compiles the kernels.
    pub fn new(device: &wgpu::Device) -> Result<ErosionKernel, GpuError> {
        let module = shader_module(device, "erosion/erosion.wgsl")?;
        // Parameters, four chunks of the cells' records (read), then the state, fluxes and three
        // transfer arrays in four chunks each, partials, control, the step log and the slopes.
        let mut read_only = vec![true; 1 + CHUNKS];
        read_only.extend([false; 5 * CHUNKS + 4]);
        let layout = storage_layout(device, "erosion", &read_only);
        let passes = |chunked: f64| {
            let c = [("chunked", chunked)];
            Passes {
                outflow: compute_pipeline_with(device, "erosion outflow", &layout, &module, "outflow", &c),
                update: compute_pipeline_with(device, "erosion update", &layout, &module, "update", &c),
                reduce: compute_pipeline_with(device, "erosion reduce", &layout, &module, "reduce", &c),
            }
        };
        Ok(ErosionKernel { whole: passes(0.0), chunked: passes(1.0), layout })
    }
}

/// A run resident on the GPU.
pub struct GpuRun {
    device: wgpu::Device,
    queue: wgpu::Queue,
    kernel: Arc<ErosionKernel>,
    /// The run as last downloaded (its grid and parameters; its state and budget as of then).
    host: Run,
    /// Cells per chunk of the per-cell arrays.
    chunk: usize,
    /// Whether the grid is bound in more than one chunk.
    chunked: bool,
    buffers: Buffers,
    bind: wgpu::BindGroup,
    groups: u32,
    /// Steps encoded since the last download (logged in `dt_log`).
    pending: u32,
    report_read: Option<(wgpu::Buffer, Arc<AtomicBool>)>,
}

struct Buffers {
    /// The state's chunks.
    state: Vec<wgpu::Buffer>,
    /// The fluxes' chunks.
    flux: Vec<wgpu::Buffer>,
    control: wgpu::Buffer,
    dt_log: wgpu::Buffer,
    _keep: Vec<wgpu::Buffer>,
}

fn to_u32_pair(v: i64) -> [u32; 2] {
    let v = v.max(0) as u64;
    [v as u32, (v >> 32) as u32]
}

fn from_u32_pair(v: [u32; 2]) -> i64 {
    (u64::from(v[0]) | (u64::from(v[1]) << 32)) as i64
}

impl GpuRun {
    /// Uploads `run` (its grid, parameters, state and budget) to the device. A grid whose
    /// per-cell arrays pass the device's binding limit is bound as up to [`CHUNKS`] chunks each;
    /// past that it is refused, naming the limit.
    pub fn new(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kernel: Arc<ErosionKernel>,
        run: &Run,
    ) -> Result<GpuRun, GpuError> {
        let limits = device.limits();
        let binding = limits.max_storage_buffer_binding_size.min(limits.max_buffer_size);
        GpuRun::with_binding_limit(device, queue, kernel, run, binding)
    }

    /// [`GpuRun::new`] as if the device bound at most `binding` bytes (tests chunk small grids).
    pub fn with_binding_limit(
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        kernel: Arc<ErosionKernel>,
        run: &Run,
        binding: u64,
    ) -> Result<GpuRun, GpuError> {
        let grid = &run.grid;
        let n = grid.len();
        // The widest per-cell arrays hold 32 bytes a cell; a chunk is a power of two of cells
        // (the shader finds a cell's chunk with a shift), at most 2³¹.
        let per_binding = (binding / 32).clamp(1, 1 << 31);
        let shift = 63 - per_binding.leading_zeros();
        let chunk = 1usize << shift;
        let chunks = n.div_ceil(chunk).max(1);
        if chunks > CHUNKS {
            return Err(GpuError::Limit(format!(
                "an erosion grid of {} × {} cells needs {} bytes per array; this device binds at most {binding} bytes, \
                 {CHUNKS} chunks of it are bound at most (choose a smaller region or a coarser level)",
                grid.width,
                grid.height,
                n as u64 * 32
            )));
        }

        let groups = (n as u32).div_ceil(WG).max(1);
        // Heights relative to the region's mean, so that f32 keeps their differences.
        let finite: Vec<f64> = grid.base_m.iter().copied().filter(|h| h.is_finite()).collect();
        let offset = if finite.is_empty() { 0.0 } else { finite.iter().sum::<f64>() / finite.len() as f64 };
        let geo: Vec<[f32; 4]> = (0..n)
            .map(|i| {
                let b = grid.base_m[i];
                [
                    if b.is_finite() { (b - offset) as f32 } else { 0.0 },
                    grid.area_m2[i] as f32,
                    grid.dx_m[i] as f32,
                    grid.dy_m[i] as f32,
                ]
            })
            .collect();
        let masks: Vec<[f32; 4]> = (0..n)
            .map(|i| {
                [
                    grid.rain_mask.as_ref().map_or(1.0, |m| m[i] as f32),
                    grid.erosion_mask.as_ref().map_or(1.0, |m| m[i] as f32),
                    grid.hardness.as_ref().map_or(0.0, |h| h[i] as f32),
                    if grid.is_sink(i) { 1.0 } else { 0.0 },
                ]
            })
            .collect();
        let s = &run.state;
        let state: Vec<[i32; 4]> =
            (0..n).map(|i| [s.water[i] as i32, s.sediment[i] as i32, s.soil[i] as i32, 0]).collect();
        let flux: Vec<f32> = s.flux_m3_s.iter().flat_map(|f| f.iter().map(|v| *v as f32)).collect();
        let params = gpu_params(run, groups, shift);
        let control = control_of(run);
        let copy = wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST;
        let none = wgpu::BufferUsages::empty();
        let make = |label: &str, bytes: &[u8], extra| storage_buffer(device, label, bytes, extra);
        let zeros = |count: usize| vec![0u8; count];
        // Per cell: the terrain record then the masks record.
        let cells: Vec<[f32; 4]> = geo.iter().zip(&masks).flat_map(|(g, m)| [*g, *m]).collect();
        // Four chunks of an array of `per` bytes a cell (empty ones: stand-ins).
        let chunked = |label: &str, bytes: &[u8], per: usize, extra| -> Vec<wgpu::Buffer> {
            (0..CHUNKS)
                .map(|c| {
                    let (a, b) = ((c * chunk).min(n) * per, ((c + 1) * chunk).min(n) * per);
                    make(&format!("{label} {c}"), &bytes[a..b], extra)
                })
                .collect()
        };
        let params_buffer = make("erosion params", bytemuck::bytes_of(&params), none);
        let cell_buffers = chunked("erosion cells", bytemuck::cast_slice(&cells), 32, none);
        let state_buffers = chunked("erosion state", bytemuck::cast_slice(&state), 16, copy);
        let flux_buffers = chunked("erosion flux", bytemuck::cast_slice(&flux), 32, copy);
        let empty = zeros(n * 32);
        let sent: Vec<wgpu::Buffer> = ["erosion sent water", "erosion sent sediment", "erosion sent soil"]
            .iter()
            .flat_map(|l| chunked(l, &empty, 32, none))
            .collect();
        let partials = make("erosion partials", &zeros(groups as usize * 48), none);
        let control_buffer = make("erosion control", bytemuck::bytes_of(&control), copy);
        let dt_log = make("erosion dt log", &zeros(LOG_STEPS as usize * 4), copy);
        let slope = make("erosion slope", &zeros(n * 4), none);
        let mut bound: Vec<&wgpu::Buffer> = vec![&params_buffer];
        bound.extend(cell_buffers.iter().chain(&state_buffers).chain(&flux_buffers).chain(&sent));
        bound.extend([&partials, &control_buffer, &dt_log, &slope]);
        let bind = bind_buffers(device, &kernel.layout, "erosion", &bound);
        let mut keep = vec![params_buffer, partials, slope];
        keep.extend(cell_buffers);
        keep.extend(sent);
        Ok(GpuRun {
            device: device.clone(),
            queue: queue.clone(),
            kernel,
            host: run.clone(),
            chunk,
            chunked: chunks > 1,
            buffers: Buffers { state: state_buffers, flux: flux_buffers, control: control_buffer, dt_log, _keep: keep },
            bind,
            groups,
            pending: 0,
            report_read: None,
        })
    }

    /// The run as of the last download.
    pub fn host(&self) -> &Run {
        &self.host
    }

    /// Steps taken, downloaded or not.
    pub fn steps(&self) -> u64 {
        self.host.steps + u64::from(self.pending)
    }

    /// Encodes and submits `count` steps (nothing is read back; the log is downloaded first when
    /// it would overflow).
    pub fn step(&mut self, count: u32) -> Result<(), GpuError> {
        let mut left = count;
        while left > 0 {
            if self.pending == LOG_STEPS {
                self.download()?;
            }
            let now = left.min(STEPS_PER_SUBMIT).min(LOG_STEPS - self.pending);
            let mut encoder = self.device.create_command_encoder(&Default::default());
            {
                let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("erosion"),
                    timestamp_writes: None,
                });
                pass.set_bind_group(0, &self.bind, &[]);
                let gx = self.groups.min(GROUPS_X);
                let gy = self.groups.div_ceil(GROUPS_X);
                let passes = if self.chunked { &self.kernel.chunked } else { &self.kernel.whole };
                for _ in 0..now {
                    pass.set_pipeline(&passes.outflow);
                    pass.dispatch_workgroups(gx, gy, 1);
                    pass.set_pipeline(&passes.update);
                    pass.dispatch_workgroups(gx, gy, 1);
                    pass.set_pipeline(&passes.reduce);
                    pass.dispatch_workgroups(1, 1, 1);
                }
            }
            self.queue.submit([encoder.finish()]);
            self.pending += now;
            left -= now;
        }
        Ok(())
    }

    /// Waits until the GPU has taken the steps submitted (reads nothing back: for timing).
    pub fn wait(&self) -> Result<(), GpuError> {
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map(|_| ())
            .map_err(|e| GpuError::Readback(format!("the GPU did not finish: {e}")))
    }

    /// Waits for the steps submitted and reads the state, the budget and the steps taken back
    /// into [`GpuRun::host`] (its simulated time summed in f64 from the logged steps).
    pub fn download(&mut self) -> Result<&Run, GpuError> {
        let n = self.host.grid.len();
        let logged = self.pending as u64 * 4;
        let sizes = [(n * 16) as u64, (n * 32) as u64, std::mem::size_of::<Control>() as u64, logged.max(4)];
        let reads: Vec<wgpu::Buffer> = sizes
            .iter()
            .map(|&size| {
                self.device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some("erosion read"),
                    size,
                    usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    mapped_at_creation: false,
                })
            })
            .collect();
        let mut encoder = self.device.create_command_encoder(&Default::default());
        // The state's and the fluxes' chunks, each at its cells' place.
        for c in 0..CHUNKS {
            let (a, b) = ((c * self.chunk).min(n), ((c + 1) * self.chunk).min(n));
            if b > a {
                let (cells, at) = ((b - a) as u64, a as u64);
                encoder.copy_buffer_to_buffer(&self.buffers.state[c], 0, &reads[0], at * 16, cells * 16);
                encoder.copy_buffer_to_buffer(&self.buffers.flux[c], 0, &reads[1], at * 32, cells * 32);
            }
        }
        encoder.copy_buffer_to_buffer(&self.buffers.control, 0, &reads[2], 0, sizes[2]);
        encoder.copy_buffer_to_buffer(&self.buffers.dt_log, 0, &reads[3], 0, sizes[3]);
        self.queue.submit([encoder.finish()]);
        for read in &reads {
            read.slice(..).map_async(wgpu::MapMode::Read, |_| {});
        }
        self.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(format!("the GPU did not finish: {e}")))?;
        let mapped = |k: usize| reads[k].slice(..).get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()));
        {
            let state = mapped(0)?;
            let state: &[[i32; 4]] = bytemuck::cast_slice(&state);
            let flux = mapped(1)?;
            let flux: &[[f32; 8]] = bytemuck::cast_slice(&flux);
            let s = &mut self.host.state;
            for i in 0..n {
                s.water[i] = i64::from(state[i][0]);
                s.sediment[i] = i64::from(state[i][1]);
                s.soil[i] = i64::from(state[i][2]);
                s.flux_m3_s[i] = flux[i].map(f64::from);
                // Speeds stay on the GPU (only their maximum is reduced).
                s.speed_m_s[i] = 0.0;
            }
        }
        let control: Control = *bytemuck::from_bytes(&mapped(2)?);
        {
            let log = mapped(3)?;
            let log: &[f32] = bytemuck::cast_slice(&log);
            let log = &log[..self.pending as usize];
            self.host.simulated_s += log.iter().map(|&dt| f64::from(dt)).sum::<f64>();
            for &dt in log {
                let r = &mut self.host.dt_range_s;
                *r = (r.0.min(f64::from(dt)), r.1.max(f64::from(dt)));
            }
        }
        self.host.steps += u64::from(self.pending);
        self.host.budget = budget_of(&control, self.host.budget.start_water);
        self.pending = 0;
        // The log restarts.
        self.queue.write_buffer(&self.buffers.control, 8, bytemuck::bytes_of(&0u32));
        Ok(&self.host)
    }

    /// Asks for the control block without waiting (a copy mapped when the GPU gets there); see
    /// [`GpuRun::poll_report`]. Does nothing while an earlier request is outstanding.
    pub fn request_report(&mut self) {
        if self.report_read.is_some() {
            return;
        }
        let size = std::mem::size_of::<Control>() as u64;
        let read = self.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("erosion report"),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = self.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(&self.buffers.control, 0, &read, 0, size);
        self.queue.submit([encoder.finish()]);
        let ready = Arc::new(AtomicBool::new(false));
        let flag = ready.clone();
        read.slice(..).map_async(wgpu::MapMode::Read, move |r| flag.store(r.is_ok(), Ordering::Release));
        self.report_read = Some((read, ready));
    }

    /// The requested report if the GPU has got there (never waits).
    pub fn poll_report(&mut self) -> Option<Report> {
        let _ = self.device.poll(wgpu::PollType::Poll);
        let (read, ready) = self.report_read.as_ref()?;
        if !ready.load(Ordering::Acquire) {
            return None;
        }
        let control: Control = *bytemuck::from_bytes(&read.slice(..).get_mapped_range().ok()?);
        self.report_read = None;
        Some(Report {
            steps: u64::from(control.step),
            budget: budget_of(&control, self.host.budget.start_water),
            next_dt_s: f64::from(control.dt),
            cfl_bound_s: f64::from(control.bound),
            max_speed_m_s: f64::from(control.max_speed),
            max_depth_m: f64::from(control.max_depth),
        })
    }
}

/// The budget the control block holds, with the water the run started with (the host's).
fn budget_of(control: &Control, start_water: i64) -> Budget {
    Budget {
        start_water,
        rain_in: from_u32_pair(control.totals[0]),
        evaporated: from_u32_pair(control.totals[1]),
        water_out: from_u32_pair(control.totals[2]),
        soil_out: from_u32_pair(control.totals[3]),
    }
}

/// The GPU as an erosion layer's [`Stepper`]: uploads the run, takes its steps, downloads it.
pub struct GpuStepper<'a> {
    /// The device.
    pub device: &'a wgpu::Device,
    /// Its queue.
    pub queue: &'a wgpu::Queue,
    /// The kernels.
    pub kernel: Arc<ErosionKernel>,
}

impl Stepper for GpuStepper<'_> {
    fn device(&self) -> Device {
        Device::Gpu
    }

    fn run(&self, run: Run, steps: u64, watch: &crate::progress::Watch) -> Result<Run, Failure> {
        let mut gpu = GpuRun::new(self.device, self.queue, self.kernel.clone(), &run)?;
        let mut left = steps;
        while left > 0 {
            watch.check()?;
            let now = left.min(u64::from(LOG_STEPS)) as u32;
            gpu.step(now)?;
            left -= u64::from(now);
            watch.advance_by(u64::from(now));
        }
        gpu.download()?;
        Ok(gpu.host)
    }
}

/// The run's constants for the shader: the grid, the parameters in f32, the workgroups and the
/// chunk shift (a cell's chunk is its index shifted right by it).
fn gpu_params(run: &Run, groups: u32, chunk_shift: u32) -> GpuParams {
    let (grid, p) = (&run.grid, &run.params);
    let n = grid.len();
    let weights = grid.pipe_weight.map(|w| w as f32);
    GpuParams {
        width: grid.width as u32,
        height: grid.height as u32,
        n: n as u32,
        groups_x: GROUPS_X,
        seed: run.seed,
        open_border: u32::from(p.border == Border::Open),
        groups,
        chunk_shift,
        unit_m3: run.unit_m3() as f32,
        g: p.gravity_m_s2 as f32,
        friction: p.friction_per_s as f32,
        tan_talus: p.talus_deg.to_radians().tan() as f32,
        thermal: p.thermal_per_s as f32,
        hardness: p.hardness as f32,
        capacity: p.capacity as f32,
        capacity_depth_m: p.capacity_depth_m as f32,
        min_slope: p.min_slope as f32,
        dissolve: p.dissolve_per_s as f32,
        deposit: p.deposit_per_s as f32,
        evaporation: p.evaporation_per_s as f32,
        rain_m_s: p.rain_m_s as f32,
        cfl: p.cfl as f32,
        dt_asked: p.dt_s as f32,
        weight_sum: weights.iter().sum(),
        weights: [[weights[0], weights[1], weights[2], weights[3]], [weights[4], weights[5], weights[6], weights[7]]],
    }
}

/// The run's control record: the step size, where the run stands and its budget so far.
fn control_of(run: &Run) -> Control {
    let p = &run.params;
    let b = &run.budget;
    Control {
        dt: p.dt_s.min(run.cfl_bound_s()) as f32,
        step: run.steps as u32,
        batch_step: 0,
        _pad: 0,
        totals: [to_u32_pair(b.rain_in), to_u32_pair(b.evaporated), to_u32_pair(b.water_out), to_u32_pair(b.soil_out)],
        bound: 0.0,
        max_speed: 0.0,
        max_depth: 0.0,
        _pad2: 0.0,
    }
}
