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

use serde::{Deserialize, Serialize};

use super::spill::{NO_CLASS, Record, Records};
use super::stats::{Histogram, NMAD_FACTOR, SlopeClass, Stats};
use crate::maths::CompensatedSum;

mod search;

pub(crate) use search::COLLECT;
pub use search::Gathering;
use search::{Gathered, GatheredFile, Job, PART, Quantiles, Reading, Search, gather};

/// Sums over one population, compensated (as `stats` sums them): parts joined give the sums
/// made in order to within an ulp or two.
#[derive(Clone, Copy, Debug)]
pub struct Moments {
    count: u64,
    w: CompensatedSum,
    wx: CompensatedSum,
    wxx: CompensatedSum,
    lo: f64,
    hi: f64,
}

impl Default for Moments {
    fn default() -> Moments {
        let zero = CompensatedSum::default();
        Moments { count: 0, w: zero, wx: zero, wxx: zero, lo: f64::INFINITY, hi: f64::NEG_INFINITY }
    }
}

impl Moments {
    fn add(&mut self, r: &Record) {
        self.count += 1;
        self.w.add(r.weight);
        self.wx.add(r.weight * r.dh_m);
        self.wxx.add(r.weight * r.dh_m * r.dh_m);
        self.lo = self.lo.min(r.dh_m);
        self.hi = self.hi.max(r.dh_m);
    }

    /// The sums of the records after these, added.
    fn join(&mut self, next: &Moments) {
        self.count += next.count;
        self.w.join(next.w);
        self.wx.join(next.wx);
        self.wxx.join(next.wxx);
        self.lo = self.lo.min(next.lo);
        self.hi = self.hi.max(next.hi);
    }

