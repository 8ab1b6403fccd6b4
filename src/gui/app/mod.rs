//! The workstation window: the viewport in the middle, the project's views, camera and visual
//! settings on the left, what is under the cursor and what the frame cost at the bottom.

use crate::gui::GuiError;
use std::path::PathBuf;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use glam::DVec3;

use super::navigate;
use super::viewport::{Viewport, frame_line};
use crate::files::lock::LockError;
use crate::geodesy;
use crate::gpu::{Editor, FrameStats, Renderer};
use crate::project::{CameraSpec, Project, ProjectError, Visuals};
use crate::scene::Camera;
use crate::scene::resolve_ramp;

mod brush;
mod debug_hook;
mod disk;
mod drainage;
mod erosion;
mod erosion_brush;
mod erosion_overlay;
mod erosion_run;
pub mod file;
pub use debug_hook::DebugHook;
mod flight;
mod landscape;
mod layers;
mod legend;
mod pointer;
mod screenshot;
use screenshot::write_screenshot;
pub use screenshot::{Outcome, ScreenshotJob};
mod profile;
mod side_panel;
mod swipe;
mod undo;

/// The workstation.
pub struct App {
    project: Project,
    project_path: PathBuf,
    renderer: Renderer,
    /// Strokes, erosion runs and undo on the renderer's layers.
    editor: Editor,
    camera: CameraSpec,
    home: CameraSpec,
    visuals: Visuals,
    threshold_px: f64,
    /// The geometric error the mesh may show, pixels (the project's `detail.max_pixel_error`).
    pixel_error: f64,
    render_scale: f32,
    viewport: Option<Viewport>,
    stats: FrameStats,
    dirty: bool,
    started: Instant,
    frames: u64,
    last_frame_ms: f64,
    /// What drawing a run's progress last cost, ms (the frame after it was handed to the
    /// renderer), and whether the next drawn frame is such a frame.
    progress_ms: (f64, bool),
    /// The gesture a press on the viewport started (navigation or a stroke), from events.
    gesture: Option<pointer::Gesture>,
    /// The button held since a press on the viewport.
    held: Option<egui::PointerButton>,
    /// A globe drag's exact anchor, still to be read back.
    anchor_query: Option<pointer::AnchorQuery>,
    /// What the surface read-back in flight was asked for.
    asked: Option<pointer::Asked>,
    hover: Option<(u32, u32)>,
    view_name: String,
    /// The tab shown below the layers: view settings or a tool.
    tab: side_panel::Tab,
    message: String,
    unsaved: bool,
    screenshot: Option<ScreenshotJob>,
    shot: Arc<Mutex<Option<Arc<egui::ColorImage>>>>,
    shot_requested: bool,
    settled_frames: u32,
    viewport_px: Option<egui::Rect>,
    /// Where the legend was drawn, physical pixels.
    legend_px: Option<egui::Rect>,
    outcome: Outcome,
    device: String,
    /// Asking whether to save before closing.
    confirm_close: bool,
    /// The user chose how to close; let the window go.
    closing: bool,
    /// The "add a dataset" form and its import in flight.
    add_dataset: crate::gui::add_dataset::AddDataset,
    cluster: crate::gui::cluster_import::ClusterImport,
    cluster_compare: crate::gui::cluster_compare::ClusterCompare,
    export_panel: crate::gui::export_panel::ExportPanel,
    /// The *Compare* section.
    compare: crate::gui::compare_panel::ComparePanel,
    /// A swipe in progress (a second renderer).
    swipe: Option<swipe::Swipe>,
    /// A swipe asked for by the panel, started on the next frame (it needs the device).
    swipe_request: Option<(String, String)>,
    /// The profile tool.
    profile: profile::ProfileTool,
    /// The drawn difference layer's range from its percentile.
    difference_range: crate::gui::difference_ui::AutoRange,
    /// The brush.
    brush: brush::BrushTool,
    /// The *Erosion* section and its run in progress.
    erosion: erosion::ErosionTool,
    /// New, open, save as, recent projects, autosave.
    file: file::FileState,
    /// Recording and replaying a camera flight.
    flight: flight::FlightTool,
    /// The project file as other processes change it.
    disk: disk::DiskState,
    /// Driven from a folder, frames slowed (the real-window tests).
    debug: Option<DebugHook>,
}

