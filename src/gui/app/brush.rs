//! Brushing in the workstation: the *Brush* section (tool, radius, strength, falloff, spacing, the
//! edit layer painted on, undo and redo), the footprint drawn on the terrain under the cursor, and
//! strokes by left drag while the brush is armed (navigation stays on the other buttons and on
//! Shift/Ctrl + left). The brush is armed on the *Brush* tab only, unless *keep armed on other
//! tabs* pins it; armed, the cursor is a crosshair, and on another tab the viewport says so.
//! The stroke's points come from the pointer's events ([`super::pointer`]): the terrain under
//! each press, move and release, read back from the surface target. While dragging, the stroke
//! so far is applied provisionally every few frames (the previous provisional version undone from
//! the undo history, which is instant); once released and every point is known, the whole
//! stroke replaces it, through `Editor::apply_stroke`, as `terrafuse brush` would append it.
use super::*;
use crate::ecm::grid::spacing_m;
use crate::edit::{Falloff, Stroke, Tool};
use crate::layers::LayerSpec;

/// The brush's settings and the stroke in progress.
pub(crate) struct BrushTool {
    pub(crate) on: bool,
    tool: Tool,
    radius_m: f64,
    /// Metres per dab for raise, lower and noise; a fraction for the others.
    strength_m: f64,
    fraction: f64,
    falloff: Falloff,
    spacing: f64,
    seed: u32,
    /// Flatten: to this height (else to the terrain's under the stroke's first point).
    flatten_to: Option<f64>,
    layer: String,
    /// Armed on every tab, not only on *Brush*.
    pub(crate) pinned: bool,
    /// A stroke released and still being turned into points.
    pub(crate) input: Option<super::pointer::StrokeInput>,
    /// While dragging: the edit layer and its strokes in effect before the stroke, once the
    /// stroke so far has been applied provisionally (the terrain updates during the drag).
    preview: Option<(usize, usize)>,
    last_preview: Option<Instant>,
}

impl Default for BrushTool {
    fn default() -> BrushTool {
        BrushTool {
            on: false,
            tool: Tool::Raise,
            radius_m: 2000.0,
            strength_m: 20.0,
            fraction: 0.5,
            falloff: Falloff::Smooth,
            spacing: 0.25,
            seed: 1,
            flatten_to: None,
            layer: "sculpt".into(),
            pinned: false,
            input: None,
            preview: None,
            last_preview: None,
        }
    }
}

/// What the *Brush* section asks the workstation to do.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum BrushAction {
    /// Move the edit layer's undo position back one stroke.
    Undo,
    /// Forward one stroke.
    Redo,
}

