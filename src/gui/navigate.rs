//! Camera navigation in the workstation, all in f64 ECEF: the globe follows a dragged point,
//! the camera orbits a point of the terrain, zooms towards the point under the cursor, and flies
//! level over the ground. Each move places the camera anew and returns its geodetic
//! description ([`Camera::spec_from_pose`]), so the view stays a plain `CameraSpec` that
//! projects store.

use glam::{DQuat, DVec3};

use crate::geodesy::{self, Ellipsoid};
use crate::project::CameraSpec;
use crate::scene::Camera;

/// The camera never goes closer than this to the body's centre, in body radii above the
/// surface, nor farther than `MAX_ALTITUDE_RADII`.
const MAX_ALTITUDE_RADII: f64 = 50.0;
/// Least height over the point it approaches, metres: zooming stops short of the surface.
const MIN_CLEARANCE_M: f64 = 1.0;
/// The orbit keeps the camera this many degrees above the pivot's horizon.
const MIN_ORBIT_ELEVATION_DEG: f64 = 2.0;

/// The pose of a moved camera as a spec, with the field of view kept and the altitude kept
/// within 50 body radii.
fn settle(e: &Ellipsoid, c: &Camera, position: DVec3, forward: DVec3, up: DVec3) -> CameraSpec {
    let mut spec = Camera::spec_from_pose(e, position, forward, up, c.spec.fov);
    spec.alt = spec.alt.min(MAX_ALTITUDE_RADII * e.a_m());
    spec
}

/// Where the ray from `origin` along unit `dir` meets the sphere of radius `r` about the
/// body's centre (the nearer crossing), or `None` if it misses.
pub fn ray_sphere(origin: DVec3, dir: DVec3, r: f64) -> Option<DVec3> {
    let b = origin.dot(dir);
    let c = origin.length_squared() - r * r;
    let disc = b * b - c;
    if disc < 0.0 {
        return None;
    }
    let t = if c > 0.0 { -b - disc.sqrt() } else { -b + disc.sqrt() };
    (t > 0.0).then(|| origin + dir * t)
}

/// Turns the globe so that `anchor` (an ECEF point grabbed when the drag began) lies under the
/// ray `dir` of the current cursor: the camera rotates about the body's centre by the rotation
/// taking the ray's crossing of the anchor's sphere to the anchor. Past the limb the ray's
/// closest approach to the centre stands in, so the drag goes on smoothly.
pub fn drag_globe(e: &Ellipsoid, c: &Camera, anchor: DVec3, dir: DVec3) -> CameraSpec {
    let r = anchor.length();
    let hit = ray_sphere(c.position, dir, r).unwrap_or_else(|| {
        let closest = c.position - dir * c.position.dot(dir);
        closest.normalize() * r
    });
    let turn = DQuat::from_rotation_arc(hit.normalize(), anchor.normalize());
    settle(e, c, turn * c.position, turn * c.forward, turn * c.up)
}

/// Orbits the camera about `pivot` (an ECEF point of the terrain): `d_heading_deg` about the
/// pivot's vertical, `d_pitch_deg` about the camera's right axis (positive tilts the view up
/// towards the horizon). The camera keeps 2° above the pivot's horizon and never passes over
/// the pivot's zenith; a tilt that would break either is dropped, the turn kept.
pub fn orbit(e: &Ellipsoid, c: &Camera, pivot: DVec3, d_heading_deg: f64, d_pitch_deg: f64) -> CameraSpec {
    let g = geodesy::geodetic_from_ecef(e, pivot);
    let vertical = geodesy::normal_from_geodetic(g.lat_rad, g.lon_rad);
    let yaw = DQuat::from_axis_angle(vertical, -d_heading_deg.to_radians());
    let tilt = DQuat::from_axis_angle(c.right, d_pitch_deg.to_radians());
    let apply = |q: DQuat| (pivot + q * (c.position - pivot), q * c.forward, q * c.up);
    let elevation = |p: DVec3| (p - pivot).normalize().dot(vertical).clamp(-1.0, 1.0).asin().to_degrees();
    let (p, f, u) = apply(yaw * tilt);
    let keeps_above = elevation(p) >= MIN_ORBIT_ELEVATION_DEG.min(elevation(c.position));
    let stays_this_side = (u.dot(vertical) >= 0.0) || (c.up.dot(vertical) < 0.0);
    let (p, f, u) = if keeps_above && stays_this_side { (p, f, u) } else { apply(yaw) };
    settle(e, c, p, f, u)
}

