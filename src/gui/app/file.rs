//! The project as a file: new, open, save, save as and recent projects in a bar above the
//! viewport; the window's title (the project, and `*` while it has unsaved changes); autosave
//! of unsaved changes to the recovery file ([`crate::project::recovery`]) and, when a project
//! opens with a recovery file newer than it, the offer to restore it.

use crate::gui::GuiError;
use crate::gui::Within;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::App;
use crate::gpu::{Editor, IMAGE_FORMAT, Renderer};
use crate::gui::recent::Recent;
use crate::project::recovery::{self, Recovery};
use crate::project::{CameraSpec, Project};
use crate::scene::Scene;

/// Unsaved changes are written to the recovery file at most this often (the first at once).
pub const AUTOSAVE_INTERVAL: Duration = Duration::from_secs(10);

/// A dialog of the file bar.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Dialog {
    /// A new, empty project on a body, written to a path.
    New { path: String, body: String },
    /// Open a project file.
    Open { path: String },
    /// Save the project under another name (relative paths rewritten).
    SaveAs { path: String },
}

/// A project opened on a worker thread (stores opened, datasets imported), for the window to
/// take over.
pub(super) struct Opening {
    project: Project,
    path: PathBuf,
    scene: Scene,
    camera: CameraSpec,
    /// Restored from this recovery file (the project then has unsaved changes).
    restored: Option<PathBuf>,
    imported: Vec<String>,
    /// What the project file held as it was read.
    on_disk: Option<crate::project::editing::OnDisk>,
}

/// The file bar's state.
#[derive(Default)]
pub(super) struct FileState {
    pub recent: Recent,
    pub dialog: Option<Dialog>,
    pub opening: Option<std::thread::JoinHandle<Result<Opening, GuiError>>>,
    /// A recovery file to offer restoring.
    pub recovery: Option<Recovery>,
    /// Changes made since the window opened, and how many the recovery file holds.
    pub changes: u64,
    pub autosaved: u64,
    pub last_autosave: Option<Instant>,
    /// The title last given to the window.
    pub title: String,
    /// The desktop's file dialog for the open dialog's path.
    pub pick: crate::gui::file_pick::FilePick,
}

/// The camera a project opens at: its default view, or the whole body from straight above.
pub(crate) fn opening_camera(project: &Project) -> CameraSpec {
    project.view(None).unwrap_or_else(|_| {
        let a = project.ellipsoid().map_or(6.4e6, |e| e.a_m());
        CameraSpec { lat: 20.0, lon: 0.0, alt: 2.5 * a, heading: 0.0, pitch: -90.0, fov: 45.0 }
    })
}

impl App {
    /// Records a change the project file does not have yet.
    pub(super) fn mark_unsaved(&mut self) {
        self.unsaved = true;
        self.file.changes += 1;
    }

    /// The window's title: the project's file name and folder, `*` first while unsaved.
    pub fn title(&self) -> String {
        let name = self.project_path.file_name().map_or_else(|| "project".into(), |n| n.to_string_lossy().into_owned());
        let dir = crate::files::folder_of(&self.project_path);
        format!("{}{name} — {} — Terrafuse", if self.unsaved { "*" } else { "" }, dir.display())
    }

    /// The project file the window edits.
    pub fn project_path(&self) -> &Path {
        &self.project_path
    }

    /// The recent projects, most recent first.
    pub fn recent(&self) -> &[PathBuf] {
        &self.file.recent.projects
    }

    /// A recovery file the window offers to restore, if any.
    pub fn recovery_offered(&self) -> Option<&Recovery> {
        self.file.recovery.as_ref()
    }

    /// Whether a project is being opened.
    pub fn opening(&self) -> bool {
        self.file.opening.is_some()
    }

    /// Starts opening `path` (or, with `restored`, the recovery file of the project at `path`)
    /// on a worker thread; the window takes it over once its stores are open.
    pub fn open_project(&mut self, path: &Path, restored: Option<PathBuf>) {
        let path = path.to_path_buf();
        self.message = format!("opening {}…", path.display());
        self.file.dialog = None;
        self.file.opening = Some(std::thread::spawn(move || {
            // What the project file holds as it is read (not the recovery file's): the window
            // saves only while the file still holds it.
            let (mut project, on_disk) = match &restored {
                Some(r) => (Project::load(r)?, crate::project::editing::OnDisk::read(&path)),
                None => {
                    let (project, seen) = Project::load_seen(&path)?;
                    (project, Some(seen))
                }
            };
            project.base_dir = crate::files::folder_of(&path).into();
            let (scene, report) = Scene::open(&project).within(path.display())?;
            let camera = opening_camera(&project);
            Ok(Opening { project, path, scene, camera, restored, imported: report.imported, on_disk })
        }));
    }

