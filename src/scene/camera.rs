//! The camera: f64 geodetic placement (latitude, longitude, altitude, heading, pitch, field of
//! view), its ECEF position and axes, and the camera-relative single-precision view-projection
//! with reversed-Z depth and an infinite far plane, which keeps depth precise from centimetres to
//! interplanetary distances in one view.

use glam::{DMat4, DVec3, DVec4, Mat4};

use crate::geodesy::{self, Ellipsoid, Geodetic};
use crate::project::CameraSpec;

/// A placed camera, everything in f64 ECEF.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Camera {
    /// The geodetic description it was placed from.
    pub spec: CameraSpec,
    /// Eye position, ECEF metres.
    pub position: DVec3,
    /// Unit vector the camera looks along.
    pub forward: DVec3,
    /// Unit vector to the right of the image.
    pub right: DVec3,
    /// Unit vector to the top of the image.
    pub up: DVec3,
    /// Local ellipsoid normal under the camera.
    pub zenith: DVec3,
    /// Vertical field of view, radians.
    pub fov_y: f64,
    /// Near plane distance, metres.
    pub near_m: f64,
}

/// A frustum plane n·p + d ≥ 0 inside (n a unit ECEF normal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Plane {
    /// Inward unit normal.
    pub normal: DVec3,
    /// Offset: n·p + d is the signed distance of p.
    pub d: f64,
}

impl Camera {
    /// Places a camera. `near_m` is the near plane; [`Camera::near_for`] picks one.
    pub fn new(ellipsoid: &Ellipsoid, spec: CameraSpec, near_m: f64) -> Camera {
        let (lat, lon) = (spec.lat.to_radians(), spec.lon.to_radians());
        let position = geodesy::ecef_from_geodetic(ellipsoid, Geodetic::from_degrees(spec.lat, spec.lon, spec.alt));
        let zenith = geodesy::normal_from_geodetic(lat, lon);
        let east = DVec3::new(-lon.sin(), lon.cos(), 0.0);
        let north = zenith.cross(east);
        let (heading, pitch) = (spec.heading.to_radians(), spec.pitch.to_radians());
        let level = north * heading.cos() + east * heading.sin();
        let forward = (level * pitch.cos() + zenith * pitch.sin()).normalize();
        let right = (east * heading.cos() - north * heading.sin()).normalize();
        let up = right.cross(forward);
        Camera { spec, position, forward, right, up, zenith, fov_y: spec.fov.to_radians(), near_m }
    }

    /// The geodetic description of a camera at `position` looking along `forward` with `up` the
    /// top of the image (the inverse of [`Camera::new`]). The spec has no roll: heading comes from
    /// the horizontal part of `forward·cos p − up·sin p`, which is exact for a camera without roll
    /// and stays defined looking straight down; `fov` is kept.
    pub fn spec_from_pose(ellipsoid: &Ellipsoid, position: DVec3, forward: DVec3, up: DVec3, fov: f64) -> CameraSpec {
        let g = geodesy::geodetic_from_ecef(ellipsoid, position);
        let zenith = geodesy::normal_from_geodetic(g.lat_rad, g.lon_rad);
        let east = DVec3::new(-g.lon_rad.sin(), g.lon_rad.cos(), 0.0);
        let north = zenith.cross(east);
        let forward = forward.normalize();
        let sin_p = forward.dot(zenith).clamp(-1.0, 1.0);
        let pitch = sin_p.asin();
        let level = forward * pitch.cos() - up.normalize() * sin_p;
        let heading = level.dot(east).atan2(level.dot(north)).to_degrees().rem_euclid(360.0);
        CameraSpec {
            lat: g.lat_rad.to_degrees(),
            lon: g.lon_rad.to_degrees(),
            alt: g.height_m,
            heading,
            pitch: pitch.to_degrees(),
            fov,
        }
    }

    /// The unit ECEF direction of the ray through image point (`x`, `y`) (pixels from the top
    /// left) of an image `width` × `height`: the inverse of [`Camera::project`].
    pub fn ray(&self, x: f64, y: f64, width: u32, height: u32) -> DVec3 {
        let tan_y = (0.5 * self.fov_y).tan();
        let tan_x = tan_y * f64::from(width) / f64::from(height.max(1));
        let nx = 2.0 * x / f64::from(width.max(1)) - 1.0;
        let ny = 1.0 - 2.0 * y / f64::from(height.max(1));
        (self.forward + self.right * (nx * tan_x) + self.up * (ny * tan_y)).normalize()
    }

