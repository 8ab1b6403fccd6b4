//! Difference layers in the workstation: their settings (operands, colour range, isolines,
//! opacity), the colour bar, and the range from a percentile of |dh|, computed on a thread
//! whenever what it depends on changes.

use crate::gui::GuiError;
use std::thread::JoinHandle;

use crate::gpu::Renderer;
use crate::layers::{LayerSpec, Operand};
use crate::project::Project;

/// A difference layer's settings. `names`: the layers an operand may name; `visible`: the shown
/// height layers (the "visible terrain" group).
pub fn settings_ui(ui: &mut egui::Ui, spec: &mut LayerSpec, names: &[String], visible: &[String], range_m: f64) {
    ui.add(egui::Slider::new(&mut spec.opacity, 0.0..=1.0).text("opacity"))
        .on_hover_text("how strongly dh covers the colour ramp (hillshade stays)");
    if let Some(of) = spec.as_difference_mut().map(|d| &mut d.of) {
        ui.horizontal(|ui| {
            operand_ui(ui, "A", &mut of[0], names, visible);
            ui.label("minus");
            operand_ui(ui, "B", &mut of[1], names, visible);
        });
    }
    let mut style = spec.difference_style();
    ui.horizontal(|ui| {
        let mut auto = style.range_m.is_none();
        if ui.checkbox(&mut auto, "range from percentile").changed() {
            style.range_m = if auto { None } else { Some(range_m) };
        }
        match &mut style.range_m {
            None => {
                ui.add(egui::DragValue::new(&mut style.percentile).speed(0.1).range(1.0..=100.0).suffix(" %"));
            }
            Some(r) => {
                ui.add(egui::DragValue::new(r).speed(0.1).range(0.01..=1e5).prefix("± ").suffix(" m"));
            }
        }
    });
    ui.add(
        egui::DragValue::new(&mut style.isolines_m)
            .speed(0.1)
            .range(0.0..=1e4)
            .prefix("dh isolines every ")
            .suffix(" m"),
    )
    .on_hover_text("lines at ±1, ±2, … intervals (0: none; zero is the colour map's white)");
    if let Some(d) = spec.as_difference_mut()
        && d.style != style
    {
        d.style = style;
    }
    legend_ui(ui, range_m);
}

/// One operand: a layer alone, or the shown layers composed ("visible terrain").
fn operand_ui(ui: &mut egui::Ui, side: &str, operand: &mut Operand, names: &[String], visible: &[String]) {
    let terrain = Operand::Group(visible.to_vec());
    let label =
        if *operand == terrain && !visible.is_empty() { "visible terrain".to_string() } else { operand.label() };
    egui::ComboBox::from_label(side).selected_text(label).show_ui(ui, |ui| {
        for n in names {
            ui.selectable_value(operand, Operand::Layer(n.clone()), n);
        }
        if !visible.is_empty() {
            ui.selectable_value(operand, terrain, "visible terrain")
                .on_hover_text(format!("{} composed as shown", visible.join(" + ")));
        }
    });
}

/// The colour bar: −range to +range, red to blue, white at zero.
pub fn legend_ui(ui: &mut egui::Ui, range_m: f64) {
    let width = ui.available_width().clamp(120.0, 320.0);
    let (rect, _) = ui.allocate_exact_size(egui::vec2(width, 14.0), egui::Sense::hover());
    let steps = 64;
    for k in 0..steps {
        let t = (k as f64 + 0.5) / steps as f64 * 2.0 - 1.0;
        let [r, g, b] = crate::colour::diverging(t).map(|c| (c * 255.0).round() as u8);
        let x0 = rect.left() + rect.width() * k as f32 / steps as f32;
        let x1 = rect.left() + rect.width() * (k + 1) as f32 / steps as f32;
        let cell = egui::Rect::from_min_max(egui::pos2(x0, rect.top()), egui::pos2(x1 + 0.5, rect.bottom()));
        ui.painter().rect_filled(cell, 0.0, egui::Color32::from_rgb(r, g, b));
    }
    ui.horizontal(|ui| {
        ui.label(format!("-{range_m:.2} m"));
        ui.add_space((width - 150.0).max(8.0) / 2.0);
        ui.label("0");
        ui.add_space((width - 150.0).max(8.0) / 2.0);
        ui.label(format!("+{range_m:.2} m"));
    });
}

/// A new difference layer A − B of the project (named "A - B", made unique).
pub fn new_layer(project: &Project, a: &str, b: &str) -> LayerSpec {
    let base = format!("{a} - {b}");
    let used = |n: &str| project.layers.iter().any(|l| l.name == n);
    let name = if used(&base) { (2..).map(|k| format!("{base} {k}")).find(|n| !used(n)).unwrap_or(base) } else { base };
    let operand = |n: &str| crate::compare::operand(project, n);
    LayerSpec::difference(&name, operand(a), operand(b))
}

/// A range computed on a thread (None: the operands do not overlap).
type RangeJob = JoinHandle<Result<Option<f64>, GuiError>>;

/// The drawn difference layer's range from its percentile: recomputed on a thread when the layer,
/// its operands' settings or its percentile change, and handed to the renderer.
#[derive(Default)]
pub struct AutoRange {
    /// What the value was computed for.
    key: Option<String>,
    job: Option<(String, RangeJob)>,
    /// The last failure, for the panel.
    pub error: Option<String>,
}

impl AutoRange {
    /// Starts or collects the computation; true when the renderer got a new range (redraw).
    pub fn poll(&mut self, project: &Project, renderer: &mut Renderer) -> bool {
        let mut changed = false;
        if self.job.as_ref().is_some_and(|(_, h)| h.is_finished())
            && let Some((key, h)) = self.job.take()
        {
            match h.join().unwrap_or_else(|_| Err("the range computation failed unexpectedly".into())) {
                Ok(range) => {
                    renderer.set_difference_range(range);
                    self.error = None;
                }
                Err(e) => self.error = Some(e.to_string()),
            }
            self.key = Some(key);
            changed = true;
        }
        if self.job.is_some() {
            return changed;
        }
        let Some(spec) = drawn_difference(project) else { return changed };
        if spec.difference_style().range_m.is_some() {
            return changed;
        }
        // The layer, its percentile, and every layer its operands read, as the project has them.
        let read: Vec<&LayerSpec> = spec
            .as_difference()
            .iter()
            .flat_map(|d| d.of.iter())
            .flat_map(|o| o.names())
            .filter_map(|n| project.layers.iter().find(|l| l.name == n))
            .collect();
        let key = serde_json::to_string(&(spec, &read)).unwrap_or_default();
        if self.key.as_deref() == Some(key.as_str()) {
            return changed;
        }
        let (p, s) = (project.clone(), spec.clone());
        let handle =
            crate::gui::background::spawn("difference-range", move || Ok(crate::compare::difference_range(&p, &s)?));
        self.job = Some((key, handle));
        changed
    }

    /// Whether a computation runs.
    pub fn busy(&self) -> bool {
        self.job.is_some()
    }
}

/// The project's drawn difference layer (the topmost shown one with opacity).
fn drawn_difference(project: &Project) -> Option<&LayerSpec> {
    crate::layers::kind::drawn_difference(&project.layers).map(|k| &project.layers[k])
}
