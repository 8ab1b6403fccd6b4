//! What `terrafuse import --plan`, `import --manifest --shard` and `store merge` print.

use std::fmt::Write as _;
use std::path::Path;

use super::CliError;

use crate::store::ImportReport;
use crate::store::merge::MergeReport;
use crate::store::shard::PlanReport;

/// The lines `terrafuse import … --plan` prints.
pub fn plan_summary(path: &Path, r: &PlanReport) -> String {
    let m = &r.manifest;
    let mut out = String::new();
    let sizes: Vec<usize> = m.shards.iter().map(|s| s.quads.len()).collect();
    let total: usize = sizes.iter().sum();
    let _ = writeln!(
        out,
        "plan {} → {}: dataset {} at level {}, {total} quads in {} shards of {}–{} quads (Hilbert order per face), {:.2} s",
        m.short_hash(),
        path.display(),
        m.import.dataset,
        m.import.level,
        m.shards.len(),
        sizes.iter().min().unwrap_or(&0),
        sizes.iter().max().unwrap_or(&0),
        r.seconds
    );
    out.push_str(&super::plans::next_steps(path, m.shards.len()));
    let _ = writeln!(
        out,
        "(parts in {}, the store {} unless merge --store; or by hand: terrafuse import --manifest {} --shard I --store PART-I.gpkg, then terrafuse store merge STORE PART-*.gpkg)",
        super::plans::import_parts(path).display(),
        super::plans::import_store(path, None).display(),
        path.display()
    );
    out
}

/// The lines `terrafuse import --manifest M --shard I` prints.
pub fn shard_summary(store: &Path, shard: usize, r: &ImportReport) -> String {
    if r.already_complete {
        return format!("shard {shard} → {} is already complete: nothing to do\n", store.display());
    }
    let (_, written, resumed) = r.levels.first().copied().unwrap_or_default();
    let resumed = if resumed > 0 { format!(", {resumed} quads finished by an earlier run") } else { String::new() };
    format!(
        "shard {shard} → {}: level {}, {written} tiles with data{resumed}; {:.2} s ({:.2} M samples/s), peak memory {:.0} MiB\n{}",
        store.display(),
        r.finest_level,
        r.seconds_finest,
        r.finest_samples as f64 / r.seconds_finest.max(1e-9) / 1e6,
        r.peak_rss_bytes as f64 / f64::from(1u32 << 20),
        super::store::lattice_line(r)
    )
}

fn ranges(shards: &[usize]) -> String {
    let mut out: Vec<String> = Vec::new();
    let mut k = 0;
    while k < shards.len() {
        let mut j = k;
        while j + 1 < shards.len() && shards[j + 1] == shards[j] + 1 {
            j += 1;
        }
        out.push(if j > k { format!("{}-{}", shards[k], shards[j]) } else { shards[k].to_string() });
        k = j + 1;
    }
    out.join(",")
}

/// Shard indices as Slurm's `--array` takes them: `0-3,5,7-9`.
pub fn array_ranges(shards: &[usize]) -> String {
    ranges(shards)
}

/// The lines `terrafuse store merge` prints.
pub fn merge_summary(store: &Path, r: &MergeReport) -> String {
    let mut out = String::new();
    let tiles: u64 = r.merged.iter().map(|m| m.1).sum();
    let merged: Vec<usize> = r.merged.iter().map(|m| m.0).collect();
    let _ = writeln!(
        out,
        "dataset {} → {} (plan {}): merged {} shards ({}), {tiles} tiles, in {:.2} s",
        r.dataset,
        store.display(),
        &r.manifest[..12.min(r.manifest.len())],
        merged.len(),
        if merged.is_empty() { "none".into() } else { ranges(&merged) },
        r.seconds_merge
    );
    if !r.skipped.is_empty() {
        let _ = writeln!(out, "  already merged, skipped: {}", ranges(&r.skipped));
    }
    if r.complete {
        for (level, written, resumed) in &r.levels {
            let resumed = if *resumed > 0 { format!(" ({resumed} finished by an earlier run)") } else { String::new() };
            let _ = writeln!(out, "  level {level:>2}: {written} tiles with data{resumed}");
        }
        let _ = writeln!(
            out,
            "complete: all {} shards in; pyramid {:.2} s; peak memory {:.0} MiB",
            r.shards,
            r.seconds_pyramid,
            r.peak_rss_bytes as f64 / f64::from(1u32 << 20)
        );
    } else {
        let _ = writeln!(
            out,
            "INCOMPLETE: {} of {} shards missing ({}); merge their parts when they are done (the pyramid is built then)",
            r.missing.len(),
            r.shards,
            ranges(&r.missing)
        );
    }
    out
}

/// The shard a task runs: a number, or `env` for the scheduler's array index.
pub(super) fn shard_index(text: &str, var: &dyn Fn(&str) -> Option<String>) -> Result<usize, CliError> {
    if text == "env" {
        const VARS: [&str; 3] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX"];
        let (name, value) = VARS
            .iter()
            .find_map(|v| var(v).map(|x| (*v, x)))
            .ok_or_else(|| format!("--shard env: none of {} is set", VARS.join(", ")))?;
        return value
            .trim()
            .parse()
            .map_err(|_| CliError::Usage(format!("--shard env: {name}={value} is not a shard number")));
    }
    text.parse().map_err(|_| CliError::Usage(format!("--shard {text}: give a shard number 0 … N−1, or env")))
}

#[cfg(test)]
mod tests {
    #[test]
    fn shard_lists_become_slurm_array_ranges() {
        assert_eq!(super::array_ranges(&[0, 1, 2, 3, 5, 7, 8, 9]), "0-3,5,7-9");
        assert_eq!(super::array_ranges(&[4]), "4");
        assert_eq!(super::array_ranges(&[]), "");
    }
}
