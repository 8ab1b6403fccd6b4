//! The composition pass: per quad that needs it, a compute dispatch of `shaders/compose/
//! compose.wgsl` that folds the quad's planned layers into its 257² heights in the height pool
//! and, where a difference layer is drawn, composes its operands A and B the same way and writes
//! A − B into the overlay pool's slot of the same index (the GPU twin of
//! [`crate::layers::compose`]). The structs below are the Pod twins of the
//! shader's `Job`, `JobLayer` and `Octave` (keep in sync; sizes asserted at compile time). All
//! positions a job carries are relative to the quad's origin O, cast from f64: the kernel works
//! in quad-local f32, and procedural lattices are addressed from per-octave f64 origins.

use super::codes;
use bytemuck::{Pod, Zeroable};
use glam::DVec3;

use super::compute::{compute_pipeline, shader_module, storage_buffer, storage_layout};
use super::context::GpuError;
use super::terrain::bind_buffers;
use super::uniforms::NO_SLOT;
use crate::ecm::geometry::{MapSymmetry, QuadGeometry, Split};
use crate::layers::spec::{BlendMode, DetailWhere, NoiseType};
use crate::layers::{MaskPlan, PlannedLayer, QuadPlan, Stack, ValueSource, noise};

/// Where quads are composed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ComposeOn {
    /// The renderer's compute pass.
    Gpu,
    /// The CPU reference (deterministic, bit for bit).
    Cpu,
}

impl ComposeOn {
    /// Where a renderer on `device_type` composes its frames by default: the compute pass on a
    /// hardware adapter, the CPU reference on a software one (where the reference is 27× faster
    /// for one dataset layer than the pass run by the CPU rasteriser: BENCHMARKS.md).
    pub fn for_adapter(device_type: wgpu::DeviceType) -> ComposeOn {
        if device_type == wgpu::DeviceType::Cpu { ComposeOn::Cpu } else { ComposeOn::Gpu }
    }
}

/// Stands for "no bound" and "no data spacing" in the shader (its `FAR`).
const FAR: f32 = 3.0e38;
/// Samples along a quad edge, and the workgroup edge.
const N: u32 = 257;
const WORKGROUP: u32 = 16;

/// One quad to compose (`Job` in compose.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct ComposeJob {
    pub(super) corners: [[f32; 4]; 4],
    pub(super) sym: [[f32; 4]; 3],
    pub(super) origin: [f32; 4],
    pub(super) slots: [u32; 4],
    pub(super) layers: [u32; 4],
    pub(super) params: [f32; 4],
}

/// One planned layer of a job (`JobLayer` in compose.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct JobLayer {
    /// What the layer's value is (`codes::kind`), how it folds (`codes::blend`), its source
    /// slot, and 1 where its extent masks it partly.
    pub(super) kind: u32,
    pub(super) blend: u32,
    pub(super) source: u32,
    pub(super) partial: u32,
    /// The extent's mask in `shapes`: first segment and count, first ring vertex and count.
    pub(super) segment_first: u32,
    pub(super) segments: u32,
    pub(super) ring_first: u32,
    pub(super) rings: u32,
    /// Procedural: first octave and count, noise type (1 ridged), placement (1 beyond the data).
    pub(super) octave_first: u32,
    pub(super) octaves: u32,
    pub(super) noise_type: u32,
    pub(super) placement: u32,
    /// Datasets: the edge slot (NO_SLOT: no edge feather), the biases' first entry and count.
    pub(super) edge_slot: u32,
    pub(super) bias_first: u32,
    pub(super) biases: u32,
    pub(super) pad0: u32,
    pub(super) opacity: f32,
    pub(super) weight: f32,
    pub(super) scale: f32,
    pub(super) offset_m: f32,
    /// The valid range (±FAR: none), the extent's feather, its ring's smallest longitude.
    pub(super) valid_lo_m: f32,
    pub(super) valid_hi_m: f32,
    pub(super) feather_m: f32,
    pub(super) ring_lon_min: f32,
    /// A constant's height; a procedural layer's amplitude and gain.
    pub(super) height_m: f32,
    pub(super) amplitude_m: f32,
    pub(super) gain: f32,
    /// A dataset's feather at its no-data edge and data spacing (FAR: none).
    pub(super) feather_edge_m: f32,
    pub(super) data_spacing_m: f32,
    /// The ring's orientation (+1: counter-clockwise in longitude and latitude).
    pub(super) orientation: f32,
    pub(super) pad1: f32,
    pub(super) pad2: f32,
}

/// One octave at one quad (`Octave` in compose.wgsl; keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct OctaveOrigin {
    pub(super) cell: [u32; 4],
    pub(super) frac: [f32; 4],
}

