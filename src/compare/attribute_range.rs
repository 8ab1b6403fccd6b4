//! The range of a terrain attribute over some quads of a scene (the workstation's *data* button
//! for a colour layer of curvature, TPI, TRI or roughness, whose values scale with the spacing
//! the screen resolves): the attribute of every interior sample of the composed stack (CPU
//! reference), with the windows of `attributes::attribute_at` over the quad's own samples and
//! their axes measured on the ellipsoid, and its 2nd and 98th percentiles.

use crate::attributes::{Attribute, PixelAxes, attribute_at};
use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::scene::Scene;

use super::CompareError;
use super::quad_geometry::{axes_at, quad_points};

/// Samples along a quad edge.
const N: usize = GRID as usize;

/// The range a colour ramp over `attribute` spans on `quads` (at most `max_quads` of them, evenly
/// chosen): its 2nd to 98th percentile, symmetric about 0 for the signed ones (the curvatures and
/// TPI, so that 0 is the ramp's middle). None where no quad has data.
pub fn attribute_range(
    scene: &Scene,
    quads: &[QuadId],
    attribute: Attribute,
    max_quads: usize,
) -> Result<Option<(f64, f64)>, CompareError> {
    let step = quads.len().div_ceil(max_quads.max(1)).max(1);
    let chosen: Vec<QuadId> = quads.iter().step_by(step).copied().collect();
    let grids = scene.compose_cpu(&chosen)?;
    let mut values = Vec::new();
    for quad in &chosen {
        let Some(h) = grids.get(quad) else { continue };
        if h.iter().all(|v| v.is_nan()) {
            continue;
        }
        let points = quad_points(&scene.ellipsoid, *quad);
        // Every fourth sample each way: 4 096 windows a quad.
        for j in (1..N - 1).step_by(4) {
            for i in (1..N - 1).step_by(4) {
                let k = j * N + i;
                let mut z = [0.0; 9];
                // Row 0 at the top: j + 1.
                for (m, v) in z.iter_mut().enumerate() {
                    *v = f64::from(h[(j + 1 - m / 3) * N + i + m % 3 - 1]);
                }
                if z.iter().any(|v| v.is_nan()) {
                    continue;
                }
                let (east, north) = axes_at(&scene.ellipsoid, points[k]);
                let x = (points[k + 1] - points[k - 1]) / 2.0;
                let y = (points[k + N] - points[k - N]) / 2.0;
                let axes = PixelAxes { x: [x.dot(east), x.dot(north)], y: [y.dot(east), y.dot(north)] };
                let value = attribute_at(attribute, &z, &axes);
                if value.is_finite() {
                    values.push(value);
                }
            }
        }
    }
    if values.is_empty() {
        return Ok(None);
    }
    values.sort_by(f64::total_cmp);
    let at = |p: f64| values[((values.len() - 1) as f64 * p).round() as usize];
    let (lo, hi) = (at(0.02), at(0.98));
    let signed = matches!(
        attribute,
        Attribute::Curvature | Attribute::PlanformCurvature | Attribute::ProfileCurvature | Attribute::Tpi
    );
    Ok(Some(if signed {
        let m = lo.abs().max(hi.abs()).max(1e-9);
        (-m, m)
    } else if hi > lo {
        (lo, hi)
    } else {
        (lo, lo + 1e-9_f64.max(lo.abs() * 1e-6))
    }))
}