impl BrushTool {
    /// The *Brush* section: its settings, edited in place, and undo and redo for the edit layer
    /// of `project` it paints on.
    pub(crate) fn ui(&mut self, ui: &mut egui::Ui, project: &Project) -> Option<BrushAction> {
        let b = self;
        ui.checkbox(&mut b.on, "brush (left drag paints)")
            .on_hover_text("navigate with the right or middle button, or Shift/Ctrl + left");
        ui.checkbox(&mut b.pinned, "keep armed on other tabs").on_hover_text("else leaving this tab disarms the brush");
        egui::ComboBox::from_label("tool").selected_text(b.tool.name()).show_ui(ui, |ui| {
            for t in Tool::ALL {
                ui.selectable_value(&mut b.tool, t, t.name());
            }
        });
        ui.add(egui::Slider::new(&mut b.radius_m, 10.0..=200_000.0).logarithmic(true).text("radius m"));
        if b.tool.strength_in_metres() {
            ui.add(egui::Slider::new(&mut b.strength_m, 0.1..=2000.0).logarithmic(true).text("m per dab"));
        } else {
            ui.add(egui::Slider::new(&mut b.fraction, 0.01..=1.0).text("fraction per dab"));
        }
        egui::ComboBox::from_label("falloff").selected_text(b.falloff.name()).show_ui(ui, |ui| {
            for f in Falloff::ALL {
                ui.selectable_value(&mut b.falloff, f, f.name());
            }
        });
        ui.add(egui::Slider::new(&mut b.spacing, 0.05..=2.0).text("spacing (radius)"));
        if b.tool == Tool::Noise {
            ui.add(egui::DragValue::new(&mut b.seed).prefix("seed "));
        }
        if b.tool == Tool::Flatten {
            ui.horizontal(|ui| {
                let mut fixed = b.flatten_to.is_some();
                let label = ui
                    .checkbox(&mut fixed, "to height")
                    .on_hover_text("off: to the terrain's height under the stroke's first point")
                    .id;
                match (fixed, b.flatten_to) {
                    (true, None) => b.flatten_to = Some(0.0),
                    (false, Some(_)) => b.flatten_to = None,
                    _ => {}
                }
                if let Some(h) = &mut b.flatten_to {
                    ui.add(egui::DragValue::new(h).speed(1.0).suffix(" m")).labelled_by(label);
                }
            });
        }
        if b.tool == Tool::Ramp {
            ui.label("ramp: from the terrain under the drag's start to that under its end");
        }
        ui.horizontal(|ui| {
            let label = ui.label("edit layer").id;
            ui.text_edit_singleline(&mut b.layer).labelled_by(label);
        });
        let index = project.layers.iter().position(|l| l.name == b.layer && l.as_edit().is_some());
        let (applied, total) = index.map_or((0, 0), |i| {
            let l = &project.layers[i];
            (l.applied_strokes().len(), l.strokes().len())
        });
        ui.horizontal(|ui| {
            let mut action = None;
            if ui.add_enabled(applied > 0, egui::Button::new("undo")).on_hover_text("Ctrl+Z").clicked() {
                action = Some(BrushAction::Undo);
            }
            if ui.add_enabled(applied < total, egui::Button::new("redo")).on_hover_text("Ctrl+Shift+Z").clicked() {
                action = Some(BrushAction::Redo);
            }
            ui.label(format!("{applied} of {total} strokes"));
            action
        })
        .inner
    }
}

impl BrushTool {
    /// The tool's name (`raise`, …).
    pub(crate) fn tool_name(&self) -> &'static str {
        self.tool.name()
    }

    /// The edit layer it paints on.
    pub(crate) fn layer_name(&self) -> &str {
        &self.layer
    }
}

impl App {
    /// The *Brush* section, its action applied.
    pub(super) fn brush_ui(&mut self, ui: &mut egui::Ui) {
        match self.brush.ui(ui, &self.project) {
            Some(BrushAction::Undo) => self.brush_undo(-1),
            Some(BrushAction::Redo) => self.brush_undo(1),
            None => {}
        }
    }

    /// Moves the brush's edit layer's undo position by `by` strokes (its buttons, Ctrl+Z and
    /// Ctrl+Shift+Z).
    pub(super) fn brush_undo(&mut self, by: i64) {
        let layer = self.brush.layer.clone();
        self.move_layer_undo(&layer, by);
    }

    /// Whether a left drag on the viewport paints: the brush is on, and this is its tab or it
    /// is pinned.
    pub(super) fn brush_armed(&self) -> bool {
        self.brush.on && (self.tab == side_panel::Tab::Brush || self.brush.pinned)
    }

    /// The brush's footprint under the cursor while it is armed (a ring on the terrain), and the
    /// crosshair cursor over the viewport.
    pub(super) fn brush_hover(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) {
        if !self.brush_armed() {
            self.renderer.set_brush_ring(None);
            return;
        }
        let under = response.hover_pos().and_then(|p| self.surface_at(p, rect));
        let ring = under.map(|p| (p, self.brush.radius_m * self.renderer.scene().visuals.exaggeration.max(1.0)));
        self.renderer.set_brush_ring(ring);
        if response.hovered() {
            self.dirty = true; // the ring moves with the cursor
            ui.ctx().set_cursor_icon(egui::CursorIcon::Crosshair);
        }
    }