const _: () = assert!(std::mem::size_of::<ComposeJob>() == 16 * 11);
const _: () = assert!(std::mem::size_of::<JobLayer>() == 16 * 8);
const _: () = assert!(std::mem::size_of::<OctaveOrigin>() == 32);

/// The jobs of one dispatch and everything they index.
#[derive(Default)]
pub struct ComposeBatch {
    quads: Vec<crate::ecm::QuadId>,
    jobs: Vec<ComposeJob>,
    layers: Vec<JobLayer>,
    octaves: Vec<OctaveOrigin>,
    shapes: Vec<[f32; 4]>,
    /// Planned layers over all jobs (what the batch reads).
    pub layers_read: usize,
}

fn v4(v: DVec3, w: f32) -> [f32; 4] {
    [v.x as f32, v.y as f32, v.z as f32, w]
}

impl ComposeBatch {
    /// Quads in the batch.
    pub fn len(&self) -> usize {
        self.jobs.len()
    }

    /// The quads, in job order.
    pub fn quads(&self) -> &[crate::ecm::QuadId] {
        &self.quads
    }

    /// Whether the batch is empty.
    pub fn is_empty(&self) -> bool {
        self.jobs.is_empty()
    }

    /// Adds a quad: its plan, geometry, the height slot it writes (and, where the plan has a
    /// difference, the same slot of the overlay pool), its map slot (None: flat patch) and the
    /// source and edge slots of each planned dataset layer (`tile_slots(k)` over
    /// [`QuadPlan::all_layers`]; NO_SLOT for the edge where the layer does not fade in from its
    /// no-data edge).
    pub fn push(
        &mut self,
        stack: &Stack,
        plan: &QuadPlan,
        geometry: &QuadGeometry,
        height_slot: u32,
        map_slot: Option<u32>,
        tile_slots: &dyn Fn(usize) -> (u32, u32),
    ) {
        let quad = plan.quad;
        let origin = geometry.corners_ecef.iter().copied().sum::<DVec3>() / 4.0;
        let symmetry = MapSymmetry::of(quad);
        let m = symmetry.matrix();
        let flags = u32::from(symmetry.swap) | u32::from(symmetry.flip_x) << 1 | u32::from(symmetry.flip_y) << 2;
        let first_layer = self.layers.len() as u32;
        let mut count = 0;
        for (k, planned) in plan.all_layers().enumerate() {
            self.push_layer(stack, planned, origin, tile_slots(k));
            count += 1;
        }
        self.layers_read += count;
        // Heights: the plan's layers; A and B follow them (their counts; 0, 0: no difference).
        let (a, b) = plan.difference.as_ref().map_or((0, 0), |d| (d.a.layers.len() as u32, d.b.layers.len() as u32));
        self.quads.push(quad);
        self.jobs.push(ComposeJob {
            corners: geometry.corners_ecef.map(|c| v4(c - origin, 0.0)),
            sym: [m.x_axis, m.y_axis, m.z_axis].map(|c| v4(c, 0.0)),
            origin: v4(origin, stack.ellipsoid.e2() as f32),
            slots: [height_slot, Split::of(quad).code(), map_slot.unwrap_or(NO_SLOT), flags],
            layers: [first_layer, plan.layers.len() as u32, a, b],
            params: [plan.spacing_m as f32, f32::from(u8::from(plan.difference.is_some())), 0.0, 0.0],
        });
    }

