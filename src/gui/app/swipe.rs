//! Swipe in the workstation: layer A left of a vertical line, layer B right of it, from one
//! camera. The window's renderer shows the project with A shown and B hidden; a second renderer
//! on the same device shows it with B shown and A hidden, into a viewport of its own; the two
//! pictures are painted on either side of the line, which is dragged sideways.

use super::*;
use crate::gpu::GpuContext;
use crate::gui::GuiError;
use crate::layers::LayerSpec;

/// Within this many points of the line a drag moves the line instead of the camera.
const GRAB_PT: f32 = 8.0;

/// A swipe in progress.
pub(crate) struct Swipe {
    /// The layer left of the line.
    pub(crate) a: String,
    /// The layer right of the line.
    pub(crate) b: String,
    /// Where the line is, 0–1 of the viewport's width.
    pub(crate) position: f32,
    /// Two linked views side by side (each the whole picture at half the width) instead of
    /// one picture split at the line.
    pub(crate) side_by_side: bool,
    /// The stack with B shown and A hidden.
    pub(crate) renderer: Renderer,
    viewport: Option<Viewport>,
    stats: FrameStats,
    dragging: bool,
}

impl App {
    /// Starts swiping layer `a` (left) against layer `b` (right): A is shown and B hidden in the
    /// window's stack, and a second renderer shows the reverse.
    pub(super) fn start_swipe(&mut self, rs: &egui_wgpu::RenderState, a: &str, b: &str) -> Result<(), GuiError> {
        let index = |name: &str| {
            self.project
                .layers
                .iter()
                .position(|l| l.name == name)
                .ok_or(format!("layer '{name}' is not in the project"))
        };
        let (ia, ib) = (index(a)?, index(b)?);
        // A swipe shows the layers themselves: no difference drawn over either side, but the ones
        // swiped (as `render --swipe` draws them).
        let differences = self
            .project
            .layers
            .iter()
            .enumerate()
            .filter(|(i, l)| *i != ia && *i != ib && !l.gives_heights() && l.visible);
        let hide: Vec<(usize, bool)> = differences.map(|(i, _)| (i, false)).collect();
        for (i, visible) in [(ia, true), (ib, false)].into_iter().chain(hide) {
            let spec = LayerSpec { visible, ..self.project.layers[i].clone() };
            self.renderer.update_layer(i, spec.clone())?;
            self.project.layers[i] = spec;
        }
        let mut other = self.project.clone();
        other.layers[ia].visible = false;
        other.layers[ib].visible = true;
        let (scene, _) = crate::scene::Scene::open(&other)?;
        let ctx = GpuContext {
            device: rs.device.clone(),
            queue: rs.queue.clone(),
            info: rs.adapter.get_info(),
            timestamps: rs.device.features().contains(wgpu::Features::TIMESTAMP_QUERY),
        };
        let mut renderer = Renderer::new(&ctx, scene, crate::gpu::IMAGE_FORMAT)?;
        renderer.set_threshold(self.threshold_px);
        renderer.set_pixel_error(self.pixel_error);
        // A difference layer shown on the second side, with its colour range like the first's.
        if let Some(d) = renderer.scene().stack.drawn_difference() {
            let spec = renderer.scene().stack.layers[d].spec.clone();
            if spec.difference_style().range_m.is_none() {
                let range = crate::compare::difference_range(&other, &spec)?;
                renderer.set_difference_range(range);
            }
        }
        self.swipe = Some(Swipe {
            a: a.into(),
            b: b.into(),
            position: 0.5,
            side_by_side: false,
            renderer,
            viewport: None,
            stats: FrameStats::default(),
            dragging: false,
        });
        self.dirty = true;
        self.message = format!("swipe: '{a}' left of the line, '{b}' right of it");
        Ok(())
    }

    /// The second picture, drawn when the first is (or while its own data stream in).
    pub(super) fn render_swipe(&mut self, rs: &egui_wgpu::RenderState, size: (u32, u32), draw: bool) {
        let camera = self.camera;
        let Some(s) = &mut self.swipe else { return };
        let vp = s.viewport.get_or_insert_with(|| Viewport::new(rs, size.0, size.1));
        let resized = vp.resize(rs, size.0, size.1);
        vp.collect(rs);
        let streaming =
            s.stats.pending > 0 || s.stats.uploads > 0 || s.stats.requested > 0 || !s.stats.composed.is_empty();
        if draw || resized || streaming || s.stats.selection.quads.is_empty() {
            s.stats = s.renderer.prepare(&camera, size.0, size.1);
            let centre = (size.0 / 2, size.1 / 2);
            if let Err(e) = vp.render(rs, &s.renderer, [centre, centre]) {
                self.message = e.to_string();
            }
        }
    }

    /// Whether the second picture is complete.
    pub(super) fn swipe_settled(&self) -> bool {
        self.swipe.as_ref().is_none_or(|s| {
            (s.stats.pending == 0 || s.stats.blocked > 0)
                && s.stats.uploads == 0
                && s.stats.requested == 0
                && s.stats.composed.is_empty()
        })
    }

