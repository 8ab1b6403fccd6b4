//! Statistics of differences in passes over them, in bounded memory: held in memory (a
//! co-registration's, a comparison that fits) or spilled to a scratch file in sample order (a
//! comparison of 10⁸ samples, [`super::spill`]), so memory stays bounded whatever their number.
//! Held records are read in up to four parts on several threads, each part's candidates gathered
//! alone and the parts' put together in order; a record whose difference is NaN is left out.
//!
//! The sums run in sample order as [`stats`](super::stats::stats) runs them, so the count, mean,
//! standard deviation, RMSE, minimum and maximum are the same bit for bit. The quantiles (median,
//! NMAD, LE90, the 90th percentile of |dh|, the histogram's range) are exact weighted order
//! statistics found by radix refinement: one pass counts a population into 2¹⁶ buckets by the top
//! 16 bits of its ordering key; the bucket where the cumulative weight reaches the quantile's
//! position is kept, and the next pass either counts its candidates by their next 16 bits or, once
//! they are few ([`COLLECT`]), reads them, sorts them and walks them as
//! [`weighted_quantile`](super::stats::weighted_quantile) walks the whole sorted set (held records
//! no more than that are read, sorted and walked at once). Positions are summed bucket by bucket
//! rather than sample by sample, so a quantile may differ from the sorted one in its last bits
//! (within 10⁻⁹ of it in the tests); the same on any number of threads.

use std::io;

use rayon::prelude::*;

use super::spill::{NO_CLASS, Record, Records};
use super::stats::{Histogram, NMAD_FACTOR, SlopeClass, Stats, order_key, order_value};

/// Bits of the ordering key one pass tells apart.
const DIGIT_BITS: u32 = 16;
/// Most candidates of one quantile read into memory (24 bytes each).
const COLLECT: u64 = 1 << 18;
/// Most parts a pass reads held records in, and the fewest records in a part.
const PARTS: usize = 4;
const PART: usize = 1 << 20;

/// Some quantiles of one population of differences in one order.
#[derive(Clone, Debug)]
struct Job {
    /// The slope class it is restricted to (every difference with None).
    class: Option<u8>,
    /// None: the values dh; Some(c): the distances |dh − c|, at equal distance those below c
    /// first, then by value (the order `folded` gives).
    centre: Option<f64>,
    /// The quantiles asked for, in [0, 1].
    quantiles: Vec<f64>,
}

impl Job {
    /// A record's place in this job's order, None outside the population; equal places keep the
    /// records' order.
    fn place(&self, r: &Record) -> Option<Place> {
        if r.dh_m.is_nan() || self.class.is_some_and(|c| c != r.class) {
            return None;
        }
        let value = order_key(r.dh_m);
        Some(match self.centre {
            None => Place { key: value, above: false, value },
            Some(c) => Place { key: order_key((r.dh_m - c).abs()), above: r.dh_m >= c, value },
        })
    }
}

/// Where an element sits in a job's order: by its key (the ordering key of the value or the
/// distance), then below the centre first, then by value (distances equal from different
/// values: −0 and +0, or rounding).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
struct Place {
    key: u64,
    above: bool,
    value: u64,
}

/// Candidates sharing a key's digit: how many, their weight, the largest key, and the first in
/// order with its weight.
#[derive(Clone, Copy, Debug)]
struct Bucket {
    count: u64,
    weight: f64,
    max: u64,
    first: (Place, f64),
}

impl Default for Bucket {
    fn default() -> Bucket {
        Bucket { count: 0, weight: 0.0, max: 0, first: (Place { key: 0, above: false, value: 0 }, 0.0) }
    }
}

impl Bucket {
    fn add(&mut self, place: Place, weight: f64) {
        self.count += 1;
        self.weight += weight;
        self.max = self.max.max(place.key);
        if self.count == 1 || place < self.first.0 {
            self.first = (place, weight);
        }
    }

    /// The candidates of the records after these, put after them.
    fn join(&mut self, next: &Bucket) {
        if next.count == 0 {
            return;
        }
        if self.count == 0 || next.first.0 < self.first.0 {
            self.first = next.first;
        }
        self.count += next.count;
        self.weight += next.weight;
        self.max = self.max.max(next.max);
    }
}

/// Buckets in a page.
const PAGE: usize = 256;

