//! The geometry of a quad's samples that comparisons read: its 257² points on the ellipsoid, each
//! cell's area, and B's gradient and slope in the tangent plane.
//!
//! The slope at a sample comes from differences of the heights along the grid's two axes (central
//! where both neighbours have data, one-sided at the quad's border or next to no data), turned
//! into the gradient in the tangent plane through the two axes' ECEF vectors, so it is metres over
//! metres on the ellipsoid wherever the grid is sheared (near cube corners).

use glam::DVec3;
use rayon::prelude::*;

use crate::ecm::grid::GRID;
use crate::ecm::points::cell_area_m2;
use crate::ecm::{CubeProjection, FacePoint, QuadId};

const N: usize = GRID as usize;

/// The area of a quad's cell [i, i + 1] × [j, j + 1] on the ellipsoid, m² (see
/// [`cell_area_m2`]), its centre the mean of its corners.
pub(super) fn cell_area(
    ellipsoid: &crate::geodesy::Ellipsoid,
    quad: QuadId,
    points: &[DVec3],
    i: usize,
    j: usize,
) -> f64 {
    let corner = |di: usize, dj: usize| points[(j + dj) * N + i + di];
    let centre = (corner(0, 0) + corner(1, 0) + corner(0, 1) + corner(1, 1)) / 4.0;
    cell_area_m2(ellipsoid, quad.level, GRID - 1, centre)
}

/// The slope of `h` at sample (i, j) of a quad, degrees (NaN where no neighbour has data).
pub(super) fn slope_deg(points: &[DVec3], h: &[f32], i: usize, j: usize) -> f64 {
    gradient(points, h, i, j).map_or(f64::NAN, |g| g.length().atan().to_degrees())
}

