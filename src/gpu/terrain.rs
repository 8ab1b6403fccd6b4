//! The terrain pass: the pipelines of the ECM terrain (colour, probe, points), their bind group
//! layout, the shared index buffer of a patch's mesh at each stride (its grid and a skirt ring),
//! the ramp buffer, and recording one instanced draw per stride.

use wgpu::util::DeviceExt;

use super::context::GpuError;
use std::sync::OnceLock;

use super::targets::{DEPTH_FORMAT, DrawMode, ID_FORMAT, IMAGE_FORMAT, SURFACE_FORMAT};
use super::uniforms::rgba;
use crate::scene::patches::{ALL_SIDES, PATCH_CELLS, STRIDES, triangles_at};

/// The indices of a patch drawn at `stride` (see terrain.wgsl's `vs_main`): with n = 32 / stride
/// cells a side, vertex b·(n+1) + a is the sample (a, b) of the patch's grid at that stride and
/// (n+1)² + b·(n+1) + a the same sample lowered by the skirt depth; two triangles a cell (the
/// diagonal from (a, b) to (a+1, b+1), as the quads were always cut), then two a cell along each
/// side in `skirts` (bit 0 south, 1 east, 2 north, 3 west) joining the edge to its lowered copy.
pub(crate) fn patch_indices(stride: u32, skirts: u8) -> Vec<u32> {
    let n = PATCH_CELLS / stride;
    let nv = n + 1;
    let low = nv * nv;
    let mut out = Vec::with_capacity(triangles_at(stride, skirts) as usize * 3);
    for b in 0..n {
        for a in 0..n {
            let v00 = b * nv + a;
            let (v10, v01) = (v00 + 1, v00 + nv);
            out.extend_from_slice(&[v00, v10, v01 + 1, v00, v01 + 1, v01]);
        }
    }
    // The ring: each side's edge from one corner to the next (south, east, north, west), and
    // its lowered copy.
    let side = |side: u32, k: u32| match side {
        0 => k,
        1 => k * nv + n,
        2 => n * nv + (n - k),
        _ => (n - k) * nv,
    };
    for s in (0..4).filter(|s| skirts & (1 << s) != 0) {
        for k in 0..n {
            let (u, w) = (side(s, k), side(s, k + 1));
            out.extend_from_slice(&[u, w, w + low, u, w + low, u + low]);
        }
    }
    out
}

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

/// The terrain pipelines and what they share. Each pipeline is compiled the first time a frame
/// draws with it (a software rasteriser spends 0.1–0.2 s on each of the six): `render` draws
/// colour only, the workstation the probe, the vertex tests the points.
pub(crate) struct TerrainPass {
    device: wgpu::Device,
    /// [without morphing, with] (see `MORPH` in terrain.wgsl).
    modules: [wgpu::ShaderModule; 2],
    pipeline_layout: wgpu::PipelineLayout,
    /// The colour target's format (the window's, or [`IMAGE_FORMAT`]).
    format: wgpu::TextureFormat,
    /// Per [`DrawMode`] (colour, probe, points) and [without morphing, with].
    pipelines: [[OnceLock<wgpu::RenderPipeline>; 2]; 3],
    pub(crate) layout: wgpu::BindGroupLayout,
    pub(crate) index_buffer: wgpu::Buffer,
    /// Per stride (in the order of [`STRIDES`]) and set of skirts: the first index of its patch
    /// mesh and the count.
    pub(crate) index_ranges: Vec<(u32, u32)>,
}

impl TerrainPass {
    /// The index range of a patch mesh at `stride` with skirts on `skirts`.
    pub(crate) fn indices_of(&self, stride: u32, skirts: u8) -> std::ops::Range<u32> {
        let k = STRIDES.iter().position(|&s| s == stride).unwrap_or(0);
        let (first, count) = self.index_ranges[k * (usize::from(ALL_SIDES) + 1) + usize::from(skirts & ALL_SIDES)];
        first..first + count
    }

