//! The renderer: the GPU cache (fixed pools of height and map slots, least recently used evicted,
//! never one drawn this frame), per-frame preparation (arrivals, selection, uploads, requests,
//! per-quad camera-relative values) and drawing to any colour target or to an image. The device
//! is in `context`, the targets and read-back in `targets`, the pipelines in `terrain`, the
//! shader structs' twins in `uniforms`, the slot pools in `slots`, the selection's data side in
//! `quads`; the layer stack's side of the renderer (composition, layer edits) in `stack`. Strokes,
//! erosion runs and undo belong to the editing session ([`crate::gpu::editing`]) that drives it.

use std::collections::HashMap;
use std::time::{Duration, Instant};

mod compose_here;
mod draw;
mod frame;
mod prepare;
mod stack;

use super::compose::{ComposeBatch, ComposeOn, ComposePass};
use super::context::{GpuContext, GpuError};
use super::patch_errors::{ErrorJob, ErrorKey, MAX_JOBS, PatchErrorPass, QuadErrors};
use super::terrain::{TerrainPass, ramp_buffer};
use super::uniforms::{FrameUniform, NO_SLOT, PatchInstance, QuadInstance, rgba, v4};
use crate::ecm::geometry::{FlatRule, MapSymmetry, QuadFrame, QuadGeometry, Split};
use crate::ecm::grid::spacing_m;
use crate::ecm::{CubeProjection, QuadId};
use crate::layers::{LayerError, LayerSpec};
use crate::project::CameraSpec;
use crate::scene::Camera;
use crate::scene::Scene;
use crate::scene::loader::{CpuCache, DataKey, Loaded, Loader, SAMPLES};
use crate::scene::patches::{
    DATA_LEVELS_UP, MORPH_BAND_END, MORPH_BAND_START, PATCHES_PER_EDGE, PatchSelection, QuadPatches, STRIDES,
    effective_errors, select_patches,
};
use crate::scene::quads::{QuadCache, Source, exaggerated_range, flat_rule_for};
use crate::scene::select::{self, SelectParams, Selection};
use crate::scene::slots::SlotPool;

/// Stored for a sample without data (the shader tests `< -1e37`).
const NODATA_STORED: f32 = -3.0e37;
/// The height a vertex without data is drawn at, metres.
const NO_DATA_FILL_M: f32 = 0.0;
/// Most slots filled per frame, so that a burst of arrivals never stalls one.
const UPLOADS_PER_FRAME: usize = 48;
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
    /// Quads that would be refined if their data were on the GPU, and drawn quads still shown
    /// with heights of an older stack while their new ones wait for data.
    pub pending: usize,
    /// Data asked of the loader this frame.
    pub requested: usize,
    /// 1 when wanted quads were left out because the GPU cache is full of this frame's quads.
    pub blocked: usize,
    /// Triangles drawn (patch grids and skirts).
    pub triangles: u64,
    /// The largest projected geometric error of what was drawn, pixels (computed in f64 from
    /// the patches' δ).
    pub max_error_px: f64,
    /// Pixels of the frame (width × height).
    pub pixels: u64,
    /// Drawn quads whose patches' errors are not back from the GPU yet (drawn meanwhile with a
    /// bound from their height range).
    pub errors_pending: usize,
    /// The patches of the drawn quads: drawn (per stride) and culled.
    pub patches: PatchSelection,
    /// Quads drawn without static maps (past the flat rule).
    pub flat_quads: usize,
    /// GPU cache: height and map slots in use, of the capacity.
    pub gpu_slots: (usize, u32, usize, u32),
    /// CPU cache bytes in use.
    pub cpu_bytes: usize,
    /// Quads composed this frame.
    pub composed: Vec<QuadId>,
    /// Layers those compositions read (invisible, transparent and distant layers are not).
    pub layers_read: usize,
    /// Errors reading data (named), since the last frame.
    pub errors: Vec<String>,
}

/// What composition has done since the renderer started (tests prove caching with these).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct ComposeCounters {
    /// Quads composed.
    pub quads: u64,
    /// Layers read over those compositions.
    pub layers_read: u64,
    /// Source tiles uploaded to the GPU.
    pub sources_uploaded: u64,
}
/// The overlay pool: `slots` quads of 257² f32 (0: a 16-byte stand-in).
fn overlay_buffer(device: &wgpu::Device, slots: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("overlay"),
        size: if slots == 0 { 16 } else { slots * u64::from(SAMPLES * SAMPLES) * 4 },
        // Written by the compute pass or, composed on the CPU, by the queue; read back by tools.
        usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    })
}