    fn mean(&self) -> f64 {
        self.wx.value() / self.w.value()
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

/// What one pass over the differences computes.
pub struct Pass {
    /// Each population's sums (the first pass).
    moments: bool,
    /// Each population's spread about these means, and the histogram (the pass after the
    /// quantiles).
    spread: Option<(Vec<f64>, Option<Histogram>)>,
    /// The searches' candidates (of these jobs).
    jobs: Vec<Job>,
    searches: Vec<Search>,
}

/// What a pass gave over some consecutive records; [`Gave::join`] puts the next records' after.
pub struct Gave {
    moments: Vec<Moments>,
    spread: Vec<CompensatedSum>,
    histogram: Option<Histogram>,
    gathered: Vec<Gathered>,
}

impl Gave {
    /// What the pass gave over the records after these, put after it.
    pub fn join(&mut self, next: Gave) {
        self.moments.iter_mut().zip(&next.moments).for_each(|(m, n)| m.join(n));
        self.spread.iter_mut().zip(&next.spread).for_each(|(s, n)| s.join(*n));
        if let (Some(h), Some(n)) = (self.histogram.as_mut(), next.histogram.as_ref()) {
            h.join(n);
        }
        self.gathered.iter_mut().zip(next.gathered).for_each(|(g, n)| g.join(n));
    }

    /// As a part file holds it: every f64 as its bits, nothing rounded.
    pub fn to_file(&self) -> GaveFile {
        let bits = |m: &Moments| {
            let [w, wx, wxx] = [m.w, m.wx, m.wxx].map(CompensatedSum::parts);
            (m.count, [w[0], w[1], wx[0], wx[1], wxx[0], wxx[1], m.lo, m.hi].map(f64::to_bits))
        };
        GaveFile {
            moments: self.moments.iter().map(bits).collect(),
            spread: self.spread.iter().map(|s| s.parts().map(f64::to_bits)).collect(),
            histogram: self
                .histogram
                .as_ref()
                .map(|h| (h.count.clone(), h.weight.iter().map(|w| w.to_bits()).collect())),
            gathered: self.gathered.iter().map(Gathered::to_file).collect(),
        }
    }

    /// What `pass` gave, from a part file; Err names what does not fit the pass.
    pub fn from_file(file: &GaveFile, pass: &Pass) -> Result<Gave, BadPart> {
        if file.moments.len() != file.spread.len() || file.gathered.len() != pass.searches.len() {
            return Err(BadPart(format!(
                "{} populations' sums, {} spreads and {} searches, for a pass of {} searches",
                file.moments.len(),
                file.spread.len(),
                file.gathered.len(),
                pass.searches.len()
            )));
        }
        let moments = file
            .moments
            .iter()
            .map(|&(count, [w0, w1, wx0, wx1, wxx0, wxx1, lo, hi])| {
                let f = f64::from_bits;
                let sum = |hi, lo| CompensatedSum::from_parts([f(hi), f(lo)]);
                Moments { count, w: sum(w0, w1), wx: sum(wx0, wx1), wxx: sum(wxx0, wxx1), lo: f(lo), hi: f(hi) }
            })
            .collect();
        let histogram = match (pass.spread.as_ref().and_then(|(_, h)| h.clone()), &file.histogram) {
            (None, None) => None,
            (Some(mut h), Some((count, weight))) if count.len() == h.count.len() && weight.len() == h.count.len() => {
                h.count.clone_from(count);
                h.weight = weight.iter().map(|&w| f64::from_bits(w)).collect();
                Some(h)
            }
            _ => return Err(BadPart("a histogram that is not the pass's".into())),
        };
        Ok(Gave {
            moments,
            spread: file.spread.iter().map(|s| CompensatedSum::from_parts(s.map(f64::from_bits))).collect(),
            histogram,
            gathered: file.gathered.iter().map(Gathered::from_file).collect::<Result<_, _>>()?,
        })
    }
}

/// A part file's result that does not fit its pass: what is wrong.
#[derive(Debug, thiserror::Error)]
#[error("{0}")]
pub struct BadPart(pub String);

/// What a pass gave, as a part file holds it (f64 as bits).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GaveFile {
    /// Each population's count, compensated sums (w, wx, wxx as their two parts), least and
    /// largest.
    moments: Vec<(u64, [u64; 8])>,
    /// Each population's spread about its mean (its two parts).
    spread: Vec<[u64; 2]>,
    /// The histogram's counts and weights.
    histogram: Option<(Vec<u64>, Vec<u64>)>,
    /// Each search's candidates.
    gathered: Vec<GatheredFile>,
}

/// The populations: 0 every difference, 1 + k slope class k.
#[derive(Clone, Copy, Debug)]
struct Populations {
    classes: usize,
}

impl Populations {
    fn new(bounds_deg: &[f64]) -> Populations {
        Populations { classes: bounds_deg.len().saturating_sub(1).min(usize::from(NO_CLASS)) }
    }

    fn len(self) -> usize {
        1 + self.classes
    }

    /// Each population's slope class (None: every difference).
    fn classes(self) -> impl Iterator<Item = Option<u8>> {
        std::iter::once(None).chain((0..self.classes).map(|k| Some(k as u8)))
    }

    /// The class population a record belongs to, if any.
    fn member(self, r: &Record) -> Option<usize> {
        (r.class != NO_CLASS && usize::from(r.class) < self.classes).then(|| 1 + usize::from(r.class))
    }
}

/// Where the statistics stand between passes.
enum Stage {
    Moments,
    Values(Quantiles),
    Spread(Vec<Vec<f64>>),
    Deviations(Vec<Vec<f64>>, Quantiles),
    Done(Vec<Vec<f64>>, Vec<Vec<f64>>),
}

/// The statistics of differences found pass by pass: ask for the next [`Pass`], run it over the
/// records (all of them, or each part and [`Gave::join`] them in order), [`Statistics::take`] what
/// it gave; once no pass is left, [`Statistics::finish`].
pub struct Statistics {
    populations: Populations,
    bounds_deg: Vec<f64>,
    bins: usize,
    gathering: Gathering,
    moments: Vec<Moments>,
    spread: Vec<CompensatedSum>,
    histogram: Option<Histogram>,
    stage: Stage,
}

impl Statistics {
    /// The statistics of differences in the slope classes `bounds_deg`, with a histogram of
    /// `bins` bins (0: none).
    pub fn new(bounds_deg: &[f64], bins: usize) -> Statistics {
        Statistics::reading(bounds_deg, bins, Gathering::default())
    }