impl App {
    /// The workstation on an opened project, at `camera`.
    pub fn new(
        project: Project,
        project_path: PathBuf,
        (renderer, editor): (Renderer, Editor),
        camera: CameraSpec,
        screenshot: Option<ScreenshotJob>,
        outcome: Outcome,
        device: String,
    ) -> App {
        let visuals = renderer.scene().visuals.clone();
        let threshold_px = renderer.scene().detail.lod_threshold_px;
        let pixel_error = renderer.scene().detail.max_pixel_error;
        App {
            project,
            project_path,
            renderer,
            editor,
            camera,
            home: camera,
            visuals,
            threshold_px,
            pixel_error,
            render_scale: 1.0,
            viewport: None,
            stats: FrameStats::default(),
            dirty: true,
            started: Instant::now(),
            frames: 0,
            last_frame_ms: 0.0,
            progress_ms: (0.0, false),
            gesture: None,
            held: None,
            anchor_query: None,
            asked: None,
            hover: None,
            view_name: String::new(),
            tab: side_panel::Tab::View,
            message: String::new(),
            unsaved: false,
            screenshot,
            shot: Arc::new(Mutex::new(None)),
            shot_requested: false,
            settled_frames: 0,
            viewport_px: None,
            legend_px: None,
            outcome,
            device,
            confirm_close: false,
            closing: false,
            add_dataset: Default::default(),
            cluster: Default::default(),
            cluster_compare: Default::default(),
            export_panel: Default::default(),
            compare: Default::default(),
            difference_range: Default::default(),
            brush: Default::default(),
            erosion: Default::default(),
            flight: Default::default(),
            swipe: None,
            swipe_request: None,
            profile: Default::default(),
            file: Default::default(),
            disk: Default::default(),
            debug: None,
        }
    }

    /// Drives the window from `hook`'s folder and slows its frames (the real-window tests).
    pub fn with_debug(mut self, hook: Option<DebugHook>) -> App {
        self.debug = hook;
        self
    }

    /// Gives the window the recent projects and a recovery file to offer (when it opens).
    pub fn with_file(
        mut self,
        recent: crate::gui::recent::Recent,
        recovery: Option<crate::project::recovery::Recovery>,
    ) -> App {
        self.file.recent = recent;
        self.file.recovery = recovery;
        self
    }

    /// The current camera.
    pub fn camera(&self) -> CameraSpec {
        self.camera
    }

    /// What the last prepared frame drew (the status bar's figures).
    pub fn frame_stats(&self) -> &FrameStats {
        &self.stats
    }

    /// Whether the view is drawn and nothing is loading: every wanted quad is there, or the
    /// GPU cache is full of this frame's quads (nothing more can arrive).
    pub fn settled(&self) -> bool {
        !self.dirty
            && self.swipe_request.is_none()
            && self.swipe_settled()
            && self.frames > 0
            && (self.stats.pending == 0 || self.stats.blocked > 0)
            && self.stats.uploads == 0
            && self.stats.requested == 0
            && self.stats.composed.is_empty()
    }

    /// Whether settings changed since the project was saved.
    pub fn unsaved(&self) -> bool {
        self.unsaved
    }

    /// The project as edited so far (saved or not).
    pub fn project(&self) -> &Project {
        &self.project
    }

    /// The viewport's rectangle in the window, physical pixels (after the first frame).
    pub fn viewport_rect_px(&self) -> Option<egui::Rect> {
        self.viewport_px
    }

