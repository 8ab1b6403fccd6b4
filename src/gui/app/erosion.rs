//! Erosion in the workstation: the *Erosion* section. A region (a box around the terrain at the
//! view's centre, rounded out to whole quads of a level), a preset, the steps and seed; *start*
//! prepares the run on the terrain the erosion layer sees, *run* and *pause* take a few steps per
//! frame (on the GPU on hardware adapters, else the CPU reference) so that the view stays
//! interactive, *step* takes one; the live time step, CFL bound, speeds and budgets show as it
//! runs, the terrain change shows on the layer a few times a second, and water depth, sediment or
//! the change of height show as a map of the region. *keep* records the run (its steps so far) on
//! the layer as `terrafuse erode` would; *discard* drops it. The erosion brush is in
//! `erosion_brush.rs`, stream power in `landscape.rs`, the drainage overlay in `drainage.rs`.
//! Undo and redo move the layer's position among its runs.

use super::*;
use crate::edit::EditRaster;
use crate::erosion::landscape::LandscapeParams;
use crate::erosion::operation::{BrushPath, Device, Model, Operation};
use crate::erosion::params::{Params, gravity_of_body};
use crate::erosion::region::Region;
use crate::erosion::sim::Run;
use crate::gpu::erosion::GpuRun;
use crate::gui::GuiError;
use crate::layers::LayerSpec;

/// What the region map shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Overlay {
    Water,
    Sediment,
    Change,
}

/// The section's settings and the run in progress.
pub(crate) struct ErosionTool {
    layer: String,
    /// Hydraulic runs step by step; stream-power runs whole (`landscape` their parameters).
    pub(super) model: Model,
    pub(super) landscape: LandscapeParams,
    preset: String,
    /// Half the region's side, metres.
    pub(super) half_m: f64,
    /// The level of the cells (None: about 512 cells across the region).
    pub(super) level: Option<u8>,
    steps: u64,
    per_frame: u32,
    seed: u64,
    overlay: Overlay,
    /// Whether the overlay is also draped over the terrain.
    drape: bool,
    pub(crate) session: Option<Session>,
    map: Option<egui::TextureHandle>,
    /// The erosion brush.
    pub(crate) brush: bool,
    pub(super) brush_radius_m: f64,
    pub(super) path: Vec<[f64; 2]>,
    pub(super) painting: bool,
    /// The window's context (for the map's texture and the pixel scale).
    ctx: Option<egui::Context>,
    /// The drainage overlay.
    pub(crate) drainage: super::drainage::DrainageTool,
}

impl Default for ErosionTool {
    fn default() -> ErosionTool {
        ErosionTool {
            layer: "erosion".into(),
            model: Model::Hydraulic,
            landscape: LandscapeParams::default(),
            preset: "rain".into(),
            half_m: 3000.0,
            level: None,
            steps: 200,
            per_frame: 2,
            seed: 1,
            overlay: Overlay::Water,
            drape: true,
            session: None,
            map: None,
            brush: false,
            brush_radius_m: 500.0,
            path: Vec::new(),
            painting: false,
            ctx: None,
            drainage: Default::default(),
        }
    }
}

/// Where the run's steps are taken.
pub(crate) enum Engine {
    Cpu(Box<Run>),
    Gpu(Box<GpuRun>),
}

/// A run in progress.
pub(crate) struct Session {
    index: usize,
    pub(super) op: Operation,
    region: Region,
    /// The layer's raster before the run.
    base: EditRaster,
    engine: Engine,
    /// The run as last seen (the CPU's own; the GPU's as last downloaded).
    pub(crate) running: bool,
    seconds: f64,
    last_shown: Option<Instant>,
    live: Option<crate::gpu::erosion::Report>,
}

impl Session {
    fn run(&self) -> &Run {
        match &self.engine {
            Engine::Cpu(run) => run,
            Engine::Gpu(gpu) => gpu.host(),
        }
    }

    fn steps(&self) -> u64 {
        match &self.engine {
            Engine::Cpu(run) => run.steps,
            Engine::Gpu(gpu) => gpu.steps(),
        }
    }

