//! A comparison too large for the window, from the workstation: write its plan for a cluster
//! (`compare … --plan`), copy the command that submits it, follow the pending round's shards as
//! their parts appear, and merge once every round is in: the statistics then show as a
//! comparison run in the window does. The shards run on the cluster (`docs/shards.md`), not here;
//! planning and merging run off the interface thread.

use std::path::{Path, PathBuf};
use std::thread::JoinHandle;

use crate::compare::sharded::{ComparePlan, Merged, merge, plan};
use crate::compare::{CompareOptions, Comparison};
use crate::gui::GuiError;

/// The form, the plan and where its rounds stand.
#[derive(Default)]
pub struct ClusterCompare {
    /// How many shards to cut the comparison into.
    pub shards: String,
    /// The level to compare (empty: the datasets' finest, as `compare` chooses).
    pub level: String,
    /// The plan's file.
    pub plan_file: String,
    plan: Option<ComparePlan>,
    /// The pending round and, per shard, whether its part of it is there.
    round: Option<(u32, Vec<bool>)>,
    /// The merged comparison.
    merged: Option<Comparison>,
    /// The last outcome, in words.
    pub message: String,
    job: Option<(&'static str, JoinHandle<Result<Outcome, GuiError>>)>,
}

enum Outcome {
    Planned(Box<ComparePlan>),
    Looked(Box<ComparePlan>, Merged),
}

impl ClusterCompare {
    /// Whether a plan or a look at the parts runs.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }

    /// The loaded plan.
    pub fn plan(&self) -> Option<&ComparePlan> {
        self.plan.as_ref()
    }

    /// The merged comparison, once every round is in.
    pub fn merged(&self) -> Option<&Comparison> {
        self.merged.as_ref()
    }

    /// The pending round and which of its shards are done (as of the last look).
    pub fn round(&self) -> Option<&(u32, Vec<bool>)> {
        self.round.as_ref()
    }

    /// Starts writing the plan of A − B of the project at `project_path` (a thread).
    pub fn start_plan(&mut self, project_path: &Path, a: &str, b: &str) -> Result<(), GuiError> {
        if self.job.is_some() {
            return Err("a plan or a merge is running already".into());
        }
        let shards: usize = self
            .shards
            .trim()
            .parse()
            .map_err(|_| GuiError::Message(format!("shards: '{}' is not a whole number", self.shards.trim())))?;
        let level = match self.level.trim() {
            "" => None,
            l => Some(l.parse::<u8>().map_err(|_| GuiError::Message(format!("level: '{l}' is not a level 0–30")))?),
        };
        if self.plan_file.trim().is_empty() {
            let dir = project_path.parent().unwrap_or(Path::new("."));
            self.plan_file = dir.join("plans").join(format!("compare-{a}-{b}.json")).display().to_string();
        }
        let plan_path = PathBuf::from(self.plan_file.trim());
        if let Some(dir) = plan_path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(GuiError::file(dir, "cannot create the plan's folder"))?;
        }
        let (project_path, a, b) = (project_path.to_path_buf(), a.to_owned(), b.to_owned());
        let handle = crate::gui::background::spawn("compare-plan", move || {
            let opts = CompareOptions { level, ..CompareOptions::default() };
            let made = plan(&project_path, [&a, &b], &opts, false, shards, &plan_path, None)?;
            Ok(Outcome::Planned(Box::new(made)))
        });
        self.job = Some(("planning: checking the layers, listing quads…", handle));
        Ok(())
    }

    /// Starts a look at the plan's parts (a thread): the pending round's shards, or, once every
    /// round is in, the merged comparison.
    pub fn start_look(&mut self) -> Result<(), GuiError> {
        if self.job.is_some() {
            return Err("a plan or a merge is running already".into());
        }
        let path = PathBuf::from(self.plan_file.trim());
        if path.as_os_str().is_empty() {
            return Err("plan file: give the plan to open".into());
        }
        let handle = crate::gui::background::spawn("compare-merge", move || {
            let loaded = ComparePlan::load(&path)?;
            let merged = merge(&path)?;
            Ok(Outcome::Looked(Box::new(loaded), merged))
        });
        self.job = Some(("reading the parts, merging…", handle));
        Ok(())
    }