    /// The *Compare* section (its last results).
    pub fn compare_panel(&self) -> &crate::gui::compare_panel::ComparePanel {
        &self.compare
    }

    /// The drawn difference layer's range (metres) and whether its percentile is being computed.
    pub fn difference_range(&self) -> (f64, bool) {
        (self.renderer.difference_range_m(), self.difference_range.busy())
    }

    /// Whether the brush is on, and the stroke in progress (its path so far).
    pub fn brush_state(&self) -> (bool, usize) {
        let drawn = match &self.gesture {
            Some(pointer::Gesture::Brush(s)) => s.path.len(),
            _ => self.brush.input.as_ref().map_or(0, |s| s.path.len()),
        };
        (self.brush.on, drawn)
    }

    /// Turns the brush on or off (tests; people tick *brush*).
    pub fn set_brush(&mut self, on: bool) {
        self.brush.on = on;
    }

    /// Whether a dataset is being imported or opened in the background.
    pub fn adding_dataset(&self) -> bool {
        self.add_dataset.busy()
    }

    /// The export section (tests read its plan and outcome).
    pub fn export_panel(&self) -> &crate::gui::export_panel::ExportPanel {
        &self.export_panel
    }

    /// The cluster-comparison section (tests read its plan, rounds and result).
    pub fn cluster_compare(&self) -> &crate::gui::cluster_compare::ClusterCompare {
        &self.cluster_compare
    }

    /// The cluster-import panel (tests read its plan and shards).
    pub fn cluster_import(&self) -> &crate::gui::cluster_import::ClusterImport {
        &self.cluster
    }

    /// The last message in the status bar (saves, errors).
    pub fn message(&self) -> &str {
        &self.message
    }

    /// The layer stack the renderer composes.
    pub fn stack(&self) -> &crate::layers::Stack {
        &self.renderer.scene().stack
    }

    /// The visuals the renderer draws with.
    pub fn renderer_visuals(&self) -> &crate::project::Visuals {
        &self.renderer.scene().visuals
    }

    /// The range the renderer's colour ramp spans (metres, or degrees by slope or aspect).
    pub fn renderer_ramp_range(&self) -> (f64, f64) {
        self.renderer.scene().ramp.range_m()
    }

    /// The probe under the cursor (or at the centre without one) of the last frame.
    pub fn hit(&self) -> Option<super::viewport::Hit> {
        self.viewport.as_ref().and_then(|v| v.hits[0])
    }

    fn placed(&self) -> Camera {
        self.renderer.camera(&self.camera)
    }

    fn set_camera(&mut self, spec: CameraSpec) {
        if spec.check().is_ok() && spec != self.camera {
            self.camera = spec;
            self.dirty = true;
        }
    }

    /// Applies edited visuals (a new ramp only when the colour map changed).
    fn apply_visuals(&mut self) {
        if self.visuals == self.renderer.scene().visuals {
            return;
        }
        let ramp = if self.visuals.colour_map == self.renderer.scene().visuals.colour_map {
            Ok(self.renderer.scene().ramp.clone())
        } else {
            resolve_ramp(&self.project, &self.visuals.colour_map, self.renderer.scene().range_m)
        };
        match ramp {
            Ok(ramp) => {
                self.renderer.set_visuals(self.visuals.clone(), ramp);
                self.dirty = true;
                self.mark_unsaved();
            }
            Err(e) => {
                self.message = format!("colour map: {}", crate::errors::chain(&e));
                self.visuals.colour_map = self.renderer.scene().visuals.colour_map.clone();
            }
        }
    }

    /// Puts the window's settings into the project (what saving writes).
    fn sync_project(&mut self) {
        self.project.visuals = self.visuals.clone();
        self.project.detail.lod_threshold_px = self.threshold_px;
        self.project.detail.max_pixel_error = self.pixel_error;
    }

