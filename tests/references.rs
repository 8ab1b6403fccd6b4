//! Accuracy against independent references: PROJ's `cct` (`+proj=qsc`, `+proj=cart`),
//! GeographicLib's `CartConvert`, and a 60-digit mpmath evaluation of the QSC formulas
//! (`tests/reference/qsc_mpmath.py`). Thousands of seeded points per body: random, face centres
//! and their close neighbourhood, poles, face edges, cube corners and longitude ±180°.

mod common;

use common::{PYTHON, parse_rows, repo_path, run_tool};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;
use terrafuse::ecm::{CubeProjection, Face, FacePoint};
use terrafuse::geodesy::{self, Ellipsoid, Geodetic};

const BODIES: [Ellipsoid; 3] = [Ellipsoid::WGS84, Ellipsoid::MOON, Ellipsoid::MARS];

/// Required agreement with the 60-digit reference, in face units (≈ 0.06 mm on Earth).
const FACE_TOLERANCE: f64 = 1e-11;

/// Geodetic test points (degrees): random, then the special places.
fn test_points(ellipsoid: &Ellipsoid, seed: u64, random: usize) -> Vec<(f64, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut points = Vec::new();
    for _ in 0..random {
        let lat = (2.0 * rng.random::<f64>() - 1.0).asin().to_degrees();
        points.push((lat, rng.random_range(-180.0..=180.0)));
    }
    // Face centres and their neighbourhood, down to 1e-12 degrees away.
    for face in Face::ALL {
        for offset in [0.0, 1e-12, 1e-10, 1e-8, 1e-6, 1e-4, 1e-2] {
            for (dx, dy) in [(1.0, 0.0), (0.0, 1.0), (-0.7, 0.7), (0.3, -0.9)] {
                let p = FacePoint { face, x: dx * offset, y: dy * offset };
                let (lat, lon) = CubeProjection::Qsc.geodetic_from_face_point(ellipsoid, p).unwrap();
                points.push((lat.to_degrees(), lon.to_degrees()));
            }
        }
        // Edges and corners of every face.
        for t in [-1.0, -0.999_999, -0.5, 0.0, 0.3, 0.999_999_999, 1.0] {
            for (x, y) in [(1.0, t), (-1.0, t), (t, 1.0), (t, -1.0)] {
                let (lat, lon) =
                    CubeProjection::Qsc.geodetic_from_face_point(ellipsoid, FacePoint { face, x, y }).unwrap();
                points.push((lat.to_degrees(), lon.to_degrees()));
            }
        }
    }
    // Poles and the antimeridian.
    for lat in [90.0, 89.999_999_999, -90.0, -89.999_999, 45.0, 0.0, -30.0] {
        for lon in [-180.0, 180.0, 179.999_999_999, -179.999_999_999, 0.0, 45.0, 135.0, -135.0] {
            points.push((lat, lon));
        }
    }
    points
}

fn degrees_text(v: f64) -> String {
    format!("{v:?}")
}

/// Angular distance of a direction from its face centre, in radians (for the zone where PROJ
/// itself is inexact).
fn distance_from_centre_rad(ellipsoid: &Ellipsoid, lat: f64, lon: f64) -> f64 {
    let d = geodesy::sphere_direction_from_geodetic(ellipsoid, lat.to_radians(), lon.to_radians());
    let face = Face::of_direction(d);
    d.cross(face.center()).length().asin()
}

