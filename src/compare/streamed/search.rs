//! The quantile search of the streamed statistics: a job (a population of differences in one
//! order), its searches (each quantile's candidates narrowed digit by digit), the buckets a pass
//! counts them into and the candidates it reads, and the stage that runs a job's searches pass by
//! pass ([`Quantiles`]). A pass's candidates gathered over consecutive parts of the records join
//! in order to what one scan gives, bit for bit: the counts are integers, the weights exact sums
//! ([`ExactSum`]), the first candidate and the largest key order-free, the candidates read kept
//! in record order (equal places in the order the records came: one process and its shards
//! joined in order read them the same way).

use std::io;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::super::spill::{Record, Records};
use super::super::stats::{order_key, order_value};
use crate::maths::ExactSum;

/// Bits of the ordering key one pass tells apart.
const DIGIT_BITS: u32 = 16;
/// Most candidates of one quantile read into memory (24 bytes each).
pub(crate) const COLLECT: u64 = 1 << 18;
/// Most parts a pass reads held records in, and the fewest records in a part.
const PARTS: usize = 4;
pub(super) const PART: usize = 1 << 20;

/// Some quantiles of one population of differences in one order.
#[derive(Clone, Debug)]
pub(super) struct Job {
    /// The slope class it is restricted to (every difference with None).
    pub(super) class: Option<u8>,
    /// None: the values dh; Some(c): the distances |dh − c|, at equal distance those below c
    /// first, then by value (the order `folded` gives).
    pub(super) centre: Option<f64>,
    /// The quantiles asked for, in [0, 1].
    pub(super) quantiles: Vec<f64>,
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
pub(super) struct Bucket {
    count: u64,
    weight: ExactSum,
    max: u64,
    first: (Place, f64),
}

impl Default for Bucket {
    fn default() -> Bucket {
        Bucket { count: 0, weight: ExactSum::default(), max: 0, first: (Place { key: 0, above: false, value: 0 }, 0.0) }
    }
}

impl Bucket {
    fn add(&mut self, place: Place, weight: f64) {
        self.count += 1;
        self.weight.add(weight);
        self.max = self.max.max(place.key);
        if self.count == 1 || before((place, weight), self.first) {
            self.first = (place, weight);
        }
    }

    /// The candidates of the records after these, put after them.
    fn join(&mut self, next: &Bucket) {
        if next.count == 0 {
            return;
        }
        if self.count == 0 || before(next.first, self.first) {
            self.first = next.first;
        }
        self.count += next.count;
        self.weight.join(next.weight);
        self.max = self.max.max(next.max);
    }
}

/// Buckets in a page.
const PAGE: usize = 256;

/// The 2¹⁶ buckets of a digit, in pages made when first reached: a population's values gather in
/// few of them, so a pass makes (and clears) only those.
pub(super) struct Buckets {
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
/// `prefix`; `below` is the weight of every element before them in order (exact, cumulative, the
/// first element's included), `before` the value just before them; `goal` the cumulative weight
/// the quantile sits at.
#[derive(Clone, Debug)]
pub(super) struct Search {
    job: usize,
    quantile: usize,
    goal: f64,
    below: ExactSum,
    before: Option<f64>,
    depth: u32,
    prefix: u64,
    /// The width of the next digit, bits: [`DIGIT_BITS`] for the first, then the refinement's.
    bits: u32,
    /// Read the candidates rather than count them by their next digit.
    collect: bool,
}

impl Search {
    /// Every element of a job.
    fn whole(job: usize) -> Search {
        Search {
            job,
            quantile: 0,
            goal: 0.0,
            below: ExactSum::default(),
            before: None,
            depth: 0,
            prefix: 0,
            bits: DIGIT_BITS,
            collect: false,
        }
    }

    fn holds(&self, key: u64) -> bool {
        self.depth == 0 || key >> (64 - self.depth) == self.prefix
    }

