//! *Export GeoTIFF* (the Project tab): the composed stack, or a terrain attribute of it, written
//! as a GeoTIFF or a Cloud-Optimized GeoTIFF on a longitude-latitude grid of the body
//! (`crate::export`), off the interface thread with a progress bar and a cancel; or, too large
//! for the window, its plan for a cluster (`export … --plan`): the `terrafuse slurm submit` line
//! to copy, the shards done, and *merge* with a progress bar (`docs/shards.md`).

use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::attributes::Attribute;
use crate::export::sharded::{ExportPlan, Merged, merge, missing, plan};
use crate::export::{ComposeOn, ComposedExport, export_composed_watched};
use crate::gui::GuiError;
use crate::progress::Watch;

/// The form and the job in flight.
#[derive(Default)]
pub struct ExportPanel {
    /// The GeoTIFF to write.
    pub out: String,
    /// WEST,SOUTH,EAST,NORTH, degrees.
    pub bounds: String,
    /// Pixel size, degrees.
    pub resolution: String,
    /// A terrain attribute instead of the heights (None: heights).
    pub attribute: Option<Attribute>,
    /// Write a Cloud-Optimized GeoTIFF.
    pub cog: bool,
    /// Shards of a plan for a cluster.
    pub shards: String,
    plan: Option<(PathBuf, ExportPlan)>,
    /// Per shard of the plan, whether its part is in (as of the last look).
    done: Vec<bool>,
    /// The last outcome, in words.
    pub message: String,
    job: Option<Job>,
}

struct Job {
    what: &'static str,
    watch: Arc<Watch>,
    handle: JoinHandle<Result<String, GuiError>>,
}

impl ExportPanel {
    /// Whether an export, a plan or a merge runs.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// The loaded plan and which of its shards are done.
    pub fn plan(&self) -> Option<(&ExportPlan, &[bool])> {
        self.plan.as_ref().map(|(_, p)| (p, self.done.as_slice()))
    }

    /// Fills the empty fields: the output beside the project, a box of 2° about `centre`
    /// (lon, lat), 0.01° pixels, 4 shards.
    fn defaults(&mut self, project_path: &Path, centre: (f64, f64)) {
        if self.out.trim().is_empty() {
            let stem = project_path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            let dir = project_path.parent().unwrap_or(Path::new("."));
            self.out = dir.join("exports").join(format!("{stem}.tif")).display().to_string();
        }
        if self.bounds.trim().is_empty() {
            let (lon, lat) = centre;
            let (s, n) = ((lat - 1.0).max(-90.0), (lat + 1.0).min(90.0));
            self.bounds = format!("{:.3},{s:.3},{:.3},{n:.3}", lon - 1.0, lon + 1.0);
        }
        if self.resolution.trim().is_empty() {
            self.resolution = "0.01".into();
        }
        if self.shards.trim().is_empty() {
            self.shards = "4".into();
        }
    }

