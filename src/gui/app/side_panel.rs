//! The panel on the left: the project's views and its layer stack, always in sight, then one
//! click away below them the view settings (camera, detail, colour, isolines, lighting, each
//! collapsible), the tools (compare, brush, erosion) and the project's facts.

use super::*;

/// What the panel shows below the layers.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Tab {
    /// The view settings.
    View,
    /// Comparison, co-registration, differences, swipes and profiles.
    Compare,
    /// Brushing an edit layer.
    Brush,
    /// Erosion runs and the erosion brush.
    Erosion,
    /// The project's file, body, datasets and device.
    Project,
}

impl Tab {
    const ALL: [(Tab, &'static str); 5] = [
        (Tab::View, "View"),
        (Tab::Compare, "Compare"),
        (Tab::Brush, "Brush"),
        (Tab::Erosion, "Erosion"),
        (Tab::Project, "Project"),
    ];

    /// The tab of a name (`brush`, `Erosion`, …).
    pub(crate) fn named(name: &str) -> Option<Tab> {
        Tab::ALL.iter().find(|(_, n)| n.eq_ignore_ascii_case(name)).map(|(t, _)| *t)
    }
}

impl App {
    pub(super) fn side_panel(&mut self, ui: &mut egui::Ui) {
        // The views and the layers: at most half the panel's height, scrolled within it.
        egui::ScrollArea::vertical().id_salt("layers").max_height(ui.available_height() * 0.5).show(ui, |ui| {
            ui.heading("Views");
            let names: Vec<String> = self.project.views.keys().cloned().collect();
            ui.horizontal_wrapped(|ui| {
                for name in names {
                    if ui.button(&name).clicked() {
                        let spec = self.project.views[&name];
                        self.set_camera(spec);
                    }
                }
                if ui.button("home").on_hover_text("the view the window opened with (key H)").clicked() {
                    self.set_camera(self.home);
                }
            });
            ui.horizontal(|ui| {
                ui.add(egui::TextEdit::singleline(&mut self.view_name).hint_text("name").desired_width(110.0));
                if ui.button("save view").on_hover_text("adds the current camera to the project's views").clicked() {
                    self.save_view();
                }
            });

            ui.separator();
            ui.heading("Layers");
            if self.difference_range.poll(&self.project, &mut self.renderer) {
                self.dirty = true;
            }
            if self.difference_range.busy() {
                ui.ctx().request_repaint_after(std::time::Duration::from_millis(100));
            }
            if let Some(e) = &self.difference_range.error {
                ui.colored_label(egui::Color32::LIGHT_RED, format!("difference range: {e}"));
            }
            // Adding a dataset comes before the list, reachable without scrolling past it.
            match self.add_dataset.ui(ui, &self.project) {
                Some(Ok((spec, info))) => {
                    let name = spec.name.clone();
                    match self.insert_dataset(spec, info) {
                        Ok(()) => {
                            self.stack_changed();
                            self.message = format!("added dataset layer '{name}'");
                        }
                        Err(e) => self.message = crate::errors::chain(&e),
                    }
                }
                Some(Err(e)) => self.message = e.to_string(),
                None => {}
            }
            if let crate::gui::cluster_import::ClusterAction::AddStore { store, dataset } =
                self.cluster.ui(ui, &self.project)
            {
                self.add_dataset.path = store.display().to_string();
                self.add_dataset.name = dataset;
                if let Err(e) = self.add_dataset.start(&self.project) {
                    self.message = e.to_string();
                }
            }
            self.layers_ui(ui);
        });
        ui.separator();
        ui.horizontal_wrapped(|ui| {
            for (tab, name) in Tab::ALL {
                ui.selectable_value(&mut self.tab, tab, name);
            }
        });
        // A tool acts on its own tab: leaving it disarms it (the brush unless pinned).
        if self.tab != Tab::Brush && !self.brush.pinned {
            self.brush.on = false;
        }
        if self.tab != Tab::Erosion {
            self.erosion.brush = false;
        }
        ui.separator();
        egui::ScrollArea::vertical().id_salt("tab").show(ui, |ui| match self.tab {
            Tab::View => self.view_settings(ui),
            Tab::Compare => self.compare_tab(ui),
            Tab::Brush => self.brush_ui(ui),
            Tab::Erosion => self.erosion_ui(ui),
            Tab::Project => {
                self.project_facts(ui);
                let (camera, body) = (self.camera(), self.renderer.scene().ellipsoid);
                self.export_panel.ui(ui, &self.project_path, &body, (camera.lon, camera.lat));
            }
        });
    }

