//! The viewport's pointer and keys from the events of a frame, not from where the pointer is
//! when the frame is drawn. At one frame a second (a software GPU, a big stroke being applied)
//! a press, its moves and its release can all arrive between two frames; reading the pointer's
//! position once a frame lost the start of a stroke, part of a drag and whole quick flicks.
//! So every pointer event egui delivers is taken in order:
//! - a press on the viewport (inside it, on its own layer: not under a window or a menu) starts
//!   a gesture: a brush stroke or an erosion-brush path where that tool is armed and no modifier
//!   is held, else navigation (left: move the globe, the grabbed point staying under the cursor;
//!   right or Ctrl + left: orbit; middle or Shift + left: look around);
//! - each move continues it, from the position of the move (not the frame's);
//! - the release ends it, at the position of the release.
//!
//! A stroke's points are the terrain under each event's pixel, read back from the last rendered
//! frame's surface target a few hundred at a time ([`super::super::viewport::Viewport::query`]),
//! so a stroke starts where the button went down and follows the path drawn, whatever the frame
//! time. Shortcuts act on key-press events, once per press (a key's repeats are ignored), with the
//! modifiers of that event: Ctrl+Z tapped between two frames undoes exactly one stroke, and a
//! shortcut with a modifier never also triggers the bare key's action.

use std::collections::VecDeque;

use super::*;

/// One pointer event that belongs to the viewport, in the order it happened.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Step {
    /// A button went down on the viewport.
    Press { pos: egui::Pos2, button: egui::PointerButton, modifiers: egui::Modifiers },
    /// The pointer moved while that button is held.
    Move { pos: egui::Pos2 },
    /// The button came up.
    Release { pos: egui::Pos2 },
}

/// A gesture in progress on the viewport.
#[derive(Clone, Debug)]
pub(super) enum Gesture {
    /// The grabbed point (ECEF) stays under the cursor.
    Globe(DVec3),
    /// Orbit about a point; the last position.
    Orbit(DVec3, egui::Pos2),
    /// Turn in place; the last position.
    Look(egui::Pos2),
    /// A brush stroke's pixels.
    Brush(StrokeInput),
    /// An erosion brush's pixels.
    Erode(StrokeInput),
}

/// The terrain under the pixel a globe drag was pressed on, asked of the surface target (the
/// anchor taken at the press is the probe's or the mean sphere's until it answers; the drag is
/// then redone about the exact point, the grabbed point under the cursor).
#[derive(Clone, Copy, Debug)]
pub(super) struct AnchorQuery {
    pixel: (u32, u32),
    /// The pointer's last position and the viewport then.
    last: egui::Pos2,
    rect: egui::Rect,
}

/// What the read-back in flight was asked for.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Asked {
    Anchor,
    Stroke,
}

/// The pixels of a stroke as the pointer drew them, turned into terrain points as the surface
/// target's read-back answers.
#[derive(Clone, Debug, Default)]
pub(crate) struct StrokeInput {
    /// Target pixels not asked for yet, in order.
    pending: VecDeque<(u32, u32)>,
    /// The last pixel added (repeats are dropped).
    last: Option<(u32, u32)>,
    /// The points resolved so far, `[lat, lon]` degrees.
    pub(crate) path: Vec<[f64; 2]>,
    /// Whether the button came up.
    pub(crate) released: bool,
    /// How many of the points were shown last (a provisional stroke).
    pub(crate) shown: usize,
}

impl StrokeInput {
    fn push(&mut self, pixel: (u32, u32)) {
        if self.last != Some(pixel) {
            self.pending.push_back(pixel);
            self.last = Some(pixel);
        }
    }

    /// Whether every pixel drawn has been turned into a point and the button is up.
    pub(crate) fn complete(&self, querying: bool) -> bool {
        self.released && self.pending.is_empty() && !querying
    }

    /// Whether points came since the last provisional showing (and marks them shown).
    pub(crate) fn grew(&mut self) -> bool {
        let grew = self.path.len() > self.shown;
        self.shown = self.path.len();
        grew
    }
}

