//! Small pure helpers that several modules share and that depend on nothing but `glam`: the
//! PCG hash that the noise, the erosion dither and the benchmarks draw from (written once in
//! Rust here and once in WGSL, `shaders/shared/hash.wgsl`), the median, the smoothstep and the
//! distance to a segment; a sum of f64 that does not depend on its terms' order (`exact_sum`).

pub mod compensated_sum;
pub mod exact_sum;
pub mod noise;

pub use compensated_sum::CompensatedSum;
pub use exact_sum::ExactSum;

use glam::DVec3;

/// The 32-bit integer hash of PCG's output permutation (O'Neill 2014), the same on the CPU and
/// the GPU (`pcg` in `shaders/shared/hash.wgsl`).
pub fn pcg(v: u32) -> u32 {
    let state = v.wrapping_mul(747_796_405).wrapping_add(2_891_336_453);
    let word = ((state >> ((state >> 28) + 4)) ^ state).wrapping_mul(277_803_737);
    (word >> 22) ^ word
}

/// The `n` of `indices` (distinct) that come first in PCG hash order, the order of
/// `(pcg(k), k)`, in that order: what sorting them all by that key and keeping the first `n`
/// gives, by selection: O(len + n log n). The hashes are uniform, so the first `n` almost always
/// lie below a threshold a little above their expected largest hash: only those are held and
/// selected from (the whole set only when fewer than `n` do). How the fits draw a deterministic
/// random subset.
pub fn first_in_hash_order(indices: &[usize], n: usize) -> Vec<usize> {
    let mut keyed = hash_selected(indices, n);
    keyed.sort_unstable();
    keyed.into_iter().map(|(_, k)| k).collect()
}

/// The indices [`first_in_hash_order`] gives, in ascending order (without its sort by hash).
pub fn first_in_hash_order_ascending(indices: &[usize], n: usize) -> Vec<usize> {
    let mut chosen: Vec<usize> = hash_selected(indices, n).into_iter().map(|(_, k)| k).collect();
    chosen.sort_unstable();
    chosen
}

/// The `n` of `indices` first in PCG hash order with their hashes, in no order.
fn hash_selected(indices: &[usize], n: usize) -> Vec<(u32, usize)> {
    let key = |k: usize| (pcg(k as u32), k);
    if n == 0 {
        return Vec::new();
    }
    let expected = n as f64 / indices.len() as f64 * 2f64.powi(32);
    let threshold = (expected * 1.1 + 4096.0).min(u32::MAX as f64) as u32;
    let mut keyed: Vec<(u32, usize)> = indices.iter().map(|&k| key(k)).filter(|k| k.0 < threshold).collect();
    if keyed.len() < n.min(indices.len()) {
        keyed = indices.iter().map(|&k| key(k)).collect();
    }
    if n < keyed.len() {
        keyed.select_nth_unstable(n - 1);
        keyed.truncate(n);
    }
    keyed
}

/// The median of `values` (the mean of the two middle ones for an even count; NaN when empty),
/// by selection rather than a sort: O(n).
pub fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return f64::NAN;
    }
    let n = values.len();
    let (below, upper, _) = values.select_nth_unstable_by(n / 2, f64::total_cmp);
    let upper = *upper;
    if n % 2 == 1 {
        return upper;
    }
    let lower = below.iter().copied().max_by(f64::total_cmp).expect("an even count of at least 2");
    0.5 * (lower + upper)
}

/// The smoothstep of `x`: 0 at or below 0, 1 at or above 1, C¹.
pub fn smoothstep(x: f64) -> f64 {
    let t = x.clamp(0.0, 1.0);
    t * t * (3.0 - 2.0 * t)
}

/// The distance from `p` to the segment [a, b], in the units of the points.
pub fn segment_distance_m(p: DVec3, a: DVec3, b: DVec3) -> f64 {
    let ab = b - a;
    let len2 = ab.length_squared();
    let t = if len2 > 0.0 { ((p - a).dot(ab) / len2).clamp(0.0, 1.0) } else { 0.0 };
    (p - (a + ab * t)).length()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn first_in_hash_order_is_the_sorted_prefix() {
        let indices: Vec<usize> = (0..5000).map(|k| k * 7 + 3).collect();
        let mut sorted = indices.clone();
        sorted.sort_by_key(|&k| (pcg(k as u32), k));
        for n in [0, 1, 17, 4999, 5000, 6000] {
            assert_eq!(first_in_hash_order(&indices, n), sorted[..n.min(5000)], "{n}");
            let mut ascending = sorted[..n.min(5000)].to_vec();
            ascending.sort_unstable();
            assert_eq!(first_in_hash_order_ascending(&indices, n), ascending, "{n}");
        }
        // Many indices, few kept (the threshold holds them), and indices whose hashes all lie
        // in the upper half (none below the threshold: the whole set is selected from).
        for indices in
            [(0..200_000).collect::<Vec<usize>>(), (0..20_000).filter(|&k| pcg(k as u32) > 1 << 31).collect()]
        {
            let mut sorted = indices.clone();
            sorted.sort_by_key(|&k| (pcg(k as u32), k));
            for n in [1, 10, 1000] {
                assert_eq!(first_in_hash_order(&indices, n), sorted[..n], "{} indices, {n}", indices.len());
            }
        }
    }

    #[test]
    fn the_median_of_odd_even_and_empty_samples() {
        assert_eq!(median(vec![3.0, 1.0, 2.0]), 2.0);
        assert_eq!(median(vec![3.0, 1.0, 2.0, 10.0]), 2.5);
        assert!(median(Vec::new()).is_nan());
    }
}
