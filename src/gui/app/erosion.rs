//! Erosion in the workstation: the *Erosion* section. A region (a box around the terrain at the
//! view's centre, rounded out to whole quads of a level), a preset, the steps and seed; *start*
//! prepares the run on the terrain the erosion layer sees, *run* and *pause* go on and stop
//! (the CPU reference steps on a thread of its own, `erosion_run.rs`, the GPU's kernels without
//! blocking the frame), *step* takes one; the live time step, CFL bound, speeds and budgets show
//! as it runs, the terrain change shows on the layer a few times a second, and water depth,
//! sediment or the change of height show as a map of the region. *keep* records the run (its
//! steps so far) on the layer as `terrafuse erode` would; *discard* drops it, and the layer too
//! when *start* made it. The erosion brush is in `erosion_brush.rs`, stream power in
//! `landscape.rs`, the drainage overlay in `drainage.rs`. Undo and redo move the layer's position
//! among its runs.

use super::erosion_overlay::Overlay;
use super::erosion_run::{Engine, Figures, Snapshot, Worker};
use super::*;
use crate::edit::EditRaster;
use crate::erosion::landscape::LandscapeParams;
use crate::erosion::operation::{BrushPath, Device, Model, Operation};
use crate::erosion::params::{Params, gravity_of_body};
use crate::erosion::region::Region;
use crate::erosion::sim::Run;
use crate::gui::Within;
use crate::layers::LayerSpec;

/// A run's progress shows at most once in this many times what showing it last cost (at least
/// every 0.4 s): frames in between only draw.
const SHOW_PACE: f64 = 4.0;

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
    pub(super) drape: bool,
    pub(crate) session: Option<Session>,
    map: Option<egui::TextureHandle>,
    /// The erosion brush.
    pub(crate) brush: bool,
    pub(super) brush_radius_m: f64,
    /// The brush's path released and still being turned into points.
    pub(crate) input: Option<super::pointer::StrokeInput>,
    /// The window's context (for the map's texture and the pixel scale).
    ctx: Option<egui::Context>,
    /// The drainage overlay.
    pub(crate) drainage: super::drainage::DrainageTool,
    /// A stream-power run taken whole on its thread.
    pub(crate) landscape_job: Option<LandscapeJob>,
}

/// A stream-power run on a thread of its own.
pub(crate) struct LandscapeJob {
    pub(super) index: usize,
    pub(super) op: Operation,
    /// *run landscape* made the erosion layer (removed again if the run fails).
    pub(super) made_layer: bool,
    /// Its steps, and its cancel switch.
    pub(super) watch: std::sync::Arc<crate::progress::Watch>,
    pub(super) handle: std::thread::JoinHandle<
        Result<(LayerSpec, EditRaster, crate::erosion::layer::Outcome), crate::erosion::layer::OperationError>,
    >,
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
            input: None,
            ctx: None,
            drainage: Default::default(),
            landscape_job: None,
        }
    }
}

/// A run in progress.
pub(crate) struct Session {
    index: usize,
    pub(super) op: Operation,
    region: Region,
    /// The layer's raster before the run.
    base: EditRaster,
    engine: Engine,
    /// The GPU's run goes on (the CPU's thread knows for itself).
    gpu_running: bool,
    /// The GPU's steps' seconds.
    gpu_seconds: f64,
    last_shown: Option<Instant>,
    /// The figures as last shown.
    figures: Figures,
    /// The GPU's live figures, read back without waiting.
    live: Option<crate::gpu::erosion::Report>,
    /// *start* made the erosion layer: *discard* removes it again.
    made_layer: bool,
    /// An erosion brush's run: kept once its steps are done.
    keep_when_done: bool,
}

impl Session {
    pub(super) fn steps(&self) -> u64 {
        match &self.engine {
            Engine::Cpu(w) => w.steps(),
            Engine::Gpu(gpu) => gpu.steps(),
        }
    }

    /// Whether its steps go on.
    pub(crate) fn running(&self) -> bool {
        match &self.engine {
            Engine::Cpu(w) => w.running(),
            Engine::Gpu(_) => self.gpu_running,
        }
    }

    /// Runs on to the run's steps, or pauses.
    pub(crate) fn set_running(&mut self, on: bool) {
        match &self.engine {
            Engine::Cpu(w) => w.set(on, if on { self.op.steps } else { w.steps() }),
            Engine::Gpu(_) => self.gpu_running = on,
        }
    }

    fn seconds(&self) -> f64 {
        match &self.engine {
            Engine::Cpu(w) => w.seconds(),
            Engine::Gpu(_) => self.gpu_seconds,
        }
    }

