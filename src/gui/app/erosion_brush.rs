//! The erosion brush: with *brush* ticked in the *Erosion* section, a left drag records a path,
//! and on release a run of the chosen steps rains and erodes within the brush's radius of it
//! only (hydraulic), or raises rock along it (stream power, the uplift brush); the run is kept.

use super::*;
use crate::erosion::operation::BrushPath;

impl App {
    /// The erosion brush's input while it is on: a left drag records a path; its release runs
    /// erosion along it and keeps the run. True when the input was the brush's.
    pub(super) fn erode_paint(&mut self, ui: &egui::Ui, response: &egui::Response, rect: egui::Rect) -> bool {
        if !self.erosion.brush {
            return false;
        }
        let modifiers = ui.input(|i| i.modifiers);
        let plain = !modifiers.shift && !modifiers.command;
        if response.drag_started_by(egui::PointerButton::Primary) && plain && self.erosion.session.is_none() {
            self.erosion.painting = true;
            self.erosion.path.clear();
        }
        if !self.erosion.painting {
            return false;
        }
        let under = response.interact_pointer_pos().or(response.hover_pos()).and_then(|p| self.surface_at(p, rect));
        if let Some(p) = under {
            let g = geodesy::geodetic_from_ecef(&self.renderer.scene().ellipsoid, p);
            let point = [g.lat_rad.to_degrees(), g.lon_rad.to_degrees()];
            if self.erosion.path.last() != Some(&point) {
                self.erosion.path.push(point);
            }
        }
        if response.drag_stopped() || !response.dragged() {
            self.erosion.painting = false;
            let points = std::mem::take(&mut self.erosion.path);
            if !points.is_empty() {
                self.erode_along(points);
            }
        }
        true
    }

    /// One erosion brush stroke: a run of the section's steps (at most 2000) along `points`,
    /// taken at once and kept.
    pub(crate) fn erode_along(&mut self, points: Vec<[f64; 2]>) {
        self.start_erosion(Some(BrushPath { points, radius_m: self.erosion.brush_radius_m }));
        let Some(s) = &self.erosion.session else { return };
        let steps = s.op.steps;
        let mut left = steps;
        while left > 0 {
            let n = left.min(256) as u32;
            if let Some(s) = &mut self.erosion.session
                && let Err(e) = s.step(n)
            {
                self.message = format!("erosion: {}", crate::errors::chain(&e));
                return;
            }
            left -= u64::from(n);
        }
        self.keep_erosion();
    }
}
