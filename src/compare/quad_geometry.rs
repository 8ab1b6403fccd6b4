//! The geometry of a quad's samples that comparisons read: its 257² points on the ellipsoid, each
//! cell's area, and B's gradient and slope in the tangent plane.
//!
//! The slope at a sample comes from differences of the heights along the grid's two axes (central
//! where both neighbours have data, one-sided at the quad's border or next to no data), turned
//! into the gradient in the tangent plane through the two axes' ECEF vectors, so it is metres over
//! metres on the ellipsoid wherever the grid is sheared (near cube corners).

use glam::DVec3;
use rayon::prelude::*;

use crate::ecm::QuadId;
use crate::ecm::points::{cell_area_m2, sample_point};
use crate::store::grid::GRID;

const N: usize = GRID as usize;

/// The area of a quad's cell [i, i + 1] × [j, j + 1] on the ellipsoid, m² (see
/// [`cell_area_m2`]), its centre the mean of its corners.
pub(super) fn cell_area(
    ellipsoid: &crate::geodesy::Ellipsoid,
    quad: QuadId,
    points: &[(DVec3, f64, f64)],
    i: usize,
    j: usize,
) -> f64 {
    let corner = |di: usize, dj: usize| points[(j + dj) * N + i + di].0;
    let centre = (corner(0, 0) + corner(1, 0) + corner(0, 1) + corner(1, 1)) / 4.0;
    cell_area_m2(ellipsoid, quad.level, GRID - 1, centre)
}

/// The slope of `h` at sample (i, j) of a quad, degrees (NaN where no neighbour has data).
pub(super) fn slope_deg(points: &[(DVec3, f64, f64)], h: &[f32], i: usize, j: usize) -> f64 {
    gradient(points, h, i, j).map_or(f64::NAN, |g| g.length().atan().to_degrees())
}

/// The gradient of `h` at sample (i, j) of a quad, in the tangent plane (ECEF, metres per metre):
/// from differences along both grid axes (central where both neighbours have data, else
/// one-sided), g = α·ex + β·ey with g·ex = dx and g·ey = dy, so it is right where the grid's axes
/// are not orthogonal (near cube corners).
pub(super) fn gradient(points: &[(DVec3, f64, f64)], h: &[f32], i: usize, j: usize) -> Option<DVec3> {
    let at = |i: usize, j: usize| (points[j * N + i].0, f64::from(h[j * N + i]));
    let axis = |before: Option<(usize, usize)>, after: Option<(usize, usize)>| -> Option<(DVec3, f64)> {
        let valid = |c: Option<(usize, usize)>| c.map(|(i, j)| at(i, j)).filter(|(_, v)| !v.is_nan());
        let (lo, hi) = match (valid(before), valid(after)) {
            (Some(lo), Some(hi)) => (lo, hi),
            (Some(lo), None) => (lo, at(i, j)),
            (None, Some(hi)) => (at(i, j), hi),
            (None, None) => return None,
        };
        Some((hi.0 - lo.0, hi.1 - lo.1))
    };
    let (ex, dx) = axis(i.checked_sub(1).map(|i| (i, j)), (i + 1 < N).then_some((i + 1, j)))?;
    let (ey, dy) = axis(j.checked_sub(1).map(|j| (i, j)), (j + 1 < N).then_some((i, j + 1)))?;
    if dx.is_nan() || dy.is_nan() {
        return None;
    }
    let (xx, xy, yy) = (ex.dot(ex), ex.dot(ey), ey.dot(ey));
    let det = xx * yy - xy * xy;
    if det <= 0.0 {
        return None;
    }
    let alpha = (dx * yy - dy * xy) / det;
    let beta = (dy * xx - dx * xy) / det;
    Some(alpha * ex + beta * ey)
}

/// A quad's 257² sample points: ECEF, longitude and latitude (radians).
pub(super) fn quad_points(ellipsoid: &crate::geodesy::Ellipsoid, quad: QuadId) -> Vec<(DVec3, f64, f64)> {
    (0..N * N).into_par_iter().map(|k| sample_point(ellipsoid, quad, GRID, (k % N) as u32, (k / N) as u32)).collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;
    use crate::geodesy::Ellipsoid;

    #[test]
    fn a_plane_tilted_by_a_known_angle_has_that_slope_even_where_the_grid_is_sheared() {
        // h = tan(20°) × the distance east of the quad's first sample along the local east axis:
        // a plane of slope 20° on the ellipsoid, at a cube corner quad (the grid most sheared).
        let e = Ellipsoid::WGS84;
        for quad in [QuadId::new(Face::Front, 9, 511, 511).unwrap(), QuadId::new(Face::Top, 9, 200, 300).unwrap()] {
            let points: Vec<(DVec3, f64, f64)> =
                (0..N * N).map(|k| sample_point(&e, quad, GRID, (k % N) as u32, (k / N) as u32)).collect();
            let (o, lon, _) = points[128 * N + 128];
            let east = DVec3::new(-lon.sin(), lon.cos(), 0.0);
            let h: Vec<f32> =
                points.iter().map(|(p, _, _)| ((p - o).dot(east) * 20f64.to_radians().tan()) as f32).collect();
            for (i, j) in [(128, 128), (0, 0), (255, 3), (40, 200)] {
                let s = slope_deg(&points, &h, i, j);
                assert!((s - 20.0).abs() < 0.05, "{quad} ({i},{j}): {s}°");
            }
        }
    }
}
