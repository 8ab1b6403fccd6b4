//! Sharded imports from the workstation: plan one for a cluster (the manifest, and the command
//! that submits it), follow its shards as their partial stores appear in the parts folder, and
//! merge them into a store with a progress bar and a cancel button. The shards run on the
//! cluster (Slurm or any array scheduler, `docs/sharded-import.md`), not in the window; a merge
//! of some shards is valid and a later one adds the rest.

use crate::gui::GuiError;
use crate::gui::Within;
use std::path::{Path, PathBuf};
use std::sync::Arc;
use std::thread::JoinHandle;

use crate::project::Project;
use crate::slurm::part_path;
use crate::store::lattice::Transform;
use crate::store::merge::{MergeOptions, merge};
use crate::store::shard::{Manifest, part_is_done, plan};
use crate::store::{ImportOptions, ImportWatch, LevelChoice, Resampling, Store, VerticalDatum};

/// What the panel asks of the window.
#[derive(Debug, PartialEq)]
pub enum ClusterAction {
    /// Nothing.
    None,
    /// Add the merged dataset of this store as a layer (the "add a dataset" form, filled in).
    AddStore {
        /// The store.
        store: PathBuf,
        /// The dataset in it.
        dataset: String,
    },
}

/// The form, the loaded plan and the job in flight.
#[derive(Default)]
pub struct ClusterImport {
    /// The raster to plan an import of.
    pub source: String,
    /// How many shards to cut it into.
    pub shards: String,
    /// The plan's file (written by "write plan", read by "open plan").
    pub manifest: String,
    /// Where the shards publish their partial stores (`part-NNNN.gpkg`).
    pub parts: String,
    /// The store the parts merge into.
    pub store: String,
    plan: Option<Manifest>,
    /// Per shard of the plan, whether its part is published and complete.
    done: Vec<bool>,
    /// The merged store and dataset, when the store holds the plan's dataset complete.
    merged: Option<(PathBuf, String)>,
    /// The last outcome, in words.
    pub message: String,
    job: Option<Job>,
}

enum Kind {
    Plan,
    Merge,
}

struct Job {
    kind: Kind,
    watch: Arc<ImportWatch>,
    handle: JoinHandle<Result<String, GuiError>>,
}

impl ClusterImport {
    /// Whether a plan or a merge is running.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// The loaded plan.
    pub fn plan(&self) -> Option<&Manifest> {
        self.plan.as_ref()
    }

    /// Per shard of the loaded plan, whether its part is done (as of the last refresh).
    pub fn shards_done(&self) -> &[bool] {
        &self.done
    }

