//! The wgpu renderer: device set-up (headless, or the caller's device for a window), the terrain
//! pipelines, the GPU cache (fixed pools of height and map slots, least recently used evicted,
//! never one drawn this frame), per-frame preparation (arrivals, selection, uploads, requests,
//! per-quad camera-relative values) and drawing to any colour target or to an image.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use bytemuck::{Pod, Zeroable};
use glam::DVec3;
use wgpu::util::DeviceExt;

use super::camera::Camera;
use super::data::{CpuCache, DataKey, Loaded, Loader, SAMPLES};
use super::scene::Scene;
use super::select::{self, QuadInfo, QuadSource, SelectParams, Selection};
use crate::ecm::geometry::{FlatRule, HeightRange, MapSymmetry, QuadBounds, QuadFrame, QuadGeometry, Split};
use crate::ecm::{CubeProjection, QuadId};
use crate::project::CameraSpec;

/// Vertices along a quad edge with the skirt ring.
pub const MESH_EDGE: u32 = SAMPLES + 2;
/// Triangles one quad draws (grid and skirts).
pub const TRIANGLES_PER_QUAD: u64 = 2 * (MESH_EDGE as u64 - 1) * (MESH_EDGE as u64 - 1);
/// The shader's "no slot".
const NO_SLOT: u32 = u32::MAX;
/// Stored for a sample without data (the shader tests `< -1e37`).
const NODATA_STORED: f32 = -3.0e37;
/// Quads without data are split down to this level at most: there the chord between two samples
/// is within millimetres of the ellipsoid on Earth-sized bodies.
const NODATA_MAX_LEVEL: u8 = 6;
/// Most slots filled per frame, so that a burst of arrivals never stalls one.
const UPLOADS_PER_FRAME: usize = 48;
/// Samples per edge of the coarse geometry that bounds a quad.
const BOUND_SAMPLES: u32 = 17;

/// The colour format of images the renderer writes (the shader encodes sRGB itself, as a window
/// surface of egui-wgpu needs).
pub const IMAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Probe target: camera-relative surface position (metres) and height.
pub const SURFACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Probe target: quad index + 1, sample i, j, flags.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;

/// A wgpu device and queue, and what the adapter can do.
pub struct GpuContext {
    /// The device.
    pub device: wgpu::Device,
    /// Its queue.
    pub queue: wgpu::Queue,
    /// The adapter (name, backend, type).
    pub info: wgpu::AdapterInfo,
    /// Whether GPU pass times can be measured.
    pub timestamps: bool,
}

impl GpuContext {
    /// A device without a window: the best adapter the environment allows (`WGPU_BACKEND`,
    /// `WGPU_ADAPTER_NAME` select one, as in every wgpu program).
    pub fn headless() -> Result<GpuContext, String> {
        let instance = wgpu::Instance::new(wgpu::InstanceDescriptor::new_without_display_handle_from_env());
        let adapter = pollster::block_on(instance.request_adapter(&wgpu::RequestAdapterOptions {
            power_preference: wgpu::PowerPreference::HighPerformance,
            force_fallback_adapter: false,
            compatible_surface: None,
            apply_limit_buckets: false,
        }))
        .map_err(|e| {
            format!("no GPU adapter ({e}); without a GPU install Mesa's lavapipe (scripts/install-deps) and set WGPU_BACKEND=vulkan")
        })?;
        GpuContext::from_adapter(&adapter)
    }

    /// A device on a given adapter, with the adapter's limits (large storage buffers) and
    /// timestamp queries where it has them.
    pub fn from_adapter(adapter: &wgpu::Adapter) -> Result<GpuContext, String> {
        let features = adapter.features() & wgpu::Features::TIMESTAMP_QUERY;
        let (device, queue) = pollster::block_on(adapter.request_device(&wgpu::DeviceDescriptor {
            label: Some("terrafuse"),
            required_features: features,
            required_limits: adapter.limits(),
            ..Default::default()
        }))
        .map_err(|e| format!("cannot open the GPU device: {e}"))?;
        Ok(GpuContext {
            device,
            queue,
            info: adapter.get_info(),
            timestamps: features.contains(wgpu::Features::TIMESTAMP_QUERY),
        })
    }

    /// "name (backend, type)".
    pub fn describe(&self) -> String {
        format!("{} ({:?}, {:?})", self.info.name, self.info.backend, self.info.device_type)
    }
}

#[repr(C)]
#[derive(Clone, Copy, Pod, Zeroable)]
struct FrameUniform {
    view_proj: [[f32; 4]; 4],
    viewport: [f32; 4],
    sun: [f32; 4],
    iso: [f32; 4],
    iso_width: [f32; 4],
    iso_colour: [f32; 4],
    below: [f32; 4],
    above: [f32; 4],
    nodata: [f32; 4],
}

/// One quad's record for the shader (layout of `Quad` in terrain.wgsl).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub struct QuadInstance {
    anchor: [f32; 4],
    corners: [[f32; 4]; 4],
    normals: [[f32; 4]; 4],
    sym: [[f32; 4]; 3],
    slots: [u32; 4],
    params: [f32; 4],
}

impl QuadInstance {
    /// The reference height h₀ the quad was placed with (exaggerated metres).
    pub fn reference_height_m(&self) -> f32 {
        self.anchor[3]
    }

    /// The skirt depth, metres.
    pub fn skirt_m(&self) -> f32 {
        self.params[0]
    }

    /// Whether the quad was drawn with static maps.
    pub fn has_maps(&self) -> bool {
        self.slots[1] != NO_SLOT
    }
}

