//! What the erosion panel's region map shows of a run: the water depth, the sediment or the
//! change of height per cell, as values and as a picture.

use crate::erosion::sim::Run;

/// What the region map shows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Overlay {
    Water,
    Sediment,
    Change,
}

/// Per cell, what the overlay shows, metres (NaN where there is nothing to show: dry, no
/// sediment, unchanged).
pub(super) fn field(run: &Run, overlay: Overlay) -> Vec<f64> {
    let g = &run.grid;
    (0..g.len())
        .map(|i| {
            let units = match overlay {
                Overlay::Water => run.state.water[i],
                Overlay::Sediment => run.state.sediment[i],
                Overlay::Change => run.state.soil[i],
            };
            if units == 0 { f64::NAN } else { units as f64 * run.unit_m3() / g.area_m2[i] }
        })
        .collect()
}

/// The region's water depth, sediment or change of height as a picture (north up), at most 256
/// pixels a side: blue for water, brown for sediment, red-blue for the change (lowered red).
pub(super) fn region_map(run: &Run, overlay: Overlay) -> egui::ColorImage {
    let g = &run.grid;
    let step = g.width.max(g.height).div_ceil(256).max(1);
    let (w, h) = (g.width.div_ceil(step), g.height.div_ceil(step));
    let value = |i: usize| match overlay {
        Overlay::Water => run.depth_m(i),
        Overlay::Sediment => run.state.sediment[i] as f64 * run.unit_m3() / g.area_m2[i],
        Overlay::Change => run.state.soil[i] as f64 * run.unit_m3() / g.area_m2[i],
    };
    let scale = (0..g.len()).map(|i| value(i).abs()).fold(0f64, f64::max).max(1e-6);
    let mut pixels = Vec::with_capacity(w * h);
    for y in (0..h).rev() {
        for x in 0..w {
            let i = (y * step).min(g.height - 1) * g.width + (x * step).min(g.width - 1);
            let v = (value(i) / scale).clamp(-1.0, 1.0);
            let a = (v.abs().sqrt() * 255.0) as u8;
            pixels.push(match overlay {
                Overlay::Water => egui::Color32::from_rgb(255 - a, 255 - a / 2, 255),
                Overlay::Sediment => egui::Color32::from_rgb(255 - a / 3, 255 - a / 2, 255 - a),
                Overlay::Change if v < 0.0 => egui::Color32::from_rgb(255, 255 - a, 255 - a),
                Overlay::Change => egui::Color32::from_rgb(255 - a, 255 - a, 255),
            });
        }
    }
    egui::ColorImage::new([w, h], pixels)
}
