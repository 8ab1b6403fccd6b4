//! A comparison cut into shards, as the import is: a plan that fixes everything deciding the
//! result, shards that each compute their part of the pending pass over their own quads, and a
//! merge that joins the parts in order and either finishes or names the next round.
//!
//! The plan (`PLAN.json`, written atomically, its `hash` the SHA-256 of itself with that field
//! empty) holds the project's path and SHA-256, each dataset store's size and modification time,
//! the operands, level, region, weighting and slope classes, and the quads of the level ordered
//! along a Hilbert curve per face and cut into N runs of equal size ±1. A round is one pass of the
//! statistics ([`Statistics`]); shard I's part of round R is `PARTS/round-R/shard-I.json`, written
//! atomically (complete or absent), holding the pass's result over that shard's quads with every
//! f64 as its bits. The merge and the shards replay the rounds already complete from their parts
//! (joined in shard order) to know the pending pass, so nothing else is kept between rounds.
//! One `compare` reads its quads in the same order (face by face along the curve), and the
//! statistics' quantile search sums its weights exactly, so the shards' parts joined in order
//! give the counts and quantiles of one `compare` bit for bit; the moments agree within rounding
//! (their sums are grouped by shard).

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::CompareError;
use super::sample::{
    CompareOptions, Comparison, Differenced, Weighting, difference_quads, hilbert_ordered, operand, operand_scene,
    overlap_quads,
};
use super::stats::SLOPE_CLASSES_DEG;
use super::streamed::{Gave, GaveFile, Statistics, Streamed};
use crate::ecm::grid::spacing_m;
use crate::ecm::{Face, QuadId};
use crate::geodesy::GeoBox;
use crate::plan::Stamp;
use crate::project::Project;
use crate::scene::Scene;

/// The plan's format name.
pub const PLAN_FORMAT: &str = "terrafuse-compare-plan";
/// A part's format name.
pub const PART_FORMAT: &str = "terrafuse-compare-part";
/// The version this build writes and reads.
pub const PLAN_VERSION: u32 = 1;
/// The most shards a plan may have.
pub const MAX_SHARDS: usize = 1 << 16;
/// Rounds at most (the statistics take eight to twelve passes).
const MAX_ROUNDS: u32 = 64;

/// A sharded comparison's plan.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ComparePlan {
    /// Always [`PLAN_FORMAT`].
    pub format: String,
    /// [`PLAN_VERSION`].
    pub version: u32,
    /// SHA-256 (hex) of the plan with this field empty: every part names it.
    pub hash: String,
    /// The project file, absolute.
    pub project: PathBuf,
    /// SHA-256 (hex) of the project file's bytes.
    pub project_sha256: String,
    /// The project's dataset stores.
    pub stores: Vec<Stamp>,
    /// Operand A, as the command line named it.
    pub a: String,
    /// Operand B, the reference.
    pub b: String,
    /// The level compared.
    pub level: u8,
    /// WEST, SOUTH, EAST, NORTH, degrees, if any.
    pub region: Option<[f64; 4]>,
    /// How samples are weighted.
    pub weighting: Weighting,
    /// Slope class edges, degrees.
    pub slope_classes_deg: Vec<f64>,
    /// Print the merged result as `compare --json` does.
    pub json: bool,
    /// The parts' folder, absolute.
    pub parts: PathBuf,
    /// Each shard's quads of `level`, as `[face, x, y]` (face in `Face::ALL` order), contiguous
    /// along the curve.
    pub shards: Vec<Vec<[u32; 3]>>,
    /// A quantile's last candidates are gathered once at most this many are left, over every
    /// shard (smaller parts, a round more; the same quantiles). Plans written before the field
    /// gather 2¹⁸, as one `compare` does.
    #[serde(default = "one_process_collect", skip_serializing_if = "is_one_process_collect")]
    pub collect: u64,
    /// The width of a quantile search's digits after the first, bits (8: at most 256 buckets a
    /// search in a part; 16 before the field, as one `compare`).
    #[serde(default = "one_process_refine_bits", skip_serializing_if = "is_one_process_refine_bits")]
    pub refine_bits: u32,
}

/// What a plan's shards gather at most per quantile: with about 30 searches (seven populations'
/// quantiles and deviations), at most ≈ 4.6 MB of candidates in a part, whatever its samples.
pub const PLAN_COLLECT: u64 = 2048;
/// A plan's digits after the first: 8 bits, at most 256 buckets a search (≈ 0.8 MB a part for
/// 30 searches), where 16 bits gave parts of 40–84 MB (BENCHMARKS.md).
pub const PLAN_REFINE_BITS: u32 = 8;

fn one_process_refine_bits() -> u32 {
    super::streamed::Gathering::default().refine_bits
}

