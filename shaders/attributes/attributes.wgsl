// Terrain attributes of a height raster: one invocation per pixel. The GPU twin of
// terrafuse::attributes (keep in sync): a 3 × 3 window of heights (row 0 at the top) and the
// pixel's axes in its tangent plane (x: one column on, y: one row up, each as east and north
// metres), measured on the ellipsoid by the CPU in f64 and cast to f32.
//!include generated/codes.wgsl
//!include shared/attributes.wgsl

// The raster and the attribute (Params in src/gpu/attributes.rs; keep in sync): width,
// height, attribute code, unused; the light's azimuth and altitude (radians), unused ×2.
struct Params {
    size: vec4<u32>,
    light: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> params: Params;
@group(0) @binding(1) var<storage, read> heights: array<f32>;
// Per pixel: x east, x north, y east, y north (all 0: no axes, at the border or outside the CRS).
@group(0) @binding(2) var<storage, read> axes: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read_write> result: array<f32>;

// No data, in and out (WGSL may assume there are no NaNs, so a sentinel stands for them).
const NODATA: f32 = -3.0e37;
const NODATA_BELOW: f32 = -1.0e37;

@compute @workgroup_size(16, 16, 1)
fn attributes(@builtin(global_invocation_id) id: vec3<u32>) {
    let width = params.size.x;
    let height = params.size.y;
    if id.x >= width || id.y >= height {
        return;
    }
    let k = id.y * width + id.x;
    let a = axes[k];
    // No axes or a window off the raster or with no data: no data.
    var ok = a.x * a.w - a.y * a.z != 0.0 && id.x > 0u && id.y > 0u && id.x + 1u < width && id.y + 1u < height;
    var z: array<f32, 9>;
    if ok {
        for (var m = 0u; m < 9u; m++) {
            let v = heights[(id.y + m / 3u - 1u) * width + id.x + m % 3u - 1u];
            ok = ok && v > NODATA_BELOW;
            z[m] = v;
        }
    }
    var value = NODATA;
    if ok {
        value = attribute_at(params.size.z, z, a, params.light.xy);
    }
    result[k] = value;
}
