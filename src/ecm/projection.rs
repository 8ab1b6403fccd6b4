//! Projections from the unit sphere onto a cube face: QSC (the ECM's choice), and gnomonic and
//! adjusted gnomonic for comparison.
//!
//! All work on a direction expressed in a face's local frame (ξ along x, η along y, ζ along the
//! centre; see [`Face`]) and produce face coordinates x, y in [−1, 1]. For QSC these equal PROJ's
//! `+proj=qsc` output divided by the semi-major axis.

use std::f64::consts::{FRAC_1_SQRT_2, FRAC_PI_4, PI};
use std::fmt;
use std::str::FromStr;

use glam::DVec3;

use super::{EcmError, Face};
use crate::geodesy::{self, Ellipsoid};

/// A projection from the sphere onto the six cube faces.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum CubeProjection {
    /// Quadrilateralized Spherical Cube (O'Neill & Laubscher 1976): equal-area.
    Qsc,
    /// Central (gnomonic) projection onto the tangent face: x = ξ/ζ.
    Gnomonic,
    /// Gnomonic with the 4/π·atan adjustment of Lerbour et al. 2010: x = (4/π)·atan(ξ/ζ).
    AdjustedGnomonic,
}

/// A point on the cube: a face and coordinates x, y in [−1, 1] in that face's frame.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FacePoint {
    /// The cube face.
    pub face: Face,
    /// Face coordinate along the face's x axis, in [−1, 1].
    pub x: f64,
    /// Face coordinate along the face's y axis, in [−1, 1].
    pub y: f64,
}

impl CubeProjection {
    /// All projections, QSC first.
    pub const ALL: [CubeProjection; 3] =
        [CubeProjection::Qsc, CubeProjection::Gnomonic, CubeProjection::AdjustedGnomonic];

    /// Name used on the command line: `qsc`, `gnomonic`, `adjusted-gnomonic`.
    pub fn name(self) -> &'static str {
        match self {
            CubeProjection::Qsc => "qsc",
            CubeProjection::Gnomonic => "gnomonic",
            CubeProjection::AdjustedGnomonic => "adjusted-gnomonic",
        }
    }

    /// Face coordinates of a unit direction given in a face's local frame (ζ > 0, and the
    /// direction on or inside that face's pyramid).
    pub fn xy_from_local(self, local: DVec3) -> (f64, f64) {
        match self {
            CubeProjection::Qsc => qsc_xy_from_local(local),
            CubeProjection::Gnomonic => (local.x / local.z, local.y / local.z),
            CubeProjection::AdjustedGnomonic => {
                (local.x.atan2(local.z) / FRAC_PI_4, local.y.atan2(local.z) / FRAC_PI_4)
            }
        }
    }

    /// Unit direction in the face's local frame for face coordinates x, y in [−1, 1].
    pub fn local_from_xy(self, x: f64, y: f64) -> DVec3 {
        match self {
            CubeProjection::Qsc => qsc_local_from_xy(x, y),
            CubeProjection::Gnomonic => DVec3::new(x, y, 1.0).normalize(),
            CubeProjection::AdjustedGnomonic => {
                DVec3::new((x * FRAC_PI_4).tan(), (y * FRAC_PI_4).tan(), 1.0).normalize()
            }
        }
    }

    /// The face point of a direction from the centre (ECEF axes, any length > 0). Points on a
    /// face edge can round a unit in the last place past ±1; they are clamped onto the face.
    pub fn face_point_from_direction(self, d: DVec3) -> FacePoint {
        let face = Face::of_direction(d);
        let (x, y) = self.xy_from_local(face.local_from_ecef(d.normalize()));
        FacePoint { face, x: x.clamp(-1.0, 1.0), y: y.clamp(-1.0, 1.0) }
    }

    /// Unit direction (ECEF axes) of a face point.
    pub fn direction_from_face_point(self, p: FacePoint) -> DVec3 {
        p.face.ecef_from_local(self.local_from_xy(p.x, p.y))
    }

    /// Forward projection of a geodetic surface point: shift to the sphere by the geocentric
    /// latitude, then project. Radians in.
    ///
    /// ```
    /// use terrafuse::ecm::{CubeProjection, Face};
    /// use terrafuse::geodesy::Ellipsoid;
    /// // PROJ (input lon lat): echo "10 20 0" | cct -d 12 +proj=qsc +lat_0=0 +lon_0=0 +ellps=WGS84
    /// //   → 1573673.296019594185  3015387.535487787332
    /// let p = CubeProjection::Qsc.face_point_from_geodetic(&Ellipsoid::WGS84, 20f64.to_radians(), 10f64.to_radians());
    /// assert_eq!(p.face, Face::Front);
    /// assert!((p.x * 6_378_137.0 - 1_573_673.296_019_594).abs() < 1e-6);
    /// assert!((p.y * 6_378_137.0 - 3_015_387.535_487_787).abs() < 1e-6);
    /// ```
    pub fn face_point_from_geodetic(self, ellipsoid: &Ellipsoid, lat_rad: f64, lon_rad: f64) -> FacePoint {
        self.face_point_from_direction(geodesy::sphere_direction_from_geodetic(ellipsoid, lat_rad, lon_rad))
    }

    /// Inverse projection: geodetic latitude and longitude (radians, longitude in (−π, π]) of
    /// a face point. Refuses coordinates outside [−1, 1] or not finite.
    pub fn geodetic_from_face_point(self, ellipsoid: &Ellipsoid, p: FacePoint) -> Result<(f64, f64), EcmError> {
        if !(p.x.is_finite() && p.y.is_finite() && p.x.abs() <= 1.0 && p.y.abs() <= 1.0) {
            return Err(EcmError::OutsideFace { x: p.x, y: p.y });
        }
        let (lat, lon) = geodesy::geodetic_from_sphere_direction(ellipsoid, self.direction_from_face_point(p));
        Ok((lat, geodesy::wrap_lon_rad(lon)))
    }
}