// Left out of the JSON (and so of the hash) where a plan written before the fields had them.
fn is_one_process_collect(collect: &u64) -> bool {
    *collect == one_process_collect()
}

fn is_one_process_refine_bits(bits: &u32) -> bool {
    *bits == one_process_refine_bits()
}

fn one_process_collect() -> u64 {
    super::streamed::COLLECT
}

/// One shard's part of one round.
#[derive(Clone, Debug, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
struct Part {
    format: String,
    plan: String,
    round: u32,
    shard: usize,
    /// Samples with data on one side only.
    nodata: u64,
    /// The least and the largest cell area compared (bits).
    area: [u64; 2],
    gave: GaveFile,
}

/// What a merge found.
pub enum Merged {
    /// The comparison, as `compare` gives it.
    Done(Box<Comparison>),
    /// Round `round` lacks these shards' parts.
    Pending {
        /// The round.
        round: u32,
        /// The shards to run.
        shards: Vec<usize>,
    },
}

/// What a shard did.
pub enum Sharded {
    /// Wrote its part of this round.
    Wrote(u32),
    /// Its part of this round was there already (the round waits for other shards').
    Already(u32),
    /// The comparison is complete: nothing to do.
    Complete,
}

fn file_error(path: &Path, problem: impl std::fmt::Display) -> CompareError {
    CompareError::File { path: path.to_path_buf(), problem: problem.to_string() }
}

impl crate::plan::Plan for ComparePlan {
    const FORMAT: &'static str = PLAN_FORMAT;
    const VERSION: u32 = PLAN_VERSION;
    const WHAT: &'static str = "a comparison plan";
    fn header(&self) -> (&str, u32, &str) {
        (&self.format, self.version, &self.hash)
    }
    fn hash_mut(&mut self) -> &mut String {
        &mut self.hash
    }
}

impl ComparePlan {
    fn digest(&self) -> String {
        crate::plan::digest(self)
    }

    /// Reads a plan and checks its format, version and hash.
    pub fn load(path: &Path) -> Result<ComparePlan, CompareError> {
        let plan: ComparePlan = crate::plan::load(path)?;
        if !(1..=16).contains(&plan.refine_bits) || plan.collect == 0 {
            return Err(file_error(
                path,
                format!("refine_bits {} and collect {}: give 1–16 and at least 1", plan.refine_bits, plan.collect),
            ));
        }
        Ok(plan)
    }

    /// Refuses a project or store that changed since the plan, naming it.
    fn check_inputs(&self) -> Result<Project, CompareError> {
        Ok(crate::plan::check_inputs(&self.project, &self.project_sha256, &self.stores)?)
    }

    fn options(&self) -> Result<CompareOptions, CompareError> {
        let region = match self.region {
            None => None,
            Some([w, s, e, n]) => Some(
                GeoBox::new(w, s, e, n)
                    .map_err(|e| CompareError::Option { option: "--region".into(), problem: e.to_string() })?,
            ),
        };
        Ok(CompareOptions {
            level: Some(self.level),
            region,
            weighting: self.weighting,
            slope_classes_deg: self.slope_classes_deg.clone(),
            ..CompareOptions::default()
        })
    }

    /// How the plan's quantile searches narrow.
    fn gathering(&self) -> super::streamed::Gathering {
        super::streamed::Gathering { collect: self.collect, refine_bits: self.refine_bits }
    }

    fn part_path(&self, round: u32, shard: usize) -> PathBuf {
        self.parts.join(format!("round-{round:03}")).join(format!("shard-{shard:06}.json"))
    }

    /// Shard `shard`'s part of `round`, if written; Err for one that is not this plan's.
    fn part(&self, round: u32, shard: usize) -> Result<Option<Part>, CompareError> {
        let path = self.part_path(round, shard);
        let text = match std::fs::read_to_string(&path) {
            Ok(t) => t,
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => return Ok(None),
            Err(e) => return Err(file_error(&path, format!("cannot read the part: {e}"))),
        };
        let part: Part = serde_json::from_str(&text).map_err(|e| file_error(&path, format!("not a part: {e}")))?;
        if part.format != PART_FORMAT || part.plan != self.hash || part.round != round || part.shard != shard {
            return Err(file_error(
                &path,
                format!(
                    "a part of another plan or place (plan {}, round {}, shard {})",
                    part.plan, part.round, part.shard
                ),
            ));
        }
        Ok(Some(part))
    }

