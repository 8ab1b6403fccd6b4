//! The 3-D viewport of the workstation: the renderer draws into its own targets (colour with
//! the probe's surface position and ids) on eframe's device, the colour target is shown as an
//! egui-wgpu native texture, and a few probe pixels (under the cursor, at the centre) and the
//! pass's GPU time come back asynchronously, never stalling the frame.

use crate::gui::GuiError;
use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use glam::DVec3;

use crate::ecm::QuadId;
use crate::gpu::{DrawMode, FrameStats, FrameTargets, Renderer};

const IDLE: u8 = 0;
const MAPPING: u8 = 1;
const READY: u8 = 2;
const FAILED: u8 = 3;

/// A small buffer read back from the GPU without waiting: `begin` after the copy is submitted,
/// `take` on a later frame once the mapping has completed.
struct Readback {
    buffer: wgpu::Buffer,
    state: Arc<AtomicU8>,
}

impl Readback {
    fn new(device: &wgpu::Device, label: &str, size: u64) -> Readback {
        let buffer = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        Readback { buffer, state: Arc::new(AtomicU8::new(IDLE)) }
    }

    fn idle(&self) -> bool {
        self.state.load(Ordering::Acquire) == IDLE
    }

    fn begin(&self) {
        self.state.store(MAPPING, Ordering::Release);
        let state = self.state.clone();
        self.buffer.slice(..).map_async(wgpu::MapMode::Read, move |r| {
            state.store(if r.is_ok() { READY } else { FAILED }, Ordering::Release);
        });
    }

    fn take(&self) -> Option<Vec<u8>> {
        match self.state.load(Ordering::Acquire) {
            READY => {
                let bytes = self.buffer.slice(..).get_mapped_range().ok().map(|d| d.to_vec());
                self.buffer.unmap();
                self.state.store(IDLE, Ordering::Release);
                bytes
            }
            FAILED => {
                self.state.store(IDLE, Ordering::Release);
                None
            }
            _ => None,
        }
    }
}

/// What the probe found at one pixel of the last rendered frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Hit {
    /// The pixel, in target pixels.
    pub pixel: (u32, u32),
    /// The surface point, ECEF metres.
    pub ecef: DVec3,
    /// Its height (the data's, before exaggeration), metres.
    pub height_m: f64,
    /// Whether the sample has data (false where the ellipsoid stands in).
    pub has_data: bool,
    /// The quad drawn there.
    pub quad: Option<QuadId>,
}

/// Bytes between probe records in the read-back buffer (copy offsets must be 256-aligned).
const PROBE_STRIDE: u64 = 256;

/// A query's answers: each pixel asked and the surface point there (None where nothing is drawn).
pub type Answers = Vec<((u32, u32), Option<DVec3>)>;

/// The most pixels one query reads back (a stroke's path points of a frame or two).
pub const QUERY_MAX: usize = 256;

/// The surface points asked for at pixels of the last rendered frame (a stroke's path), read
/// back without waiting, like the probe.
struct Queries {
    read: Readback,
    /// The eye of the frame the pending query reads, and its pixels.
    asked: Option<(DVec3, Vec<(u32, u32)>)>,
    /// What came back and was not taken yet.
    done: Option<Answers>,
}

/// The viewport's targets, their egui texture and the pending read-backs.
pub struct Viewport {
    targets: FrameTargets,
    /// The colour target as egui knows it.
    pub texture: egui::TextureId,
    probe: Readback,
    /// The frame and pixels the pending probe read.
    probe_frame: Option<ProbeFrame>,
    timing: Option<(wgpu::QuerySet, wgpu::Buffer, Readback)>,
    /// The last probe results: under the cursor and at the centre.
    pub hits: [Option<Hit>; 2],
    /// GPU time of the last measured pass, milliseconds.
    pub gpu_ms: Option<f64>,
    /// Eye and quads of the last rendered frame (probes copied later read that frame).
    rendered: Option<(DVec3, Vec<QuadId>)>,
    queries: Queries,
}

/// What a probe read: the eye of its frame (positions are relative to it), the pixels (cursor,
/// centre) and the frame's quads (ids index them).
struct ProbeFrame {
    eye: DVec3,
    pixels: [(u32, u32); 2],
    drawn: Vec<QuadId>,
}