/// The gradient of `h` at sample (i, j) of a quad, in the tangent plane (ECEF, metres per metre):
/// from differences along both grid axes (central where both neighbours have data, else
/// one-sided), g = α·ex + β·ey with g·ex = dx and g·ey = dy, so it is right where the grid's axes
/// are not orthogonal (near cube corners).
pub(super) fn gradient(points: &[DVec3], h: &[f32], i: usize, j: usize) -> Option<DVec3> {
    let at = |i: usize, j: usize| (points[j * N + i], f64::from(h[j * N + i]));
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

/// Samples between the nodes a quad's points are projected at exactly.
const STEP: usize = 4;
/// Nodes along a quad's edge.
const NODES: usize = (N - 1) / STEP + 1;
/// The coarsest level whose quads are interpolated (nodes 610 m apart on Earth; at level 6,
/// 2.4 km apart, the interpolation misses by 8·10⁻⁷ m).
const INTERPOLATED_FROM_LEVEL: u8 = 8;
/// Quads within this many quads of a face's centre are projected exactly: QSC's cusp there
/// bends the points faster than a cubic follows (0.16 mm off in a quad next to the centre at
/// level 9, 2·10⁻⁸ m eight quads away).
const CENTRE_QUADS: i64 = 16;

/// A quad's 257² sample points on the ellipsoid (ECEF, metres).
///
/// A point is taken straight along QSC's sphere direction u onto the ellipsoid (r(ψ)·u, the
/// projection's shift to the sphere; the points of [`sample_point`](crate::ecm::points::sample_point)
/// without going through geodetic coordinates and back). QSC's inverse is exact at every fourth
/// sample each way (65² nodes) and the samples between are read from those nodes by cubic
/// Lagrange interpolation (`ecm::grid`'s weights; exact at the nodes): the points are a smooth
/// function of the grid position inside each of QSC's four triangles of a face, and there the
/// interpolation is within 10⁻⁸ m of the exact inverse (test below: 6·10⁻⁹ m at worst, a few
/// times the rounding of f64 Earth coordinates, 10⁻⁹ m). Where that does not hold, every point is
/// projected exactly: quads coarser than level 8, quads that a face's diagonal crosses (the
/// triangles meet there with a kink) and quads near the face's centre (QSC's cusp). One
/// sixteenth of the inverse projections elsewhere.
pub(super) fn quad_points(ellipsoid: &crate::geodesy::Ellipsoid, quad: QuadId) -> Vec<DVec3> {
    let at = |i: usize, j: usize| {
        let (x, y) = quad.sample_xy(GRID, i as u32, j as u32);
        let u = CubeProjection::Qsc.direction_from_face_point(FacePoint { face: quad.face, x, y });
        crate::geodesy::surface_point_from_direction(ellipsoid, u)
    };
    if !smooth_inside(quad) {
        return (0..N * N).into_par_iter().map(|k| at(k % N, k / N)).collect();
    }
    let nodes: Vec<DVec3> =
        (0..NODES * NODES).into_par_iter().map(|k| at(k % NODES * STEP, k / NODES * STEP)).collect();
    let weights: Vec<(usize, [f64; 4])> =
        (0..N).map(|i| crate::ecm::grid::cubic_weights(i as f64 / STEP as f64, NODES)).collect();
    (0..N * N)
        .into_par_iter()
        .map(|k| {
            let ((bu, wu), (bv, wv)) = (weights[k % N], weights[k / N]);
            let mut p = DVec3::ZERO;
            for (dj, w_v) in wv.iter().enumerate() {
                let row = &nodes[(bv + dj) * NODES + bu..][..4];
                let across = row[0] * wu[0] + row[1] * wu[1] + row[2] * wu[2] + row[3] * wu[3];
                p += across * *w_v;
            }
            p
        })
        .collect()
}

/// Whether a quad's points are smooth enough to interpolate: at an interpolated level, crossed
/// by no face diagonal and at least `CENTRE_QUADS` quads from the face's centre.
fn smooth_inside(quad: QuadId) -> bool {
    if quad.level < INTERPOLATED_FROM_LEVEL {
        return false;
    }
    // The quad's edges in half quads from the face's centre.
    let n = 1i64 << quad.level;
    let (x0, y0) = (2 * i64::from(quad.x) - n, 2 * i64::from(quad.y) - n);
    let (x1, y1) = (x0 + 2, y0 + 2);
    // The diagonal y = x crosses the open square where the intervals of x and y overlap
    // (touching at a corner only is fine); y = −x where those of −x and y do.
    let crosses = |lo: i64, hi: i64| lo < y1 && y0 < hi;
    let far = 2 * CENTRE_QUADS;
    let off_centre = x0 >= far || x1 <= -far || y0 >= far || y1 <= -far;
    !crosses(x0, x1) && !crosses(-x1, -x0) && off_centre
}

/// The longitude and geodetic latitude (radians) of a surface point p (ECEF, metres): those of
/// its direction from the centre.
pub(super) fn lon_lat(ellipsoid: &crate::geodesy::Ellipsoid, p: DVec3) -> (f64, f64) {
    let (lat, lon) = crate::geodesy::geodetic_from_sphere_direction(ellipsoid, p);
    (lon, lat)
}

/// The local east and north unit vectors at a surface point `p` (ECEF, metres) of the ellipsoid,
/// as [`local_axes`](crate::geodesy::local_axes)`(lon, lat)` gives them, from p itself: east
/// across its meridian, north from the ellipsoid's normal (x/a², y/a², z/b²), no sines and
/// cosines; on the axis, as `local_axes` gives them there.
pub(super) fn axes_at(ellipsoid: &crate::geodesy::Ellipsoid, p: DVec3) -> (DVec3, DVec3) {
    let r = (p.x * p.x + p.y * p.y).sqrt();
    if r == 0.0 {
        let (lon, lat) = lon_lat(ellipsoid, p);
        return crate::geodesy::local_axes(lon, lat);
    }
    let (cos_lon, sin_lon) = (p.x / r, p.y / r);
    // The normal's horizontal and vertical parts: r/a², z/b².
    let (horizontal, vertical) = (r / ellipsoid.a_m().powi(2), p.z / ellipsoid.b_m().powi(2));
    let length = (horizontal * horizontal + vertical * vertical).sqrt();
    let (cos_lat, sin_lat) = (horizontal / length, vertical / length);
    (DVec3::new(-sin_lon, cos_lon, 0.0), DVec3::new(-sin_lat * cos_lon, -sin_lat * sin_lon, cos_lat))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;
    use crate::ecm::points::sample_point;
    use crate::geodesy::Ellipsoid;

    #[test]
    fn a_plane_tilted_by_a_known_angle_has_that_slope_even_where_the_grid_is_sheared() {
        // h = tan(20°) × the distance east of the quad's first sample along the local east axis:
        // a plane of slope 20° on the ellipsoid, at a cube corner quad (the grid most sheared).
        let e = Ellipsoid::WGS84;
        for quad in [QuadId::new(Face::Front, 9, 511, 511).unwrap(), QuadId::new(Face::Top, 9, 200, 300).unwrap()] {
            let points: Vec<DVec3> =
                (0..N * N).map(|k| sample_point(&e, quad, GRID, (k % N) as u32, (k / N) as u32).0).collect();
            let o = points[128 * N + 128];
            let (east, _) = axes_at(&e, o);
            let h: Vec<f32> = points.iter().map(|p| ((p - o).dot(east) * 20f64.to_radians().tan()) as f32).collect();
            for (i, j) in [(128, 128), (0, 0), (255, 3), (40, 200)] {
                let s = slope_deg(&points, &h, i, j);
                assert!((s - 20.0).abs() < 0.05, "{quad} ({i},{j}): {s}°");
            }
        }
    }

    #[test]
    fn quad_points_and_axes_are_those_of_the_exact_projection() {
        let e = Ellipsoid::WGS84;
        // At a face's centre and next to it (exact: the cusp), 16 quads from it, on and next to
        // a diagonal, at a cube corner, next to the pole, level 8's coarsest interpolated quads,
        // level 14, a quad of level 1 (exact); the Moon.
        let mut worst = 0f64;
        for (body, face, level, x, y) in [
            (e, Face::Front, 9, 255, 255),
            (e, Face::Front, 9, 257, 255),
            (e, Face::Front, 9, 272, 256),
            (e, Face::Front, 9, 300, 300),
            (e, Face::Front, 9, 301, 300),
            (e, Face::Right, 9, 511, 511),
            (e, Face::Top, 9, 250, 260),
            (e, Face::Top, 9, 200, 300),
            (e, Face::Top, 8, 144, 128),
            (e, Face::Back, 8, 200, 60),
            (e, Face::Left, 14, 9000, 3000),
            (Ellipsoid::MOON, Face::Bottom, 10, 100, 700),
            (e, Face::Top, 1, 0, 0),
        ] {
            let quad = QuadId::new(face, level, x, y).unwrap();
            let points = quad_points(&body, quad);
            for (k, &q) in points.iter().enumerate() {
                let (p, lon, lat) = sample_point(&body, quad, GRID, (k % N) as u32, (k / N) as u32);
                worst = worst.max((p - q).length());
                if k % 31 == 0 {
                    let (lon_q, lat_q) = lon_lat(&body, q);
                    assert!((lon - lon_q).abs() < 1e-14 && (lat - lat_q).abs() < 1e-14, "{quad} {k}");
                    let (east, north) = crate::geodesy::local_axes(lon, lat);
                    let (east_q, north_q) = axes_at(&body, q);
                    assert!((east - east_q).length() < 1e-14 && (north - north_q).length() < 1e-14, "{quad} {k}");
                }
            }
        }
        assert!(worst < 1e-8, "{worst} m");
        let quad = |level, x, y| QuadId::new(Face::Front, level, x, y).unwrap();
        assert!(
            smooth_inside(quad(9, 272, 256)) && smooth_inside(quad(9, 301, 300)) && smooth_inside(quad(9, 212, 300))
        );
        assert!(
            !smooth_inside(quad(9, 271, 256)) && !smooth_inside(quad(9, 300, 300)) && !smooth_inside(quad(9, 211, 300))
        );
        assert!(!smooth_inside(quad(7, 100, 30)) && smooth_inside(quad(8, 200, 60)));
    }
}