    /// A near plane for a camera `clearance_m` above the highest terrain that may be in view: half
    /// the clearance, within 5 cm … 10 km. Reversed-Z float depth keeps the far range precise,
    /// so only the near plane needs choosing.
    pub fn near_for(clearance_m: f64) -> f64 {
        (0.5 * clearance_m).clamp(0.05, 10_000.0)
    }

    /// Camera-relative view-projection (ECEF metres relative to the eye → clip), computed in f64
    /// and cast: reversed Z (near → 1, infinity → 0).
    pub fn view_projection(&self, width: u32, height: u32) -> DMat4 {
        let aspect = f64::from(width) / f64::from(height.max(1));
        let (r, u, f) = (self.right, self.up, self.forward);
        // Rows: right, up, backward (a right-handed view looking down −z).
        let view = DMat4::from_cols(
            DVec4::new(r.x, u.x, -f.x, 0.0),
            DVec4::new(r.y, u.y, -f.y, 0.0),
            DVec4::new(r.z, u.z, -f.z, 0.0),
            DVec4::W,
        );
        // Infinite far plane, reversed: clip z = near, w = −z_view, so depth = near / distance.
        let focal = 1.0 / (0.5 * self.fov_y).tan();
        let projection = DMat4::from_cols(
            DVec4::new(focal / aspect, 0.0, 0.0, 0.0),
            DVec4::new(0.0, focal, 0.0, 0.0),
            DVec4::new(0.0, 0.0, 0.0, -1.0),
            DVec4::new(0.0, 0.0, self.near_m, 0.0),
        );
        projection * view
    }

    /// [`Camera::view_projection`] in f32, what the shader gets.
    pub fn view_projection_f32(&self, width: u32, height: u32) -> Mat4 {
        self.view_projection(width, height).as_mat4()
    }

    /// Pixels per radian at the image centre (the focal length in pixels).
    pub fn focal_px(&self, height: u32) -> f64 {
        0.5 * f64::from(height) / (0.5 * self.fov_y).tan()
    }

    /// The five planes of the (infinite) frustum in ECEF: left, right, bottom, top, near.
    pub fn frustum(&self, width: u32, height: u32) -> [Plane; 5] {
        let tan_y = (0.5 * self.fov_y).tan();
        let tan_x = tan_y * f64::from(width) / f64::from(height.max(1));
        let through_eye = |n: DVec3| {
            let n = n.normalize();
            Plane { normal: n, d: -n.dot(self.position) }
        };
        [
            through_eye(self.right + self.forward * tan_x),
            through_eye(-self.right + self.forward * tan_x),
            through_eye(self.up + self.forward * tan_y),
            through_eye(-self.up + self.forward * tan_y),
            Plane { normal: self.forward, d: -self.forward.dot(self.position) - self.near_m },
        ]
    }

