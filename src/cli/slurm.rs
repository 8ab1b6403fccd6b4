//! `terrafuse slurm submit`: a plan's missing shards as a Slurm job array, and the merge after it
//! (an import's manifest, or a comparison's or an export's plan).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;

use super::CliError;
use super::error::Context;

type Result<T> = std::result::Result<T, CliError>;

/// Returns a failed run's message.
macro_rules! bail {
    ($($arg:tt)*) => {
        return Err(CliError::Run(format!($($arg)*)))
    };
}

use super::shard::array_ranges;
use crate::slurm::{PlanJob, SlurmJob, part_path};
use crate::store::merge::merged_shards;
use crate::store::shard::{Manifest, part_is_done};

/// What `terrafuse slurm submit` is given.
#[derive(Clone, Debug)]
pub struct SubmitRequest {
    /// The manifest.
    pub manifest: PathBuf,
    /// Folder of the partial stores (shared storage).
    pub parts: PathBuf,
    /// The merged store.
    pub store: PathBuf,
    /// CPUs per task.
    pub threads: usize,
    /// Memory budget per task.
    pub memory_budget: String,
    /// Node-local work folder (a shell word, expanded on the node).
    pub work_dir: String,
    /// Extra `sbatch` arguments (partition, account, time…), for both jobs.
    pub sbatch_args: Vec<String>,
    /// The terrafuse the nodes run (default: this one).
    pub terrafuse: Option<PathBuf>,
    /// Print the commands instead of running them.
    pub dry_run: bool,
}

fn absolute(path: &Path) -> Result<PathBuf> {
    std::path::absolute(path).with_context(|| format!("{}: cannot make the path absolute", path.display()))
}

fn run(cmd: &mut Command) -> Result<String> {
    let out = cmd.output().with_context(|| {
        format!("cannot run {:?}: is Slurm installed (sbatch, squeue on the PATH, SLURM_CONF set)?", cmd.get_program())
    })?;
    if !out.status.success() {
        bail!(
            "{:?} failed (is this a Slurm login node: slurmctld reachable, SLURM_CONF set if needed?): {}",
            cmd.get_program(),
            String::from_utf8_lossy(&out.stderr).trim()
        );
    }
    Ok(String::from_utf8_lossy(&out.stdout).trim().to_owned())
}

fn show(cmd: &Command) -> String {
    std::iter::once(cmd.get_program())
        .chain(cmd.get_args())
        .map(|a| crate::slurm::shell_quote(&a.to_string_lossy()))
        .collect::<Vec<_>>()
        .join(" ")
}

