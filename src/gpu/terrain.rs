//! The terrain pass: the pipelines of the ECM terrain (colour, probe, points), their bind group
//! layout, the shared index buffer of a quad's 259² mesh (257² samples and a skirt ring), the
//! ramp buffer, and recording the one instanced draw.

use wgpu::util::DeviceExt;

use super::context::GpuError;
use super::targets::{DEPTH_FORMAT, ID_FORMAT, IMAGE_FORMAT, SURFACE_FORMAT};
use super::uniforms::rgba;
use crate::scene::loader::SAMPLES;

/// Vertices along a quad edge with the skirt ring.
pub const MESH_EDGE: u32 = SAMPLES + 2;
/// Triangles one quad draws (grid and skirts).
pub const TRIANGLES_PER_QUAD: u64 = 2 * (MESH_EDGE as u64 - 1) * (MESH_EDGE as u64 - 1);

/// The ramp's stops for the shader: value, padding, linear RGBA.
pub(crate) fn ramp_buffer(device: &wgpu::Device, ramp: &crate::colour::Ramp) -> wgpu::Buffer {
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

/// A bind group of storage and uniform buffers in binding order.
pub(crate) fn bind_buffers(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
    buffers: &[&wgpu::Buffer],
) -> wgpu::BindGroup {
    let entries: Vec<wgpu::BindGroupEntry> = buffers
        .iter()
        .enumerate()
        .map(|(k, b)| wgpu::BindGroupEntry { binding: k as u32, resource: b.as_entire_binding() })
        .collect();
    device.create_bind_group(&wgpu::BindGroupDescriptor { label: Some(label), layout, entries: &entries })
}

/// The terrain pipelines and what they share.
pub(crate) struct TerrainPass {
    pub(crate) pipeline: wgpu::RenderPipeline,
    pub(crate) probe_pipeline: wgpu::RenderPipeline,
    pub(crate) points_pipeline: wgpu::RenderPipeline,
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) index_buffer: wgpu::Buffer,
    pub(crate) index_count: u32,
}

impl TerrainPass {
    /// The pipelines drawing into targets of `format` (the window's, or [`IMAGE_FORMAT`]).
    pub(crate) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Result<TerrainPass, GpuError> {
        let source = super::shaders::composed("terrain.wgsl")?;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("terrain.wgsl"),
            source: wgpu::ShaderSource::Wgsl(source.into()),
        });

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
                entry(7, wgpu::ShaderStages::VERTEX, read),
            ],
        });
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

        Ok(TerrainPass {
            pipeline,
            probe_pipeline,
            points_pipeline,
            layout,
            index_count: indices.len() as u32,
            index_buffer,
        })
    }

    /// The terrain bind group: frame, quads, heights, the three maps, the ramp, the overlay.
    pub(crate) fn bind_group(&self, device: &wgpu::Device, buffers: [&wgpu::Buffer; 8]) -> wgpu::BindGroup {
        bind_buffers(device, &self.layout, "terrain", &buffers)
    }
}
