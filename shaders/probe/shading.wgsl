// Evaluates the shared shading functions for a list of inputs, so that a test can compare them
// with their CPU twins in src/gpu/shading.rs (the terrain's fragment stage calls the same ones).

//!include shared/shading.wgsl

struct Probe {
    normal: vec4<f32>,
    up: vec4<f32>,
    // azimuth, elevation, strength (radians, radians, 0–1), unused
    sun: vec4<f32>,
    // x, fw, width, min_width
    iso: vec4<f32>,
    // spacing_factor, vertical exaggeration, unused ×2
    spacing: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> probes: array<Probe>;
// hillshade, isoline coverage, slope, aspect
@group(0) @binding(1) var<storage, read_write> results: array<vec4<f32>>;

@compute @workgroup_size(64)
fn probe(@builtin(global_invocation_id) id: vec3<u32>) {
    let k = id.x;
    if k >= arrayLength(&probes) {
        return;
    }
    let p = probes[k];
    let shade = hillshade(p.normal.xyz, p.up.xyz, p.sun.x, p.sun.y, p.sun.z);
    let iso = isoline_coverage(p.iso.x, p.iso.y, p.iso.z, p.iso.w, p.spacing.x);
    let sa = slope_aspect(p.normal.xyz, p.up.xyz, p.spacing.y);
    results[k] = vec4<f32>(shade, iso, sa.x, sa.y);
}
