//! `terrafuse shard`, `terrafuse merge` and `terrafuse shards run`: the shards of a comparison
//! or an export planned with `compare … --plan PLAN --shards N` (`compare::sharded`) or `export
//! … --plan PLAN --shards N` (`export::sharded`), run one at a time by a scheduler's array task,
//! or all on this machine. The plan's `format` says which command planned it.

use std::path::Path;
use std::process::Command;

use super::console::Console;
use super::error::Context;
use super::{CliError, Within};
use crate::compare::sharded::{self, Merged, Sharded};
use crate::export::sharded as export_sharded;
use crate::store::shard::{MANIFEST_FORMAT, Manifest, part_is_done};

/// An import plan's parts: `PLAN.parts` beside it.
pub fn import_parts(plan: &Path) -> std::path::PathBuf {
    plan.with_extension("parts")
}

/// An import plan's store: `store`, or the plan's name with `.gpkg`.
pub fn import_store(plan: &Path, store: Option<&Path>) -> std::path::PathBuf {
    store.map_or_else(|| plan.with_extension("gpkg"), Path::to_path_buf)
}

/// An import plan's shards without a complete part.
fn import_missing(plan: &Path) -> Result<Vec<usize>, CliError> {
    let m = Manifest::load(plan)?;
    let parts = import_parts(plan);
    Ok((0..m.shards.len()).filter(|&i| !part_is_done(&crate::slurm::part_path(&parts, i), &m, i)).collect())
}

/// The exit status of a merge that waits for shards.
pub const PENDING: u8 = 3;

/// Which command planned a plan.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Planned {
    /// `compare … --plan`.
    Compare,
    /// `export … --plan`.
    Export,
    /// `import … --plan` (the manifest).
    Import,
}

/// Reads the plan's `format`.
pub fn planned(plan: &Path) -> Result<Planned, CliError> {
    let format = crate::plan::format_of(plan)?;
    match format.as_str() {
        sharded::PLAN_FORMAT => Ok(Planned::Compare),
        export_sharded::PLAN_FORMAT => Ok(Planned::Export),
        MANIFEST_FORMAT => Ok(Planned::Import),
        other => Err(format!("{}: format {other}: not a plan of compare, export or import", plan.display()).into()),
    }
}

/// What a plan's maker prints after it: the commands that run it.
pub fn next_steps(plan: &Path, shards: usize) -> String {
    let p = plan.display();
    format!(
        "run each shard: terrafuse shard {p} I   (I = 0 … {}, or env in a job array)\n\
         then:           terrafuse merge {p}\n\
         or all here:    terrafuse shards run {p}   on Slurm: terrafuse slurm submit {p}\n",
        shards - 1
    )
}

/// The round a plan waits on and its shards still to run; None when every part is in (the
/// merge then finishes).
pub fn pending(plan: &Path) -> Result<Option<(u32, Vec<usize>)>, CliError> {
    Ok(match planned(plan)? {
        Planned::Compare => match sharded::merge(plan).within(plan.display())? {
            Merged::Done(_) => None,
            Merged::Pending { round, shards } => Some((round, shards)),
        },
        Planned::Export => {
            let loaded = export_sharded::ExportPlan::load(plan)?;
            let missing = export_sharded::missing(&loaded)?;
            (!missing.is_empty()).then_some((0, missing))
        }
        Planned::Import => {
            let missing = import_missing(plan)?;
            (!missing.is_empty()).then_some((0, missing))
        }
    })
}

/// Computes shard `shard` (a number, or `env`) of the plan's pending round.
pub fn shard_command(plan: &Path, shard: &str, c: &mut Console) -> Result<u8, CliError> {
    let index = super::shard::shard_index(shard, c.var)?;
    if planned(plan)? == Planned::Import {
        let part = crate::slurm::part_path(&import_parts(plan), index);
        std::fs::create_dir_all(import_parts(plan))
            .with_context(|| format!("{}: cannot make the folder", import_parts(plan).display()))?;
        let opts = crate::store::shard::ShardOptions {
            manifest: plan.to_path_buf(),
            shard: index,
            store: part.clone(),
            work_dir: None,
            threads: None,
            memory_budget: super::parse_bytes("2GiB")?,
            progress: false,
            watch: None,
        };
        let report = crate::store::shard::import_shard(&opts)?;
        return c.print(super::shard_summary(&part, index, &report)).map(|()| 0);
    }
    if planned(plan)? == Planned::Export {
        let outcome = super::feedback::watched(c, true, |fb| export_sharded::shard(plan, index, fb.watch))?;
        return c
            .print(match outcome {
                export_sharded::Sharded::Wrote => format!("shard {index}: wrote its rows\n"),
                export_sharded::Sharded::Already => format!("shard {index}: its rows are there already\n"),
            })
            .map(|()| 0);
    }
    let scratch = Some(std::env::temp_dir());
    let outcome = super::feedback::watched(c, true, |fb| sharded::shard(plan, index, scratch, Some(fb.watch.clone())))
        .within(plan.display())?;
    c.print(match outcome {
        Sharded::Wrote(round) => format!("shard {index}: wrote its part of round {round}\n"),
        Sharded::Already(round) => format!("shard {index}: its part of round {round} is there already\n"),
        Sharded::Complete => {
            format!("shard {index}: the comparison is complete; run terrafuse merge {}\n", plan.display())
        }
    })?;
    Ok(0)
}