    /// Takes `n` steps (the GPU's without waiting).
    pub(super) fn step(&mut self, n: u32) -> Result<(), GuiError> {
        let t = Instant::now();
        match &mut self.engine {
            Engine::Cpu(run) => {
                for _ in 0..n {
                    run.step();
                }
            }
            Engine::Gpu(gpu) => {
                gpu.step(n)?;
                gpu.request_report();
                if let Some(r) = gpu.poll_report() {
                    self.live = Some(r);
                }
            }
        }
        self.seconds += t.elapsed().as_secs_f64();
        Ok(())
    }

    /// The run brought up to date (the GPU's downloaded).
    fn sync(&mut self) -> Result<&Run, GuiError> {
        if let Engine::Gpu(gpu) = &mut self.engine {
            gpu.download()?;
        }
        Ok(self.run())
    }
}

/// What the *Erosion* section asks the workstation to do (run and pause are the section's own).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum ErosionAction {
    /// Prepare a run on a region around the view's centre.
    Start,
    /// Take one step.
    Step,
    /// Record the run on the layer.
    Keep,
    /// Drop the run.
    Discard,
    /// Move the layer's undo position back one run.
    Undo,
    /// Forward one run.
    Redo,
    /// Route the drainage overlay again (or remove it).
    Drainage,
}

impl ErosionTool {
    /// The *Erosion* section: its settings, edited in place, the run in progress, and the
    /// erosion layer of `project`'s runs.
    pub(crate) fn ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<ErosionAction> {
        let mut action = None;
        let t = &mut *self;
        t.ctx = Some(ui.ctx().clone());
        ui.horizontal(|ui| {
            let label = ui.label("erosion layer").id;
            ui.text_edit_singleline(&mut t.layer).labelled_by(label);
        });
        egui::ComboBox::from_label("model").selected_text(t.model.name()).show_ui(ui, |ui| {
            ui.selectable_value(&mut t.model, Model::Hydraulic, Model::Hydraulic.name());
            ui.selectable_value(&mut t.model, Model::StreamPower, Model::StreamPower.name());
        });
        if t.model == Model::StreamPower {
            return t.landscape_ui(ui, project);
        }
        egui::ComboBox::from_label("preset").selected_text(t.preset.clone()).show_ui(ui, |ui| {
            for p in Params::PRESETS {
                ui.selectable_value(&mut t.preset, p.to_string(), p);
            }
        });
        if Params::preset(&t.preset, 9.81).is_some_and(|p| !p.start.is_dry()) {
            ui.label(format!(
                "time-scaled: starts with its rain's rivers full, transport {}× the physical rate, no deposition while water flows",
                crate::erosion::params::TRANSPORT_SCALE
            ))
            .on_hover_text("a few minutes of flow cut what centuries of floods would (docs/erosion.md)");
        }
        ui.add(egui::Slider::new(&mut t.half_m, 100.0..=100_000.0).logarithmic(true).text("region half-size m"));
        ui.horizontal(|ui| {
            let mut auto = t.level.is_none();
            ui.checkbox(&mut auto, "auto level").on_hover_text("about 512 cells across the region");
            match (auto, t.level) {
                (true, Some(_)) => t.level = None,
                (false, None) => t.level = Some(10),
                _ => {}
            }
            if let Some(l) = &mut t.level {
                let label = ui.label("level").id;
                ui.add(egui::DragValue::new(l).range(0..=22)).labelled_by(label);
            }
        });
        ui.horizontal(|ui| {
            let label = ui.label("steps").id;
            ui.add(egui::DragValue::new(&mut t.steps).range(1..=1_000_000)).labelled_by(label);
            let label = ui.label("seed").id;
            ui.add(egui::DragValue::new(&mut t.seed)).labelled_by(label);
        });
        ui.add(egui::Slider::new(&mut t.per_frame, 1..=64).text("steps per frame"));
        let busy = self.session.is_some();
        ui.horizontal(|ui| {
            if ui
                .add_enabled(!busy, egui::Button::new("start"))
                .on_hover_text("a region around the view's centre")
                .clicked()
            {
                action = Some(ErosionAction::Start);
            }
            let running = self.session.as_ref().is_some_and(|s| s.running);
            if ui.add_enabled(busy, egui::Button::new(if running { "pause" } else { "run" })).clicked()
                && let Some(s) = &mut self.session
            {
                s.running = !s.running;
            }
            if ui.add_enabled(busy && !running, egui::Button::new("step")).clicked() {
                action = Some(ErosionAction::Step);
            }
            if ui.add_enabled(busy, egui::Button::new("keep")).on_hover_text("records the run on the layer").clicked() {
                action = Some(ErosionAction::Keep);
            }
            if ui.add_enabled(busy, egui::Button::new("discard")).clicked() {
                action = Some(ErosionAction::Discard);
            }
        });
        let t = &mut *self;
        ui.horizontal(|ui| {
            ui.checkbox(&mut t.brush, "brush (left drag erodes)")
                .on_hover_text("a run of the steps above along the drag");
        });
        ui.add(egui::Slider::new(&mut t.brush_radius_m, 10.0..=20_000.0).logarithmic(true).text("brush radius m"));
        if let Some(s) = &self.session {
            let run = s.run();
            let steps = s.steps();
            let device = if matches!(s.engine, Engine::Gpu(_)) { "GPU" } else { "CPU reference" };
            ui.label(format!(
                "{steps} of {} steps on the {device}, {} × {} cells at level {}, {:.1} s",
                s.op.steps, s.region.width, s.region.height, s.region.level, s.seconds
            ));
            let unit = run.unit_m3();
            let (budget, dt, bound, speed, depth) = match (&s.engine, &s.live) {
                (Engine::Gpu(_), Some(r)) => (r.budget, r.next_dt_s, r.cfl_bound_s, r.max_speed_m_s, r.max_depth_m),
                _ => {
                    let max_speed = run.state.speed_m_s.iter().fold(0f64, |m, v| m.max(*v));
                    let max_depth = (0..run.grid.len()).map(|i| run.depth_m(i)).fold(0f64, f64::max);
                    let bound = run.cfl_bound_s();
                    (run.budget, run.params.dt_s.min(bound), bound, max_speed, max_depth)
                }
            };
            ui.label(format!("Δt {dt:.4} s (CFL bound {bound:.4} s), |v| ≤ {speed:.2} m/s, depth ≤ {depth:.3} m"));
            ui.label(format!(
                "water at the start {:.1} m³, rain {:.1} m³, evaporated {:.1} m³, out {:.1} m³ of water, {:.3} m³ of soil",
                budget.start_water as f64 * unit,
                budget.rain_in as f64 * unit,
                budget.evaporated as f64 * unit,
                budget.water_out as f64 * unit,
                budget.soil_out as f64 * unit
            ));
            let (w, soil) = run.unexplained();
            ui.label(format!("unexplained (as last read): water {w} units, soil {soil} units"));
            ui.horizontal(|ui| {
                let t = &mut self.overlay;
                ui.selectable_value(t, Overlay::Water, "water");
                ui.selectable_value(t, Overlay::Sediment, "sediment");
                ui.selectable_value(t, Overlay::Change, "change");
                ui.checkbox(&mut self.drape, "on the terrain");
            });
            if let Some(map) = &self.map {
                ui.image((map.id(), egui::vec2(200.0, 200.0)));
            }
        }
        self.undo_ui(ui, project).or(action)
    }