/// Moves the camera towards `target` (or away, for `factor` > 1) so that its distance to the
/// target is multiplied by `factor`; the view direction is kept, so the target stays under the
/// same pixel. Stops `MIN_CLEARANCE_M` short of the target.
pub fn zoom(e: &Ellipsoid, c: &Camera, target: DVec3, factor: f64) -> CameraSpec {
    let offset = c.position - target;
    let distance = offset.length();
    let new_distance = (distance * factor).max(MIN_CLEARANCE_M.min(distance));
    let position = target + offset * (new_distance / distance.max(f64::MIN_POSITIVE));
    settle(e, c, position, c.forward, c.up)
}

/// A point to zoom towards when no terrain is under the cursor: where the ray meets the
/// ellipsoid's mean sphere, else the point on the ray as far as the horizon.
pub fn fallback_target(e: &Ellipsoid, c: &Camera, dir: DVec3) -> DVec3 {
    let r = 0.5 * (e.a_m() + e.b_m());
    ray_sphere(c.position, dir, r).unwrap_or_else(|| {
        let h = (c.position.length_squared() - r * r).max(1.0).sqrt();
        c.position + dir * h
    })
}

/// Flies the camera: `forward_m` along the level heading, `right_m` to its right, `up_m` along
/// the vertical, keeping its heading and pitch.
pub fn fly(e: &Ellipsoid, c: &Camera, forward_m: f64, right_m: f64, up_m: f64) -> CameraSpec {
    let level = (c.forward - c.zenith * c.forward.dot(c.zenith)).try_normalize().unwrap_or(c.up);
    let side = level.cross(c.zenith);
    let position = c.position + level * forward_m + side * right_m + c.zenith * up_m;
    let mut spec = settle(e, c, position, c.forward, c.up);
    spec.heading = c.spec.heading;
    spec.pitch = c.spec.pitch;
    spec
}