    /// The finished job's outcome, once.
    pub fn poll(&mut self) -> Option<Result<(), GuiError>> {
        if !self.job.as_ref()?.1.is_finished() {
            return None;
        }
        let (_, handle) = self.job.take()?;
        let result = handle.join().unwrap_or_else(|_| Err("the job failed unexpectedly".into()));
        let result = match result {
            Ok(Outcome::Planned(p)) => {
                self.message = format!(
                    "wrote plan {}: {} shards of {} quads at level {}",
                    &p.hash[..12],
                    p.shards.len(),
                    p.shards.iter().map(Vec::len).sum::<usize>(),
                    p.level
                );
                let shards = p.shards.len();
                self.plan = Some(*p);
                (self.round, self.merged) = (Some((0, vec![false; shards])), None);
                Ok(())
            }
            Ok(Outcome::Looked(p, Merged::Pending { round, shards: missing })) => {
                let done = (0..p.shards.len()).map(|i| !missing.contains(&i)).collect();
                self.message = format!("round {round}: {} of {} shards to run", missing.len(), p.shards.len());
                (self.plan, self.round, self.merged) = (Some(*p), Some((round, done)), None);
                Ok(())
            }
            Ok(Outcome::Looked(p, Merged::Done(c))) => {
                self.message = format!("merged: every round of plan {} is in", &p.hash[..12]);
                (self.plan, self.round, self.merged) = (Some(*p), None, Some(*c));
                Ok(())
            }
            Err(e) => {
                self.message = e.to_string();
                Err(e)
            }
        };
        Some(result)
    }

    /// The command that runs the plan on Slurm, round after round.
    pub fn submit_command(&self) -> String {
        format!("terrafuse slurm submit {}", crate::slurm::shell_quote(self.plan_file.trim()))
    }

    /// The section, for A − B of the project at `project_path`.
    pub fn ui(&mut self, ui: &mut egui::Ui, project_path: &Path, a: &str, b: &str) {
        ui.collapsing("on a cluster (too large for the window)", |ui| {
            if let Some((what, _)) = &self.job {
                ui.add(egui::ProgressBar::new(0.0).animate(true).text(*what).desired_width(260.0));
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
                let _ = self.poll();
                return;
            }
            if self.shards.is_empty() {
                self.shards = "16".into();
            }
            use super::widgets::field;
            field(ui, "shards", &mut self.shards, "e.g. 64");
            field(ui, "level", &mut self.level, "default: the datasets' finest");
            field(ui, "plan file", &mut self.plan_file, "default: plans/compare-A-B.json");
            ui.horizontal(|ui| {
                if ui
                    .button("write plan")
                    .on_hover_text(format!("check {a} − {b} as compare does and cut its quads into shards"))
                    .clicked()
                    && let Err(e) = self.start_plan(project_path, a, b)
                {
                    self.message = e.to_string();
                }
                if ui.button("open plan").on_hover_text("read the plan and look at its parts").clicked()
                    && let Err(e) = self.start_look()
                {
                    self.message = e.to_string();
                }
            });
            if let Some(p) = &self.plan {
                ui.label(format!(
                    "plan {}: {} − {} at level {}, {} shards",
                    &p.hash[..12],
                    p.a,
                    p.b,
                    p.level,
                    p.shards.len()
                ));
                if let Some((round, done)) = &self.round {
                    let n = done.iter().filter(|d| **d).count();
                    ui.label(format!(
                        "round {round} of the statistics (6–12 in all): {n} of {} shards done",
                        done.len()
                    ));
                    super::widgets::shard_squares(ui, done);
                }
                let command = self.submit_command();
                ui.horizontal(|ui| {
                    ui.label("on the cluster:");
                    if ui.button("copy").on_hover_text("copy the command that submits the rounds").clicked() {
                        ui.ctx().copy_text(command.clone());
                    }
                });
                ui.add(egui::Label::new(egui::RichText::new(&command).monospace().small()).wrap());
                if ui
                    .button("merge")
                    .on_hover_text("look at the parts: the shards still to run, or the comparison once all are in")
                    .clicked()
                    && let Err(e) = self.start_look()
                {
                    self.message = e.to_string();
                }
            }
            if let Some(c) = &self.merged {
                super::compare_panel::comparison_ui(ui, c);
            }
            if !self.message.is_empty() {
                ui.add(egui::Label::new(egui::RichText::new(&self.message).small()).wrap());
            }
        });
    }
}