impl fmt::Display for CubeProjection {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(self.name())
    }
}

impl FromStr for CubeProjection {
    type Err = EcmError;
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        CubeProjection::ALL
            .into_iter()
            .find(|p| p.name() == text.trim().to_ascii_lowercase())
            .ok_or_else(|| EcmError::UnknownProjection(text.to_string()))
    }
}

/// Rotates a local direction by −90°·k about the face centre so that it lands in QSC's area of
/// definition (ξ ≥ |η|); returns the rotated ξ, η and k.
fn qsc_area(xi: f64, eta: f64) -> (f64, f64, u8) {
    if xi >= eta.abs() {
        (xi, eta, 0)
    } else if eta >= xi.abs() {
        (eta, -xi, 1)
    } else if -xi >= eta.abs() {
        (-xi, -eta, 2)
    } else {
        (-eta, xi, 3)
    }
}

/// Rotates (x, y) by +90°·k, undoing [`qsc_area`].
fn rotate_quarter_turns(x: f64, y: f64, k: u8) -> (f64, f64) {
    match k {
        0 => (x, y),
        1 => (-y, x),
        2 => (-x, -y),
        _ => (y, -x),
    }
}

/// QSC forward on a unit local direction.
///
/// PROJ (after O'Neill & Laubscher, eq. 3-21 and 3-38) computes φ = acos(ζ), the angle from the
/// face centre, and then 1 − cos φ; near the centre acos loses half the digits (≈ 1.5e-8 rad,
/// 8 cm on Earth). Here every quantity comes from ξ, η, ζ without cancellation:
/// 1 − cos φ = ρ²/(1 + ζ) with ρ² = ξ² + η², cos θ = ξ/ρ, θ = atan2(η, ξ), and
/// acos(sin θ·cos 45°) − 90° = −asin(sin θ / √2). In the area of definition (ξ ≥ |η|):
/// x = sqrt((1 − cos φ) / (1 − cos θ / sqrt(1 + cos² θ))), y = x·(12/π)·(θ − asin(sin θ/√2)).
fn qsc_xy_from_local(local: DVec3) -> (f64, f64) {
    let (xi, eta, k) = qsc_area(local.x, local.y);
    let rho = xi.hypot(eta);
    if rho == 0.0 {
        return (0.0, 0.0);
    }
    let cos_theta = xi / rho;
    let sin_theta = eta / rho;
    let theta = eta.atan2(xi);
    let root = (1.0 + cos_theta * cos_theta).sqrt();
    // 1 − cos θ / √(1 + cos²θ) = 1 / (√(1 + cos²θ)·(√(1 + cos²θ) + cos θ)), ≥ 0.29: no cancellation.
    let denominator = 1.0 / (root * (root + cos_theta));
    let x = rho / ((1.0 + local.z) * denominator).sqrt();
    let y = x * (12.0 / PI) * (theta - (sin_theta * FRAC_1_SQRT_2).asin());
    rotate_quarter_turns(x, y, k)
}

