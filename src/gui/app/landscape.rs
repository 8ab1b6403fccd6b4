//! Landscape evolution in the *Erosion* section: the stream-power settings (years, time step,
//! uplift, K, m, n, K_d, deposition, routing, the uplift brush) and *run landscape*, which takes
//! the whole run at once on the CPU reference and keeps it on the erosion layer.

use super::erosion::{ErosionAction, ErosionTool};
use super::*;
use crate::erosion::landscape::flow::Routing;
use crate::erosion::operation::{Model, Operation};

impl ErosionTool {
    /// The stream-power settings: a region around the view's centre, the years and time step,
    /// uplift, K, m, n, K_d, the deposition coefficient G and the routing, and *run landscape*
    /// (the whole run at once, on the CPU reference; with *brush* ticked, a drag raises rock
    /// along its path instead).
    pub(super) fn landscape_ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<ErosionAction> {
        let mut action = None;
        let p = &mut self.landscape;
        ui.add(egui::Slider::new(&mut self.half_m, 100.0..=100_000.0).logarithmic(true).text("region half-size m"));
        let field = |ui: &mut egui::Ui, label: &str, value: &mut f64, speed: f64| {
            ui.horizontal(|ui| {
                let id = ui.label(label).id;
                ui.add(egui::DragValue::new(value).speed(speed)).labelled_by(id);
            });
        };
        field(ui, "years", &mut p.years, 1e4);
        field(ui, "time step, years", &mut p.dt_years, 100.0);
        field(ui, "uplift m/yr", &mut p.uplift_m_per_year, 1e-5);
        field(ui, "K", &mut p.k, 1e-6);
        field(ui, "m", &mut p.m, 0.01);
        field(ui, "n", &mut p.n, 0.01);
        field(ui, "K_d m²/yr", &mut p.kd_m2_per_year, 1e-3);
        field(ui, "deposition G", &mut p.deposition, 0.01);
        ui.horizontal(|ui| {
            ui.label("drainage area");
            ui.selectable_value(&mut p.routing, Routing::D8, "D8");
            ui.selectable_value(&mut p.routing, Routing::Mfd, "MFD").on_hover_text("Freeman 1991");
        });
        ui.horizontal(|ui| {
            ui.checkbox(&mut self.brush, "uplift brush (left drag raises rock)")
                .on_hover_text("a run whose uplift follows the drag, on a region three radii around it");
        });
        ui.add(egui::Slider::new(&mut self.brush_radius_m, 10.0..=20_000.0).logarithmic(true).text("brush radius m"));
        let p = &self.landscape;
        let check = p.check();
        if let Err(e) = &check {
            ui.colored_label(egui::Color32::LIGHT_RED, e.to_string());
        }
        let idle = self.session.is_none();
        if ui
            .add_enabled(idle && check.is_ok(), egui::Button::new("run landscape"))
            .on_hover_text(
                "uplift, river incision and hillslope diffusion over the years, on a region around the view's centre",
            )
            .clicked()
        {
            action = Some(ErosionAction::Start);
        }
        self.undo_ui(ui, project).or(action)
    }
}

impl App {
    /// Switches the erosion section to stream power for `years` in steps of `dt_years` (tests;
    /// people use the panel).
    pub fn set_landscape(&mut self, years: f64, dt_years: f64) {
        self.erosion.model = Model::StreamPower;
        self.erosion.landscape.years = years;
        self.erosion.landscape.dt_years = dt_years;
    }

    /// Runs a stream-power operation whole on erosion layer `index` and keeps it.
    pub(super) fn run_landscape(&mut self, index: usize, op: Operation) {
        let steps = op.steps;
        match self.editor.run_whole(&mut self.renderer, index, op) {
            Ok((spec, o)) => {
                let years = o.landscape.map_or(0.0, |f| f.simulated_years);
                self.message = format!(
                    "landscape run {} kept: {steps} steps, {years} years in {:.1} s, change {:.1} … {:.1} m",
                    spec.runs().len() - 1,
                    o.seconds,
                    o.range_m.0,
                    o.range_m.1
                );
                self.project.layers[index] = spec;
                self.mark_unsaved();
            }
            Err(e) => self.message = format!("landscape: {}", crate::errors::chain(&e)),
        }
        self.dirty = true;
        self.update_drainage();
    }
}