    /// Each frame: the stroke being drawn turned into points; shown provisionally every few
    /// frames while the button is down, applied whole once released and complete.
    pub(super) fn brush_frame(&mut self) {
        let busy = self.pointer_busy();
        let due = self.brush.last_preview.is_none_or(|t| t.elapsed() > Duration::from_millis(80));
        let ramp = self.brush.tool == Tool::Ramp;
        let preview = match &mut self.gesture {
            // A ramp needs its two ends before it shows.
            Some(super::pointer::Gesture::Brush(s)) if due && (!ramp || s.path.len() >= 2) => {
                s.grew().then(|| s.path.clone())
            }
            _ => None,
        };
        if let Some(path) = preview {
            self.brush.last_preview = Some(Instant::now());
            self.apply_brush_stroke(path, true);
            return;
        }
        if !self.brush.input.as_ref().is_some_and(|s| s.complete(busy)) {
            return;
        }
        let path = self.brush.input.take().map(|s| s.path).unwrap_or_default();
        self.brush.last_preview = None;
        if path.is_empty() {
            // Nothing under the stroke (off the globe): the provisional one goes.
            if let Some((index, before)) = self.brush.preview.take()
                && let Ok(spec) = self.editor.set_applied(&mut self.renderer, index, before)
            {
                self.project.layers[index] = spec;
            }
        } else {
            self.apply_brush_stroke(path, false);
        }
    }

    /// The terrain point (ECEF) under a window position on the viewport `rect`: the probe's when
    /// it is for that pixel, else the mean sphere's.
    pub(super) fn surface_at(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<DVec3> {
        self.surface_under(self.target_px(pos, rect)?)
    }

    /// Appends a stroke along `path` to the brush's edit layer (made on top of the stack when the
    /// project has none of that name).
    pub(crate) fn apply_brush_stroke(&mut self, path: Vec<[f64; 2]>, provisional: bool) {
        // The provisional version of this stroke, if any, goes first (instant: from the history).
        if let Some((index, before)) = self.brush.preview.take() {
            match self.editor.set_applied(&mut self.renderer, index, before) {
                Ok(spec) => self.project.layers[index] = spec,
                Err(e) => {
                    self.message = e.to_string();
                    return;
                }
            }
        }
        let b = &self.brush;
        let e = self.renderer.scene().ellipsoid;
        let level = (0..=crate::edit::stroke::MAX_LEVEL)
            .find(|l| spacing_m(&e, *l) <= b.radius_m / 10.0)
            .unwrap_or(crate::edit::stroke::MAX_LEVEL);
        let stroke = Stroke {
            tool: b.tool,
            radius_m: b.radius_m,
            strength: if b.tool.strength_in_metres() { b.strength_m } else { b.fraction },
            falloff: b.falloff,
            spacing: b.spacing,
            level,
            path,
            seed: b.seed,
            height_m: if b.tool == Tool::Flatten { b.flatten_to } else { None },
        };
        let name = b.layer.clone();
        let index = match self.project.layers.iter().position(|l| l.name == name) {
            Some(i) => i,
            None => {
                let spec = LayerSpec::edit(&name);
                let top = self.project.layers.len();
                if let Err(e) = self.renderer.insert_layer(top, spec.clone()) {
                    self.message = e.to_string();
                    return;
                }
                self.project.layers.push(spec);
                top
            }
        };
        let t = Instant::now();
        let before = self.project.layers[index].applied_strokes().len();
        // While dragging, the stroke so far is shown from the GPU rasteriser (where the adapter
        // is hardware); the stroke kept, on release, is the CPU reference's.
        match self.editor.apply_stroke_on(&mut self.renderer, index, stroke, provisional) {
            Ok(spec) => {
                if provisional {
                    self.brush.preview = Some((index, before));
                }
                self.message = format!(
                    "stroke {} on '{name}' ({:.0} ms to rasterise)",
                    spec.strokes().len() - 1,
                    t.elapsed().as_secs_f64() * 1e3
                );
                self.project.layers[index] = spec;
                self.dirty = true;
                self.mark_unsaved();
            }
            Err(e) => self.message = e.to_string(),
        }
    }
}