    /// *undo run* and *redo run* for the erosion layer of `project`, while no run is in
    /// progress, and the drainage overlay.
    pub(super) fn undo_ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<ErosionAction> {
        let undo = self.undo_buttons(ui, project);
        ui.separator();
        let drainage = self.drainage.ui(ui).then_some(ErosionAction::Drainage);
        undo.or(drainage)
    }

    /// *undo run*, *redo run* and where the layer stands among its runs.
    fn undo_buttons(&self, ui: &mut egui::Ui, project: &Project) -> Option<ErosionAction> {
        let index = project.layers.iter().position(|l| l.name == self.layer && l.as_erosion().is_some());
        let (applied, total) =
            index.map_or((0, 0), |i| (project.layers[i].applied_runs().len(), project.layers[i].runs().len()));
        let idle = self.session.is_none();
        ui.horizontal(|ui| {
            let mut action = None;
            if ui.add_enabled(idle && applied > 0, egui::Button::new("undo run")).clicked() {
                action = Some(ErosionAction::Undo);
            }
            if ui.add_enabled(idle && applied < total, egui::Button::new("redo run")).clicked() {
                action = Some(ErosionAction::Redo);
            }
            ui.label(format!("{applied} of {total} runs"));
            action
        })
        .inner
    }
}

impl ErosionTool {
    /// The erosion layer's name.
    pub(crate) fn layer_name(&self) -> &str {
        &self.layer
    }
}

