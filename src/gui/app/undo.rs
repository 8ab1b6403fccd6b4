//! Undo and redo in the window: an edit or erosion layer's undo position moved by some of its
//! operations (the brush's and the erosion panel's buttons, Ctrl+Z and Ctrl+Shift+Z on the
//! brush's layer), the layer rebuilt to there by the editing session.

use super::App;

impl App {
    /// Moves the undo position of the edit or erosion layer `name` by `by` of its operations
    /// (strokes or runs); nothing past either end.
    pub(super) fn move_layer_undo(&mut self, name: &str, by: i64) {
        let Some(index) = self.project.layers.iter().position(|l| l.name == name) else { return };
        let spec = &self.project.layers[index];
        let erosion = spec.as_erosion().is_some();
        let total = spec.operations() as i64;
        let applied = spec.applied().map_or(total, |a| a as i64) + by;
        if !(0..=total).contains(&applied) {
            return;
        }
        let rebuilt = if erosion {
            self.editor.set_erosion_applied(&mut self.renderer, index, applied as usize)
        } else {
            self.editor.set_applied(&mut self.renderer, index, applied as usize)
        };
        match rebuilt {
            Ok(spec) => {
                self.project.layers[index] = spec;
                self.dirty = true;
                self.mark_unsaved();
                let (done, what) = (if by < 0 { "undone" } else { "redone" }, if erosion { "runs" } else { "strokes" });
                self.message = format!("{done} to {applied} of {total} {what}");
                if erosion {
                    self.update_drainage();
                }
            }
            Err(e) => self.message = e.to_string(),
        }
    }
}