    /// Camera, detail, colour, isolines and lighting, each in a collapsible section.
    fn view_settings(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Camera").default_open(false).show(ui, |ui| self.camera_settings(ui));
        self.flight_ui(ui);
        egui::CollapsingHeader::new("Detail").default_open(false).show(ui, |ui| self.detail_settings(ui));
        egui::CollapsingHeader::new("Colour").default_open(true).show(ui, |ui| self.colour_settings(ui));
        egui::CollapsingHeader::new("Isolines").default_open(true).show(ui, |ui| self.isoline_settings(ui));
        egui::CollapsingHeader::new("Lighting").default_open(false).show(ui, |ui| self.lighting_settings(ui));
        self.apply_visuals();
        ui.separator();
        ui.label(
            egui::RichText::new(
                "drag: move the globe · right drag or ctrl+drag: orbit · middle drag or shift+drag: look · \
                 wheel: zoom to the cursor · W A S D / arrows: fly · Q E: down, up · N: north up · H: home",
            )
            .small(),
        );
    }

    /// The camera's place, direction and field of view, and its `--camera` for `terrafuse render`.
    fn camera_settings(&mut self, ui: &mut egui::Ui) {
        let mut c = self.camera;
        egui::Grid::new("camera").num_columns(2).show(ui, |ui| {
            let row = |ui: &mut egui::Ui, label: &str, v: &mut f64, speed: f64, range: (f64, f64), unit: &str| {
                let name = ui.label(label).id;
                ui.add(egui::DragValue::new(v).speed(speed).range(range.0..=range.1).suffix(unit).max_decimals(6))
                    .labelled_by(name);
                ui.end_row();
            };
            row(ui, "latitude", &mut c.lat, 0.01, (-90.0, 90.0), "°");
            row(ui, "longitude", &mut c.lon, 0.01, (-180.0, 180.0), "°");
            let alt_speed = (c.alt.abs() * 0.01).max(1.0);
            row(ui, "altitude", &mut c.alt, alt_speed, (-1.0e5, 1.0e9), " m");
            row(ui, "heading", &mut c.heading, 0.5, (0.0, 360.0), "°");
            row(ui, "pitch", &mut c.pitch, 0.5, (-90.0, 90.0), "°");
            row(ui, "field of view", &mut c.fov, 0.5, (1.0, 150.0), "°");
        });
        self.set_camera(c);
        let text = format!(
            "{:.6},{:.6},{:.1},{:.2},{:.2},{:.1}",
            self.camera.lat, self.camera.lon, self.camera.alt, self.camera.heading, self.camera.pitch, self.camera.fov
        );
        ui.label(egui::RichText::new(format!("--camera {text}")).monospace().small())
            .on_hover_text("this camera for terrafuse render");
    }

    /// The level-of-detail threshold t, the pixel error and the render scale.
    fn detail_settings(&mut self, ui: &mut egui::Ui) {
        let t = self.threshold_px;
        ui.add(egui::Slider::new(&mut self.threshold_px, 0.5..=8.0).logarithmic(true).text("t, pixels per sample"));
        if t != self.threshold_px {
            self.renderer.set_threshold(self.threshold_px);
            self.dirty = true;
            self.mark_unsaved();
        }
        let e = self.pixel_error;
        ui.add(egui::Slider::new(&mut self.pixel_error, 0.05..=8.0).logarithmic(true).text("pixel error, px"))
            .on_hover_text(
                "the mesh is drawn as coarsely as keeps its geometric error under this on screen; \
                 colours, isolines and shading are read from the data per pixel whatever the mesh",
            );
        if e != self.pixel_error {
            self.renderer.set_pixel_error(self.pixel_error);
            self.dirty = true;
            self.mark_unsaved();
        }
        let s = self.render_scale;
        ui.add(egui::Slider::new(&mut self.render_scale, 0.25..=1.0).text("render scale"))
            .on_hover_text("renders fewer pixels and scales the image up (for software GPUs)");
        if s != self.render_scale {
            self.dirty = true;
        }
    }