impl App {
    /// The erosion run in progress: steps taken and asked (tests; people read the panel).
    pub fn erosion_progress(&self) -> Option<(u64, u64)> {
        self.erosion.session.as_ref().map(|s| (s.steps(), s.op.steps))
    }

    /// Sets the erosion section's steps and region half-size (tests; people use the panel).
    pub fn set_erosion(&mut self, steps: u64, half_m: f64) {
        self.erosion.steps = steps;
        self.erosion.half_m = half_m;
    }

    /// The *Erosion* section, its action applied.
    pub(super) fn erosion_ui(&mut self, ui: &mut egui::Ui) {
        match self.erosion.ui(ui, &self.project) {
            Some(ErosionAction::Start) => self.start_erosion(None),
            Some(ErosionAction::Step) => self.erosion_steps(1, true),
            Some(ErosionAction::Keep) => self.keep_erosion(),
            Some(ErosionAction::Discard) => {
                if let Some(s) = self.erosion.session.take() {
                    let _ = self.editor.set_erosion_overlay(&mut self.renderer, None);
                    self.editor.discard_erosion(&mut self.renderer, s.index, s.base);
                    self.dirty = true;
                    self.update_drainage();
                }
            }
            Some(ErosionAction::Undo) => self.move_erosion_undo(-1),
            Some(ErosionAction::Redo) => self.move_erosion_undo(1),
            Some(ErosionAction::Drainage) => self.update_drainage(),
            None => {}
        }
    }

    /// Every frame: a running session takes its steps, and its progress shows.
    pub(super) fn erosion_frame(&mut self, ctx: &egui::Context) {
        self.erosion.ctx = Some(ctx.clone());
        let Some(s) = &self.erosion.session else { return };
        if s.running {
            let left = s.op.steps.saturating_sub(s.steps());
            let n = (self.erosion.per_frame as u64).min(left) as u32;
            self.erosion_steps(n, false);
            if let Some(s) = &mut self.erosion.session
                && s.steps() >= s.op.steps
            {
                s.running = false;
                self.message = format!("erosion: {} steps done (keep or discard)", s.steps());
            }
            ctx.request_repaint();
        }
    }

    /// Takes `n` steps; shows the progress on the layer and the map now (`show`) or when due.
    fn erosion_steps(&mut self, n: u32, show: bool) {
        let Some(s) = &mut self.erosion.session else { return };
        if let Err(e) = s.step(n) {
            self.message = format!("erosion: {}", crate::errors::chain(&e));
            s.running = false;
            return;
        }
        let due = show || !s.running || s.last_shown.is_none_or(|t| t.elapsed() > Duration::from_millis(400));
        if !due {
            return;
        }
        s.last_shown = Some(Instant::now());
        let run = match s.sync() {
            Ok(run) => run.clone(),
            Err(e) => {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                return;
            }
        };
        let (index, base, region) = (s.index, s.base.clone(), s.region);
        self.editor.show_erosion(&mut self.renderer, index, &base, &region, &run);
        let image = region_map(&run, self.erosion.overlay);
        self.set_map(image);
        let drape = self.erosion.drape.then(|| {
            let values = field(&run, self.erosion.overlay);
            let range = values.iter().filter(|v| v.is_finite()).fold(0f64, |m, v| m.max(v.abs()));
            (crate::erosion::layer::field_raster(base.ellipsoid, &region, &values), &region, range)
        });
        if let Err(e) = self.editor.set_erosion_overlay(&mut self.renderer, drape) {
            self.message = format!("erosion overlay: {}", crate::errors::chain(&e));
        }
        self.dirty = true;
    }

    fn set_map(&mut self, image: egui::ColorImage) {
        let t = &mut self.erosion;
        match (&mut t.map, &t.ctx) {
            (Some(map), _) => map.set(image, egui::TextureOptions::NEAREST),
            (None, Some(ctx)) => t.map = Some(ctx.load_texture("erosion map", image, egui::TextureOptions::NEAREST)),
            (None, None) => {}
        }
    }