    fn save_project(&mut self) {
        self.sync_project();
        match self.write_project() {
            Ok(()) => {
                self.unsaved = false;
                self.file.autosaved = self.file.changes;
                crate::project::recovery::remove(&self.project_path);
                self.message = format!("saved {}", self.project_path.display());
                // The edit layers' rasters beside it, so that the session reopens without
                // replaying its strokes (a cache: a failure is reported, the project is saved).
                let scene = self.renderer.scene();
                for (index, layer) in scene.stack.layers.iter().enumerate() {
                    if layer.spec.holds_deltas()
                        && let Err(e) = scene.save_edit_cache(index)
                    {
                        self.message += &format!(
                            "; {} layer '{}' not cached: {}",
                            layer.spec.kind().name(),
                            layer.spec.name,
                            crate::errors::chain(&e)
                        );
                    }
                }
            }
            Err(ProjectError::Lock(LockError::Busy { holder, .. })) => {
                self.message = format!("waiting for {holder} to finish changing the project: saving when it is done");
            }
            Err(e) => self.message = crate::errors::chain(&e),
        }
    }

    fn save_view(&mut self) {
        let name = self.view_name.trim().to_string();
        if name.is_empty() {
            self.message = "name the view first".into();
            return;
        }
        self.project.views.insert(name.clone(), self.camera);
        self.save_project();
        if !self.unsaved {
            self.message = format!("view '{name}' saved in {}", self.project_path.display());
        }
    }

    /// Two lines of fixed height, whatever they hold (a long message is cut short, whole on
    /// hover), so that the layout never jumps and the viewport never shrinks for a message.
    fn status_bar(&self, ui: &mut egui::Ui) {
        ui.style_mut().wrap_mode = Some(egui::TextWrapMode::Truncate);
        ui.horizontal(|ui| {
            match self.viewport.as_ref().and_then(|v| v.hits[0]) {
                Some(hit) => {
                    let g = geodesy::geodetic_from_ecef(&self.renderer.scene().ellipsoid, hit.ecef);
                    let (lat, lon) = (g.lat_rad.to_degrees(), g.lon_rad.to_degrees());
                    let height = if hit.has_data { format!("{:.1} m", hit.height_m) } else { "no data".into() };
                    let quad = hit.quad.map_or(String::new(), |q| format!(" · quad {q}"));
                    ui.monospace(format!(
                        "{:.5}°{} {:.5}°{} · {height}{quad}",
                        lat.abs(),
                        if lat >= 0.0 { "N" } else { "S" },
                        lon.abs(),
                        if lon >= 0.0 { "E" } else { "W" }
                    ));
                }
                None => {
                    ui.monospace("—");
                }
            }
            ui.separator();
            ui.label(format!("camera {:.0} m", self.camera.alt));
            ui.separator();
            ui.label(frame_line(&self.stats));
            if let Some(ms) = self.viewport.as_ref().and_then(|v| v.gpu_ms) {
                ui.separator();
                ui.label(format!("GPU {ms:.2} ms"));
            }
            ui.separator();
            ui.label(format!("CPU {:.1} ms", self.last_frame_ms))
                .on_hover_text("preparing and recording the last drawn frame");
        });
        ui.horizontal(|ui| {
            let text = if self.message.is_empty() { " " } else { self.message.as_str() };
            ui.add(egui::Label::new(text).truncate()).on_hover_text(&self.message);
        });
    }

    /// The cursor's pixel (for the probe), the wheel's and a pinch's zoom towards the terrain
    /// under the cursor, and a double click's. Drags are the pointer's events' (`pointer.rs`).
    fn navigate(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        self.hover = response.hover_pos().and_then(|pos| self.target_px(pos, rect)).map(|p| (p.0 as u32, p.1 as u32));
        if !response.hovered() {
            return;
        }
        let Some((w, h)) = self.viewport.as_ref().map(|v| v.size()) else { return };
        let (scroll, zoom) = ui.input(|i| (i.smooth_scroll_delta().y, i.zoom_delta()));
        let mut factor = (-f64::from(scroll) * 0.003).exp() / f64::from(zoom);
        if response.double_clicked() {
            factor *= 0.5;
        }
        if (factor - 1.0).abs() > 1e-6 {
            let p = response.hover_pos().and_then(|pos| self.target_px(pos, rect));
            let p = p.unwrap_or((0.5 * f64::from(w), 0.5 * f64::from(h)));
            if let Some(under) = self.surface_under(p) {
                let e = self.renderer.scene().ellipsoid;
                self.set_camera(navigate::zoom(&e, &self.placed(), under, factor));
            }
        }
    }

