//! Unbiased rounding of small per-step amounts to whole volume units, reproducibly: an amount x
//! becomes ⌊x + u⌋ with u ∈ [0, 1) drawn from a hash of (seed, step, cell, stream). Flooring
//! alone would drop rain, evaporation, dissolving and deposition smaller than a unit per step
//! (rain of 10⁻⁶ m/s at Δt = 0.5 s is 0.05 units on a 10 µm quantum: never a whole one); the
//! dither keeps their mean. The hash is [`pcg`] (PCG's output function, O'Neill 2014), which
//! `shaders/shared/hash.wgsl` writes the same way, so the CPU and the GPU draw the same u.

use crate::maths::pcg;

/// The dither streams, one per rounded quantity.
pub const DISSOLVE: u32 = 1;
/// Deposition.
pub const DEPOSIT: u32 = 2;
/// Evaporation.
pub const EVAPORATE: u32 = 3;
/// Rain.
pub const RAIN: u32 = 4;
/// The water sent through pipe k: stream `PIPE + k`.
pub const PIPE: u32 = 8;

/// u ∈ [0, 1) for (seed, step, cell, stream), a multiple of 2⁻²⁴ (exact in f32 and f64).
pub fn uniform(seed: u32, step: u32, cell: u32, stream: u32) -> f64 {
    let h = pcg(pcg(pcg(seed ^ stream.wrapping_mul(0x9e37_79b9)) ^ step) ^ cell);
    f64::from(h >> 8) / f64::from(1u32 << 24)
}

/// The seed of a run as the kernels take it (a project's u64 seed folded to 32 bits).
pub fn fold_seed(seed: u64) -> u32 {
    (seed as u32) ^ ((seed >> 32) as u32)
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_dither_is_uniform_and_keeps_the_mean() {
        // 10⁵ draws: mean ½ within 0.5 %, and ⌊0.05 + u⌋ averages 0.05 within 5 %.
        let n = 100_000u32;
        let draws: Vec<f64> = (0..n).map(|c| super::uniform(3, 17, c, super::RAIN)).collect();
        let mean = draws.iter().sum::<f64>() / f64::from(n);
        assert!((mean - 0.5).abs() < 0.0025, "{mean}");
        assert!(draws.iter().all(|u| (0.0..1.0).contains(u)));
        let kept = draws.iter().map(|u| (0.05 + u).floor()).sum::<f64>() / f64::from(n);
        assert!((kept - 0.05).abs() < 0.0025, "{kept}");
        // Different streams and steps draw differently.
        assert_ne!(super::uniform(3, 17, 5, 1), super::uniform(3, 17, 5, 2));
        assert_ne!(super::uniform(3, 17, 5, 1), super::uniform(3, 18, 5, 1));
    }
}
