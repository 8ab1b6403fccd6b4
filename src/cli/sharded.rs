//! `terrafuse shard`, `terrafuse merge` and `terrafuse shards run`: the shards of a comparison
//! or an export planned with `compare … --plan PLAN --shards N` (`compare::sharded`) or `export
//! … --plan PLAN --shards N` (`export::sharded`), run one at a time by a scheduler's array task,
//! or all on this machine. The plan's `format` says which command planned it.

use std::path::Path;
use std::process::Command;

use super::console::Console;
use super::error::Context;
use super::plans::{Planned, import_missing, import_parts, import_store, pending, planned};
use super::{CliError, Within};
use crate::compare::sharded::{self, Merged, Sharded};
use crate::export::sharded as export_sharded;
use crate::store::shard::Manifest;

/// The exit status of a merge that waits for shards.
pub const PENDING: u8 = 3;

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
                c.print(super::report::export_line(&loaded.out, attribute, &report, started.elapsed()))?;
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