    /// Moves the line when a press lands on it, from the pointer's events (`steps`, in points):
    /// true while the line is being dragged, the camera then staying.
    pub(super) fn drag_swipe(&mut self, steps: &[pointer::Step], rect: egui::Rect) -> bool {
        let Some(s) = &mut self.swipe else { return false };
        if s.side_by_side {
            return false;
        }
        let was = s.dragging;
        for step in steps {
            match *step {
                pointer::Step::Press { pos, button: egui::PointerButton::Primary, .. } => {
                    let line_x = rect.left() + s.position * rect.width();
                    s.dragging = (pos.x - line_x).abs() <= GRAB_PT;
                }
                pointer::Step::Move { pos } if s.dragging => {
                    s.position = ((pos.x - rect.left()) / rect.width()).clamp(0.0, 1.0);
                }
                pointer::Step::Release { pos } if s.dragging => {
                    s.position = ((pos.x - rect.left()) / rect.width()).clamp(0.0, 1.0);
                    s.dragging = false;
                    return true;
                }
                _ => {}
            }
        }
        was || s.dragging
    }

    /// Paints both pictures, split at the line, and the line.
    pub(super) fn paint_swipe(&self, ui: &egui::Ui, rect: egui::Rect) -> bool {
        let (Some(s), Some(main)) = (&self.swipe, &self.viewport) else { return false };
        let Some(other) = &s.viewport else { return false };
        let whole = egui::Rect::from_min_max(egui::pos2(0.0, 0.0), egui::pos2(1.0, 1.0));
        if s.side_by_side {
            let (left, right) = halves(rect);
            ui.painter().image(main.texture, left, whole, egui::Color32::WHITE);
            ui.painter().image(other.texture, right, whole, egui::Color32::WHITE);
            ui.painter().vline(right.left(), rect.y_range(), egui::Stroke::new(2.0, egui::Color32::WHITE));
            for (text, r) in [(&s.a, left), (&s.b, right)] {
                ui.painter().text(
                    r.left_top() + egui::vec2(6.0, 6.0),
                    egui::Align2::LEFT_TOP,
                    text,
                    egui::FontId::proportional(13.0),
                    egui::Color32::WHITE,
                );
            }
            return true;
        }
        let split = rect.left() + s.position * rect.width();
        let left = egui::Rect::from_min_max(rect.min, egui::pos2(split, rect.bottom()));
        let right = egui::Rect::from_min_max(egui::pos2(split, rect.top()), rect.max);
        let uv = |x0: f32, x1: f32| egui::Rect::from_min_max(egui::pos2(x0, 0.0), egui::pos2(x1, 1.0));
        ui.painter().image(main.texture, left, uv(0.0, s.position), egui::Color32::WHITE);
        ui.painter().image(other.texture, right, uv(s.position, 1.0), egui::Color32::WHITE);
        ui.painter().vline(split, rect.y_range(), egui::Stroke::new(2.0, egui::Color32::WHITE));
        let label = |text: &str, pos: egui::Pos2, align: egui::Align2| {
            ui.painter().text(pos, align, text, egui::FontId::proportional(13.0), egui::Color32::WHITE);
        };
        label(&s.a, egui::pos2(split - 6.0, rect.top() + 6.0), egui::Align2::RIGHT_TOP);
        label(&s.b, egui::pos2(split + 6.0, rect.top() + 6.0), egui::Align2::LEFT_TOP);
        true
    }

    /// Whether the view shows two linked views side by side.
    pub fn side_by_side(&self) -> bool {
        self.swipe.as_ref().is_some_and(|s| s.side_by_side)
    }

    /// The rectangle a view is drawn in: the whole viewport, or with linked views the half under
    /// the pointer (both halves show the same camera, so either maps pointer positions alike).
    pub(super) fn view_rect(&self, ui: &egui::Ui, rect: egui::Rect) -> egui::Rect {
        if !self.side_by_side() {
            return rect;
        }
        let (left, right) = halves(rect);
        match ui.input(|i| i.pointer.latest_pos()) {
            Some(p) if right.contains(p) => right,
            _ => left,
        }
    }

    /// Where the swipe's line is (0–1 of the width), if swiping.
    pub fn swipe_position(&self) -> Option<f32> {
        self.swipe.as_ref().map(|s| s.position)
    }

    /// The second renderer's stack, if swiping.
    pub fn swipe_stack(&self) -> Option<&crate::layers::Stack> {
        self.swipe.as_ref().map(|s| &s.renderer.scene().stack)
    }
}

/// The left and right halves of a rectangle.
fn halves(rect: egui::Rect) -> (egui::Rect, egui::Rect) {
    let mid = rect.center().x;
    (
        egui::Rect::from_min_max(rect.min, egui::pos2(mid, rect.bottom())),
        egui::Rect::from_min_max(egui::pos2(mid, rect.top()), rect.max),
    )
}
