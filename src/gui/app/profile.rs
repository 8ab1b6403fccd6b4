//! Drawing a profile in the workstation: two clicks on the terrain give the line, every visible
//! layer and the composed stack are sampled along its geodesic on a thread
//! (`compare::profile`), and the panel draws them, one colour per layer; the line can be saved
//! into the project (`comparison.profiles`).

use crate::gui::GuiError;
use std::thread::JoinHandle;

use super::*;
use crate::compare::{Profile, ProfileOptions, profile};
use crate::project::ProfileLine;

/// Samples along a profile drawn in the window.
const SAMPLES: usize = 400;

/// The tool's state.
#[derive(Default)]
pub(crate) struct ProfileTool {
    /// Clicks still wanted: 2 for the start, 1 for the end, 0 when not picking.
    picking: u8,
    from: Option<[f64; 2]>,
    line: Option<ProfileLine>,
    job: Option<JoinHandle<Result<Profile, GuiError>>>,
    result: Option<Result<Profile, GuiError>>,
}

/// Colours of the columns, in order (the composed stack last, white).
const COLOURS: [egui::Color32; 6] = [
    egui::Color32::from_rgb(230, 120, 60),
    egui::Color32::from_rgb(80, 170, 240),
    egui::Color32::from_rgb(120, 200, 90),
    egui::Color32::from_rgb(220, 90, 200),
    egui::Color32::from_rgb(240, 210, 70),
    egui::Color32::from_rgb(150, 150, 150),
];

impl App {
    /// Takes a click on the terrain as the next end of the profile; true when it did. The point
    /// is the probe's when it is for the clicked pixel (it arrives a frame or more late), else
    /// where the pixel's ray meets the body's mean sphere.
    pub(super) fn pick_profile(&mut self, response: &egui::Response, rect: egui::Rect) -> bool {
        if self.profile.picking == 0 || !response.clicked() {
            return false;
        }
        let (Some(vp), Some(at)) = (&self.viewport, response.interact_pointer_pos()) else { return true };
        let (w, h) = vp.size();
        let px = (
            f64::from((at.x - rect.min.x) / rect.width()) * f64::from(w),
            f64::from((at.y - rect.min.y) / rect.height()) * f64::from(h),
        );
        let e = self.renderer.scene().ellipsoid;
        let ecef = vp.hits[0]
            .filter(|hit| (f64::from(hit.pixel.0) - px.0).abs() < 3.0 && (f64::from(hit.pixel.1) - px.1).abs() < 3.0)
            .map_or_else(
                || {
                    let cam = self.placed();
                    navigate::fallback_target(&e, &cam, cam.ray(px.0, px.1, w, h))
                },
                |hit| hit.ecef,
            );
        let g = geodesy::geodetic_from_ecef(&e, ecef);
        let point = [g.lat_rad.to_degrees(), g.lon_rad.to_degrees()];
        if self.profile.picking == 2 {
            self.profile.from = Some(point);
            self.profile.picking = 1;
            self.message = "profile: click its end".into();
        } else if let Some(from) = self.profile.from.take() {
            self.profile.picking = 0;
            let line = ProfileLine { from, to: point };
            self.profile.line = Some(line);
            let project = self.project.clone();
            self.profile.job = Some(crate::gui::background::spawn("profile", move || {
                let opts = ProfileOptions { from: line.from, to: line.to, samples: Some(SAMPLES), level: None };
                Ok(profile(&project, &opts)?)
            }));
            self.message = format!(
                "profile from {:.5}°, {:.5}° to {:.5}°, {:.5}°",
                line.from[0], line.from[1], line.to[0], line.to[1]
            );
        }
        true
    }

    /// Whether a profile is being picked or sampled.
    pub fn profile_busy(&self) -> bool {
        self.profile.picking > 0 || self.profile.job.is_some()
    }

    /// The last profile, if any.
    pub fn last_profile(&self) -> Option<&Profile> {
        self.profile.result.as_ref().and_then(|r| r.as_ref().ok())
    }

