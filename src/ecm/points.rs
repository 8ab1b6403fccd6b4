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