/// The 2¹⁶ buckets of a digit, in pages made when first reached: a population's values gather in
/// few of them, so a pass makes (and clears) only those.
struct Buckets {
    pages: Vec<Option<Box<[Bucket; PAGE]>>>,
}

impl Buckets {
    fn new() -> Buckets {
        Buckets { pages: (0..(1 << DIGIT_BITS) / PAGE).map(|_| None).collect() }
    }

    fn at(&mut self, digit: usize) -> &mut Bucket {
        let page = self.pages[digit / PAGE].get_or_insert_with(|| Box::new([Bucket::default(); PAGE]));
        &mut page[digit % PAGE]
    }

    /// The buckets that hold candidates, with their digits, in digit order.
    fn filled(&self) -> impl Iterator<Item = (usize, &Bucket)> {
        self.pages
            .iter()
            .enumerate()
            .filter_map(|(p, page)| page.as_ref().map(|page| (p, page)))
            .flat_map(|(p, page)| page.iter().enumerate().map(move |(k, b)| (p * PAGE + k, b)))
            .filter(|(_, b)| b.count > 0)
    }

    /// The candidates of the records after these, put after them.
    fn join(&mut self, next: Buckets) {
        for (mine, theirs) in self.pages.iter_mut().zip(next.pages) {
            match (mine.as_mut(), theirs) {
                (_, None) => {}
                (None, Some(theirs)) => *mine = Some(theirs),
                (Some(mine), Some(theirs)) => mine.iter_mut().zip(theirs.iter()).for_each(|(b, n)| b.join(n)),
            }
        }
    }
}

/// Where one quantile's search stands: its candidates share the top `depth` bits of their key,
/// `prefix`; `below` is the weight of every element before them in order (cumulative, the
/// first element's included), `before` the value just before them; `goal` the cumulative weight
/// the quantile sits at.
#[derive(Clone, Debug)]
struct Search {
    job: usize,
    quantile: usize,
    goal: f64,
    below: f64,
    before: Option<f64>,
    depth: u32,
    prefix: u64,
    /// Read the candidates rather than count them by their next digit.
    collect: bool,
}

impl Search {
    /// Every element of a job.
    fn whole(job: usize) -> Search {
        Search { job, quantile: 0, goal: 0.0, below: 0.0, before: None, depth: 0, prefix: 0, collect: false }
    }

    fn holds(&self, key: u64) -> bool {
        self.depth == 0 || key >> (64 - self.depth) == self.prefix
    }

    fn digit(&self, key: u64) -> usize {
        ((key >> (64 - self.depth - DIGIT_BITS)) & ((1 << DIGIT_BITS) - 1)) as usize
    }
}

/// One search's candidates after a pass: counted by digit, or read.
struct Gathered {
    buckets: Buckets,
    candidates: Vec<(Place, f64)>,
}

/// How the passes read: at most `collect` candidates of a quantile read at once; held records
/// in parts of at least `part` records (at most [`PARTS`] of them, each with its own buckets), on
/// several threads. The same on any number of threads.
#[derive(Clone, Copy, Debug)]
struct Reading {
    collect: u64,
    part: usize,
}

/// One pass over the records: every search's candidates. Records held in memory are read in
/// parts, each part's candidates gathered alone and the parts' put together in order: the same
/// candidates in the same order, and the same counts, as one scan gives (the buckets' weights
/// summed part by part).
fn gather(records: &dyn Records, jobs: &[Job], searches: &[Search], reading: Reading) -> io::Result<Vec<Gathered>> {
    if let Some(all) = records.held() {
        let parts = (all.len() / reading.part.max(1)).clamp(1, PARTS);
        let chunks: Vec<&[Record]> = all.chunks(all.len().div_ceil(parts).max(1)).collect();
        if chunks.is_empty() {
            return Ok(searches.iter().map(|_| Gathered::empty()).collect());
        }
        let n = chunks.len();
        let mut pieces = (0..searches.len() * n)
            .into_par_iter()
            .map(|t| gather_part(chunks[t % n], &jobs[searches[t / n].job], &searches[t / n]))
            .collect::<Vec<_>>()
            .into_iter();
        let mut gathered = Vec::with_capacity(searches.len());
        while let Some(mut g) = pieces.next() {
            for next in pieces.by_ref().take(n - 1) {
                g.join(next);
            }
            gathered.push(g);
        }
        return Ok(gathered);
    }
    let mut gathered: Vec<Gathered> = searches.iter().map(|_| Gathered::empty()).collect();
    records.scan(&mut |block| {
        gathered.par_iter_mut().zip(searches).for_each(|(g, s)| g.add(block, &jobs[s.job], s));
    })?;
    Ok(gathered)
}

