use std::collections::BTreeSet;

use glam::DVec3;

use super::dabs::dab_centres;
use super::{EditRaster, Falloff, Stroke, Tool, ellipsoid_below};
use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::ecm::points::sample_point;
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};

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
        let r = EditRaster::build(e, std::slice::from_ref(&s), &ellipsoid_below).unwrap();
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
    let r = EditRaster::build(e, std::slice::from_ref(&s), &ellipsoid_below).unwrap();
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
        stroke(Tool::Smooth, 3000.0, 0.7, 9, &[[10.0, 20.02], [10.04, 20.1]]),
        stroke(Tool::Raise, 5000.0, 4.0, 9, &[[10.3, 20.5], [10.35, 20.55]]),
        stroke(Tool::Flatten, 2000.0, 0.5, 9, &[[10.02, 20.0], [10.0, 20.06]]),
        stroke(Tool::Ramp, 2500.0, 0.8, 9, &[[10.3, 20.45], [10.33, 20.6]]),
    ];
    let in_pool = |threads: usize| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build()
            .unwrap()
            .install(|| EditRaster::build(e, &strokes, &rough_below).unwrap())
    };
    let one = in_pool(1);
    let three = in_pool(3);
    assert!(one.tiles.len() >= 2, "{} tiles", one.tiles.len());
    assert_eq!(one, three, "1 and 3 threads");
    // Undo all but the first two strokes: the quads they touched are recomputed from the first
    // two and equal a fresh build of those two, bit for bit; the untouched ones were never
    // changed. Both ways: from the before-images, and recomputed without them.
    let two = EditRaster::build(e, &strokes[..2], &rough_below).unwrap();
    let mut recomputed = one.clone();
    recomputed.clear_history();
    recomputed.undo_to(&strokes, 2, &rough_below).unwrap();
    assert!(recomputed == two, "recomputed undo");
    let mut edited = one.clone();
    edited.undo_to(&strokes, 2, &rough_below).unwrap();
    assert!(edited == two, "undo from the history");
    // Redo: applying them again gives the full raster bit for bit.
    for (k, s) in strokes.iter().enumerate().skip(2) {
        edited.apply(k, s, &rough_below).unwrap();
    }
    assert_eq!(edited, one, "redo");
    // Undo past a terrain-reading stroke without the history: rebuilt, equal to a fresh build.
    let mut rebuilt = one.clone();
    rebuilt.clear_history();
    rebuilt.undo_to(&strokes, 6, &rough_below).unwrap();
    assert!(rebuilt == EditRaster::build(e, &strokes[..6], &rough_below).unwrap(), "undo past smooth");
    // Undo to nothing: no tile left.
    edited.undo_to(&strokes, 0, &rough_below).unwrap();
    assert!(edited.tiles.is_empty());
}

/// Terrain under the edit layer for the tests: a tilt of 5 cm per metre along a fixed direction
/// plus waves of 100 m amplitude and about 1.9 km wavelength (`rough_at`), at every sample.
fn rough_below(q: QuadId) -> Result<Vec<f32>, crate::errors::Failure> {
    terrain_below(q, rough_at)
}

fn rough_at(p: DVec3) -> f64 {
    tilt_at(p) + 100.0 * (p.dot(DVec3::new(0.6, 0.8, 0.0)) / 300.0).sin()
}

fn tilt_at(p: DVec3) -> f64 {
    0.05 * p.dot(DVec3::new(0.0, 0.6, 0.8))
}

fn terrain_below(q: QuadId, height: fn(DVec3) -> f64) -> Result<Vec<f32>, crate::errors::Failure> {
    let e = Ellipsoid::MOON;
    Ok((0..N * N).map(|k| height(sample_point(&e, q, GRID, (k % N) as u32, (k / N) as u32).0) as f32).collect())
}