    /// The statistics with every complete round taken, the round pending (None once done), the
    /// shards missing from it, and the samples' counts from round 0.
    fn replay(&self) -> Result<Standing, CompareError> {
        let mut statistics =
            Statistics::reading(&self.slope_classes_deg, super::stats::HISTOGRAM_BINS, self.gathering());
        let mut replayed = Replayed { nodata: 0, area: (f64::INFINITY, 0.0), round: 0, missing: Vec::new() };
        while let Some(pass) = statistics.pass() {
            if replayed.round >= MAX_ROUNDS {
                return Err(file_error(
                    &self.parts,
                    format!("more than {MAX_ROUNDS} rounds: the parts are not this plan's"),
                ));
            }
            let mut joined: Option<Gave> = None;
            for shard in 0..self.shards.len() {
                let Some(part) = self.part(replayed.round, shard)? else {
                    replayed.missing.push(shard);
                    continue;
                };
                let path = self.part_path(replayed.round, shard);
                let gave = Gave::from_file(&part.gave, &pass).map_err(|e| file_error(&path, e))?;
                if replayed.round == 0 {
                    replayed.nodata += part.nodata;
                    replayed.area = (
                        replayed.area.0.min(f64::from_bits(part.area[0])),
                        replayed.area.1.max(f64::from_bits(part.area[1])),
                    );
                }
                match joined.as_mut() {
                    None => joined = Some(gave),
                    Some(j) => j.join(gave),
                }
            }
            if !replayed.missing.is_empty() {
                return Ok(Standing { statistics, pass: Some(pass), replayed });
            }
            if let Some(gave) = joined {
                statistics.take(gave);
            }
            replayed.round += 1;
        }
        Ok(Standing { statistics, pass: None, replayed })
    }
}

/// Where the rounds stand.
struct Replayed {
    nodata: u64,
    area: (f64, f64),
    round: u32,
    missing: Vec<usize>,
}

/// The statistics after the complete rounds, and the pending pass.
struct Standing {
    statistics: Statistics,
    pass: Option<super::streamed::Pass>,
    replayed: Replayed,
}

/// Plans a comparison of `a` with `b` of the project at `project_path` in `shards` shards:
/// checks everything as `compare` would, writes the plan to `plan_path` atomically (its parts to
/// go to `parts`, default `PLAN.parts` beside it) and computes nothing else.
pub fn plan(
    project_path: &Path,
    [a, b]: [&str; 2],
    opts: &CompareOptions,
    json: bool,
    shards: usize,
    plan_path: &Path,
    parts: Option<&Path>,
) -> Result<ComparePlan, CompareError> {
    if !(1..=MAX_SHARDS).contains(&shards) {
        return Err(CompareError::Option {
            option: "--shards".into(),
            problem: format!("{shards}: give 1 … {MAX_SHARDS}"),
        });
    }
    let absolute = |p: &Path| std::path::absolute(p).map_err(|e| file_error(p, e));
    let project_path = absolute(project_path)?;
    let project = Project::load(&project_path).map_err(|e| file_error(&project_path, e))?;
    let (oa, ob) = (operand(&project, a), operand(&project, b));
    if oa == ob {
        return Err(CompareError::Option { option: "B".into(), problem: format!("'{oa}' compared with itself") });
    }
    let (scene, _) = Scene::open(&project)?;
    let (scene_a, scene_b) = (operand_scene(&scene, &project, &oa)?, operand_scene(&scene, &project, &ob)?);
    let (level, quads) = overlap_quads(&scene_a, &scene_b, opts.level, opts.region)?;
    let quads = hilbert_ordered(level, quads);
    if quads.len() < shards {
        return Err(CompareError::Option {
            option: "--shards".into(),
            problem: format!(
                "{shards} shards for {} quads at level {level}: give at most {}",
                quads.len(),
                quads.len()
            ),
        });
    }
    // Already along the curve, face by face: the order one `compare` reads them in.
    let ordered: Vec<[u32; 3]> = quads.iter().map(|q| [q.face as u32, q.x, q.y]).collect();
    let cut = crate::plan::runs(ordered.len(), shards).into_iter().map(|(a, b)| ordered[a..b].to_vec()).collect();
    let plan_path = absolute(plan_path)?;
    let parts = match parts {
        Some(p) => absolute(p)?,
        None => plan_path.with_extension("parts"),
    };
    let (project_sha256, stores) = crate::plan::inputs(&project_path, &project)?;
    let mut plan = ComparePlan {
        format: PLAN_FORMAT.into(),
        version: PLAN_VERSION,
        hash: String::new(),
        project: project_path,
        project_sha256,
        stores,
        a: a.into(),
        b: b.into(),
        level,
        region: opts.region.map(|r| [r.west_deg, r.south_deg, r.east_deg, r.north_deg]),
        weighting: opts.weighting,
        slope_classes_deg: if opts.slope_classes_deg.is_empty() {
            SLOPE_CLASSES_DEG.to_vec()
        } else {
            opts.slope_classes_deg.clone()
        },
        json,
        parts,
        shards: cut,
        collect: PLAN_COLLECT,
        refine_bits: PLAN_REFINE_BITS,
    };
    plan.hash = plan.digest();
    crate::plan::write(&plan_path, &plan.parts, &plan)?;
    Ok(plan)
}

