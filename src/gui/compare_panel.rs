//! The *Compare* section: statistics of A − B (as `terrafuse compare` prints them: the numbers,
//! the histogram, the slope classes) and co-registration of A onto B by a pipeline of bias
//! corrections (as `terrafuse coregister --pipeline`; Nuth & Kääb alone by default) with each
//! step's result and an *apply* button, and the uncertainty of the mean change
//! ([`super::uncertainty_ui`]), each computed on a thread while the view keeps drawing.

use crate::gui::GuiError;
use std::thread::JoinHandle;

use crate::compare::{
    CompareOptions, Comparison, CoregOptions, Coregistration, Step, Uncertainty, UncertaintyOptions, compare,
    coregister, uncertainty,
};
use crate::project::Project;

/// What the panel asks of the window.
pub enum CompareAction {
    /// Nothing.
    None,
    /// Draw A − B over the terrain (a difference layer on top of the stack).
    ShowDifference {
        /// A.
        a: String,
        /// B.
        b: String,
    },
    /// Apply a co-registration to its layer A (`Coregistration::apply_to`).
    Apply(Box<Coregistration>),
}

/// The section's state.
#[derive(Default)]
pub struct ComparePanel {
    a: String,
    b: String,
    /// The pipeline as `--pipeline` spells it (empty: `nuth_kaab`).
    pipeline: String,
    comparing: Option<JoinHandle<Result<Comparison, GuiError>>>,
    coregistering: Option<JoinHandle<Result<Coregistration, GuiError>>>,
    estimating: Option<JoinHandle<Result<Uncertainty, GuiError>>>,
    comparison: Option<Result<Comparison, GuiError>>,
    coregistration: Option<Result<Coregistration, GuiError>>,
    uncertainty: Option<Result<Uncertainty, GuiError>>,
    /// Where the computation in flight stands, and its cancel switch.
    watch: std::sync::Arc<crate::progress::Watch>,
}

impl ComparePanel {
    /// The layers chosen: A and B (the reference).
    pub fn selection(&self) -> (&str, &str) {
        (&self.a, &self.b)
    }

    /// Whether a computation runs.
    pub fn busy(&self) -> bool {
        self.comparing.is_some() || self.coregistering.is_some() || self.estimating.is_some()
    }

    /// The last uncertainty, if any.
    pub fn uncertainty(&self) -> Option<&Uncertainty> {
        self.uncertainty.as_ref().and_then(|r| r.as_ref().ok())
    }

    /// The last statistics, if any.
    pub fn comparison(&self) -> Option<&Comparison> {
        self.comparison.as_ref().and_then(|r| r.as_ref().ok())
    }

    /// The last co-registration, if any.
    pub fn coregistration(&self) -> Option<&Coregistration> {
        self.coregistration.as_ref().and_then(|r| r.as_ref().ok())
    }

    fn poll(&mut self) {
        if self.comparing.as_ref().is_some_and(|h| h.is_finished())
            && let Some(h) = self.comparing.take()
        {
            self.comparison = Some(h.join().unwrap_or_else(|_| Err("the comparison failed unexpectedly".into())));
        }
        if self.coregistering.as_ref().is_some_and(|h| h.is_finished())
            && let Some(h) = self.coregistering.take()
        {
            self.coregistration =
                Some(h.join().unwrap_or_else(|_| Err("the co-registration failed unexpectedly".into())));
        }
        if self.estimating.as_ref().is_some_and(|h| h.is_finished())
            && let Some(h) = self.estimating.take()
        {
            self.uncertainty = Some(h.join().unwrap_or_else(|_| Err("the uncertainty failed unexpectedly".into())));
        }
    }

