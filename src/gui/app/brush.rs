//! Brushing in the workstation: the *Brush* section (tool, radius, strength, falloff, spacing, the
//! edit layer painted on, undo and redo), the footprint drawn on the terrain under the cursor, and
//! strokes by left drag while the brush is on (navigation stays on the other buttons and on
//! Shift/Ctrl + left). The path is the terrain point under the cursor each frame (the probe's, or
//! the mean sphere's until the probe catches up); while dragging, the stroke so far is applied
//! provisionally every few frames (the previous provisional version undone from the undo history,
//! which is instant), and on release the whole stroke replaces it, through
//! `Editor::apply_stroke`, as `terrafuse brush` would append it.
//! Ctrl+Z and Ctrl+Shift+Z undo and redo on the edit layer.

use super::*;
use crate::edit::{Falloff, Stroke, Tool};
use crate::layers::LayerSpec;
use crate::store::grid::spacing_m;

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
    /// The path so far, `[lat, lon]` degrees.
    pub(crate) path: Vec<[f64; 2]>,
    painting: bool,
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
            path: Vec::new(),
            painting: false,
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

impl App {
    /// The *Brush* section, its action applied.
    pub(super) fn brush_ui(&mut self, ui: &mut egui::Ui) {
        match self.brush.ui(ui, &self.project) {
            Some(BrushAction::Undo) => self.move_undo(-1),
            Some(BrushAction::Redo) => self.move_undo(1),
            None => {}
        }
    }

    /// Ctrl+Z and Ctrl+Shift+Z (when no text field has the keyboard).
    pub(super) fn brush_keys(&mut self, ui: &egui::Ui) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        let (undo, redo) = ui.input(|i| {
            let z = i.key_pressed(egui::Key::Z) && i.modifiers.command;
            (z && !i.modifiers.shift, z && i.modifiers.shift)
        });
        if undo {
            self.move_undo(-1);
        } else if redo {
            self.move_undo(1);
        }
    }

    fn move_undo(&mut self, by: i64) {
        let Some(index) = self.project.layers.iter().position(|l| l.name == self.brush.layer) else { return };
        let applied = self.project.layers[index].applied_strokes().len() as i64 + by;
        let total = self.project.layers[index].strokes().len() as i64;
        if !(0..=total).contains(&applied) {
            return;
        }
        match self.editor.set_applied(&mut self.renderer, index, applied as usize) {
            Ok(spec) => {
                self.project.layers[index] = spec;
                self.dirty = true;
                self.mark_unsaved();
                self.message = format!("{} to {applied} of {total} strokes", if by < 0 { "undone" } else { "redone" });
            }
            Err(e) => self.message = e.to_string(),
        }
    }

    /// Takes the viewport's input while the brush is on: the footprint follows the cursor, a left
    /// drag records a stroke, its release applies it. True when the input was the brush's.
    pub(super) fn paint(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) -> bool {
        if !self.brush.on {
            self.renderer.set_brush_ring(None);
            return false;
        }
        let under = response.hover_pos().or(response.interact_pointer_pos()).and_then(|p| self.surface_at(p, rect));
        let ring = under.map(|p| (p, self.brush.radius_m * self.renderer.scene().visuals.exaggeration.max(1.0)));
        self.renderer.set_brush_ring(ring);
        if response.hovered() {
            self.dirty = true; // the ring moves with the cursor
        }
        let modifiers = ui.input(|i| i.modifiers);
        let plain = !modifiers.shift && !modifiers.command;
        if response.clicked_by(egui::PointerButton::Primary) && plain {
            // A click is one dab.
            if let Some(p) = under {
                let g = geodesy::geodetic_from_ecef(&self.renderer.scene().ellipsoid, p);
                self.apply_brush_stroke(vec![[g.lat_rad.to_degrees(), g.lon_rad.to_degrees()]]);
            }
            return true;
        }
        if response.drag_started_by(egui::PointerButton::Primary) && plain {
            self.brush.painting = true;
            self.brush.path.clear();
        }
        if !self.brush.painting {
            return false;
        }
        if let Some(p) = under {
            let g = geodesy::geodetic_from_ecef(&self.renderer.scene().ellipsoid, p);
            let point = [g.lat_rad.to_degrees(), g.lon_rad.to_degrees()];
            if self.brush.path.last() != Some(&point) {
                self.brush.path.push(point);
                let due = self.brush.last_preview.is_none_or(|t| t.elapsed() > Duration::from_millis(80));
                // A ramp needs its two ends before it shows.
                let shows = self.brush.tool != Tool::Ramp || self.brush.path.len() >= 2;
                if due && shows && response.dragged() && !response.drag_stopped() {
                    self.brush.last_preview = Some(Instant::now());
                    let path = self.brush.path.clone();
                    self.apply_brush_stroke(path);
                }
            }
        }
        if response.drag_stopped() || !response.dragged() {
            self.brush.painting = false;
            self.brush.last_preview = None;
            let path = std::mem::take(&mut self.brush.path);
            if !path.is_empty() {
                self.apply_brush_stroke(path);
            }
        }
        true
    }

    /// The terrain point (ECEF) under a window position: the probe's when it is for that pixel,
    /// else the mean sphere's.
    pub(super) fn surface_at(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<DVec3> {
        let vp = self.viewport.as_ref()?;
        let (w, h) = vp.size();
        let px = (
            f64::from((pos.x - rect.min.x) / rect.width()) * f64::from(w),
            f64::from((pos.y - rect.min.y) / rect.height()) * f64::from(h),
        );
        let hit = vp.hits[0]
            .filter(|hit| (f64::from(hit.pixel.0) - px.0).abs() < 3.0 && (f64::from(hit.pixel.1) - px.1).abs() < 3.0);
        Some(hit.map_or_else(
            || {
                let cam = self.placed();
                navigate::fallback_target(&self.renderer.scene().ellipsoid, &cam, cam.ray(px.0, px.1, w, h))
            },
            |hit| hit.ecef,
        ))
    }

    /// Appends a stroke along `path` to the brush's edit layer (made on top of the stack when the
    /// project has none of that name).
    pub(crate) fn apply_brush_stroke(&mut self, path: Vec<[f64; 2]>) {
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
        match self.editor.apply_stroke_on(&mut self.renderer, index, stroke, self.brush.painting) {
            Ok(spec) => {
                if self.brush.painting {
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
