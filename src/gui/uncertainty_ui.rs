//! The *uncertainty* of the Compare section (as `terrafuse compare --uncertainty` prints it): the
//! mean elevation change and the volume change with their 1σ, the error model with its binned
//! NMAD by slope and curvature, and the variogram of the standardised differences with its fit.

use crate::compare::Uncertainty;
use crate::compare::variogram::VariogramModel;

/// Draws an uncertainty.
pub fn uncertainty_ui(ui: &mut egui::Ui, u: &Uncertainty) {
    ui.label(egui::RichText::new(format!("mean dh {:+.3} ± {:.3} m (1σ)", u.mean_dh_m, u.mean_dh_sigma_m)).strong());
    ui.label(format!(
        "volume change {:+.4e} ± {:.4e} m³ over {:.2} km² ({} effective samples)",
        u.volume_m3,
        u.volume_sigma_m3,
        u.area_m2 / 1e6,
        u.effective_samples.round()
    ));
    let h = &u.heteroscedasticity;
    ui.label(format!(
        "σ(dh) = {:.2} × √({:.2}² + ({:.1} tan slope)² + ({:.1} curvature)²) m, {:.2} m on average",
        h.scale, h.base_m, h.slope_m, h.curvature_m, u.mean_error_m
    ));
    if u.fit_quad_count < u.quad_count {
        ui.label(
            egui::RichText::new(format!(
                "model and variogram fitted on {} of the {} quads; the mean and volume over all",
                u.fit_quad_count, u.quad_count
            ))
            .small(),
        );
    }
    // The binned NMAD: rows by slope, columns by curvature, shaded by value.
    ui.label(egui::RichText::new("NMAD of dh by slope (rows) and maximal curvature (columns), m").small());
    let peak = h.nmad_m.iter().flatten().flatten().copied().fold(0.0, f64::max).max(f64::MIN_POSITIVE);
    egui::Grid::new("uncertainty bins").spacing([2.0, 1.0]).show(ui, |ui| {
        for (i, row) in h.nmad_m.iter().enumerate() {
            ui.label(
                egui::RichText::new(format!("{:.0}–{:.0}°", h.slope_edges_deg[i], h.slope_edges_deg[i + 1])).small(),
            );
            for v in row {
                let text = v.map_or("–".to_string(), |v| format!("{v:.1}"));
                let shade = v.map_or(0.0, |v| (v / peak) as f32);
                let fill = egui::Color32::from_rgba_unmultiplied(200, 80, 40, (shade * 160.0) as u8);
                egui::Frame::new().fill(fill).show(ui, |ui| ui.monospace(egui::RichText::new(text).small()));
            }
            ui.end_row();
        }
    });
    let models: Vec<String> =
        u.variogram.models.iter().map(|m| format!("{:.0} m ({:.2})", m.range_m, m.psill)).collect();
    ui.label(format!("variogram of dh / σ: spherical ranges {}", models.join(" + ")));
    variogram_plot(ui, u);
}

/// The empirical variogram (dots) and the fitted model (line) against the lag on a log axis.
fn variogram_plot(ui: &mut egui::Ui, u: &Uncertainty) {
    let bins = &u.variogram.bins;
    let (Some(first), Some(last)) = (bins.first(), bins.last()) else { return };
    let model = VariogramModel { models: u.variogram.models.clone() };
    let top = bins.iter().map(|b| b.gamma).fold(model.sill(), f64::max) * 1.1;
    let (rect, _) = ui.allocate_exact_size(egui::vec2(ui.available_width().min(280.0), 90.0), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    painter.rect_filled(rect, 0.0, ui.visuals().extreme_bg_color);
    let (lo, hi) = (first.lag_m.ln(), last.lag_m.ln());
    let at = |lag: f64, gamma: f64| {
        egui::pos2(
            rect.left() + rect.width() * ((lag.ln() - lo) / (hi - lo).max(1e-9)) as f32,
            rect.bottom() - rect.height() * (gamma / top) as f32,
        )
    };
    let line: Vec<egui::Pos2> = (0..=60)
        .map(|k| {
            let lag = (lo + (hi - lo) * f64::from(k) / 60.0).exp();
            at(lag, model.gamma(lag))
        })
        .collect();
    painter.add(egui::Shape::line(line, egui::Stroke::new(1.5, ui.visuals().selection.bg_fill)));
    for b in bins {
        painter.circle_filled(at(b.lag_m, b.gamma), 2.5, ui.visuals().strong_text_color());
    }
    ui.label(
        egui::RichText::new(format!("lag {:.0} m … {:.1} km (log), γ 0 … {top:.2}", first.lag_m, last.lag_m / 1000.0))
            .small(),
    );
}
