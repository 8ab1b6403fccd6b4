//! Where a run goes, the same rules for the workstation and the command line: the box around a
//! point (the view's centre) or along a brush path, and the level of its cells when none is given.

use crate::ecm::grid::spacing_m;
use crate::geodesy::{BoxError, Ellipsoid, GeoBox};

/// Cells along a region's north–south side that the default level aims at.
pub const DEFAULT_CELLS_PER_SIDE: f64 = 512.0;
/// The finest level the default reaches.
pub const DEFAULT_FINEST_LEVEL: u8 = 22;

/// Cosines of latitude below this are taken as this, so that a box near a pole stays finite.
const MIN_COS_LAT: f64 = 0.05;

/// The box of half-size `half_m` (metres on the surface, north–south and east–west) around
/// (`lat`, `lon`) in degrees.
pub fn box_around(ellipsoid: &Ellipsoid, lat: f64, lon: f64, half_m: f64) -> Result<GeoBox, BoxError> {
    let d = (half_m / ellipsoid.a_m()).to_degrees();
    let d_lon = d / lat.to_radians().cos().max(MIN_COS_LAT);
    GeoBox::wrapped(lon - d_lon, lat - d, lon + d_lon, lat + d)
}

/// The box around a brush path (`[lat, lon]` degrees) widened by the brush's radius.
pub fn box_along(ellipsoid: &Ellipsoid, points: &[[f64; 2]], radius_m: f64) -> Result<GeoBox, BoxError> {
    let (lat0, lat1) = points.iter().fold((90f64, -90f64), |m, p| (m.0.min(p[0]), m.1.max(p[0])));
    let (lon0, lon1) = points.iter().fold((180f64, -180f64), |m, p| (m.0.min(p[1]), m.1.max(p[1])));
    let r = (radius_m / ellipsoid.a_m()).to_degrees();
    GeoBox::wrapped(
        lon0 - r / lat0.to_radians().cos().max(MIN_COS_LAT),
        lat0 - r,
        lon1 + r / lat1.to_radians().cos().max(MIN_COS_LAT),
        lat1 + r,
    )
}

/// The level of a run's cells when none is given: the coarsest whose samples put at least
/// [`DEFAULT_CELLS_PER_SIDE`] cells along the region's north–south side (at most
/// [`DEFAULT_FINEST_LEVEL`]).
pub fn default_level(ellipsoid: &Ellipsoid, region: &GeoBox) -> u8 {
    let side_m = (region.north_deg - region.south_deg).to_radians() * ellipsoid.a_m();
    (0..=DEFAULT_FINEST_LEVEL)
        .find(|l| spacing_m(ellipsoid, *l) * DEFAULT_CELLS_PER_SIDE <= side_m)
        .unwrap_or(DEFAULT_FINEST_LEVEL)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_around_a_point_has_its_half_size_in_metres() {
        let e = Ellipsoid::WGS84;
        let b = box_around(&e, 60.0, 10.0, 5000.0).unwrap();
        let ns_m = (b.north_deg - b.south_deg).to_radians() * e.a_m();
        assert!((ns_m - 10_000.0).abs() < 1e-6, "{ns_m}");
        // East–west: wider in degrees by 1 / cos(lat).
        let ew_deg = b.east_deg - b.west_deg;
        assert!((ew_deg - 2.0 * (b.north_deg - 60.0) / 0.5).abs() < 1e-9, "{ew_deg}");
    }

    #[test]
    fn the_default_level_puts_about_512_cells_along_the_side() {
        let e = Ellipsoid::WGS84;
        let b = box_around(&e, 39.4, 40.2, 3000.0).unwrap();
        let level = default_level(&e, &b);
        let side_m = 6000.0;
        let cells = side_m / spacing_m(&e, level);
        assert!((512.0..1024.0).contains(&cells), "level {level}: {cells} cells");
        // A box along a path covers every point with the radius around it.
        let along = box_along(&e, &[[39.0, 40.0], [39.5, 40.6]], 2000.0).unwrap();
        assert!(along.south_deg < 39.0 && along.north_deg > 39.5 && along.west_deg < 40.0 && along.east_deg > 40.6);
    }
}