    /// One planned layer's record; `slots` its source and edge tiles' slots.
    fn push_layer(&mut self, stack: &Stack, planned: &PlannedLayer, origin: DVec3, slots: (u32, u32)) {
        let layer = &stack.layers[planned.index];
        let spec = &layer.spec;
        // The kernel's value code and the tile it reads.
        let (kind, source) = match spec.value_source() {
            ValueSource::StoreTile => (codes::kind::STORE_TILE, slots.0),
            ValueSource::Noise(_) => (codes::kind::NOISE, NO_SLOT),
            ValueSource::Constant(_) => (codes::kind::CONSTANT, NO_SLOT),
            ValueSource::Deltas => (codes::kind::DELTAS, slots.0),
            ValueSource::Nothing => unreachable!("a layer without heights is never planned"),
        };
        let blend = match planned.blend {
            BlendMode::Over => codes::blend::OVER,
            BlendMode::Add => codes::blend::ADD,
            BlendMode::Min => codes::blend::MIN,
            BlendMode::Max => codes::blend::MAX,
            BlendMode::Mean => codes::blend::MEAN,
        };
        let mut record = JobLayer { kind, blend, source, data_spacing_m: FAR, ..JobLayer::zeroed() };
        let mut lon_min = 0.0f32;
        let mut orientation = 1.0f32;
        let partial = match (&planned.mask, &layer.extent) {
            (MaskPlan::Partial(near), Some(extent)) => {
                record.segment_first = self.shapes.len() as u32;
                record.segments = near.segments.len() as u32;
                for &s in &near.segments {
                    let [a, b] = extent.segments[s as usize];
                    self.shapes.push(v4(a - origin, 0.0));
                    self.shapes.push(v4(b - origin, 0.0));
                }
                // Then a sphere around each block of MASK_BLOCK segments, so that a sample skips
                // the blocks that cannot hold its nearest segment.
                for &(centre, radius) in &near.spheres {
                    self.shapes.push(v4(centre - origin, radius as f32));
                }
                record.ring_first = self.shapes.len() as u32;
                match extent.box_rad {
                    // A box: no ring, its bounds in one entry.
                    Some(b) => self.shapes.push(b.map(|v| v as f32)),
                    None => {
                        record.rings = extent.ring_rad.len() as u32;
                        self.shapes
                            .extend(extent.ring_rad.iter().map(|[lon, lat]| [*lon as f32, *lat as f32, 0.0, 0.0]));
                    }
                }
                lon_min = extent.lon_min_rad as f32;
                orientation = extent.orientation() as f32;
                1
            }
            _ => 0,
        };
        if let ValueSource::Noise(n) = spec.value_source() {
            record.octave_first = self.octaves.len() as u32;
            record.octaves = planned.octaves;
            record.noise_type = u32::from(n.noise_type == NoiseType::Ridged);
            record.placement = u32::from(n.placement == DetailWhere::BeyondData);
            for o in 0..planned.octaves {
                let wavelength = noise::octave_wavelength_m(n, o);
                let (cell, frac) = noise::lattice_origin(origin, wavelength);
                self.octaves.push(OctaveOrigin {
                    cell: [cell[0], cell[1], cell[2], noise::octave_seed(n.seed, o)],
                    frac: [frac[0] as f32, frac[1] as f32, frac[2] as f32, wavelength as f32],
                });
            }
            record.amplitude_m = n.amplitude_m as f32;
            record.gain = n.gain as f32;
        }
        if let ValueSource::Constant(h) = spec.value_source() {
            record.height_m = h as f32;
        }
        if spec.is_data() {
            // The edge slot; the bias corrections' first entry in `shapes` and their count.
            record.edge_slot = slots.1;
            record.bias_first = self.shapes.len() as u32;
            record.biases = layer.correction.biases.len() as u32;
            push_correction(&mut self.shapes, &layer.correction, origin);
            record.feather_edge_m = spec.feather_edge_m() as f32;
            if layer.data_spacing_m.is_finite() {
                record.data_spacing_m = layer.data_spacing_m as f32;
            }
        }
        record.orientation = orientation;
        let [lo, hi] = spec.valid_range_m.map_or([-FAR, FAR], |[a, b]| [a as f32, b as f32]);
        self.layers.push(JobLayer {
            partial,
            opacity: planned.opacity as f32,
            weight: spec.weight as f32,
            scale: spec.scale as f32,
            offset_m: spec.offset_m as f32,
            valid_lo_m: lo,
            valid_hi_m: hi,
            feather_m: spec.feather_m as f32,
            ring_lon_min: lon_min,
            ..record
        });
    }
}

