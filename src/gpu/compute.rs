//! What the compute passes share (composition, the brush's stroke kernel): a WGSL module from
//! `shaders/`, a bind group layout of storage buffers, a pipeline per entry point, storage
//! buffers made from data, and reading a result back.

use wgpu::util::DeviceExt;

use super::context::GpuError;

/// The composed WGSL file `name` (see [`super::shaders::composed`]) as a module.
pub(crate) fn shader_module(device: &wgpu::Device, name: &str) -> Result<wgpu::ShaderModule, GpuError> {
    let source = super::shaders::composed(name)?;
    Ok(device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(name),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    }))
}

/// A bind group layout of storage buffers for a compute pass, binding k read-only where
/// `read_only[k]`.
pub(crate) fn storage_layout(device: &wgpu::Device, label: &str, read_only: &[bool]) -> wgpu::BindGroupLayout {
    let entries: Vec<wgpu::BindGroupLayoutEntry> = read_only
        .iter()
        .enumerate()
        .map(|(binding, &read_only)| wgpu::BindGroupLayoutEntry {
            binding: binding as u32,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Storage { read_only },
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        })
        .collect();
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor { label: Some(label), entries: &entries })
}

/// The compute pipeline of `entry` in `module`, with one bind group of `layout`.
pub(crate) fn compute_pipeline(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
) -> wgpu::ComputePipeline {
    compute_pipeline_with(device, label, layout, module, entry, &[])
}

/// [`compute_pipeline`] with values for the module's pipeline-overridable constants.
pub(crate) fn compute_pipeline_with(
    device: &wgpu::Device,
    label: &str,
    layout: &wgpu::BindGroupLayout,
    module: &wgpu::ShaderModule,
    entry: &str,
    constants: &[(&str, f64)],
) -> wgpu::ComputePipeline {
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        module,
        entry_point: Some(entry),
        compilation_options: wgpu::PipelineCompilationOptions { constants, ..Default::default() },
        cache: None,
    })
}

/// A buffer of `bytes` to copy a result into and map for reading.
pub(crate) fn readback_buffer(device: &wgpu::Device, label: &str, bytes: u64) -> wgpu::Buffer {
    device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    })
}

/// The contents of a [`readback_buffer`] whose copy has been submitted: maps it and waits for the
/// GPU.
pub(crate) fn read_mapped<T: bytemuck::Pod>(device: &wgpu::Device, read: &wgpu::Buffer) -> Result<Vec<T>, GpuError> {
    read.slice(..).map_async(wgpu::MapMode::Read, |_| {});
    device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(|e| GpuError::Readback(format!("the GPU did not finish: {e}")))?;
    let data = read.slice(..).get_mapped_range().map_err(|e| GpuError::Readback(e.to_string()))?;
    Ok(bytemuck::cast_slice(&data).to_vec())
}

/// A storage buffer holding `bytes` (bindings may not be empty: 32 zero bytes stand in), with
/// `extra` usages.
pub(crate) fn storage_buffer(
    device: &wgpu::Device,
    label: &str,
    bytes: &[u8],
    extra: wgpu::BufferUsages,
) -> wgpu::Buffer {
    let contents = if bytes.is_empty() { &[0u8; 32][..] } else { bytes };
    device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
        label: Some(label),
        contents,
        usage: wgpu::BufferUsages::STORAGE | extra,
    })
}