/// One part's candidates of one search.
fn gather_part(part: &[Record], job: &Job, search: &Search) -> Gathered {
    let mut g = Gathered::empty();
    g.add(part, job, search);
    g
}

impl Gathered {
    /// Nothing gathered yet for a search.
    fn empty() -> Gathered {
        Gathered { buckets: Buckets::new(), candidates: Vec::new() }
    }

    /// A block's candidates, in order.
    fn add(&mut self, block: &[Record], job: &Job, search: &Search) {
        for r in block {
            if let Some(place) = job.place(r)
                && search.holds(place.key)
            {
                if search.collect {
                    self.candidates.push((place, r.weight));
                } else {
                    self.buckets.at(search.digit(place.key)).add(place, r.weight);
                }
            }
        }
    }

    /// The candidates of the records after these (the next part), put after them.
    fn join(&mut self, next: Gathered) {
        self.candidates.extend(next.candidates);
        self.buckets.join(next.buckets);
    }
}

/// The quantile from its candidates read: sorted (stably) and walked from `below` as
/// [`weighted_quantile`](super::stats::weighted_quantile) walks the whole set.
fn walk(search: &Search, mut candidates: Vec<(Place, f64)>) -> f64 {
    candidates.sort_by_key(|c| c.0);
    walk_sorted(search, &candidates)
}

/// [`walk`] of candidates already sorted.
fn walk_sorted(search: &Search, candidates: &[(Place, f64)]) -> f64 {
    let (mut below, mut before) = (search.below, search.before);
    for &(place, weight) in candidates {
        let x = order_value(place.key);
        let at = below + weight;
        if at >= search.goal {
            return match before {
                Some(v) => {
                    let t = if at > below { (search.goal - below) / (at - below) } else { 0.0 };
                    v + t * (x - v)
                }
                None => x,
            };
        }
        (below, before) = (at, Some(x));
    }
    // The goal rounded past the last candidate: the largest.
    before.unwrap_or(f64::NAN)
}

/// The bucket of `buckets` (the candidates of `search` counted by their next digit) where the
/// goal is reached: the quantile where that settles it, else the search narrowed to the bucket.
fn narrow(search: Search, buckets: &Buckets, collect: u64) -> Result<f64, Search> {
    let (mut below, mut before) = (search.below, search.before);
    for (digit, bucket) in buckets.filled() {
        if below + bucket.weight >= search.goal {
            let depth = search.depth + DIGIT_BITS;
            let prefix = (search.prefix << DIGIT_BITS) | digit as u64;
            let narrowed = Search { below, before, depth, prefix, collect: bucket.count <= collect, ..search };
            if depth == 64 {
                // One key, one value: only the first candidate's weight can matter.
                return Ok(walk(&narrowed, vec![bucket.first]));
            }
            return Err(narrowed);
        }
        below += bucket.weight;
        before = Some(order_value(bucket.max));
    }
    Ok(before.unwrap_or(f64::NAN))
}