/// Turns the camera where it stands: heading and pitch change, pitch within ±90°.
pub fn look(spec: &CameraSpec, d_heading_deg: f64, d_pitch_deg: f64) -> CameraSpec {
    CameraSpec {
        heading: (spec.heading + d_heading_deg).rem_euclid(360.0),
        pitch: (spec.pitch + d_pitch_deg).clamp(-90.0, 90.0),
        ..*spec
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn camera(e: &Ellipsoid, lat: f64, lon: f64, alt: f64, heading: f64, pitch: f64) -> Camera {
        Camera::new(e, CameraSpec { lat, lon, alt, heading, pitch, fov: 45.0 }, 1.0)
    }

    #[test]
    fn a_dragged_point_follows_the_cursor() {
        let e = Ellipsoid::WGS84;
        let (w, h) = (800, 600);
        for c in [camera(&e, 39.9, 41.3, 30_000.0, 0.0, -60.0), camera(&e, 10.0, 20.0, 8.0e6, 0.0, -90.0)] {
            let grab = c.ray(400.0, 350.0, w, h);
            let anchor = ray_sphere(c.position, grab, e.a_m()).expect("the ray hits the globe");
            for (x, y) in [(430.0, 350.0), (400.0, 300.0), (380.0, 372.0)] {
                let moved = Camera::new(&e, drag_globe(&e, &c, anchor, c.ray(x, y, w, h)), 1.0);
                let (px, py, _) = moved.project(anchor - moved.position, w, h).unwrap();
                // The spec has no roll: the rotation's roll (tiny for small drags) is dropped.
                let miss = (px - x).hypot(py - y);
                assert!(miss < 0.5, "anchor at ({px:.2}, {py:.2}), cursor ({x}, {y})");
            }
        }
    }

    #[test]
    fn zoom_keeps_the_target_under_its_pixel_and_scales_the_distance() {
        let e = Ellipsoid::WGS84;
        let c = camera(&e, 39.9, 41.3, 30_000.0, 20.0, -45.0);
        let dir = c.ray(200.0, 150.0, 800, 600);
        let target = ray_sphere(c.position, dir, e.a_m() + 1500.0).unwrap();
        let before = (target - c.position).length();
        let z = Camera::new(&e, zoom(&e, &c, target, 0.5), 1.0);
        let after = (target - z.position).length();
        assert!((after / before - 0.5).abs() < 1e-9, "{after} vs {before}");
        let (px, py, _) = z.project(target - z.position, 800, 600).unwrap();
        // Within half a pixel: the spec has no roll, and the local north turns as the camera moves.
        assert!((px - 200.0).abs() < 0.5 && (py - 150.0).abs() < 0.5, "({px}, {py})");
        // Zooming in again and again stops short of the surface.
        let mut spec = z.spec;
        for _ in 0..100 {
            spec = zoom(&e, &Camera::new(&e, spec, 1.0), target, 0.5);
        }
        let d = (target - Camera::new(&e, spec, 1.0).position).length();
        assert!((MIN_CLEARANCE_M * 0.5..=MIN_CLEARANCE_M * 1.01).contains(&d), "{d}");
        // Out never beyond 50 radii.
        for _ in 0..100 {
            spec = zoom(&e, &Camera::new(&e, spec, 1.0), target, 4.0);
        }
        assert!(spec.alt <= MAX_ALTITUDE_RADII * e.a_m() + 1e-6);
    }

    #[test]
    fn orbit_turns_about_the_pivot_and_stays_above_its_horizon() {
        let e = Ellipsoid::MOON;
        let c = camera(&e, -43.3, -11.2, 50_000.0, 0.0, -50.0);
        let pivot = ray_sphere(c.position, c.forward, e.a_m()).unwrap();
        let d0 = (pivot - c.position).length();
        let turned = Camera::new(&e, orbit(&e, &c, pivot, 90.0, 0.0), 1.0);
        assert!(((pivot - turned.position).length() - d0).abs() < 1e-6 * d0, "distance to the pivot kept");
        let dh = (turned.spec.heading - 90.0 + 540.0).rem_euclid(360.0) - 180.0;
        // The camera moved ~60 km round the pivot, where north points 1.3° differently.
        assert!(dh.abs() < 2.0, "heading {} after a 90° turn", turned.spec.heading);
        let (px, py, _) = turned.project(pivot - turned.position, 800, 600).unwrap();
        assert!((px - 400.0).abs() < 1.0 && (py - 300.0).abs() < 1.0, "pivot stays centred: ({px}, {py})");
        // Tilting down towards the nadir and back up to the horizon turns the pitch.
        let steeper = orbit(&e, &c, pivot, 0.0, -20.0);
        assert!((steeper.pitch - (-70.0)).abs() < 1.5, "pitch {} after tilting 20° down", steeper.pitch);
        let shallower = orbit(&e, &c, pivot, 0.0, 20.0);
        assert!((shallower.pitch - (-30.0)).abs() < 1.5, "pitch {} after tilting 20° up", shallower.pitch);
        // Tilting far towards the horizon is refused past it; the camera stays above it.
        let mut spec = c.spec;
        for _ in 0..30 {
            spec = orbit(&e, &Camera::new(&e, spec, 1.0), pivot, 0.0, 5.0);
        }
        let p = Camera::new(&e, spec, 1.0).position;
        let up = (pivot).normalize();
        let elevation = (p - pivot).normalize().dot(up).asin().to_degrees();
        assert!(elevation >= MIN_ORBIT_ELEVATION_DEG - 1e-9, "elevation {elevation}");
    }

    #[test]
    fn flying_keeps_the_attitude_and_moves_level() {
        let e = Ellipsoid::WGS84;
        let c = camera(&e, 40.0, 41.0, 3000.0, 90.0, -30.0);
        let s = fly(&e, &c, 1000.0, 0.0, 0.0);
        assert_eq!((s.heading, s.pitch), (90.0, -30.0));
        assert!((s.lat - 40.0).abs() < 1e-3 && s.lon > 41.0 + 0.011, "east by 1 km: {s:?}");
        assert!((s.alt - 3000.0).abs() < 0.2, "level flight (the Earth curves 0.08 m under 1 km)");
        let up = fly(&e, &c, 0.0, 0.0, 500.0);
        assert!((up.alt - 3500.0).abs() < 1e-6);
        let l = look(&c.spec, 300.0, -80.0);
        assert_eq!((l.heading, l.pitch), (30.0, -90.0));
    }
}
