//! Geodesy in f64: ellipsoids, geodetic ↔ ECEF, surface normals and the geocentric shift that
//! the Ellipsoidal Cube Map uses to move a surface point from the ellipsoid to the sphere.
//!
//! Frames: ECEF is the body-fixed Cartesian frame with +Z along the rotation axis (north),
//! +X through latitude 0, longitude 0 and +Y through longitude +90°. Geodetic coordinates are
//! latitude and longitude in radians and the height in metres along the ellipsoid normal.
//! No I/O and no dependency on other Terrafuse modules.

mod ellipsoid;
mod geobox;
pub mod geodesic;

pub use ellipsoid::Ellipsoid;
pub use geobox::{BoxError, GeoBox};
use glam::DVec3;

/// Errors of the geodesy module.
#[derive(Debug, thiserror::Error, PartialEq)]
pub enum GeodesyError {
    /// The axes do not describe an oblate ellipsoid or sphere.
    #[error("invalid ellipsoid a = {a_m} m, b = {b_m} m: need finite a ≥ b > 0")]
    InvalidEllipsoid {
        /// Equatorial semi-axis that was given.
        a_m: f64,
        /// Polar semi-axis that was given.
        b_m: f64,
    },
    /// The body name or parameter list is not understood.
    #[error("unknown body '{0}': use wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres)")]
    UnknownBody(String),
}

/// A geodetic position: latitude and longitude in radians, height in metres along the
/// ellipsoid normal (not along the radius).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Geodetic {
    /// Geodetic latitude φ in radians, in [−π/2, π/2].
    pub lat_rad: f64,
    /// Longitude λ in radians (any value; outputs lie in (−π, π]).
    pub lon_rad: f64,
    /// Height above the ellipsoid in metres, along the ellipsoid normal.
    pub height_m: f64,
}

impl Geodetic {
    /// A position from degrees and metres (the units of files and command lines).
    pub fn from_degrees(lat_deg: f64, lon_deg: f64, height_m: f64) -> Geodetic {
        Geodetic { lat_rad: lat_deg.to_radians(), lon_rad: lon_deg.to_radians(), height_m }
    }
}

/// ECEF position of a geodetic point (metres).
///
/// ```
/// use terrafuse::geodesy::{ecef_from_geodetic, Ellipsoid, Geodetic};
/// // GeographicLib's CartConvert: "20 10 100" → 5904838.6983116427 1041182.3792437945 2167730.9898430901
/// let p = ecef_from_geodetic(&Ellipsoid::WGS84, Geodetic::from_degrees(20.0, 10.0, 100.0));
/// assert!((p.x - 5_904_838.698_311_642_7).abs() < 1e-8);
/// assert!((p.z - 2_167_730.989_843_090_1).abs() < 1e-8);
/// ```
pub fn ecef_from_geodetic(ellipsoid: &Ellipsoid, point: Geodetic) -> DVec3 {
    let (sin_lat, cos_lat) = point.lat_rad.sin_cos();
    let (sin_lon, cos_lon) = point.lon_rad.sin_cos();
    let n = ellipsoid.a_m() / (1.0 - ellipsoid.e2() * sin_lat * sin_lat).sqrt();
    let r = (n + point.height_m) * cos_lat;
    DVec3::new(r * cos_lon, r * sin_lon, (n * ellipsoid.b2_over_a2() + point.height_m) * sin_lat)
}