/// The flat rule of a body and height range, fitted once per process (the fit scans thousands
/// of quads).
fn flat_rule_for(ellipsoid: &crate::geodesy::Ellipsoid, heights: HeightRange) -> FlatRule {
    type Key = (u64, u64, u64, u64);
    static RULES: std::sync::Mutex<Vec<(Key, FlatRule)>> = std::sync::Mutex::new(Vec::new());
    let key = (ellipsoid.a_m().to_bits(), ellipsoid.b_m().to_bits(), heights.min_m.to_bits(), heights.max_m.to_bits());
    let mut rules = RULES.lock().unwrap_or_else(|p| p.into_inner());
    if let Some((_, rule)) = rules.iter().find(|(k, _)| *k == key) {
        return *rule;
    }
    let rule = FlatRule::fit(ellipsoid, CubeProjection::Qsc, FlatRule::DEFAULT_TOLERANCE_M, heights);
    rules.push((key, rule));
    rule
}

fn v4(v: glam::Vec3, w: f32) -> [f32; 4] {
    [v.x, v.y, v.z, w]
}

fn rgba(c: [u8; 4]) -> [f32; 4] {
    c.map(|v| f32::from(v) / 255.0)
}

/// The heights the terrain may reach: the body's range, widened by the exaggerated data.
fn exaggerated_range(scene: &Scene, exaggeration: f64) -> HeightRange {
    let heights = HeightRange::for_body(&scene.ellipsoid);
    HeightRange {
        min_m: heights.min_m.min(scene.range_m.0 * exaggeration),
        max_m: heights.max_m.max(scene.range_m.1 * exaggeration),
    }
}

/// The ramp's stops for the shader: value, padding, linear RGBA.
fn ramp_buffer(device: &wgpu::Device, ramp: &crate::colour::Ramp) -> wgpu::Buffer {
    let stops: Vec<[f32; 8]> = ramp
        .stops
        .iter()
        .map(|s| {
            let c = rgba(s.rgba);
            [s.value_m as f32, 0.0, 0.0, 0.0, c[0], c[1], c[2], c[3]]
        })
        .collect();
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some("ramp"),
        contents: bytemuck::cast_slice(&stops),
        usage: wgpu::BufferUsages::STORAGE,
    })
}

/// The terrain bind group: frame, quads, heights, the three maps, the ramp.
fn bind_group(device: &wgpu::Device, layout: &wgpu::BindGroupLayout, buffers: [&wgpu::Buffer; 7]) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some("terrain"), layout, entries: &entries })
}

/// A fixed pool of equal slots in one GPU buffer, keyed by quad, least recently used reused.
struct SlotPool {
    capacity: u32,
    slots: HashMap<QuadId, (u32, u64)>,
    free: Vec<u32>,
}

impl SlotPool {
    fn new(capacity: u32) -> SlotPool {
        SlotPool { capacity, slots: HashMap::new(), free: (0..capacity).rev().collect() }
    }

    fn get(&self, quad: QuadId) -> Option<u32> {
        self.slots.get(&quad).map(|s| s.0)
    }

    fn touch(&mut self, quad: QuadId, frame: u64) -> Option<u32> {
        self.slots.get_mut(&quad).map(|s| {
            s.1 = frame;
            s.0
        })
    }

    /// A slot for `quad`: a free one, or the least recently used one not used in `frame`.
    fn allocate(&mut self, quad: QuadId, frame: u64) -> Option<u32> {
        let slot = match self.free.pop() {
            Some(s) => s,
            None => {
                let (&victim, &(slot, _)) =
                    self.slots.iter().filter(|(_, (_, used))| *used < frame).min_by_key(|(_, (_, used))| *used)?;
                self.slots.remove(&victim);
                slot
            }
        };
        self.slots.insert(quad, (slot, frame));
        Some(slot)
    }
}

/// What one frame drew and what it cost.
#[derive(Clone, Debug, Default)]
pub struct FrameStats {
    /// The selection.
    pub selection: Selection,
    /// CPU time of the selection, milliseconds.
    pub select_ms: f64,
    /// CPU time of the whole preparation (arrivals, selection, uploads, per-quad values), ms.
    pub prepare_ms: f64,
    /// Slots filled this frame.
    pub uploads: usize,
    /// Quads that would be refined if their data were on the GPU.
    pub pending: usize,
    /// Data asked of the loader this frame.
    pub requested: usize,
    /// 1 when wanted quads were left out because the GPU cache is full of this frame's quads.
    pub blocked: usize,
    /// Triangles drawn.
    pub triangles: u64,
    /// Quads drawn without static maps (past the flat rule).
    pub flat_quads: usize,
    /// GPU cache: height and map slots in use, of the capacity.
    pub gpu_slots: (usize, u32, usize, u32),
    /// CPU cache bytes in use.
    pub cpu_bytes: usize,
    /// Errors reading data (named), since the last frame.
    pub errors: Vec<String>,
}

/// An image read back from the GPU.
#[derive(Clone, Debug)]
pub struct RenderedImage {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// RGBA8, sRGB-encoded, row 0 at the top.
    pub rgba: Vec<u8>,
    /// Per pixel: camera-relative surface position (metres) and height (metres); NaN-free zeros
    /// where nothing was drawn. Only with the probe.
    pub surface: Option<Vec<[f32; 4]>>,
    /// Per pixel: quad index + 1 (0: nothing), sample i, sample j, flags (bit 0 data, bit 1
    /// skirt). Only with the probe.
    pub ids: Option<Vec<[u32; 4]>>,
    /// GPU time of the terrain pass, milliseconds (where timestamps exist).
    pub gpu_ms: Option<f64>,
}

/// The targets of one frame: the colour image ([`IMAGE_FORMAT`], sRGB-encoded), for probes the
/// camera-relative surface position with height ([`SURFACE_FORMAT`]) and the ids
/// ([`ID_FORMAT`]), and the depth buffer.
pub struct FrameTargets {
    /// Width, pixels.
    pub width: u32,
    /// Height, pixels.
    pub height: u32,
    /// The colour image.
    pub colour: wgpu::Texture,
    /// Surface position and height (probe targets only).
    pub surface: Option<wgpu::Texture>,
    /// Quad and sample ids (probe targets only).
    pub ids: Option<wgpu::Texture>,
    views: Vec<wgpu::TextureView>,
    depth_view: wgpu::TextureView,
}