/// Loader threads: the cores, at most 4.
fn loader_threads() -> usize {
    std::thread::available_parallelism().map_or(2, |n| n.get()).clamp(1, 4)
}

/// The terrain renderer.
pub struct Renderer {
    device: wgpu::Device,
    queue: wgpu::Queue,
    timestamps: bool,
    terrain: TerrainPass,
    bind_group: wgpu::BindGroup,
    ramp_buffer: wgpu::Buffer,
    frame_buffer: wgpu::Buffer,
    quad_buffer: wgpu::Buffer,
    /// The drawn patches' records, grouped by stride.
    patch_buffer: wgpu::Buffer,
    heights_buffer: wgpu::Buffer,
    /// A − B of the drawn difference layer, one slot per height slot (a stand-in of one sample
    /// until a difference is drawn).
    overlay_buffer: wgpu::Buffer,
    sources_buffer: wgpu::Buffer,
    map_buffers: [wgpu::Buffer; 3],
    heights_pool: SlotPool,
    sources_pool: SlotPool<DataKey>,
    maps_pool: SlotPool,
    /// Per composed height slot, the stamp of the plan it was composed from.
    composed: HashMap<QuadId, u64>,
    /// The patches' geometric errors on the GPU, and those that came back, per quad.
    error_pass: PatchErrorPass,
    errors: HashMap<QuadId, (ErrorKey, QuadErrors)>,
    compose: ComposePass,
    /// Where frames compose their quads (`compose_now` always on the GPU).
    compose_on: ComposeOn,
    /// The frame's quads to compose on the CPU (with `compose_on` the CPU).
    cpu_jobs: Vec<compose_here::CpuJob>,
    counters: ComposeCounters,
    scene: Scene,
    loader: Loader,
    cpu: CpuCache,
    cache: QuadCache,
    flat: FlatRule,
    frame: u64,
    instances: Vec<QuadInstance>,
    drawn: Vec<QuadId>,
    /// The prepared frame's patches.
    patches: PatchSelection,
    /// The prepared frame's patch boxes at each stride, per drawn quad.
    patch_boxes: Vec<crate::scene::quads::PatchBoxes>,
    /// Whether patches are culled and drawn at the stride they need (else every patch of a drawn
    /// quad at stride 1: the quads whole).
    adaptive: bool,
    /// Whether vertices morph toward the coarser stride's mesh (only with adaptive patches).
    geomorph: bool,
    camera: Option<Camera>,
    size: (u32, u32),
    /// The drawn difference's range from its percentile (set by the tool that computed it).
    auto_range_m: Option<f64>,
    /// The brush's footprint to draw: centre (ECEF) and radius, metres.
    brush: Option<(glam::DVec3, f64)>,
}

