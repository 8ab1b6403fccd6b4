//! Where a check hashes: the quads at a level over a region, or around where a view looks.

use glam::DVec3;

use crate::Invalid;
use crate::ecm::{CubeProjection, QuadId};
use crate::geodesy::{self, Ellipsoid};
use crate::project::CameraSpec;
use crate::project::checks::MAX_CHECK_TILES;
use crate::scene::Camera;

/// The quads at `level` that a `[west, south, east, north]` region (degrees; east < west crosses
/// ±180°) touches, in quad order: every quad holding a point of a lattice a quarter of a quad
/// apart over the region, its edges included. More than [`MAX_CHECK_TILES`] is an error.
pub fn region_quads(ellipsoid: &Ellipsoid, [w, s, e, n]: [f64; 4], level: u8) -> Result<Vec<QuadId>, Invalid> {
    let span_lon = if e > w { e - w } else { e - w + 360.0 };
    // A face spans 90°; a quad of `level` about 90° / 2^level (less near the face's edges).
    let step = 90.0 / f64::from(1u32 << level.min(24)) / 4.0;
    let (rows, cols) = ((n - s) / step, span_lon / step);
    let too_many = || {
        format!(
            "region: it covers more than {MAX_CHECK_TILES} quads at level {level}; choose a smaller region or a coarser level"
        )
    };
    // Each quad holds about 16 lattice points; 64 per allowed tile leaves room for distortion.
    if rows * cols > 64.0 * MAX_CHECK_TILES as f64 {
        return Err(too_many().into());
    }
    let (rows, cols) = (rows.ceil() as usize, cols.ceil() as usize);
    let mut quads = std::collections::BTreeSet::new();
    for r in 0..=rows {
        let lat = s + (n - s) * r as f64 / rows.max(1) as f64;
        for c in 0..=cols {
            let lon = w + span_lon * c as f64 / cols.max(1) as f64;
            quads.insert(quad_at(ellipsoid, lat, lon, level)?);
        }
        if quads.len() > MAX_CHECK_TILES {
            return Err(too_many().into());
        }
    }
    Ok(quads.into_iter().collect())
}

/// The 3 × 3 quads at `level` around the point a view's centre looks at (where its centre ray
/// meets the ellipsoid, or the point below the camera when it looks past the body), those on
/// the same face as that point.
pub fn view_quads(ellipsoid: &Ellipsoid, view: CameraSpec, level: u8) -> Result<Vec<QuadId>, Invalid> {
    let camera = Camera::new(ellipsoid, view, 1.0);
    let (lat, lon) = match ray_hit(ellipsoid, camera.position, camera.forward) {
        Some(p) => {
            let g = geodesy::geodetic_from_ecef(ellipsoid, p);
            (g.lat_rad.to_degrees(), g.lon_rad.to_degrees())
        }
        None => (view.lat, view.lon),
    };
    let centre = quad_at(ellipsoid, lat, lon, level)?;
    let last = (1i64 << level) - 1;
    let mut quads = Vec::new();
    for dy in -1..=1 {
        for dx in -1..=1 {
            let (x, y) = (i64::from(centre.x) + dx, i64::from(centre.y) + dy);
            if (0..=last).contains(&x) && (0..=last).contains(&y) {
                quads.push(QuadId { x: x as u32, y: y as u32, ..centre });
            }
        }
    }
    quads.sort();
    Ok(quads)
}

fn quad_at(ellipsoid: &Ellipsoid, lat: f64, lon: f64, level: u8) -> Result<QuadId, Invalid> {
    let p = CubeProjection::Qsc.face_point_from_geodetic(ellipsoid, lat.to_radians(), lon.to_radians());
    QuadId::containing(p, level).map_err(|e| Invalid(format!("level: {e}")))
}

/// Where a ray first meets the ellipsoid's surface (h = 0), if it does: the ray scaled so that
/// the ellipsoid is the unit sphere.
fn ray_hit(ellipsoid: &Ellipsoid, origin: DVec3, dir: DVec3) -> Option<DVec3> {
    let scale = DVec3::new(1.0 / ellipsoid.a_m(), 1.0 / ellipsoid.a_m(), 1.0 / ellipsoid.b_m());
    let (o, d) = (origin * scale, dir * scale);
    let (a, b, c) = (d.dot(d), 2.0 * o.dot(d), o.dot(o) - 1.0);
    let disc = b * b - 4.0 * a * c;
    if disc < 0.0 {
        return None;
    }
    let t = (-b - disc.sqrt()) / (2.0 * a);
    (t > 0.0).then(|| origin + dir * t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_region_gives_the_quads_it_touches_and_a_view_the_block_it_looks_at() {
        let e = Ellipsoid::WGS84;
        // 1° × 1° at level 8 (quads of about 0.35°): 3 to 5 a side.
        let quads = region_quads(&e, [40.6, 39.5, 41.6, 40.5], 8).unwrap();
        assert!((9..=25).contains(&quads.len()), "{} quads", quads.len());
        assert!(quads.windows(2).all(|w| w[0] < w[1]));
        // Across the antimeridian: east < west.
        let across = region_quads(&e, [179.5, -0.5, -179.5, 0.5], 6).unwrap();
        assert!(across.iter().any(|q| q.face != across[0].face) || across.len() >= 2);
        let e2 = region_quads(&e, [-180.0, -90.0, 180.0, 90.0], 10).unwrap_err();
        assert!(e2.to_string().contains("more than 256 quads at level 10"), "{e2}");
        // Straight down: the block around the nadir's quad.
        let down = CameraSpec { lat: 39.9, lon: 41.3, alt: 5000.0, heading: 0.0, pitch: -90.0, fov: 45.0 };
        let block = view_quads(&e, down, 10).unwrap();
        assert_eq!(block.len(), 9);
        assert_eq!(block[4], quad_at(&e, 39.9, 41.3, 10).unwrap());
        // Looking north at 30° down from 10 km: the target is about 17 km north.
        let ahead = CameraSpec { pitch: -30.0, alt: 10_000.0, ..down };
        let p = ray_hit(&e, Camera::new(&e, ahead, 1.0).position, Camera::new(&e, ahead, 1.0).forward).unwrap();
        let g = geodesy::geodetic_from_ecef(&e, p);
        let north_km = (g.lat_rad.to_degrees() - 39.9) * 111.0;
        assert!((north_km - 17.3).abs() < 0.5, "{north_km} km");
        assert!(g.height_m.abs() < 1e-3, "on the surface: {} m", g.height_m);
    }
}
