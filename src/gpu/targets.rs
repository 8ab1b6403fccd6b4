//! Render targets and read-back, shared by images (the command line, tests) and the window:
//! the colour image, the probe targets (surface position and height, quad and sample ids),
//! the depth buffer, and copying them back to the CPU.

use super::context::GpuError;

/// The probe's unit of sample coordinates, per sample (the terrain shader's `PROBE_SUBSAMPLES`).
pub const PROBE_SUBSAMPLES: u32 = 256;
/// Where the probe's sample coordinates count from: a quad's width (256 samples) west and south
/// of the quad, in its units, since a pixel may read the data past its quad's edge.
pub const PROBE_ORIGIN: u32 = 256 * PROBE_SUBSAMPLES;

/// The colour format of images the renderer writes (the shader encodes sRGB itself, as a window
/// surface of egui-wgpu needs).
pub const IMAGE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8Unorm;
pub(crate) const DEPTH_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;
/// Probe target: camera-relative surface position (metres) and height.
pub const SURFACE_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Float;
/// Probe target: quad index + 1, sample i, j, flags.
pub const ID_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba32Uint;
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
    /// Per pixel: quad index + 1 (0: nothing), the sample coordinates i and j the pixel's data
    /// were read at in 1/[`PROBE_SUBSAMPLES`] of a sample from [`PROBE_ORIGIN`], flags (bit 0 data, bit 1 skirt, the
    /// patch's stride from bit 2 on). Only with the probe.
    pub ids: Option<Vec<[u32; 4]>>,
    /// GPU time of the terrain pass, milliseconds (where timestamps exist).
    pub gpu_ms: Option<f64>,
}

impl RenderedImage {
    /// Writes the image as PNG, atomically (beside, then renamed).
    pub fn write_png(&self, path: &std::path::Path) -> Result<(), GpuError> {
        use image::ImageEncoder as _;
        let mut bytes = Vec::new();
        image::codecs::png::PngEncoder::new(&mut bytes)
            .write_image(&self.rgba, self.width, self.height, image::ExtendedColorType::Rgba8)
            .map_err(|source| GpuError::Png { path: path.into(), source })?;
        crate::files::write_atomic(path, &bytes).map_err(|source| GpuError::Write { path: path.into(), source })
    }
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
    pub(crate) views: Vec<wgpu::TextureView>,
    pub(crate) depth_view: wgpu::TextureView,
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

impl FrameTargets {
    /// Copies the targets (and the pass's timestamps, when `queries` holds them) to the CPU after
    /// what `encoder` recorded, submits, waits, and returns the image.
    pub(crate) fn read_back(
        &self,
        device: &wgpu::Device,
        queue: &wgpu::Queue,
        mut encoder: wgpu::CommandEncoder,
        queries: Option<&wgpu::QuerySet>,
    ) -> Result<RenderedImage, GpuError> {
        let (width, height) = (self.width, self.height);
        let probe = self.surface.is_some();
        let mut targets = vec![(&self.colour, 4u32)];
        if let (Some(surface), Some(ids)) = (&self.surface, &self.ids) {
            targets.push((surface, 16));
            targets.push((ids, 16));
        }
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
        let time_buffers = queries.map(|q| {
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
        queue.submit([encoder.finish()]);
        let mut mapped: Vec<&wgpu::Buffer> = reads.iter().map(|r| &r.0).collect();
        mapped.extend(time_buffers.iter());
        for b in &mapped {
            b.slice(..).map_async(wgpu::MapMode::Read, |r| {
                // A failed mapping shows when the range is read below.
                let _ = r;
            });
        }
        device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(|e| GpuError::Readback(format!("the GPU did not finish: {e}")))?;
        let unpad = |(buffer, row, bpp): &(wgpu::Buffer, u32, u32)| -> Result<Vec<u8>, GpuError> {
            let data = buffer.slice(..).get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
            let mut out = Vec::with_capacity((width * height * bpp) as usize);
            for y in 0..height as usize {
                let start = y * *row as usize;
                out.extend_from_slice(&data[start..start + (width * bpp) as usize]);
            }
            Ok(out)
        };
        let rgba = unpad(&reads[0])?;
        let (surface, ids) = if probe {
            (
                Some(bytemuck::cast_slice::<u8, [f32; 4]>(&unpad(&reads[1])?).to_vec()),
                Some(bytemuck::cast_slice::<u8, [u32; 4]>(&unpad(&reads[2])?).to_vec()),
            )
        } else {
            (None, None)
        };
        let gpu_ms = match time_buffers {
            Some(b) => {
                let data = b.slice(..).get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
                let t: &[u64] = bytemuck::cast_slice(&data);
                Some((t[1].saturating_sub(t[0])) as f64 * f64::from(queue.get_timestamp_period()) / 1e6)
            }
            None => None,
        };
        Ok(RenderedImage { width, height, rgba, surface, ids, gpu_ms })
    }
}
