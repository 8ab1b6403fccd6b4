//! The desktop's own file dialog (through `rfd`: the XDG desktop portal on Linux), on a thread of
//! its own so that the window keeps drawing while it is open. It only fills the typed path of
//! the window's forms (open, save as, new, add a dataset): where the desktop has no portal (a
//! bare X server, CI) the button does nothing harmful and the typed path still works.

use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

/// What the dialog is for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Purpose {
    /// An existing project file.
    OpenProject,
    /// A new or existing project file to write.
    SaveProject,
    /// A raster or a store to add as a dataset.
    Dataset,
}

/// A dialog open on its thread.
#[derive(Default)]
pub struct FilePick {
    handle: Option<JoinHandle<Option<PathBuf>>>,
}

impl FilePick {
    /// Opens the dialog for `purpose`, starting in the folder of `near` (no-op while one is open).
    pub fn start(&mut self, purpose: Purpose, near: &str) {
        if self.handle.is_some() {
            return;
        }
        let folder = Path::new(near).parent().filter(|p| p.is_dir()).map(Path::to_path_buf);
        self.handle = std::thread::Builder::new()
            .name("terrafuse-file-dialog".into())
            .spawn(move || {
                let mut dialog = rfd::FileDialog::new();
                if let Some(f) = folder {
                    dialog = dialog.set_directory(f);
                }
                match purpose {
                    Purpose::OpenProject => dialog.add_filter("Terrafuse project", &["json"]).pick_file(),
                    Purpose::SaveProject => dialog.add_filter("Terrafuse project", &["json"]).save_file(),
                    Purpose::Dataset => dialog
                        .add_filter("rasters and stores", &["tif", "tiff", "gpkg", "img", "vrt", "dem", "hgt", "nc"])
                        .add_filter("any file GDAL reads", &["*"])
                        .pick_file(),
                }
            })
            .ok();
    }

    /// Whether a dialog is open.
    pub fn open(&self) -> bool {
        self.handle.is_some()
    }

    /// The chosen path once the dialog closed (None while open, cancelled or unavailable).
    pub fn poll(&mut self) -> Option<PathBuf> {
        if !self.handle.as_ref()?.is_finished() {
            return None;
        }
        self.handle.take()?.join().ok().flatten()
    }

    /// A *browse…* button beside a typed path: opens the dialog, and fills `path` with the
    /// choice once it closes.
    pub fn button(&mut self, ui: &mut egui::Ui, purpose: Purpose, path: &mut String) {
        if let Some(chosen) = self.poll() {
            *path = chosen.display().to_string();
        }
        if ui
            .add_enabled(!self.open(), egui::Button::new("browse…"))
            .on_hover_text("the desktop's file dialog (typing the path works too)")
            .clicked()
        {
            self.start(purpose, path);
        }
        if self.open() {
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
        }
    }
}