/// Geodetic position of an ECEF point, exact to rounding everywhere outside the evolute
/// (within ≈ e²·a of the centre) and correct inside it.
///
/// This is Vermeille's closed-form solution (J. Geodesy 2011, "An analytical method to
/// transform geocentric into geodetic coordinates") in the arrangement that avoids cancellation
/// published by Karney (GeographicLib, `Geocentric::IntReverse`): a quartic in k solved by a
/// real cube root or a trigonometric root, then φ and h from k. No iteration, no Bowring step.
///
/// ```
/// use terrafuse::geodesy::{geodetic_from_ecef, Ellipsoid};
/// use glam::DVec3;
/// let g = geodetic_from_ecef(&Ellipsoid::WGS84, DVec3::new(5_904_838.698_311_642_7, 1_041_182.379_243_794_5, 2_167_730.989_843_090_1));
/// assert!((g.lat_rad.to_degrees() - 20.0).abs() < 1e-13);
/// assert!((g.height_m - 100.0).abs() < 1e-8);
/// ```
pub fn geodetic_from_ecef(ellipsoid: &Ellipsoid, p: DVec3) -> Geodetic {
    let a = ellipsoid.a_m();
    let e2 = ellipsoid.e2();
    let e2m = ellipsoid.b2_over_a2();
    let e4 = e2 * e2;
    let r = p.x.hypot(p.y);
    let lon_rad = if r == 0.0 { 0.0 } else { p.y.atan2(p.x) };
    // Beyond 2a/ε the ellipsoid is a point: the geocentric direction is the normal.
    let max_radius_m = 2.0 * a / f64::EPSILON;
    let distance_m = r.hypot(p.z);
    let (sin_lat, cos_lat, height_m);
    if distance_m > max_radius_m || e4 == 0.0 {
        // A sphere (or a point so far away that flattening is below rounding).
        let scale = if distance_m == 0.0 { 1.0 } else { distance_m };
        sin_lat = p.z / scale;
        cos_lat = if distance_m == 0.0 { 1.0 } else { r / scale };
        height_m = distance_m - a;
    } else {
        // Vermeille's variables, scaled by a.
        let pp = (r / a) * (r / a);
        let q = e2m * (p.z / a) * (p.z / a);
        let rr = (pp + q - e4) / 6.0;
        if !(e4 * q == 0.0 && rr <= 0.0) {
            let s = e4 * pp * q / 4.0;
            let r2 = rr * rr;
            let r3 = rr * r2;
            let disc = s * (2.0 * r3 + s);
            let mut u = rr;
            if disc >= 0.0 {
                let mut t3 = s + r3;
                // Pick the sign of the square root that avoids cancellation.
                t3 += if t3 < 0.0 { -disc.sqrt() } else { disc.sqrt() };
                let t = t3.cbrt();
                u += t + if t != 0.0 { r2 / t } else { 0.0 };
            } else {
                // Three real roots: take the one that avoids cancellation (disc < 0 ⇒ rr < 0).
                let angle = (-disc).sqrt().atan2(-(s + r3));
                u += 2.0 * rr * (angle / 3.0).cos();
            }
            let v = (u * u + e4 * q).sqrt();
            let uv = if u < 0.0 { e4 * q / (v - u) } else { u + v };
            let w = (e2 * (uv - q) / (2.0 * v)).max(0.0);
            let k = uv / ((uv + w * w).sqrt() + w);
            let k1 = k;
            let k2 = k + e2;
            let d = k1 * r / k2;
            let hyp = (p.z / k1).hypot(r / k2);
            sin_lat = (p.z / k1) / hyp;
            cos_lat = (r / k2) / hyp;
            height_m = (1.0 - e2m / k1) * d.hypot(p.z);
        } else {
            // On the equatorial plane inside the evolute: the limit of the general formulas.
            let zz = ((e4 - pp) / e2m).sqrt();
            let xx = pp.sqrt();
            let hyp = zz.hypot(xx);
            sin_lat = if p.z < 0.0 { -zz / hyp } else { zz / hyp };
            cos_lat = xx / hyp;
            height_m = -a * e2m * hyp / e2;
        }
    }
    Geodetic { lat_rad: sin_lat.atan2(cos_lat), lon_rad, height_m }
}

/// Unit outward ellipsoid normal at geodetic latitude and longitude (radians), in ECEF.
pub fn normal_from_geodetic(lat_rad: f64, lon_rad: f64) -> DVec3 {
    let (sin_lat, cos_lat) = lat_rad.sin_cos();
    let (sin_lon, cos_lon) = lon_rad.sin_cos();
    DVec3::new(cos_lat * cos_lon, cos_lat * sin_lon, sin_lat)
}

/// The local east and north unit vectors (ECEF) at a longitude and latitude (radians).
pub fn local_axes(lon: f64, lat: f64) -> (DVec3, DVec3) {
    let (sl, cl) = lon.sin_cos();
    let (sp, cp) = lat.sin_cos();
    (DVec3::new(-sl, cl, 0.0), DVec3::new(-sp * cl, -sp * sl, cp))
}

