//! 3-D gradient noise of a position (Perlin's improved noise, quintic fade, the 12 cube-edge
//! gradients), one octave at a time, with the lattice addressed in f64 on the CPU and split into
//! a quad origin and an f32 offset the way the GPU addresses it (`shaders/shared/noise.wgsl`).
//! The procedural detail layer (`crate::layers::noise`) sums octaves of it; the noise brush
//! (`crate::edit`) adds one.

use glam::DVec3;

use super::pcg;

/// Largest |value| of one octave of [`gradient_noise`] (bounds use it): the improved noise with
/// these gradients stays within ±1 (measured maximum 0.97 over 10⁶ random points, see the test).
pub const OCTAVE_MAX: f64 = 1.0;

/// The hash of a lattice point of one octave of one seed.
pub fn hash_cell(cell: [u32; 3], seed: u32) -> u32 {
    pcg(pcg(pcg(pcg(seed) ^ cell[0]) ^ cell[1]) ^ cell[2])
}

/// The improved-noise gradient (one of the 12 cube edge midpoints) dotted with `d`.
pub fn gradient_dot(hash: u32, d: [f64; 3]) -> f64 {
    let [x, y, z] = d;
    match hash % 12 {
        0 => x + y,
        1 => -x + y,
        2 => x - y,
        3 => -x - y,
        4 => x + z,
        5 => -x + z,
        6 => x - z,
        7 => -x - z,
        8 => y + z,
        9 => -y + z,
        10 => y - z,
        _ => -y - z,
    }
}

fn fade(t: f64) -> f64 {
    t * t * t * (t * (t * 6.0 - 15.0) + 10.0)
}

fn lerp(a: f64, b: f64, t: f64) -> f64 {
    a + (b - a) * t
}

/// Gradient noise at a point given as an integer cell and the offset inside it (each in [0, 1]).
pub fn gradient_noise(cell: [u32; 3], t: [f64; 3], seed: u32) -> f64 {
    let corner = |dx: u32, dy: u32, dz: u32| {
        let h = hash_cell([cell[0].wrapping_add(dx), cell[1].wrapping_add(dy), cell[2].wrapping_add(dz)], seed);
        gradient_dot(h, [t[0] - f64::from(dx), t[1] - f64::from(dy), t[2] - f64::from(dz)])
    };
    let (u, v, w) = (fade(t[0]), fade(t[1]), fade(t[2]));
    let x00 = lerp(corner(0, 0, 0), corner(1, 0, 0), u);
    let x10 = lerp(corner(0, 1, 0), corner(1, 1, 0), u);
    let x01 = lerp(corner(0, 0, 1), corner(1, 0, 1), u);
    let x11 = lerp(corner(0, 1, 1), corner(1, 1, 1), u);
    lerp(lerp(x00, x10, v), lerp(x01, x11, v), w)
}

/// The seed of octave k (octaves are decorrelated by seed, not by offsets that lose precision).
pub fn octave_seed(seed: u32, octave: u32) -> u32 {
    pcg(seed.wrapping_add(octave.wrapping_mul(0x9e37_79b9)))
}

/// One octave at an ECEF position, the lattice addressed in f64 (the CPU reference).
pub fn octave_at(p_ecef: DVec3, wavelength_m: f64, seed: u32) -> f64 {
    let x = p_ecef / wavelength_m;
    let f = x.floor();
    // Two's-complement wrap of the i64 cell to 32 bits: the GPU adds i32 offsets the same way.
    let cell = [f.x as i64 as u32, f.y as i64 as u32, f.z as i64 as u32];
    gradient_noise(cell, [x.x - f.x, x.y - f.y, x.z - f.z], seed)
}

/// A quad's lattice origin for octave k: the integer cell of O/λ (wrapped to 32 bits) and the
/// fraction inside it, both from f64 (what the GPU receives per quad and octave).
pub fn lattice_origin(origin_ecef: DVec3, wavelength_m: f64) -> ([u32; 3], [f64; 3]) {
    let x = origin_ecef / wavelength_m;
    let f = x.floor();
    ([f.x as i64 as u32, f.y as i64 as u32, f.z as i64 as u32], [x.x - f.x, x.y - f.y, x.z - f.z])
}

/// One octave the way the GPU evaluates it: from a quad's lattice origin and a quad-local offset
/// (both as the shader receives them, the offset in f32); the twin of `noise_octave` in
/// noise.wgsl, used to check that the split addressing gives the f64 lattice's value.
pub fn octave_from_origin(cell: [u32; 3], frac: [f32; 3], local_m: [f32; 3], wavelength_m: f32, seed: u32) -> f64 {
    let mut c = cell;
    let mut t = [0f64; 3];
    for a in 0..3 {
        let x = frac[a] + local_m[a] / wavelength_m;
        let f = x.floor();
        c[a] = c[a].wrapping_add(f as i32 as u32);
        t[a] = f64::from(x - f);
    }
    gradient_noise(c, t, seed)
}