/// A dataset layer's bias corrections as the kernel's `correction` reads them from `shapes`: per
/// bias a head (code, count, sin and cos of the azimuth); for a ramp or sinusoids its frame
/// relative to the quad's origin O ((east, e₀), (north, n₀), e₀ and n₀ the east and north metres
/// of O, so a sample at O + x is at e₀ + east·x), then its terms: a ramp's box (km) and
/// coefficients four to an entry, the sinusoids' (offset, range) and one entry each (wavelength,
/// amplitude, phase / 2π), an elevation bias's bins two to an entry.
fn push_correction(shapes: &mut Vec<[f32; 4]>, correction: &crate::layers::correction::Correction, origin: DVec3) {
    use crate::layers::correction::Bias;
    let frame = |shapes: &mut Vec<[f32; 4]>, f: &Option<crate::layers::correction::Frame>| {
        // Every bias of position has one (`Correction::new`).
        let (east, north, (e0, n0)) =
            f.map_or((DVec3::ZERO, DVec3::ZERO, (0.0, 0.0)), |f| (f.east, f.north, f.local(origin)));
        shapes.push(v4(east, e0 as f32));
        shapes.push(v4(north, n0 as f32));
    };
    for (bias, f) in &correction.biases {
        match bias {
            Bias::Deramp { order, coefficients, box_km, .. } => {
                shapes.push([codes::bias::DERAMP as f32, f32::from(*order), 0.0, 0.0]);
                frame(shapes, f);
                shapes.push(box_km.map(|v| v as f32));
                for c in coefficients.chunks(4) {
                    let mut entry = [0.0f32; 4];
                    entry.iter_mut().zip(c).for_each(|(e, c)| *e = *c as f32);
                    shapes.push(entry);
                }
            }
            Bias::TerrainBias { bins, .. } => {
                shapes.push([codes::bias::ELEVATION as f32, bins.len() as f32, 0.0, 0.0]);
                for pair in bins.chunks(2) {
                    let mut entry = [0.0f32; 4];
                    entry.iter_mut().zip(pair.as_flattened()).for_each(|(e, v)| *e = *v as f32);
                    shapes.push(entry);
                }
            }
            Bias::Directional { azimuth_deg, offset_m, sinusoids, range_m, .. } => {
                let (s, c) = azimuth_deg.to_radians().sin_cos();
                shapes.push([codes::bias::DIRECTIONAL as f32, sinusoids.len() as f32, s as f32, c as f32]);
                frame(shapes, f);
                shapes.push([*offset_m as f32, range_m[0] as f32, range_m[1] as f32, 0.0]);
                for q in sinusoids {
                    let turns = q.phase_rad / std::f64::consts::TAU;
                    shapes.push([q.wavelength_m as f32, q.amplitude_m as f32, turns as f32, 0.0]);
                }
            }
        }
    }
}

/// The pools a dispatch reads and writes.
pub(crate) struct ComposePools<'a> {
    /// Raw source and edge tiles.
    pub(crate) sources: &'a wgpu::Buffer,
    /// The static displacement maps.
    pub(crate) map_o: &'a wgpu::Buffer,
    /// Composed heights (written).
    pub(crate) heights: &'a wgpu::Buffer,
    /// The drawn difference (written where a job has one).
    pub(crate) overlay: &'a wgpu::Buffer,
}

/// The compose pipeline.
pub(crate) struct ComposePass {
    pipeline: wgpu::ComputePipeline,
    /// The drawn difference's A − B, dispatched only for batches with one.
    difference: wgpu::ComputePipeline,
    layout: wgpu::BindGroupLayout,
}

impl ComposePass {
    pub(crate) fn new(device: &wgpu::Device) -> Result<ComposePass, GpuError> {
        let module = shader_module(device, "compose/compose.wgsl")?;
        let read_only = [true, true, true, true, true, true, false, false];
        let layout = storage_layout(device, "compose", &read_only);
        let pipeline = compute_pipeline(device, "compose", &layout, &module, "compose");
        let difference = compute_pipeline(device, "compose difference", &layout, &module, "compose_difference");
        Ok(ComposePass { pipeline, difference, layout })
    }

    /// Records the batch's dispatch into `encoder` (nothing for an empty batch).
    pub(crate) fn encode(
        &self,
        device: &wgpu::Device,
        encoder: &mut wgpu::CommandEncoder,
        batch: &ComposeBatch,
        pools: ComposePools,
    ) {
        let ComposePools { sources, map_o, heights, overlay } = pools;
        if batch.is_empty() {
            return;
        }
        let storage = |label: &str, bytes: &[u8]| storage_buffer(device, label, bytes, wgpu::BufferUsages::empty());
        let jobs = storage("compose jobs", bytemuck::cast_slice(&batch.jobs));
        let layers = storage("compose layers", bytemuck::cast_slice(&batch.layers));
        let octaves = storage("compose octaves", bytemuck::cast_slice(&batch.octaves));
        let shapes = storage("compose shapes", bytemuck::cast_slice(&batch.shapes));
        let bind = bind_buffers(
            device,
            &self.layout,
            "compose",
            &[&jobs, &layers, &octaves, &shapes, sources, map_o, heights, overlay],
        );
        let mut pass =
            encoder.begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("compose"), timestamp_writes: None });
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &bind, &[]);
        let groups = N.div_ceil(WORKGROUP);
        // At most 65 535 workgroups along z: batches are far smaller (one job per quad).
        pass.dispatch_workgroups(groups, groups, batch.jobs.len() as u32);
        if batch.jobs.iter().any(|j| j.params[1] > 0.5) {
            pass.set_pipeline(&self.difference);
            pass.dispatch_workgroups(groups, groups, batch.jobs.len() as u32);
        }
    }
}