    /// [`Statistics::new`], the quantiles' searches narrowing as `gathering` says (a sharded
    /// comparison's plan: smaller parts, more passes; the same quantiles).
    pub fn reading(bounds_deg: &[f64], bins: usize, gathering: Gathering) -> Statistics {
        let populations = Populations::new(bounds_deg);
        Statistics {
            populations,
            bounds_deg: bounds_deg.to_vec(),
            bins,
            gathering,
            moments: vec![Moments::default(); populations.len()],
            spread: vec![CompensatedSum::default(); populations.len()],
            histogram: None,
            stage: Stage::Moments,
        }
    }

    /// Runs `pass` over `records` (all of them, or a part whose result is joined with the
    /// others' in order).
    pub fn run(&self, records: &dyn Records, pass: &Pass) -> io::Result<Gave> {
        run_pass(records, pass, self.populations, Reading { collect: self.gathering.collect, part: PART })
    }

    /// The next pass, None once the statistics are found.
    pub fn pass(&self) -> Option<Pass> {
        let searching = |q: &Quantiles| Pass {
            moments: false,
            spread: None,
            jobs: q.jobs.clone(),
            searches: q.searches().to_vec(),
        };
        match &self.stage {
            Stage::Moments => Some(Pass { moments: true, spread: None, jobs: Vec::new(), searches: Vec::new() }),
            Stage::Values(q) | Stage::Deviations(_, q) => Some(searching(q)),
            Stage::Spread(values) => {
                let means = self.moments.iter().map(Moments::mean).collect();
                let histogram = (self.moments[0].count > 0 && self.bins > 0)
                    .then(|| Histogram::over(values[0][3], values[0][4], self.bins));
                Some(Pass { moments: false, spread: Some((means, histogram)), jobs: Vec::new(), searches: Vec::new() })
            }
            Stage::Done(..) => None,
        }
    }

    /// Takes what the current pass gave over every record.
    pub fn take(&mut self, gave: Gave) {
        let stage = std::mem::replace(&mut self.stage, Stage::Moments);
        self.stage = match stage {
            Stage::Moments => {
                self.moments = gave.moments;
                Stage::Values(Quantiles::new(self.value_jobs(), self.moments[0].count, self.gathering)).settled()
            }
            Stage::Values(mut q) => {
                q.take(gave.gathered);
                Stage::Values(q).settled()
            }
            Stage::Spread(values) => {
                (self.spread, self.histogram) = (gave.spread, gave.histogram);
                // The median absolute deviations: distances from each population's median.
                let jobs = self
                    .populations
                    .classes()
                    .enumerate()
                    .map(|(p, class)| Job { class, centre: Some(values[2 * p][0]), quantiles: vec![0.5] })
                    .collect();
                Stage::Deviations(values, Quantiles::new(jobs, self.moments[0].count, self.gathering)).settled()
            }
            Stage::Deviations(values, mut q) => {
                q.take(gave.gathered);
                Stage::Deviations(values, q).settled()
            }
            done @ Stage::Done(..) => done,
        };
    }

