//! A sharded import, comparison or export as Slurm batch scripts: a job array with one shard per
//! task and a merge job that runs after every task succeeded (`--dependency=afterok`). An
//! import's shard is built on the node's local disk and copied to shared storage when complete;
//! a comparison's merge that needs another round (exit 3) submits that round itself.
//!
//! The scripts only call `terrafuse`; the contract a task fulfils is "import shard I of the
//! manifest into `PARTS/part-I.gpkg`", with I from `SLURM_ARRAY_TASK_ID`. Any array scheduler
//! can run the same command with its own index (Kubernetes `JOB_COMPLETION_INDEX`, AWS Batch
//! `AWS_BATCH_JOB_ARRAY_INDEX`, GNU parallel's `{}`).

use std::path::{Path, PathBuf};

/// What the scripts run.
#[derive(Clone, Debug)]
pub struct SlurmJob {
    /// The `terrafuse` executable, as the compute nodes see it.
    pub terrafuse: PathBuf,
    /// The manifest (absolute).
    pub manifest: PathBuf,
    /// The folder of the partial stores, on shared storage (absolute).
    pub parts: PathBuf,
    /// The merged store (absolute).
    pub store: PathBuf,
    /// The plan's number of shards.
    pub shards: usize,
    /// The job name (`tf-` and the plan's short hash): how a resubmission finds the plan's jobs.
    pub name: String,
    /// CPUs per task (and the import's threads).
    pub threads: usize,
    /// Memory budget per task, as `--memory-budget` takes it.
    pub memory_budget: String,
    /// The node-local folder a task builds its shard in, a shell word expanded on the node.
    pub work_dir: String,
}

/// Quotes a word for a POSIX shell.
pub fn shell_quote(text: &str) -> String {
    format!("'{}'", text.replace('\'', r"'\''"))
}

fn q(path: &Path) -> String {
    shell_quote(&path.to_string_lossy())
}

/// The partial store of a shard.
pub fn part_path(parts: &Path, shard: usize) -> PathBuf {
    parts.join(format!("part-{shard:04}.gpkg"))
}

impl SlurmJob {
    /// The folder of the scripts and logs.
    pub fn slurm_dir(&self) -> PathBuf {
        self.parts.join("slurm")
    }

    /// The job array's script: one shard per task.
    pub fn shard_script(&self) -> String {
        format!(
            "#!/bin/bash
# A shard of terrafuse plan {name}: written by `terrafuse slurm submit`; submit with
# sbatch --array=0-{last} {script}
#SBATCH --job-name={name}
#SBATCH --cpus-per-task={threads}
#SBATCH --output={log}
#SBATCH --open-mode=append
set -euo pipefail
shard=${{SLURM_ARRAY_TASK_ID:?not a job array task}}
part={parts}/part-$(printf %04d \"$shard\").gpkg
# Built on node-local disk (SQLite on a network file system is unsafe), copied to shared
# storage and renamed into place when complete; a rerun resumes from the local journal.
exec {exe} import --manifest {manifest} --shard \"$shard\" --store \"$part\" \\
  --work-dir \"{work}/terrafuse-{name}\" --threads {threads} --memory-budget {budget} --quiet
",
            name = self.name,
            last = self.shards.saturating_sub(1),
            script = q(&self.slurm_dir().join("shard.sbatch")),
            threads = self.threads,
            log = self.slurm_dir().join("shard-%a.log").to_string_lossy(),
            parts = q(&self.parts),
            exe = q(&self.terrafuse),
            manifest = q(&self.manifest),
            work = self.work_dir,
            budget = shell_quote(&self.memory_budget),
        )
    }

    /// The merge job's script: every part into the store, then the pyramid.
    pub fn merge_script(&self) -> String {
        let parts: Vec<String> = (0..self.shards).map(|i| q(&part_path(&self.parts, i))).collect();
        format!(
            "#!/bin/bash
# The merge of terrafuse plan {name}: written by `terrafuse slurm submit`, run after every
# shard succeeded (--dependency=afterok).
#SBATCH --job-name={name}-merge
#SBATCH --cpus-per-task={threads}
#SBATCH --output={log}
#SBATCH --open-mode=append
set -euo pipefail
exec {exe} store merge {store} \\
  {parts} \\
  --threads {threads} --quiet
",
            name = self.name,
            threads = self.threads,
            log = self.slurm_dir().join("merge.log").to_string_lossy(),
            exe = q(&self.terrafuse),
            store = q(&self.store),
            parts = parts.join(" \\\n  "),
        )
    }
}

/// The scripts of a comparison's or an export's plan (`terrafuse … --plan`).
#[derive(Clone, Debug)]
pub struct PlanJob {
    /// The `terrafuse` executable, as the compute nodes see it.
    pub terrafuse: PathBuf,
    /// The plan (absolute).
    pub plan: PathBuf,
    /// The folder of the scripts, logs and result, on shared storage (absolute).
    pub dir: PathBuf,
    /// The job name (`tf-` and the plan's short hash).
    pub name: String,
    /// CPUs per task.
    pub threads: usize,
    /// Where the merge job writes what `terrafuse merge` prints.
    pub result: PathBuf,
    /// The arguments of `terrafuse slurm submit PLAN` the merge runs to submit the next round.
    pub resubmit: Vec<String>,
}

impl PlanJob {
    /// The job array's script: `terrafuse shard PLAN env`, one shard per task.
    pub fn shard_script(&self) -> String {
        format!(
            "#!/bin/bash
# A shard of terrafuse plan {name}: written by `terrafuse slurm submit`.
#SBATCH --job-name={name}
#SBATCH --cpus-per-task={threads}
#SBATCH --output={log}
#SBATCH --open-mode=append
set -euo pipefail
exec {exe} shard {plan} env
",
            name = self.name,
            threads = self.threads,
            log = self.dir.join("shard-%a.log").to_string_lossy(),
            exe = q(&self.terrafuse),
            plan = q(&self.plan),
        )
    }