#[test]
fn qsc_forward_matches_60_digit_reference_and_proj() {
    let mut report = String::new();
    for (index, ellipsoid) in BODIES.iter().enumerate() {
        let points = test_points(ellipsoid, 7 + index as u64, 3000);
        let ours: Vec<FacePoint> = points
            .iter()
            .map(|(lat, lon)| {
                CubeProjection::Qsc.face_point_from_geodetic(ellipsoid, lat.to_radians(), lon.to_radians())
            })
            .collect();
        // 60-digit reference on the face we chose.
        let input: String = points
            .iter()
            .zip(&ours)
            .map(|((lat, lon), p)| {
                format!(
                    "fwd {:?} {:?} {} {} {}\n",
                    ellipsoid.a_m(),
                    ellipsoid.b_m(),
                    p.face.index(),
                    degrees_text(*lat),
                    degrees_text(*lon)
                )
            })
            .collect();
        let reference =
            parse_rows(&run_tool(PYTHON, &[repo_path("tests/reference/qsc_mpmath.py").to_str().unwrap()], &input));
        assert_eq!(reference.len(), points.len());
        let mut worst = 0.0f64;
        for ((p, r), (lat, lon)) in ours.iter().zip(&reference).zip(&points) {
            let err = (p.x - r[0]).abs().max((p.y - r[1]).abs());
            assert!(
                err < FACE_TOLERANCE,
                "{}: lat {lat} lon {lon} on {}: ours ({}, {}) reference ({}, {}) diff {err:e}",
                ellipsoid.name(),
                p.face,
                p.x,
                p.y,
                r[0],
                r[1]
            );
            worst = worst.max(err);
        }
        // PROJ, face by face.
        let mut worst_proj = 0.0f64;
        let mut worst_proj_centre = 0.0f64;
        let mut compared = 0;
        for face in Face::ALL {
            let selected: Vec<usize> = (0..points.len()).filter(|&i| ours[i].face == face).collect();
            let input: String = selected
                .iter()
                .map(|&i| format!("{} {} 0\n", degrees_text(points[i].1), degrees_text(points[i].0)))
                .collect();
            let params = format!("+proj=qsc {} {}", face.proj_center(), ellipsoid.proj_params());
            let args: Vec<&str> = ["-d", "12"].into_iter().chain(params.split(' ')).collect();
            let proj = parse_rows(&run_tool("cct", &args, &input));
            assert_eq!(proj.len(), selected.len());
            for (&i, row) in selected.iter().zip(&proj) {
                let (x, y) = (row[0] / ellipsoid.a_m(), row[1] / ellipsoid.a_m());
                let err = (ours[i].x - x).abs().max((ours[i].y - y).abs());
                let ref_err = (reference[i][0] - x).abs().max((reference[i][1] - y).abs());
                if distance_from_centre_rad(ellipsoid, points[i].0, points[i].1) < 1e-4 {
                    // PROJ's acos(cos φ) loses half the digits here: record, do not compare.
                    worst_proj_centre = worst_proj_centre.max(ref_err);
                    continue;
                }
                assert!(
                    err < FACE_TOLERANCE,
                    "{} {face}: lat {} lon {}: ours ({}, {}) PROJ ({x}, {y}) diff {err:e}",
                    ellipsoid.name(),
                    points[i].0,
                    points[i].1,
                    ours[i].x,
                    ours[i].y
                );
                worst_proj = worst_proj.max(err);
                compared += 1;
            }
        }
        assert!(compared > 2500, "too few PROJ comparisons: {compared}");
        report += &format!(
            "{}: {} points; ours vs 60-digit: max {worst:.2e}; ours vs PROJ (outside 1e-4 rad of centres, {compared} pts): max {worst_proj:.2e}; PROJ vs 60-digit within 1e-4 rad of centres: max {worst_proj_centre:.2e} = {:.3} mm\n",
            ellipsoid.name(),
            points.len(),
            worst_proj_centre * ellipsoid.a_m() * 1000.0
        );
    }
    println!("{report}");
}