    /// The colour map, what it colours, its range and the vertical exaggeration.
    fn colour_settings(&mut self, ui: &mut egui::Ui) {
        let v = &mut self.visuals;
        let current = match &v.colour_map.file {
            Some(f) => format!("file {}", f.display()),
            None => v.colour_map.preset.clone(),
        };
        egui::ComboBox::from_label("colour map").selected_text(current).show_ui(ui, |ui| {
            for (name, _, _) in crate::colour::PRESETS {
                if ui.selectable_label(v.colour_map.file.is_none() && v.colour_map.preset == *name, *name).clicked() {
                    v.colour_map.preset = (*name).to_string();
                    v.colour_map.file = None;
                }
            }
        });
        egui::ComboBox::from_label("colour by").selected_text(v.colour_map.by.name()).show_ui(ui, |ui| {
            for by in crate::project::ColourBy::all() {
                if ui.selectable_label(v.colour_map.by == by, by.name()).clicked() && v.colour_map.by != by {
                    v.colour_map.by = by;
                    v.colour_map.range_m = None;
                }
            }
        });
        let data = v.colour_map.by.default_range(self.renderer.scene().range_m);
        let unit = format!(" {}", v.colour_map.by.unit());
        let mut range = v.colour_map.range_m.unwrap_or([data.0, data.1]);
        ui.horizontal(|ui| {
            ui.label("range");
            // A hundredth of the default span a point dragged (1 m of a 100 m relief, 0.04 of a curvature's ±2).
            let speed = (data.1 - data.0).abs().max(1e-3) / 100.0;
            let low = ui.add(egui::DragValue::new(&mut range[0]).speed(speed).suffix(&unit));
            low.on_hover_text("the value of the ramp's first colour");
            let high = ui.add(egui::DragValue::new(&mut range[1]).speed(speed).suffix(&unit));
            high.on_hover_text("the value of the ramp's last colour");
            let window = v.colour_map.by.attribute().filter(|a| {
                use crate::attributes::Attribute;
                !matches!(a, Attribute::Slope | Attribute::Aspect | Attribute::Hillshade)
            });
            let hint = match window {
                Some(_) => "the attribute's 2nd to 98th percentile on the quads drawn now (symmetric about 0 for the curvatures and TPI)",
                None => "the default range (the datasets' heights, 0–45° of slope, 0–360° of aspect, 1–255 of hillshade)",
            };
            if ui.small_button("data").on_hover_text(hint).clicked() {
                range = [data.0, data.1];
                if let Some(attribute) = window {
                    let scene = self.renderer.scene();
                    match crate::compare::attribute_range(scene, self.renderer.drawn(), attribute, 16) {
                        Ok(Some((lo, hi))) => range = [lo, hi],
                        Ok(None) => self.message = format!("{}: no data drawn", attribute.name()),
                        Err(e) => self.message = format!("{}: {}", attribute.name(), crate::errors::chain(&e)),
                    }
                }
            }
        });
        if range[1] > range[0] && Some(range) != v.colour_map.range_m && range != [data.0, data.1] {
            v.colour_map.range_m = Some(range);
        } else if range == [data.0, data.1] {
            v.colour_map.range_m = None;
        }
        ui.add(egui::Slider::new(&mut v.exaggeration, 0.1..=50.0).logarithmic(true).text("exaggeration"));
    }

    /// The isolines: shown or not, interval, offset, major lines and widths.
    fn isoline_settings(&mut self, ui: &mut egui::Ui) {
        let v = &mut self.visuals;
        let iso = &mut v.isolines;
        ui.checkbox(&mut iso.enabled, "show isolines");
        egui::Grid::new("isolines").num_columns(2).show(ui, |ui| {
            let row = |ui: &mut egui::Ui, label: &str, value: egui::DragValue<'_>| {
                let name = ui.label(label).id;
                ui.add(value).labelled_by(name);
                ui.end_row();
            };
            row(ui, "interval", egui::DragValue::new(&mut iso.interval_m).speed(1.0).range(0.01..=1.0e6).suffix(" m"));
            row(ui, "offset", egui::DragValue::new(&mut iso.offset_m).speed(1.0).suffix(" m"));
            row(ui, "major every", egui::DragValue::new(&mut iso.major_every).range(0..=100));
            row(ui, "width", egui::DragValue::new(&mut iso.width_px).speed(0.05).range(0.1..=10.0).suffix(" px"));
            row(
                ui,
                "major width",
                egui::DragValue::new(&mut iso.major_width_px).speed(0.05).range(0.1..=10.0).suffix(" px"),
            );
        });
    }

