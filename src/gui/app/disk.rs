//! The project file as other processes see it: the window keeps the project in memory between
//! saves, while a command (`terrafuse brush …`) or another window may change the file. The
//! window remembers what the file held when it last read or wrote it, looks at the file once a
//! second, and:
//! - with no unsaved changes, reloads a file that another process changed (the camera stays);
//! - with unsaved changes, offers to reload (dropping them) or to keep them as a copy beside the
//!   project, and never writes over the other process's change: a save is refused while the
//!   file holds something this window did not read ([`crate::project::editing`]);
//! - while another process holds the project's lock, the save waits for it (retried each second,
//!   the status bar saying whom it waits for).

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::App;
use crate::project::ProjectError;
use crate::project::editing::{OnDisk, Stamp, save_unless_changed};

/// How often the window looks at the project file.
const LOOK_EVERY: Duration = Duration::from_secs(1);

/// Who the window is, in the lock file (what a waiting command names).
const HOLDER: &str = "terrafuse view (the workstation, saving)";

/// What the window knows of the file on disk.
#[derive(Default)]
pub(super) struct DiskState {
    /// What the file held when this window last read or wrote it (None: not known).
    pub on_disk: Option<OnDisk>,
    /// The file's size and time then, to notice a change without reading it.
    stamp: Option<Stamp>,
    /// When the file was last looked at.
    looked: Option<Instant>,
    /// Another process changed the file while this window has unsaved changes.
    pub conflict: bool,
    /// A save waits for another process's lock (tried again each second).
    pending_save: bool,
    /// The camera to keep when the reloaded project opens.
    pub reload_camera: Option<crate::project::CameraSpec>,
}

impl App {
    /// Remembers what the file holds, as this window read or wrote it.
    pub(super) fn remember_disk(&mut self, on_disk: Option<OnDisk>) {
        self.disk.on_disk = on_disk;
        self.disk.stamp = Stamp::of(&self.project_path);
        self.disk.looked = Some(Instant::now());
    }

    /// Gives the window what the file held when its project was read.
    pub fn with_disk(mut self, on_disk: Option<OnDisk>) -> App {
        self.remember_disk(on_disk);
        self
    }

    /// Whether another process changed the project file while this window has unsaved changes
    /// (the window then offers to reload it or to keep its changes as a copy).
    pub fn disk_conflict(&self) -> bool {
        self.disk.conflict
    }

    /// Writes the project over its file unless another process changed the file since this
    /// window read or wrote it (or holds it now, for longer than a moment).
    pub(super) fn write_project(&mut self) -> Result<(), ProjectError> {
        let result = save_unless_changed(
            &self.project,
            &self.project_path,
            self.disk.on_disk,
            HOLDER,
            Duration::from_millis(200),
        );
        self.disk.pending_save = false;
        match result {
            Ok(written) => {
                self.remember_disk(Some(written));
                Ok(())
            }
            Err(ProjectError::ChangedOnDisk { path }) => {
                self.disk.conflict = true;
                Err(ProjectError::ChangedOnDisk { path })
            }
            Err(e @ ProjectError::Lock(crate::files::lock::LockError::Busy { .. })) => {
                self.disk.pending_save = true;
                Err(e)
            }
            Err(e) => Err(e),
        }
    }

    /// Looks at the project file once a second: a change by another process is reloaded (no
    /// unsaved changes here) or offered (unsaved changes); a save that waited is tried again.
    pub(super) fn watch_disk(&mut self) {
        if self.file.opening.is_some() || self.screenshot.is_some() {
            return;
        }
        if self.disk.looked.is_some_and(|t| t.elapsed() < LOOK_EVERY) {
            return;
        }
        self.disk.looked = Some(Instant::now());
        if self.disk.pending_save {
            self.save_project();
            return;
        }
        let stamp = Stamp::of(&self.project_path);
        if stamp == self.disk.stamp || self.disk.conflict {
            return;
        }
        self.disk.stamp = stamp;
        let now = OnDisk::read(&self.project_path);
        if now.is_none() || now == self.disk.on_disk {
            return;
        }
        if self.unsaved {
            self.disk.conflict = true;
            self.message = format!(
                "{} was changed by another program: reload it, or keep your changes as a copy",
                self.project_path.display()
            );
        } else {
            self.reload_from_disk();
            self.message = format!("{} was changed by another program: reloaded", self.project_path.display());
        }
    }

    /// Reads the project again from its file (dropping unsaved changes), keeping the camera.
    pub fn reload_from_disk(&mut self) {
        self.disk.conflict = false;
        self.disk.reload_camera = Some(self.camera);
        let path = self.project_path.clone();
        self.open_project(&path, None);
    }

    /// Saves this window's version beside the project as `<name>.mine.json` (or `.mine-2.json`, …,
    /// never over a file), then edits that copy; the project file keeps the other process's
    /// version. Returns the copy's path.
    pub fn keep_as_copy(&mut self) -> Option<PathBuf> {
        let (original, copy) = (self.project_path.clone(), copy_path(&self.project_path));
        self.save_as(&copy);
        if self.unsaved {
            return None;
        }
        self.disk.conflict = false;
        self.message = format!(
            "your changes are saved in {} (the window edits it now); {} keeps the other program's version",
            copy.display(),
            original.display()
        );
        Some(copy)
    }

    /// The dialog shown while another process's change and this window's unsaved ones conflict.
    pub(super) fn conflict_dialog(&mut self, ctx: &egui::Context) {
        if !self.disk.conflict || self.screenshot.is_some() {
            return;
        }
        let mut choice = None;
        egui::Modal::new(egui::Id::unique("disk-conflict")).show(ctx, |ui| {
            ui.label(format!(
                "{} was changed by another program (a command, or another window) since you opened it, \
                 and you have unsaved changes here. Saving now would lose one of the two.",
                self.project_path.display()
            ));
            ui.horizontal(|ui| {
                if ui.button("reload it (drop my changes)").clicked() {
                    choice = Some(1);
                }
                if ui
                    .button("keep mine as a copy")
                    .on_hover_text(format!("saves your version as {}", copy_path(&self.project_path).display()))
                    .clicked()
                {
                    choice = Some(2);
                }
                if ui.button("decide later").clicked() {
                    choice = Some(3);
                }
            });
        });
        match choice {
            Some(1) => self.reload_from_disk(),
            Some(2) => {
                self.keep_as_copy();
            }
            Some(_) => {
                // Asked again at the next save (which is refused while the file differs).
                self.disk.conflict = false;
                self.disk.stamp = Stamp::of(&self.project_path);
            }
            None => {}
        }
    }
}

/// `<stem>.mine.json` beside `path`, or `.mine-2.json`, … when taken.
fn copy_path(path: &Path) -> PathBuf {
    let stem = path.file_stem().map_or_else(|| "project".into(), |s| s.to_string_lossy().into_owned());
    let ext = path.extension().map_or_else(|| "json".into(), |e| e.to_string_lossy().into_owned());
    (1..)
        .map(|k| {
            let tail = if k == 1 { "mine".to_string() } else { format!("mine-{k}") };
            path.with_file_name(format!("{stem}.{tail}.{ext}"))
        })
        .find(|p| !p.exists())
        .unwrap_or_else(|| path.with_extension("mine.json"))
}
