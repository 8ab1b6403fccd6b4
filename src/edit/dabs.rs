//! Where a stroke's dabs go: along its path by arc length on the ellipsoid, one every
//! `spacing × radius_m` metres from the first point on (the first point always has one), along
//! each segment's geodesic (Vincenty, `geodesy::geodesic`). The dabs depend on the path and the
//! spacing only, never on how the path was sampled in time.

use crate::errors::AtField;
use glam::DVec3;

use super::stroke::{MAX_DABS, Stroke};
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic, geodesic};

/// The dab centres of a stroke on the ellipsoid (ECEF metres), in order; an error names the path
/// segment whose geodesic cannot be computed (nearly antipodal points) or too many dabs.
pub fn dab_centres(ellipsoid: &Ellipsoid, stroke: &Stroke) -> Result<Vec<DVec3>, crate::Invalid> {
    let at = |lat: f64, lon: f64| ecef_from_geodetic(ellipsoid, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 });
    let step = stroke.spacing * stroke.radius_m;
    let points: Vec<(f64, f64)> = stroke.path.iter().map(|[lat, lon]| (lat.to_radians(), lon.to_radians())).collect();
    let mut dabs = vec![at(points[0].0, points[0].1)];
    // Arc length from the path's start to the next dab.
    let mut next = step;
    let mut walked = 0.0;
    for (k, pair) in points.windows(2).enumerate() {
        let ((lat1, lon1), (lat2, lon2)) = (pair[0], pair[1]);
        let (length, azimuth, _) = geodesic::inverse(ellipsoid, lat1, lon1, lat2, lon2)
            .at_field(format_args!("path segment {k}–{}", k + 1))?;
        while next <= walked + length {
            let (lat, lon) = geodesic::direct(ellipsoid, lat1, lon1, azimuth, next - walked);
            dabs.push(at(lat, lon));
            if dabs.len() > MAX_DABS {
                return Err(format!("more than {MAX_DABS} dabs: raise the spacing or shorten the path").into());
            }
            next += step;
        }
        walked += length;
    }
    Ok(dabs)
}
