//! What the shard plans of every command share (`compare … --plan`, `export … --plan`; the
//! import's manifest is older and keeps its own): the stamps of the project and the dataset
//! stores a plan read, by which a shard refuses inputs that changed since; the plan's hash over
//! its own JSON; the cut of N items into runs of equal size ±1; and the atomic writing of a
//! plan. Each command's plan says what else decides its result.

use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use crate::files::sha256_hex;
use crate::project::Project;

/// Why a plan, or a file it names, cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum PlanError {
    /// The file and what is wrong with it.
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// What is wrong.
        problem: String,
    },
}

/// A [`PlanError::File`].
pub fn file_error(path: &Path, problem: impl std::fmt::Display) -> PlanError {
    PlanError::File { path: path.to_path_buf(), problem: problem.to_string() }
}

/// A file the plan depends on, as it was when planned.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Stamp {
    /// The file.
    pub path: PathBuf,
    /// Its size, bytes.
    pub bytes: u64,
    /// Its modification time, nanoseconds since the epoch.
    pub modified_ns: u128,
}

/// A file's stamp.
fn stamp(path: &Path) -> Result<Stamp, PlanError> {
    let meta = std::fs::metadata(path).map_err(|e| file_error(path, format!("cannot read: {e}")))?;
    let modified = meta.modified().ok().and_then(|t| t.duration_since(std::time::UNIX_EPOCH).ok());
    Ok(Stamp { path: path.to_path_buf(), bytes: meta.len(), modified_ns: modified.map_or(0, |d| d.as_nanos()) })
}

/// The SHA-256 of a project file's bytes and the stamps of its dataset stores.
pub fn inputs(project_path: &Path, project: &Project) -> Result<(String, Vec<Stamp>), PlanError> {
    let bytes = std::fs::read(project_path).map_err(|e| file_error(project_path, format!("cannot read: {e}")))?;
    let stores = project
        .layers
        .iter()
        .filter_map(|l| l.as_dataset())
        .map(|d| stamp(&project.resolve(&d.store)))
        .collect::<Result<_, _>>()?;
    Ok((sha256_hex(&bytes), stores))
}

/// Loads the project and refuses it, or one of its stores, if it changed since the plan
/// recorded `project_sha256` and `stores`, naming the file.
pub fn check_inputs(project_path: &Path, project_sha256: &str, stores: &[Stamp]) -> Result<Project, PlanError> {
    let project = Project::load(project_path).map_err(|e| file_error(project_path, e))?;
    let (sha, now) = inputs(project_path, &project)?;
    if sha != project_sha256 {
        return Err(file_error(project_path, "the project changed since the plan was made: make the plan again"));
    }
    for (now, then) in now.iter().zip(stores) {
        if now != then {
            return Err(file_error(&now.path, "the store changed since the plan was made: make the plan again"));
        }
    }
    if now.len() != stores.len() {
        return Err(file_error(project_path, "its datasets changed since the plan was made: make the plan again"));
    }
    Ok(project)
}

/// A command's shard plan: its format, version and hash, as [`load`] checks them.
pub trait Plan: Serialize + serde::de::DeserializeOwned + Clone {
    /// The `format` this build writes.
    const FORMAT: &'static str;
    /// The `version` this build writes and reads.
    const VERSION: u32;
    /// What the file is, for a message ("a comparison plan").
    const WHAT: &'static str;
    /// The plan's `format`, `version` and `hash` fields.
    fn header(&self) -> (&str, u32, &str);
    /// Its `hash` field.
    fn hash_mut(&mut self) -> &mut String;
}

/// The SHA-256 of a plan's JSON with its `hash` field empty.
pub fn digest<T: Plan>(plan: &T) -> String {
    let mut bare = plan.clone();
    bare.hash_mut().clear();
    sha256_hex(serde_json::to_string(&bare).unwrap_or_default().as_bytes())
}

/// Reads a plan and checks its format, version and hash, naming the file.
pub fn load<T: Plan>(path: &Path) -> Result<T, PlanError> {
    let text = std::fs::read_to_string(path).map_err(|e| file_error(path, format!("cannot read the plan: {e}")))?;
    let plan: T = serde_json::from_str(&text).map_err(|e| file_error(path, format!("not {}: {e}", T::WHAT)))?;
    let (format, version, hash) = plan.header();
    if format != T::FORMAT || version != T::VERSION {
        return Err(file_error(
            path,
            format!("format {format} version {version}: this build reads {} version {}", T::FORMAT, T::VERSION),
        ));
    }
    if digest(&plan) != hash {
        return Err(file_error(path, "its hash does not match its contents: the plan was edited or damaged"));
    }
    Ok(plan)
}

/// `n` items cut into `shards` runs of equal size ±1 (the longer first), as `(start, end)`.
pub fn runs(n: usize, shards: usize) -> Vec<(usize, usize)> {
    let shards = shards.max(1);
    let (per, extra) = (n / shards, n % shards);
    let mut start = 0;
    (0..shards)
        .map(|k| {
            let end = start + per + usize::from(k < extra);
            let run = (start, end);
            start = end;
            run
        })
        .collect()
}

/// The `format` field of a plan file: which command planned it.
pub fn format_of(path: &Path) -> Result<String, PlanError> {
    #[derive(Deserialize)]
    struct Head {
        format: String,
    }
    let text = std::fs::read_to_string(path).map_err(|e| file_error(path, format!("cannot read the plan: {e}")))?;
    let head: Head = serde_json::from_str(&text).map_err(|e| file_error(path, format!("not a plan: {e}")))?;
    Ok(head.format)
}

/// Writes a plan as pretty JSON, atomically, and makes its parts' folder.
pub fn write<T: Serialize>(plan_path: &Path, parts: &Path, plan: &T) -> Result<(), PlanError> {
    std::fs::create_dir_all(parts).map_err(|e| file_error(parts, format!("cannot create the parts' folder: {e}")))?;
    let text = serde_json::to_string_pretty(plan).map_err(|e| file_error(plan_path, e))?;
    crate::files::write_atomic(plan_path, text.as_bytes())
        .map_err(|e| file_error(plan_path, format!("cannot write: {e}")))
}

/// A shard's number, checked against the plan's `shards`.
pub fn check_shard(plan_path: &Path, shard: usize, shards: usize) -> Result<(), PlanError> {
    if shard >= shards {
        return Err(file_error(plan_path, format!("shard {shard}: the plan has shards 0 … {}", shards - 1)));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn runs_cover_every_item_once_in_sizes_differing_by_at_most_one() {
        for (n, k) in [(10, 3), (7, 7), (100, 1), (5, 2)] {
            let r = runs(n, k);
            assert_eq!(r.len(), k);
            assert_eq!(r[0].0, 0);
            assert_eq!(r[k - 1].1, n);
            assert!(r.windows(2).all(|w| w[0].1 == w[1].0));
            let sizes: Vec<usize> = r.iter().map(|(a, b)| b - a).collect();
            assert!(sizes.iter().max().unwrap() - sizes.iter().min().unwrap() <= 1, "{sizes:?}");
        }
    }
}