/// Each job's quantiles (NaN for an empty population), in passes over the records read as
/// `reading` says. Records held in memory and no more than a quantile's candidates read at once
/// are read in one pass, sorted and walked.
fn quantiles(records: &dyn Records, jobs: &[Job], reading: Reading) -> io::Result<Vec<Vec<f64>>> {
    let few = records.held().is_some_and(|all| all.len() as u64 <= reading.collect);
    let whole: Vec<Search> = (0..jobs.len()).map(|j| Search { collect: few, ..Search::whole(j) }).collect();
    let tops = gather(records, jobs, &whole, reading)?;
    let mut answers: Vec<Vec<f64>> = jobs.iter().map(|j| vec![f64::NAN; j.quantiles.len()]).collect();
    let mut open = Vec::new();
    for (j, (job, mut top)) in jobs.iter().zip(tops).enumerate() {
        top.candidates.sort_by_key(|c| c.0);
        let (count, first, total): (u64, _, f64) = if few {
            (top.candidates.len() as u64, top.candidates.first().copied(), top.candidates.iter().map(|c| c.1).sum())
        } else {
            (
                top.buckets.filled().map(|(_, b)| b.count).sum(),
                top.buckets.filled().next().map(|(_, b)| b.first),
                top.buckets.filled().map(|(_, b)| b.weight).sum(),
            )
        };
        let Some(first) = first else {
            continue;
        };
        let (least, w0) = (order_value(first.0.key), first.1);
        for (q, &p) in job.quantiles.iter().enumerate() {
            // weighted_quantile's position p·(W − w₀) past the first element.
            let target = p.clamp(0.0, 1.0) * (total - w0);
            if count == 1 || target.is_nan() || target <= 0.0 {
                answers[j][q] = least;
                continue;
            }
            let search = Search { quantile: q, goal: w0 + target, ..whole[j].clone() };
            if few {
                answers[j][q] = walk_sorted(&search, &top.candidates);
                continue;
            }
            match narrow(search, &top.buckets, reading.collect) {
                Ok(v) => answers[j][q] = v,
                Err(s) => open.push(s),
            }
        }
    }
    while !open.is_empty() {
        let gathered = gather(records, jobs, &open, reading)?;
        let mut still = Vec::new();
        for (search, g) in open.into_iter().zip(gathered) {
            let (j, q) = (search.job, search.quantile);
            let found = if search.collect {
                Ok(walk(&search, g.candidates))
            } else {
                narrow(search, &g.buckets, reading.collect)
            };
            match found {
                Ok(v) => answers[j][q] = v,
                Err(s) => still.push(s),
            }
        }
        open = still;
    }
    Ok(answers)
}

/// Sums over one population in record order, as `stats` sums them.
#[derive(Clone, Copy, Debug)]
struct Moments {
    count: u64,
    w: f64,
    wx: f64,
    wxx: f64,
    lo: f64,
    hi: f64,
}

impl Default for Moments {
    fn default() -> Moments {
        Moments { count: 0, w: 0.0, wx: 0.0, wxx: 0.0, lo: f64::INFINITY, hi: f64::NEG_INFINITY }
    }
}

impl Moments {
    fn add(&mut self, r: &Record) {
        self.count += 1;
        self.w += r.weight;
        self.wx += r.weight * r.dh_m;
        self.wxx += r.weight * r.dh_m * r.dh_m;
        self.lo = self.lo.min(r.dh_m);
        self.hi = self.hi.max(r.dh_m);
    }
}

/// What a comparison reports of its differences.
pub struct Streamed {
    /// The statistics of them all.
    pub stats: Stats,
    /// Their histogram.
    pub histogram: Histogram,
    /// The statistics per slope class.
    pub by_slope: Vec<SlopeClass>,
}

/// The statistics, histogram and slope classes of `records` (their classes those of
/// `bounds_deg`), as `stats`, `histogram` and `by_slope` give them for the same differences in
/// memory, with `nodata_count` recorded as given; `bins` 0 makes no histogram (left empty).
pub fn streamed_stats(
    records: &dyn Records,
    nodata_count: u64,
    bounds_deg: &[f64],
    bins: usize,
) -> io::Result<Streamed> {
    streamed_stats_with(records, nodata_count, bounds_deg, bins, Reading { collect: COLLECT, part: PART })
}

/// [`streamed_stats`] of records held in memory (which reading cannot fail).
pub fn held_stats(records: &Vec<Record>, nodata_count: u64, bounds_deg: &[f64], bins: usize) -> Streamed {
    match streamed_stats(records, nodata_count, bounds_deg, bins) {
        Ok(s) => s,
        Err(_) => unreachable!("records held in memory are read without error"),
    }
}

