//! Statistics of elevation differences dh = A − B, each sample weighted (by its cell's area on
//! the ellipsoid, or 1 to count samples as xDEM and demcompare do): count, mean, median, standard
//! deviation, RMSE, NMAD, min, max, LE90, the 90th percentile of |dh|, a histogram, and the same
//! per slope class. Deterministic: sums in f64 in sample order, quantiles from one stable sort
//! and the absolute deviations merged from it. This is the definition, written to be read:
//! `compare` and `coregister` make the same figures in passes over their differences, on every
//! thread and in bounded memory ([`super::streamed`]), and are tested against it.
//!
//! Weighted quantiles generalise numpy's default (linear interpolation between order statistics,
//! sample k of n at p = k/(n − 1)): sorted by value, sample k sits at p_k = (W_k − w_0)/(W − w_0)
//! with W_k the weights up to and including k, and p is interpolated linearly between the two
//! samples around it. With equal weights this is numpy's `quantile(x, p)` exactly.

use crate::maths::CompensatedSum;
use serde::Serialize;

/// The factor that makes the median absolute deviation a standard deviation for normal data.
pub const NMAD_FACTOR: f64 = 1.4826;

/// Default slope classes, degrees (the last one open).
pub const SLOPE_CLASSES_DEG: [f64; 7] = [0.0, 5.0, 10.0, 20.0, 30.0, 45.0, 90.0];

/// Bins of the histogram.
pub const HISTOGRAM_BINS: usize = 50;

/// One difference: its value, weight and the reference's slope there.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Diff {
    /// A − B, metres.
    pub dh_m: f64,
    /// The sample's weight (its cell's area in m², or 1).
    pub weight: f64,
    /// The slope of the reference (B), degrees.
    pub slope_deg: f64,
}

/// The statistics of a set of differences (field names are the JSON's: scripts rely on them).
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Stats {
    /// Samples with a difference.
    pub count: u64,
    /// Samples where one of A and B has data and the other none.
    pub nodata_count: u64,
    /// Σ weights (the area compared in m² when weighted by area).
    pub weight_sum: f64,
    /// Weighted mean, metres.
    pub mean_m: f64,
    /// Weighted median, metres.
    pub median_m: f64,
    /// Weighted standard deviation (population), metres.
    pub std_m: f64,
    /// Weighted root mean square, metres.
    pub rmse_m: f64,
    /// 1.4826 × the weighted median of |dh − median|, metres.
    pub nmad_m: f64,
    /// Smallest difference, metres.
    pub min_m: f64,
    /// Largest difference, metres.
    pub max_m: f64,
    /// 95th − 5th weighted percentile, metres.
    pub le90_m: f64,
    /// The 90th weighted percentile of |dh|, metres.
    pub p90_abs_m: f64,
}

impl Stats {
    /// The statistics of no differences: counts 0 (and `nodata_count`), the rest NaN.
    pub fn empty(nodata_count: u64) -> Stats {
        let nan = f64::NAN;
        Stats {
            nodata_count,
            mean_m: nan,
            median_m: nan,
            std_m: nan,
            rmse_m: nan,
            nmad_m: nan,
            min_m: nan,
            max_m: nan,
            le90_m: nan,
            p90_abs_m: nan,
            ..Stats::default()
        }
    }
}

/// A histogram of dh: `edges_m` has one more entry than `count` and `weight`.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct Histogram {
    /// Bin edges, metres (the 0.5th to the 99.5th percentile, equal bins).
    pub edges_m: Vec<f64>,
    /// Samples per bin (values outside the edges go to the end bins).
    pub count: Vec<u64>,
    /// Σ weights per bin.
    pub weight: Vec<f64>,
    /// The bins' width, metres.
    #[serde(skip)]
    width_m: f64,
}

/// Statistics within one slope class.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct SlopeClass {
    /// Lower bound, degrees (inclusive).
    pub min_deg: f64,
    /// Upper bound, degrees (exclusive; the last class includes 90°).
    pub max_deg: f64,
    /// The statistics of its samples.
    #[serde(flatten)]
    pub stats: Stats,
}

/// The weighted quantile p ∈ [0, 1] of values sorted ascending with their weights (see the
/// module documentation); NaN for no values.
pub fn weighted_quantile(sorted: &[(f64, f64)], p: f64) -> f64 {
    weighted_quantiles(sorted, [p])[0]
}