impl FrameTargets {
    /// Targets of a size; `usage` is added to every colour target's (copying out, sampling in a
    /// window).
    pub fn new(
        device: &wgpu::Device,
        width: u32,
        height: u32,
        probe: bool,
        usage: wgpu::TextureUsages,
    ) -> FrameTargets {
        let texture = |label: &str, format: wgpu::TextureFormat, usage: wgpu::TextureUsages| {
            device.create_texture(&wgpu::TextureDescriptor {
                label: Some(label),
                size: wgpu::Extent3d { width: width.max(1), height: height.max(1), depth_or_array_layers: 1 },
                mip_level_count: 1,
                sample_count: 1,
                dimension: wgpu::TextureDimension::D2,
                format,
                usage: wgpu::TextureUsages::RENDER_ATTACHMENT | usage,
                view_formats: &[],
            })
        };
        let colour = texture("colour", IMAGE_FORMAT, usage);
        let surface = probe.then(|| texture("surface", SURFACE_FORMAT, usage));
        let ids = probe.then(|| texture("ids", ID_FORMAT, usage));
        let depth = texture("depth", DEPTH_FORMAT, wgpu::TextureUsages::empty());
        let views = std::iter::once(&colour)
            .chain(surface.iter())
            .chain(ids.iter())
            .map(|t| t.create_view(&Default::default()))
            .collect();
        let depth_view = depth.create_view(&Default::default());
        FrameTargets { width, height, colour, surface, ids, views, depth_view }
    }

    /// The colour target's view.
    pub fn colour_view(&self) -> &wgpu::TextureView {
        &self.views[0]
    }
}

/// How to draw: the normal pass, the probe (colour + surface + ids), or the probe drawing every
/// vertex as a point (positions exactly as the vertex stage computed them).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum DrawMode {
    /// Colour only.
    Colour,
    /// Colour, surface position and ids per pixel.
    Probe,
    /// Vertices as points, with surface and ids.
    Points,
}

/// Per-quad geometry and bounds kept for selection and per-frame values.
struct QuadCache {
    geometry: HashMap<QuadId, QuadGeometry>,
    infos: HashMap<QuadId, ((f32, f32), QuadInfo)>,
    ranges: HashMap<QuadId, (f32, f32, f32)>,
}

/// The data side of selection, borrowing the renderer's parts.
struct Source<'a> {
    scene: &'a Scene,
    cache: &'a mut QuadCache,
    heights: &'a SlotPool,
    maps: &'a SlotPool,
    flat: &'a FlatRule,
    exaggeration: f64,
}

impl QuadCache {
    fn geometry(&mut self, scene: &Scene, quad: QuadId) -> &QuadGeometry {
        self.geometry
            .entry(quad)
            .or_insert_with(|| QuadGeometry::compute(&scene.ellipsoid, CubeProjection::Qsc, quad, BOUND_SAMPLES))
    }

    /// The height range a quad may span (its own once loaded; the datasets' before), with 0
    /// (where no-data samples are drawn), exaggerated.
    fn range(&self, scene: &Scene, quad: QuadId, has_data: bool, exaggeration: f64) -> (f32, f32) {
        let (lo, hi) = match self.ranges.get(&quad) {
            Some(&(lo, hi, _)) => (f64::from(lo), f64::from(hi)),
            None if has_data => scene.range_m,
            None => (0.0, 0.0),
        };
        // No-data samples are drawn at height 0, so 0 is always in the range.
        ((lo.min(0.0) * exaggeration) as f32, (hi.max(0.0) * exaggeration) as f32)
    }
}

impl QuadSource for Source<'_> {
    fn info(&mut self, quad: QuadId) -> QuadInfo {
        let has = self.scene.has_data(quad);
        let range = self.cache.range(self.scene, quad, has, self.exaggeration);
        if let Some((r, info)) = self.cache.infos.get(&quad)
            && *r == range
        {
            return *info;
        }
        let ellipsoid = self.scene.ellipsoid;
        let g = self.cache.geometry(self.scene, quad);
        let q = g.corners_ecef;
        let edge_m =
            [(q[1] - q[0]), (q[2] - q[0]), (q[3] - q[1]), (q[3] - q[2])].iter().map(|v| v.length()).fold(0.0, f64::max);
        let mut bounds = QuadBounds::compute(g, f64::from(range.0), f64::from(range.1));
        // The 257² surface between the coarse samples bulges by at most the sagitta of a coarse
        // cell's diagonal on the most curved part of the ellipsoid.
        let cell = edge_m / f64::from(BOUND_SAMPLES - 1) * std::f64::consts::SQRT_2;
        let r_min = ellipsoid.b_m() * ellipsoid.b_m() / ellipsoid.a_m();
        bounds.half_extents_m += DVec3::splat(1.5 * cell * cell / (8.0 * r_min));
        let info = QuadInfo { bounds, edge_m };
        self.cache.infos.insert(quad, (range, info));
        info
    }

    fn ready(&self, quad: QuadId) -> bool {
        let heights = !self.scene.has_data(quad) || self.heights.get(quad).is_some();
        let maps = self.flat.is_flat(quad) || self.maps.get(MapSymmetry::of(quad).canonical).is_some();
        heights && maps
    }

    fn refinable(&self, quad: QuadId) -> bool {
        match self.scene.finest_level_at(quad) {
            Some(f) => quad.level < f,
            None => quad.level < NODATA_MAX_LEVEL,
        }
    }
}