    fn digit(&self, key: u64) -> usize {
        ((key >> (64 - self.depth - self.bits)) & ((1 << self.bits) - 1)) as usize
    }
}

/// One search's candidates after a pass: counted by digit, or read.
pub(super) struct Gathered {
    buckets: Buckets,
    candidates: Vec<(Place, f64)>,
}

/// How the passes read: at most `collect` candidates of a quantile read at once; held records
/// in parts of at least `part` records (at most [`PARTS`] of them, each with its own buckets), on
/// several threads. The same on any number of threads.
#[derive(Clone, Copy, Debug)]
pub(super) struct Reading {
    pub(super) collect: u64,
    pub(super) part: usize,
}

/// One pass over the records: every search's candidates. Records held in memory are read in
/// parts, each part's candidates gathered alone and the parts' put together in order: the same
/// candidates in the same order, and the same counts, as one scan gives (the buckets' weights
/// summed part by part).
pub(super) fn gather(
    records: &dyn Records,
    jobs: &[Job],
    searches: &[Search],
    reading: Reading,
) -> io::Result<Vec<Gathered>> {
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
    pub(super) fn join(&mut self, next: Gathered) {
        self.candidates.extend(next.candidates);
        self.buckets.join(next.buckets);
    }

    /// As a part file holds it: nothing rounded.
    pub(super) fn to_file(&self) -> GatheredFile {
        let element = |(p, w): (Place, f64)| (p.key, p.above, p.value, w.to_bits());
        GatheredFile {
            buckets: self
                .buckets
                .filled()
                .map(|(digit, b)| (digit as u32, b.count, b.weight.units().to_string(), b.max, element(b.first)))
                .collect(),
            candidates: self.candidates.iter().map(|&c| element(c)).collect(),
        }
    }

    /// From a part file; Err names what is wrong.
    pub(super) fn from_file(file: &GatheredFile) -> Result<Gathered, super::BadPart> {
        let element = |(key, above, value, w): (u64, bool, u64, u64)| (Place { key, above, value }, f64::from_bits(w));
        let mut g = Gathered::empty();
        for (digit, count, units, max, first) in &file.buckets {
            if *digit >= 1 << DIGIT_BITS || *count == 0 {
                return Err(super::BadPart(format!("bucket {digit} with {count} candidates")));
            }
            let units: i128 =
                units.parse().map_err(|_| super::BadPart(format!("bucket {digit}: weight '{units}' is not a sum")))?;
            *g.buckets.at(*digit as usize) =
                Bucket { count: *count, weight: ExactSum::from_units(units), max: *max, first: element(*first) };
        }
        g.candidates = file.candidates.iter().map(|&c| element(c)).collect();
        Ok(g)
    }
}

/// A search's candidates as a part file holds them: each bucket that has some (its digit, count,
/// weight in units of 2⁻⁶⁴ as text, largest key and first element), and the candidates read; an
/// element is (key, above the centre, value key, weight's bits).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GatheredFile {
    buckets: Vec<(u32, u64, String, u64, ElementFile)>,
    candidates: Vec<ElementFile>,
}

/// An element as a part file holds it: (key, above the centre, value key, weight's bits).
type ElementFile = (u64, bool, u64, u64);

/// Whether element `a` comes before `b`: by place (equal places keep the records' order).
fn before(a: (Place, f64), b: (Place, f64)) -> bool {
    a.0 < b.0
}

/// Candidates in order: by place, stably (equal places keep the records' order).
fn sort(candidates: &mut [(Place, f64)]) {
    candidates.sort_by_key(|c| c.0);
}

/// The quantile from its candidates read: sorted (stably) and walked from `below` as
/// [`weighted_quantile`](super::stats::weighted_quantile) walks the whole set.
fn walk(search: &Search, mut candidates: Vec<(Place, f64)>) -> f64 {
    sort(&mut candidates);
    walk_sorted(search, &candidates)
}

/// [`walk`] of candidates already sorted. The cumulative weight is summed exactly from `below`
/// on and rounded once where it is read, so it does not depend on how the search narrowed.
fn walk_sorted(search: &Search, candidates: &[(Place, f64)]) -> f64 {
    let (mut below, mut before) = (search.below.value(), search.before);
    let mut past = search.below;
    for &(place, weight) in candidates {
        let x = order_value(place.key);
        past.add(weight);
        let at = past.value();
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
fn narrow(search: Search, buckets: &Buckets, gathering: Gathering) -> Result<f64, Search> {
    let (mut below, mut before) = (search.below, search.before);
    for (digit, bucket) in buckets.filled() {
        let mut after = below;
        after.join(bucket.weight);
        if after.value() >= search.goal {
            let depth = search.depth + search.bits;
            let prefix = (search.prefix << search.bits) | digit as u64;
            let collect = bucket.count <= gathering.collect;
            let bits = gathering.refine_bits.min(64 - depth);
            let narrowed = Search { below, before, depth, prefix, bits, collect, ..search };
            if depth == 64 {
                // One key, one value: only the first candidate's weight can matter.
                return Ok(walk(&narrowed, vec![bucket.first]));
            }
            return Err(narrowed);
        }
        below = after;
        before = Some(order_value(bucket.max));
    }
    Ok(before.unwrap_or(f64::NAN))
}

/// Each job's quantiles (NaN for an empty population), found pass by pass: the first pass
/// counts every job's whole population (or, where `few`, reads it all), the next ones the
/// candidates of the quantiles not yet settled, until none is open.
pub(super) struct Quantiles {
    pub(super) jobs: Vec<Job>,
    answers: Vec<Vec<f64>>,
    /// The searches the next pass gathers for.
    open: Vec<Search>,
    started: bool,
    /// Every element is read in the first pass (there are at most `collect`).
    few: bool,
    gathering: Gathering,
}

/// How a quantile's search narrows: its candidates read once at most `collect` are left, else
/// counted by their next digit, [`DIGIT_BITS`] wide the first time and `refine_bits` (16 or 8,
/// dividing what is left of the 64) after it. Smaller values: fewer buckets and candidates in a
/// pass's result, more passes; the same quantiles.
#[derive(Clone, Copy, Debug)]
pub struct Gathering {
    /// Candidates read at once, at most.
    pub collect: u64,
    /// The width of a digit after the first, bits: 16 or 8.
    pub refine_bits: u32,
}

impl Default for Gathering {
    fn default() -> Gathering {
        Gathering { collect: COLLECT, refine_bits: DIGIT_BITS }
    }
}

impl Quantiles {
    /// The search for `jobs`' quantiles over `count` elements, at most `collect` candidates of a
    /// quantile read at once (all of them in the first pass where there are no more).
    pub(super) fn new(jobs: Vec<Job>, count: u64, gathering: Gathering) -> Quantiles {
        let few = count <= gathering.collect;
        let open = (0..jobs.len()).map(|j| Search { collect: few, ..Search::whole(j) }).collect();
        let answers = jobs.iter().map(|j| vec![f64::NAN; j.quantiles.len()]).collect();
        Quantiles { jobs, answers, open, started: false, few, gathering }
    }

    /// The searches the next pass gathers for; none once every quantile is found.
    pub(super) fn searches(&self) -> &[Search] {
        &self.open
    }

    /// Every job's quantiles, once [`Quantiles::searches`] is empty.
    pub(super) fn answers(&self) -> &[Vec<f64>] {
        &self.answers
    }

    /// Takes what a pass gathered for each open search (over every record, in order).
    pub(super) fn take(&mut self, gathered: Vec<Gathered>) {
        let open = std::mem::take(&mut self.open);
        if !self.started {
            self.started = true;
            self.take_tops(open, gathered);
            return;
        }
        for (search, g) in open.into_iter().zip(gathered) {
            let (j, q) = (search.job, search.quantile);
            let found = if search.collect {
                Ok(walk(&search, g.candidates))
            } else {
                narrow(search, &g.buckets, self.gathering)
            };
            match found {
                Ok(v) => self.answers[j][q] = v,
                Err(s) => self.open.push(s),
            }
        }
    }

    /// The first pass: each job's whole population, counted or read.
    fn take_tops(&mut self, whole: Vec<Search>, tops: Vec<Gathered>) {
        for (j, mut top) in tops.into_iter().enumerate() {
            sort(&mut top.candidates);
            let (count, first, total): (u64, _, f64) = if self.few {
                let mut total = ExactSum::default();
                top.candidates.iter().for_each(|c| total.add(c.1));
                (top.candidates.len() as u64, top.candidates.first().copied(), total.value())
            } else {
                let mut total = ExactSum::default();
                top.buckets.filled().for_each(|(_, b)| total.join(b.weight));
                (
                    top.buckets.filled().map(|(_, b)| b.count).sum(),
                    top.buckets.filled().next().map(|(_, b)| b.first),
                    total.value(),
                )
            };
            let Some(first) = first else {
                continue;
            };
            let (least, w0) = (order_value(first.0.key), first.1);
            for (q, &p) in self.jobs[j].quantiles.iter().enumerate() {
                // weighted_quantile's position p·(W − w₀) past the first element.
                let target = p.clamp(0.0, 1.0) * (total - w0);
                if count == 1 || target.is_nan() || target <= 0.0 {
                    self.answers[j][q] = least;
                    continue;
                }
                let search = Search { quantile: q, goal: w0 + target, ..whole[j].clone() };
                if self.few {
                    self.answers[j][q] = walk_sorted(&search, &top.candidates);
                    continue;
                }
                match narrow(search, &top.buckets, self.gathering) {
                    Ok(v) => self.answers[j][q] = v,
                    Err(s) => self.open.push(s),
                }
            }
        }
    }
}
