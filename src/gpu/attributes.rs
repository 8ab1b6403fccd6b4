//! Terrain attributes on the GPU: `shaders/attributes/attributes.wgsl` over a height raster, the
//! twin of [`crate::attributes::attribute_raster`]. The pixels' axes are measured on the
//! ellipsoid by the CPU in f64 ([`crate::attributes::pixel_axes`]) and cast to f32; the kernel
//! works in f32.

use bytemuck::{Pod, Zeroable};

use super::codes;
use super::compute::{compute_pipeline, read_mapped, readback_buffer, shader_module, storage_buffer, storage_layout};
use super::context::{GpuContext, GpuError};
use super::terrain::bind_buffers;
use crate::attributes::{Attribute, LIGHT_ALTITUDE_DEG, LIGHT_AZIMUTH_DEG, PixelAxes};

/// No data in the kernel's buffers (its `NODATA`).
const NODATA: f32 = -3.0e37;
const WORKGROUP: u32 = 16;

/// The kernel's `Params` (keep in sync).
#[repr(C)]
#[derive(Clone, Copy, Debug, Pod, Zeroable)]
pub(crate) struct AttributeParams {
    pub(crate) size: [u32; 4],
    pub(crate) light: [f32; 4],
}

/// The kernels' code of an attribute (the attributes kernel's and the terrain's colour layer's).
pub(crate) fn code(attribute: Attribute) -> u32 {
    match attribute {
        Attribute::Slope => codes::attribute::SLOPE,
        Attribute::Aspect => codes::attribute::ASPECT,
        Attribute::Hillshade => codes::attribute::HILLSHADE,
        Attribute::Curvature => codes::attribute::CURVATURE,
        Attribute::PlanformCurvature => codes::attribute::PLANFORM_CURVATURE,
        Attribute::ProfileCurvature => codes::attribute::PROFILE_CURVATURE,
        Attribute::Tpi => codes::attribute::TPI,
        Attribute::Tri => codes::attribute::TRI,
        Attribute::Roughness => codes::attribute::ROUGHNESS,
    }
}

/// The attribute of a `width` × `height` raster of heights (row 0 at the top, NaN no data) with
/// its pixels' axes, computed on the GPU; NaN where it has none.
pub fn attribute_raster(
    ctx: &GpuContext,
    attribute: Attribute,
    width: usize,
    height: usize,
    heights: &[f32],
    axes: &[Option<PixelAxes>],
) -> Result<Vec<f32>, GpuError> {
    let device = &ctx.device;
    let module = shader_module(device, "attributes/attributes.wgsl")?;
    let layout = storage_layout(device, "attributes", &[true, true, true, false]);
    let pipeline = compute_pipeline(device, "attributes", &layout, &module, "attributes");
    let params = AttributeParams {
        size: [width as u32, height as u32, code(attribute), 0],
        light: [LIGHT_AZIMUTH_DEG.to_radians() as f32, LIGHT_ALTITUDE_DEG.to_radians() as f32, 0.0, 0.0],
    };
    let z: Vec<f32> = heights.iter().map(|&v| if v.is_nan() { NODATA } else { v }).collect();
    let a: Vec<[f32; 4]> = axes
        .iter()
        .map(|a| a.map_or([0.0; 4], |a| [a.x[0] as f32, a.x[1] as f32, a.y[0] as f32, a.y[1] as f32]))
        .collect();
    let bytes = (heights.len().max(1) * 4) as u64;
    let storage = |label: &str, data: &[u8]| storage_buffer(device, label, data, wgpu::BufferUsages::empty());
    let params = storage("attribute params", bytemuck::bytes_of(&params));
    let z = storage("attribute heights", bytemuck::cast_slice(&z));
    let a = storage("attribute axes", bytemuck::cast_slice(&a));
    let output = storage_buffer(device, "attribute", &vec![0u8; bytes as usize], wgpu::BufferUsages::COPY_SRC);
    let read = readback_buffer(device, "attribute read", bytes);
    let bind = bind_buffers(device, &layout, "attributes", &[&params, &z, &a, &output]);
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("attributes"), timestamp_writes: None });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups((width as u32).div_ceil(WORKGROUP), (height as u32).div_ceil(WORKGROUP), 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &read, 0, bytes);
    ctx.queue.submit([encoder.finish()]);
    let values: Vec<f32> = read_mapped(device, &read)?;
    Ok(values[..heights.len()].iter().map(|&v| if v < -1.0e37 { f32::NAN } else { v }).collect())
}