    /// Takes over a project opened on the worker thread: a new renderer on this device, every
    /// panel reset, the recent list kept.
    pub(super) fn finish_open(&mut self, frame: &eframe::Frame) {
        if !self.file.opening.as_ref().is_some_and(|h| h.is_finished()) {
            return;
        }
        let handle = self.file.opening.take().expect("checked above");
        let opened = match handle.join() {
            Ok(Ok(o)) => o,
            Ok(Err(e)) => {
                self.message = e.to_string();
                return;
            }
            Err(_) => {
                self.message = "opening the project failed (the worker stopped)".into();
                return;
            }
        };
        let Some(rs) = frame.wgpu_render_state() else {
            self.message = "no wgpu device to draw the project with".into();
            return;
        };
        let ctx = crate::gui::context_of(rs);
        let made = Renderer::new(&ctx, opened.scene, IMAGE_FORMAT).and_then(|r| Ok((r, Editor::new(&ctx)?)));
        let (renderer, editor) = match made {
            Ok(r) => r,
            Err(e) => {
                self.message = format!("{}: {}", opened.path.display(), crate::errors::chain(&e));
                return;
            }
        };
        let mut recent = std::mem::take(&mut self.file.recent);
        if let Err(e) = recent.add(&opened.path) {
            self.message = format!("the recent list was not kept: {}", crate::errors::chain(&e));
        }
        let camera = self.disk.reload_camera.take().unwrap_or(opened.camera);
        let next = App::new(
            opened.project,
            opened.path.clone(),
            (renderer, editor),
            camera,
            None,
            self.outcome.clone(),
            self.device.clone(),
        )
        .with_disk(opened.on_disk);
        *self = next;
        self.file.recent = recent;
        self.message = match &opened.restored {
            Some(r) => {
                self.mark_unsaved();
                format!("restored the unsaved changes from {}: save to keep them", r.display())
            }
            None => format!("opened {}", opened.path.display()),
        };
        if !opened.imported.is_empty() {
            self.message += &format!(" ({})", opened.imported.join("; "));
        }
        if opened.restored.is_none() {
            self.file.recovery = recovery::find(&self.project_path);
        }
    }

    /// Saves the project under `path`: relative paths rewritten to reach the same files from its
    /// folder; the window then edits the new file.
    pub fn save_as(&mut self, path: &Path) {
        let dir = crate::files::folder_of(path);
        let (old_path, old_project, old_disk) = (self.project_path.clone(), self.project.clone(), self.disk.on_disk);
        self.project.rebase(dir);
        self.project_path = path.to_path_buf();
        // The user chose this file: what it holds now may be written over.
        self.disk.on_disk = crate::project::editing::OnDisk::read(path);
        self.save_project();
        if self.unsaved {
            // Not written: the message says why; keep editing the old file.
            (self.project_path, self.project) = (old_path, old_project);
            self.remember_disk(old_disk);
            return;
        }
        recovery::remove(&old_path);
        if let Err(e) = self.file.recent.add(path) {
            self.message += &format!(" (the recent list was not kept: {})", crate::errors::chain(&e));
        }
    }

    /// A new project on `body` written to `path` (never over an existing file), then opened.
    pub fn new_project(&mut self, path: &Path, body: &str) {
        if path.exists() {
            self.message = format!("{} exists: choose another name (open it to edit it)", path.display());
            return;
        }
        let mut project = Project::new(body);
        match project.ellipsoid() {
            Ok(e) => {
                let globe =
                    CameraSpec { lat: 20.0, lon: 0.0, alt: 2.5 * e.a_m(), heading: 0.0, pitch: -90.0, fov: 45.0 };
                project.views.insert("globe".into(), globe);
            }
            Err(e) => {
                self.message = e.to_string();
                return;
            }
        }
        match project.save(path) {
            Ok(()) => self.open_project(path, None),
            Err(e) => self.message = e.to_string(),
        }
    }

    /// Writes unsaved changes to the recovery file: at once after the first change, then at
    /// most every [`AUTOSAVE_INTERVAL`].
    pub(super) fn autosave(&mut self) {
        if !self.unsaved || self.file.changes == self.file.autosaved || self.screenshot.is_some() {
            return;
        }
        if self.file.last_autosave.is_some_and(|t| t.elapsed() < AUTOSAVE_INTERVAL) {
            return;
        }
        self.sync_project();
        // Two windows on one project share its recovery file: one writes it at a time (the other
        // tries again at its next autosave).
        let target = recovery::path_of(&self.project_path);
        let Ok(_lock) =
            crate::files::lock::Lock::acquire(&target, "terrafuse view (autosave)", Duration::ZERO, &mut |_| {})
        else {
            return;
        };
        match recovery::write(&self.project, &self.project_path) {
            Ok(_) => self.file.autosaved = self.file.changes,
            Err(e) => self.message = format!("autosave failed: {}", crate::errors::chain(&e)),
        }
        self.file.last_autosave = Some(Instant::now());
    }

    /// Keeps the window's title in step with the project and its unsaved changes.
    pub(super) fn update_title(&mut self, ctx: &egui::Context) {
        let title = self.title();
        if title != self.file.title {
            ctx.send_viewport_cmd(egui::ViewportCommand::Title(title.clone()));
            self.file.title = title;
        }
    }