/// The pointer events of this frame that belong to the viewport `rect` on `layer`: a press
/// inside it on that layer, then every move and the release of that button (wherever they
/// are). `held` carries the held button from frame to frame.
pub(super) fn viewport_steps(
    ctx: &egui::Context,
    layer: egui::LayerId,
    rect: egui::Rect,
    held: &mut Option<egui::PointerButton>,
) -> Vec<Step> {
    let events = ctx.input(|i| i.events.clone());
    let mut steps = Vec::new();
    for event in events {
        match event {
            egui::Event::PointerButton { pos, button, pressed: true, modifiers } if held.is_none() => {
                let ours = rect.contains(pos) && ctx.layer_id_at(pos).is_none_or(|l| l == layer);
                if ours {
                    *held = Some(button);
                    steps.push(Step::Press { pos, button, modifiers });
                }
            }
            egui::Event::PointerMoved(pos) if held.is_some() => steps.push(Step::Move { pos }),
            egui::Event::PointerButton { pos, button, pressed: false, .. } if *held == Some(button) => {
                *held = None;
                steps.push(Step::Release { pos });
            }
            egui::Event::PointerGone if held.is_some() => {
                *held = None;
                let pos = ctx.input(|i| i.pointer.latest_pos()).unwrap_or(rect.center());
                steps.push(Step::Release { pos });
            }
            _ => {}
        }
    }
    steps
}

/// Key presses of this frame (not their repeats), each with the modifiers held as it went down.
pub(super) fn key_presses(ctx: &egui::Context) -> Vec<(egui::Key, egui::Modifiers)> {
    ctx.input(|i| {
        i.events
            .iter()
            .filter_map(|e| match e {
                egui::Event::Key { key, pressed: true, repeat: false, modifiers, .. } => Some((*key, *modifiers)),
                _ => None,
            })
            .collect()
    })
}

impl App {
    /// A window position on the viewport `rect` as target pixels (fractions kept).
    pub(super) fn target_px(&self, pos: egui::Pos2, rect: egui::Rect) -> Option<(f64, f64)> {
        let (w, h) = self.viewport.as_ref()?.size();
        Some((
            f64::from((pos.x - rect.min.x) / rect.width()) * f64::from(w),
            f64::from((pos.y - rect.min.y) / rect.height()) * f64::from(h),
        ))
    }

