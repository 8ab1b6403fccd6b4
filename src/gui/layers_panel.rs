//! The layers panel: the stack top to bottom as a person reads it, each layer's visibility,
//! blend mode, opacity and parameters edited live (the renderer recomposes only the quads the
//! changed layer touches), order changed with up/down, constant and procedural layers added and
//! removed.

use crate::gpu::Renderer;
use crate::layers::{BlendMode, DetailWhere, LayerKind, LayerSpec, NoiseSpec, NoiseType};
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
        ui.label("no layers yet: add a constant or detail here, datasets in the project file");
    }
    ui.horizontal(|ui| {
        if ui.small_button("add constant").on_hover_text("a constant height on top of the stack").clicked() {
            let spec = LayerSpec {
                blend: BlendMode::Max,
                opacity: 0.5,
                ..LayerSpec::constant(&unique_name(project, "constant"), 0.0)
            };
            insert(renderer, project, spec, &mut change);
        }
        if ui.small_button("add detail").on_hover_text("fBm noise added on top of the stack").clicked() {
            let noise = NoiseSpec {
                noise_type: NoiseType::Fbm,
                seed: 1,
                amplitude_m: 20.0,
                wavelength_m: 2000.0,
                octaves: 8,
                lacunarity: 2.0,
                gain: 0.5,
                placement: DetailWhere::Everywhere,
            };
            insert(renderer, project, LayerSpec::procedural(&unique_name(project, "detail"), noise), &mut change);
        }
    });
    let mut swap: Option<(usize, usize)> = None;
    let mut remove: Option<usize> = None;
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
                if spec.kind != LayerKind::Dataset && ui.small_button("remove").clicked() {
                    remove = Some(index);
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
    if let Some(index) = remove {
        match renderer.remove_layer(index) {
            Ok(()) => {
                project.layers.remove(index);
                change.changed = true;
            }
            Err(e) => change.error = Some(e.to_string()),
        }
    }
    if let Some((from, to)) = swap {
        renderer.move_layer(from, to);
        let layer = project.layers.remove(from);
        project.layers.insert(to, layer);
        change.changed = true;
    }
    change
}

/// A layer name not used yet: `base`, else `base 2`, `base 3`, …
fn unique_name(project: &Project, base: &str) -> String {
    let used = |n: &str| project.layers.iter().any(|l| l.name == n);
    if !used(base) {
        return base.to_string();
    }
    (2..).map(|k| format!("{base} {k}")).find(|n| !used(n)).unwrap_or_else(|| base.to_string())
}

/// Puts a new layer on top of the stack, in the renderer and the project.
fn insert(renderer: &mut Renderer, project: &mut Project, spec: LayerSpec, change: &mut LayersChange) {
    let top = project.layers.len();
    match renderer.insert_layer(top, spec.clone()) {
        Ok(()) => {
            project.layers.push(spec);
            change.changed = true;
        }
        Err(e) => change.error = Some(e.to_string()),
    }
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
        LayerKind::Dataset => {
            ui.add(
                egui::DragValue::new(&mut spec.feather_edge_m)
                    .speed(100.0)
                    .range(0.0..=1e6)
                    .prefix("edge feather ")
                    .suffix(" m"),
            )
            .on_hover_text("fade the dataset in from its own no-data edge over this distance on the surface");
        }
    }
}