/// Geocentric latitude ψ (radians) of the surface point at geodetic latitude φ:
/// tan ψ = (b²/a²) tan φ. This is the ECM's shift from the ellipsoid to the sphere (the
/// longitude is unchanged); it is exact for points at zero height.
pub fn geocentric_lat_from_geodetic(ellipsoid: &Ellipsoid, lat_rad: f64) -> f64 {
    let (s, c) = lat_rad.sin_cos();
    (ellipsoid.b2_over_a2() * s).atan2(c)
}

/// Inverse of [`geocentric_lat_from_geodetic`]: tan φ = (a²/b²) tan ψ.
pub fn geodetic_lat_from_geocentric(ellipsoid: &Ellipsoid, geocentric_lat_rad: f64) -> f64 {
    let (s, c) = geocentric_lat_rad.sin_cos();
    s.atan2(ellipsoid.b2_over_a2() * c)
}

/// Unit direction from the centre to the surface point at geodetic latitude and longitude:
/// the point on the unit sphere that the ECM projects onto the cube. Equivalent to
/// (cos ψ cos λ, cos ψ sin λ, sin ψ) with the geocentric latitude ψ, but computed without the
/// intermediate angle so it stays exact at the poles.
pub fn sphere_direction_from_geodetic(ellipsoid: &Ellipsoid, lat_rad: f64, lon_rad: f64) -> DVec3 {
    let (sin_lat, cos_lat) = lat_rad.sin_cos();
    let (sin_lon, cos_lon) = lon_rad.sin_cos();
    let z = ellipsoid.b2_over_a2() * sin_lat;
    let norm = cos_lat.hypot(z);
    DVec3::new(cos_lat * cos_lon / norm, cos_lat * sin_lon / norm, z / norm)
}

/// Geodetic latitude and longitude (radians) of the surface point in the direction `d` from
/// the centre (need not be normalised). Inverse of [`sphere_direction_from_geodetic`].
pub fn geodetic_from_sphere_direction(ellipsoid: &Ellipsoid, d: DVec3) -> (f64, f64) {
    let r = d.x.hypot(d.y);
    let lat = d.z.atan2(ellipsoid.b2_over_a2() * r);
    let lon = if r == 0.0 { 0.0 } else { d.y.atan2(d.x) };
    (lat, lon)
}

/// ECEF position of the ellipsoid surface point in the direction `d` from the centre.
pub fn surface_point_from_direction(ellipsoid: &Ellipsoid, d: DVec3) -> DVec3 {
    let a = ellipsoid.a_m();
    let b = ellipsoid.b_m();
    let k = 1.0 / ((d.x / a).hypot(d.y / a)).hypot(d.z / b);
    d * k
}