    /// Starts writing a plan of the source's import on the project's body (a thread: it scans
    /// the source's footprint).
    pub fn start_plan(&mut self, project: &Project) -> Result<(), GuiError> {
        if self.job.is_some() {
            return Err("a plan or a merge is running already".into());
        }
        let source = self.source.trim();
        if source.is_empty() {
            return Err("source: give the raster to import".into());
        }
        let source = std::fs::canonicalize(source).within(format_args!("source: {source}"))?;
        let shards: usize = self
            .shards
            .trim()
            .parse()
            .map_err(|_| GuiError::Message(format!("shards: '{}' is not a whole number", self.shards.trim())))?;
        if self.manifest.trim().is_empty() {
            let stem = source.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
            self.manifest = project.resolve(Path::new(&format!("plans/{stem}.json"))).display().to_string();
        }
        let manifest = PathBuf::from(self.manifest.trim());
        if let Some(dir) = manifest.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(GuiError::file(dir, "cannot create the plan's folder"))?;
        }
        let opts = ImportOptions {
            sources: vec![source],
            store: manifest.clone(),
            body: project.ellipsoid()?,
            name: None,
            level: LevelChoice::Auto,
            resampling: Resampling::Bilinear,
            transform: Transform::Lattice,
            vertical: VerticalDatum::Ellipsoidal,
            memory_budget: 1 << 30,
            threads: None,
            progress: false,
            watch: None,
            finest_only: false,
        };
        let handle = std::thread::Builder::new()
            .name("terrafuse-plan".into())
            .spawn(move || {
                let r = plan(&opts, &manifest, shards)?;
                Ok(format!(
                    "wrote plan {}: {} shards of dataset {} at level {}",
                    &r.manifest.hash[..12],
                    r.manifest.shards.len(),
                    r.manifest.import.dataset,
                    r.manifest.import.level
                ))
            })
            .within("cannot start the plan")?;
        self.job = Some(Job { kind: Kind::Plan, watch: Arc::new(ImportWatch::default()), handle });
        Ok(())
    }

    /// Reads the plan named in the form, fills in the parts folder and the store beside it
    /// where they are empty, and looks which shards are done.
    pub fn open_plan(&mut self) -> Result<(), GuiError> {
        let path = PathBuf::from(self.manifest.trim());
        let m = Manifest::load(&path)?;
        let dir = path.parent().map(Path::to_path_buf).unwrap_or_default();
        if self.parts.trim().is_empty() {
            self.parts = dir.join("parts").display().to_string();
        }
        if self.store.trim().is_empty() {
            self.store = dir.join(format!("{}.gpkg", m.import.dataset)).display().to_string();
        }
        self.plan = Some(m);
        self.refresh();
        Ok(())
    }

    /// Looks again which shards' parts are published and complete, and whether the store holds
    /// the plan's dataset complete.
    pub fn refresh(&mut self) {
        let parts = PathBuf::from(self.parts.trim());
        self.done = match &self.plan {
            Some(m) => (0..m.shards.len()).map(|i| part_is_done(&part_path(&parts, i), m, i)).collect(),
            None => Vec::new(),
        };
        self.merged = self.plan.as_ref().and_then(|m| {
            let store = PathBuf::from(self.store.trim());
            let s = Store::open_read_only(&store).ok()?;
            let d = s.dataset(&m.import.dataset).ok()??;
            d.completed.is_some().then(|| (store, m.import.dataset.clone()))
        });
    }

    /// The store and dataset a complete merge made (as of the last refresh).
    pub fn merged(&self) -> Option<&(PathBuf, String)> {
        self.merged.as_ref()
    }

    /// The command that submits the plan's missing shards and the merge on Slurm.
    pub fn submit_command(&self) -> String {
        let q = |s: &str| crate::slurm::shell_quote(s.trim());
        format!(
            "terrafuse slurm submit --manifest {} --parts {} --store {}",
            q(&self.manifest),
            q(&self.parts),
            q(&self.store)
        )
    }

    /// Starts merging the parts that are done into the store (a thread, with progress and
    /// cancel).
    pub fn start_merge(&mut self) -> Result<(), GuiError> {
        if self.job.is_some() {
            return Err("a plan or a merge is running already".into());
        }
        let parts_dir = PathBuf::from(self.parts.trim());
        let parts: Vec<PathBuf> =
            self.done.iter().enumerate().filter(|(_, d)| **d).map(|(i, _)| part_path(&parts_dir, i)).collect();
        if parts.is_empty() {
            return Err(format!("parts: no finished shard in {}", parts_dir.display()).into());
        }
        let store = PathBuf::from(self.store.trim());
        if store.as_os_str().is_empty() {
            return Err("store: give the store to merge into".into());
        }
        let watch = Arc::new(ImportWatch::default());
        let opts = MergeOptions { store, parts, threads: None, progress: false, watch: Some(watch.clone()) };
        let handle = std::thread::Builder::new()
            .name("terrafuse-merge".into())
            .spawn(move || {
                let r = merge(&opts)?;
                let merged: u64 = r.merged.iter().map(|(_, t)| t).sum();
                Ok(if r.complete {
                    format!(
                        "merged {} shards ({merged} tiles): {} complete, all {} shards in",
                        r.merged.len(),
                        r.dataset,
                        r.shards
                    )
                } else {
                    format!(
                        "merged {} shards ({merged} tiles): {} INCOMPLETE, {} of {} shards missing",
                        r.merged.len(),
                        r.dataset,
                        r.missing.len(),
                        r.shards
                    )
                })
            })
            .within("cannot start the merge")?;
        self.job = Some(Job { kind: Kind::Merge, watch, handle });
        Ok(())
    }

    /// The finished job's outcome, once; a finished plan is opened.
    pub fn poll(&mut self) -> Option<Result<String, GuiError>> {
        if !self.job.as_ref()?.handle.is_finished() {
            return None;
        }
        let job = self.job.take()?;
        let result = job.handle.join().unwrap_or_else(|_| Err("the job failed unexpectedly".into()));
        let result = match (job.kind, result) {
            (Kind::Plan, Ok(m)) => self.open_plan().map(|()| m),
            (Kind::Merge, r) => {
                self.refresh();
                r
            }
            (_, r) => r,
        };
        self.message = match &result {
            Ok(m) => m.clone(),
            Err(e) => e.to_string(),
        };
        Some(result)
    }

    /// The panel.
    pub fn ui(&mut self, ui: &mut egui::Ui, project: &Project) -> ClusterAction {
        let mut action = ClusterAction::None;
        ui.collapsing("cluster import", |ui| {
            if let Some(job) = &self.job {
                let p = job.watch.progress();
                let text = match job.kind {
                    Kind::Plan => "planning: checking the source, listing quads…".to_string(),
                    Kind::Merge if p.phase.is_empty() => "merging…".to_string(),
                    Kind::Merge => format!("merging: {} {}/{} tiles", p.phase, p.done, p.total),
                };
                let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
                ui.horizontal(|ui| {
                    ui.add(egui::ProgressBar::new(fraction).text(text).desired_width(220.0));
                    if matches!(job.kind, Kind::Merge) {
                        if job.watch.is_cancelled() {
                            ui.label("cancelling…");
                        } else if ui
                            .button("cancel merge")
                            .on_hover_text("what is merged stays; merge again later")
                            .clicked()
                        {
                            job.watch.cancel();
                        }
                    }
                });
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
                let _ = self.poll();
                return;
            }
            use super::widgets::field;
            field(ui, "source", &mut self.source, "raster to import (.tif, …)");
            field(ui, "shards", &mut self.shards, "e.g. 64");
            field(ui, "plan file", &mut self.manifest, "default: plans/<source>.json");
            ui.horizontal(|ui| {
                if ui.button("write plan").on_hover_text("check the source and cut its quads into shards").clicked()
                    && let Err(e) = self.start_plan(project)
                {
                    self.message = e.to_string();
                }
                if ui.button("open plan").on_hover_text("read the plan file and look at its shards").clicked()
                    && let Err(e) = self.open_plan()
                {
                    self.message = e.to_string();
                }
            });
            field(ui, "parts", &mut self.parts, "folder of part-NNNN.gpkg");
            field(ui, "merged store", &mut self.store, "store to merge into (.gpkg)");
            if let Some(m) = &self.plan {
                let done = self.done.iter().filter(|d| **d).count();
                ui.label(format!(
                    "plan {}: {} at level {}, {done} of {} shards done",
                    &m.hash[..12],
                    m.import.dataset,
                    m.import.level,
                    m.shards.len()
                ));
                super::widgets::shard_squares(ui, &self.done);
                let command = self.submit_command();
                ui.horizontal(|ui| {
                    ui.label("on the cluster:");
                    if ui.button("copy").on_hover_text("copy the command that submits the missing shards").clicked() {
                        ui.ctx().copy_text(command.clone());
                    }
                });
                ui.add(egui::Label::new(egui::RichText::new(&command).monospace().small()).wrap());
                ui.horizontal(|ui| {
                    if ui.button("refresh").on_hover_text("look again which parts are done").clicked() {
                        self.refresh();
                    }
                    if ui
                        .add_enabled(done > 0, egui::Button::new(format!("merge {done} parts")))
                        .on_hover_text("merge the finished parts; the pyramid is built once all are in")
                        .clicked()
                        && let Err(e) = self.start_merge()
                    {
                        self.message = e.to_string();
                    }
                });
                if let Some((store, dataset)) = &self.merged
                    && ui.button("add merged dataset").on_hover_text("put the merged dataset on the stack").clicked()
                {
                    action = ClusterAction::AddStore { store: store.clone(), dataset: dataset.clone() };
                }
            }
            if !self.message.is_empty() {
                ui.add(egui::Label::new(egui::RichText::new(&self.message).small()).wrap());
            }
        });
        action
    }
}
