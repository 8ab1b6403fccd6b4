//! The recent projects: a short list, most recent first, kept as JSON in the workstation's
//! configuration folder (the caller says where; `terrafuse` uses `$XDG_CONFIG_HOME/terrafuse`).

use crate::gui::GuiError;
use crate::gui::Within;
use std::path::{Path, PathBuf};

/// Projects kept in the list.
pub const KEPT: usize = 10;

/// The recent projects and the file they are kept in.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Recent {
    /// Where the list is kept (None: not kept).
    pub file: Option<PathBuf>,
    /// Absolute paths, most recent first.
    pub projects: Vec<PathBuf>,
}

impl Recent {
    /// The list kept in `dir/recent.json` (empty when the file is missing or unreadable).
    pub fn load(dir: Option<&Path>) -> Recent {
        let file = dir.map(|d| d.join("recent.json"));
        let projects = file
            .as_deref()
            .and_then(|f| std::fs::read_to_string(f).ok())
            .and_then(|text| serde_json::from_str::<Vec<PathBuf>>(&text).ok())
            .unwrap_or_default();
        Recent { file, projects }
    }

    /// The most recent project that still exists.
    pub fn last(&self) -> Option<&Path> {
        self.projects.iter().map(PathBuf::as_path).find(|p| p.is_file())
    }

    /// Puts `project` first and writes the list (atomically). An error says why it was not
    /// kept; the list in memory is updated regardless.
    pub fn add(&mut self, project: &Path) -> Result<(), GuiError> {
        let project = std::path::absolute(project).unwrap_or_else(|_| project.to_path_buf());
        self.projects.retain(|p| *p != project);
        self.projects.insert(0, project);
        self.projects.truncate(KEPT);
        let Some(file) = &self.file else {
            return Ok(());
        };
        if let Some(dir) = file.parent() {
            std::fs::create_dir_all(dir).map_err(GuiError::file(dir, "cannot create"))?;
        }
        let text = serde_json::to_string_pretty(&self.projects).within("recent projects")?;
        crate::files::write_atomic(file, text.as_bytes()).map_err(GuiError::file(file, "cannot write"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_list_keeps_the_latest_first_once_each_and_survives_a_restart() {
        let dir = std::env::temp_dir().join(format!("terrafuse-recent-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut r = Recent::load(Some(&dir));
        assert!(r.projects.is_empty() && r.last().is_none());
        let files: Vec<PathBuf> = (0..12).map(|k| dir.join(format!("p{k}.json"))).collect();
        std::fs::create_dir_all(&dir).unwrap();
        for f in &files {
            std::fs::write(f, "{}").unwrap();
            r.add(f).unwrap();
        }
        r.add(&files[5]).unwrap();
        let again = Recent::load(Some(&dir));
        assert_eq!(again.projects.len(), KEPT);
        assert_eq!(again.projects[0], files[5]);
        assert_eq!(again.projects[1], files[11]);
        std::fs::remove_file(&files[5]).unwrap();
        assert_eq!(again.last(), Some(files[11].as_path()), "a project that is gone is skipped");
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