impl Renderer {
    /// A renderer of `scene` on a device, drawing into targets of `format` (the window's, or
    /// [`IMAGE_FORMAT`] for images).
    pub fn new(ctx: &GpuContext, scene: Scene, format: wgpu::TextureFormat) -> Result<Renderer, GpuError> {
        let device = ctx.device.clone();
        // GPU cache: 10 % of the budget for composed heights and 10 % for raw source tiles (4
        // bytes a sample each), the rest for the three maps (36 bytes a sample), each buffer
        // within the device's largest storage binding.
        let limit = device.limits().max_storage_buffer_binding_size.min(device.limits().max_buffer_size);
        let budget = scene.detail.gpu_cache_mib.max(16) << 20;
        let height_slot = u64::from(SAMPLES * SAMPLES) * 4;
        let map_slot = u64::from(SAMPLES * SAMPLES) * 12;
        let height_slots = ((budget * 10 / 100) / height_slot).min(limit / height_slot).max(8) as u32;
        let map_slots = ((budget * 80 / 100) / (3 * map_slot)).min(limit / map_slot).max(8) as u32;
        let storage = |label: &str, size: u64| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        // Composed heights are read back by tools and tests (`read_heights`).
        let heights_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("heights"),
            size: u64::from(height_slots) * height_slot,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let sources_buffer = storage("sources", u64::from(height_slots) * height_slot);
        let overlay_buffer = overlay_buffer(&device, 0);
        let map_buffers = ["map o", "map n", "map dn"].map(|l| storage(l, u64::from(map_slots) * map_slot));
        let max_quads = scene.detail.max_quads.max(6);
        let quad_buffer = storage("quads", (max_quads * std::mem::size_of::<QuadInstance>()) as u64);
        let patches_per_quad = (PATCHES_PER_EDGE * PATCHES_PER_EDGE) as usize;
        let patch_buffer =
            storage("patches", (max_quads * patches_per_quad * std::mem::size_of::<PatchInstance>()) as u64);
        let frame_buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("frame"),
            size: std::mem::size_of::<FrameUniform>() as u64,
            usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let ramp_buffer = ramp_buffer(&device, &scene.ramp);
        let terrain = TerrainPass::new(&device, format)?;
        let compose = ComposePass::new(&device)?;
        let error_pass = PatchErrorPass::new(&device, &heights_buffer)?;
        let bind_group = terrain.bind_group(
            &device,
            [
                &frame_buffer,
                &quad_buffer,
                &heights_buffer,
                &map_buffers[0],
                &map_buffers[1],
                &map_buffers[2],
                &ramp_buffer,
                &overlay_buffer,
                &patch_buffer,
            ],
        );

        let flat = flat_rule_for(&scene.ellipsoid, exaggerated_range(&scene, scene.visuals.exaggeration));
        let loader = Loader::start(scene.datasets.clone(), scene.ellipsoid, loader_threads());
        let cpu = CpuCache::new((scene.detail.cpu_cache_mib.max(16) << 20) as usize);
        Ok(Renderer {
            device,
            queue: ctx.queue.clone(),
            timestamps: ctx.timestamps,
            terrain,
            bind_group,
            ramp_buffer,
            frame_buffer,
            quad_buffer,
            patch_buffer,
            heights_buffer,
            overlay_buffer,
            sources_buffer,
            map_buffers,
            heights_pool: SlotPool::new(height_slots),
            sources_pool: SlotPool::new(height_slots),
            maps_pool: SlotPool::new(map_slots),
            composed: HashMap::new(),
            error_pass,
            errors: HashMap::new(),
            compose,
            compose_on: ComposeOn::for_adapter(ctx.info.device_type),
            cpu_jobs: Vec::new(),
            counters: ComposeCounters::default(),
            scene,
            loader,
            cpu,
            cache: QuadCache::default(),
            flat,
            frame: 0,
            instances: Vec::new(),
            drawn: Vec::new(),
            patches: PatchSelection::default(),
            patch_boxes: Vec::new(),
            adaptive: true,
            geomorph: true,
            camera: None,
            size: (1, 1),
            auto_range_m: None,
            brush: None,
        })
    }

    /// Whether patches are culled and drawn at the stride they need (the default), or every
    /// patch of a drawn quad at stride 1 (the quads whole, as before patches: for comparisons).
    pub fn set_adaptive_patches(&mut self, adaptive: bool) {
        self.adaptive = adaptive;
    }

    /// Whether vertices morph toward the coarser stride's mesh over the band before a patch's
    /// stride changes (the default), so that a change of stride draws what was drawn before.
    pub fn set_geomorph(&mut self, geomorph: bool) {
        self.geomorph = geomorph;
    }

    /// Where frames compose their quads: by default the compute pass on a hardware adapter and
    /// the CPU reference on a software one ([`ComposeOn::for_adapter`]). Quads composed before
    /// stay as they are until their plans change.
    pub fn set_compose_on(&mut self, on: ComposeOn) {
        self.compose_on = on;
    }

    /// Where frames compose their quads.
    pub fn compose_on(&self) -> ComposeOn {
        self.compose_on
    }

    /// Whether the frames morph (geomorphing on and adaptive patches).
    pub fn geomorphs(&self) -> bool {
        self.geomorph && self.adaptive
    }

    /// The prepared frame's image size.
    pub fn size(&self) -> (u32, u32) {
        self.size
    }

    /// The prepared frame's patches.
    pub fn patches(&self) -> &PatchSelection {
        &self.patches
    }

    /// The scene.
    pub fn scene(&self) -> &Scene {
        &self.scene
    }

