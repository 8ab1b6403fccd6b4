//! The layers panel: the stack top to bottom as a person reads it, one compact row a layer
//! (drag handle, visibility, name, kind, opacity, remove) and the selected layer's up, down,
//! blend mode and parameters below the list, as QGIS and image editors lay it out, all edited live (the renderer recomposes only the quads the
//! changed layer touches), order changed by dragging a layer onto another or with the selected one's up/down,
//! constant, procedural and difference layers added (datasets by [`super::add_dataset`]; a
//! difference's settings by [`super::difference_ui`]) and any layer removed (not one a difference
//! reads). The panel reads the project and returns [`LayerAction`]s; the workstation applies
//! them to the renderer and the project.

use crate::layers::{BlendMode, DetailWhere, ExtentSpec, LayerPayload, LayerSpec, NoiseSpec, NoiseType};
use crate::project::Project;

/// A change of the stack asked for in the panel.
#[derive(Clone, Debug, PartialEq)]
pub enum LayerAction {
    /// Put a new layer on top of the stack.
    Insert(LayerSpec),
    /// Layer `index` gets these settings.
    Update(usize, LayerSpec),
    /// Take layer `index` off the stack.
    Remove(usize),
    /// Move layer `from` to position `to` (0: bottom).
    Move {
        /// The layer's position now.
        from: usize,
        /// Its new one.
        to: usize,
    },
}

/// What the panel shows of the renderer: the drawn difference layer and its range, metres.
#[derive(Clone, Copy, Debug)]
pub struct Drawn {
    /// The difference layer drawn over the terrain, if any.
    pub difference: Option<usize>,
    /// Its colour map's range, metres.
    pub range_m: f64,
}

/// Draws the panel for `project`'s stack; returns what the person asked for this frame.
pub fn layers_ui(ui: &mut egui::Ui, project: &Project, drawn: Drawn) -> Vec<LayerAction> {
    let mut actions = Vec::new();
    let count = project.layers.len();
    if count == 0 {
        ui.label("no layers yet: add a dataset, a constant or detail");
    }
    ui.horizontal(|ui| {
        if ui.small_button("add constant").on_hover_text("a constant height on top of the stack").clicked() {
            let spec = LayerSpec {
                blend: BlendMode::Max,
                opacity: 0.5,
                ..LayerSpec::constant(&unique_name(project, "constant"), 0.0)
            };
            actions.push(LayerAction::Insert(spec));
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
            actions.push(LayerAction::Insert(LayerSpec::procedural(&unique_name(project, "detail"), noise)));
        }
        let heights: Vec<&str> = project.layers.iter().filter(|l| l.gives_heights()).map(|l| l.name.as_str()).collect();
        let two = heights.len() >= 2;
        if ui
            .add_enabled(two, egui::Button::new("add difference").small())
            .on_hover_text("A - B of the top two layers, drawn over the terrain in red and blue")
            .on_disabled_hover_text("needs two layers with heights")
            .clicked()
        {
            let (a, b) = (heights[heights.len() - 1], heights[heights.len() - 2]);
            let spec = super::difference_ui::new_layer(project, a, b);
            actions.push(LayerAction::Insert(spec));
        }
    });
    // A move from one position to another (up, down, or a layer dragged onto another).
    let mut moved: Option<(usize, usize)> = None;
    let mut remove: Option<usize> = None;
    // Which layer's details show below the list (the panel's own state, in egui's memory; the
    // top layer until one is picked).
    let selected_id = selected_id();
    let mut selected: usize =
        ui.data(|d| d.get_temp::<usize>(selected_id)).filter(|&k| k < count).unwrap_or(count.saturating_sub(1));
    // One compact row a layer, top of the stack first, as in every layer panel.
    for index in (0..count).rev() {
        let mut spec = project.layers[index].clone();
        let before = spec.clone();
        let row = ui
            .push_id(index, |ui| {
                ui.horizontal(|ui| {
                    ui.dnd_drag_source(ui.scope_id().with("drag"), index, |ui| ui.label("::"))
                        .response
                        .on_hover_text("drag onto another layer to move it there");
                    ui.checkbox(&mut spec.visible, "visible");
                    let name = egui::RichText::new(&spec.name).strong();
                    if ui.selectable_label(selected == index, name).on_hover_text("show its settings below").clicked() {
                        selected = index;
                    }
                    ui.label(egui::RichText::new(spec.kind().name()).small());
                    if spec.gives_heights() {
                        // Narrow, so that the row keeps the panel as wide as the buttons need.
                        ui.spacing_mut().slider_width = 40.0;
                        ui.add(egui::Slider::new(&mut spec.opacity, 0.0..=1.0).show_value(false))
                            .on_hover_text(format!("opacity {:.2}", spec.opacity));
                    }
                    if ui.small_button("remove").on_hover_text("take the layer off the stack").clicked() {
                        remove = Some(index);
                    }
                });
            })
            .response;
        if row.dnd_hover_payload::<usize>().is_some_and(|from| *from != index) {
            let stroke = egui::Stroke::new(2.0, ui.visuals().selection.stroke.color);
            ui.painter().hline(row.rect.x_range(), row.rect.top(), stroke);
        }
        if let Some(from) = row.dnd_release_payload::<usize>()
            && *from != index
        {
            moved = Some((*from, index));
        }
        if spec != before {
            actions.push(LayerAction::Update(index, spec));
        }
    }
    ui.data_mut(|d| d.insert_temp(selected_id, selected));
    // The selected layer's settings below the list.
    if let Some(layer) = project.layers.get(selected) {
        ui.separator();
        ui.horizontal(|ui| {
            ui.label(egui::RichText::new(format!("{} ({})", layer.name, layer.kind().name())).strong());
            if ui.small_button("up").on_hover_text("move up the stack").clicked() && selected + 1 < count {
                moved = Some((selected, selected + 1));
            }
            if ui.small_button("down").on_hover_text("move down the stack").clicked() && selected > 0 {
                moved = Some((selected, selected - 1));
            }
        });
        let mut spec = layer.clone();
        if !spec.gives_heights() {
            let heights = project.layers.iter().filter(|l| l.gives_heights());
            let names: Vec<String> = heights.clone().map(|l| l.name.clone()).collect();
            let visible: Vec<String> = heights.filter(|l| l.visible).map(|l| l.name.clone()).collect();
            super::difference_ui::settings_ui(ui, &mut spec, &names, &visible, drawn.range_m);
            if drawn.difference != Some(selected) && spec.visible {
                ui.label("(a difference above this one is drawn)");
            }
        } else {
            layer_settings_ui(ui, &mut spec);
        }
        // A change made in the row above this frame wins; the details' own change goes next frame.
        if spec != *layer && !actions.iter().any(|a| matches!(a, LayerAction::Update(k, _) if *k == selected)) {
            actions.push(LayerAction::Update(selected, spec));
        }
    }
    actions.extend(remove.map(LayerAction::Remove));
    actions.extend(moved.map(|(from, to)| LayerAction::Move { from, to }));
    actions
}