    /// The pipeline drawing `mode`, with or without morphing, compiled on first use.
    pub(crate) fn pipeline(&self, mode: DrawMode, morphs: bool) -> &wgpu::RenderPipeline {
        let kind = match mode {
            DrawMode::Colour => 0,
            DrawMode::Probe => 1,
            DrawMode::Points => 2,
        };
        self.pipelines[kind][usize::from(morphs)].get_or_init(|| self.make(mode, &self.modules[usize::from(morphs)]))
    }

    fn make(&self, mode: DrawMode, module: &wgpu::ShaderModule) -> wgpu::RenderPipeline {
        let target = |format: wgpu::TextureFormat| {
            Some(wgpu::ColorTargetState { format, blend: None, write_mask: wgpu::ColorWrites::ALL })
        };
        let colour_target = [target(self.format)];
        let probe_targets = [target(IMAGE_FORMAT), target(SURFACE_FORMAT), target(ID_FORMAT)];
        let (label, fragment, targets, topology): (_, _, &[Option<wgpu::ColorTargetState>], _) = match mode {
            DrawMode::Colour => ("terrain", "fs_main", &colour_target, wgpu::PrimitiveTopology::TriangleList),
            DrawMode::Probe => ("terrain probe", "fs_probe", &probe_targets, wgpu::PrimitiveTopology::TriangleList),
            DrawMode::Points => ("terrain points", "fs_points", &probe_targets, wgpu::PrimitiveTopology::PointList),
        };
        self.device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
            label: Some(label),
            layout: Some(&self.pipeline_layout),
            vertex: wgpu::VertexState {
                module,
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
                module,
                entry_point: Some(fragment),
                compilation_options: Default::default(),
                targets,
            }),
            multiview_mask: None,
            cache: None,
        })
    }

    /// The pass drawing into targets of `format` (the window's, or [`IMAGE_FORMAT`]).
    pub(crate) fn new(device: &wgpu::Device, format: wgpu::TextureFormat) -> Result<TerrainPass, GpuError> {
        let source = super::shaders::composed("terrain.wgsl")?;
        let flat = source.replace("const MORPH: bool = true;", "const MORPH: bool = false;");
        if flat == source {
            return Err(GpuError::Targets("terrain.wgsl lacks `const MORPH: bool = true;`"));
        }
        // [without morphing, with]: see `MORPH` in terrain.wgsl.
        let modules = [flat, source].map(|text| {
            device.create_shader_module(wgpu::ShaderModuleDescriptor {
                label: Some("terrain.wgsl"),
                source: wgpu::ShaderSource::Wgsl(text.into()),
            })
        });

        let mut indices = Vec::new();
        let mut index_ranges = Vec::new();
        for &stride in &STRIDES {
            for skirts in 0..=ALL_SIDES {
                let mesh = patch_indices(stride, skirts);
                index_ranges.push((indices.len() as u32, mesh.len() as u32));
                indices.extend(mesh);
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
                // The quads and their heights: the fragment stage reads the data at each pixel.
                entry(1, both, read),
                entry(2, both, read),
                // The static maps: the fragment stage finds the mesh's height from the offsets.
                entry(3, both, read),
                entry(4, both, read),
                entry(5, both, read),
                entry(6, wgpu::ShaderStages::FRAGMENT, read),
                entry(7, wgpu::ShaderStages::FRAGMENT, read),
                entry(8, wgpu::ShaderStages::VERTEX, read),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("terrain"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        Ok(TerrainPass {
            device: device.clone(),
            modules,
            pipeline_layout,
            format,
            pipelines: Default::default(),
            layout,
            index_ranges,
            index_buffer,
        })
    }

    /// The terrain bind group: frame, quads, heights, the three maps, the ramp, the overlay, the
    /// patches.
    pub(crate) fn bind_group(&self, device: &wgpu::Device, buffers: [&wgpu::Buffer; 9]) -> wgpu::BindGroup {
        bind_buffers(device, &self.layout, "terrain", &buffers)
    }
}
