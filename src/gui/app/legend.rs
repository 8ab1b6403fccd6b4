//! The legend drawn on the viewport, bottom left: the colour ramp with its heights in metres, or,
//! while a difference layer is drawn, the diverging ramp of A − B with its range.

use super::*;

/// Width and height of the colour bar, points.
const BAR: egui::Vec2 = egui::vec2(180.0, 12.0);
/// Samples along the bar.
const STEPS: usize = 48;

/// The sRGB colour (0–255) of a value on the legend's scale.
type ColourOf = Box<dyn Fn(f64) -> [f64; 3]>;

/// A value at the end of the legend, with the decimals its span needs (a curvature's ±0.5 too).
fn label(value: f64, span: f64) -> String {
    let decimals = if span.abs() >= 10.0 { 0 } else { (1.0 - span.abs().max(1e-6).log10()).ceil() as usize };
    format!("{value:.decimals$}")
}

impl App {
    /// Paints the legend in `view` and records where it is (physical pixels) for the screenshot
    /// report.
    pub(super) fn legend(&mut self, ui: &egui::Ui, view: egui::Rect) {
        let scene = self.renderer.scene();
        let (title, low, high, colour): (String, f64, f64, ColourOf) = match scene.stack.drawn_difference() {
            Some(d) => {
                let r = self.renderer.difference_range_m();
                let name = scene.stack.layers[d].spec.name.clone();
                let colour = move |t: f64| crate::colour::diverging(t).map(|c| c * 255.0);
                (format!("{name} (m)"), -r, r, Box::new(move |h: f64| colour(h / r.max(1e-9))))
            }
            None => {
                let ramp = scene.ramp.clone();
                let first = ramp.stops.first().map_or(0.0, |s| s.value_m);
                let last = ramp.stops.last().map_or(1.0, |s| s.value_m);
                let colour = move |h: f64| {
                    let c = ramp.colour_at(h);
                    [c[0], c[1], c[2]]
                };
                let title = scene.visuals.colour_map.by.title();
                (title.to_string(), first, last, Box::new(colour))
            }
        };
        let margin = 8.0;
        let size = egui::vec2(BAR.x + 2.0 * margin, BAR.y + 36.0);
        let frame = egui::Rect::from_min_size(egui::pos2(view.left() + 10.0, view.bottom() - size.y - 10.0), size);
        if !view.contains_rect(frame) {
            self.legend_px = None;
            return;
        }
        let painter = ui.painter_at(view);
        painter.rect_filled(frame, 4.0, egui::Color32::from_black_alpha(170));
        let text = egui::Color32::from_gray(230);
        let font = egui::FontId::proportional(11.0);
        painter.text(frame.min + egui::vec2(margin, 4.0), egui::Align2::LEFT_TOP, title, font.clone(), text);
        let bar = egui::Rect::from_min_size(frame.min + egui::vec2(margin, 18.0), BAR);
        let w = BAR.x / STEPS as f32;
        for k in 0..STEPS {
            let h = low + (high - low) * (k as f64 + 0.5) / STEPS as f64;
            let [r, g, b] = colour(h).map(|c| c.round().clamp(0.0, 255.0) as u8);
            let cell = egui::Rect::from_min_size(bar.min + egui::vec2(k as f32 * w, 0.0), egui::vec2(w + 0.5, BAR.y));
            painter.rect_filled(cell, 0.0, egui::Color32::from_rgb(r, g, b));
        }
        let below = bar.bottom() + 2.0;
        painter.text(egui::pos2(bar.left(), below), egui::Align2::LEFT_TOP, label(low, high - low), font.clone(), text);
        painter.text(egui::pos2(bar.right(), below), egui::Align2::RIGHT_TOP, label(high, high - low), font, text);
        let ppp = ui.ctx().pixels_per_point();
        let outer = frame.expand(1.0);
        self.legend_px = Some(egui::Rect::from_min_max(
            (outer.min.to_vec2() * ppp).to_pos2(),
            (outer.max.to_vec2() * ppp).to_pos2(),
        ));
    }
}
