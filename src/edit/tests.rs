use glam::DVec3;

use super::dabs::dab_centres;
use super::{EditRaster, Falloff, Stroke, Tool};
use crate::ecm::QuadId;
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};
use crate::layers::stack::sample_point;
use crate::store::grid::GRID;

const N: usize = GRID as usize;

fn stroke(tool: Tool, radius_m: f64, strength: f64, level: u8, path: &[[f64; 2]]) -> Stroke {
    Stroke {
        tool,
        radius_m,
        strength,
        falloff: Falloff::Smooth,
        spacing: 0.25,
        level,
        path: path.to_vec(),
        seed: 3,
        height_m: None,
    }
}

fn centre(e: &Ellipsoid, lat: f64, lon: f64) -> DVec3 {
    ecef_from_geodetic(e, Geodetic::from_degrees(lat, lon, 0.0))
}

/// Every sample of the raster's tiles: its point and δ.
fn samples(r: &EditRaster) -> Vec<(QuadId, usize, DVec3, f32)> {
    let mut out = Vec::new();
    for (q, tile) in &r.tiles {
        for (k, v) in tile.iter().enumerate() {
            let (p, _, _) = sample_point(&r.ellipsoid, *q, GRID, (k % N) as u32, (k / N) as u32);
            out.push((*q, k, p, *v));
        }
    }
    out
}

#[test]
fn the_falloff_curves_follow_their_formulas() {
    for t in [0.0, 0.1, 0.25, 0.5, 0.75, 0.9, 0.999] {
        assert_eq!(Falloff::Smooth.weight(t), 1.0 - t * t * (3.0 - 2.0 * t));
        assert_eq!(Falloff::Linear.weight(t), 1.0 - t);
        assert_eq!(Falloff::Spherical.weight(t), (1.0 - t * t).sqrt());
        assert_eq!(Falloff::Tip.weight(t), (1.0 - t).powi(3));
    }
    for f in Falloff::ALL {
        assert_eq!(f.weight(0.0), 1.0, "{f:?} at the centre");
        assert_eq!(f.weight(1.0), 0.0, "{f:?} at the rim");
        assert_eq!(f.weight(2.0), 0.0, "{f:?} beyond");
        assert_eq!(f.weight(f64::NAN), 0.0, "{f:?} of NaN");
    }
}

#[test]
fn one_dab_raises_each_sample_by_strength_times_the_falloff_of_its_distance_at_80_north_and_on_a_cube_corner() {
    // One dab (a one-point path) at 80°N, and one on the cube corner of WGS84 (front, right and
    // top faces meet at 45°E and about 35.26°N): δ at every sample equals strength·f(d/r) to f32
    // rounding, d the chord from the dab's centre; the footprint is a disc of radius r.
    let e = Ellipsoid::WGS84;
    let corner_lat = crate::geodesy::geodetic_lat_from_geocentric(&e, (1.0f64 / 3f64.sqrt()).asin());
    for (lat, lon, falloff) in [(80.0, 10.0, Falloff::Tip), (corner_lat.to_degrees(), 45.0, Falloff::Spherical)] {
        let mut s = stroke(Tool::Raise, 3000.0, 7.5, 11, &[[lat, lon]]);
        s.falloff = falloff;
        let r = EditRaster::build(e, std::slice::from_ref(&s)).unwrap();
        let c = centre(&e, lat, lon);
        let (mut inside, mut faces) = (0usize, std::collections::BTreeSet::new());
        for (q, _, p, v) in samples(&r) {
            let d = (p - c).length();
            let expected = (7.5 * falloff.weight(d / 3000.0)) as f32;
            assert_eq!(v, expected, "{q} at {d} m");
            if d < 3000.0 {
                inside += 1;
                faces.insert(q.face as u8);
            }
        }
        // A 3 km disc over level-11 samples (≈ 36 m apart near the corner, 26 m at 80°N).
        assert!(inside > 20_000, "{inside} samples inside");
        if lon == 45.0 {
            assert_eq!(faces.len(), 3, "the corner's disc spans three faces");
        }
    }
}

#[test]
fn shared_samples_agree_across_a_face_edge_and_strokes_are_circular_there() {
    // A raise stroke along the equator across the front/right face edge at 45°E: every sample
    // on the edge, as the two faces' quads hold it, has the same δ to 10⁻⁶ m, and the footprint
    // on each side reaches r from the path and no further.
    let e = Ellipsoid::WGS84;
    let s = stroke(Tool::Raise, 2000.0, 10.0, 10, &[[0.0, 44.97], [0.0, 45.03]]);
    let r = EditRaster::build(e, std::slice::from_ref(&s)).unwrap();
    let dabs = dab_centres(&e, &s).unwrap();
    let mut on_edge: Vec<(DVec3, f32)> = Vec::new();
    let mut faces = std::collections::BTreeSet::new();
    for (q, k, p, v) in samples(&r) {
        let nearest = dabs.iter().map(|c| (p - *c).length()).fold(f64::INFINITY, f64::min);
        assert_eq!(v != 0.0, nearest < 2000.0, "{q} sample {k}: δ {v} at {nearest} m from the nearest dab");
        if v != 0.0 {
            faces.insert(q.face as u8);
        }
        let (i, j) = (k % N, k / N);
        if i == 0 || i == N - 1 || j == 0 || j == N - 1 {
            on_edge.push((p, v));
        }
    }
    assert_eq!(faces.len(), 2, "the stroke spans the face edge");
    let mut compared = 0;
    for (a, (p, v)) in on_edge.iter().enumerate() {
        for (q, w) in &on_edge[a + 1..] {
            if (*p - *q).length() < 1e-6 {
                assert!((v - w).abs() <= 1e-6, "shared sample: {v} and {w}");
                compared += 1;
            }
        }
    }
    assert!(compared > 100, "{compared} shared samples compared");
}