/// QSC inverse to a unit local direction (see [`qsc_xy_from_local`] for the forms used):
/// tan θ = sin t / (cos t − 1/√2) with t = (π/12)·(y/x), and 1 − cos φ = x²·(1 − cos θ/√(1 + cos²θ));
/// sin φ = √(D(2 − D)) with D = 1 − cos φ, so nothing cancels near the centre.
fn qsc_local_from_xy(x: f64, y: f64) -> DVec3 {
    let (xa, ya, k) = qsc_area(x, y);
    if xa == 0.0 {
        return DVec3::Z;
    }
    let t = (PI / 12.0) * (ya / xa);
    let (sin_t, cos_t) = t.sin_cos();
    let theta = sin_t.atan2(cos_t - FRAC_1_SQRT_2);
    let (sin_theta, cos_theta) = theta.sin_cos();
    let root = (1.0 + cos_theta * cos_theta).sqrt();
    let d = xa * xa / (root * (root + cos_theta));
    let sin_phi = (d * (2.0 - d)).sqrt();
    let (xi, eta) = rotate_quarter_turns(sin_phi * cos_theta, sin_phi * sin_theta, k);
    DVec3::new(xi, eta, 1.0 - d)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_centres_corners_and_edges_map_to_the_square() {
        for projection in CubeProjection::ALL {
            for face in Face::ALL {
                let p = projection.face_point_from_direction(face.center());
                assert_eq!((p.face, p.x, p.y), (face, 0.0, 0.0), "{projection}");
                let corner = face.center() + face.x_axis() + face.y_axis();
                let (x, y) = projection.xy_from_local(face.local_from_ecef(corner.normalize()));
                assert!((x - 1.0).abs() < 1e-15 && (y - 1.0).abs() < 1e-15, "{projection} {face}: {x} {y}");
                let edge_mid = face.center() - face.y_axis();
                let (x, y) = projection.xy_from_local(face.local_from_ecef(edge_mid.normalize()));
                assert!(x.abs() < 1e-15 && (y + 1.0).abs() < 1e-15, "{projection} {face}: {x} {y}");
            }
        }
    }

    #[test]
    fn inverse_undoes_forward_on_a_grid() {
        for projection in CubeProjection::ALL {
            for i in 0..=40 {
                for j in 0..=40 {
                    let (x, y) = (-1.0 + i as f64 / 20.0, -1.0 + j as f64 / 20.0);
                    let local = projection.local_from_xy(x, y);
                    assert!((local.length() - 1.0).abs() < 1e-15);
                    let (x2, y2) = projection.xy_from_local(local);
                    assert!((x2 - x).abs() < 1e-14 && (y2 - y).abs() < 1e-14, "{projection} ({x}, {y}) → ({x2}, {y2})");
                }
            }
        }
    }

    #[test]
    fn qsc_is_equal_area() {
        // Area of a small square near the corner and near the centre: the spherical areas agree
        // because QSC is equal-area (each face covers 4π/6 sr over 4 units of face area).
        let area = |x0: f64, y0: f64, h: f64| {
            let p = |x: f64, y: f64| CubeProjection::Qsc.local_from_xy(x, y);
            let du = (p(x0 + h, y0) - p(x0 - h, y0)) / (2.0 * h);
            let dv = (p(x0, y0 + h) - p(x0, y0 - h)) / (2.0 * h);
            du.cross(dv).length()
        };
        let expected = 4.0 * PI / 6.0 / 4.0;
        for (x, y) in [(0.1, 0.05), (0.9, 0.3), (0.95, -0.9), (-0.5, 0.2), (0.2, -0.7)] {
            let a = area(x, y, 1e-6);
            assert!((a - expected).abs() < 1e-7, "({x},{y}): {a} vs {expected}");
        }
    }
}