    /// Changes the scene (an editing session's strokes and runs: [`crate::gpu::editing`]); the
    /// quads whose plans changed are recomposed from the next prepared frame on.
    pub fn with_scene<T>(&mut self, change: impl FnOnce(&mut Scene) -> T) -> T {
        let out = change(&mut self.scene);
        self.cache.plans.clear();
        out
    }

    /// Changes the geometric error the mesh may show on screen (pixels, τ).
    pub fn set_pixel_error(&mut self, max_pixel_error: f64) {
        self.scene.detail.max_pixel_error = max_pixel_error;
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
            self.rebind();
            self.scene.ramp = ramp;
        }
        if visuals.exaggeration != self.scene.visuals.exaggeration {
            self.flat = flat_rule_for(&self.scene.ellipsoid, exaggerated_range(&self.scene, visuals.exaggeration));
        }
        self.scene.visuals = visuals;
    }

    /// Sets the drawn difference layer's range from its percentile, metres (what
    /// [`crate::compare::difference_range`] found; a `range_m` in its style overrides it).
    pub fn set_difference_range(&mut self, range_m: Option<f64>) {
        self.auto_range_m = range_m.filter(|r| r.is_finite() && *r > 0.0);
    }

    /// The drawn difference layer's range, metres: its style's `range_m`, else the one set from
    /// its percentile, else (until that is known) 1 % of the height span of the layers its
    /// operands read (at least 1 m).
    pub fn difference_range_m(&self) -> f64 {
        let stack = &self.scene.stack;
        let Some(d) = stack.drawn_difference() else { return 1.0 };
        let spec = &stack.layers[d].spec;
        if let Some(r) = spec.difference_style().range_m.or(self.auto_range_m) {
            return r;
        }
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        for name in spec.as_difference().iter().flat_map(|d| d.of.iter()).flat_map(|o| o.names()) {
            if let Some(i) = stack.index_of(name) {
                let (a, b) = stack.layers[i].value_range_m();
                (lo, hi) = (lo.min(a), hi.max(b));
            }
        }
        if hi > lo { ((hi - lo) / 100.0).max(1.0) } else { 1.0 }
    }

    /// Draws the brush's footprint (a ring of its radius around a surface point, ECEF) from the
    /// next prepared frame on, or none.
    pub fn set_brush_ring(&mut self, ring: Option<(glam::DVec3, f64)>) {
        self.brush = ring;
    }

    /// Rebuilds the terrain's bind group (after a buffer it binds was replaced).
    fn rebind(&mut self) {
        self.bind_group = self.terrain.bind_group(
            &self.device,
            [
                &self.frame_buffer,
                &self.quad_buffer,
                &self.heights_buffer,
                &self.map_buffers[0],
                &self.map_buffers[1],
                &self.map_buffers[2],
                &self.ramp_buffer,
                &self.overlay_buffer,
                &self.patch_buffer,
            ],
        );
    }

    /// Gives the overlay pool a slot per height slot once a difference layer is drawn (it costs
    /// one sample until then); the quads composed before it have no difference and are
    /// composed anew.
    fn ensure_overlay(&mut self) {
        if self.scene.stack.drawn_difference().is_none() || self.overlay_buffer.size() > 16 {
            return;
        }
        self.overlay_buffer = overlay_buffer(&self.device, u64::from(self.heights_pool.capacity));
        self.rebind();
        self.composed.clear();
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

    /// The box by which the prepared frame culled patch (px, py) of its `index`-th drawn quad at
    /// `stride`: it holds every vertex the patch draws there.
    pub fn patch_box(&self, index: usize, px: u32, py: u32, stride: u32) -> Option<crate::ecm::geometry::QuadBounds> {
        let k = crate::scene::patches::stride_index(stride);
        self.patch_boxes.get(index)?.get((py * PATCHES_PER_EDGE + px) as usize)?.get(k).copied()
    }

    /// A quad's height range as quad selection bounds it (exaggerated metres).
    pub fn quad_height_range(&mut self, quad: QuadId) -> (f32, f32) {
        let plan = self.cache.plan(&self.scene, quad);
        self.cache.range(&self.scene, &plan, self.scene.visuals.exaggeration)
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
            Loaded::Tile(DataKey::Source(d, q), Ok(h)) => {
                self.cache.note_tile(*d, *q, h);
            }
            Loaded::Tile(key, Err(e)) => {
                let d = key.dataset().unwrap_or(0) as usize;
                errors.push(format!("dataset '{}', {key}: {e}", self.scene.datasets[d].dataset))
            }
            Loaded::Tile(..) => {}
            Loaded::Maps(..) => {}
        }
        self.cpu.insert(item);
    }

    /// Takes the patch errors that came back from the GPU; forgets those of quads no longer
    /// resident once they outnumber the height slots.
    fn take_patch_errors(&mut self) {
        let _ = self.device.poll(wgpu::PollType::Poll);
        for (quad, key, errors) in self.error_pass.take_ready() {
            self.errors.insert(quad, (key, errors));
        }
        if self.errors.len() > 2 * self.heights_pool.capacity as usize {
            self.errors.retain(|q, _| self.heights_pool.get(*q).is_some());
        }
    }

    /// A quad's patch errors as the GPU computed them (true metres, per patch and stride), if
    /// they are back and current: for tests.
    pub fn patch_errors(&self, quad: QuadId) -> Option<&[[f32; STRIDES.len()]]> {
        self.errors.get(&quad).map(|(_, e)| e.as_slice())
    }

    /// Fills a GPU slot from the CPU cache; false if the data are not there or no slot is free.
    fn upload(&mut self, key: DataKey) -> bool {
        match key {
            DataKey::Source(..) | DataKey::Edge(..) | DataKey::Edit(..) => {
                let Some(h) = self.cpu.tile(key) else { return false };
                let Some(slot) = self.sources_pool.allocate(key, self.frame) else { return false };
                let values: Vec<f32> = h.grid.iter().map(|&v| if v.is_nan() { NODATA_STORED } else { v }).collect();
                let offset = u64::from(slot) * u64::from(SAMPLES * SAMPLES) * 4;
                self.queue.write_buffer(&self.sources_buffer, offset, bytemuck::cast_slice(&values));
                self.counters.sources_uploaded += 1;
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

    /// The quad's static maps, if it needs them and they are not on the GPU.
    fn missing_maps(&self, quad: QuadId) -> Option<DataKey> {
        let canonical = MapSymmetry::of(quad).canonical;
        (!self.flat.is_flat(quad) && self.maps_pool.get(canonical).is_none()).then_some(DataKey::Maps(canonical))
    }

    /// Prepares frames until the selection needs nothing more (every wanted quad loaded and on
    /// the GPU), waiting for the loader in between, or until `timeout`; returns the last frame's
    /// statistics. The command line uses it to render a finished frame; an interactive view calls
    /// [`Renderer::prepare`] once per frame instead.
    pub fn settle(&mut self, spec: &CameraSpec, width: u32, height: u32, timeout: Duration) -> FrameStats {
        self.settle_traced(spec, width, height, timeout, &mut |_, _| {})
    }

    /// [`Renderer::settle`], showing each waiting step to `trace` (its statistics and the
    /// loader's requests waiting or in flight): for tools that report what a view waits for.
    pub fn settle_traced(
        &mut self,
        spec: &CameraSpec,
        width: u32,
        height: u32,
        timeout: Duration,
        trace: &mut dyn FnMut(&FrameStats, usize),
    ) -> FrameStats {
        let start = Instant::now();
        let mut errors = Vec::new();
        let mut stalls = 0;
        for _ in 0..100_000 {
            let mut stats = self.prepare(spec, width, height);
            trace(&stats, self.loader.busy());
            errors.append(&mut stats.errors);
            if stats.pending == 0 || start.elapsed() > timeout {
                stats.errors = errors;
                return stats;
            }
            if stats.uploads == 0 && stats.requested == 0 && stats.composed.is_empty() && self.loader.busy() == 0 {
                // Nothing arriving and nothing fits: the GPU cache is full of this frame's quads.
                stalls += 1;
                if stalls > 2 {
                    stats.errors = errors;
                    return stats;
                }
            } else {
                stalls = 0;
            }
            if stats.errors_pending > 0 && self.error_pass.pending().next().is_some() {
                // The patches' errors are computing: wait for the GPU, not the loader.
                let _ = self.device.poll(wgpu::PollType::wait_indefinitely());
                continue;
            }
            if stats.uploads == 0
                && stats.composed.is_empty()
                && let Some(item) = self.loader.wait(Duration::from_millis(200))
            {
                self.absorb(item, &mut errors);
            }
        }
        let mut stats = self.prepare(spec, width, height);
        stats.errors.append(&mut errors);
        stats
    }
}