    /// A box of half-size `half_m` around the terrain at the view's centre (an error message
    /// when the view shows no terrain there).
    pub(super) fn view_box(&self, half_m: f64) -> Result<crate::geodesy::GeoBox, String> {
        let e = self.renderer.scene().ellipsoid;
        let ppp = self.erosion.ctx.as_ref().map_or(1.0, egui::Context::pixels_per_point);
        let centre = self.viewport_rect_px().and_then(|rect| {
            let r =
                egui::Rect::from_min_max((rect.min.to_vec2() / ppp).to_pos2(), (rect.max.to_vec2() / ppp).to_pos2());
            self.surface_at(r.center(), r)
        });
        let Some(p) = centre else { return Err("no terrain at the view's centre".into()) };
        let g = geodesy::geodetic_from_ecef(&e, p);
        crate::erosion::placement::box_around(&e, g.lat_rad.to_degrees(), g.lon_rad.to_degrees(), half_m)
            .map_err(|e| crate::errors::chain(&e))
    }

    /// Prepares a run on the erosion layer (made on top when missing): around the view's centre,
    /// or along a brush path.
    pub(crate) fn start_erosion(&mut self, brush: Option<BrushPath>) {
        let e = self.renderer.scene().ellipsoid;
        // A stream-power brush raises rock along the path; its rivers need room around it.
        let room = if self.erosion.model == Model::StreamPower { 3.0 } else { 1.0 };
        let region = match &brush {
            Some(b) => crate::erosion::placement::box_along(&e, &b.points, room * b.radius_m)
                .map_err(|e| format!("erosion: {}", crate::errors::chain(&e))),
            None => self.view_box(self.erosion.half_m).map_err(|m| format!("erosion: {m}")),
        };
        let region = match region {
            Ok(b) => b,
            Err(message) => {
                self.message = message;
                return;
            }
        };
        let t = &self.erosion;
        let index = self.project.layers.iter().position(|l| l.name == t.layer);
        let layer_level = index.and_then(|i| self.project.layers[i].runs().first().map(|r| r.level));
        let level = layer_level.or(t.level).unwrap_or_else(|| crate::erosion::placement::default_level(&e, &region));
        // A stream-power brush is an uplift brush (the path's mask scales U).
        let landscape = (t.model == Model::StreamPower).then(|| t.landscape.clone());
        let params = match &landscape {
            Some(_) => Params::standard(),
            None => {
                let Some(params) = Params::preset(&t.preset, gravity_of_body(&self.project.body)) else { return };
                params
            }
        };
        let steps = match (&landscape, &brush) {
            (Some(p), _) => p.steps(),
            (None, Some(_)) => t.steps.min(2000),
            (None, None) => t.steps,
        };
        let op = Operation {
            region,
            level,
            steps,
            seed: t.seed,
            preset: landscape.is_none().then(|| t.preset.clone()),
            params,
            model: if landscape.is_some() { Model::StreamPower } else { Model::Hydraulic },
            stream_power: landscape,
            brush,
            device: Device::Cpu,
        };
        let name = t.layer.clone();
        let index = match index {
            Some(i) if self.project.layers[i].as_erosion().is_some() => i,
            Some(_) => {
                self.message = format!("erosion: '{name}' is not an erosion layer");
                return;
            }
            None => {
                let spec = LayerSpec::erosion(&name);
                let top = self.project.layers.len();
                if let Err(e) = self.renderer.insert_layer(top, spec.clone()) {
                    self.message = e.to_string();
                    return;
                }
                self.project.layers.push(spec);
                top
            }
        };
        if op.model == Model::StreamPower {
            self.run_landscape(index, op);
            return;
        }
        let (region, run, base) = match self.editor.prepare_erosion(&self.renderer, index, &op) {
            Ok(prepared) => prepared,
            Err(e) => {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                return;
            }
        };
        let mut op = op;
        let engine = match self.editor.erosion_on_gpu(&run) {
            Some(Ok(gpu)) => {
                op.device = Device::Gpu;
                Engine::Gpu(Box::new(gpu))
            }
            Some(Err(e)) => {
                self.message = format!("erosion on the GPU: {}; on the CPU instead", crate::errors::chain(&e));
                Engine::Cpu(Box::new(run))
            }
            None => Engine::Cpu(Box::new(run)),
        };
        self.message = format!("erosion: {} × {} cells at level {level}", region.width, region.height);
        self.erosion.session = Some(Session {
            index,
            op,
            region,
            base,
            engine,
            running: false,
            seconds: 0.0,
            last_shown: None,
            live: None,
        });
    }