/// Wraps a longitude in radians into (−π, π].
pub fn wrap_lon_rad(lon_rad: f64) -> f64 {
    use std::f64::consts::{PI, TAU};
    if lon_rad > -PI && lon_rad <= PI {
        return lon_rad;
    }
    let wrapped = lon_rad - TAU * ((lon_rad + PI) / TAU).floor();
    if wrapped <= -PI { wrapped + TAU } else { wrapped }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn roundtrip_error_m(ellipsoid: &Ellipsoid, g: Geodetic) -> f64 {
        let p = ecef_from_geodetic(ellipsoid, g);
        let back = geodetic_from_ecef(ellipsoid, p);
        (ecef_from_geodetic(ellipsoid, back) - p).length()
    }

    #[test]
    fn roundtrip_everywhere_including_poles_and_extreme_heights() {
        for ellipsoid in [Ellipsoid::WGS84, Ellipsoid::MOON, Ellipsoid::MARS] {
            for lat in [-90.0, -89.999_999_9, -45.0, -1e-12, 0.0, 1e-9, 33.3, 60.0, 89.9, 90.0] {
                for lon in [-180.0, -179.5, 0.0, 45.0, 179.999_999, 180.0] {
                    for h in [-12_000.0, -100.0, 0.0, 1.0, 8848.0, 4e5, 3.6e7, 1e8] {
                        let g = Geodetic::from_degrees(lat, lon, h);
                        let err = roundtrip_error_m(&ellipsoid, g);
                        let p = ecef_from_geodetic(&ellipsoid, g).length();
                        // < 1e-9 m, or a few ulp of the coordinate itself where 1 ulp exceeds that.
                        let tolerance = 1e-9_f64.max(4.0 * p * f64::EPSILON);
                        assert!(
                            err < tolerance,
                            "{} lat {lat} lon {lon} h {h}: error {err:e} m > {tolerance:e}",
                            ellipsoid.name()
                        );
                    }
                }
            }
        }
    }

    #[test]
    fn inside_the_evolute_is_finite_and_consistent() {
        let e = Ellipsoid::WGS84;
        for p in
            [DVec3::ZERO, DVec3::new(1000.0, 0.0, 0.0), DVec3::new(0.0, 0.0, -2000.0), DVec3::new(3000.0, 4000.0, 10.0)]
        {
            let g = geodetic_from_ecef(&e, p);
            assert!(g.lat_rad.is_finite() && g.height_m.is_finite(), "{p:?} → {g:?}");
            let back = ecef_from_geodetic(&e, g);
            assert!((back - p).length() < 1e-6, "{p:?} → {g:?} → {back:?}");
        }
    }

    #[test]
    fn geocentric_shift_matches_closed_form_and_inverts() {
        let e = Ellipsoid::WGS84;
        for lat_deg in [-90.0_f64, -60.0, -1.0, 0.0, 10.0, 45.0, 89.0, 90.0] {
            let lat = lat_deg.to_radians();
            let psi = geocentric_lat_from_geodetic(&e, lat);
            if lat_deg.abs() < 90.0 {
                let closed = (e.b2_over_a2() * lat.tan()).atan();
                assert!((psi - closed).abs() < 1e-15, "{lat_deg}: {psi} vs {closed}");
            }
            assert!((geodetic_lat_from_geocentric(&e, psi) - lat).abs() < 1e-15);
            let d = sphere_direction_from_geodetic(&e, lat, 0.3);
            assert!((d.length() - 1.0).abs() < 1e-15);
            assert!((d.z.asin() - psi).abs() < 1e-7 || lat_deg.abs() == 90.0);
            let (lat2, lon2) = geodetic_from_sphere_direction(&e, d);
            assert!((lat2 - lat).abs() < 1e-15 && (lat_deg.abs() == 90.0 || (lon2 - 0.3).abs() < 1e-15));
            // The surface point in that direction has zero height and that latitude.
            let s = surface_point_from_direction(&e, d);
            let g = geodetic_from_ecef(&e, s);
            assert!(g.height_m.abs() < 1e-8 && (g.lat_rad - lat).abs() < 1e-15, "{g:?}");
        }
        // The largest shift on WGS84 is 11′32.7″ = 11.545′, near 45°.
        let shift = (45f64.to_radians() - geocentric_lat_from_geodetic(&e, 45f64.to_radians())).to_degrees() * 60.0;
        assert!((shift - 11.545).abs() < 0.001, "{shift}");
    }

    #[test]
    fn normal_is_perpendicular_to_the_surface() {
        let e = Ellipsoid::MARS;
        let (lat, lon) = (0.7_f64, -2.0_f64);
        let n = normal_from_geodetic(lat, lon);
        let p0 = ecef_from_geodetic(&e, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 });
        let p1 = ecef_from_geodetic(&e, Geodetic { lat_rad: lat + 1e-7, lon_rad: lon, height_m: 0.0 });
        let p2 = ecef_from_geodetic(&e, Geodetic { lat_rad: lat, lon_rad: lon + 1e-7, height_m: 0.0 });
        assert!(n.dot((p1 - p0).normalize()).abs() < 1e-7);
        assert!(n.dot((p2 - p0).normalize()).abs() < 1e-7);
    }

    #[test]
    fn wraps_longitude() {
        use std::f64::consts::PI;
        assert_eq!(wrap_lon_rad(PI), PI);
        assert_eq!(wrap_lon_rad(-PI), PI);
        assert!((wrap_lon_rad(3.0 * PI / 2.0) + PI / 2.0).abs() < 1e-15);
        assert_eq!(wrap_lon_rad(0.5), 0.5);
    }
}