    /// Where a camera-relative point lands on the image (pixels from the top left) and its
    /// depth, or `None` behind the eye: the f64 twin of the shader's projection, for tests.
    pub fn project(&self, relative: DVec3, width: u32, height: u32) -> Option<(f64, f64, f64)> {
        let clip = self.view_projection(width, height) * DVec4::new(relative.x, relative.y, relative.z, 1.0);
        if clip.w <= 0.0 {
            return None;
        }
        let ndc = clip.truncate() / clip.w;
        Some(((ndc.x + 1.0) * 0.5 * f64::from(width), (1.0 - ndc.y) * 0.5 * f64::from(height), ndc.z))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(lat: f64, lon: f64, alt: f64, heading: f64, pitch: f64) -> CameraSpec {
        CameraSpec { lat, lon, alt, heading, pitch, fov: 60.0 }
    }

    #[test]
    fn heading_and_pitch_turn_the_view_as_documented() {
        let e = Ellipsoid::WGS84;
        // Looking straight down: forward is the negative zenith, and heading turns the image.
        let down = Camera::new(&e, spec(10.0, 20.0, 1000.0, 0.0, -90.0), 1.0);
        assert!((down.forward + down.zenith).length() < 1e-12);
        let north = down.zenith.cross(DVec3::new(-20f64.to_radians().sin(), 20f64.to_radians().cos(), 0.0));
        assert!((down.up - north).length() < 1e-12, "north is up in the image at heading 0");
        // At the horizon with heading 90 the camera looks east.
        let east = Camera::new(&e, spec(0.0, 0.0, 10.0, 90.0, 0.0), 1.0);
        assert!((east.forward - DVec3::Y).length() < 1e-12);
        assert!((east.up - DVec3::X).length() < 1e-12, "the zenith is up at the horizon");
        assert!((east.right + DVec3::Z).length() < 1e-12, "south is right when looking east");
        // The basis is orthonormal and right-handed.
        for c in [down, east, Camera::new(&e, spec(-45.0, 170.0, 5e5, 33.0, -20.0), 1.0)] {
            assert!((c.right.cross(c.up) - (-c.forward)).length() < 1e-12);
        }
    }

    #[test]
    fn reversed_z_puts_near_at_one_and_far_towards_zero() {
        let c = Camera::new(&Ellipsoid::MOON, spec(0.0, 0.0, 100.0, 0.0, 0.0), 0.5);
        let (x, y, z) = c.project(c.forward * 0.5, 800, 600).unwrap();
        assert!((x - 400.0).abs() < 1e-9 && (y - 300.0).abs() < 1e-9 && (z - 1.0).abs() < 1e-12);
        let (_, _, z_far) = c.project(c.forward * 1e8, 800, 600).unwrap();
        assert!(z_far > 0.0 && z_far < 1e-8);
        // Depth stays strictly ordered in f32 from 1 m to 10⁸ m: 1 % steps never collide.
        let mut previous = f32::INFINITY;
        let mut d = 1.0;
        while d < 1e8 {
            let (_, _, z) = c.project(c.forward * d, 800, 600).unwrap();
            let z = z as f32;
            assert!(z < previous, "depth at {d} m not below the one before");
            previous = z;
            d *= 1.01;
        }
        assert!(c.project(-c.forward, 800, 600).is_none());
        // A point at the top edge of the field of view lands on row 0.
        let top = c.forward + c.up * (0.5 * c.fov_y).tan();
        assert!(c.project(top, 800, 600).unwrap().1.abs() < 1e-9);
    }

    #[test]
    fn pose_inverts_placement() {
        for e in [Ellipsoid::WGS84, Ellipsoid::MOON] {
            for s in [
                spec(39.9, 41.3, 30_000.0, 12.5, -35.0),
                spec(-89.0, -170.0, 2.0e6, 300.0, -90.0),
                spec(0.0, 179.9, 150.0, 90.0, 10.0),
                spec(60.0, 5.0, 800.0, 0.0, -89.999),
            ] {
                let c = Camera::new(&e, s, 1.0);
                let back = Camera::spec_from_pose(&e, c.position, c.forward, c.up, s.fov);
                assert!((back.lat - s.lat).abs() < 1e-9 && (back.alt - s.alt).abs() < 1e-6, "{back:?} from {s:?}");
                let dlon = (back.lon - s.lon + 540.0).rem_euclid(360.0) - 180.0;
                let dheading = (back.heading - s.heading + 540.0).rem_euclid(360.0) - 180.0;
                assert!(
                    dlon.abs() < 1e-9 && dheading.abs() < 1e-7 && (back.pitch - s.pitch).abs() < 1e-7,
                    "{back:?} from {s:?}"
                );
            }
        }
    }

    #[test]
    fn rays_go_through_the_pixels_they_name() {
        let c = Camera::new(&Ellipsoid::WGS84, spec(30.0, 40.0, 2000.0, 10.0, -30.0), 1.0);
        for (x, y) in [(0.0, 0.0), (320.0, 240.0), (639.5, 17.25), (100.0, 479.0)] {
            let d = c.ray(x, y, 640, 480);
            let (px, py, _) = c.project(d * 1000.0, 640, 480).unwrap();
            assert!((px - x).abs() < 1e-9 && (py - y).abs() < 1e-9, "({x}, {y}) → ({px}, {py})");
        }
    }

    #[test]
    fn frustum_planes_hold_what_is_in_view() {
        let c = Camera::new(&Ellipsoid::WGS84, spec(30.0, 40.0, 2000.0, 10.0, -30.0), 1.0);
        let planes = c.frustum(640, 480);
        let inside = c.position + c.forward * 100.0 + c.right * 10.0;
        let behind = c.position - c.forward * 100.0;
        let far_left = c.position + c.forward * 10.0 - c.right * 100.0;
        let side = |p: DVec3| planes.iter().all(|pl| pl.normal.dot(p) + pl.d >= 0.0);
        assert!(side(inside));
        assert!(!side(behind));
        assert!(!side(far_left));
    }
}