    /// Each population's median, 5th and 95th percentiles (and the histogram's 0.5th and 99.5th
    /// for them all), then the 90th percentile of |dh|.
    fn value_jobs(&self) -> Vec<Job> {
        let mut jobs = Vec::new();
        for (p, class) in self.populations.classes().enumerate() {
            let mut quantiles = vec![0.5, 0.05, 0.95];
            if p == 0 && self.bins > 0 {
                quantiles.extend([0.005, 0.995]);
            }
            jobs.push(Job { class, centre: None, quantiles });
            jobs.push(Job { class, centre: Some(0.0), quantiles: vec![0.9] });
        }
        jobs
    }

    /// The statistics found (`nodata_count` recorded as given); None while a pass is left.
    pub fn finish(self, nodata_count: u64) -> Option<Streamed> {
        let Stage::Done(values, deviations) = self.stage else {
            return None;
        };
        let of = |p: usize| (&values[2 * p], values[2 * p + 1][0]);
        let stats_of = |p: usize, nodata_count: u64| {
            let m = &self.moments[p];
            if m.count == 0 {
                return Stats::empty(nodata_count);
            }
            let (q, p90_abs) = of(p);
            Stats {
                count: m.count,
                nodata_count,
                weight_sum: m.w.value(),
                mean_m: m.mean(),
                median_m: q[0],
                std_m: (self.spread[p].value() / m.w.value()).sqrt(),
                rmse_m: (m.wxx.value() / m.w.value()).sqrt(),
                nmad_m: NMAD_FACTOR * deviations[p][0],
                min_m: m.lo,
                max_m: m.hi,
                le90_m: q[2] - q[1],
                p90_abs_m: p90_abs,
            }
        };
        let by_slope = self
            .bounds_deg
            .windows(2)
            .take(self.populations.classes)
            .enumerate()
            .map(|(k, b)| SlopeClass { min_deg: b[0], max_deg: b[1], stats: stats_of(1 + k, 0) })
            .collect();
        Some(Streamed { stats: stats_of(0, nodata_count), histogram: self.histogram.unwrap_or_default(), by_slope })
    }
}

impl Stage {
    /// The stage after this one where its searches are all settled (no pass needed).
    fn settled(self) -> Stage {
        match self {
            Stage::Values(q) if q.searches().is_empty() => Stage::Spread(q.answers().to_vec()),
            Stage::Deviations(values, q) if q.searches().is_empty() => Stage::Done(values, q.answers().to_vec()),
            other => other,
        }
    }
}

/// Runs one pass over `records` (read as `reading` says).
fn run_pass(records: &dyn Records, pass: &Pass, populations: Populations, reading: Reading) -> io::Result<Gave> {
    let mut gave = Gave {
        moments: vec![Moments::default(); populations.len()],
        spread: vec![CompensatedSum::default(); populations.len()],
        histogram: pass.spread.as_ref().and_then(|(_, h)| h.clone()),
        gathered: Vec::new(),
    };
    if pass.moments || pass.spread.is_some() {
        let means = pass.spread.as_ref().map(|(m, _)| m.as_slice()).unwrap_or_default();
        records.scan(&mut |block| {
            for r in block.iter().filter(|r| !r.dh_m.is_nan()) {
                let member = populations.member(r);
                if pass.moments {
                    gave.moments[0].add(r);
                    if let Some(p) = member {
                        gave.moments[p].add(r);
                    }
                }
                if !means.is_empty() {
                    gave.spread[0].add(r.weight * (r.dh_m - means[0]).powi(2));
                    if let Some(p) = member {
                        gave.spread[p].add(r.weight * (r.dh_m - means[p]).powi(2));
                    }
                    if let Some(h) = gave.histogram.as_mut() {
                        h.add(r.dh_m, r.weight);
                    }
                }
            }
        })?;
    }
    if !pass.searches.is_empty() {
        gave.gathered = gather(records, &pass.jobs, &pass.searches, reading)?;
    }
    Ok(gave)
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
    let gathering = Gathering { collect: reading.collect, ..Gathering::default() };
    let mut statistics = Statistics::reading(bounds_deg, bins, gathering);
    while let Some(pass) = statistics.pass() {
        let gave = run_pass(records, &pass, statistics.populations, reading)?;
        statistics.take(gave);
    }
    statistics.finish(nodata_count).ok_or_else(|| io::Error::other("the statistics stopped before their last pass"))
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

    #[test]
    fn passes_run_over_parts_and_joined_in_order_find_one_scans_quantiles_bit_for_bit() {
        // 300 000 differences are more than a quantile reads at once: the radix search's path;
        // 5 000 with `collect` 5 narrow to single keys; 7 and 1 leave parts empty.
        for (n, collect) in [(300_000, COLLECT), (5000, 5), (5000, COLLECT), (7, COLLECT), (1, COLLECT)] {
            // Weights as cell areas are: full mantissas, so that their f64 sums depend on order.
            let mut all = records(&differences(n));
            for (k, r) in all.iter_mut().enumerate() {
                r.weight = 9.7e3 * (1.0 + f64::from(crate::maths::pcg(k as u32 ^ 0x5bd1)) / 7.3e9);
            }
            let reading = Reading { collect, part: PART };
            let one = streamed_stats_with(&Scanned(all.clone()), 3, &SLOPE_CLASSES_DEG, 50, reading).unwrap();
            // In parts, also narrowing by 8-bit digits after the first (as a sharded plan does):
            // the cumulative weights are exact, so the quantiles do not depend on the digits.
            for (shards, refine_bits) in [(1, 16), (3, 16), (7, 16), (3, 8), (7, 8)] {
                let size = all.len().div_ceil(shards).max(1);
                let parts: Vec<Scanned> =
                    (0..shards).map(|k| Scanned(all.iter().skip(k * size).take(size).copied().collect())).collect();
                let gathering = Gathering { collect, refine_bits };
                let mut statistics = Statistics::reading(&SLOPE_CLASSES_DEG, 50, gathering);
                let mut passes = 0;
                while let Some(pass) = statistics.pass() {
                    let mut gave: Option<Gave> = None;
                    for part in &parts {
                        let g = run_pass(part, &pass, statistics.populations, reading).unwrap();
                        match gave.as_mut() {
                            None => gave = Some(g),
                            Some(joined) => joined.join(g),
                        }
                    }
                    statistics.take(gave.unwrap());
                    passes += 1;
                }
                let sharded = statistics.finish(3).unwrap();
                let what =
                    format!("n {n}, collect {collect}, {refine_bits}-bit digits, {shards} parts, {passes} passes");
                let pairs = std::iter::once((&sharded.stats, &one.stats))
                    .chain(sharded.by_slope.iter().map(|c| &c.stats).zip(one.by_slope.iter().map(|c| &c.stats)));
                for (a, b) in pairs {
                    assert_eq!((a.count, a.nodata_count), (b.count, b.nodata_count), "{what}");
                    let quantiles =
                        |s: &Stats| [s.median_m, s.nmad_m, s.le90_m, s.p90_abs_m, s.min_m, s.max_m].map(f64::to_bits);
                    assert_eq!(quantiles(a), quantiles(b), "{what}");
                    for (x, y) in
                        [(a.weight_sum, b.weight_sum), (a.mean_m, b.mean_m), (a.std_m, b.std_m), (a.rmse_m, b.rmse_m)]
                    {
                        assert!((x - y).abs() <= 1e-12 * y.abs() || (x.is_nan() && y.is_nan()), "{what}: {x} {y}");
                    }
                }
                assert_eq!(sharded.histogram.count, one.histogram.count, "{what}");
                assert_eq!(sharded.histogram.edges_m, one.histogram.edges_m, "{what}");
            }
        }
    }

    /// Records that can only be scanned, as a spill's are.
    struct Scanned(Vec<Record>);

    impl Records for Scanned {
        fn scan(&self, f: &mut dyn FnMut(&[Record])) -> io::Result<()> {
            self.0.scan(f)
        }
    }
}