    /// The merge job's script: the result into its file once every round is in; where another
    /// round is needed (exit 3), that round submitted, its own merge after it.
    pub fn merge_script(&self) -> String {
        let resubmit: Vec<String> = self.resubmit.iter().map(|a| shell_quote(a)).collect();
        format!(
            "#!/bin/bash
# The merge of terrafuse plan {name}: written by `terrafuse slurm submit`, run after every
# shard of the round succeeded (--dependency=afterok).
#SBATCH --job-name={name}-merge
#SBATCH --cpus-per-task=1
#SBATCH --output={log}
#SBATCH --open-mode=append
set -uo pipefail
result={result}
{exe} merge {plan} >\"$result.tmp\"
rc=$?
if [ $rc -eq 0 ]; then
  mv -f \"$result.tmp\" \"$result\"
  echo \"terrafuse: complete: the result is in $result\"
  exit 0
fi
rm -f \"$result.tmp\"
if [ $rc -eq 3 ]; then
  exec {exe} slurm submit {plan} {resubmit}
fi
exit $rc
",
            name = self.name,
            log = self.dir.join("merge.log").to_string_lossy(),
            result = q(&self.result),
            exe = q(&self.terrafuse),
            plan = q(&self.plan),
            resubmit = resubmit.join(" "),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn words_are_quoted_for_the_shell() {
        assert_eq!(shell_quote("a b"), "'a b'");
        assert_eq!(shell_quote("it's"), r"'it'\''s'");
    }

    #[test]
    fn the_scripts_name_the_plan_and_every_part() {
        let job = SlurmJob {
            terrafuse: "/opt/tf/terrafuse".into(),
            manifest: "/shared/plan.json".into(),
            parts: "/shared/parts".into(),
            store: "/shared/srtm.gpkg".into(),
            shards: 3,
            name: "tf-0123456789ab".into(),
            threads: 4,
            memory_budget: "2GiB".into(),
            work_dir: "${TMPDIR:-/tmp}".into(),
        };
        let s = job.shard_script();
        assert!(s.contains("#SBATCH --job-name=tf-0123456789ab"), "{s}");
        assert!(s.contains("--shard \"$shard\""), "{s}");
        assert!(s.contains("--work-dir \"${TMPDIR:-/tmp}/terrafuse-tf-0123456789ab\""), "{s}");
        let m = job.merge_script();
        for i in 0..3 {
            assert!(m.contains(&format!("'/shared/parts/part-000{i}.gpkg'")), "{m}");
        }
        assert!(m.contains("store merge '/shared/srtm.gpkg'"), "{m}");
    }
}
