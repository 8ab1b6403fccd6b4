// Gradient noise on the ellipsoid: the GPU twin of terrafuse::maths::noise and terrafuse::layers::noise (keep in sync).
// A quad carries per octave the integer lattice cell of its origin O (computed in f64 on the
// CPU, wrapped to 32 bits) and the fraction frac(O/λ); a sample adds its quad-local offset in
// f32, so metre wavelengths stay exact at planetary distances.

//!include shared/hash.wgsl

fn noise_hash_cell(cell: vec3<u32>, seed: u32) -> u32 {
    return pcg(pcg(pcg(pcg(seed) ^ cell.x) ^ cell.y) ^ cell.z);
}

fn noise_gradient_dot(hash: u32, d: vec3<f32>) -> f32 {
    switch hash % 12u {
        case 0u: { return d.x + d.y; }
        case 1u: { return -d.x + d.y; }
        case 2u: { return d.x - d.y; }
        case 3u: { return -d.x - d.y; }
        case 4u: { return d.x + d.z; }
        case 5u: { return -d.x + d.z; }
        case 6u: { return d.x - d.z; }
        case 7u: { return -d.x - d.z; }
        case 8u: { return d.y + d.z; }
        case 9u: { return -d.y + d.z; }
        case 10u: { return d.y - d.z; }
        default: { return -d.y - d.z; }
    }
}

fn noise_fade(t: vec3<f32>) -> vec3<f32> {
    return t * t * t * (t * (t * 6.0 - 15.0) + 10.0);
}

fn noise_corner(cell: vec3<u32>, t: vec3<f32>, seed: u32, o: vec3<u32>) -> f32 {
    return noise_gradient_dot(noise_hash_cell(cell + o, seed), t - vec3<f32>(o));
}

// Gradient noise at an integer cell and the offset inside it.
fn noise_gradient(cell: vec3<u32>, t: vec3<f32>, seed: u32) -> f32 {
    let f = noise_fade(t);
    let x00 = mix(noise_corner(cell, t, seed, vec3<u32>(0u, 0u, 0u)), noise_corner(cell, t, seed, vec3<u32>(1u, 0u, 0u)), f.x);
    let x10 = mix(noise_corner(cell, t, seed, vec3<u32>(0u, 1u, 0u)), noise_corner(cell, t, seed, vec3<u32>(1u, 1u, 0u)), f.x);
    let x01 = mix(noise_corner(cell, t, seed, vec3<u32>(0u, 0u, 1u)), noise_corner(cell, t, seed, vec3<u32>(1u, 0u, 1u)), f.x);
    let x11 = mix(noise_corner(cell, t, seed, vec3<u32>(0u, 1u, 1u)), noise_corner(cell, t, seed, vec3<u32>(1u, 1u, 1u)), f.x);
    return mix(mix(x00, x10, f.y), mix(x01, x11, f.y), f.z);
}

// One octave from a quad's lattice origin (cell, frac) and a quad-local offset in metres
// (layers::noise::octave_from_origin).
fn noise_octave(cell: vec3<u32>, frac: vec3<f32>, local_m: vec3<f32>, wavelength_m: f32, seed: u32) -> f32 {
    let x = frac + local_m / wavelength_m;
    let f = floor(x);
    let c = cell + bitcast<vec3<u32>>(vec3<i32>(f));
    return noise_gradient(c, x - f, seed);
}

// Octave weights (layers::noise::resolved_weight and beyond_data_weight).
fn noise_resolved_weight(wavelength_m: f32, spacing_m: f32) -> f32 {
    if spacing_m <= 0.0 {
        return 1.0;
    }
    return clamp(wavelength_m / spacing_m - 1.0, 0.0, 1.0);
}

fn noise_beyond_data_weight(wavelength_m: f32, data_spacing_m: f32) -> f32 {
    if data_spacing_m > 1.0e37 {
        return 1.0;
    }
    return 1.0 - clamp(wavelength_m / data_spacing_m - 1.0, 0.0, 1.0);
}