#[test]
fn qsc_inverse_matches_60_digit_reference_and_proj() {
    let mut report = String::new();
    for (index, ellipsoid) in BODIES.iter().enumerate() {
        let mut rng = ChaCha8Rng::seed_from_u64(100 + index as u64);
        let mut face_points = Vec::new();
        for face in Face::ALL {
            for _ in 0..400 {
                face_points.push(FacePoint { face, x: rng.random_range(-1.0..=1.0), y: rng.random_range(-1.0..=1.0) });
            }
            for (x, y) in [
                (0.0, 0.0),
                (1e-12, 0.0),
                (0.0, -1e-10),
                (3e-9, 2e-9),
                (1.0, 1.0),
                (-1.0, 1.0),
                (1.0, -0.25),
                (0.5, -1.0),
                (-1.0, -1.0),
                (0.999_999_999_9, 1e-7),
            ] {
                face_points.push(FacePoint { face, x, y });
            }
        }
        let ours: Vec<(f64, f64)> = face_points
            .iter()
            .map(|p| {
                let (lat, lon) = CubeProjection::Qsc.geodetic_from_face_point(ellipsoid, *p).unwrap();
                (lat.to_degrees(), lon.to_degrees())
            })
            .collect();
        let input: String = face_points
            .iter()
            .map(|p| {
                format!("inv {:?} {:?} {} {:?} {:?}\n", ellipsoid.a_m(), ellipsoid.b_m(), p.face.index(), p.x, p.y)
            })
            .collect();
        let reference =
            parse_rows(&run_tool(PYTHON, &[repo_path("tests/reference/qsc_mpmath.py").to_str().unwrap()], &input));
        // Angular error in radians, with longitude weighted by cos(lat): on the unit sphere this
        // is comparable with face units.
        let angular = |a: (f64, f64), b: (f64, f64)| {
            let dlat = (a.0 - b.0).to_radians();
            let mut dlon = (a.1 - b.1).rem_euclid(360.0);
            if dlon > 180.0 {
                dlon -= 360.0;
            }
            dlat.abs().max((dlon.to_radians() * b.0.to_radians().cos()).abs())
        };
        let mut worst = 0.0f64;
        for ((p, o), r) in face_points.iter().zip(&ours).zip(&reference) {
            let err = angular(*o, (r[0], r[1]));
            assert!(err < FACE_TOLERANCE, "{} {p:?}: ours {o:?} reference {r:?} diff {err:e}", ellipsoid.name());
            worst = worst.max(err);
        }
        let mut worst_proj = 0.0f64;
        for face in Face::ALL {
            let selected: Vec<usize> = (0..face_points.len())
                .filter(|&i| face_points[i].face == face)
                // PROJ's inverse loses digits near the face centre, and its ellipsoidal shift
                // near the equator (sqrt(a² − xa²) cancels): compare outside those zones.
                .filter(|&i| {
                    face_points[i].x.hypot(face_points[i].y) > 1e-4 && (ellipsoid.is_sphere() || ours[i].0.abs() > 0.5)
                })
                .collect();
            let input: String = selected
                .iter()
                .map(|&i| {
                    format!("{:?} {:?} 0\n", face_points[i].x * ellipsoid.a_m(), face_points[i].y * ellipsoid.a_m())
                })
                .collect();
            let params = format!("+proj=qsc {} {}", face.proj_center(), ellipsoid.proj_params());
            let args: Vec<&str> = ["-d", "14", "-I"].into_iter().chain(params.split(' ')).collect();
            let proj = parse_rows(&run_tool("cct", &args, &input));
            for (&i, row) in selected.iter().zip(&proj) {
                let err = angular(ours[i], (row[1], row[0]));
                assert!(
                    err < FACE_TOLERANCE,
                    "{} {:?}: ours {:?} PROJ ({}, {}) diff {err:e}",
                    ellipsoid.name(),
                    face_points[i],
                    ours[i],
                    row[1],
                    row[0]
                );
                worst_proj = worst_proj.max(err);
            }
        }
        report += &format!(
            "{}: inverse vs 60-digit max {worst:.2e} rad; vs PROJ max {worst_proj:.2e} rad\n",
            ellipsoid.name()
        );
    }
    println!("{report}");
}

#[test]
fn qsc_roundtrips_return_to_the_same_surface_point() {
    for (index, ellipsoid) in BODIES.iter().enumerate() {
        let mut worst = 0.0f64;
        for (lat, lon) in test_points(ellipsoid, 200 + index as u64, 5000) {
            let (lat, lon) = (lat.to_radians(), lon.to_radians());
            let p = CubeProjection::Qsc.face_point_from_geodetic(ellipsoid, lat, lon);
            let (lat2, lon2) = CubeProjection::Qsc.geodetic_from_face_point(ellipsoid, p).unwrap();
            let at =
                |lat_rad, lon_rad| geodesy::ecef_from_geodetic(ellipsoid, Geodetic { lat_rad, lon_rad, height_m: 0.0 });
            let err = (at(lat, lon) - at(lat2, lon2)).length();
            worst = worst.max(err);
            // 1e-9 m, or 4 ulp of the coordinates where that is more (Earth: 1 ulp ≈ 0.93e-9 m).
            let tolerance = 1e-9f64.max(4.0 * ellipsoid.a_m() * f64::EPSILON);
            assert!(
                err < tolerance,
                "{}: ({}, {}) → {p:?} → ({}, {}): {err:e} m",
                ellipsoid.name(),
                lat.to_degrees(),
                lon.to_degrees(),
                lat2.to_degrees(),
                lon2.to_degrees()
            );
        }
        println!("{}: worst QSC round trip {worst:.2e} m", ellipsoid.name());
    }
}

fn ecef_points(seed: u64) -> Vec<(f64, f64, f64)> {
    let mut rng = ChaCha8Rng::seed_from_u64(seed);
    let mut points: Vec<(f64, f64, f64)> = (0..3000)
        .map(|_| {
            let lat = (2.0 * rng.random::<f64>() - 1.0).asin().to_degrees();
            let lon = rng.random_range(-180.0..=180.0);
            // Heights from −12 km to 1e8 m, log-spread above 1 km.
            let h = match rng.random_range(0..3) {
                0 => rng.random_range(-12_000.0..10_000.0),
                1 => 10f64.powf(rng.random_range(3.0..8.0)),
                _ => rng.random_range(-100.0..100.0),
            };
            (lat, lon, h)
        })
        .collect();
    for lat in [90.0, -90.0, 89.999_999_9, 0.0, 45.0] {
        for lon in [-180.0, 180.0, 0.0] {
            for h in [-12_000.0, 0.0, 8848.0, 1e8] {
                points.push((lat, lon, h));
            }
        }
    }
    points
}

