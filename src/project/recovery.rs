//! The recovery file: what the workstation autosaves while a project has unsaved changes, so that
//! a crash or a kill loses at most the last few seconds of work. It is the project as edited,
//! written atomically to `.<file name>.recovery` beside the project (so that its relative paths
//! mean the same), removed when the project is saved or the changes are discarded, and offered
//! for restoring when the project is next opened while it is newer than the project.

use std::path::{Path, PathBuf};
use std::time::SystemTime;

use super::{Project, ProjectError};

/// The recovery file of the project at `path`.
pub fn path_of(project: &Path) -> PathBuf {
    let name = project.file_name().map_or_else(|| "project".into(), |n| n.to_string_lossy().into_owned());
    let dir = crate::files::folder_of(project);
    dir.join(format!(".{name}.recovery"))
}

/// A recovery file found beside a project.
#[derive(Clone, Debug, PartialEq)]
pub struct Recovery {
    /// The recovery file.
    pub path: PathBuf,
    /// When it was written.
    pub modified: SystemTime,
}

impl Recovery {
    /// A line saying it is there and how to use it.
    pub fn notice(&self) -> String {
        let age = self.modified.elapsed().map_or(0, |d| d.as_secs());
        format!(
            "a recovery file with unsaved changes exists: {} (written {} ago); `terrafuse view` offers to restore it",
            self.path.display(),
            age_text(age)
        )
    }

    /// Reads the recovered project (it resolves paths from the project's folder).
    pub fn load(&self) -> Result<Project, ProjectError> {
        Project::load(&self.path)
    }
}

fn age_text(seconds: u64) -> String {
    match seconds {
        s if s < 120 => format!("{s} s"),
        s if s < 7200 => format!("{} min", s / 60),
        s if s < 172_800 => format!("{} h", s / 3600),
        s => format!("{} days", s / 86_400),
    }
}

/// The recovery file of the project at `path`, when there is one newer than the project (or the
/// project is gone).
pub fn find(project: &Path) -> Option<Recovery> {
    let path = path_of(project);
    let modified = std::fs::metadata(&path).and_then(|m| m.modified()).ok()?;
    let saved = std::fs::metadata(project).and_then(|m| m.modified()).ok();
    saved.is_none_or(|s| modified >= s).then_some(Recovery { path, modified })
}

/// Writes `project` as the recovery file of the project at `path` (atomically).
pub fn write(project: &Project, path: &Path) -> Result<PathBuf, ProjectError> {
    let target = path_of(path);
    project.save(&target)?;
    Ok(target)
}

/// Removes the recovery file of the project at `path` (after a save, or a discard).
pub fn remove(path: &Path) {
    let _ = std::fs::remove_file(path_of(path));
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_recovery_file_is_found_while_newer_than_the_project_and_reads_back() {
        let dir = std::env::temp_dir().join(format!("terrafuse-recovery-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("p.json");
        let mut p = Project::new("moon");
        p.save(&path).unwrap();
        assert_eq!(find(&path), None);
        p.visuals.exaggeration = 3.0;
        let written = write(&p, &path).unwrap();
        assert_eq!(written, dir.join(".p.json.recovery"));
        let found = find(&path).expect("newer than the project");
        assert!(found.notice().contains(".p.json.recovery"), "{}", found.notice());
        assert_eq!(found.load().unwrap().visuals.exaggeration, 3.0);
        remove(&path);
        assert_eq!(find(&path), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