    /// The file bar: new, open, save, save as, recent projects.
    pub(super) fn file_bar(&mut self, ui: &mut egui::Ui) {
        ui.horizontal(|ui| {
            let busy = self.file.opening.is_some();
            if ui.add_enabled(!busy, egui::Button::new("new…")).clicked() {
                let path = self.project_path.with_file_name("untitled.json");
                self.file.dialog =
                    Some(Dialog::New { path: path.display().to_string(), body: self.project.body.clone() });
            }
            if ui.add_enabled(!busy, egui::Button::new("open…")).clicked() {
                self.file.dialog = Some(Dialog::Open { path: self.project_path.display().to_string() });
            }
            let label = if self.unsaved { "save project *" } else { "save project" };
            let save = ui
                .add_enabled(!busy, egui::Button::new(label))
                .on_hover_text("writes the layers, their edits, the views and the visual settings (Ctrl+S)");
            if save.clicked() || ui.input_mut(|i| i.consume_key(egui::Modifiers::COMMAND, egui::Key::S)) {
                self.save_project();
            }
            if ui.add_enabled(!busy, egui::Button::new("save as…")).clicked() {
                self.file.dialog = Some(Dialog::SaveAs { path: self.project_path.display().to_string() });
            }
            let mut chosen = None;
            ui.add_enabled_ui(!busy && !self.file.recent.projects.is_empty(), |ui| {
                ui.menu_button("recent", |ui| {
                    for p in &self.file.recent.projects {
                        if ui.add_enabled(p.is_file(), egui::Button::new(p.display().to_string())).clicked() {
                            chosen = Some(p.clone());
                        }
                    }
                });
            });
            if let Some(p) = chosen {
                self.open_project(&p, None);
            }
            ui.separator();
            ui.label(self.title().trim_end_matches(" — Terrafuse").to_string());
        });
    }

    /// The file bar's dialogs and the recovery offer.
    pub(super) fn file_dialogs(&mut self, ctx: &egui::Context) {
        if self.screenshot.is_some() {
            return;
        }
        if let Some(r) = self.file.recovery.clone() {
            let mut choice = None;
            egui::Modal::new(egui::Id::unique("recovery")).show(ctx, |ui| {
                ui.label(format!(
                    "{} has unsaved changes from an earlier session, kept in {}.",
                    self.project_path.display(),
                    r.path.display()
                ));
                ui.horizontal(|ui| {
                    if ui.button("restore them").clicked() {
                        choice = Some(1);
                    }
                    if ui.button("discard them").clicked() {
                        choice = Some(2);
                    }
                    if ui.button("decide later").clicked() {
                        choice = Some(3);
                    }
                });
            });
            match choice {
                Some(1) => {
                    self.file.recovery = None;
                    let path = self.project_path.clone();
                    self.open_project(&path, Some(r.path));
                }
                Some(2) => {
                    recovery::remove(&self.project_path);
                    self.file.recovery = None;
                }
                Some(_) => self.file.recovery = None,
                None => {}
            }
            return;
        }
        let Some(mut dialog) = self.file.dialog.take() else {
            return;
        };
        let mut go = false;
        let mut cancel = false;
        egui::Modal::new(egui::Id::unique("file-dialog")).show(ctx, |ui| {
            let (title, path) = match &mut dialog {
                Dialog::New { path, body } => {
                    ui.horizontal(|ui| {
                        let label = ui.label("body").id;
                        egui::ComboBox::from_id_salt("new-body").selected_text(body.as_str()).show_ui(ui, |ui| {
                            for b in ["moon", "wgs84", "mars"] {
                                ui.selectable_value(body, b.to_string(), b);
                            }
                        });
                        let _ = label;
                    });
                    ("New project: its file", path)
                }
                Dialog::Open { path } => ("Open the project file", path),
                Dialog::SaveAs { path } => ("Save the project as", path),
            };
            let label = ui.label(title).id;
            let purpose = if title.starts_with("Open") {
                crate::gui::file_pick::Purpose::OpenProject
            } else {
                crate::gui::file_pick::Purpose::SaveProject
            };
            ui.horizontal(|ui| {
                let edit = ui.add(egui::TextEdit::singleline(path).desired_width(420.0)).labelled_by(label);
                if edit.lost_focus() && ui.input(|i| i.key_pressed(egui::Key::Enter)) {
                    go = true;
                }
                self.file.pick.button(ui, purpose, path);
            });
            ui.horizontal(|ui| {
                go |= ui.button("ok").clicked();
                cancel = ui.button("cancel").clicked();
            });
        });
        if cancel {
            return;
        }
        if !go {
            self.file.dialog = Some(dialog);
            return;
        }
        match dialog {
            Dialog::New { path, body } => self.new_project(Path::new(path.trim()), &body),
            Dialog::Open { path } => {
                let path = PathBuf::from(path.trim());
                match Project::load(&path) {
                    // Checked here, so that a bad file is named at once and nothing is replaced.
                    Ok(_) => self.open_project(&path, None),
                    Err(e) => self.message = e.to_string(),
                }
            }
            Dialog::SaveAs { path } => self.save_as(Path::new(path.trim())),
        }
    }
}
