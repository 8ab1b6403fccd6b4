//! Procedural noise on the ellipsoid: 3-D gradient noise (Perlin's improved noise, quintic fade,
//! the 12 cube-edge gradients) of the ECEF position, summed over octaves as fBm or a ridged
//! multifractal. Being a function of the 3-D position, it is seamless across faces and levels by
//! construction. CPU reference of `shaders/shared/noise.wgsl` (keep in sync).
//!
//! Precision: the lattice of octave k (cell size λₖ) is addressed by integer cell indices. On the
//! CPU, x = P/λₖ in f64, cell = ⌊x⌋ (i64, wrapped to 32 bits for hashing), t = x − ⌊x⌋. On the
//! GPU, a quad carries per octave the f64-computed integer cell of its origin O and the fraction
//! frac(O/λₖ); each sample adds its quad-local offset (P − O)/λₖ in f32. The GPU's error is then
//! that of the quad-local offset (≈ 2⁻²⁴·|P − O|/λₖ cells), not that of P (≈ 2⁻²⁴·6.4·10⁶ m ≈
//! 0.4 m on Earth, which would make metre wavelengths noise).

use glam::DVec3;

use super::spec::{DetailWhere, NoiseSpec, NoiseType};
pub use crate::maths::noise::{OCTAVE_MAX, gradient_noise, lattice_origin, octave_at, octave_from_origin, octave_seed};

/// Wavelength of octave k, metres.
pub fn octave_wavelength_m(noise: &NoiseSpec, octave: u32) -> f64 {
    noise.wavelength_m / noise.lacunarity.powi(octave as i32)
}

/// How much of an octave of wavelength λ a grid of sample spacing s shows: 1 for λ ≥ 2s
/// (resolved), 0 for λ ≤ s (would alias), linear between. `s = 0` keeps every octave.
pub fn resolved_weight(wavelength_m: f64, spacing_m: f64) -> f64 {
    if spacing_m <= 0.0 { 1.0 } else { (wavelength_m / spacing_m - 1.0).clamp(0.0, 1.0) }
}

/// For [`DetailWhere::BeyondData`]: how much of an octave the data below still lack: 0 for
/// λ ≥ 2·s_data (the data have it), 1 for λ ≤ s_data; 1 everywhere without data (s = ∞).
pub fn beyond_data_weight(wavelength_m: f64, data_spacing_m: f64) -> f64 {
    if data_spacing_m.is_infinite() { 1.0 } else { 1.0 - (wavelength_m / data_spacing_m - 1.0).clamp(0.0, 1.0) }
}

/// The octave weights at a sample: resolved by the grid (`spacing_m`, 0 for all) and, for
/// `beyond_data`, missing from the data below: (1 − c) + c·[`beyond_data_weight`], with c the
/// share of the running height that comes from datasets (so the detail fades in with a
/// dataset's feather instead of jumping where its coverage reaches 0).
pub fn octave_weights(noise: &NoiseSpec, spacing_m: f64, data_spacing_m: f64, data_coverage: f64) -> Vec<f64> {
    (0..noise.octaves)
        .map(|k| {
            let lambda = octave_wavelength_m(noise, k);
            let mut w = resolved_weight(lambda, spacing_m);
            if noise.placement == DetailWhere::BeyondData {
                w *= (1.0 - data_coverage) + data_coverage * beyond_data_weight(lambda, data_spacing_m);
            }
            w
        })
        .collect()
}

/// The octaves a grid of `spacing_m` evaluates (those with a nonzero resolved weight).
pub fn octaves_resolved(noise: &NoiseSpec, spacing_m: f64) -> u32 {
    (0..noise.octaves).take_while(|&k| resolved_weight(octave_wavelength_m(noise, k), spacing_m) > 0.0).count() as u32
}

/// The fractal from per-octave values nₖ and weights wₖ, metres (before scale and offset).
pub fn fractal(noise: &NoiseSpec, values: &[f64], weights: &[f64]) -> f64 {
    let mut sum = 0.0;
    let mut amplitude = noise.amplitude_m;
    let mut ridge_weight = 1.0;
    for (n, w) in values.iter().zip(weights) {
        match noise.noise_type {
            NoiseType::Fbm => sum += amplitude * w * n,
            NoiseType::Ridged => {
                let s = (1.0 - n.abs()) * (1.0 - n.abs()) * ridge_weight;
                ridge_weight = (2.0 * s).clamp(0.0, 1.0);
                sum += amplitude * w * s;
            }
        }
        amplitude *= noise.gain;
    }
    sum
}

/// The noise at an ECEF position with given octave weights (CPU reference, f64 lattice).
pub fn noise_at(noise: &NoiseSpec, p_ecef: DVec3, weights: &[f64]) -> f64 {
    let values: Vec<f64> = (0..weights.len() as u32)
        .map(|k| {
            if weights[k as usize] > 0.0 || noise.noise_type == NoiseType::Ridged {
                octave_at(p_ecef, octave_wavelength_m(noise, k), octave_seed(noise.seed, k))
            } else {
                0.0
            }
        })
        .collect();
    fractal(noise, &values, weights)
}

/// The range the noise can take, metres (before scale and offset).
pub fn noise_range_m(noise: &NoiseSpec) -> (f64, f64) {
    let total: f64 = (0..noise.octaves).map(|k| noise.amplitude_m * noise.gain.powi(k as i32)).sum();
    match noise.noise_type {
        NoiseType::Fbm => (-total * OCTAVE_MAX, total * OCTAVE_MAX),
        NoiseType::Ridged => (0.0, total),
    }
}

