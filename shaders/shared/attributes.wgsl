// The attribute of a 3 × 3 window of heights, shared by the attributes kernel and the terrain's
// colour layer. The CPU reference is terrafuse::attributes::attribute_at (keep in sync).
//!include generated/codes.wgsl

// The hillshade (1–255) of a slope (radians) facing `aspect` (degrees from north) under a light
// (azimuth, altitude, radians).
fn hillshade_value(slope: f32, aspect: f32, light: vec2<f32>) -> f32 {
    let shade = sin(light.y) * cos(slope) + cos(light.y) * sin(slope) * cos(light.x - radians(aspect));
    return 1.0 + 254.0 * max(shade, 0.0);
}

// attributes::attribute_at: the attribute `code` (generated ATTRIBUTE_*) of a 3 × 3 window of
// heights z (row 0 at the top: z[0] north-west … z[8] south-east) with the centre's axes a (x east,
// x north, y east, y north, metres) and hillshade's light (azimuth, altitude, radians).
fn attribute_at(code: u32, z: array<f32, 9>, a: vec4<f32>, light: vec2<f32>) -> f32 {
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
        return hillshade_value(slope, aspect, light);
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