    /// The terrain point (ECEF) under a target pixel: the probe's when it read that pixel, else
    /// the ray's crossing of the body's mean sphere.
    pub(super) fn surface_under(&self, px: (f64, f64)) -> Option<DVec3> {
        let vp = self.viewport.as_ref()?;
        let (w, h) = vp.size();
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

    /// Applies the viewport's pointer events of this frame, in order.
    pub(super) fn pointer_steps(&mut self, steps: &[Step], rect: egui::Rect) {
        for step in steps {
            match *step {
                Step::Press { pos, button, modifiers } => self.press(pos, button, modifiers, rect),
                Step::Move { pos } => self.pointer_to(pos, rect),
                Step::Release { pos } => {
                    self.pointer_to(pos, rect);
                    match self.gesture.take() {
                        Some(Gesture::Brush(mut s)) => {
                            s.released = true;
                            self.brush.input = Some(s);
                        }
                        Some(Gesture::Erode(mut s)) => {
                            s.released = true;
                            self.erosion.input = Some(s);
                        }
                        _ => {}
                    }
                }
            }
        }
    }

    /// A button went down on the viewport: the gesture it starts.
    fn press(&mut self, pos: egui::Pos2, button: egui::PointerButton, modifiers: egui::Modifiers, rect: egui::Rect) {
        let Some(px) = self.target_px(pos, rect) else { return };
        let plain = !modifiers.shift && !modifiers.command && !modifiers.ctrl && !modifiers.alt;
        let primary = button == egui::PointerButton::Primary;
        let pixel = (px.0.max(0.0) as u32, px.1.max(0.0) as u32);
        self.gesture = if primary && plain && self.brush_armed() {
            let mut s = StrokeInput::default();
            s.push(pixel);
            Some(Gesture::Brush(s))
        } else if primary && plain && self.erosion_brush_armed() {
            let mut s = StrokeInput::default();
            s.push(pixel);
            Some(Gesture::Erode(s))
        } else if button == egui::PointerButton::Middle || (primary && modifiers.shift) {
            Some(Gesture::Look(pos))
        } else if button == egui::PointerButton::Secondary || (primary && (modifiers.command || modifiers.ctrl)) {
            let pivot = self.viewport.as_ref().and_then(|v| v.hits[1]).map(|h| h.ecef);
            pivot.or_else(|| self.surface_under(px)).map(|p| Gesture::Orbit(p, pos))
        } else if primary {
            // The exact terrain under the press is asked for; the drag is redone about it.
            self.anchor_query = Some(AnchorQuery { pixel, last: pos, rect });
            self.surface_under(px).map(Gesture::Globe)
        } else {
            None
        };
    }

    /// The pointer is at `pos` (a move or the release) while a gesture goes on.
    fn pointer_to(&mut self, pos: egui::Pos2, rect: egui::Rect) {
        let Some(px) = self.target_px(pos, rect) else { return };
        let Some((w, h)) = self.viewport.as_ref().map(|v| v.size()) else { return };
        let e = self.renderer.scene().ellipsoid;
        let cam = self.placed();
        if let Some(q) = &mut self.anchor_query {
            (q.last, q.rect) = (pos, rect);
        }
        let spec = match &mut self.gesture {
            Some(Gesture::Globe(anchor)) => Some(navigate::drag_globe(&e, &cam, *anchor, cam.ray(px.0, px.1, w, h))),
            Some(Gesture::Orbit(pivot, last)) => {
                let d = pos - *last;
                *last = pos;
                Some(navigate::orbit(&e, &cam, *pivot, f64::from(d.x) * 0.3, f64::from(d.y) * 0.3))
            }
            Some(Gesture::Look(last)) => {
                let d = pos - *last;
                *last = pos;
                Some(navigate::look(&self.camera, f64::from(d.x) * 0.1, -f64::from(d.y) * 0.1))
            }
            Some(Gesture::Brush(s) | Gesture::Erode(s)) => {
                s.push((px.0.clamp(0.0, f64::from(w - 1)) as u32, px.1.clamp(0.0, f64::from(h - 1)) as u32));
                None
            }
            None => None,
        };
        if let Some(spec) = spec {
            self.set_camera(spec);
        }
    }

    /// Each frame: the surface target's answers taken (the exact anchor of a globe drag, the
    /// points of the stroke being drawn or just released) and the next pixels asked for.
    pub(super) fn pointer_frame(&mut self, rs: &egui_wgpu::RenderState) {
        let e = self.renderer.scene().ellipsoid;
        let answers = self.viewport.as_mut().and_then(|v| v.take_queried());
        match (self.asked.take(), answers) {
            (Some(Asked::Anchor), Some(answers)) => {
                let exact = answers.first().and_then(|a| a.1);
                if let (Some(q), Some(anchor)) = (self.anchor_query.take(), exact) {
                    if let Some(Gesture::Globe(a)) = &mut self.gesture {
                        *a = anchor;
                    }
                    // The drag so far, redone about the exact point (the same move, released or not).
                    if let (Some(px), Some((w, h))) =
                        (self.target_px(q.last, q.rect), self.viewport.as_ref().map(|v| v.size()))
                    {
                        let cam = self.placed();
                        self.set_camera(navigate::drag_globe(&e, &cam, anchor, cam.ray(px.0, px.1, w, h)));
                    }
                }
            }
            (Some(Asked::Stroke), Some(answers)) => {
                if let Some(s) = self.stroke_input() {
                    for (_, point) in answers {
                        let Some(p) = point else { continue };
                        let g = geodesy::geodetic_from_ecef(&e, p);
                        let point = [g.lat_rad.to_degrees(), g.lon_rad.to_degrees()];
                        if s.path.last() != Some(&point) {
                            s.path.push(point);
                        }
                    }
                }
            }
            (asked, None) => self.asked = asked,
            (None, Some(_)) => {}
        }
        if self.asked.is_some() {
            return;
        }
        if let Some(q) = self.anchor_query {
            if self.viewport.as_mut().is_some_and(|v| v.query(rs, &[q.pixel])) {
                self.asked = Some(Asked::Anchor);
            }
            return;
        }
        let batch: Vec<(u32, u32)> = match self.stroke_input() {
            Some(s) => s.pending.iter().take(crate::gui::viewport::QUERY_MAX).copied().collect(),
            None => return,
        };
        if !batch.is_empty() && self.viewport.as_mut().is_some_and(|v| v.query(rs, &batch)) {
            self.asked = Some(Asked::Stroke);
            if let Some(s) = self.stroke_input() {
                s.pending.drain(..batch.len());
            }
        }
    }

    /// The stroke whose pixels are being turned into points: the one being drawn, else one
    /// released and not complete (the brush's or the erosion brush's).
    fn stroke_input(&mut self) -> Option<&mut StrokeInput> {
        match &mut self.gesture {
            Some(Gesture::Brush(s) | Gesture::Erode(s)) => Some(s),
            _ => self.brush.input.as_mut().or(self.erosion.input.as_mut()),
        }
    }

    /// Whether a read-back is in flight or a pixel waits to be asked.
    pub(super) fn pointer_busy(&self) -> bool {
        self.asked.is_some() || self.anchor_query.is_some()
    }

    /// Keys of this frame: undo and redo (once per press), north up, home; and the held flying
    /// keys (none while a modifier is held: Ctrl+Q is the quit prompt's, not a flight down).
    pub(super) fn keys(&mut self, ui: &egui::Ui) {
        if ui.ctx().egui_wants_keyboard_input() {
            return;
        }
        for (key, modifiers) in key_presses(ui.ctx()) {
            let command = modifiers.command || modifiers.ctrl;
            match key {
                egui::Key::Z if command && !modifiers.shift => self.brush_undo(-1),
                egui::Key::Z if command => self.brush_undo(1),
                egui::Key::N if modifiers.is_none() => self.set_camera(CameraSpec { heading: 0.0, ..self.camera }),
                egui::Key::H if modifiers.is_none() => self.set_camera(self.home),
                _ => {}
            }
        }
        let (dt, held, modified) = ui.input(|i| {
            let k = |a: egui::Key, b: egui::Key| f64::from(u8::from(i.key_down(a) || i.key_down(b)));
            let m = i.modifiers;
            (
                f64::from(i.stable_dt.min(0.1)),
                [
                    k(egui::Key::W, egui::Key::ArrowUp) - k(egui::Key::S, egui::Key::ArrowDown),
                    k(egui::Key::D, egui::Key::ArrowRight) - k(egui::Key::A, egui::Key::ArrowLeft),
                    k(egui::Key::E, egui::Key::PageUp) - k(egui::Key::Q, egui::Key::PageDown),
                ],
                m.command || m.ctrl || m.alt,
            )
        });
        if !modified && held.iter().any(|k| *k != 0.0) {
            let cam = self.placed();
            let centre = self.viewport.as_ref().and_then(|v| v.hits[1]).map(|h| h.ecef);
            // A second crosses the distance to the terrain in view (or the height above it).
            let scale = centre.map_or(self.camera.alt.abs(), |c| (c - cam.position).length()).max(10.0);
            let v = scale * dt;
            let e = self.renderer.scene().ellipsoid;
            self.set_camera(navigate::fly(&e, &cam, held[0] * v, held[1] * v, held[2] * v));
            ui.ctx().request_repaint();
        }
    }
}

impl App {
    /// What a left drag on the viewport does now, written on it while a tool has taken it over,
    /// so that no mode edits behind the user's back.
    pub(super) fn mode_banner(&self, ui: &egui::Ui, view: egui::Rect) {
        let text = if self.brush_armed() {
            let pinned = if self.tab == side_panel::Tab::Brush { "" } else { " (kept armed on every tab)" };
            format!(
                "brush{pinned}: left drag paints {} on '{}' · right or middle drag, or Shift/Ctrl + left: navigate",
                self.brush.tool_name(),
                self.brush.layer_name()
            )
        } else if self.erosion_brush_armed() {
            "erosion brush: left drag erodes along it · right or middle drag, or Shift/Ctrl + left: navigate".into()
        } else {
            return;
        };
        let painter = ui.painter_at(view);
        let galley = painter.layout_no_wrap(text, egui::FontId::proportional(13.0), egui::Color32::WHITE);
        let at = view.left_top() + egui::vec2(8.0, 8.0);
        let frame = egui::Rect::from_min_size(at, galley.size()).expand(4.0);
        painter.rect_filled(frame, 4.0, egui::Color32::from_rgba_unmultiplied(20, 20, 20, 200));
        painter.galley(at, galley, egui::Color32::WHITE);
    }
}
