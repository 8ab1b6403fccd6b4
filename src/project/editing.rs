//! A project changed from several places at once: commands run side by side, the workstation
//! open while a script brushes. Every change is a read, a change and an atomic write; each of
//! those is safe alone, but two of them interleaved lose the first writer's change. So:
//!
//! - a command that changes a project takes the project's lock ([`crate::files::lock`]) before
//!   it reads the file and keeps it until the new file is written ([`Project::load_to_change`],
//!   [`Held::save`]); a second command waits for the first, saying whom it waits for, and gives
//!   up after its wait with nothing changed;
//! - the workstation keeps the project in memory between saves, so it remembers what the file
//!   held when it read or wrote it ([`OnDisk`]) and saves only while the file still holds that
//!   ([`save_unless_changed`]): a change made by another process in between is never written
//!   over; the window offers to reload it or to keep its own version as a copy.

use std::path::{Path, PathBuf};
use std::time::Duration;

use sha2::Digest as _;

use super::{Project, ProjectError};
use crate::files::lock::Lock;

/// Who changes a project, and how long it waits while another process changes it.
pub struct Changer<'a> {
    /// A few words naming the process, e.g. `terrafuse brush` (the lock adds the process id).
    pub holder: &'a str,
    /// How long to wait for another process that holds the project (zero: do not wait).
    pub wait: Duration,
    /// Told once, with the holder's words, when this process has to wait.
    pub waiting: &'a mut dyn FnMut(&str),
}

/// A project file held for a change: saving through it writes the file while no other
/// Terrafuse process can read it to change it. Dropping it lets the next one in.
#[derive(Debug)]
pub struct Held {
    path: PathBuf,
    _lock: Lock,
}

impl Project {
    /// Takes the project's lock (waiting as `changer` says), then reads the project: what is read
    /// is what the file holds until [`Held::save`] writes the change.
    pub fn load_to_change(path: &Path, changer: Changer) -> Result<(Project, Held), ProjectError> {
        let lock = Lock::acquire(path, changer.holder, changer.wait, changer.waiting)?;
        let project = Project::load(path)?;
        Ok((project, Held { path: path.to_path_buf(), _lock: lock }))
    }
}

impl Held {
    /// Writes `project` over the held file (atomically, as [`Project::save`]).
    pub fn save(&self, project: &Project) -> Result<(), ProjectError> {
        project.save(&self.path)
    }

    /// The held file.
    pub fn path(&self) -> &Path {
        &self.path
    }
}

/// What a project file held when it was last read or written: a digest of its bytes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct OnDisk([u8; 32]);

impl OnDisk {
    /// What the file at `path` holds now (None: it cannot be read, or is gone).
    pub fn read(path: &Path) -> Option<OnDisk> {
        std::fs::read(path).ok().map(|bytes| OnDisk::of(&bytes))
    }

    /// The digest of a file's bytes.
    pub fn of(bytes: &[u8]) -> OnDisk {
        OnDisk(sha2::Sha256::digest(bytes).into())
    }
}

/// A cheap look at a file (its size and modification time), to notice a change without reading
/// it; a different stamp is then confirmed with [`OnDisk::read`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Stamp {
    len: u64,
    modified: Option<std::time::SystemTime>,
}

impl Stamp {
    /// The stamp of the file at `path` (None: gone).
    pub fn of(path: &Path) -> Option<Stamp> {
        let m = std::fs::metadata(path).ok()?;
        Some(Stamp { len: m.len(), modified: m.modified().ok() })
    }
}

/// Saves `project` at `path` for `holder` (the workstation) unless the file no longer holds
/// `known` (what this process last read or wrote there; None: a new file, which must not exist
/// yet): [`ProjectError::ChangedOnDisk`] then, and the file is left as the other process wrote
/// it. While another process holds the project the save waits up to `wait`, then
/// [`ProjectError::Lock`]. Returns what the file holds after the save.
pub fn save_unless_changed(
    project: &Project,
    path: &Path,
    known: Option<OnDisk>,
    holder: &str,
    wait: Duration,
) -> Result<OnDisk, ProjectError> {
    let lock = Lock::acquire(path, holder, wait, &mut |_| {})?;
    let now = OnDisk::read(path);
    if now.is_some() && now != known {
        return Err(ProjectError::ChangedOnDisk { path: path.to_path_buf() });
    }
    project.save(path)?;
    let written = OnDisk::read(path).ok_or_else(|| ProjectError::Read {
        path: path.to_path_buf(),
        source: std::io::Error::other("the file is gone after it was written"),
    })?;
    drop(lock);
    Ok(written)
}

/// The default wait of a command for another that changes the same project.
pub const DEFAULT_WAIT: Duration = Duration::from_secs(600);

#[cfg(test)]
mod tests {
    use super::*;

    fn camera() -> super::super::CameraSpec {
        super::super::CameraSpec { lat: 0.0, lon: 0.0, alt: 1e6, heading: 0.0, pitch: -90.0, fov: 45.0 }
    }

    fn folder(name: &str) -> PathBuf {
        let dir = std::env::temp_dir().join(format!("terrafuse-editing-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    #[test]
    fn a_save_over_a_file_changed_by_another_writer_is_refused_and_leaves_it() {
        let dir = folder("changed");
        let path = dir.join("p.json");
        let mut mine = Project::new("moon");
        mine.save(&path).unwrap();
        let known = OnDisk::read(&path);
        // Another process changes the file.
        let mut theirs = Project::new("moon");
        theirs.default_view = None;
        theirs.views.insert("theirs".into(), camera());
        theirs.save(&path).unwrap();
        let theirs_bytes = std::fs::read(&path).unwrap();
        mine.views.insert("mine".into(), camera());
        let e = save_unless_changed(&mine, &path, known, "test", Duration::ZERO).unwrap_err();
        assert!(matches!(e, ProjectError::ChangedOnDisk { .. }), "{e}");
        assert_eq!(std::fs::read(&path).unwrap(), theirs_bytes, "their change is kept");
        // Saved against what is there now, it goes through and says what it wrote.
        let now = OnDisk::read(&path);
        let written = save_unless_changed(&mine, &path, now, "test", Duration::ZERO).unwrap();
        assert_eq!(Some(written), OnDisk::read(&path));
        assert!(Project::load(&path).unwrap().views.contains_key("mine"));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_held_project_makes_a_second_changer_wait_and_give_up() {
        let dir = folder("held");
        let path = dir.join("p.json");
        Project::new("moon").save(&path).unwrap();
        let mut quiet = |_: &str| {};
        let (p, held) =
            Project::load_to_change(&path, Changer { holder: "first", wait: Duration::ZERO, waiting: &mut quiet })
                .unwrap();
        let mut told = String::new();
        let mut tell = |w: &str| told = w.to_string();
        let e = Project::load_to_change(
            &path,
            Changer { holder: "second", wait: Duration::from_millis(50), waiting: &mut tell },
        )
        .unwrap_err();
        assert!(told.starts_with("first, pid"), "{told}");
        assert!(e.to_string().contains("first, pid"), "{e}");
        // The workstation's save waits as well, and is refused while the command holds it.
        let e = save_unless_changed(&p, &path, OnDisk::read(&path), "view", Duration::ZERO).unwrap_err();
        assert!(matches!(e, ProjectError::Lock(_)), "{e}");
        held.save(&p).unwrap();
        drop(held);
        assert!(save_unless_changed(&p, &path, OnDisk::read(&path), "view", Duration::ZERO).is_ok());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
