//! Points of a quad's sample grid on the ellipsoid, exact in f64: what every CPU reference that
//! walks a quad's samples (composition, brushes, erosion, comparison) places them with.

use glam::DVec3;

use super::{CubeProjection, FacePoint, QuadId};
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};

/// A point of a quad's sample grid: ECEF and (lon, lat) radians, exact (f64).
pub fn sample_point(ellipsoid: &Ellipsoid, quad: QuadId, n: u32, i: u32, j: u32) -> (DVec3, f64, f64) {
    let (x, y) = quad.sample_xy(n, i, j);
    let (lat, lon) = CubeProjection::Qsc
        .geodetic_from_face_point(ellipsoid, FacePoint { face: quad.face, x, y })
        .unwrap_or((0.0, 0.0));
    (ecef_from_geodetic(ellipsoid, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 }), lon, lat)
}

/// The area on the ellipsoid of a grid cell of `level` with `cells` cells along a quad's edge,
/// whose centre is near ECEF point `centre`, m².
///
/// QSC is equal-area on the sphere, so every cell covers the same solid angle,
/// 4π / (6 · 4^level · cells²). The ellipsoid's point of a sphere direction u is r(ψ)·u at the
/// geocentric latitude ψ of u (the projection's shift to the sphere), with
/// r(ψ) = ab / √(b² cos²ψ + a² sin²ψ); its area element is r √(r² + r′²) per unit of solid angle.
/// Taken at the cell's centre this is exact to (cell / R)² · e², everywhere on the face: unlike
/// the quadrilateral of the cell's corners, which misses by up to 5 % next to a face's centre,
/// where QSC bends cells too sharply for straight sides (QSC's cusp).
pub fn cell_area_m2(ellipsoid: &Ellipsoid, level: u8, cells: u32, centre: DVec3) -> f64 {
    let (a, b) = (ellipsoid.a_m(), ellipsoid.b_m());
    let length = centre.length();
    let sin_psi = (centre.z / length).clamp(-1.0, 1.0);
    let cos_psi = (centre.x * centre.x + centre.y * centre.y).sqrt() / length;
    let q = b * b * cos_psi * cos_psi + a * a * sin_psi * sin_psi;
    let r = a * b / q.sqrt();
    let dr = -a * b * (a * a - b * b) * sin_psi * cos_psi / (q * q.sqrt());
    let solid_angle = 4.0 * std::f64::consts::PI / (6.0 * 4f64.powi(i32::from(level)) * f64::from(cells).powi(2));
    r * (r * r + dr * dr).sqrt() * solid_angle
}

/// A ball around every sample of a quad: its centre sample and a radius, metres.
pub fn quad_ball(ellipsoid: &Ellipsoid, quad: QuadId) -> (DVec3, (f64, f64), f64) {
    let (centre, lon, lat) = sample_point(ellipsoid, quad, 3, 1, 1);
    let mut radius = 0f64;
    for (i, j) in [(0, 0), (2, 0), (0, 2), (2, 2), (1, 0), (0, 1), (2, 1), (1, 2)] {
        radius = radius.max((sample_point(ellipsoid, quad, 3, i, j).0 - centre).length());
    }
    // The edges bulge beyond the chord between their samples by less than 2 % at level 0.
    (centre, (lon, lat), radius * 1.05)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;

    /// The centre (mean of the corners) of cell (i, j) of a quad with `n` samples along an edge.
    fn centre(e: &Ellipsoid, quad: QuadId, n: u32, i: u32, j: u32) -> DVec3 {
        let corner = |di: u32, dj: u32| sample_point(e, quad, n, i + di, j + dj).0;
        (corner(0, 0) + corner(1, 0) + corner(0, 1) + corner(1, 1)) / 4.0
    }

    #[test]
    fn the_cells_of_every_face_add_up_to_the_ellipsoids_surface() {
        // 2πa² (1 + (1 − e²)/e · atanh e), the surface of an oblate ellipsoid.
        let e = Ellipsoid::WGS84;
        let (a, ecc) = (e.a_m(), e.e2().sqrt());
        let surface = 2.0 * std::f64::consts::PI * a * a * (1.0 + (1.0 - ecc * ecc) / ecc * ecc.atanh());
        let cells = 64u32;
        let mut sum = 0.0;
        for face in Face::ALL {
            let quad = QuadId { face, level: 0, x: 0, y: 0 };
            for j in 0..cells {
                for i in 0..cells {
                    sum += cell_area_m2(&e, 0, cells, centre(&e, quad, cells + 1, i, j));
                }
            }
        }
        assert!((sum / surface - 1.0).abs() < 1e-6, "{sum} vs {surface}");
    }

    #[test]
    fn away_from_a_faces_centre_a_cell_is_the_quadrilateral_of_its_corners() {
        let e = Ellipsoid::WGS84;
        let quad = QuadId::new(Face::Front, 9, 300, 200).unwrap();
        for (i, j) in [(0, 0), (100, 200), (255, 255)] {
            let corner = |di: u32, dj: u32| sample_point(&e, quad, 257, i + di, j + dj).0;
            let flat = 0.5 * (corner(1, 1) - corner(0, 0)).cross(corner(0, 1) - corner(1, 0)).length();
            let exact = cell_area_m2(&e, 9, 256, centre(&e, quad, 257, i, j));
            assert!((exact / flat - 1.0).abs() < 1e-6, "({i},{j}): {exact} vs {flat}");
        }
        // On a sphere every cell has the same area, next to a face's centre too.
        let moon = Ellipsoid::MOON;
        let quad = QuadId::new(Face::Back, 1, 1, 1).unwrap();
        let expected = 4.0 * std::f64::consts::PI * moon.a_m().powi(2) / (6.0 * 4.0 * 65536.0);
        let area = cell_area_m2(&moon, 1, 256, centre(&moon, quad, 257, 0, 0));
        assert!((area / expected - 1.0).abs() < 1e-12, "{area} vs {expected}");
    }
}