#[test]
fn flatten_moves_each_sample_by_strength_times_falloff_towards_its_height() {
    // One flatten dab to 500 m over the tilted terrain: δ = s·w·(500 − B) at every sample within
    // the radius (f32 rounding of B and δ); without a height, the target is the terrain under
    // the first point (bilinear between samples: within 1 mm of the tilt there).
    let e = Ellipsoid::MOON;
    let path = [[10.0, 20.0]];
    let tilt = |q| terrain_below(q, tilt_at);
    let to_500 = Stroke { height_m: Some(500.0), ..stroke(Tool::Flatten, 3000.0, 0.8, 10, &path) };
    let r = EditRaster::build(e, std::slice::from_ref(&to_500), &tilt).unwrap();
    let c = centre(&e, 10.0, 20.0);
    let mut inside = 0;
    for (_, _, p, v) in samples(&r) {
        let w = Falloff::Smooth.weight((p - c).length() / 3000.0);
        let expected = 0.8 * w * (500.0 - f64::from(tilt_at(p) as f32));
        assert!((f64::from(v) - expected).abs() <= 1e-4 * expected.abs().max(1.0), "{v} vs {expected}");
        inside += usize::from(w > 0.0);
    }
    assert!(inside > 1000, "{inside} samples in the disc");
    let first = stroke(Tool::Flatten, 3000.0, 1.0, 10, &path);
    let target = super::terrain::Target::of(&e, &first, 10, None);
    assert!(matches!(target, super::terrain::Target::Flatten { height_m } if height_m.is_nan()), "no snapshot");
    let r = EditRaster::build(e, std::slice::from_ref(&first), &tilt).unwrap();
    // At the centre sample nearest the first point w ≈ 1: the terrain there is the target.
    let (p, v) = samples(&r)
        .into_iter()
        .map(|(_, _, p, v)| (p, v))
        .min_by(|a, b| (a.0 - c).length().total_cmp(&(b.0 - c).length()))
        .unwrap();
    let w = Falloff::Smooth.weight((p - c).length() / 3000.0);
    let terrain = tilt_at(p) + f64::from(v);
    assert!(
        ((terrain - tilt_at(c)) - (1.0 - w) * (tilt_at(p) - tilt_at(c))).abs() < 1e-3,
        "{terrain} vs {}",
        tilt_at(c)
    );
}

#[test]
fn ramp_brings_the_terrain_to_the_line_between_its_ends_and_smooth_leaves_a_tilt_alone() {
    // A full-strength ramp over the rough terrain, dabs every 10 % of the radius: along the path
    // (within r/10 of the chord, between 10 % and 90 % of it) the terrain is the line from the
    // height under the first point to the height under the last, to 1 % of the waves' height.
    let e = Ellipsoid::MOON;
    let ramp = Stroke { spacing: 0.1, ..stroke(Tool::Ramp, 3000.0, 1.0, 10, &[[10.0, 20.0], [10.0, 20.3]]) };
    let r = EditRaster::build(e, std::slice::from_ref(&ramp), &rough_below).unwrap();
    let (a, b) = (centre(&e, 10.0, 20.0), centre(&e, 10.0, 20.3));
    let (ha, hb) = (rough_at(a), rough_at(b));
    let mut on_line = 0;
    for (_, _, p, v) in samples(&r) {
        let t = (p - a).dot(b - a) / (b - a).length_squared();
        let off = (p - (a + t * (b - a))).length();
        if (0.1..0.9).contains(&t) && off < 300.0 {
            let terrain = f64::from(rough_at(p) as f32) + f64::from(v);
            let line = ha + (hb - ha) * t;
            assert!((terrain - line).abs() < 1.0, "t {t:.3}: terrain {terrain:.2} vs the line {line:.2}");
            on_line += 1;
        }
    }
    assert!(on_line > 500, "{on_line} samples along the ramp");
    // Smooth over a tilt: the ring mean of a linear function is the function, but this tilt is
    // linear in ECEF, and the surface under the ring (radius h) lies h²/2R below its tangent
    // plane: the mean is lower by at most 0.05·h²/2R (8 mm for h = 750 m on the Moon). δ stays
    // within that, plus 1 mm for the bilinear reading between samples.
    let smooth = stroke(Tool::Smooth, 3000.0, 1.0, 10, &[[10.0, 20.0], [10.02, 20.1]]);
    let r = EditRaster::build(e, std::slice::from_ref(&smooth), &|q| terrain_below(q, tilt_at)).unwrap();
    let (lo, hi) = r.range_m();
    let bound = 0.05 * 750f64.powi(2) / (2.0 * e.a_m()) + 1e-3;
    assert!(lo > -bound && hi < 1e-3, "smooth moved a tilt by {lo} … {hi} m (bound {bound})");
    // Over the waves it takes their amplitude down: the ring mean of a sine of wavenumber k over
    // a ring of radius h is J₀(kh) of it (0.38 here, h = 750 m); after a full-strength stroke the
    // waves' deviation from the tilt near the path is at most 0.6 of what it was.
    let r = EditRaster::build(e, std::slice::from_ref(&smooth), &rough_below).unwrap();
    let (c0, c1) = (centre(&e, 10.0, 20.0), centre(&e, 10.02, 20.1));
    let (mut before, mut after) = (0.0, 0.0);
    for (_, _, p, v) in samples(&r) {
        let t = ((p - c0).dot(c1 - c0) / (c1 - c0).length_squared()).clamp(0.0, 1.0);
        if (p - (c0 + t * (c1 - c0))).length() < 300.0 {
            before += (rough_at(p) - tilt_at(p)).powi(2);
            after += (rough_at(p) + f64::from(v) - tilt_at(p)).powi(2);
        }
    }
    assert!(before > 0.0 && (after / before).sqrt() < 0.6, "rms of the waves {:.3} of before", (after / before).sqrt());
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
        (
            Stroke { tool: Tool::Ramp, strength: 0.5, ..ok.clone() },
            "strokes[1]: path: a ramp runs from the path's first point to its last",
        ),
    ];
    for (bad, expected) in cases {
        let e = EditRaster::build(e, &[ok.clone(), bad], &ellipsoid_below).unwrap_err().to_string();
        assert!(e.contains(expected), "{e}\n  expected: {expected}");
    }
}