    /// Takes `n` steps on the GPU (without waiting), or asks the CPU's thread for `n` more.
    pub(super) fn step(&mut self, n: u32) -> Result<(), GuiError> {
        match &mut self.engine {
            Engine::Cpu(w) => w.set(true, w.steps() + u64::from(n)),
            Engine::Gpu(gpu) => {
                let t = Instant::now();
                gpu.step(n)?;
                gpu.request_report();
                if let Some(r) = gpu.poll_report() {
                    self.live = Some(r);
                }
                self.gpu_seconds += t.elapsed().as_secs_f64();
            }
        }
        Ok(())
    }

    /// Stops the run and takes it back with its seconds (the GPU's downloaded).
    fn finish(self) -> Result<(Run, f64), GuiError> {
        let seconds = self.seconds();
        match self.engine {
            Engine::Cpu(w) => Ok((w.finish()?, seconds)),
            Engine::Gpu(mut gpu) => Ok((gpu.download()?.clone(), seconds)),
        }
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
            let running = self.session.as_ref().is_some_and(|s| s.running());
            if ui.add_enabled(busy, egui::Button::new(if running { "pause" } else { "run" })).clicked()
                && let Some(s) = &mut self.session
            {
                s.set_running(!running);
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
        self.session_ui(ui);
        self.undo_ui(ui, project).or(action)
    }

    /// The run in progress: its steps, its time step and CFL bound, its water and soil budget,
    /// the overlay's choice and its map.
    fn session_ui(&mut self, ui: &mut egui::Ui) {
        let Some(s) = &self.session else { return };
        let steps = s.steps();
        let device = if matches!(s.engine, Engine::Gpu(_)) { "GPU" } else { "CPU reference, on its own thread" };
        ui.label(format!(
            "{steps} of {} steps on the {device}, {} × {} cells at level {}, {:.1} s",
            s.op.steps,
            s.region.width,
            s.region.height,
            s.region.level,
            s.seconds()
        ));
        ui.add(egui::ProgressBar::new(steps as f32 / s.op.steps.max(1) as f32).desired_width(220.0));
        let f = &s.figures;
        let (budget, dt, bound, speed, depth) = match (&s.engine, &s.live) {
            (Engine::Gpu(_), Some(r)) => (r.budget, r.next_dt_s, r.cfl_bound_s, r.max_speed_m_s, r.max_depth_m),
            _ => (f.budget, f.dt_s, f.cfl_bound_s, f.max_speed_m_s, f.max_depth_m),
        };
        let unit = f.unit_m3;
        ui.label(format!("Δt {dt:.4} s (CFL bound {bound:.4} s), |v| ≤ {speed:.2} m/s, depth ≤ {depth:.3} m"));
        ui.label(format!(
            "water at the start {:.1} m³, rain {:.1} m³, evaporated {:.1} m³, out {:.1} m³ of water, {:.3} m³ of soil",
            budget.start_water as f64 * unit,
            budget.rain_in as f64 * unit,
            budget.evaporated as f64 * unit,
            budget.water_out as f64 * unit,
            budget.soil_out as f64 * unit
        ));
        let (w, soil) = f.unexplained;
        ui.label(format!("unexplained (as last read): water {w} units, soil {soil} units"));
        ui.horizontal(|ui| {
            let t = &mut self.overlay;
            ui.selectable_value(t, Overlay::Water, "water");
            ui.selectable_value(t, Overlay::Sediment, "sediment");
            ui.selectable_value(t, Overlay::Change, "change");
            ui.checkbox(&mut self.drape, "on the terrain");
        });
        if let Engine::Cpu(w) = &s.engine {
            w.set_overlay(self.overlay);
        }
        if let Some(map) = &self.map {
            // At the region's true aspect, 200 points along its longer side.
            let [w, h] = map.size();
            let k = 200.0 / w.max(h).max(1) as f32;
            ui.image((map.id(), egui::vec2(w as f32 * k, h as f32 * k)));
        }
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
            Some(ErosionAction::Discard) => self.discard_erosion(),
            Some(ErosionAction::Undo) => self.move_layer_undo(&self.erosion.layer.clone(), -1),
            Some(ErosionAction::Redo) => self.move_layer_undo(&self.erosion.layer.clone(), 1),
            Some(ErosionAction::Drainage) => self.update_drainage(),
            None => {}
        }
    }