/// Where the panel keeps which layer's settings show (egui's memory: the panel's own state).
fn selected_id() -> egui::Id {
    egui::Id::unique("terrafuse: the layer whose settings show")
}

/// Shows layer `index`'s settings below the list from the next frame on (a tool that changed
/// the layer: a co-registration applied to it).
pub fn show_settings_of(ctx: &egui::Context, index: usize) {
    ctx.data_mut(|d| d.insert_temp(selected_id(), index));
}

/// A layer name not used yet: `base`, else `base 2`, `base 3`, …
fn unique_name(project: &Project, base: &str) -> String {
    let used = |n: &str| project.layers.iter().any(|l| l.name == n);
    if !used(base) {
        return base.to_string();
    }
    (2..).map(|k| format!("{base} {k}")).find(|n| !used(n)).unwrap_or_else(|| base.to_string())
}

fn layer_settings_ui(ui: &mut egui::Ui, spec: &mut LayerSpec) {
    egui::ComboBox::from_label("blend").selected_text(spec.blend.name()).show_ui(ui, |ui| {
        for mode in BlendMode::ALL {
            ui.selectable_value(&mut spec.blend, mode, mode.name());
        }
    });
    // The opacity is on the layer's row.
    if spec.blend == BlendMode::Mean {
        ui.add(egui::Slider::new(&mut spec.weight, 0.0..=10.0).text("weight"));
    }
    ui.horizontal(|ui| {
        ui.add(egui::DragValue::new(&mut spec.scale).speed(0.01).prefix("scale "));
        ui.add(egui::DragValue::new(&mut spec.offset_m).speed(1.0).prefix("offset ").suffix(" m"));
    });
    valid_range_ui(ui, spec);
    extent_ui(ui, spec);
    let (applied_strokes, applied_runs) = (spec.applied_strokes().len(), spec.applied_runs().len());
    match &mut spec.payload {
        LayerPayload::Constant(c) => {
            ui.add(egui::DragValue::new(&mut c.height_m).speed(1.0).prefix("height ").suffix(" m"));
        }
        LayerPayload::Procedural(p) => {
            let n = &mut p.noise;
            ui.add(
                egui::DragValue::new(&mut n.amplitude_m).speed(1.0).range(0.0..=1e5).prefix("amplitude ").suffix(" m"),
            );
            ui.add(
                egui::DragValue::new(&mut n.wavelength_m)
                    .speed(10.0)
                    .range(1.0..=1e7)
                    .prefix("wavelength ")
                    .suffix(" m"),
            );
            egui::ComboBox::from_label("noise").selected_text(noise_name(n.noise_type)).show_ui(ui, |ui| {
                for t in [NoiseType::Fbm, NoiseType::Ridged] {
                    ui.selectable_value(&mut n.noise_type, t, noise_name(t));
                }
            });
            ui.add(egui::Slider::new(&mut n.octaves, 1..=16).text("octaves"));
            ui.add(egui::Slider::new(&mut n.lacunarity, 1.5..=3.0).text("lacunarity"));
            ui.add(egui::Slider::new(&mut n.gain, 0.05..=0.95).text("gain"));
            let mut beyond = n.placement == DetailWhere::BeyondData;
            if ui.checkbox(&mut beyond, "only beyond the data").changed() {
                n.placement = if beyond { DetailWhere::BeyondData } else { DetailWhere::Everywhere };
            }
            ui.add(egui::DragValue::new(&mut n.seed).prefix("seed "));
        }
        LayerPayload::Difference(_) => {}
        LayerPayload::Edit(e) => {
            ui.label(format!("{applied_strokes} strokes applied of {}", e.strokes.len()));
        }
        LayerPayload::Erosion(e) => {
            ui.label(format!("{applied_runs} erosion runs applied of {}", e.runs.len()));
        }
        LayerPayload::Dataset(d) => {
            ui.add(
                egui::DragValue::new(&mut d.feather_edge_m)
                    .speed(100.0)
                    .range(0.0..=1e6)
                    .prefix("edge feather ")
                    .suffix(" m"),
            )
            .on_hover_text("fade the dataset in from its own no-data edge over this distance on the surface");
            ui.horizontal(|ui| {
                let [east, north] = &mut d.shift_m;
                ui.add(
                    egui::DragValue::new(east).speed(1.0).range(-10_000.0..=10_000.0).prefix("shift E ").suffix(" m"),
                );
                ui.add(egui::DragValue::new(north).speed(1.0).range(-10_000.0..=10_000.0).prefix("N ").suffix(" m"));
            })
            .response
            .on_hover_text("move the dataset east and north (what terrafuse coregister --apply writes)");
            // Each bias correction in a line (each removable), as coregister --apply wrote it.
            let mut removed = None;
            for (k, bias) in d.correction.iter().enumerate() {
                ui.horizontal(|ui| {
                    ui.label(format!("correction {}: {} (up to {:.2} m)", k + 1, bias.step_name(), bias.bound_m()));
                    if ui.small_button(format!("remove correction {}", k + 1)).clicked() {
                        removed = Some(k);
                    }
                });
            }
            if let Some(k) = removed {
                d.correction.remove(k);
            }
        }
    }
}

