//! The drainage overlay of the *Erosion* section: where rivers run on the visible stack, before
//! and after a run. *drainage* routes the composed terrain of a region around the view's centre
//! (the erosion region's size; the level that gives about 512 cells across it, or the section's)
//! as a stream-power step routes it, and drapes over the terrain either the flow accumulation
//! (log-scaled, red on divides to blue in the largest river) or the channel network (cells
//! draining at least a threshold area, darker downstream). It follows the stack: a kept run, an
//! undo or a redo routes it again; *update* routes it again where the view now is.

use super::*;
use crate::erosion::landscape::drainage::{Drainage, Show};
use crate::erosion::landscape::flow::Routing;
use crate::erosion::region::Region;

/// The overlay's settings and what it last found.
pub(crate) struct DrainageTool {
    /// Whether the overlay is shown.
    on: bool,
    show: Show,
    /// The channels' threshold, km² of drainage area.
    threshold_km2: f64,
    routing: Routing,
    /// What the last routing found.
    summary: String,
}

impl Default for DrainageTool {
    fn default() -> DrainageTool {
        DrainageTool {
            on: false,
            show: Show::Channels,
            threshold_km2: 1.0,
            routing: Routing::D8,
            summary: String::new(),
        }
    }
}

impl DrainageTool {
    /// The settings; true when the overlay must be routed again (or removed, when off).
    pub(crate) fn ui(&mut self, ui: &mut egui::Ui) -> bool {
        let mut changed = false;
        ui.horizontal(|ui| {
            changed |= ui
                .checkbox(&mut self.on, "drainage")
                .on_hover_text("where rivers run on the visible stack, around the view's centre")
                .changed();
            if self.on && ui.button("update").on_hover_text("route again around the view's centre").clicked() {
                changed = true;
            }
        });
        if !self.on {
            return changed;
        }
        ui.horizontal(|ui| {
            changed |= ui.selectable_value(&mut self.show, Show::Channels, "channels").changed();
            changed |= ui.selectable_value(&mut self.show, Show::Accumulation, "accumulation").changed();
            changed |= ui.selectable_value(&mut self.routing, Routing::D8, "D8").changed();
            changed |= ui
                .selectable_value(&mut self.routing, Routing::Mfd, "MFD")
                .on_hover_text("area shared among every lower neighbour (Freeman 1991)")
                .changed();
        });
        if self.show == Show::Channels {
            changed |= ui
                .add(
                    egui::Slider::new(&mut self.threshold_km2, 0.01..=1000.0)
                        .logarithmic(true)
                        .text("channels from km²"),
                )
                .changed();
        }
        if !self.summary.is_empty() {
            ui.label(&self.summary);
        }
        changed
    }
}

impl App {
    /// Routes the visible stack around the view's centre and drapes the drainage over it (or
    /// removes the drape when the overlay is off). Nothing while a hydraulic run shows its own.
    pub(crate) fn update_drainage(&mut self) {
        if self.erosion.session.is_some() {
            return;
        }
        if !self.erosion.drainage.on {
            self.erosion.drainage.summary.clear();
            if let Err(e) = self.editor.set_erosion_overlay(&mut self.renderer, None) {
                self.message = format!("drainage: {}", crate::errors::chain(&e));
            }
            self.dirty = true;
            return;
        }
        match self.drainage_drape() {
            Ok(summary) => self.erosion.drainage.summary = summary,
            Err(message) => self.message = format!("drainage: {message}"),
        }
        self.dirty = true;
    }

    /// Routes and drapes; the summary, or what went wrong.
    fn drainage_drape(&mut self) -> Result<String, GuiError> {
        let e = self.renderer.scene().ellipsoid;
        let bounds = self.view_box(self.erosion.half_m)?;
        // The erosion layer's level when it has runs (the runs' cells), else the section's, else
        // about 512 cells across but not finer than the stack's detail.
        let layer_level = self
            .project
            .layers
            .iter()
            .find(|l| l.name == self.erosion.layer_name())
            .and_then(|l| l.runs().first().map(|r| r.level));
        let coarse = || {
            let level = crate::erosion::placement::default_level(&e, &bounds);
            self.renderer.scene().detail_level().map_or(level, |d| level.min(d))
        };
        let level = layer_level.or(self.erosion.level).unwrap_or_else(coarse);
        let region = Region::from_box(&e, bounds, level)?;
        // The composed stack, without the drape itself (hidden layers compose nothing).
        let scene = self.renderer.scene();
        let grid = region.grid(&e, &|q| Ok(scene.heights_cpu(q)?))?;
        if grid.base_m.iter().all(|h| h.is_nan()) {
            return Err(GuiError::Message("the stack has no data around the view's centre".into()));
        }
        let t = &self.erosion.drainage;
        let drainage = Drainage::of(&grid, t.routing);
        let threshold_m2 = t.threshold_km2 * 1e6;
        let shade = drainage.shade(&grid, t.show, threshold_m2);
        let summary = format!(
            "{} × {} cells at level {level} ({}): largest basin {:.1} km², {} channel cells from {} km², {} lake cells",
            region.width,
            region.height,
            t.routing.name(),
            drainage.largest_m2() / 1e6,
            drainage.channel_cells(threshold_m2),
            t.threshold_km2,
            drainage.flow.lake_cells
        );
        let raster = crate::erosion::layer::field_raster(e, &region, &shade);
        self.editor.set_erosion_overlay(&mut self.renderer, Some((raster, &region, 1.0)))?;
        Ok(summary)
    }

    /// Shows or hides the drainage overlay (tests; people tick the box).
    pub fn set_drainage(&mut self, on: bool) {
        self.erosion.drainage.on = on;
        self.update_drainage();
    }

    /// What the drainage overlay last found (tests; people read the panel).
    pub fn drainage_summary(&self) -> &str {
        &self.erosion.drainage.summary
    }
}