fn streamed_stats_with(
    records: &dyn Records,
    nodata_count: u64,
    bounds_deg: &[f64],
    bins: usize,
    reading: Reading,
) -> io::Result<Streamed> {
    // Population 0: every difference; 1 + k: slope class k.
    let classes = bounds_deg.len().saturating_sub(1).min(usize::from(NO_CLASS));
    let populations: Vec<Option<u8>> = std::iter::once(None).chain((0..classes).map(|k| Some(k as u8))).collect();
    let member = |r: &Record| (r.class != NO_CLASS && usize::from(r.class) < classes).then(|| 1 + usize::from(r.class));
    let mut moments = vec![Moments::default(); populations.len()];
    records.scan(&mut |block| {
        for r in block.iter().filter(|r| !r.dh_m.is_nan()) {
            moments[0].add(r);
            if let Some(p) = member(r) {
                moments[p].add(r);
            }
        }
    })?;
    // The median, 5th and 95th percentiles (and the histogram's 0.5th and 99.5th for them all),
    // and the 90th percentile of |dh|.
    let mut jobs = Vec::new();
    for (p, &class) in populations.iter().enumerate() {
        let mut quantiles = vec![0.5, 0.05, 0.95];
        if p == 0 && bins > 0 {
            quantiles.extend([0.005, 0.995]);
        }
        jobs.push(Job { class, centre: None, quantiles });
        jobs.push(Job { class, centre: Some(0.0), quantiles: vec![0.9] });
    }
    let values = quantiles(records, &jobs, reading)?;
    let of = |p: usize| (&values[2 * p], values[2 * p + 1][0]);
    // The variances about the means, and the histogram over the 0.5th to 99.5th percentile.
    let means: Vec<f64> = moments.iter().map(|m| m.wx / m.w).collect();
    let mut spread = vec![0f64; populations.len()];
    let mut histogram = (moments[0].count > 0 && bins > 0).then(|| Histogram::over(of(0).0[3], of(0).0[4], bins));
    records.scan(&mut |block| {
        for r in block.iter().filter(|r| !r.dh_m.is_nan()) {
            spread[0] += r.weight * (r.dh_m - means[0]).powi(2);
            if let Some(p) = member(r) {
                spread[p] += r.weight * (r.dh_m - means[p]).powi(2);
            }
            if let Some(h) = histogram.as_mut() {
                h.add(r.dh_m, r.weight);
            }
        }
    })?;
    // The median absolute deviations.
    let deviations: Vec<Job> = populations
        .iter()
        .enumerate()
        .map(|(p, &class)| Job { class, centre: Some(of(p).0[0]), quantiles: vec![0.5] })
        .collect();
    let deviations = quantiles(records, &deviations, reading)?;
    let stats_of = |p: usize, nodata_count: u64| {
        let m = &moments[p];
        if m.count == 0 {
            return Stats::empty(nodata_count);
        }
        let (q, p90_abs) = of(p);
        Stats {
            count: m.count,
            nodata_count,
            weight_sum: m.w,
            mean_m: means[p],
            median_m: q[0],
            std_m: (spread[p] / m.w).sqrt(),
            rmse_m: (m.wxx / m.w).sqrt(),
            nmad_m: NMAD_FACTOR * deviations[p][0],
            min_m: m.lo,
            max_m: m.hi,
            le90_m: q[2] - q[1],
            p90_abs_m: p90_abs,
        }
    };
    let by_slope = bounds_deg
        .windows(2)
        .take(classes)
        .enumerate()
        .map(|(k, b)| SlopeClass { min_deg: b[0], max_deg: b[1], stats: stats_of(1 + k, 0) })
        .collect();
    Ok(Streamed { stats: stats_of(0, nodata_count), histogram: histogram.unwrap_or_default(), by_slope })
}

#[cfg(test)]
mod tests {
    use super::super::stats::{Diff, SLOPE_CLASSES_DEG, by_slope, histogram, slope_class, stats};
    use super::*;

    /// Differences with ties of every kind: repeated values, ±0, distances equal on both sides of
    /// the median, weights that vary.
    fn differences(n: u32) -> Vec<Diff> {
        (0..n)
            .map(|k| {
                let h = crate::maths::pcg(k);
                let dh_m = match h % 6 {
                    0 => f64::from(h % 9) - 4.0,
                    1 => -0.0,
                    2 => 0.0,
                    _ => (f64::from(h % 100_000) - 50_000.0) * 1e-3,
                };
                let weight = 1.0 + f64::from(h % 7) * 0.125;
                let slope_deg = if h.is_multiple_of(11) { f64::NAN } else { f64::from(h % 900) / 10.0 };
                Diff { dh_m, weight, slope_deg }
            })
            .collect()
    }