/// Submits the shards whose parts are missing as one job array, and a merge job that depends on
/// it; with every part present, only the merge; with the store complete, nothing.
pub fn slurm_submit(req: &SubmitRequest) -> Result<String> {
    let m = Manifest::load(&req.manifest)?;
    let parts = absolute(&req.parts)?;
    let store = absolute(&req.store)?;
    let terrafuse = match &req.terrafuse {
        Some(p) => absolute(p)?,
        None => std::env::current_exe().context("cannot find this terrafuse executable")?,
    };
    let job = SlurmJob {
        terrafuse,
        manifest: absolute(&req.manifest)?,
        parts: parts.clone(),
        store: store.clone(),
        shards: m.shards.len(),
        name: format!("tf-{}", m.short_hash()),
        threads: req.threads.max(1),
        memory_budget: req.memory_budget.clone(),
        work_dir: req.work_dir.clone(),
    };
    let mut out = String::new();
    if let Some((_, true)) = merged_shards(&store, &m.import.dataset, &m.hash)? {
        let _ = writeln!(out, "{}: dataset {} is complete: nothing to submit", store.display(), m.import.dataset);
        return Ok(out);
    }
    if !req.dry_run {
        refuse_queued(&job.name, None)?;
    }
    let merged = merged_shards(&store, &m.import.dataset, &m.hash)?.map(|(s, _)| s).unwrap_or_default();
    let missing: Vec<usize> =
        (0..m.shards.len()).filter(|&i| !merged.contains(&i) && !part_is_done(&part_path(&parts, i), &m, i)).collect();
    std::fs::create_dir_all(job.slurm_dir())
        .with_context(|| format!("{}: cannot make the folder", job.slurm_dir().display()))?;
    let shard_script = job.slurm_dir().join("shard.sbatch");
    let merge_script = job.slurm_dir().join("merge.sbatch");
    for (path, text) in [(&shard_script, job.shard_script()), (&merge_script, job.merge_script())] {
        crate::files::write_atomic(path, text.as_bytes())
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    let _ = writeln!(
        out,
        "plan {}: {} shards, {} to run ({}), parts in {}",
        m.short_hash(),
        m.shards.len(),
        missing.len(),
        if missing.is_empty() { "none".into() } else { array_ranges(&missing) },
        parts.display()
    );
    let scripts = Scripts { shard: &shard_script, merge: &merge_script, dir: &job.slurm_dir(), name: &job.name };
    if !submit_jobs(&mut out, &scripts, &missing, &req.sbatch_args, req.dry_run)? {
        return Ok(out);
    }
    let _ = writeln!(
        out,
        "watch: squeue -n {0},{0}-merge; after a failure run the same command again: only missing shards are submitted",
        job.name
    );
    Ok(out)
}

/// Refuses to submit while jobs named `name` or `name-merge` are queued or running (but the
/// running merge job `own_job`, which submits the next round).
fn refuse_queued(name: &str, own_job: Option<&str>) -> Result<()> {
    let queued = run(Command::new("squeue").args(["-h", "-o", "%i %j %T", "-n"]).arg(format!("{name},{name}-merge")))?;
    let queued: Vec<&str> =
        queued.lines().filter(|l| own_job.is_none_or(|own| l.split(' ').next() != Some(own))).collect();
    if !queued.is_empty() {
        bail!(
            "jobs of plan {name} are still queued or running:\n{}\nwait for them to end (squeue -n {name}) or cancel them (scancel -n {name}), then submit again",
            queued.join("\n")
        );
    }
    Ok(())
}

/// What `terrafuse slurm submit PLAN` is given.
#[derive(Clone, Debug)]
pub struct PlanSubmit {
    /// A comparison's or an export's plan.
    pub plan: PathBuf,
    /// CPUs per task.
    pub threads: usize,
    /// An import's memory budget per task.
    pub memory_budget: String,
    /// An import's node-local work folder (a shell word, expanded on the node).
    pub work_dir: String,
    /// Extra `sbatch` arguments, for both jobs.
    pub sbatch_args: Vec<String>,
    /// The terrafuse the nodes run (default: this one).
    pub terrafuse: Option<PathBuf>,
    /// Print the commands instead of running them.
    pub dry_run: bool,
    /// The Slurm job this runs in (`SLURM_JOB_ID`): a merge job submitting the next round.
    pub own_job: Option<String>,
}

/// Submits the pending round's missing shards of a comparison's or an export's plan as one job
/// array, and a merge job after it whose exit 3 (another round) submits that round the same way;
/// with every part in, only the merge; with the result written, nothing.
pub fn submit_plan(req: &PlanSubmit) -> Result<String> {
    use super::plans::{Planned, pending, planned};
    let plan = absolute(&req.plan)?;
    let kind = planned(&plan)?;
    let (hash, parts, json) = match kind {
        Planned::Compare => {
            let p = crate::compare::sharded::ComparePlan::load(&plan)?;
            (p.hash, p.parts, p.json)
        }
        Planned::Export => {
            let p = crate::export::sharded::ExportPlan::load(&plan)?;
            (p.hash, p.parts, false)
        }
        // An import's plan, its parts and store beside it as `terrafuse shard` and `merge` keep them.
        Planned::Import => {
            return slurm_submit(&SubmitRequest {
                manifest: plan.clone(),
                parts: super::plans::import_parts(&plan),
                store: super::plans::import_store(&plan, None),
                threads: req.threads,
                memory_budget: req.memory_budget.clone(),
                work_dir: req.work_dir.clone(),
                sbatch_args: req.sbatch_args.clone(),
                terrafuse: req.terrafuse.clone(),
                dry_run: req.dry_run,
            });
        }
    };
    let terrafuse = match &req.terrafuse {
        Some(p) => absolute(p)?,
        None => std::env::current_exe().context("cannot find this terrafuse executable")?,
    };
    let dir = parts.join("slurm");
    let mut resubmit = vec!["--threads".to_owned(), req.threads.max(1).to_string()];
    resubmit.extend(req.sbatch_args.iter().map(|a| format!("--sbatch-arg={a}")));
    resubmit.extend(["--terrafuse".to_owned(), terrafuse.to_string_lossy().into_owned()]);
    let job = PlanJob {
        terrafuse,
        plan: plan.clone(),
        dir: dir.clone(),
        name: format!("tf-{}", &hash[..12.min(hash.len())]),
        threads: req.threads.max(1),
        result: dir.join(if json { "result.json" } else { "result.txt" }),
        resubmit,
    };
    let mut out = String::new();
    let pending = pending(&plan)?;
    if pending.is_none() && job.result.exists() {
        let _ =
            writeln!(out, "plan {}: complete, the result is in {}: nothing to submit", job.name, job.result.display());
        return Ok(out);
    }
    if !req.dry_run {
        refuse_queued(&job.name, req.own_job.as_deref())?;
    }
    std::fs::create_dir_all(&dir).with_context(|| format!("{}: cannot make the folder", dir.display()))?;
    let shard_script = dir.join("shard.sbatch");
    let merge_script = dir.join("merge.sbatch");
    for (path, text) in [(&shard_script, job.shard_script()), (&merge_script, job.merge_script())] {
        crate::files::write_atomic(path, text.as_bytes())
            .with_context(|| format!("{}: cannot write", path.display()))?;
    }
    let (round, missing) = pending.unwrap_or((0, Vec::new()));
    let _ = writeln!(
        out,
        "plan {}: round {round}: {} shards to run ({}), parts in {}",
        job.name,
        missing.len(),
        if missing.is_empty() { "none".into() } else { array_ranges(&missing) },
        parts.display()
    );
    let scripts = Scripts { shard: &shard_script, merge: &merge_script, dir: &dir, name: &job.name };
    if !submit_jobs(&mut out, &scripts, &missing, &req.sbatch_args, req.dry_run)? {
        return Ok(out);
    }
    let _ = writeln!(
        out,
        "the result goes to {}; watch: squeue -n {1},{1}-merge; after a failure run the same command again",
        job.result.display(),
        job.name
    );
    Ok(out)
}

/// A plan's two batch scripts, their folder (the logs) and the jobs' name.
struct Scripts<'a> {
    shard: &'a Path,
    merge: &'a Path,
    dir: &'a Path,
    name: &'a str,
}

