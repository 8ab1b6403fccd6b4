//! What the shard commands share about a plan (`terrafuse shard`, `merge`, `shards run`,
//! `slurm submit`, and the planning commands' last lines): which command planned it, the round
//! it waits on, where an import's parts and store go, and the commands that run it.

use std::path::Path;

use super::{CliError, Within};
use crate::compare::sharded::{self, Merged};
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
pub fn import_missing(plan: &Path) -> Result<Vec<usize>, CliError> {
    let m = Manifest::load(plan)?;
    let parts = import_parts(plan);
    Ok((0..m.shards.len()).filter(|&i| !part_is_done(&crate::slurm::part_path(&parts, i), &m, i)).collect())
}

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