    /// The export the form asks for, on the body's longitude-latitude grid.
    fn request(&self, project_path: &Path, body: &crate::geodesy::Ellipsoid) -> Result<ComposedExport, GuiError> {
        let numbers: Vec<f64> = self.bounds.split(',').filter_map(|v| v.trim().parse().ok()).collect();
        let [w, s, e, n] = numbers[..] else {
            return Err(format!("bounds: '{}' is not WEST,SOUTH,EAST,NORTH in degrees", self.bounds.trim()).into());
        };
        let r: f64 = self.resolution.trim().parse().ok().filter(|r: &f64| *r > 0.0).ok_or_else(|| {
            GuiError::Message(format!("resolution: '{}' is not a pixel size in degrees", self.resolution.trim()))
        })?;
        let out = PathBuf::from(self.out.trim());
        if let Some(dir) = out.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(GuiError::file(dir, "cannot create the output's folder"))?;
        }
        Ok(ComposedExport {
            project: project_path.to_path_buf(),
            out,
            crs: format!("+proj=longlat +a={} +b={} +no_defs", body.a_m(), body.b_m()),
            bounds: [w, s, e, n],
            resolution: (r, r),
            level: None,
            compose_on: ComposeOn::Cpu,
            difference: None,
            attribute: self.attribute,
            layer: None,
            cog: self.cog,
        })
    }

    fn start(&mut self, what: &'static str, work: impl FnOnce(&Watch) -> Result<String, GuiError> + Send + 'static) {
        let watch = Arc::new(Watch::default());
        let w = watch.clone();
        let handle = crate::gui::background::spawn("export", move || work(&w));
        self.job = Some(Job { what, watch, handle });
    }

    /// Starts the export (saved project as on disk: save first).
    pub fn start_export(&mut self, project_path: &Path, body: &crate::geodesy::Ellipsoid) -> Result<(), GuiError> {
        let opts = self.request(project_path, body)?;
        self.start("exporting", move |watch| {
            let r = export_composed_watched(&opts, watch).map_err(|e| GuiError::Message(crate::errors::chain(&e)))?;
            Ok(format!(
                "wrote {} ({}×{} pixels, level {}, {} pixels with data)",
                opts.out.display(),
                r.size.0,
                r.size.1,
                r.level,
                r.valid
            ))
        });
        Ok(())
    }

    /// Writes the plan for a cluster beside the output (`OUT.plan.json`, parts in
    /// `OUT.plan.parts`).
    pub fn start_plan(&mut self, project_path: &Path, body: &crate::geodesy::Ellipsoid) -> Result<(), GuiError> {
        let opts = self.request(project_path, body)?;
        let shards: usize = self
            .shards
            .trim()
            .parse()
            .map_err(|_| GuiError::Message(format!("shards: '{}' is not a whole number", self.shards.trim())))?;
        let path = opts.out.with_extension("plan.json");
        self.plan = None;
        self.start("planning", move |_| {
            let made = plan(&opts, shards, &path, None).map_err(|e| GuiError::Message(crate::errors::chain(&e)))?;
            Ok(format!(
                "wrote plan {}: {} rows in {} shards, to {}",
                &made.hash[..12],
                made.size[1],
                made.shards.len(),
                path.display()
            ))
        });
        Ok(())
    }

    /// Looks which shards' parts are in.
    pub fn refresh(&mut self) -> Result<(), GuiError> {
        let out = PathBuf::from(self.out.trim());
        let path = out.with_extension("plan.json");
        let plan_error = |e: crate::plan::PlanError| GuiError::Message(e.to_string());
        let loaded = ExportPlan::load(&path).map_err(plan_error)?;
        let missing = missing(&loaded).map_err(plan_error)?;
        self.done = (0..loaded.shards.len()).map(|i| !missing.contains(&i)).collect();
        self.plan = Some((path, loaded));
        Ok(())
    }

    /// Starts the merge of a complete plan's parts into its output.
    pub fn start_merge(&mut self) {
        let Some((path, _)) = self.plan.clone() else { return };
        self.start("merging", move |watch| {
            match merge(&path, watch).map_err(|e| GuiError::Message(crate::errors::chain(&e)))? {
                Merged::Done(r) => Ok(format!("merged: {}×{} pixels, {} with data", r.size.0, r.size.1, r.valid)),
                Merged::Pending(shards) => Ok(format!("{} shards still to run", shards.len())),
            }
        });
    }

    fn poll(&mut self) {
        if !self.job.as_ref().is_some_and(|j| j.handle.is_finished()) {
            return;
        }
        let Some(job) = self.job.take() else { return };
        let result = job.handle.join().unwrap_or_else(|_| Err("the export failed unexpectedly".into()));
        self.message = match result {
            Ok(m) => m,
            Err(e) => e.to_string(),
        };
        if matches!(job.what, "planning" | "merging") {
            let _ = self.refresh();
        }
    }

    /// The section, for the project at `project_path` (as saved) on `body`, the view at `centre`
    /// (lon, lat, degrees).
    pub fn ui(&mut self, ui: &mut egui::Ui, project_path: &Path, body: &crate::geodesy::Ellipsoid, centre: (f64, f64)) {
        self.poll();
        ui.collapsing("export GeoTIFF", |ui| {
            if let Some(job) = &self.job {
                let p = job.watch.progress();
                let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
                ui.horizontal(|ui| {
                    let text = format!("{}: {} of {} rows", job.what, p.done, p.total);
                    ui.add(egui::ProgressBar::new(fraction).text(text).desired_width(220.0));
                    if ui.button("cancel").clicked() {
                        job.watch.cancel();
                    }
                });
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
                return;
            }
            self.defaults(project_path, centre);
            use super::widgets::field;
            field(ui, "output", &mut self.out, "GeoTIFF to write");
            field(ui, "bounds", &mut self.bounds, "WEST,SOUTH,EAST,NORTH degrees");
            field(ui, "pixel size", &mut self.resolution, "degrees");
            ui.horizontal(|ui| {
                egui::ComboBox::from_label("values")
                    .selected_text(self.attribute.map_or("heights", Attribute::name))
                    .show_ui(ui, |ui| {
                        ui.selectable_value(&mut self.attribute, None, "heights");
                        for a in Attribute::ALL {
                            ui.selectable_value(&mut self.attribute, Some(a), a.name());
                        }
                    });
                ui.checkbox(&mut self.cog, "Cloud-Optimized");
            });
            ui.horizontal(|ui| {
                if ui.button("export").on_hover_text("the saved project's visible stack, composed on the CPU").clicked()
                    && let Err(e) = self.start_export(project_path, body)
                {
                    self.message = e.to_string();
                }
                let l = ui.label("shards");
                ui.add(egui::TextEdit::singleline(&mut self.shards).desired_width(40.0)).labelled_by(l.id);
                if ui
                    .button("write plan")
                    .on_hover_text("too large for the window: cut its rows into shards for a cluster")
                    .clicked()
                    && let Err(e) = self.start_plan(project_path, body)
                {
                    self.message = e.to_string();
                }
            });
            if let Some((path, p)) = &self.plan {
                let n = self.done.iter().filter(|d| **d).count();
                ui.label(format!("plan {}: {n} of {} shards done", &p.hash[..12], p.shards.len()));
                super::widgets::shard_squares(ui, &self.done);
                let command = format!("terrafuse slurm submit {}", crate::slurm::shell_quote(&path.to_string_lossy()));
                ui.horizontal(|ui| {
                    ui.label("on the cluster:");
                    if ui.button("copy").clicked() {
                        ui.ctx().copy_text(command.clone());
                    }
                });
                ui.add(egui::Label::new(egui::RichText::new(&command).monospace().small()).wrap());
                let complete = n == self.done.len();
                ui.horizontal(|ui| {
                    if ui.button("refresh").on_hover_text("look again which parts are in").clicked()
                        && let Err(e) = self.refresh()
                    {
                        self.message = e.to_string();
                    }
                    if ui
                        .add_enabled(complete, egui::Button::new("merge"))
                        .on_hover_text("write the output from every part")
                        .clicked()
                    {
                        self.start_merge();
                    }
                });
            }
            if !self.message.is_empty() {
                ui.add(egui::Label::new(egui::RichText::new(&self.message).small()).wrap());
            }
        });
    }
}
