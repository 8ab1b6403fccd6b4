//! The erosion brush: with *brush* ticked in the *Erosion* section (and that tab shown), a left
//! drag records a path from the pointer's events ([`super::pointer`]), and on release a run of
//! the chosen steps rains and erodes within the brush's radius of it only (hydraulic), or raises
//! rock along it (stream power, the uplift brush); the run is kept.

use super::*;
use crate::erosion::operation::BrushPath;

impl App {
    /// Whether a left drag on the viewport draws the erosion brush's path: it is ticked, this is
    /// the *Erosion* tab, and no run is in progress.
    pub(super) fn erosion_brush_armed(&self) -> bool {
        self.erosion.brush && self.tab == side_panel::Tab::Erosion && self.erosion.session.is_none()
    }

    /// Each frame: the erosion brush's path turned into points; once released and complete, the
    /// run along it.
    pub(super) fn erosion_brush_frame(&mut self) {
        if self.erosion.input.as_ref().is_some_and(|s| s.complete(self.pointer_busy())) {
            let points = self.erosion.input.take().map(|s| s.path).unwrap_or_default();
            if !points.is_empty() {
                self.erode_along(points);
            }
        }
    }

    /// One erosion brush stroke: a run of the section's steps (at most 2000) along `points`,
    /// run to its end (on the CPU's thread, or the GPU) and kept once done.
    pub(crate) fn erode_along(&mut self, points: Vec<[f64; 2]>) {
        self.start_erosion(Some(BrushPath { points, radius_m: self.erosion.brush_radius_m }));
        if let Some(s) = &mut self.erosion.session {
            s.set_running(true);
        }
    }
}