/// The terrain renderer.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    timestamps: bool,
    pipeline: wgpu::RenderPipeline,
    probe_pipeline: wgpu::RenderPipeline,
    points_pipeline: wgpu::RenderPipeline,
    bind_layout: wgpu::BindGroupLayout,
    bind_group: wgpu::BindGroup,
    ramp_buffer: wgpu::Buffer,
    frame_buffer: wgpu::Buffer,
    quad_buffer: wgpu::Buffer,
    heights_buffer: wgpu::Buffer,
    map_buffers: [wgpu::Buffer; 3],
    index_buffer: wgpu::Buffer,
    index_count: u32,
    heights_pool: SlotPool,
    maps_pool: SlotPool,
    scene: Scene,
    loader: Loader,
    cpu: CpuCache,
    cache: QuadCache,
    flat: FlatRule,
    frame: u64,
    instances: Vec<QuadInstance>,
    drawn: Vec<QuadId>,
    camera: Option<Camera>,
    size: (u32, u32),
}

impl Renderer {
    /// A renderer of `scene` on a device, drawing into targets of `format` (the window's, or
    /// [`IMAGE_FORMAT`] for images).
    pub fn new(ctx: &GpuContext, scene: Scene, format: wgpu::TextureFormat) -> Result<Renderer, String> {
        let device = ctx.device.clone();
        let source = super::shaders::composed("terrain.wgsl")?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("terrain.wgsl"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });

        // GPU cache: 15 % of the budget for heights (4 bytes a sample), the rest for the three
        // maps (36 bytes a sample), each buffer within the device's largest storage binding.
        let limit = device.limits().max_storage_buffer_binding_size.min(device.limits().max_buffer_size);
        let budget = scene.detail.gpu_cache_mib.max(16) << 20;
        let height_slot = u64::from(SAMPLES * SAMPLES) * 4;
        let map_slot = u64::from(SAMPLES * SAMPLES) * 12;
        let height_slots = ((budget * 15 / 100) / height_slot).min(limit / height_slot).max(8) as u32;
        let map_slots = ((budget * 85 / 100) / (3 * map_slot)).min(limit / map_slot).max(8) as u32;
        let storage = |label: &str, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        let heights_buffer = storage("heights", u64::from(height_slots) * height_slot);
        let map_buffers = ["map o", "map n", "map dn"].map(|l| storage(l, u64::from(map_slots) * map_slot));
        let max_quads = scene.detail.max_quads.max(6);
        let quad_buffer = storage("quads", (max_quads * std::mem::size_of::<QuadInstance>()) as u64);
        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let ramp_buffer = ramp_buffer(&device, &scene.ramp);
        let mut indices = Vec::with_capacity(TRIANGLES_PER_QUAD as usize * 3);
        for b in 0..MESH_EDGE - 1 {
            for a in 0..MESH_EDGE - 1 {
                let v00 = b * MESH_EDGE + a;
                let (v10, v01) = (v00 + 1, v00 + MESH_EDGE);
                indices.extend_from_slice(&[v00, v10, v01 + 1, v00, v01 + 1, v01]);
            }
        }
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("quad mesh"),
            contents: bytemuck::cast_slice(&indices),
            usage: wgpu::BufferUsages::INDEX,
        });

        let entry =
            |binding: u32, visibility: wgpu::ShaderStages, ty: wgpu::BufferBindingType| wgpu::BindGroupLayoutEntry {
                binding,
                visibility,
                ty: wgpu::BindingType::Buffer { ty, has_dynamic_offset: false, min_binding_size: None },
                count: None,
            };
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let both = wgpu::ShaderStages::VERTEX | wgpu::ShaderStages::FRAGMENT;
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("terrain"),
            entries: &[
                entry(0, both, wgpu::BufferBindingType::Uniform),
                entry(1, wgpu::ShaderStages::VERTEX, read),
                entry(2, wgpu::ShaderStages::VERTEX, read),
                entry(3, wgpu::ShaderStages::VERTEX, read),
                entry(4, wgpu::ShaderStages::VERTEX, read),
                entry(5, wgpu::ShaderStages::VERTEX, read),
                entry(6, wgpu::ShaderStages::FRAGMENT, read),
            ],
        });
        let bind_group = bind_group(
            &device,
            &layout,
            [
                &frame_buffer,
                &quad_buffer,
                &heights_buffer,
                &map_buffers[0],
                &map_buffers[1],
                &map_buffers[2],
                &ramp_buffer,
            ],
        );
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let make = |label: &str,
                    fragment: &str,
                    targets: &[Option<wgpu::ColorTargetState>],
                    topology: wgpu::PrimitiveTopology| {
            device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                vertex: wgpu::VertexState {
                    module: &module,
                    entry_point: Some("vs_main"),
                    compilation_options: Default::default(),
                    buffers: &[],
                },
                primitive: wgpu::PrimitiveState { topology, cull_mode: None, ..Default::default() },
                depth_stencil: Some(wgpu::DepthStencilState {
                    format: DEPTH_FORMAT,
                    depth_write_enabled: Some(true),
                    depth_compare: Some(wgpu::CompareFunction::Greater),
                    stencil: Default::default(),
                    bias: Default::default(),
                }),
                multisample: Default::default(),
                fragment: Some(wgpu::FragmentState {
                    module: &module,
                    entry_point: Some(fragment),
                    compilation_options: Default::default(),
                    targets,
                }),
                multiview_mask: None,
                cache: None,
            })
        };
        let target = |format: wgpu::TextureFormat| {
            Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })
        };
        let probe_targets = [target(IMAGE_FORMAT), target(SURFACE_FORMAT), target(ID_FORMAT)];
        let pipeline = make("terrain", "fs_main", &[target(format)], wgpu::PrimitiveTopology::TriangleList);
        let probe_pipeline = make("terrain probe", "fs_probe", &probe_targets, wgpu::PrimitiveTopology::TriangleList);
        let points_pipeline = make("terrain points", "fs_probe", &probe_targets, wgpu::PrimitiveTopology::PointList);

        let flat = flat_rule_for(&scene.ellipsoid, exaggerated_range(&scene, scene.visuals.exaggeration));
        let threads = std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(1, 4);
        let loader = Loader::start(scene.datasets.clone(), scene.ellipsoid, threads);
        let cpu = CpuCache::new((scene.detail.cpu_cache_mib.max(16) << 20) as usize);
        Ok(Renderer {
            device,
            queue: ctx.queue.clone(),
            timestamps: ctx.timestamps,
            pipeline,
            probe_pipeline,
            points_pipeline,
            bind_layout: layout,
            bind_group,
            ramp_buffer,
            frame_buffer,
            quad_buffer,
            heights_buffer,
            map_buffers,
            index_buffer,
            index_count: indices.len() as u32,
            heights_pool: SlotPool::new(height_slots),
            maps_pool: SlotPool::new(map_slots),
            scene,
            loader,
            cpu,
            cache: QuadCache { geometry: HashMap::new(), infos: HashMap::new(), ranges: HashMap::new() },
            flat,
            frame: 0,
            instances: Vec::new(),
            drawn: Vec::new(),
            camera: None,
            size: (1, 1),
        })
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Changes the level-of-detail threshold (pixels per sample).
    pub fn set_threshold(&mut self, threshold_px: f64) {
        self.scene.detail.lod_threshold_px = threshold_px;
    }

    /// Changes how the terrain looks (colour ramp, isolines, lighting, exaggeration, background)
    /// from the next prepared frame on. A new exaggeration changes the flat rule, recomputed here,
    /// and the quads' bounds, which are cached under their exaggerated height range and so
    /// recomputed when next asked for.
    pub fn set_visuals(&mut self, visuals: crate::project::Visuals, ramp: crate::colour::Ramp) {
        if ramp != self.scene.ramp {
            self.ramp_buffer = ramp_buffer(&self.device, &ramp);
            self.bind_group = bind_group(
                &self.device,
                &self.bind_layout,
                [
                    &self.frame_buffer,
                    &self.quad_buffer,
                    &self.heights_buffer,
                    &self.map_buffers[0],
                    &self.map_buffers[1],
                    &self.map_buffers[2],
                    &self.ramp_buffer,
                ],
            );
            self.scene.ramp = ramp;
        }
        if visuals.exaggeration != self.scene.visuals.exaggeration {
            self.flat = flat_rule_for(&self.scene.ellipsoid, exaggerated_range(&self.scene, visuals.exaggeration));
        }
        self.scene.visuals = visuals;
    }

    /// The camera placed for a spec, with a near plane from its clearance over the terrain.
    pub fn camera(&self, spec: &CameraSpec) -> Camera {
        let top = self.scene.range_m.1.max(0.0) * self.scene.visuals.exaggeration;
        Camera::new(&self.scene.ellipsoid, *spec, Camera::near_for(spec.alt - top))
    }

    /// The quads of the last prepared frame, in instance order.
    pub fn drawn(&self) -> &[QuadId] {
        &self.drawn
    }

    /// The per-quad values of the last prepared frame, in instance order.
    pub fn instances(&self) -> &[QuadInstance] {
        &self.instances
    }

    /// The camera of the last prepared frame.
    pub fn last_camera(&self) -> Option<&Camera> {
        self.camera.as_ref()
    }

    /// The exact geometry of a quad with full maps (for tests and the CPU reference).
    pub fn reference_geometry(&self, quad: QuadId) -> QuadGeometry {
        QuadGeometry::cached(
            &self.scene.ellipsoid,
            CubeProjection::Qsc,
            quad,
            SAMPLES,
            &crate::ecm::geometry::MapCache::new(),
            Some(&self.flat),
        )
    }

    /// The heights a quad was drawn with, if still cached on the CPU.
    pub fn cpu_heights(&mut self, quad: QuadId) -> Option<std::sync::Arc<super::data::QuadHeights>> {
        self.cpu.heights(quad)
    }

    /// The flat rule in use.
    pub fn flat_rule(&self) -> &FlatRule {
        &self.flat
    }

    fn take_arrivals(&mut self, errors: &mut Vec<String>) -> usize {
        let arrived = self.loader.drain();
        let n = arrived.len();
        for item in arrived {
            self.absorb(item, errors);
        }
        n
    }

    fn absorb(&mut self, item: Loaded, errors: &mut Vec<String>) {
        match &item {
            Loaded::Heights(q, Ok(h)) => {
                self.cache.ranges.insert(*q, (h.range_m.0, h.range_m.1, h.edge_roughness_m));
            }
            Loaded::Heights(q, Err(e)) => errors.push(format!("quad {q}: {e}")),
            Loaded::Maps(..) => {}
        }
        self.cpu.insert(item);
    }

    /// Fills a GPU slot from the CPU cache; false if the data are not there or no slot is free.
    fn upload(&mut self, key: DataKey) -> bool {
        match key {
            DataKey::Heights(q) => {
                let Some(h) = self.cpu.heights(q) else { return false };
                let Some(slot) = self.heights_pool.allocate(q, self.frame) else { return false };
                let values: Vec<f32> = h.grid.iter().map(|&v| if v.is_nan() { NODATA_STORED } else { v }).collect();
                let offset = u64::from(slot) * u64::from(SAMPLES * SAMPLES) * 4;
                self.queue.write_buffer(&self.heights_buffer, offset, bytemuck::cast_slice(&values));
                true
            }
            DataKey::Maps(q) => {
                let Some(m) = self.cpu.maps(q) else { return false };
                let Some(slot) = self.maps_pool.allocate(q, self.frame) else { return false };
                let offset = u64::from(slot) * u64::from(SAMPLES * SAMPLES) * 12;
                for (buffer, data) in self.map_buffers.iter().zip([&m.displacement_m, &m.normal, &m.normal_delta]) {
                    self.queue.write_buffer(buffer, offset, bytemuck::cast_slice(data));
                }
                true
            }
        }
    }

    /// What a quad still needs on the GPU.
    fn missing_keys(&self, quad: QuadId) -> Vec<DataKey> {
        let mut keys = Vec::new();
        if self.scene.has_data(quad) && self.heights_pool.get(quad).is_none() {
            keys.push(DataKey::Heights(quad));
        }
        let canonical = MapSymmetry::of(quad).canonical;
        if !self.flat.is_flat(quad) && self.maps_pool.get(canonical).is_none() {
            keys.push(DataKey::Maps(canonical));
        }
        keys
    }

    /// Prepares a frame without waiting for anything: takes the data that arrived, selects the
    /// quads, fills GPU slots for the most wanted ones, asks the loader for the rest, and writes
    /// the per-quad values and the frame's uniforms.
    pub fn prepare(&mut self, spec: &CameraSpec, width: u32, height: u32) -> FrameStats {
        let start = Instant::now();
        self.frame += 1;
        let mut stats = FrameStats::default();
        self.take_arrivals(&mut stats.errors);
        let camera = self.camera(spec);
        let exaggeration = self.scene.visuals.exaggeration;
        let lowest = self.scene.range_m.0.min(0.0) * exaggeration;
        let e = self.scene.ellipsoid;
        let params = SelectParams {
            threshold_px: self.scene.detail.lod_threshold_px,
            max_quads: self.scene.detail.max_quads.max(6),
            width,
            height,
            occluder_m: (e.a_m() + lowest, e.b_m() + lowest),
        };
        let t = Instant::now();
        let selection = {
            let mut source = Source {
                scene: &self.scene,
                cache: &mut self.cache,
                heights: &self.heights_pool,
                maps: &self.maps_pool,
                flat: &self.flat,
                exaggeration,
            };
            select::select(&camera, &params, &mut source)
        };
        stats.select_ms = t.elapsed().as_secs_f64() * 1e3;

        // Keep what is drawn and its ancestors; then, in priority order (coarsest and largest first), take wanted
        // quads while their slots fit in what the drawn ones leave free, keep their slots, fill
        // the missing ones from the CPU cache and ask the loader for the rest. Strict priority
        // and no more than fits means slots are never taken from each other in circles.
        // Ancestors stay too: selection walks down through them every frame, and they stand in
        // at once when the view pulls back (a 4-ary tree has at most a third as many inner
        // quads as leaves).
        let mut kept: std::collections::HashSet<QuadId> = selection.quads.iter().copied().collect();
        for q in &selection.quads {
            let mut p = q.parent();
            while let Some(a) = p {
                if !kept.insert(a) {
                    break;
                }
                p = a.parent();
            }
        }
        let mut maps_counted = std::collections::HashSet::new();
        let mut heights_pinned = 0u32;
        for q in &kept {
            if self.heights_pool.touch(*q, self.frame).is_some() {
                heights_pinned += 1;
            }
            let canonical = MapSymmetry::of(*q).canonical;
            if !self.flat.is_flat(*q) && maps_counted.insert(canonical) {
                self.maps_pool.touch(canonical, self.frame);
            }
        }
        let mut free_heights = self.heights_pool.capacity.saturating_sub(heights_pinned);
        let mut free_maps = self.maps_pool.capacity.saturating_sub(maps_counted.len() as u32);
        let mut requests = Vec::new();
        for q in &selection.wanted {
            let has = self.scene.has_data(*q);
            let canonical = MapSymmetry::of(*q).canonical;
            let new_map = !self.flat.is_flat(*q) && !maps_counted.contains(&canonical);
            if u32::from(has) > free_heights || u32::from(new_map) > free_maps {
                stats.blocked += 1;
                break;
            }
            free_heights -= u32::from(has);
            if new_map {
                free_maps -= 1;
                maps_counted.insert(canonical);
                self.maps_pool.touch(canonical, self.frame);
            }
            if has {
                self.heights_pool.touch(*q, self.frame);
            }
            for key in self.missing_keys(*q) {
                if !self.cpu.contains(key) {
                    if !requests.contains(&key) {
                        requests.push(key);
                    }
                } else if stats.uploads < UPLOADS_PER_FRAME && self.upload(key) {
                    stats.uploads += 1;
                }
            }
        }
        stats.requested = requests.len();
        self.loader.request(&requests);
        if stats.uploads > 0 {
            // Hand the writes to the GPU now, so that their staging memory is released even when
            // frames are prepared without being drawn.
            self.queue.submit([]);
            let _ = self.device.poll(wgpu::PollType::Poll);
        }

        // Per-quad values, camera-relative, from f64.
        self.instances.clear();
        for &quad in &selection.quads {
            let has = self.scene.has_data(quad);
            let range = self.cache.range(&self.scene, quad, has, exaggeration);
            let roughness = self.cache.ranges.get(&quad).map_or(0.0, |r| f64::from(r.2));
            let info = self.cache.infos.get(&quad).map(|i| i.1);
            let g = self.cache.geometry(&self.scene, quad);
            let h0 = spec.alt.clamp(f64::from(range.0), f64::from(range.1));
            let frame = QuadFrame::new(&g.corners_ecef, &g.corner_normals, camera.position, h0);
            let symmetry = MapSymmetry::of(quad);
            let m = symmetry.matrix();
            let map_slot = if self.flat.is_flat(quad) {
                NO_SLOT
            } else {
                self.maps_pool.get(symmetry.canonical).unwrap_or(NO_SLOT)
            };
            let height_slot = if has { self.heights_pool.get(quad).unwrap_or(NO_SLOT) } else { NO_SLOT };
            let flags = u32::from(symmetry.swap) | u32::from(symmetry.flip_x) << 1 | u32::from(symmetry.flip_y) << 2;
            let edge_m = info.map_or(0.0, |i| i.edge_m);
            let spacing = edge_m / f64::from(SAMPLES - 1);
            let r_min = e.b_m() * e.b_m() / e.a_m();
            let sag = spacing * spacing / (8.0 * r_min);
            let relief = f64::from(range.1 - range.0);
            let skirt = (8.0 * roughness * exaggeration).min(relief + roughness * exaggeration)
                + 64.0 * sag
                + 1e-3 * spacing
                + 0.01;
            if map_slot == NO_SLOT {
                stats.flat_quads += 1;
            }
            self.instances.push(QuadInstance {
                anchor: v4(frame.anchor, frame.reference_height_m),
                corners: frame.corners.map(|c| v4(c, 0.0)),
                normals: frame.corner_normals.map(|n| v4(n, 0.0)),
                sym: [m.x_axis, m.y_axis, m.z_axis].map(|c| v4(c.as_vec3(), 0.0)),
                slots: [Split::of(quad).code(), map_slot, height_slot, flags],
                params: [skirt as f32, f32::from(quad.level), 0.0, 0.0],
            });
        }
        if !self.instances.is_empty() {
            self.queue.write_buffer(&self.quad_buffer, 0, bytemuck::cast_slice(&self.instances));
        }
        self.write_frame(&camera, width, height);
        self.drawn = selection.quads.clone();
        stats.triangles = self.instances.len() as u64 * TRIANGLES_PER_QUAD;
        stats.pending = selection.wanted.len();
        stats.gpu_slots = (
            self.heights_pool.slots.len(),
            self.heights_pool.capacity,
            self.maps_pool.slots.len(),
            self.maps_pool.capacity,
        );
        stats.cpu_bytes = self.cpu.used_bytes();
        stats.selection = selection;
        stats.prepare_ms = start.elapsed().as_secs_f64() * 1e3;
        self.camera = Some(camera);
        self.size = (width, height);
        stats
    }

    fn write_frame(&self, camera: &Camera, width: u32, height: u32) {
        let v = &self.scene.visuals;
        let iso = &v.isolines;
        let light = &v.lighting;
        let uniform = FrameUniform {
            view_proj: camera.view_projection_f32(width, height).to_cols_array_2d(),
            viewport: [width as f32, height as f32, v.exaggeration as f32, self.scene.ramp.stops.len() as f32],
            sun: [
                light.sun_azimuth_deg.to_radians() as f32,
                light.sun_elevation_deg.to_radians() as f32,
                light.strength as f32,
                if light.enabled { 1.0 } else { 0.0 },
            ],
            iso: [
                iso.interval_m as f32,
                iso.offset_m as f32,
                iso.major_every as f32,
                if iso.enabled { 1.0 } else { 0.0 },
            ],
            iso_width: [iso.width_px, iso.major_width_px, iso.min_width_px, 0.0],
            iso_colour: rgba(iso.colour),
            below: rgba(self.scene.ramp.below),
            above: rgba(self.scene.ramp.above),
            nodata: rgba(self.scene.ramp.nodata),
        };
        self.queue.write_buffer(&self.frame_buffer, 0, bytemuck::bytes_of(&uniform));
    }

    /// Prepares frames until the selection needs nothing more (every wanted quad loaded and on
    /// the GPU), waiting for the loader in between, or until `timeout`; returns the last frame's
    /// statistics. The command line uses it to render a finished frame; an interactive view calls
    /// [`Renderer::prepare`] once per frame instead.
    pub fn settle(&mut self, spec: &CameraSpec, width: u32, height: u32, timeout: Duration) -> FrameStats {
        let start = Instant::now();
        let mut errors = Vec::new();
        let mut stalls = 0;
        for _ in 0..100_000 {
            let mut stats = self.prepare(spec, width, height);
            if std::env::var_os("TERRAFUSE_DEBUG").is_some() {
                eprintln!(
                    "settle: {} drawn, {} pending, {} uploads, {} requested, {} blocked, loader {} / culled {} {} visited {}",
                    stats.selection.quads.len(),
                    stats.pending,
                    stats.uploads,
                    stats.requested,
                    stats.blocked,
                    self.loader.busy(),
                    stats.selection.culled_frustum,
                    stats.selection.culled_horizon,
                    stats.selection.visited
                );
                if std::env::var_os("TERRAFUSE_DEBUG_QUADS").is_some() {
                    eprintln!(
                        "  drawn {:?}\n  wanted {:?}",
                        stats.selection.quads.iter().map(|q| q.to_string()).collect::<Vec<_>>(),
                        stats.selection.wanted.iter().map(|q| q.to_string()).collect::<Vec<_>>()
                    );
                }
            }
            errors.append(&mut stats.errors);
            if stats.pending == 0 || start.elapsed() > timeout {
                stats.errors = errors;
                return stats;
            }
            if stats.uploads == 0 && stats.requested == 0 && self.loader.busy() == 0 {
                // Nothing arriving and nothing fits: the GPU cache is full of this frame's quads.
                stalls += 1;
                if stalls > 2 {
                    stats.errors = errors;
                    return stats;
                }
            } else {
                stalls = 0;
            }
            if stats.uploads == 0
                && let Some(item) = self.loader.wait(Duration::from_millis(200))
            {
                self.absorb(item, &mut errors);
            }
        }
        let mut stats = self.prepare(spec, width, height);
        stats.errors.append(&mut errors);
        stats
    }

    /// Draws the prepared frame into a render pass.
    pub fn draw<'a>(&'a self, pass: &mut wgpu::RenderPass<'a>, mode: DrawMode) {
        if self.instances.is_empty() {
            return;
        }
        let n = self.instances.len() as u32;
        pass.set_bind_group(0, &self.bind_group, &[]);
        match mode {
            DrawMode::Colour | DrawMode::Probe => {
                pass.set_pipeline(if mode == DrawMode::Colour { &self.pipeline } else { &self.probe_pipeline });
                pass.set_index_buffer(self.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
                pass.draw_indexed(0..self.index_count, 0, 0..n);
            }
            DrawMode::Points => {
                pass.set_pipeline(&self.points_pipeline);
                pass.draw(0..MESH_EDGE * MESH_EDGE, 0..n);
            }
        }
    }

    /// Records the prepared frame into `targets`: the colour target cleared to the background,
    /// the probe targets (for [`DrawMode::Probe`] and [`DrawMode::Points`]) to zero, depth to 0
    /// (reversed Z). `timestamps` gets the pass's start and end.
    pub fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        targets: &FrameTargets,
        mode: DrawMode,
        timestamps: Option<&wgpu::QuerySet>,
    ) -> Result<(), String> {
        let probe = mode != DrawMode::Colour;
        if probe && targets.surface.is_none() {
            return Err("a probe pass needs probe targets (FrameTargets::new with probe = true)".into());
        }
        let bg = self.scene.visuals.background.map(|c| crate::colour::srgb_to_linear(f64::from(c)));
        // The colour image is cleared to the background (the shader's output is already
        // sRGB-encoded, and so is the stored clear value of a unorm target).
        let clear = wgpu::Color {
            r: crate::colour::linear_to_srgb(bg[0]),
            g: crate::colour::linear_to_srgb(bg[1]),
            b: crate::colour::linear_to_srgb(bg[2]),
            a: f64::from(self.scene.visuals.background[3]) / 255.0,
        };
        let mut views = vec![(&targets.views[0], clear)];
        if probe {
            views.extend(targets.views[1..].iter().map(|v| (v, wgpu::Color::TRANSPARENT)));
        }
        let attachments: Vec<Option<wgpu::RenderPassColorAttachment>> = views
            .into_iter()
            .map(|(view, clear)| {
                Some(wgpu::RenderPassColorAttachment {
                    view,
                    depth_slice: None,
                    resolve_target: None,
                    ops: wgpu::Operations { load: wgpu::LoadOp::Clear(clear), store: wgpu::StoreOp::Store },
                })
            })
            .collect();
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("terrain"),
            color_attachments: &attachments,
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth_view,
                depth_ops: Some(wgpu::Operations { load: wgpu::LoadOp::Clear(0.0), store: wgpu::StoreOp::Store }),
                stencil_ops: None,
            }),
            timestamp_writes: timestamps.map(|q| wgpu::RenderPassTimestampWrites {
                query_set: q,
                beginning_of_pass_write_index: Some(0),
                end_of_pass_write_index: Some(1),
            }),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.draw(&mut pass, mode);
        Ok(())
    }

    /// Draws the prepared frame into an image and reads it back.
    pub fn render_image(&self, mode: DrawMode) -> Result<RenderedImage, String> {
        let (width, height) = self.size;
        let device = &self.device;
        let probe = mode != DrawMode::Colour;
        let frame = FrameTargets::new(device, width, height, probe, wgpu::TextureUsages::COPY_SRC);
        let mut targets = vec![(&frame.colour, 4u32)];
        if let (Some(surface), Some(ids)) = (&frame.surface, &frame.ids) {
            targets.push((surface, 16));
            targets.push((ids, 16));
        }
        let queries = self.timestamps.then(|| {
            device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("pass time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            })
        });
        let mut encoder = device.create_command_encoder(&Default::default());
        self.encode(&mut encoder, &frame, mode, queries.as_ref())?;
        let readback = |bytes_per_pixel: u32| {
            let row = (width * bytes_per_pixel).div_ceil(256) * 256;
            let buffer = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("readback"),
                size: u64::from(row) * u64::from(height),
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            (buffer, row)
        };
        let mut reads = Vec::new();
        for (texture, bpp) in targets {
            let (buffer, row) = readback(bpp);
            encoder.copy_texture_to_buffer(
                texture.as_image_copy(),
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: 0,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(height),
                    },
                },
                wgpu::Extent3d { width, height, depth_or_array_layers: 1 },
            );
            reads.push((buffer, row, bpp));
        }
        let time_buffers = queries.as_ref().map(|q| {
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            let read = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("timestamps read"),
                size: 16,
                usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                mapped_at_creation: false,
            });
            encoder.resolve_query_set(q, 0..2, &resolve, 0);
            encoder.copy_buffer_to_buffer(&resolve, 0, &read, 0, 16);
            read
        });
        self.queue.submit([encoder.finish()]);
        let mut mapped: Vec<&wgpu::Buffer> = reads.iter().map(|r| &r.0).collect();
        mapped.extend(time_buffers.iter());
        for b in &mapped {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                if let Err(e) = r {
                    eprintln!("terrafuse: reading back from the GPU failed: {e}");
                }
            });
        }
        device.poll(wgpu::PollType::wait_indefinitely()).map_err(|e| format!("GPU did not finish: {e}"))?;
        let unpad = |(buffer, row, bpp): &(wgpu::Buffer, u32, u32)| -> Vec<u8> {
            let data = buffer.slice(..).get_mapped_range().expect("mapped above");
            let mut out = Vec::with_capacity((width * height * bpp) as usize);
            for y in 0..height as usize {
                let start = y * *row as usize;
                out.extend_from_slice(&data[start..start + (width * bpp) as usize]);
            }
            out
        };
        let rgba = unpad(&reads[0]);
        let surface = probe.then(|| bytemuck::cast_slice::<u8, [f32; 4]>(&unpad(&reads[1])).to_vec());
        let ids = probe.then(|| bytemuck::cast_slice::<u8, [u32; 4]>(&unpad(&reads[2])).to_vec());
        let gpu_ms = time_buffers.map(|b| {
            let data = b.slice(..).get_mapped_range().expect("mapped above");
            let t: &[u64] = bytemuck::cast_slice(&data);
            (t[1].saturating_sub(t[0])) as f64 * f64::from(self.queue.get_timestamp_period()) / 1e6
        });
        Ok(RenderedImage { width, height, rgba, surface, ids, gpu_ms })
    }
}
