//! The workstation applies the layers panel's actions ([`LayerAction`]) and the tools' new layers
//! (a dataset added, a difference shown) to the renderer and the project alike: a change the
//! renderer refuses leaves the project as it was, and the refusal goes to the status line.

use super::*;
use crate::gui::layers_panel::{Drawn, LayerAction};
use crate::layers::{LayerError, LayerSpec};

impl App {
    /// The layers panel, its actions applied.
    pub(super) fn layers_ui(&mut self, ui: &mut egui::Ui) {
        let drawn = Drawn {
            difference: self.renderer.scene().stack.drawn_difference(),
            range_m: self.renderer.difference_range_m(),
        };
        let actions = crate::gui::layers_panel::layers_ui(ui, &self.project, drawn);
        let mut changed = false;
        for action in actions {
            match self.apply_layer_action(action) {
                Ok(()) => changed = true,
                Err(e) => self.message = crate::errors::chain(&e),
            }
        }
        if changed {
            self.stack_changed();
        }
    }

    /// Applies one action to the renderer, then (when it took it) to the project.
    fn apply_layer_action(&mut self, action: LayerAction) -> Result<(), LayerError> {
        let layers = &mut self.project.layers;
        match action {
            LayerAction::Insert(spec) => return self.insert_layer(spec),
            LayerAction::Update(index, spec) => {
                self.renderer.update_layer(index, spec.clone())?;
                layers[index] = spec;
            }
            LayerAction::Remove(index) => {
                self.renderer.remove_layer(index)?;
                let removed = layers.remove(index);
                // Saved swipes that show it go with it (the project would not load otherwise).
                self.project.comparison.swipes.retain(|_, s| s.a != removed.name && s.b != removed.name);
            }
            LayerAction::Move { from, to } => {
                self.renderer.move_layer(from, to);
                let layer = layers.remove(from);
                layers.insert(to, layer);
            }
        }
        Ok(())
    }

    /// Draws A − B over the terrain: the difference layer of these two operands already in the
    /// stack (shown, if it was hidden), else a new one on top.
    pub(super) fn show_difference(&mut self, a: &str, b: &str) {
        let of = [crate::layers::Operand::Layer(a.into()), crate::layers::Operand::Layer(b.into())];
        let existing = self.project.layers.iter().position(|l| l.as_difference().is_some_and(|d| d.of == of));
        let result = match existing {
            Some(k) if self.project.layers[k].visible => Ok(false),
            Some(k) => {
                let spec = LayerSpec { visible: true, ..self.project.layers[k].clone() };
                self.apply_layer_action(LayerAction::Update(k, spec)).map(|()| true)
            }
            None => self.insert_layer(crate::gui::difference_ui::new_layer(&self.project, a, b)).map(|()| true),
        };
        match (result, existing) {
            (Ok(changed), Some(k)) => {
                if changed {
                    self.stack_changed();
                }
                self.message = format!("{a} - {b} is drawn by layer '{}'", self.project.layers[k].name);
            }
            (Ok(_), None) => {
                self.stack_changed();
                self.message = format!("drawing {a} - {b} over the terrain (layer on top of the stack)");
            }
            (Err(e), _) => self.message = crate::errors::chain(&e),
        }
    }

    /// Puts a new layer (not a dataset's) on top of the stack.
    pub(super) fn insert_layer(&mut self, spec: LayerSpec) -> Result<(), LayerError> {
        let top = self.project.layers.len();
        self.renderer.insert_layer(top, spec.clone())?;
        self.project.layers.push(spec);
        Ok(())
    }

    /// Puts a dataset layer (opened by [`crate::gui::add_dataset`]) on top of the stack.
    pub(super) fn insert_dataset(
        &mut self,
        spec: LayerSpec,
        info: crate::scene::dataset::DatasetInfo,
    ) -> Result<(), crate::gpu::GpuError> {
        let top = self.project.layers.len();
        self.renderer.insert_dataset_layer(top, spec.clone(), info)?;
        self.project.layers.push(spec);
        Ok(())
    }

    /// After the stack changed: redraw, mark the project unsaved, and stop a swipe (its second
    /// stack would no longer match the first).
    pub(super) fn stack_changed(&mut self) {
        self.dirty = true;
        self.mark_unsaved();
        if self.swipe.take().is_some() {
            self.message = "swipe stopped: the layer stack changed".into();
        }
    }
}