/// Submits the `missing` shards as one job array (none: no array) and the merge after it
/// (`afterok`, killed with an invalid dependency), saying so in `out`; with `dry_run` prints the
/// `sbatch` lines instead and returns false.
fn submit_jobs(
    out: &mut String,
    scripts: &Scripts,
    missing: &[usize],
    sbatch_args: &[String],
    dry_run: bool,
) -> Result<bool> {
    let mut array = Command::new("sbatch");
    array.arg("--parsable").arg(format!("--array={}", array_ranges(missing))).args(sbatch_args).arg(scripts.shard);
    let mut merge = Command::new("sbatch");
    merge.arg("--parsable").args(sbatch_args);
    if dry_run {
        if !missing.is_empty() {
            let _ = writeln!(out, "{}", show(&array));
            merge.arg("--dependency=afterok:ARRAY_JOB_ID").arg("--kill-on-invalid-dep=yes");
        }
        let _ = writeln!(out, "{}", show(merge.arg(scripts.merge)));
        if !missing.is_empty() {
            let _ = writeln!(out, "(ARRAY_JOB_ID: the job id the first sbatch prints)");
        }
        return Ok(false);
    }
    if !missing.is_empty() {
        let id = run(&mut array)?;
        let id = id.split(';').next().unwrap_or(&id).to_owned();
        let _ =
            writeln!(out, "submitted job array {id} ({}), logs {}/shard-*.log", scripts.name, scripts.dir.display());
        merge.arg(format!("--dependency=afterok:{id}")).arg("--kill-on-invalid-dep=yes");
    }
    let id = run(merge.arg(scripts.merge))?;
    let _ = writeln!(out, "submitted merge job {id} ({}-merge), log {}/merge.log", scripts.name, scripts.dir.display());
    Ok(true)
}
