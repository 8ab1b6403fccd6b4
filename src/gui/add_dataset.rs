//! Adding a dataset layer from the workstation: from a store that holds the dataset, or from a
//! raster imported into a store beside the project (`stores/<name>.gpkg`), in the background with
//! a progress bar and a cancel button. The layer records its store and source, so the project
//! opens the same way from the command line; a cancelled import leaves a valid store that the
//! next attempt resumes.

use crate::gui::GuiError;
use crate::gui::Within;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::layers::{LayerSpec, SourceSpec};
use crate::project::Project;
use crate::scene::dataset::DatasetInfo;
use crate::scene::{import_needed, open_dataset};
use crate::store::ImportWatch;

/// A dataset opened and ready to go on the stack.
pub type Ready = (LayerSpec, DatasetInfo);

/// The form and the import in flight.
#[derive(Default)]
pub struct AddDataset {
    /// A raster (any GDAL format) or a store (`.gpkg`).
    pub path: String,
    /// The layer's name, and the dataset's in its store (default: the file's stem).
    pub name: String,
    /// The raster's vertical datum: ellipsoidal, egm96 or egm2008.
    pub vertical: String,
    job: Option<Job>,
    /// The desktop's file dialog for the path.
    pick: crate::gui::file_pick::FilePick,
}

struct Job {
    name: String,
    watch: Arc<ImportWatch>,
    handle: JoinHandle<Result<Ready, GuiError>>,
}

impl AddDataset {
    /// Whether an import or an opening is under way.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// Starts adding: checks the form, then imports (if needed) and opens on a thread.
    pub fn start(&mut self, project: &Project) -> Result<(), GuiError> {
        if self.job.is_some() {
            return Err("a dataset is being added already".into());
        }
        let spec = self.layer_spec(project)?;
        let watch = Arc::new(ImportWatch::default());
        let (project, thread_watch) = (project.clone(), watch.clone());
        let name = spec.name.clone();
        let handle = std::thread::Builder::new()
            .name("terrafuse-add-dataset".into())
            .spawn(move || {
                if let Some(mut opts) = import_needed(&project, &spec)? {
                    opts.watch = Some(thread_watch);
                    crate::store::import(&opts)?;
                }
                Ok((spec.clone(), open_dataset(&project, &spec)?))
            })
            .within("cannot start the import")?;
        self.job = Some(Job { name, watch, handle });
        Ok(())
    }

    /// Cancels the import in flight (it stops after the tiles in flight).
    pub fn cancel(&self) {
        if let Some(job) = &self.job {
            job.watch.cancel();
        }
    }

    /// The finished job's result, once (None while it runs or when there is none).
    pub fn poll(&mut self) -> Option<Result<Ready, GuiError>> {
        if !self.job.as_ref()?.handle.is_finished() {
            return None;
        }
        let job = self.job.take()?;
        Some(job.handle.join().unwrap_or_else(|_| Err(format!("adding '{}' failed unexpectedly", job.name).into())))
    }

    /// The layer the form describes: a store's dataset, or a raster's import into
    /// `stores/<name>.gpkg` beside the project. Paths inside the project's folder are kept
    /// relative to it.
    fn layer_spec(&self, project: &Project) -> Result<LayerSpec, GuiError> {
        let typed = self.path.trim();
        if typed.is_empty() {
            return Err("path: give a raster (GeoTIFF, …) or a store (.gpkg)".into());
        }
        let path = std::fs::canonicalize(typed).within(typed)?;
        let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
        let name = if self.name.trim().is_empty() { stem } else { self.name.trim().to_string() };
        if project.layers.iter().any(|l| l.name == name) {
            return Err(format!("name: '{name}' is used by another layer").into());
        }
        let base = project.resolve(Path::new("."));
        let relative = |p: &Path| -> PathBuf {
            let base = std::fs::canonicalize(&base).unwrap_or(base.clone());
            p.strip_prefix(&base).map_or_else(|_| p.to_path_buf(), Path::to_path_buf)
        };
        let is_store = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("gpkg"));
        if !is_store {
            crate::store::gpkg::check_dataset_name(&name).within("name")?;
        }
        let spec = if is_store {
            // The dataset's name in the store is the layer's, the default.
            LayerSpec::dataset(&name, relative(&path))
        } else {
            let vertical = match self.vertical.trim() {
                "" | "ellipsoidal" => None,
                v => Some(v.to_string()),
            };
            let source = SourceSpec { files: vec![relative(&path)], max_level: None, vertical_datum: vertical };
            let mut spec = LayerSpec::dataset(&name, format!("stores/{name}.gpkg"));
            if let Some(d) = spec.as_dataset_mut() {
                d.source = Some(source);
            }
            spec
        };
        spec.check(project.ellipsoid()?.a_m())?;
        Ok(spec)
    }

    /// The form, or the import's progress and its cancel button. Returns a finished result.
    pub fn ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<Result<Ready, GuiError>> {
        if let Some(job) = &self.job {
            let p = job.watch.progress();
            let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
            let text = if p.phase.is_empty() {
                format!("adding '{}'…", job.name)
            } else {
                format!("importing '{}': {} {}/{} tiles", job.name, p.phase, p.done, p.total)
            };
            ui.horizontal(|ui| {
                ui.add(egui::ProgressBar::new(fraction).text(text).desired_width(220.0));
                if job.watch.is_cancelled() {
                    ui.label("cancelling…");
                } else if ui.button("cancel").on_hover_text("stop the import; a later one resumes it").clicked() {
                    job.watch.cancel();
                }
            });
            ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
            return self.poll();
        }
        let mut started = None;
        ui.collapsing("add a dataset", |ui| {
            ui.horizontal(|ui| {
                let label = ui.label("file");
                ui.add(egui::TextEdit::singleline(&mut self.path).hint_text("raster (.tif, …) or store (.gpkg)"))
                    .labelled_by(label.id);
                self.pick.button(ui, crate::gui::file_pick::Purpose::Dataset, &mut self.path);
            });
            ui.horizontal(|ui| {
                let label = ui.label("name");
                ui.add(egui::TextEdit::singleline(&mut self.name).hint_text("default: the file's"))
                    .labelled_by(label.id);
            });
            egui::ComboBox::from_label("vertical datum")
                .selected_text(if self.vertical.is_empty() { "ellipsoidal" } else { self.vertical.as_str() })
                .show_ui(ui, |ui| {
                    for v in ["ellipsoidal", "egm96", "egm2008"] {
                        ui.selectable_value(&mut self.vertical, v.to_string(), v);
                    }
                });
            if ui
                .button("add dataset")
                .on_hover_text("import the raster (or open the store) and put it on top")
                .clicked()
            {
                started = Some(self.start(project));
            }
        });
        match started {
            Some(Err(e)) => Some(Err(e)),
            _ => None,
        }
    }
}
