//! Landscape evolution in the *Erosion* section: the stream-power settings (years, time step,
//! uplift, K, m, n, K_d, deposition, routing, the uplift brush) and *run landscape*, which takes
//! the whole run on the CPU reference on a thread of its own (a progress bar and *cancel* in the
//! panel, the window answering meanwhile) and keeps it on the erosion layer when done.

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
        if let Some(job) = &self.landscape_job {
            let p = job.watch.progress();
            ui.add(
                egui::ProgressBar::new(p.done as f32 / p.total.max(1) as f32)
                    .text(format!("{} of {} steps", p.done, p.total))
                    .desired_width(220.0),
            );
            if ui.button("cancel").on_hover_text("stops the run; the layer stays as it was").clicked() {
                job.watch.cancel();
            }
        }
        let idle = self.session.is_none() && self.landscape_job.is_none();
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

    /// Starts a stream-power operation whole on erosion layer `index` on a thread of its own;
    /// [`App::landscape_frame`] keeps it when done.
    pub(super) fn start_landscape(&mut self, index: usize, op: Operation, made_layer: bool) {
        let (spec, mut raster, below) = match self.editor.whole_run_inputs(&self.renderer, index) {
            Ok(inputs) => inputs,
            Err(e) => {
                self.message = format!("landscape: {}", crate::errors::chain(&e));
                self.forget_made_layer(index, made_layer);
                return;
            }
        };
        let watch = std::sync::Arc::new(crate::progress::Watch::default());
        let (w, run) = (watch.clone(), op.clone());
        let handle = crate::gui::background::spawn("landscape-run", move || {
            let applied = spec.applied_runs().len();
            let stepper = crate::erosion::layer::CpuStepper;
            let outcome =
                crate::erosion::layer::apply(&mut raster, applied, &run, &|q| Ok(below.heights_cpu(q)?), &stepper, &w)?;
            Ok((spec, raster, outcome))
        });
        self.message = format!("landscape: {} steps on a thread of their own", op.steps);
        self.erosion.landscape_job = Some(super::erosion::LandscapeJob { index, op, made_layer, watch, handle });
    }

    /// Each frame: a landscape run that has finished is kept (or its failure said, and a layer it
    /// made removed).
    pub(super) fn landscape_frame(&mut self, ctx: &egui::Context) {
        let Some(job) = &self.erosion.landscape_job else { return };
        if !job.handle.is_finished() {
            ctx.request_repaint_after(Duration::from_millis(100));
            return;
        }
        let job = self.erosion.landscape_job.take().expect("checked above");
        let (index, steps, made) = (job.index, job.op.steps, job.made_layer);
        let result = job.handle.join().unwrap_or_else(|_| {
            Err(crate::erosion::layer::OperationError {
                index: 0,
                field: "runs".into(),
                problem: "the run's thread stopped".into(),
                cause: None,
            })
        });
        match result {
            Ok((spec, raster, o)) => match self.editor.commit_whole(&mut self.renderer, index, spec, job.op, raster) {
                Ok(spec) => {
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
            },
            Err(e) => {
                self.message = format!("landscape: {}", crate::errors::chain(&e));
                self.forget_made_layer(index, made);
            }
        }
        self.dirty = true;
        self.update_drainage();
    }
}