    /// Every frame: a running session's progress shows (the CPU's snapshots as its thread makes
    /// them; the GPU takes its steps here, without waiting); an erosion brush's run, once done,
    /// is kept.
    pub(super) fn erosion_frame(&mut self, ctx: &egui::Context) {
        self.erosion.ctx = Some(ctx.clone());
        self.landscape_frame(ctx);
        let Some(s) = &mut self.erosion.session else { return };
        let was_running = s.running();
        if let Engine::Gpu(_) = s.engine
            && s.gpu_running
        {
            let left = s.op.steps.saturating_sub(s.steps());
            let n = (self.erosion.per_frame as u64).min(left) as u32;
            self.erosion_steps(n, false);
        }
        if let Some(wait) = self.show_erosion_progress() {
            ctx.request_repaint_after(wait);
        }
        let Some(s) = &mut self.erosion.session else { return };
        let done = s.steps() >= s.op.steps;
        if done && s.gpu_running {
            s.gpu_running = false;
        }
        if done && s.keep_when_done {
            self.keep_erosion();
            return;
        }
        if done && was_running {
            self.message = format!("erosion: {} steps done (keep or discard)", s.steps());
        }
        if s.running() || was_running {
            ctx.request_repaint_after(Duration::from_millis(50));
        }
    }

    /// Takes `n` steps on the GPU, or asks the CPU's thread for them; shows the progress now
    /// (`show`) or when due.
    fn erosion_steps(&mut self, n: u32, show: bool) {
        let Some(s) = &mut self.erosion.session else { return };
        if let Err(e) = s.step(n) {
            self.message = format!("erosion: {}", crate::errors::chain(&e));
            s.set_running(false);
            return;
        }
        if show && let Engine::Gpu(_) = s.engine {
            s.last_shown = None;
        }
    }

    /// Shows the run as it stands: the CPU thread's latest snapshot, or the GPU's downloaded
    /// when due (a few times a second, or after a single step). Returns how long to wait before
    /// asking again when it is too early to show.
    fn show_erosion_progress(&mut self) -> Option<Duration> {
        let s = self.erosion.session.as_mut()?;
        // Showing progress recomposes the region's quads; where that is slow (a software GPU)
        // the frames between stay as cheap as drawing, so that the window answers the user.
        let pace = Duration::from_secs_f64(SHOW_PACE * self.progress_ms.0 / 1e3).max(Duration::from_millis(400));
        if let Some(t) = s.last_shown
            && t.elapsed() < pace
        {
            return Some(pace - t.elapsed());
        }
        let snapshot = match &mut s.engine {
            Engine::Cpu(w) => w.take_snapshot(),
            Engine::Gpu(gpu) => {
                if gpu.steps() == 0 {
                    None
                } else {
                    match gpu.download() {
                        Ok(run) => Some(Snapshot::of(run, &s.base, &s.region, self.erosion.overlay)),
                        Err(e) => {
                            self.message = format!("erosion: {}", crate::errors::chain(&e));
                            s.gpu_running = false;
                            None
                        }
                    }
                }
            }
        };
        let snapshot = snapshot?;
        s.last_shown = Some(Instant::now());
        s.figures = snapshot.figures;
        let (index, region) = (s.index, s.region);
        self.editor.show_erosion(&mut self.renderer, index, snapshot.raster);
        self.set_map(snapshot.map);
        let drape = self.erosion.drape.then_some((snapshot.field.0, &region, snapshot.field.1));
        if let Err(e) = self.editor.set_erosion_overlay(&mut self.renderer, drape) {
            self.message = format!("erosion overlay: {}", crate::errors::chain(&e));
        }
        self.dirty = true;
        self.progress_ms.1 = true;
        None
    }

