// Per-pixel shading helpers: sRGB transfer, isoline coverage, hillshade. Pure functions; CPU
// twins: the sRGB transfer in src/colour.rs, isoline coverage and hillshade in
// src/gpu/shading.rs (a test evaluates both here and there through shaders/probe/shading.wgsl).

fn srgb_to_linear(c: vec3<f32>) -> vec3<f32> {
    let low = c / 12.92;
    let high = pow((c + vec3<f32>(0.055)) / 1.055, vec3<f32>(2.4));
    return select(high, low, c <= vec3<f32>(0.04045));
}

fn linear_to_srgb(c: vec3<f32>) -> vec3<f32> {
    let x = clamp(c, vec3<f32>(0.0), vec3<f32>(1.0));
    let low = x * 12.92;
    let high = 1.055 * pow(x, vec3<f32>(1.0 / 2.4)) - vec3<f32>(0.055);
    return select(high, low, x <= vec3<f32>(0.0031308));
}

// Coverage (0–1) of an isoline at a pixel. x: height in units of the interval (lines at
// integers); fw: |∂x/∂screen| summed over both axes (fwidth), intervals per pixel; width and
// min_width in pixels; spacing_factor: how many intervals apart lines of this kind are (1 minor,
// k major). Lines thinner than min_width are drawn min_width wide and proportionally fainter;
// lines closer than 6 widths apart fade out (gone at 3 widths) instead of turning into noise.
fn isoline_coverage(x: f32, fw: f32, width: f32, min_width: f32, spacing_factor: f32) -> f32 {
    let safe_fw = max(fw, 1e-20);
    let distance_px = abs(x - round(x)) / safe_fw;
    let w = max(width, min_width);
    let thinness = select(1.0, width / max(min_width, 1e-6), width < min_width);
    let coverage = clamp(0.5 * w + 0.5 - distance_px, 0.0, 1.0);
    let spacing_px = spacing_factor / safe_fw;
    let fade = clamp((spacing_px - 3.0 * w) / (3.0 * w), 0.0, 1.0);
    return coverage * thinness * fade;
}

// Hillshade factor: 1 on flat ground, brighter on slopes facing the sun, darker away from it.
// n: surface normal; up: ellipsoid normal; sun azimuth (clockwise from north) and elevation in
// radians, in the local east-north-up frame.
fn hillshade(n: vec3<f32>, up: vec3<f32>, azimuth: f32, elevation: f32, strength: f32) -> f32 {
    var east = cross(vec3<f32>(0.0, 0.0, 1.0), up);
    if length(east) < 1e-6 {
        east = vec3<f32>(0.0, 1.0, 0.0);
    }
    east = normalize(east);
    let north = cross(up, east);
    let sun = cos(elevation) * (sin(azimuth) * east + cos(azimuth) * north) + sin(elevation) * up;
    let lit = max(dot(n, sun), 0.0) / max(sin(elevation), 1e-3);
    return (1.0 - strength) + strength * lit;
}

// The slope (degrees, of the true heights: the exaggerated normal's tangent over `exaggeration`)
// and aspect (degrees clockwise from north, the way the slope faces) of a surface normal `n`
// over the ellipsoid normal `up` (gpu::shading::slope_aspect).
fn slope_aspect(n: vec3<f32>, up: vec3<f32>, exaggeration: f32) -> vec2<f32> {
    var east = cross(vec3<f32>(0.0, 0.0, 1.0), up);
    if length(east) < 1e-6 {
        east = vec3<f32>(0.0, 1.0, 0.0);
    }
    east = normalize(east);
    let north = cross(up, east);
    // The normal leans downslope.
    let level = n - dot(n, up) * up;
    let slope = atan(length(level) / max(dot(n, up), 1e-6) / max(exaggeration, 1e-6));
    var aspect = degrees(atan2(dot(level, east), dot(level, north)));
    aspect = aspect - 360.0 * floor(aspect / 360.0);
    return vec2<f32>(degrees(slope), aspect);
}

// ColorBrewer's RdBu, 11 classes, red to blue (sRGB 0–1): src/colour.rs DIVERGING.
const DIVERGING: array<vec3<f32>, 11> = array<vec3<f32>, 11>(
    vec3<f32>(0.403921569, 0.0, 0.121568627),
    vec3<f32>(0.698039216, 0.094117647, 0.168627451),
    vec3<f32>(0.839215686, 0.376470588, 0.301960784),
    vec3<f32>(0.956862745, 0.647058824, 0.509803922),
    vec3<f32>(0.992156863, 0.858823529, 0.780392157),
    vec3<f32>(0.968627451, 0.968627451, 0.968627451),
    vec3<f32>(0.819607843, 0.898039216, 0.941176471),
    vec3<f32>(0.57254902, 0.77254902, 0.870588235),
    vec3<f32>(0.262745098, 0.576470588, 0.764705882),
    vec3<f32>(0.129411765, 0.4, 0.674509804),
    vec3<f32>(0.019607843, 0.188235294, 0.380392157),
);

// The diverging map's sRGB colour at t = dh / range (clamped to [−1, 1]): colour::diverging.
fn diverging_colour(t: f32) -> vec3<f32> {
    let x = (clamp(t, -1.0, 1.0) + 1.0) * 5.0;
    let k = min(u32(floor(x)), 9u);
    let w = x - f32(k);
    var stops = DIVERGING;
    return stops[k] + w * (stops[k + 1u] - stops[k]);
}