/// [`weighted_quantile`] at each of `ps` (ascending), the same bit for bit, with one sum of the
/// weights and one walk.
fn weighted_quantiles<const N: usize>(sorted: &[(f64, f64)], ps: [f64; N]) -> [f64; N] {
    match sorted.len() {
        0 => [f64::NAN; N],
        1 => [sorted[0].0; N],
        _ => {
            let w0 = sorted[0].1;
            let total: f64 = sorted.iter().map(|s| s.1).sum();
            let span = total - w0;
            if span <= 0.0 {
                return [sorted[0].0; N];
            }
            let mut out = [sorted[sorted.len() - 1].0; N];
            // Positions W_k − w_0 are increasing: find the pair around each target.
            let (mut below, mut k) = (0.0, 1); // W_{k−1} − w_0
            for (q, p) in out.iter_mut().zip(ps) {
                let target = p.clamp(0.0, 1.0) * span;
                while k < sorted.len() {
                    let at = below + sorted[k].1;
                    if at >= target {
                        let t = if at > below { (target - below) / (at - below) } else { 0.0 };
                        *q = sorted[k - 1].0 + t * (sorted[k].0 - sorted[k - 1].0);
                        break;
                    }
                    below = at;
                    k += 1;
                }
            }
            out
        }
    }
}

/// The differences' (value, weight) pairs sorted by value, stably (ties keep the samples' order).
fn sorted_pairs(diffs: &[Diff]) -> Vec<(f64, f64)> {
    sorted_by_value(diffs.iter().map(|d| (d.dh_m, d.weight)).collect())
}

/// Pairs sorted by their first value in `f64::total_cmp`'s order, stably.
fn sorted_by_value(mut pairs: Vec<(f64, f64)>) -> Vec<(f64, f64)> {
    pairs.sort_by(|a, b| a.0.total_cmp(&b.0));
    pairs
}

/// `f64::total_cmp`'s order as an unsigned one: negatives' bits flipped whole, positives' sign
/// bit set (so keys compare as the values do, −0 before +0).
pub(super) fn order_key(x: f64) -> u64 {
    let b = x.to_bits();
    if b >> 63 == 1 { !b } else { b | (1 << 63) }
}

/// The value of an [`order_key`].
pub(super) fn order_value(key: u64) -> f64 {
    f64::from_bits(if key >> 63 == 1 { key & !(1 << 63) } else { !key })
}

/// |x − c| with the weights of values sorted ascending, sorted ascending: the values below c
/// taken back from c merged with those from c on, in O(n) instead of a sort. The order is the
/// one a stable sort of |x − c| in value order gives: equal distances in value order (a run of
/// them below c keeps its own order), those below c before those above.
#[cfg(test)]
fn folded(sorted: &[(f64, f64)], c: f64) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(sorted.len());
    fold_each(sorted, c, |pair| {
        out.push(pair);
        true
    });
    out
}

/// [`folded`]'s pairs handed to `emit` in its order, without holding them.
/// `emit` returns whether to go on.
fn fold_each(sorted: &[(f64, f64)], c: f64, mut emit: impl FnMut((f64, f64)) -> bool) {
    let split = sorted.partition_point(|p| p.0 < c);
    let (below, above) = sorted.split_at(split);
    let distance = |x: f64| (x - c).abs();
    let (mut end, mut j) = (below.len(), 0);
    while end > 0 {
        // The run of equal distances ending at `end` (distances fall along `below`).
        let d = distance(below[end - 1].0);
        let mut start = end - 1;
        while start > 0 && distance(below[start - 1].0) == d {
            start -= 1;
        }
        while j < above.len() && distance(above[j].0) < d {
            if !emit((distance(above[j].0), above[j].1)) {
                return;
            }
            j += 1;
        }
        if !below[start..end].iter().all(|&(x, w)| emit((distance(x), w))) {
            return;
        }
        end = start;
    }
    let _ = above[j..].iter().all(|&(x, w)| emit((distance(x), w)));
}

/// `weighted_quantile(&folded(sorted, c), p)`, the same bit for bit, in two passes over the
/// folding and without holding it (on millions of samples, allocating it cost more than
/// walking it twice).
fn folded_quantile(sorted: &[(f64, f64)], c: f64, p: f64) -> f64 {
    // Pass 1: what `weighted_quantile` reads before its walk (the sum in the folding's order).
    let (mut count, mut first, mut total) = (0usize, (f64::NAN, 0.0), 0.0);
    fold_each(sorted, c, |pair| {
        if count == 0 {
            first = pair;
            total = pair.1;
        } else {
            total += pair.1;
        }
        count += 1;
        true
    });
    match count {
        0 => return f64::NAN,
        1 => return first.0,
        _ => {}
    }
    let span = total - first.1;
    if span <= 0.0 {
        return first.0;
    }
    // Pass 2: the walk, up to the pair around the target.
    let target = p.clamp(0.0, 1.0) * span;
    let (mut k, mut below, mut previous, mut found) = (0usize, 0.0, f64::NAN, None);
    fold_each(sorted, c, |(x, w)| {
        if k > 0 {
            let at = below + w;
            if at >= target {
                let t = if at > below { (target - below) / (at - below) } else { 0.0 };
                found = Some(previous + t * (x - previous));
                return false;
            }
            below = at;
        }
        previous = x;
        k += 1;
        true
    });
    found.unwrap_or(previous)
}