    /// The hillshade: on or off, the sun's azimuth and elevation, its strength.
    fn lighting_settings(&mut self, ui: &mut egui::Ui) {
        let v = &mut self.visuals;
        let light = &mut v.lighting;
        ui.checkbox(&mut light.enabled, "hillshade");
        ui.add(egui::Slider::new(&mut light.sun_azimuth_deg, 0.0..=360.0).text("sun azimuth °"));
        ui.add(egui::Slider::new(&mut light.sun_elevation_deg, 0.0..=90.0).text("sun elevation °"));
        ui.add(egui::Slider::new(&mut light.strength, 0.0..=1.0).text("strength"));
    }

    /// The comparison panel, its profile and the swipe.
    fn compare_tab(&mut self, ui: &mut egui::Ui) {
        match self.compare.ui(ui, &self.project) {
            crate::gui::compare_panel::CompareAction::Apply(c) => self.apply_coregistration(&ui.ctx().clone(), &c),
            crate::gui::compare_panel::CompareAction::ShowDifference { a, b } => self.show_difference(&a, &b),
            crate::gui::compare_panel::CompareAction::None => {}
        }
        let (a, b) = self.compare.selection();
        let (a, b) = (a.to_string(), b.to_string());
        if !a.is_empty() && a != b {
            self.cluster_compare.ui(ui, &self.project_path, &a, &b);
        }
        self.profile_ui(ui);
        if !a.is_empty() && a != b {
            let mut on = self.swipe.is_some();
            if ui
                .checkbox(&mut on, format!("swipe {a} | {b}"))
                .on_hover_text("A left of a line, B right of it; drag the line in the view")
                .changed()
            {
                if on {
                    self.swipe_request = Some((a, b));
                } else {
                    self.swipe = None;
                    self.dirty = true;
                }
            }
            if let Some(swipe) = &mut self.swipe
                && ui
                    .checkbox(&mut swipe.side_by_side, "side by side")
                    .on_hover_text("two linked views, one camera, instead of one split picture")
                    .changed()
            {
                self.dirty = true;
            }
        }
    }

    /// The project's file, body, datasets and device.
    fn project_facts(&mut self, ui: &mut egui::Ui) {
        ui.label(self.project_path.display().to_string());
        ui.label(format!("body: {}", self.project.body));
        for info in self.renderer.scene().datasets.iter() {
            ui.label(format!(
                "{}: levels 0–{}, {:.0} … {:.0} m",
                info.dataset, info.finest_level, info.range_m.0, info.range_m.1
            ));
        }
        ui.label(egui::RichText::new(&self.device).small());
    }

    /// Applies a co-registration to its layer A: shift, raise and biases (`Coregistration::apply_to`).
    fn apply_coregistration(&mut self, ctx: &egui::Context, c: &crate::compare::Coregistration) {
        let Some(index) = self.project.layers.iter().position(|l| l.name == c.a) else { return };
        let mut spec = self.project.layers[index].clone();
        if let Err(e) = c.apply_to(&mut spec) {
            self.message = e.to_string();
            return;
        }
        match self.renderer.update_layer(index, spec.clone()) {
            Ok(()) => {
                self.project.layers[index] = spec;
                self.dirty = true;
                self.mark_unsaved();
                // The layers panel shows what the layer now holds.
                crate::gui::layers_panel::show_settings_of(ctx, index);
                let biases = c.biases().iter().map(|b| b.step_name()).collect::<Vec<_>>();
                let corrected =
                    if biases.is_empty() { String::new() } else { format!(", corrected by {}", biases.join(", ")) };
                self.message = format!(
                    "moved '{}' east {:+.2} m, north {:+.2} m, up {:+.2} m{corrected}",
                    c.a, c.east_m, c.north_m, c.up_m
                );
            }
            Err(e) => self.message = e.to_string(),
        }
    }
}