/// Computes shard `shard`'s part of the plan's pending round (nothing where it is written
/// already or the comparison is complete), after checking that the project and its stores are
/// as planned; differences past what memory holds go to a scratch file in `scratch` (default:
/// the project's folder), counted and cancelled on `watch`.
pub fn shard(
    plan_path: &Path,
    shard: usize,
    scratch: Option<PathBuf>,
    watch: Option<std::sync::Arc<crate::progress::Watch>>,
) -> Result<Sharded, CompareError> {
    let plan = ComparePlan::load(plan_path)?;
    if shard >= plan.shards.len() {
        return Err(CompareError::Option {
            option: "SHARD".into(),
            problem: format!("{shard}: the plan has shards 0 … {}", plan.shards.len() - 1),
        });
    }
    let project = plan.check_inputs()?;
    let standing = plan.replay()?;
    let Some(pass) = standing.pass else {
        return Ok(Sharded::Complete);
    };
    let round = standing.replayed.round;
    if !standing.replayed.missing.contains(&shard) {
        return Ok(Sharded::Already(round));
    }
    let opts = CompareOptions { watch, scratch, ..plan.options()? };
    let (scene, _) = Scene::open(&project)?;
    let (oa, ob) = (operand(&project, &plan.a), operand(&project, &plan.b));
    let (scene_a, scene_b) = (operand_scene(&scene, &project, &oa)?, operand_scene(&scene, &project, &ob)?);
    let quads: Vec<QuadId> = plan.shards[shard]
        .iter()
        .map(|&[f, x, y]| QuadId { face: Face::ALL[f as usize % 6], level: plan.level, x, y })
        .collect();
    let Differenced { diffs, nodata, area, .. } = difference_quads(&project, &scene_a, &scene_b, &quads, &opts)?;
    let records = diffs.into_records()?;
    let gave = standing.statistics.run(&*records, &pass).map_err(|e| file_error(&plan.parts, e))?;
    let part = Part {
        format: PART_FORMAT.into(),
        plan: plan.hash.clone(),
        round,
        shard,
        nodata,
        area: [area.0.to_bits(), area.1.to_bits()],
        gave: gave.to_file(),
    };
    let path = plan.part_path(round, shard);
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| file_error(dir, format!("cannot create: {e}")))?;
    }
    let text = serde_json::to_string(&part).map_err(|e| file_error(&path, e))?;
    crate::files::write_atomic(&path, text.as_bytes()).map_err(|e| file_error(&path, format!("cannot write: {e}")))?;
    Ok(Sharded::Wrote(round))
}

/// Joins the plan's parts: the comparison where every round is complete, else the round and
/// shards still to run. Every part is checked before anything is reported.
pub fn merge(plan_path: &Path) -> Result<Merged, CompareError> {
    let plan = ComparePlan::load(plan_path)?;
    let project = plan.check_inputs()?;
    let standing = plan.replay()?;
    if standing.pass.is_some() {
        return Ok(Merged::Pending { round: standing.replayed.round, shards: standing.replayed.missing });
    }
    let Replayed { nodata, area: (area_lo, area_hi), .. } = standing.replayed;
    let Some(Streamed { stats, histogram, by_slope }) = standing.statistics.finish(nodata) else {
        return Err(file_error(&plan.parts, "the statistics stopped before their last round"));
    };
    let (oa, ob) = (operand(&project, &plan.a), operand(&project, &plan.b));
    if let Some([w, s, e, n]) = plan.region
        && stats.count == 0
    {
        return Err(CompareError::Option {
            option: "--region".into(),
            problem: format!(
                "{w},{s},{e},{n}: no sample inside has data in both {oa} and {ob} (the order is WEST,SOUTH,EAST,NORTH)"
            ),
        });
    }
    let ellipsoid = project.ellipsoid()?;
    Ok(Merged::Done(Box::new(Comparison {
        a: oa.label(),
        b: ob.label(),
        level: plan.level,
        spacing_m: spacing_m(&ellipsoid, plan.level),
        weighting: plan.weighting,
        area_km2: if plan.weighting == Weighting::Samples { f64::NAN } else { stats.weight_sum / 1e6 },
        weight_ratio: if stats.count == 0 { f64::NAN } else { area_hi / area_lo },
        stats,
        histogram,
        by_slope,
        samples: Vec::new(),
    })))
}
