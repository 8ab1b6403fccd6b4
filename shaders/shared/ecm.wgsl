// ECM vertex geometry in single precision: the GPU twin of terrafuse::ecm::geometry::vertex_f32.
// Same expressions, same order (keep in sync with src/ecm/geometry/mod.rs).

// Patch interpolation of four corner values (SW, SE, NW, NE) at (s, t): bilinear (split 0), or
// two triangles split along the main diagonal (1) or the anti-diagonal (2), barycentric weights.
fn ecm_interpolate(split: u32, q0: vec3<f32>, q1: vec3<f32>, q2: vec3<f32>, q3: vec3<f32>, s: f32, t: f32) -> vec3<f32> {
    if split == 1u {
        if s >= t {
            return q0 * (1.0 - s) + q1 * (s - t) + q3 * t;
        }
        return q0 * (1.0 - t) + q2 * (t - s) + q3 * s;
    }
    if split == 2u {
        if s + t <= 1.0 {
            return q0 * ((1.0 - s) - t) + q1 * s + q2 * t;
        }
        return q1 * (1.0 - t) + q2 * (1.0 - s) + q3 * ((s + t) - 1.0);
    }
    return (q0 * (1.0 - s) + q1 * s) * (1.0 - t) + (q2 * (1.0 - s) + q3 * s) * t;
}

// The canonical quad's sample for the target's sample (i, j) of an n×n grid; flags: bit 0 swap,
// bit 1 flip x, bit 2 flip y (MapSymmetry::canonical_sample).
fn ecm_canonical_sample(flags: u32, n: u32, i: u32, j: u32) -> vec2<u32> {
    var i1 = i;
    var j1 = j;
    if (flags & 2u) != 0u {
        i1 = n - 1u - i;
    }
    if (flags & 4u) != 0u {
        j1 = n - 1u - j;
    }
    if (flags & 1u) != 0u {
        return vec2<u32>(j1, i1);
    }
    return vec2<u32>(i1, j1);
}

// The local part of a vertex with maps: patch + oₑ + h₀·δn + (h − h₀)·nₑ (A′ is added after).
fn ecm_local_with_maps(base: vec3<f32>, o: vec3<f32>, n: vec3<f32>, dn: vec3<f32>, h0: f32, h: f32) -> vec3<f32> {
    return base + o + dn * h0 + n * (h - h0);
}

// The local part of a vertex past the flat rule: patch + (h − h₀)·normalize(patch of normals).
fn ecm_local_flat(base: vec3<f32>, normal: vec3<f32>, h0: f32, h: f32) -> vec3<f32> {
    return base + normalize(normal) * (h - h0);
}