impl Viewport {
    /// A viewport of `width` × `height` pixels on the window's device.
    pub fn new(rs: &egui_wgpu::RenderState, width: u32, height: u32) -> Viewport {
        let device = &rs.device;
        let targets = targets(device, width, height);
        let texture =
            rs.renderer.write().register_native_texture(device, targets.colour_view(), wgpu::FilterMode::Linear);
        let timing = device.features().contains(wgpu::Features::TIMESTAMP_QUERY).then(|| {
            let set = device.create_query_set(&wgpu::QuerySetDescriptor {
                label: Some("viewport pass time"),
                ty: wgpu::QueryType::Timestamp,
                count: 2,
            });
            let resolve = device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("viewport timestamps"),
                size: 16,
                usage: wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            });
            (set, resolve, Readback::new(device, "viewport timestamps read", 16))
        });
        Viewport {
            targets,
            texture,
            probe: Readback::new(device, "viewport probe", 3 * PROBE_STRIDE),
            probe_frame: None,
            timing,
            hits: [None, None],
            gpu_ms: None,
            rendered: None,
            queries: Queries {
                read: Readback::new(device, "viewport queries", QUERY_MAX as u64 * PROBE_STRIDE),
                asked: None,
                done: None,
            },
        }
    }

    /// Asks for the surface points (ECEF) under `pixels` (target pixels, at most [`QUERY_MAX`])
    /// of the last rendered frame; false while an earlier query has not come back (ask again on
    /// a later frame) or before the first frame.
    pub fn query(&mut self, rs: &egui_wgpu::RenderState, pixels: &[(u32, u32)]) -> bool {
        let (Some(surface), Some((eye, _))) = (&self.targets.surface, &self.rendered) else {
            return false;
        };
        if !self.queries.read.idle() || self.queries.asked.is_some() || pixels.is_empty() {
            return false;
        }
        let (w, h) = self.size();
        let pixels: Vec<(u32, u32)> =
            pixels.iter().take(QUERY_MAX).map(|&(x, y)| (x.min(w - 1), y.min(h - 1))).collect();
        let mut encoder = rs.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("query") });
        for (k, &(x, y)) in pixels.iter().enumerate() {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: surface,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x, y, z: 0 },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.queries.read.buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: k as u64 * PROBE_STRIDE,
                        bytes_per_row: None,
                        rows_per_image: None,
                    },
                },
                wgpu::Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
            );
        }
        rs.queue.submit([encoder.finish()]);
        self.queries.read.begin();
        self.queries.asked = Some((*eye, pixels));
        true
    }

    /// The last query's answers once they came back (in the order asked): each pixel and the
    /// surface point there (None where nothing was drawn).
    pub fn take_queried(&mut self) -> Option<Answers> {
        self.queries.done.take()
    }

    /// Whether a query is in flight or its answers are waiting to be taken.
    pub fn querying(&self) -> bool {
        self.queries.asked.is_some() || self.queries.done.is_some()
    }

    /// The target size, pixels.
    pub fn size(&self) -> (u32, u32) {
        (self.targets.width, self.targets.height)
    }

    /// Resizes the targets (and the egui texture) when the size changed; true if it did.
    pub fn resize(&mut self, rs: &egui_wgpu::RenderState, width: u32, height: u32) -> bool {
        if (width, height) == self.size() || width == 0 || height == 0 {
            return false;
        }
        self.targets = targets(&rs.device, width, height);
        rs.renderer.write().update_egui_texture_from_wgpu_texture(
            &rs.device,
            self.targets.colour_view(),
            wgpu::FilterMode::Linear,
            self.texture,
        );
        self.rendered = None;
        true
    }

    /// Draws the renderer's prepared frame into the targets and probes `pixels` (cursor,
    /// centre) of it.
    pub fn render(
        &mut self,
        rs: &egui_wgpu::RenderState,
        renderer: &Renderer,
        pixels: [(u32, u32); 2],
    ) -> Result<(), GuiError> {
        let mut encoder = rs.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("viewport") });
        let timed = self.timing.as_ref().is_some_and(|t| t.2.idle());
        let timing = self.timing.as_ref().filter(|_| timed);
        renderer.encode(&mut encoder, &self.targets, DrawMode::Probe, timing.map(|t| &t.0))?;
        if let Some((set, resolve, read)) = timing {
            encoder.resolve_query_set(set, 0..2, resolve, 0);
            encoder.copy_buffer_to_buffer(resolve, 0, &read.buffer, 0, 16);
        }
        let eye = renderer.last_camera().map_or(DVec3::ZERO, |c| c.position);
        self.rendered = Some((eye, renderer.drawn().to_vec()));
        let probing = self.copy_probe(&mut encoder, pixels);
        rs.queue.submit([encoder.finish()]);
        if let Some((_, _, read)) = self.timing.as_ref().filter(|_| timed) {
            read.begin();
        }
        if probing {
            self.probe.begin();
        }
        Ok(())
    }

    /// Probes `pixels` of the last rendered frame without drawing (the cursor moved); false if
    /// the previous probe has not come back yet.
    pub fn probe(&mut self, rs: &egui_wgpu::RenderState, pixels: [(u32, u32); 2]) -> bool {
        let mut encoder = rs.device.create_command_encoder(&wgpu::CommandEncoderDescriptor { label: Some("probe") });
        if !self.copy_probe(&mut encoder, pixels) {
            return false;
        }
        rs.queue.submit([encoder.finish()]);
        self.probe.begin();
        true
    }

    fn copy_probe(&mut self, encoder: &mut wgpu::CommandEncoder, pixels: [(u32, u32); 2]) -> bool {
        let (Some(surface), Some(ids), Some((eye, drawn))) = (&self.targets.surface, &self.targets.ids, &self.rendered)
        else {
            return false;
        };
        if !self.probe.idle() {
            return false;
        }
        let (w, h) = self.size();
        let pixels = pixels.map(|(x, y)| (x.min(w - 1), y.min(h - 1)));
        let copy = |encoder: &mut wgpu::CommandEncoder, texture: &wgpu::Texture, (x, y): (u32, u32), slot: u64| {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture,
                    mip_level: 0,
                    origin: wgpu::Origin3d { x, y, z: 0 },
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &self.probe.buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset: slot * PROBE_STRIDE,
                        bytes_per_row: None,
                        rows_per_image: None,
                    },
                },
                wgpu::Extent3d { width: 1, height: 1, depth_or_array_layers: 1 },
            );
        };
        copy(encoder, surface, pixels[0], 0);
        copy(encoder, surface, pixels[1], 1);
        copy(encoder, ids, pixels[0], 2);
        self.probe_frame = Some(ProbeFrame { eye: *eye, pixels, drawn: drawn.clone() });
        true
    }

    /// Takes what came back from the GPU since the last call; true if anything did.
    pub fn collect(&mut self, rs: &egui_wgpu::RenderState) -> bool {
        let _ = rs.device.poll(wgpu::PollType::Poll);
        let mut any = false;
        if let Some(bytes) = self.probe.take()
            && let Some(ProbeFrame { eye, pixels, drawn }) = self.probe_frame.take()
        {
            let surface = |slot: usize| -> [f32; 4] {
                let o = slot * PROBE_STRIDE as usize;
                bytemuck::pod_read_unaligned(&bytes[o..o + 16])
            };
            let ids: [u32; 4] = bytemuck::pod_read_unaligned(&bytes[2 * PROBE_STRIDE as usize..][..16]);
            for (k, pixel) in pixels.into_iter().enumerate() {
                let s = surface(k);
                let rel = DVec3::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2]));
                // Nothing drawn there: the targets are cleared to zero.
                self.hits[k] = (rel != DVec3::ZERO).then(|| Hit {
                    pixel,
                    ecef: eye + rel,
                    height_m: f64::from(s[3]),
                    has_data: k == 0 && ids[3] & 1 == 1,
                    quad: if k == 0 {
                        ids[0].checked_sub(1).and_then(|i| drawn.get(i as usize).copied())
                    } else {
                        None
                    },
                });
            }
            any = true;
        }
        let queried = self.queries.read.take();
        if queried.is_none()
            && self.queries.read.idle()
            && let Some((_, pixels)) = self.queries.asked.take()
        {
            // The read-back failed: nothing is known under those pixels.
            self.queries.done = Some(pixels.into_iter().map(|p| (p, None)).collect());
        }
        if let Some(bytes) = queried
            && let Some((eye, pixels)) = self.queries.asked.take()
        {
            let answers = pixels
                .into_iter()
                .enumerate()
                .map(|(k, pixel)| {
                    let s: [f32; 4] = bytemuck::pod_read_unaligned(&bytes[k * PROBE_STRIDE as usize..][..16]);
                    let rel = DVec3::new(f64::from(s[0]), f64::from(s[1]), f64::from(s[2]));
                    (pixel, (rel != DVec3::ZERO).then_some(eye + rel))
                })
                .collect();
            self.queries.done = Some(answers);
            any = true;
        }
        if let Some((_, _, read)) = &self.timing
            && let Some(bytes) = read.take()
        {
            let t: [u64; 2] = bytemuck::pod_read_unaligned(&bytes[..16]);
            let period_ns = f64::from(rs.queue.get_timestamp_period());
            self.gpu_ms = Some(t[1].saturating_sub(t[0]) as f64 * period_ns / 1e6);
            any = true;
        }
        any
    }
}

fn targets(device: &wgpu::Device, width: u32, height: u32) -> FrameTargets {
    FrameTargets::new(
        device,
        width.max(1),
        height.max(1),
        true,
        wgpu::TextureUsages::TEXTURE_BINDING | wgpu::TextureUsages::COPY_SRC,
    )
}

/// One line about a frame: quads by level, triangles (and per pixel of the view), the largest
/// geometric error drawn, what is still loading.
pub fn frame_line(stats: &FrameStats) -> String {
    let levels: Vec<String> = stats.selection.per_level().iter().map(|(l, n)| format!("L{l}×{n}")).collect();
    format!(
        "{} quads ({}), {:.2} M triangles ({:.3} a pixel), error ≤ {:.2} px, prepare {:.2} ms{}",
        stats.selection.quads.len(),
        levels.join(" "),
        stats.triangles as f64 / 1e6,
        stats.triangles as f64 / stats.pixels.max(1) as f64,
        stats.max_error_px,
        stats.prepare_ms,
        if stats.pending > 0 { format!(", {} loading", stats.pending) } else { String::new() }
    )
}