    /// Drops the run in progress: the layer as it was, and gone again when *start* made it.
    pub(crate) fn discard_erosion(&mut self) {
        let Some(s) = self.erosion.session.take() else { return };
        let _ = self.editor.set_erosion_overlay(&mut self.renderer, None);
        let (index, made) = (s.index, s.made_layer);
        let base = s.base.clone();
        if let Err(e) = s.finish() {
            self.message = format!("erosion: {}", crate::errors::chain(&e));
        }
        self.editor.discard_erosion(&mut self.renderer, index, base);
        self.forget_made_layer(index, made);
        self.dirty = true;
        self.update_drainage();
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
    pub(super) fn view_box(&self, half_m: f64) -> Result<crate::geodesy::GeoBox, GuiError> {
        let e = self.renderer.scene().ellipsoid;
        let ppp = self.erosion.ctx.as_ref().map_or(1.0, egui::Context::pixels_per_point);
        let centre = self.viewport_rect_px().and_then(|rect| {
            let r =
                egui::Rect::from_min_max((rect.min.to_vec2() / ppp).to_pos2(), (rect.max.to_vec2() / ppp).to_pos2());
            self.surface_at(r.center(), r)
        });
        let Some(p) = centre else { return Err(GuiError::Message("no terrain at the view's centre".into())) };
        let g = geodesy::geodetic_from_ecef(&e, p);
        Ok(crate::erosion::placement::box_around(&e, g.lat_rad.to_degrees(), g.lon_rad.to_degrees(), half_m)?)
    }

    /// Prepares a run on the erosion layer (made on top when missing): around the view's centre,
    /// or along a brush path.
    pub(crate) fn start_erosion(&mut self, brush: Option<BrushPath>) {
        let e = self.renderer.scene().ellipsoid;
        // A stream-power brush raises rock along the path; its rivers need room around it.
        let room = if self.erosion.model == Model::StreamPower { 3.0 } else { 1.0 };
        let region = match &brush {
            Some(b) => crate::erosion::placement::box_along(&e, &b.points, room * b.radius_m).within("erosion"),
            None => self.view_box(self.erosion.half_m).within("erosion"),
        };
        let region = match region {
            Ok(b) => b,
            Err(e) => {
                self.message = e.to_string();
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
        let (index, made_layer) = match index {
            Some(i) if self.project.layers[i].as_erosion().is_some() => (i, false),
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
                (top, true)
            }
        };
        if op.model == Model::StreamPower {
            self.start_landscape(index, op, made_layer);
            return;
        }
        let (region, run, base) = match self.editor.prepare_erosion(&self.renderer, index, &op) {
            Ok(prepared) => prepared,
            Err(e) => {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                self.forget_made_layer(index, made_layer);
                return;
            }
        };
        let mut op = op;
        let figures = Figures::of(&run);
        let engine = match self.editor.erosion_on_gpu(&run) {
            Some(Ok(gpu)) => {
                op.device = Device::Gpu;
                Engine::Gpu(Box::new(gpu))
            }
            Some(Err(e)) => {
                self.message = format!("erosion on the GPU: {}; on the CPU instead", crate::errors::chain(&e));
                Engine::Cpu(Worker::start(run, base.clone(), region, self.erosion.overlay))
            }
            None => Engine::Cpu(Worker::start(run, base.clone(), region, self.erosion.overlay)),
        };
        self.message = format!("erosion: {} × {} cells at level {level}", region.width, region.height);
        let keep_when_done = op.brush.is_some();
        self.erosion.session = Some(Session {
            index,
            op,
            region,
            base,
            engine,
            gpu_running: false,
            gpu_seconds: 0.0,
            last_shown: None,
            figures,
            live: None,
            made_layer,
            keep_when_done,
        });
    }

    /// Removes the erosion layer a refused or discarded run made (an empty one: the project as
    /// it was before *start*).
    pub(super) fn forget_made_layer(&mut self, index: usize, made: bool) {
        if !made || !self.project.layers.get(index).is_some_and(|l| l.runs().is_empty()) {
            return;
        }
        match self.renderer.remove_layer(index) {
            Ok(()) => {
                self.project.layers.remove(index);
            }
            Err(e) => self.message = e.to_string(),
        }
    }

    /// Records the session's run (its steps so far) on the layer.
    pub(crate) fn keep_erosion(&mut self) {
        let Some(s) = self.erosion.session.take() else { return };
        if let Err(e) = self.editor.set_erosion_overlay(&mut self.renderer, None) {
            self.message = format!("erosion overlay: {}", crate::errors::chain(&e));
        }
        let (index, op, base, region, made) = (s.index, s.op.clone(), s.base.clone(), s.region, s.made_layer);
        let (run, seconds) = match s.finish() {
            Ok(finished) => finished,
            Err(e) => {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                self.editor.discard_erosion(&mut self.renderer, index, base);
                self.forget_made_layer(index, made);
                return;
            }
        };
        if run.steps == 0 {
            self.editor.discard_erosion(&mut self.renderer, index, base);
            self.forget_made_layer(index, made);
            self.message = "erosion: no step taken, nothing kept".into();
            return;
        }
        match self.editor.commit_erosion(&mut self.renderer, index, op, base, region, &run, seconds) {
            Ok((spec, o)) => {
                self.message = format!(
                    "erosion run {} kept: {} steps, {:.1} s simulated, change {:.2} … {:.2} m",
                    spec.runs().len() - 1,
                    o.steps,
                    o.simulated_s,
                    o.range_m.0,
                    o.range_m.1
                );
                self.project.layers[index] = spec;
                self.mark_unsaved();
            }
            Err(e) => self.message = e.to_string(),
        }
        self.dirty = true;
        self.update_drainage();
    }
}
