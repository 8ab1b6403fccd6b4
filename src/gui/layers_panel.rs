//! The layers panel: the stack top to bottom as a person reads it, each layer's visibility,
//! blend mode, opacity and parameters edited live (the renderer recomposes only the quads the
//! changed layer touches), and order changed with the arrows.

use crate::gpu::Renderer;
use crate::layers::{BlendMode, LayerKind, LayerSpec};
use crate::project::Project;

/// What the panel did this frame.
#[derive(Default)]
pub struct LayersChange {
    /// A layer's settings or the order changed (the view must be redrawn, the project saved).
    pub changed: bool,
    /// A refused edit, for the status line.
    pub error: Option<String>,
}

/// Draws the panel; edits go to the renderer and into the project (saved with "save project").
pub fn layers_ui(ui: &mut egui::Ui, renderer: &mut Renderer, project: &mut Project) -> LayersChange {
    let mut change = LayersChange::default();
    let count = project.layers.len();
    if count == 0 {
        ui.label("no layers: add datasets, constants or procedural detail in the project file");
    }
    let mut swap: Option<(usize, usize)> = None;
    // Top of the stack first, as in every layer panel.
    for index in (0..count).rev() {
        let mut spec = project.layers[index].clone();
        let before = spec.clone();
        ui.push_id(index, |ui| {
            ui.horizontal(|ui| {
                ui.checkbox(&mut spec.visible, "visible");
                ui.label(egui::RichText::new(&spec.name).strong());
                ui.label(egui::RichText::new(spec.kind.name()).small());
                if ui.small_button("up").on_hover_text("move up the stack").clicked() && index + 1 < count {
                    swap = Some((index, index + 1));
                }
                if ui.small_button("down").on_hover_text("move down the stack").clicked() && index > 0 {
                    swap = Some((index, index - 1));
                }
            });
            layer_settings_ui(ui, &mut spec);
        });
        if spec != before {
            match renderer.update_layer(index, spec.clone()) {
                Ok(()) => {
                    project.layers[index] = spec;
                    change.changed = true;
                }
                Err(e) => change.error = Some(e.to_string()),
            }
        }
        ui.separator();
    }
    if let Some((from, to)) = swap {
        renderer.move_layer(from, to);
        let layer = project.layers.remove(from);
        project.layers.insert(to, layer);
        change.changed = true;
    }
    change
}

fn layer_settings_ui(ui: &mut egui::Ui, spec: &mut LayerSpec) {
    egui::ComboBox::from_label("blend").selected_text(spec.blend.name()).show_ui(ui, |ui| {
        for mode in BlendMode::ALL {
            ui.selectable_value(&mut spec.blend, mode, mode.name());
        }
    });
    ui.add(egui::Slider::new(&mut spec.opacity, 0.0..=1.0).text("opacity"));
    if spec.blend == BlendMode::Mean {
        ui.add(egui::Slider::new(&mut spec.weight, 0.0..=10.0).text("weight"));
    }
    ui.add(egui::DragValue::new(&mut spec.scale).speed(0.01).prefix("scale "));
    ui.add(egui::DragValue::new(&mut spec.offset_m).speed(1.0).prefix("offset ").suffix(" m"));
    if spec.extent.is_some() {
        ui.add(egui::DragValue::new(&mut spec.feather_m).speed(100.0).range(0.0..=1e7).prefix("feather ").suffix(" m"));
    }
    match spec.kind {
        LayerKind::Constant => {
            if let Some(h) = &mut spec.height_m {
                ui.add(egui::DragValue::new(h).speed(1.0).prefix("height ").suffix(" m"));
            }
        }
        LayerKind::Procedural => {
            if let Some(n) = &mut spec.noise {
                ui.add(
                    egui::DragValue::new(&mut n.amplitude_m)
                        .speed(1.0)
                        .range(0.0..=1e5)
                        .prefix("amplitude ")
                        .suffix(" m"),
                );
                ui.add(
                    egui::DragValue::new(&mut n.wavelength_m)
                        .speed(10.0)
                        .range(1.0..=1e7)
                        .prefix("wavelength ")
                        .suffix(" m"),
                );
                ui.add(egui::Slider::new(&mut n.octaves, 1..=16).text("octaves"));
                ui.add(egui::Slider::new(&mut n.gain, 0.05..=0.95).text("gain"));
                ui.add(egui::DragValue::new(&mut n.seed).prefix("seed "));
            }
        }
        LayerKind::Dataset => {}
    }
}