/// Joins the parts: prints the comparison (exit 0), or names what to run (exit [`PENDING`]).
pub fn merge_command(plan: &Path, store: Option<&Path>, c: &mut Console) -> Result<u8, CliError> {
    if planned(plan)? == Planned::Import {
        let missing = import_missing(plan)?;
        if !missing.is_empty() {
            let listed: Vec<String> = missing.iter().map(ToString::to_string).collect();
            c.note(format!(
                "terrafuse: the import waits for shards {}: run terrafuse shard {} I for each, then merge again",
                listed.join(","),
                plan.display()
            ));
            return Ok(PENDING);
        }
        let m = Manifest::load(plan)?;
        let store = import_store(plan, store);
        let opts = crate::store::merge::MergeOptions {
            store: store.clone(),
            parts: (0..m.shards.len()).map(|i| crate::slurm::part_path(&import_parts(plan), i)).collect(),
            threads: None,
            progress: false,
            watch: None,
        };
        let report = crate::store::merge::merge(&opts)?;
        c.print(super::merge_summary(&store, &report))?;
        return Ok(if report.complete { 0 } else { PENDING });
    }
    if planned(plan)? == Planned::Export {
        let started = std::time::Instant::now();
        let merged = super::feedback::watched(c, true, |fb| export_sharded::merge(plan, fb.watch))?;
        return match merged {
            export_sharded::Merged::Done(report) => {
                let loaded = export_sharded::ExportPlan::load(plan)?;
                let attribute = loaded.attribute.and_then(|a| crate::attributes::Attribute::parse(&a));
                c.print(super::dispatch::export_line(&loaded.out, attribute, &report, started.elapsed()))?;
                Ok(0)
            }
            export_sharded::Merged::Pending(shards) => {
                let listed: Vec<String> = shards.iter().map(ToString::to_string).collect();
                c.note(format!(
                    "terrafuse: the export waits for shards {}: run terrafuse shard {} I for each, then merge again",
                    listed.join(","),
                    plan.display()
                ));
                Ok(PENDING)
            }
        };
    }
    let json = sharded::ComparePlan::load(plan)?.json;
    match sharded::merge(plan).within(plan.display())? {
        Merged::Done(comparison) => {
            if json {
                c.print(serde_json::to_string_pretty(&comparison)? + "\n")?;
            } else {
                c.print(super::compare::table(&comparison))?;
            }
            Ok(0)
        }
        Merged::Pending { round, shards } => {
            let listed: Vec<String> = shards.iter().map(ToString::to_string).collect();
            c.note(format!(
                "terrafuse: round {round} waits for shards {}: run terrafuse shard {} I for each, then merge again",
                listed.join(","),
                plan.display()
            ));
            Ok(PENDING)
        }
    }
}

/// Runs the pending shards as local processes, `jobs` at a time, round after round, then merges.
pub fn shards_run(plan: &Path, store: Option<&Path>, jobs: usize, c: &mut Console) -> Result<u8, CliError> {
    if jobs == 0 {
        return Err("--jobs 0: give at least 1".into());
    }
    let exe = std::env::current_exe().context("this program's path")?;
    loop {
        let Some((round, shards)) = pending(plan)? else {
            return merge_command(plan, store, c);
        };
        c.note(format!("terrafuse: round {round}: {} shards", shards.len()));
        for batch in shards.chunks(jobs) {
            let children: Vec<_> = batch
                .iter()
                .map(|i| {
                    Command::new(&exe)
                        .args(["shard", &plan.to_string_lossy(), &i.to_string()])
                        .stdout(std::process::Stdio::null())
                        .stderr(std::process::Stdio::piped())
                        .spawn()
                        .map(|child| (*i, child))
                })
                .collect::<Result<_, _>>()
                .context("cannot start a shard")?;
            for (i, child) in children {
                let out = child.wait_with_output().with_context(|| format!("shard {i} of round {round}"))?;
                if !out.status.success() {
                    return Err(format!(
                        "shard {i} of round {round} failed: {}",
                        String::from_utf8_lossy(&out.stderr).trim()
                    )
                    .into());
                }
            }
        }
    }
}