#[test]
fn the_same_strokes_give_the_same_tiles_whatever_the_threads_and_undo_and_redo_restore_them_bit_for_bit() {
    let e = Ellipsoid::MOON;
    let strokes = vec![
        stroke(Tool::Raise, 4000.0, 30.0, 9, &[[10.0, 20.0], [10.05, 20.1], [10.0, 20.2]]),
        stroke(Tool::Noise, 3000.0, 8.0, 9, &[[10.02, 20.05], [10.02, 20.15]]),
        stroke(Tool::Lower, 2500.0, 12.0, 9, &[[9.98, 20.12]]),
        Stroke { strength: 0.6, ..stroke(Tool::Restore, 3500.0, 0.6, 9, &[[10.0, 20.0], [10.01, 20.08]]) },
        stroke(Tool::Raise, 5000.0, 4.0, 9, &[[10.3, 20.5], [10.35, 20.55]]),
    ];
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| EditRaster::build(e, &strokes).unwrap())
    };
    let one = in_pool(1);
    let three = in_pool(3);
    assert!(one.tiles.len() >= 2, "{} tiles", one.tiles.len());
    assert_eq!(one, three, "1 and 3 threads");
    // Undo the last three strokes: the quads they touched are recomputed from the first two and
    // equal a fresh build of those two, bit for bit; the untouched ones were never changed.
    // Both ways: from the before-images, and recomputed without them.
    let two = EditRaster::build(e, &strokes[..2]).unwrap();
    let mut recomputed = one.clone();
    recomputed.clear_history();
    recomputed.undo_to(&strokes, 2).unwrap();
    assert!(recomputed == two, "recomputed undo");
    let mut edited = one.clone();
    edited.undo_to(&strokes, 2).unwrap();
    assert!(edited == two, "undo from the history");
    // Redo: applying them again gives the full raster bit for bit.
    for (k, s) in strokes.iter().enumerate().skip(2) {
        edited.apply(k, s).unwrap();
    }
    assert_eq!(edited, one, "redo");
    // Undo to nothing: no tile left.
    edited.undo_to(&strokes, 0).unwrap();
    assert!(edited.tiles.is_empty());
}

#[test]
fn dabs_are_placed_by_arc_length_whatever_the_path_is_sampled_at() {
    // The same 10 km line given as 2 points or as 50: the same dabs (to 0.1 mm), one every
    // spacing × radius along it.
    let e = Ellipsoid::WGS84;
    let two = stroke(Tool::Raise, 1000.0, 1.0, 12, &[[40.0, 30.0], [40.0, 30.1173]]);
    let (lat, lon1, lon2) = (40.0f64, 30.0f64, 30.1173f64);
    let (length, az, _) =
        crate::geodesy::geodesic::inverse(&e, lat.to_radians(), lon1.to_radians(), lat.to_radians(), lon2.to_radians())
            .unwrap();
    let points: Vec<[f64; 2]> = (0..=49)
        .map(|k| {
            let (la, lo) =
                crate::geodesy::geodesic::direct(&e, lat.to_radians(), lon1.to_radians(), az, length * k as f64 / 49.0);
            [la.to_degrees(), lo.to_degrees()]
        })
        .collect();
    let many = Stroke { path: points, ..two.clone() };
    let (a, b) = (dab_centres(&e, &two).unwrap(), dab_centres(&e, &many).unwrap());
    assert_eq!(a.len(), (length / 250.0).floor() as usize + 1);
    assert_eq!(a.len(), b.len());
    // The 50 points come from Vincenty's direct problem, iterated to 10⁻¹² rad (6·10⁻⁶ m here).
    for (p, q) in a.iter().zip(&b) {
        assert!((*p - *q).length() < 1e-4, "{}", (*p - *q).length());
    }
}

#[test]
fn bad_strokes_name_the_stroke_the_field_and_the_problem() {
    let e = Ellipsoid::WGS84;
    let ok = stroke(Tool::Raise, 500.0, 20.0, 12, &[[40.0, 30.0]]);
    let cases = vec![
        (Stroke { radius_m: 1e10, ..ok.clone() }, "strokes[1]: radius_m: 10000000000 must be a distance"),
        (Stroke { radius_m: f64::NAN, ..ok.clone() }, "strokes[1]: radius_m: NaN"),
        (Stroke { tool: Tool::Restore, ..ok.clone() }, "strokes[1]: strength: 20 must be a fraction in [0, 1]"),
        (Stroke { spacing: 0.0, ..ok.clone() }, "strokes[1]: spacing: 0 must be a fraction"),
        (Stroke { path: vec![], ..ok.clone() }, "strokes[1]: path: 0 points"),
        (Stroke { path: vec![[95.0, 0.0]], ..ok.clone() }, "strokes[1]: path: point 0 [95, 0]"),
        (Stroke { level: 40, ..ok.clone() }, "strokes[1]: level: 40 must be at most 24"),
        (Stroke { height_m: Some(5.0), ..ok.clone() }, "strokes[1]: height_m: is the flatten height"),
        (Stroke { tool: Tool::Smooth, strength: 0.5, ..ok.clone() }, "strokes[1]: tool: smooth reads the terrain"),
    ];
    for (bad, expected) in cases {
        let e = EditRaster::build(e, &[ok.clone(), bad]).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}\n  expected: {expected}");
    }
}
