//! The CPU twins of the per-pixel shading in `shaders/shared/shading.wgsl`, written in f32 and in
//! the shader's order: hillshade, isoline coverage, and the slope and aspect the ramp colours
//! when a project asks for them. [`probe`] evaluates the shader's own
//! functions on the device for a list of inputs, so that a test compares the two.

use bytemuck::{Pod, Zeroable};
use glam::Vec3;

use super::compute::{compute_pipeline, read_mapped, readback_buffer, shader_module, storage_buffer, storage_layout};
use super::context::{GpuContext, GpuError};

/// Hillshade factor: 1 on flat ground, brighter on slopes facing the sun, darker away from it.
/// `n`: the surface normal; `up`: the ellipsoid normal; the sun's azimuth (clockwise from north)
/// and elevation in radians, in the local east-north-up frame; `strength` 0–1. With strength 1,
/// the factor times sin(elevation) is the cosine of the angle between the normal and the sun,
/// gdaldem's hillshade (Horn's normal aside) divided by 255.
pub fn hillshade(n: Vec3, up: Vec3, azimuth: f32, elevation: f32, strength: f32) -> f32 {
    let mut east = Vec3::Z.cross(up);
    if east.length() < 1e-6 {
        east = Vec3::Y;
    }
    east = east.normalize();
    let north = up.cross(east);
    let sun = elevation.cos() * (azimuth.sin() * east + azimuth.cos() * north) + elevation.sin() * up;
    let lit = n.dot(sun).max(0.0) / elevation.sin().max(1e-3);
    (1.0 - strength) + strength * lit
}

/// The slope (degrees, of the true heights: the exaggerated normal's tangent over
/// `exaggeration`) and aspect (degrees clockwise from north, the way the slope faces) of a
/// surface normal `n` over the ellipsoid normal `up`: what the ramp colours when a project's
/// colour map is `by` slope or aspect.
pub fn slope_aspect(n: Vec3, up: Vec3, exaggeration: f32) -> [f32; 2] {
    let mut east = Vec3::Z.cross(up);
    if east.length() < 1e-6 {
        east = Vec3::Y;
    }
    east = east.normalize();
    let north = up.cross(east);
    let level = n - n.dot(up) * up;
    let slope = (level.length() / n.dot(up).max(1e-6) / exaggeration.max(1e-6)).atan();
    let aspect = level.dot(east).atan2(level.dot(north)).to_degrees();
    [slope.to_degrees(), aspect - 360.0 * (aspect / 360.0).floor()]
}

/// Coverage (0–1) of an isoline at a pixel. `x`: height in units of the interval (lines at
/// integers); `fw`: intervals per pixel (the length of the shader's screen gradient); `width` and `min_width` in pixels;
/// `spacing_factor`: intervals between lines of this kind (1 minor, k major). Lines thinner than
/// `min_width` are drawn `min_width` wide and fainter; lines closer than 6 widths apart fade out.
pub fn isoline_coverage(x: f32, fw: f32, width: f32, min_width: f32, spacing_factor: f32) -> f32 {
    let safe_fw = fw.max(1e-20);
    let distance_px = (x - x.round()).abs() / safe_fw;
    let w = width.max(min_width);
    let thinness = if width < min_width { width / min_width.max(1e-6) } else { 1.0 };
    let coverage = (0.5 * w + 0.5 - distance_px).clamp(0.0, 1.0);
    let spacing_px = spacing_factor / safe_fw;
    let fade = ((spacing_px - 3.0 * w) / (3.0 * w)).clamp(0.0, 1.0);
    coverage * thinness * fade
}

/// One input of the shading probe: `Probe` in `shaders/probe/shading.wgsl`.
#[repr(C)]
#[derive(Clone, Copy, Debug, Default, Pod, Zeroable)]
pub struct ShadingProbe {
    /// The surface normal (w unused).
    pub normal: [f32; 4],
    /// The ellipsoid normal (w unused).
    pub up: [f32; 4],
    /// Sun azimuth and elevation (radians), hillshade strength, unused.
    pub sun: [f32; 4],
    /// Isoline x, fw, width and min_width.
    pub iso: [f32; 4],
    /// Isoline spacing factor, vertical exaggeration (slope), unused ×2.
    pub spacing: [f32; 4],
}

