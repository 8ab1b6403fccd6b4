//! `terrafuse shard`, `terrafuse merge` and `terrafuse shards run`: the shards of a comparison
//! planned with `compare … --plan PLAN --shards N` (`compare::sharded`), run one at a time by a
//! scheduler's array task, or all on this machine.

use std::path::Path;
use std::process::Command;

use super::console::Console;
use super::error::Context;
use super::{CliError, Within};
use crate::compare::sharded::{self, Merged, Sharded};

/// The exit status of a merge that waits for shards.
pub const PENDING: u8 = 3;

/// Computes shard `shard` (a number, or `env`) of the plan's pending round.
pub fn shard_command(plan: &Path, shard: &str, c: &mut Console) -> Result<u8, CliError> {
    let index = super::shard::shard_index(shard, c.var)?;
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
pub fn merge_command(plan: &Path, c: &mut Console) -> Result<u8, CliError> {
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
pub fn shards_run(plan: &Path, jobs: usize, c: &mut Console) -> Result<u8, CliError> {
    if jobs == 0 {
        return Err("--jobs 0: give at least 1".into());
    }
    let exe = std::env::current_exe().context("this program's path")?;
    loop {
        let pending = match sharded::merge(plan).within(plan.display())? {
            Merged::Done(_) => return merge_command(plan, c),
            Merged::Pending { round, shards } => (round, shards),
        };
        let (round, shards) = pending;
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