    /// The profile's part of the *Compare* section.
    pub(super) fn profile_ui(&mut self, ui: &mut egui::Ui) {
        if self.profile.job.as_ref().is_some_and(|j| j.is_finished())
            && let Some(job) = self.profile.job.take()
        {
            self.profile.result = Some(job.join().unwrap_or_else(|_| Err("the profile failed unexpectedly".into())));
        }
        ui.horizontal(|ui| {
            let label = if self.profile.picking > 0 { "click on the terrain…" } else { "draw a profile" };
            if ui.button(label).on_hover_text("two clicks on the terrain: start, then end").clicked() {
                self.profile.picking = 2;
                self.profile.from = None;
                self.message = "profile: click its start on the terrain".into();
            }
            if self.profile.job.is_some() {
                ui.spinner();
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
            }
            if let (Some(line), Some(Ok(_))) = (self.profile.line, &self.profile.result)
                && ui.button("save line").on_hover_text("into the project's comparison.profiles").clicked()
            {
                let n =
                    (1..).find(|k| !self.project.comparison.profiles.contains_key(&format!("line {k}"))).unwrap_or(1);
                let name = format!("line {n}");
                self.project.comparison.profiles.insert(name.clone(), line);
                self.mark_unsaved();
                self.message = format!("profile saved as '{name}' (save the project to keep it)");
            }
            if let Some(Ok(p)) = &self.profile.result
                && ui.button("write CSV").on_hover_text("profile.csv beside the project file").clicked()
            {
                let path = self.project.resolve(std::path::Path::new("profile.csv"));
                self.message = match crate::files::write_atomic(&path, p.csv().as_bytes()) {
                    Ok(()) => format!("wrote {}", path.display()),
                    Err(e) => format!("{}: cannot write: {e}", path.display()),
                };
            }
        });
        match &self.profile.result {
            Some(Ok(p)) => profile_chart(ui, p),
            Some(Err(e)) => {
                ui.colored_label(egui::Color32::LIGHT_RED, e.to_string());
            }
            None => {}
        }
    }
}

/// The profile's columns as lines over distance, with their names and the height range.
fn profile_chart(ui: &mut egui::Ui, p: &Profile) {
    let mut columns: Vec<(&str, &Vec<f64>)> = p.layers.iter().map(|(n, h)| (n.as_str(), h)).collect();
    columns.push(("composed", &p.composed));
    let (lo, hi) = columns
        .iter()
        .flat_map(|(_, h)| h.iter().copied().filter(|v| !v.is_nan()))
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), v| (a.min(v), b.max(v)));
    if lo > hi {
        ui.label("no layer has data along the line");
        return;
    }
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width().min(280.0), 120.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
    let span = (hi - lo).max(1.0);
    let to_screen = |s: f64, h: f64| {
        egui::pos2(
            rect.left() + (s / p.length_m) as f32 * rect.width(),
            rect.bottom() - ((h - lo) / span) as f32 * rect.height(),
        )
    };
    for (k, (_, h)) in columns.iter().enumerate() {
        let colour = if k + 1 == columns.len() { egui::Color32::WHITE } else { COLOURS[k % COLOURS.len()] };
        // Lines break where a layer has no data.
        let mut run: Vec<egui::Pos2> = Vec::new();
        for (s, v) in p.distance_m.iter().zip(h.iter()) {
            if v.is_nan() {
                if run.len() > 1 {
                    painter.add(egui::Shape::line(std::mem::take(&mut run), egui::Stroke::new(1.0, colour)));
                }
                run.clear();
            } else {
                run.push(to_screen(*s, *v));
            }
        }
        if run.len() > 1 {
            painter.add(egui::Shape::line(run, egui::Stroke::new(1.0, colour)));
        }
    }
    ui.horizontal_wrapped(|ui| {
        for (k, (name, _)) in columns.iter().enumerate() {
            let colour = if k + 1 == columns.len() { egui::Color32::WHITE } else { COLOURS[k % COLOURS.len()] };
            ui.colored_label(colour, *name);
        }
    });
    ui.label(
        egui::RichText::new(format!("{:.2} km, {lo:.0} … {hi:.0} m, level {}", p.length_m / 1e3, p.level)).small(),
    );
}