    /// Draws the section.
    pub fn ui(&mut self, ui: &mut egui::Ui, project: &Project) -> CompareAction {
        self.poll();
        let names: Vec<String> = project.layers.iter().filter(|l| l.is_data()).map(|l| l.name.clone()).collect();
        if names.len() < 2 {
            ui.label("add a second dataset layer to compare");
            return CompareAction::None;
        }
        if !names.contains(&self.a) || !names.contains(&self.b) || self.a == self.b {
            // Default: the top dataset against the one below it.
            (self.a, self.b) = (names[names.len() - 1].clone(), names[names.len() - 2].clone());
        }
        ui.horizontal(|ui| {
            egui::ComboBox::from_label("minus").selected_text(&self.a).show_ui(ui, |ui| {
                for n in &names {
                    ui.selectable_value(&mut self.a, n.clone(), n);
                }
            });
            egui::ComboBox::from_label("(reference)").selected_text(&self.b).show_ui(ui, |ui| {
                for n in &names {
                    ui.selectable_value(&mut self.b, n.clone(), n);
                }
            });
        });
        ui.horizontal(|ui| {
            let label = ui.label("pipeline");
            ui.add(
                egui::TextEdit::singleline(&mut self.pipeline)
                    .hint_text("nuth_kaab")
                    .desired_width(320.0),
            )
            .labelled_by(label.id)
            .on_hover_text(
                "steps, comma-separated: nuth_kaab, vertical, deramp:1-3, terrain_bias:elevation|max_curvature|slope, directional:AZIMUTH",
            );
        });
        let mut action = self.buttons(ui, project);
        if self.busy() {
            ui.horizontal(|ui| {
                let p = self.watch.progress();
                let fraction = if p.total > 0 { p.done as f32 / p.total as f32 } else { 0.0 };
                let text =
                    if p.total > 0 { format!("{}: {} of {}", p.phase, p.done, p.total) } else { p.phase.clone() };
                ui.add(egui::ProgressBar::new(fraction).text(text).desired_width(220.0));
                if ui.button("cancel").clicked() {
                    self.watch.cancel();
                }
            });
        }
        match &self.comparison {
            Some(Ok(c)) => comparison_ui(ui, c),
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, e.to_string());
            }
            None => {}
        }
        match &self.uncertainty {
            Some(Ok(u)) => super::uncertainty_ui::uncertainty_ui(ui, u),
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, e.to_string());
            }
            None => {}
        }
        if let Some(applied) = self.coregistration_ui(ui, project) {
            action = applied;
        }
        action
    }

    /// The buttons that start a comparison, a co-registration or an uncertainty off the interface
    /// thread, and the one that shows the difference layer (its action).
    fn buttons(&mut self, ui: &mut egui::Ui, project: &Project) -> CompareAction {
        let mut action = CompareAction::None;
        ui.horizontal(|ui| {
            let idle = !self.busy() && self.a != self.b;
            if idle {
                // A new computation counts on a new watch (the last one may be cancelled).
                self.watch = Default::default();
            }
            let watch = Some(self.watch.clone());
            if ui.add_enabled(idle, egui::Button::new("compare")).clicked() {
                let (p, a, b) = (project.clone(), self.a.clone(), self.b.clone());
                let watch = watch.clone();
                self.comparing = Some(crate::gui::background::spawn("compare", move || {
                    // A comparison too large for memory spills to the temporary folder.
                    let opts =
                        CompareOptions { scratch: Some(std::env::temp_dir()), watch, ..CompareOptions::default() };
                    Ok(compare(&p, &a, &b, &opts)?)
                }));
            }
            if ui
                .add_enabled(idle, egui::Button::new("co-register"))
                .on_hover_text("A onto B by the pipeline below (Nuth & Kääb alone when empty)")
                .clicked()
            {
                let (p, a, b) = (project.clone(), self.a.clone(), self.b.clone());
                let text =
                    if self.pipeline.trim().is_empty() { "nuth_kaab".to_string() } else { self.pipeline.clone() };
                let watch = watch.clone();
                self.coregistering = Some(crate::gui::background::spawn("coregister", move || {
                    let opts = CoregOptions { pipeline: Step::parse_list(&text)?, watch, ..CoregOptions::default() };
                    Ok(coregister(&p, &a, &b, &opts)?)
                }));
            }
            if ui
                .add_enabled(idle, egui::Button::new("uncertainty"))
                .on_hover_text(
                    "the mean dh and the volume change over the overlap with their 1σ (Hugonnet et al. 2022)",
                )
                .clicked()
            {
                let (p, a, b) = (project.clone(), self.a.clone(), self.b.clone());
                let opts = UncertaintyOptions { watch: watch.clone(), ..UncertaintyOptions::default() };
                self.estimating =
                    Some(crate::gui::background::spawn("uncertainty", move || Ok(uncertainty(&p, &a, &b, &opts)?)));
            }
            if ui
                .add_enabled(self.a != self.b, egui::Button::new("show difference"))
                .on_hover_text("a difference layer A - B on top of the stack: red where A is lower, blue higher")
                .clicked()
            {
                action = CompareAction::ShowDifference { a: self.a.clone(), b: self.b.clone() };
            }
            if self.busy() {
                ui.spinner();
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
            }
        });
        action
    }

    /// The co-registration's result, and its *apply* button (the action, where pressed).
    fn coregistration_ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<CompareAction> {
        match &self.coregistration {
            Some(Ok(c)) => {
                ui.label(format!(
                    "move {} east {:+.2} m, north {:+.2} m, up {:+.2} m ({} iterations{})",
                    c.a,
                    c.east_m,
                    c.north_m,
                    c.up_m,
                    c.iterations,
                    if c.converged { "" } else { ", not converged" }
                ));
                for (name, step) in c.pipeline.iter().zip(&c.steps) {
                    ui.monospace(format!(
                        "{name:<26} NMAD {:.2} -> {:.2} m, median {:+.2} -> {:+.2} m",
                        step.before.nmad_m, step.after.nmad_m, step.before.median_m, step.after.median_m
                    ));
                }
                ui.label(format!(
                    "NMAD {:.2} m to {:.2} m, RMSE {:.2} m to {:.2} m",
                    c.before.nmad_m, c.after.nmad_m, c.before.rmse_m, c.after.rmse_m
                ));
                // What applying would write, tried on a copy of A: a layer that cannot hold it says why.
                let storable = project.layers.iter().find(|l| l.name == c.a).map(|l| c.apply_to(&mut l.clone()));
                if let Some(Err(e)) = storable {
                    ui.label(format!("cannot apply: {e}"));
                } else if ui
                    .button(format!("apply to {}", c.a))
                    .on_hover_text(
                        "adds the shift to its shift_m, the raise to its offset_m, the biases to its correction",
                    )
                    .clicked()
                {
                    let apply = CompareAction::Apply(Box::new(c.clone()));
                    self.coregistration = None;
                    return Some(apply);
                }
            }
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, e.to_string());
            }
            None => {}
        }
        None
    }
}