fn noise_name(t: NoiseType) -> &'static str {
    match t {
        NoiseType::Fbm => "fBm",
        NoiseType::Ridged => "ridged",
    }
}

/// `valid_range_m`: values outside are no data.
fn valid_range_ui(ui: &mut egui::Ui, spec: &mut LayerSpec) {
    ui.horizontal(|ui| {
        let mut on = spec.valid_range_m.is_some();
        if ui.checkbox(&mut on, "valid range").changed() {
            spec.valid_range_m = on.then_some([-11_000.0, 9_000.0]);
        }
        if let Some([lo, hi]) = &mut spec.valid_range_m {
            ui.add(egui::DragValue::new(lo).speed(10.0).range(-1e6..=*hi).suffix(" m"));
            ui.add(egui::DragValue::new(hi).speed(10.0).range(*lo..=1e6).suffix(" m"));
        }
    });
}

/// The extent: none, a box (west, south, east, north in degrees) or a polygon (edited in the
/// project file; its feather here), and the feather inside its edge.
fn extent_ui(ui: &mut egui::Ui, spec: &mut LayerSpec) {
    ui.horizontal(|ui| {
        let mut boxed = matches!(spec.extent, Some(ExtentSpec::Box(_)));
        let polygon = matches!(spec.extent, Some(ExtentSpec::Polygon(_)));
        if !polygon && ui.checkbox(&mut boxed, "extent box").changed() {
            spec.extent = boxed.then_some(ExtentSpec::Box([-180.0, -90.0, 180.0, 90.0]));
            if !boxed {
                spec.feather_m = 0.0;
            }
        }
        if let Some(ExtentSpec::Polygon(p)) = &spec.extent {
            ui.label(format!("extent: polygon of {} vertices", p.len()));
        }
    });
    if let Some(ExtentSpec::Box([w, so, e, n])) = &mut spec.extent {
        ui.horizontal(|ui| {
            ui.add(egui::DragValue::new(w).speed(0.01).range(-180.0..=180.0).prefix("W ").suffix("°"));
            ui.add(egui::DragValue::new(so).speed(0.01).range(-90.0..=*n).prefix("S ").suffix("°"));
            ui.add(egui::DragValue::new(e).speed(0.01).range(-180.0..=180.0).prefix("E ").suffix("°"));
            ui.add(egui::DragValue::new(n).speed(0.01).range(*so..=90.0).prefix("N ").suffix("°"));
        });
    }
    if spec.extent.is_some() {
        ui.add(egui::DragValue::new(&mut spec.feather_m).speed(100.0).range(0.0..=1e7).prefix("feather ").suffix(" m"));
    }
}