    /// Prepares and draws the frame when anything changed or data are still arriving; probes
    /// the cursor otherwise.
    fn render(&mut self, frame: &eframe::Frame, size_px: (u32, u32)) {
        let Some(rs) = frame.wgpu_render_state() else { return };
        let scaled = (
            ((size_px.0 as f32 * self.render_scale).round() as u32).max(1),
            ((size_px.1 as f32 * self.render_scale).round() as u32).max(1),
        );
        let vp = self.viewport.get_or_insert_with(|| Viewport::new(rs, scaled.0, scaled.1));
        if vp.resize(rs, scaled.0, scaled.1) {
            self.dirty = true;
        }
        vp.collect(rs);
        let (w, h) = vp.size();
        let centre = (w / 2, h / 2);
        // The hover pixel is in target pixels already (navigation maps onto the target's size).
        let cursor = self.hover.map_or(centre, |(x, y)| (x.min(w - 1), y.min(h - 1)));
        let waiting = self.stats.pending > 0 && self.stats.blocked == 0;
        let streaming =
            waiting || self.stats.uploads > 0 || self.stats.requested > 0 || !self.stats.composed.is_empty();
        let draw_swipe = self.dirty;
        if self.dirty || streaming {
            let t = Instant::now();
            let stats = self.renderer.prepare(&self.camera, w, h);
            if let Some(e) = stats.errors.last() {
                self.message = e.clone();
            }
            // A new mesh counts too: the patches' errors arrive a frame or two after their quad
            // is composed and change the strides without any upload or composition.
            let changed = self.dirty
                || stats.uploads > 0
                || !stats.composed.is_empty()
                || stats.selection.quads != self.stats.selection.quads
                || stats.patches != self.stats.patches;
            self.stats = stats;
            if changed {
                if let Err(e) = vp.render(rs, &self.renderer, [cursor, centre]) {
                    self.message = e.to_string();
                }
                self.frames += 1;
                self.last_frame_ms = t.elapsed().as_secs_f64() * 1e3;
                if self.progress_ms.1 {
                    self.progress_ms = (self.last_frame_ms, false);
                }
            }
            self.dirty = false;
        } else if self.hover.is_some() && vp.hits[0].is_none_or(|h| h.pixel != cursor) {
            vp.probe(rs, [cursor, centre]);
        }
        self.render_swipe(rs, (w, h), draw_swipe);
    }
}

