// Terrain attributes of a height raster: one invocation per pixel. The GPU twin of
// terrafuse::attributes (keep in sync): a 3 × 3 window of heights (row 0 at the top) and the
// pixel's axes in its tangent plane (x: one column on, y: one row up, each as east and north
// metres), measured on the ellipsoid by the CPU in f64 and cast to f32.
//!include generated/codes.wgsl

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

// attributes::attribute_at.
fn attribute_at(code: u32, z: array<f32, 9>, a: vec4<f32>) -> f32 {
    let nw = z[0];
    let n = z[1];
    let ne = z[2];
    let w = z[3];
    let c = z[4];
    let e = z[5];
    let sw = z[6];
    let s = z[7];
    let se = z[8];
    if code <= ATTRIBUTE_HILLSHADE {
        let dz_dx = ((ne + 2.0 * e + se) - (nw + 2.0 * w + sw)) / 8.0;
        let dz_dy = ((nw + 2.0 * n + ne) - (sw + 2.0 * s + se)) / 8.0;
        // PixelAxes::gradient: the 2 × 2 system of the two axes.
        let det = a.x * a.w - a.y * a.z;
        let ge = (dz_dx * a.w - dz_dy * a.y) / det;
        let gn = (dz_dy * a.x - dz_dx * a.z) / det;
        let slope = atan(length(vec2<f32>(ge, gn)));
        var aspect = degrees(atan2(-ge, -gn));
        aspect = aspect - 360.0 * floor(aspect / 360.0);
        if code == ATTRIBUTE_SLOPE {
            return degrees(slope);
        }
        if code == ATTRIBUTE_ASPECT {
            return aspect;
        }
        let h = params.light.y;
        let shade = sin(h) * cos(slope) + cos(h) * sin(slope) * cos(params.light.x - radians(aspect));
        return 1.0 + 254.0 * max(shade, 0.0);
    }
    if code <= ATTRIBUTE_PROFILE_CURVATURE {
        let lx = length(a.xy);
        let ly = length(a.zw);
        let zx = (e - w) / (2.0 * lx);
        let zy = (n - s) / (2.0 * ly);
        let zxx = (w - 2.0 * c + e) / (lx * lx);
        let zyy = (n - 2.0 * c + s) / (ly * ly);
        let zxy = (ne - nw - se + sw) / (4.0 * lx * ly);
        let p = zx * zx + zy * zy;
        if code == ATTRIBUTE_CURVATURE {
            return 100.0 * -2.0 * (zxx + zyy);
        }
        if code == ATTRIBUTE_PLANFORM_CURVATURE {
            if p < 1e-14 {
                return 0.0;
            }
            return 100.0 * -(zxx * zy * zy - 2.0 * zxy * zx * zy + zyy * zx * zx) / pow(p, 1.5);
        }
        if p <= 0.0 {
            return 0.0;
        }
        return 100.0 * -(zxx * zx * zx + 2.0 * zxy * zx * zy + zyy * zy * zy) / (p * pow(1.0 + p, 1.5));
    }
    if code == ATTRIBUTE_TPI {
        return c - (nw + n + ne + w + e + sw + s + se) / 8.0;
    }
    if code == ATTRIBUTE_TRI {
        var sum = 0.0;
        for (var k = 0u; k < 9u; k++) {
            sum += (z[k] - c) * (z[k] - c);
        }
        return sqrt(sum);
    }
    var lo = z[0];
    var hi = z[0];
    for (var k = 1u; k < 9u; k++) {
        lo = min(lo, z[k]);
        hi = max(hi, z[k]);
    }
    return hi - lo;
}

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
        value = attribute_at(params.size.z, z, a);
    }
    result[k] = value;
}
