//! Small widgets the panels share: a labelled text field, and a square per shard of a plan.

/// A text field with its label before it (the label names the field for screen readers and tests).
pub(crate) fn field(ui: &mut egui::Ui, label: &str, text: &mut String, hint: &str) {
    ui.horizontal(|ui| {
        let l = ui.label(label);
        ui.add(egui::TextEdit::singleline(text).hint_text(hint)).labelled_by(l.id);
    });
}

/// One small square per shard: green when its part is done, grey when not.
pub(crate) fn shard_squares(ui: &mut egui::Ui, done: &[bool]) {
    const SIDE: f32 = 7.0;
    let per_row = ((ui.available_width() / (SIDE + 1.0)) as usize).max(1);
    let rows = done.len().div_ceil(per_row).min(40);
    let (rect, response) =
        ui.allocate_exact_size(egui::vec2(ui.available_width(), rows as f32 * (SIDE + 1.0)), egui::Sense::hover());
    let painter = ui.painter_at(rect);
    for (i, d) in done.iter().enumerate().take(rows * per_row) {
        let min = rect.min + egui::vec2((i % per_row) as f32 * (SIDE + 1.0), (i / per_row) as f32 * (SIDE + 1.0));
        let colour = if *d { egui::Color32::from_rgb(80, 170, 90) } else { egui::Color32::from_gray(90) };
        painter.rect_filled(egui::Rect::from_min_size(min, egui::vec2(SIDE, SIDE)), 1.0, colour);
    }
    let missing: Vec<String> =
        done.iter().enumerate().filter(|(_, d)| !**d).map(|(i, _)| i.to_string()).take(20).collect();
    if !missing.is_empty() {
        response.on_hover_text(format!("missing shards: {}", missing.join(", ")));
    }
}