/// The statistics of `diffs` (weights > 0), with `nodata_count` recorded as given.
pub fn stats(diffs: &[Diff], nodata_count: u64) -> Stats {
    pair_stats(diffs.iter().map(|d| (d.dh_m, d.weight)).collect(), nodata_count)
}

/// [`stats`] of (dh, weight) pairs in sample order (weights > 0). The pairs become the sort's
/// buffer.
fn pair_stats(pairs: Vec<(f64, f64)>, nodata_count: u64) -> Stats {
    if pairs.is_empty() {
        return Stats::empty(nodata_count);
    }
    let mut s = Stats { count: pairs.len() as u64, nodata_count, ..Stats::default() };
    // Compensated sums, as the streamed statistics make them (shards joined agree with these).
    let (mut w, mut wx, mut wxx) = (CompensatedSum::default(), CompensatedSum::default(), CompensatedSum::default());
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for &(dh, weight) in &pairs {
        w.add(weight);
        wx.add(weight * dh);
        wxx.add(weight * dh * dh);
        lo = lo.min(dh);
        hi = hi.max(dh);
    }
    let (w, wx, wxx) = (w.value(), wx.value(), wxx.value());
    let mean = wx / w;
    let var = pairs.iter().map(|&(dh, weight)| weight * (dh - mean).powi(2)).sum::<CompensatedSum>().value() / w;
    let sorted = sorted_by_value(pairs);
    let [q05, median, q95] = weighted_quantiles(&sorted, [0.05, 0.5, 0.95]);
    // The two foldings are independent, each walked in order on one thread: the same result on
    // any number of threads.
    let (nmad, p90_abs) = rayon::join(|| folded_quantile(&sorted, median, 0.5), || folded_quantile(&sorted, 0.0, 0.9));
    s.weight_sum = w;
    s.mean_m = mean;
    s.median_m = median;
    s.std_m = var.sqrt();
    s.rmse_m = (wxx / w).sqrt();
    s.nmad_m = NMAD_FACTOR * nmad;
    s.min_m = lo;
    s.max_m = hi;
    s.le90_m = q95 - q05;
    s.p90_abs_m = p90_abs;
    s
}

/// A histogram of `diffs` over their 0.5th to 99.5th weighted percentile in `bins` equal bins.
pub fn histogram(diffs: &[Diff], bins: usize) -> Histogram {
    let bins = bins.max(1);
    if diffs.is_empty() {
        return Histogram::default();
    }
    let sorted = sorted_pairs(diffs);
    let [lo, hi] = weighted_quantiles(&sorted, [0.005, 0.995]);
    let mut h = Histogram::over(lo, hi, bins);
    for d in diffs {
        h.add(d.dh_m, d.weight);
    }
    h
}

impl Histogram {
    /// An empty histogram of `bins` equal bins from `lo` to `hi` (a metre wide around `lo` where
    /// `hi` is not above it).
    pub(super) fn over(mut lo: f64, mut hi: f64, bins: usize) -> Histogram {
        if hi <= lo {
            (lo, hi) = (lo - 0.5, lo + 0.5);
        }
        let width = (hi - lo) / bins as f64;
        let edges_m = (0..=bins).map(|k| lo + width * k as f64).collect();
        Histogram { edges_m, count: vec![0; bins], weight: vec![0.0; bins], width_m: width }
    }

    /// The counts of another histogram over the same bins added to these.
    pub(super) fn join(&mut self, other: &Histogram) {
        self.count.iter_mut().zip(&other.count).for_each(|(c, o)| *c += o);
        self.weight.iter_mut().zip(&other.weight).for_each(|(w, o)| *w += o);
    }

    /// Counts `dh` with its weight (outside the edges, in the end bins).
    pub(super) fn add(&mut self, dh_m: f64, weight: f64) {
        let bins = self.count.len();
        let k = (((dh_m - self.edges_m[0]) / self.width_m).floor().max(0.0) as usize).min(bins - 1);
        self.count[k] += 1;
        self.weight[k] += weight;
    }
}