#[test]
fn coarse_levels_are_area_means_that_keep_a_small_edits_volume_and_follow_undo() {
    // A 150 m dab at level 12 (3 m samples on the Moon) seen at level 6 (170 m samples): a point
    // sample there would mostly miss it; the area means spread it over the coarse cells with its
    // volume: Σ δ·cell area agrees with the fine level's to 3 % (QSC's cells vary in area by
    // less than that over the few coarse cells involved).
    let e = Ellipsoid::MOON;
    let dab = stroke(Tool::Raise, 150.0, 10.0, 12, &[[10.0, 20.0]]);
    let mut r = EditRaster::build(e, std::slice::from_ref(&dab), &ellipsoid_below).unwrap();
    let volume = |level: u8, values: &[(QuadId, usize, f32)]| {
        let cell = crate::ecm::grid::spacing_m(&e, level).powi(2);
        // Each sample once: a quad's last row and column are its neighbours' first.
        values
            .iter()
            .filter(|(_, k, _)| k % N != N - 1 && k / N != N - 1)
            .map(|(_, _, v)| f64::from(*v) * cell)
            .sum::<f64>()
    };
    let fine: Vec<(QuadId, usize, f32)> = samples(&r).into_iter().map(|(q, k, _, v)| (q, k, v)).collect();
    let coarse_quads: BTreeSet<QuadId> =
        r.tiles.keys().map(|q| q.ancestor_at(6)).flat_map(super::pyramid::with_neighbours).collect();
    let mut coarse = Vec::new();
    for q in &coarse_quads {
        if let Some(g) = r.grid(*q) {
            coarse.extend(g.into_iter().enumerate().map(|(k, v)| (*q, k, v)));
        }
    }
    let (vf, vc) = (volume(12, &fine), volume(6, &coarse));
    assert!(vf > 0.0 && ((vc - vf) / vf).abs() < 0.03, "volume {vc:.0} m³ at level 6, {vf:.0} m³ at level 12");
    let peak = coarse.iter().map(|c| c.2).fold(0f32, f32::max);
    assert!(peak > 0.01, "the dab shows at level 6: {peak} m");
    // The same means whichever order they are asked for in (a fresh raster, coarsest first).
    let fresh = EditRaster::build(e, std::slice::from_ref(&dab), &ellipsoid_below).unwrap();
    for l in (0..12).rev().chain(0..12) {
        let q = r.tiles.keys().next().unwrap().ancestor_at(l);
        assert_eq!(fresh.grid(q), r.grid(q), "level {l}");
    }
    // Undone, nothing is left at any level; the means follow the tiles.
    r.undo_to(std::slice::from_ref(&dab), 0, &ellipsoid_below).unwrap();
    for q in &coarse_quads {
        assert!(r.grid(*q).is_none(), "{q} after undo");
    }
}

#[test]
fn coarse_tiles_made_ahead_equal_those_made_when_asked_for_bit_for_bit() {
    let e = Ellipsoid::MOON;
    let strokes = vec![
        stroke(Tool::Raise, 4000.0, 30.0, 9, &[[10.0, 20.0], [10.05, 20.1], [10.0, 20.2]]),
        stroke(Tool::Lower, 2500.0, 12.0, 9, &[[10.3, 20.5]]),
    ];
    let cold = EditRaster::build(e, &strokes, &rough_below).unwrap();
    let warm = cold.clone();
    warm.warm();
    let quads = cold.pyramid.coarse_quads();
    assert!(quads.iter().any(|q| q.level == 0) && quads.iter().any(|q| q.level == 8), "{} coarse quads", quads.len());
    // Asked for from the coarsest down (the reverse of how `warm` reaches them), one by one.
    for q in quads.iter().rev() {
        let (a, b) = (cold.grid(*q), warm.grid(*q));
        assert_eq!(
            a.map(|v| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>()),
            b.map(|v| v.iter().map(|x| x.to_bits()).collect()),
            "{q:?}"
        );
    }
}