/// The statistics, the histogram and the slope classes of a comparison.
pub(crate) fn comparison_ui(ui: &mut egui::Ui, c: &Comparison) {
    let s = &c.stats;
    ui.label(format!("{} - {} at level {} ({:.0} m), by cell area", c.a, c.b, c.level, c.spacing_m));
    egui::Grid::new("compare stats").num_columns(4).show(ui, |ui| {
        let mut cell = |name: &str, v: String| {
            ui.label(name);
            ui.monospace(v);
        };
        cell("samples", s.count.to_string());
        cell("no data", s.nodata_count.to_string());
        ui.end_row();
        for (k, (name, v)) in [
            ("mean", s.mean_m),
            ("median", s.median_m),
            ("std", s.std_m),
            ("RMSE", s.rmse_m),
            ("NMAD", s.nmad_m),
            ("LE90", s.le90_m),
            ("min", s.min_m),
            ("max", s.max_m),
            ("p90 |dh|", s.p90_abs_m),
        ]
        .into_iter()
        .enumerate()
        {
            ui.label(name);
            ui.monospace(format!("{v:.2} m"));
            if k % 2 == 1 {
                ui.end_row();
            }
        }
        ui.end_row();
    });
    // The histogram: bars scaled to the largest bin.
    let h = &c.histogram;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width().min(280.0), 70.0), egui::Sense::hover());
    let peak = h.count.iter().copied().max().unwrap_or(1).max(1) as f32;
    let width = rect.width() / h.count.len().max(1) as f32;
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
    for (k, n) in h.count.iter().enumerate() {
        let height = rect.height() * (*n as f32 / peak);
        let x = rect.left() + k as f32 * width;
        painter.rect_filled(
            egui::Rect::from_min_max(egui::pos2(x, rect.bottom() - height), egui::pos2(x + width - 1.0, rect.bottom())),
            0.0,
            ui.visuals().selection.bg_fill,
        );
    }
    if let (Some(lo), Some(hi)) = (h.edges_m.first(), h.edges_m.last()) {
        ui.label(egui::RichText::new(format!("dh {lo:.1} … {hi:.1} m")).small());
    }
    egui::Grid::new("compare slopes").num_columns(4).striped(true).show(ui, |ui| {
        for head in ["slope of B", "samples", "median", "NMAD"] {
            ui.label(egui::RichText::new(head).small());
        }
        ui.end_row();
        for k in &c.by_slope {
            ui.label(format!("{}–{}°", k.min_deg, k.max_deg));
            ui.monospace(k.stats.count.to_string());
            ui.monospace(format!("{:.2}", k.stats.median_m));
            ui.monospace(format!("{:.2}", k.stats.nmad_m));
            ui.end_row();
        }
    });
}