/// The largest change of the noise over a distance d (metres): Σ amplitudeₖ·min(2, G·d/λₖ),
/// with G = 2.5 bounding the improved noise's gradient per cell (a slope bound for skirts).
pub fn noise_change_bound_m(noise: &NoiseSpec, distance_m: f64) -> f64 {
    (0..noise.octaves)
        .map(|k| {
            let amplitude = noise.amplitude_m * noise.gain.powi(k as i32);
            amplitude * (2.5 * distance_m / octave_wavelength_m(noise, k)).min(2.0)
        })
        .sum()
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    fn spec(noise_type: NoiseType) -> NoiseSpec {
        NoiseSpec {
            noise_type,
            seed: 11,
            amplitude_m: 10.0,
            wavelength_m: 1000.0,
            octaves: 6,
            lacunarity: 2.0,
            gain: 0.5,
            placement: DetailWhere::Everywhere,
        }
    }

    #[test]
    fn one_octave_stays_within_its_bound_and_vanishes_on_the_lattice() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let mut worst = 0f64;
        for _ in 0..200_000 {
            let t = [rng.random::<f64>(), rng.random::<f64>(), rng.random::<f64>()];
            let cell = [rng.random::<u32>(), rng.random::<u32>(), rng.random::<u32>()];
            worst = worst.max(gradient_noise(cell, t, 5).abs());
        }
        assert!(worst <= OCTAVE_MAX && worst > 0.8, "largest |n| {worst}");
        assert_eq!(gradient_noise([7, 8, 9], [0.0, 0.0, 0.0], 5), 0.0);
    }

    #[test]
    fn noise_is_continuous_across_lattice_cells() {
        // Just below and just above a cell boundary, the value is the same to first order.
        let p = DVec3::new(6_378_137.0, 1000.0 * 17.0, 250.0);
        let e = 1e-6;
        let a = octave_at(p - DVec3::new(0.0, e, 0.0), 1000.0, 3);
        let b = octave_at(p + DVec3::new(0.0, e, 0.0), 1000.0, 3);
        assert!((a - b).abs() < 1e-8, "{a} vs {b}");
    }

    #[test]
    fn the_split_lattice_address_gives_the_f64_value_at_metre_wavelengths_on_earth() {
        // A 1 m octave 6 378 km from the centre: O/λ ≈ 6.4·10⁶ cells, far beyond f32's 2²⁴.
        let origin = DVec3::new(6_378_137.0, -1234.5678, 2222.125);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(9);
        let mut worst = 0f64;
        for _ in 0..2000 {
            // Quad-local offsets of up to 300 m (a level-15 quad on Earth).
            let local = DVec3::new(
                rng.random_range(-300.0..300.0),
                rng.random_range(-300.0..300.0),
                rng.random_range(-300.0..300.0),
            );
            let exact = octave_at(origin + local, 1.0, 4);
            let (cell, frac) = lattice_origin(origin, 1.0);
            let split = octave_from_origin(cell, frac.map(|f| f as f32), local.as_vec3().to_array(), 1.0, 4);
            worst = worst.max((exact - split).abs());
        }
        // f32 quad-local offsets of ≤ 300 m round by ≤ 1.5·10⁻⁵ m = 1.5·10⁻⁵ cells, and adding
        // the fraction rounds once more (a sum ≤ 301: 1.5·10⁻⁵); the noise's gradient is ≤ 2.5
        // per cell: ≤ 7.5·10⁻⁵.
        assert!(worst < 7.5e-5, "worst difference {worst}");
        // Whereas f32 absolute positions would be useless at this wavelength.
        let p = origin + DVec3::new(0.3, 0.2, 0.1);
        let naive = octave_at(p.as_vec3().as_dvec3(), 1.0, 4);
        assert!((naive - octave_at(p, 1.0, 4)).abs() > 1e-3);
    }

    #[test]
    fn fractals_stay_within_their_ranges() {
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
        for kind in [NoiseType::Fbm, NoiseType::Ridged] {
            let n = spec(kind);
            let (lo, hi) = noise_range_m(&n);
            let weights = vec![1.0; n.octaves as usize];
            for _ in 0..5000 {
                let p = DVec3::new(rng.random_range(-1e6..1e6), rng.random_range(-1e6..1e6), 6e6);
                let v = noise_at(&n, p, &weights);
                assert!(v >= lo && v <= hi, "{kind:?}: {v} outside [{lo}, {hi}]");
            }
        }
    }

    #[test]
    fn octaves_finer_than_the_grid_are_weighted_out() {
        let n = spec(NoiseType::Fbm); // 1000, 500, 250, 125, 62.5, 31.25 m
        assert_eq!(octaves_resolved(&n, 100.0), 4); // 125 m: weight 0.25; 62.5 m: 0
        let w = octave_weights(&n, 100.0, f64::INFINITY, 0.0);
        assert_eq!(w, vec![1.0, 1.0, 1.0, 0.25, 0.0, 0.0]);
        assert_eq!(octaves_resolved(&n, 0.0), 6);
        // Beyond the data: a dataset of 300 m spacing already has 1000 m and 500 m (≥ 600 m).
        let mut b = spec(NoiseType::Fbm);
        b.placement = DetailWhere::BeyondData;
        let w = octave_weights(&b, 0.0, 300.0, 1.0);
        assert_eq!(w[0], 0.0, "1000 m ≥ 2 × 300 m: in the data");
        assert!((w[1] - (1.0 - (500.0 / 300.0 - 1.0))).abs() < 1e-12, "500 m: partly");
        assert_eq!(&w[2..], &[1.0; 4], "250 m and finer: all missing from the data");
        // Half covered by data (a feather): halfway between all octaves and the data's gap.
        let half = octave_weights(&b, 0.0, 300.0, 0.5);
        assert_eq!(half[0], 0.5);
        assert_eq!(octave_weights(&b, 0.0, 300.0, 0.0), vec![1.0; 6]);
    }
}