/// The shader's hillshade, isoline coverage, slope and aspect for each probe, evaluated on the
/// device.
pub fn probe(ctx: &GpuContext, probes: &[ShadingProbe]) -> Result<Vec<[f32; 4]>, GpuError> {
    let device = &ctx.device;
    let module = shader_module(device, "probe/shading.wgsl")?;
    let layout = storage_layout(device, "shading probe", &[true, false]);
    let pipeline = compute_pipeline(device, "shading probe", &layout, &module, "probe");
    let input = storage_buffer(device, "probes", bytemuck::cast_slice(probes), wgpu::BufferUsages::empty());
    let bytes = (probes.len().max(1) * 16) as u64;
    let output = storage_buffer(device, "results", &vec![0u8; bytes as usize], wgpu::BufferUsages::COPY_SRC);
    let read = readback_buffer(device, "results read", bytes);
    let bind = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some("shading probe"),
        layout: &layout,
        entries: &[
            wgpu::BindGroupEntry { binding: 0, resource: input.as_entire_binding() },
            wgpu::BindGroupEntry { binding: 1, resource: output.as_entire_binding() },
        ],
    });
    let mut encoder = device.create_command_encoder(&Default::default());
    {
        let mut pass = encoder
            .begin_compute_pass(&wgpu::ComputePassDescriptor { label: Some("shading probe"), timestamp_writes: None });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &bind, &[]);
        pass.dispatch_workgroups((probes.len() as u32).div_ceil(64), 1, 1);
    }
    encoder.copy_buffer_to_buffer(&output, 0, &read, 0, bytes);
    ctx.queue.submit([encoder.finish()]);
    let mut values: Vec<[f32; 4]> = read_mapped(device, &read)?;
    values.truncate(probes.len());
    Ok(values)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hillshade_is_the_cosine_to_the_sun_over_its_flat_value() {
        // A plane tilted by `slope` facing `aspect` (clockwise from north), on the equator at
        // longitude 0, where up = x, east = y and north = z.
        let up = Vec3::X;
        let (east, north) = (Vec3::Y, Vec3::Z);
        for (slope, aspect, azimuth, elevation) in
            [(0.3f32, 0.5f32, 5.5f32, 0.6f32), (0.0, 0.0, 1.0, 0.4), (0.8, 2.0, 2.0, 1.2)]
        {
            let downhill = aspect.sin() * east + aspect.cos() * north;
            let n = (slope.cos() * up + slope.sin() * downhill).normalize();
            // gdaldem's formula: sin(alt)cos(slope) + cos(alt)sin(slope)cos(az − aspect).
            let expected = (elevation.sin() * slope.cos() + elevation.cos() * slope.sin() * (azimuth - aspect).cos())
                .max(0.0)
                / elevation.sin();
            let got = hillshade(n, up, azimuth, elevation, 1.0);
            assert!((got - expected).abs() < 1e-5, "{slope} {aspect}: {got} vs {expected}");
            assert!((hillshade(n, up, azimuth, elevation, 0.0) - 1.0).abs() < 1e-7);
        }
        assert!((hillshade(up, up, 0.3, 0.5, 0.7) - 1.0).abs() < 1e-6, "flat ground is 1");
    }

    #[test]
    fn an_isoline_covers_its_width_and_fades_when_crowded() {
        // On the line, well spaced: full coverage; half a width plus a pixel away: none.
        assert_eq!(isoline_coverage(3.0, 0.01, 1.0, 1.0, 1.0), 1.0);
        assert_eq!(isoline_coverage(3.0 + 0.011 * 1.5, 0.01, 1.0, 1.0, 1.0), 0.0);
        // Thinner than the minimum: drawn at the minimum, fainter in proportion.
        assert!((isoline_coverage(3.0, 0.01, 0.5, 1.0, 1.0) - 0.5).abs() < 1e-6);
        // Lines 3 widths apart are gone, 6 apart fully there.
        assert_eq!(isoline_coverage(3.0, 1.0 / 3.0, 1.0, 1.0, 1.0), 0.0);
        assert_eq!(isoline_coverage(3.0, 1.0 / 6.0, 1.0, 1.0, 1.0), 1.0);
    }
}