/// The slope class of `slope_deg` among classes with edges `bounds_deg` (the last class includes
/// its upper bound); None outside them all or for a NaN slope.
pub fn slope_class(bounds_deg: &[f64], slope_deg: f64) -> Option<usize> {
    let classes = bounds_deg.len().saturating_sub(1);
    bounds_deg
        .windows(2)
        .enumerate()
        .position(|(k, b)| slope_deg >= b[0] && (slope_deg < b[1] || (k + 1 == classes && slope_deg <= b[1])))
}

/// The statistics per slope class; `bounds_deg` are the class edges (the last class includes its
/// upper bound).
pub fn by_slope(diffs: &[Diff], bounds_deg: &[f64]) -> Vec<SlopeClass> {
    bounds_deg
        .windows(2)
        .enumerate()
        .map(|(k, b)| {
            let members: Vec<Diff> =
                diffs.iter().filter(|d| slope_class(bounds_deg, d.slope_deg) == Some(k)).copied().collect();
            SlopeClass { min_deg: b[0], max_deg: b[1], stats: stats(&members, 0) }
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn plain(values: &[f64]) -> Vec<Diff> {
        values.iter().map(|&dh_m| Diff { dh_m, weight: 1.0, slope_deg: 0.0 }).collect()
    }

    #[test]
    fn equal_weights_give_numpys_linear_quantiles() {
        // numpy.quantile([1, 2, 4, 7, 11], [0, 0.1, 0.5, 0.9, 1]) = [1, 1.4, 4, 9.4, 11]
        let sorted: Vec<(f64, f64)> = [1.0, 2.0, 4.0, 7.0, 11.0].iter().map(|&x| (x, 3.0)).collect();
        for (p, expected) in [(0.0, 1.0), (0.1, 1.4), (0.5, 4.0), (0.9, 9.4), (1.0, 11.0)] {
            assert!((weighted_quantile(&sorted, p) - expected).abs() < 1e-12, "p {p}");
        }
    }

    #[test]
    fn closed_forms_on_a_small_set() {
        // dh = 1, 2, 3, 4, 100: mean 22, median 3, |dh − 3| = 2,1,0,1,97 → median 1.
        let s = stats(&plain(&[4.0, 1.0, 100.0, 3.0, 2.0]), 7);
        assert_eq!((s.count, s.nodata_count), (5, 7));
        assert_eq!(s.mean_m, 22.0);
        assert_eq!(s.median_m, 3.0);
        assert!((s.nmad_m - NMAD_FACTOR).abs() < 1e-12);
        assert_eq!((s.min_m, s.max_m), (1.0, 100.0));
        let var = [1.0f64, 2.0, 3.0, 4.0, 100.0].iter().map(|x| (x - 22.0).powi(2)).sum::<f64>() / 5.0;
        assert!((s.std_m - var.sqrt()).abs() < 1e-12);
        let rms = ([1.0f64, 4.0, 9.0, 16.0, 10_000.0].iter().sum::<f64>() / 5.0).sqrt();
        assert!((s.rmse_m - rms).abs() < 1e-12);
    }

    #[test]
    fn a_weight_of_k_is_the_sample_repeated_k_times_in_the_moments() {
        let values = [0.3, -1.7, 2.2, 5.0, -0.4, 0.9];
        let weights = [1.0, 3.0, 2.0, 1.0, 4.0, 2.0];
        let weighted: Vec<Diff> =
            values.iter().zip(weights).map(|(&dh_m, weight)| Diff { dh_m, weight, slope_deg: 0.0 }).collect();
        let repeated: Vec<f64> =
            values.iter().zip(weights).flat_map(|(&v, w)| std::iter::repeat_n(v, w as usize)).collect();
        let (a, b) = (stats(&weighted, 0), stats(&plain(&repeated), 0));
        for (x, y) in [(a.mean_m, b.mean_m), (a.std_m, b.std_m), (a.rmse_m, b.rmse_m), (a.min_m, b.min_m)] {
            assert!((x - y).abs() < 1e-12, "{x} {y}");
        }
        // Quantiles of a weighted set lie within the repeated set's neighbouring order statistics.
        assert!(a.median_m >= -0.4 && a.median_m <= 0.9, "{}", a.median_m);
    }

    #[test]
    fn slope_classes_split_the_samples_and_the_histogram_holds_them_all() {
        let diffs: Vec<Diff> =
            (0..900).map(|k| Diff { dh_m: (k % 17) as f64 - 8.0, weight: 1.0, slope_deg: k as f64 / 10.0 }).collect();
        let classes = by_slope(&diffs, &SLOPE_CLASSES_DEG);
        assert_eq!(classes.len(), 6);
        assert_eq!(classes.iter().map(|c| c.stats.count).sum::<u64>(), 900);
        assert_eq!(classes[0].stats.count, 50); // 0.0 … 4.9°
        assert_eq!(classes[5].stats.count, 450); // 45.0 … 89.9°
        let h = histogram(&diffs, HISTOGRAM_BINS);
        assert_eq!(h.count.iter().sum::<u64>(), 900);
        assert_eq!(h.edges_m.len(), HISTOGRAM_BINS + 1);
        let empty = stats(&[], 3);
        assert!(empty.mean_m.is_nan() && empty.count == 0 && empty.nodata_count == 3);
    }

    #[test]
    fn the_quantiles_of_tiny_foldings() {
        assert!(folded_quantile(&[], 0.0, 0.5).is_nan());
        assert_eq!(folded_quantile(&[(-3.0, 2.0)], 1.0, 0.5), 4.0);
        assert_eq!(
            folded_quantile(&[(-3.0, 2.0), (5.0, 1.0)], 1.0, 0.5),
            weighted_quantile(&[(4.0, 2.0), (4.0, 1.0)], 0.5)
        );
        assert_eq!(
            folded_quantile(&[(1.0, 2.0), (2.0, 1.0), (4.0, 1.0)], 2.0, 0.9),
            weighted_quantile(&[(0.0, 1.0), (1.0, 2.0), (2.0, 1.0)], 0.9)
        );
    }

    #[test]
    fn folding_a_sorted_list_orders_it_as_sorting_the_distances_stably_would() {
        // Ties of every kind: equal values, equal distances on both sides of c, values at c, and
        // distances that round to the same number from different values.
        let mut values: Vec<(f64, f64)> = Vec::new();
        for k in 0..400u32 {
            let x = f64::from(crate::maths::pcg(k) % 41) / 4.0 - 5.0;
            values.push((x, f64::from(k % 7 + 1)));
        }
        values.extend([(1e-17, 2.0), (2e-17, 3.0), (0.0, 5.0), (-0.0, 4.0)]);
        values.sort_by(|a, b| a.0.total_cmp(&b.0));
        for c in [0.0, 0.25, 1.0, -2.5, 1.0 + 1e-16, 100.0, -100.0] {
            let mut want: Vec<(f64, f64)> = values.iter().map(|&(x, w)| ((x - c).abs(), w)).collect();
            want.sort_by(|a, b| a.0.total_cmp(&b.0));
            let got = folded(&values, c);
            assert_eq!(got.len(), want.len());
            for (g, w) in got.iter().zip(&want) {
                assert_eq!((g.0.to_bits(), g.1.to_bits()), (w.0.to_bits(), w.1.to_bits()), "c = {c}");
            }
            for p in [0.0, 0.05, 0.5, 0.9, 0.95, 1.0] {
                let quantile = weighted_quantile(&got, p);
                assert_eq!(folded_quantile(&values, c, p).to_bits(), quantile.to_bits(), "c = {c}, p = {p}");
            }
        }
    }

    #[test]
    fn quantiles_walked_together_are_each_quantile_bit_for_bit() {
        let sorted = sorted_by_value(
            (0..3000u32).map(|k| (f64::from(crate::maths::pcg(k) % 1000) * 0.37, 1.0 + f64::from(k % 7))).collect(),
        );
        let ps = [0.0, 0.005, 0.05, 0.5, 0.5, 0.95, 0.995, 1.0];
        for (p, q) in ps.iter().zip(weighted_quantiles(&sorted, ps)) {
            assert_eq!(q.to_bits(), weighted_quantile_alone(&sorted, *p).to_bits(), "p = {p}");
        }
    }

    /// `weighted_quantile` as it was written before the quantiles were walked together.
    fn weighted_quantile_alone(sorted: &[(f64, f64)], p: f64) -> f64 {
        let total: f64 = sorted.iter().map(|s| s.1).sum();
        let (span, target) = (total - sorted[0].1, p * (total - sorted[0].1));
        assert!(span > 0.0);
        let mut below = 0.0;
        for k in 1..sorted.len() {
            let at = below + sorted[k].1;
            if at >= target {
                let t = if at > below { (target - below) / (at - below) } else { 0.0 };
                return sorted[k - 1].0 + t * (sorted[k].0 - sorted[k - 1].0);
            }
            below = at;
        }
        sorted[sorted.len() - 1].0
    }
}