#[test]
fn geodetic_to_ecef_matches_geographiclib_and_proj() {
    for (index, ellipsoid) in BODIES.iter().enumerate() {
        let points = ecef_points(300 + index as u64);
        let input: String = points.iter().map(|(lat, lon, h)| format!("{lat:?} {lon:?} {h:?}\n")).collect();
        let f = format!("{:?}", ellipsoid.flattening());
        let a = format!("{:?}", ellipsoid.a_m());
        let cart = parse_rows(&run_tool("CartConvert", &["-p", "10", "-e", &a, &f], &input));
        let proj_input: String = points.iter().map(|(lat, lon, h)| format!("{lon:?} {lat:?} {h:?}\n")).collect();
        let params = format!("+proj=cart {}", ellipsoid.proj_params());
        let args: Vec<&str> = ["-d", "10"].into_iter().chain(params.split(' ')).collect();
        let proj = parse_rows(&run_tool("cct", &args, &proj_input));
        let mut worst = 0.0f64;
        for (i, (lat, lon, h)) in points.iter().enumerate() {
            let ours = geodesy::ecef_from_geodetic(ellipsoid, Geodetic::from_degrees(*lat, *lon, *h));
            let c = DVec3::new(cart[i][0], cart[i][1], cart[i][2]);
            let p = DVec3::new(proj[i][0], proj[i][1], proj[i][2]);
            // 1e-9 m plus the printed precision (1e-10 m) and 4 ulp of the coordinates.
            let tolerance = 1.1e-9 + 4.0 * ours.length() * f64::EPSILON;
            let (ec, ep) = ((ours - c).length(), (ours - p).length());
            assert!(
                ec < tolerance && ep < tolerance,
                "{} ({lat}, {lon}, {h}): ours {ours} CartConvert {c} ({ec:e}) PROJ {p} ({ep:e})",
                ellipsoid.name()
            );
            worst = worst.max(ec);
        }
        println!("{}: geodetic→ECEF vs CartConvert max {worst:.2e} m", ellipsoid.name());
    }
}

#[test]
fn ecef_to_geodetic_matches_geographiclib_everywhere() {
    for (index, ellipsoid) in BODIES.iter().enumerate() {
        let points = ecef_points(400 + index as u64);
        let ecef: Vec<DVec3> = points
            .iter()
            .map(|(lat, lon, h)| geodesy::ecef_from_geodetic(ellipsoid, Geodetic::from_degrees(*lat, *lon, *h)))
            .collect();
        let input: String = ecef.iter().map(|p| format!("{:?} {:?} {:?}\n", p.x, p.y, p.z)).collect();
        let f = format!("{:?}", ellipsoid.flattening());
        let a = format!("{:?}", ellipsoid.a_m());
        let cart = parse_rows(&run_tool("CartConvert", &["-r", "-p", "10", "-e", &a, &f], &input));
        let mut worst = 0.0f64;
        for (p, row) in ecef.iter().zip(&cart) {
            let ours = geodesy::geodetic_from_ecef(ellipsoid, *p);
            let r = ours.height_m + ellipsoid.a_m();
            let dlat = (ours.lat_rad.to_degrees() - row[0]).to_radians() * r;
            let mut dlon = (ours.lon_rad.to_degrees() - row[1]).rem_euclid(360.0);
            if dlon > 180.0 {
                dlon -= 360.0;
            }
            let dlon = dlon.to_radians() * r * ours.lat_rad.cos();
            let dh = ours.height_m - row[2];
            let err = dlat.abs().max(dlon.abs()).max(dh.abs());
            // CartConvert prints 15 decimals of degrees (1e-10 m on Earth) and 10 of metres.
            let tolerance = 1e-9 + 4.0 * p.length() * f64::EPSILON;
            assert!(err < tolerance, "{} {p}: ours {ours:?} CartConvert {row:?}: {err:e} m", ellipsoid.name());
            worst = worst.max(err);
            // And the point itself comes back.
            let back = geodesy::ecef_from_geodetic(ellipsoid, ours);
            assert!((back - *p).length() < tolerance, "{} {p}: round trip {back}", ellipsoid.name());
        }
        println!("{}: ECEF→geodetic vs CartConvert max {worst:.2e} m", ellipsoid.name());
    }
}