    /// Records the session's run (its steps so far) on the layer.
    pub(crate) fn keep_erosion(&mut self) {
        let Some(mut s) = self.erosion.session.take() else { return };
        if let Err(e) = self.editor.set_erosion_overlay(&mut self.renderer, None) {
            self.message = format!("erosion overlay: {}", crate::errors::chain(&e));
        }
        let run = match s.sync() {
            Ok(run) => run.clone(),
            Err(e) => {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                return;
            }
        };
        if run.steps == 0 {
            self.editor.discard_erosion(&mut self.renderer, s.index, s.base);
            self.message = "erosion: no step taken, nothing kept".into();
            return;
        }
        match self.editor.commit_erosion(&mut self.renderer, s.index, s.op, s.base, s.region, &run, s.seconds) {
            Ok((spec, o)) => {
                self.message = format!(
                    "erosion run {} kept: {} steps, {:.1} s simulated, change {:.2} … {:.2} m",
                    spec.runs().len() - 1,
                    o.steps,
                    o.simulated_s,
                    o.range_m.0,
                    o.range_m.1
                );
                self.project.layers[s.index] = spec;
                self.mark_unsaved();
            }
            Err(e) => self.message = e.to_string(),
        }
        self.dirty = true;
        self.update_drainage();
    }

    fn move_erosion_undo(&mut self, by: i64) {
        let Some(index) = self.project.layers.iter().position(|l| l.name == self.erosion.layer) else { return };
        let applied = self.project.layers[index].applied_runs().len() as i64 + by;
        let total = self.project.layers[index].runs().len() as i64;
        if !(0..=total).contains(&applied) {
            return;
        }
        match self.editor.set_erosion_applied(&mut self.renderer, index, applied as usize) {
            Ok(spec) => {
                self.project.layers[index] = spec;
                self.dirty = true;
                self.mark_unsaved();
                self.message = format!("{} to {applied} of {total} runs", if by < 0 { "undone" } else { "redone" });
                self.update_drainage();
            }
            Err(e) => self.message = e.to_string(),
        }
    }
}

/// Per cell, what the overlay shows, metres (NaN where there is nothing to show: dry, no
/// sediment, unchanged).
fn field(run: &Run, overlay: Overlay) -> Vec<f64> {
    let g = &run.grid;
    (0..g.len())
        .map(|i| {
            let units = match overlay {
                Overlay::Water => run.state.water[i],
                Overlay::Sediment => run.state.sediment[i],
                Overlay::Change => run.state.soil[i],
            };
            if units == 0 { f64::NAN } else { units as f64 * run.unit_m3() / g.area_m2[i] }
        })
        .collect()
}

/// The region's water depth, sediment or change of height as a picture (north up), at most 256
/// pixels a side: blue for water, brown for sediment, red-blue for the change (lowered red).
fn region_map(run: &Run, overlay: Overlay) -> egui::ColorImage {
    let g = &run.grid;
    let step = g.width.max(g.height).div_ceil(256).max(1);
    let (w, h) = (g.width.div_ceil(step), g.height.div_ceil(step));
    let value = |i: usize| match overlay {
        Overlay::Water => run.depth_m(i),
        Overlay::Sediment => run.state.sediment[i] as f64 * run.unit_m3() / g.area_m2[i],
        Overlay::Change => run.state.soil[i] as f64 * run.unit_m3() / g.area_m2[i],
    };
    let scale = (0..g.len()).map(|i| value(i).abs()).fold(0f64, f64::max).max(1e-6);
    let mut pixels = Vec::with_capacity(w * h);
    for y in (0..h).rev() {
        for x in 0..w {
            let i = (y * step).min(g.height - 1) * g.width + (x * step).min(g.width - 1);
            let v = (value(i) / scale).clamp(-1.0, 1.0);
            let a = (v.abs().sqrt() * 255.0) as u8;
            pixels.push(match overlay {
                Overlay::Water => egui::Color32::from_rgb(255 - a, 255 - a / 2, 255),
                Overlay::Sediment => egui::Color32::from_rgb(255 - a / 3, 255 - a / 2, 255 - a),
                Overlay::Change if v < 0.0 => egui::Color32::from_rgb(255, 255 - a, 255 - a),
                Overlay::Change => egui::Color32::from_rgb(255 - a, 255 - a, 255),
            });
        }
    }
    egui::ColorImage::new([w, h], pixels)
}