impl App {
    /// Closing with unsaved settings asks first: save, discard or stay.
    fn close_guard(&mut self, ctx: &egui::Context) {
        if ctx.input(|i| i.viewport().close_requested()) && self.unsaved && !self.closing && self.screenshot.is_none() {
            ctx.send_viewport_cmd(egui::ViewportCommand::CancelClose);
            self.confirm_close = true;
        }
        if !self.confirm_close {
            return;
        }
        let mut choice = None;
        egui::Modal::new(egui::Id::unique("unsaved")).show(ctx, |ui| {
            ui.label(format!("Save the changed settings to {}?", self.project_path.display()));
            ui.horizontal(|ui| {
                if ui.button("save and close").clicked() {
                    choice = Some(true);
                }
                if ui.button("close without saving").clicked() {
                    choice = Some(false);
                }
                if ui.button("cancel").clicked() {
                    self.confirm_close = false;
                }
            });
        });
        if let Some(save) = choice {
            if save {
                self.save_project();
                if self.unsaved {
                    // Saving failed: the message says why; stay open.
                    self.confirm_close = false;
                    return;
                }
            }
            if !save {
                // The user chose to drop the changes: the recovery file goes with them.
                crate::project::recovery::remove(&self.project_path);
            }
            self.closing = true;
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
    }
}

impl eframe::App for App {
    fn ui(&mut self, ui: &mut egui::Ui, frame: &mut eframe::Frame) {
        let started = Instant::now();
        self.finish_open(frame);
        egui::Panel::top("file").show(ui, |ui| self.file_bar(ui));
        egui::Panel::bottom("status").show(ui, |ui| self.status_bar(ui));
        egui::Panel::left("settings").default_size(290.0).resizable(true).show(ui, |ui| self.side_panel(ui));
        egui::CentralPanel::no_frame().show(ui, |ui| {
            let ppp = ui.ctx().pixels_per_point();
            // Whole physical pixels, so that the image maps 1:1 onto the window at scale 1.
            let avail = ui.available_rect_before_wrap();
            let rect = egui::Rect::from_min_max(
                ((avail.min.to_vec2() * ppp).ceil() / ppp).to_pos2(),
                ((avail.max.to_vec2() * ppp).floor() / ppp).to_pos2(),
            );
            let response = ui.allocate_rect(rect, egui::Sense::click_and_drag());
            // With linked views each picture takes half the width.
            let view = self.view_rect(ui, rect);
            let size_px = ((view.width() * ppp).round() as u32, (view.height() * ppp).round() as u32);
            self.viewport_px = Some(egui::Rect::from_min_size((view.min.to_vec2() * ppp).to_pos2(), view.size() * ppp));
            if let (Some((a, b)), Some(rs)) = (self.swipe_request.take(), frame.wgpu_render_state())
                && let Err(e) = self.start_swipe(rs, &a, &b)
            {
                self.message = e.to_string();
            }
            // The pointer's events on the viewport, in the order they happened (a press, its
            // moves and its release may all fall between two frames).
            let steps = pointer::viewport_steps(ui.ctx(), response.layer_id, view, &mut self.held);
            self.keys(ui);
            self.erosion_frame(ui.ctx());
            self.flight_frame(ui.ctx());
            if !self.drag_swipe(&steps, rect) && !self.pick_profile(&response, view) {
                self.pointer_steps(&steps, view);
                self.navigate(ui, &response, view);
            }
            self.brush_hover(ui, &response, view);
            if let Some(rs) = frame.wgpu_render_state() {
                self.pointer_frame(rs);
            }
            self.brush_frame();
            self.erosion_brush_frame();
            if self.gesture.is_some()
                || self.brush.input.is_some()
                || self.erosion.input.is_some()
                || self.pointer_busy()
            {
                ui.ctx().request_repaint();
            }
            self.render(frame, size_px);
            if !self.paint_swipe(ui, rect)
                && let Some(vp) = &self.viewport
            {
                let uv = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
                ui.painter().image(vp.texture, rect, uv, egui::Color32::WHITE);
            }
            if self.viewport.is_some() {
                self.legend(ui, view);
            }
            self.mode_banner(ui, view);
        });
        if self.stats.pending > 0 || self.stats.uploads > 0 || self.stats.requested > 0 || !self.swipe_settled() {
            ui.ctx().request_repaint_after(Duration::from_millis(30));
        }
        self.screenshot(ui);
        self.autosave();
        self.watch_disk();
        self.update_title(ui.ctx());
        self.file_dialogs(ui.ctx());
        self.conflict_dialog(ui.ctx());
        if self.file.opening.is_some() {
            ui.ctx().request_repaint_after(Duration::from_millis(50));
        }
        self.close_guard(ui.ctx());
        self.debug_frame(ui.ctx(), started.elapsed());
    }
}