    fn records(diffs: &[Diff]) -> Vec<Record> {
        diffs
            .iter()
            .map(|d| Record {
                dh_m: d.dh_m,
                weight: d.weight,
                class: slope_class(&SLOPE_CLASSES_DEG, d.slope_deg).map_or(NO_CLASS, |k| k as u8),
            })
            .collect()
    }

    fn assert_same(streamed: &Stats, memory: &Stats, what: &str) {
        // The sums run in the same order: equal bit for bit.
        let exact =
            |s: &Stats| [s.weight_sum, s.mean_m, s.std_m, s.rmse_m, s.min_m, s.max_m].map(f64::to_bits).to_vec();
        assert_eq!((streamed.count, streamed.nodata_count), (memory.count, memory.nodata_count), "{what}");
        assert_eq!(exact(streamed), exact(memory), "{what}");
        for (a, b, name) in [
            (streamed.median_m, memory.median_m, "median"),
            (streamed.nmad_m, memory.nmad_m, "NMAD"),
            (streamed.le90_m, memory.le90_m, "LE90"),
            (streamed.p90_abs_m, memory.p90_abs_m, "p90 |dh|"),
        ] {
            assert!((a - b).abs() <= 1e-9 * (1.0 + b.abs()) || (a.is_nan() && b.is_nan()), "{what} {name}: {a} {b}");
        }
    }

    #[test]
    fn streamed_statistics_are_the_in_memory_ones_however_few_candidates_are_read_at_once() {
        for n in [0, 1, 2, 7, 5000] {
            let diffs = differences(n);
            let memory = (stats(&diffs, 3), histogram(&diffs, 50), by_slope(&diffs, &SLOPE_CLASSES_DEG));
            // 0: every quantile narrowed to a single key; 5: a few read; COLLECT: read at once
            // (held records: sorted at once). Held records in one part or in four on threads;
            // records that can only be scanned (a spill's), block by block.
            for collect in [0, 5, COLLECT] {
                for part in [PART, 1000] {
                    let reading = Reading { collect, part };
                    let held = records(&diffs);
                    let scanned = Scanned(held.clone());
                    for (records, how) in [(&held as &dyn Records, "held"), (&scanned, "scanned")] {
                        let what = format!("n {n}, collect {collect}, part {part}, {how}");
                        let s = streamed_stats_with(records, 3, &SLOPE_CLASSES_DEG, 50, reading).unwrap();
                        assert_same(&s.stats, &memory.0, &what);
                        assert_eq!(s.histogram.count, memory.1.count, "{what}");
                        assert_eq!(s.by_slope.len(), memory.2.len());
                        for (a, b) in s.by_slope.iter().zip(&memory.2) {
                            assert_eq!((a.min_deg, a.max_deg), (b.min_deg, b.max_deg));
                            assert_same(&a.stats, &b.stats, &format!("{what}, class {}", a.min_deg));
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn records_without_a_difference_are_left_out_of_every_statistic() {
        let diffs = differences(3000);
        let mut with_gaps = records(&diffs);
        for k in (0..with_gaps.len()).rev().step_by(3) {
            with_gaps.insert(k, Record { dh_m: f64::NAN, weight: 1e9, class: 0 });
        }
        let reading = Reading { collect: 5, part: 500 };
        let a = streamed_stats_with(&records(&diffs), 3, &SLOPE_CLASSES_DEG, 50, reading).unwrap();
        let b = streamed_stats_with(&with_gaps, 3, &SLOPE_CLASSES_DEG, 50, reading).unwrap();
        assert_same(&b.stats, &a.stats, "gaps");
        assert_eq!(b.histogram.count, a.histogram.count);
        for (x, y) in b.by_slope.iter().zip(&a.by_slope) {
            assert_same(&x.stats, &y.stats, "gaps, a class");
        }
        // No histogram asked for: none made.
        assert!(held_stats(&with_gaps, 0, &[], 0).histogram.count.is_empty());
    }

    /// Records that can only be scanned, as a spill's are.
    struct Scanned(Vec<Record>);

    impl Records for Scanned {
        fn scan(&self, f: &mut dyn FnMut(&[Record])) -> io::Result<()> {
            self.0.scan(f)
        }
    }
}
