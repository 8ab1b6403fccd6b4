//! One side of a comparison, a difference or a check, as a scene of its own: a layer alone, or a
//! group of layers composed. The rule is written here once, for `compare`, `coregister`, the
//! uncertainty, profiles, `export --layer` and replay's checks:
//! - a layer alone is shown with `over` and opacity 1, its other settings as the project has
//!   them, and every other layer hidden;
//! - a layer of deltas (an edit or an erosion layer) alone is its deltas over a zero plane (its
//!   deltas are still the ones its operations made on the terrain really below it);
//! - a group (`A+B`) shows its layers in the project's order with their own blend modes and
//!   opacities.

use super::Scene;
use crate::layers::{BlendMode, LayerError, LayerSpec, Operand};

impl Scene {
    /// The scene of `operand`: this scene with the layers that are not the operand's hidden (see
    /// the module's documentation). Names that are not layers are simply not shown.
    pub fn of_operand(&self, operand: &Operand) -> Result<Scene, LayerError> {
        let names = operand.names();
        let mut scene = self.clone();
        let alone = matches!(operand, Operand::Layer(_));
        let mut deltas_alone = false;
        for k in 0..scene.stack.layers.len() {
            let mut spec = scene.stack.layers[k].spec.clone();
            spec.visible = names.contains(&spec.name.as_str());
            if spec.visible && alone {
                spec.opacity = 1.0;
                deltas_alone = spec.holds_deltas();
                if !deltas_alone {
                    spec.blend = BlendMode::Over;
                }
            }
            scene.stack.set(k, spec)?;
        }
        if deltas_alone {
            let used = |n: &str| scene.stack.index_of(n).is_some();
            let zero = (0..).map(|k| format!("zero plane {k}")).find(|n| !used(n)).unwrap_or_default();
            scene.stack.insert(0, LayerSpec::constant(&zero, 0.0))?;
        }
        Ok(scene)
    }
}
