use super::*;
use crate::ecm::{Edge, Face};

const QSC: CubeProjection = CubeProjection::Qsc;
const BODIES: [Ellipsoid; 3] = [Ellipsoid::WGS84, Ellipsoid::MOON, Ellipsoid::MARS];

/// 2⁻²⁴: the relative rounding error of an f32.
const F32_EPS: f64 = 1.0 / 16_777_216.0;

/// The camera's geodetic height clamped to a height range: the renderer's reference height.
fn reference_height(e: &Ellipsoid, camera: DVec3, range: (f64, f64)) -> f64 {
    geodesy::geodetic_from_ecef(e, camera).height_m.clamp(range.0, range.1)
}

/// Face points where QSC or the ellipsoid is at its least regular: cube corners, edge midpoints,
/// face centres (the poles among them), a point just off the diagonal near a centre, ±180°.
fn stress_points() -> Vec<FacePoint> {
    let mut points = Vec::new();
    for face in Face::ALL {
        for (x, y) in [
            (0.0, 0.0),
            (1.0, 1.0),
            (-1.0, 1.0),
            (-1.0, -1.0),
            (1.0, -1.0),
            (1.0, 0.0),
            (0.0, 1.0),
            (-1.0, 0.0),
            (0.0, -1.0),
            (1e-9, 1e-9 + 1e-15),
            (0.5, 0.5),
            (-0.25, 0.25),
        ] {
            points.push(FacePoint { face, x, y });
        }
    }
    points
}

#[test]
fn maps_are_finite_on_every_quad_the_stress_points_touch_on_every_level_and_body() {
    // Every level 0..=30, every preset body, the quad holding each stress point and its four
    // neighbours (across face edges where the point is on one): no NaN, no infinity, unit normals,
    // and the corners' displacement exactly zero.
    let mut quads = std::collections::HashSet::new();
    for p in stress_points() {
        for level in 0..=crate::ecm::MAX_LEVEL {
            let q = QuadId::containing(p, level).unwrap();
            quads.insert(q);
            for edge in Edge::ALL {
                quads.insert(q.neighbour(edge).quad);
            }
        }
    }
    assert!(quads.len() > 5000, "{}", quads.len());
    for e in BODIES {
        let bad: Vec<String> = quads
            .iter()
            .filter_map(|&quad| {
                let maps = StaticMaps::compute(&e, QSC, quad, 5);
                let finite =
                    maps.displacement_m.iter().chain(&maps.normal).chain(&maps.normal_delta).all(|v| v.is_finite());
                let unit = maps.normal.iter().all(|n| (n.length() - 1.0).abs() < 1e-6);
                let corners = [0usize, 4, 20, 24].iter().all(|&k| maps.displacement_m[k] == Vec3::ZERO);
                (!(finite && unit && corners)).then(|| format!("{quad}"))
            })
            .collect();
        assert!(bad.is_empty(), "{}: bad maps for {bad:?}", e.name());
    }
}

#[test]
fn shared_maps_read_back_what_a_direct_computation_gives() {
    // Every face, both halves of each axis, the diagonals, level 30: the map read through the
    // symmetry equals the map computed for the quad itself to f32 rounding.
    let e = Ellipsoid::MARS;
    for face in Face::ALL {
        for (level, x, y) in [(1u8, 1u32, 0u32), (4, 12, 3), (4, 3, 12), (5, 20, 20), (5, 7, 24), (13, 8000, 100)]
            .into_iter()
            .chain([(30u8, (1u32 << 30) - 1, 5u32)])
        {
            let quad = QuadId { face, level, x, y };
            let shared = QuadGeometry::compute(&e, QSC, quad, 9);
            let direct = StaticMaps::compute(&e, QSC, quad, 9);
            for j in 0..9 {
                for i in 0..9 {
                    let k = (j * 9 + i) as usize;
                    let pairs = [
                        (shared.displacement(i, j).unwrap(), direct.displacement_m[k]),
                        (shared.normal(i, j).unwrap(), direct.normal[k]),
                        (shared.normal_delta(i, j).unwrap(), direct.normal_delta[k]),
                    ];
                    for (a, b) in pairs {
                        let tolerance = 2.0 * F32_EPS as f32 * b.length().max(a.length()) + 1e-12;
                        assert!((a - b).length() <= tolerance, "{quad} ({i},{j}): shared {a} direct {b}");
                    }
                }
            }
        }
    }
}

#[test]
fn the_cache_holds_one_map_per_canonical_quad() {
    let e = Ellipsoid::WGS84;
    let cache = MapCache::new();
    for face in Face::ALL {
        for x in 0..4 {
            for y in 0..4 {
                QuadGeometry::cached(&e, QSC, QuadId { face, level: 2, x, y }, 5, &cache, None);
            }
        }
    }
    assert_eq!(cache.len() as u128, distinct_maps_per_level(2).1);
    assert_eq!(distinct_maps_per_level(2), (96, 7));
}

#[test]
fn the_diagonal_split_restores_quadratic_convergence_except_at_the_face_centre() {
    // A bilinear patch across the face diagonal misses QSC's kink by O(L): one level down only
    // halves the displacement. Split along the diagonal it quarters, like an ordinary quad. At the
    // face centre QSC is not differentiable and the displacement halves whatever the split.
    let e = Ellipsoid::MOON;
    let diag = |level: u8| {
        quad_extremes(&e, QSC, QuadId::new(Face::Front, level, 3 << (level - 2), 3 << (level - 2)).unwrap(), 17)
    };
    let (d8, d9) = (diag(8), diag(9));
    let bilinear = d8.displacement_bilinear_m / d9.displacement_bilinear_m;
    let split = d8.displacement_m / d9.displacement_m;
    assert!((bilinear - 2.0).abs() < 0.1, "bilinear ratio {bilinear}");
    assert!((split - 4.0).abs() < 0.2, "split ratio {split}");
    let centre = |level: u8| {
        let m = 1u32 << (level - 1);
        quad_extremes(&e, QSC, QuadId::new(Face::Front, level, m, m + 1).unwrap(), 17).displacement_m
    };
    let ratio = centre(8) / centre(9);
    assert!((ratio - 2.0).abs() < 0.05, "centre ratio {ratio}");
}

#[test]
fn neighbours_agree_on_their_shared_edge_across_every_face_edge_to_f32_rounding() {
    // For each face and edge, a quad on that edge and its neighbour on the next face: the f32
    // positions of their common edge samples, for one camera near the edge and one height field,
    // agree to the rounding of the camera-relative position: two independent roundings, on
    // average within 1.5× the f32 limit.
    let e = Ellipsoid::WGS84;
    let n = 17u32;
    let height = |p: DVec3| 3000.0 + 1000.0 * (p.x * 1e-5).sin() * (p.y * 1e-5).cos();
    for face in Face::ALL {
        for edge in Edge::ALL {
            let level = 9u8;
            let last = (1u32 << level) - 1;
            let (x, y) = match edge {
                Edge::East => (last, 77),
                Edge::North => (300, last),
                Edge::West => (0, 411),
                Edge::South => (5, 0),
            };
            let a = QuadGeometry::compute(&e, QSC, QuadId { face, level, x, y }, n);
            let b = QuadGeometry::compute(&e, QSC, a.quad.neighbour(edge).quad, n);
            let edge_samples = |g: &QuadGeometry| -> Vec<(u32, u32, DVec3)> {
                (0..n)
                    .flat_map(|j| (0..n).map(move |i| (i, j)))
                    .filter(|&(i, j)| i == 0 || j == 0 || i == n - 1 || j == n - 1)
                    .map(|(i, j)| (i, j, g.exact_position(&e, QSC, DVec3::ZERO, i, j, 0.0)))
                    .collect()
            };
            let (ea, eb) = (edge_samples(&a), edge_samples(&b));
            let mid = ea[ea.len() / 2].2;
            let camera = mid + mid.normalize() * 20_000.0;
            let h0 = reference_height(&e, camera, (2000.0, 4000.0));
            let (fa, fb) = (a.frame(camera, h0), b.frame(camera, h0));
            let (mut shared, mut sum_ratio) = (0, 0.0);
            for &(i, j, p) in &ea {
                let Some(&(bi, bj, _)) = eb.iter().find(|(_, _, q)| (*q - p).length() < 1e-6) else { continue };
                shared += 1;
                let h = height(p) as f32;
                let pa = a.position_f32(&fa, i, j, h).as_dvec3();
                let pb = b.position_f32(&fb, bi, bj, h).as_dvec3();
                // Each side is within 2× the limit of the exact position (two roundings of a
                // camera-sized value: the anchor's cast and the final sum), so they agree within 4×.
                let ratio = (pa - pb).length() / ((p - camera).length() * F32_EPS);
                assert!(ratio <= 4.0, "{face} {edge:?} ({i},{j}): {pa} vs {pb}: {ratio} × the limit");
                sum_ratio += ratio;
            }
            let mean = sum_ratio / f64::from(shared);
            assert!(mean <= 1.5, "{face} {edge:?}: mean disagreement {mean} × the limit");
            assert_eq!(shared, n, "{face} {edge:?}");
        }
    }
}

/// The largest error of the f32 path over a 9×9 subgrid of a quad's samples (and the sample
/// under the camera), as a ratio to the f32 limit |P − C|·2⁻²⁴ and in metres.
fn worst_ratio(
    e: &Ellipsoid,
    g: &QuadGeometry,
    camera: DVec3,
    h0: f64,
    heights: impl Fn(u32, u32) -> f64,
) -> (f64, f64) {
    let frame = g.frame(camera, h0);
    let n = g.samples;
    let mut worst = (0.0f64, 0.0f64);
    let subgrid: Vec<u32> = (0..9).map(|k| k * (n - 1) / 8).collect();
    for &j in &subgrid {
        for &i in &subgrid {
            let h = heights(i, j) as f32;
            let exact = g.exact_position(e, QSC, camera, i, j, f64::from(h));
            let ours = g.position_f32(&frame, i, j, h).as_dvec3();
            let err = (ours - exact).length();
            worst = (worst.0.max(err / (exact.length() * F32_EPS)), worst.1.max(err));
        }
    }
    worst
}

#[test]
fn a_camera_one_metre_above_a_high_peak_is_within_twice_the_f32_limit_with_the_reference_height() {
    // Earth, a 9 000 m peak, a level-26 quad (15 cm) and the camera 1 m above its centre sample.
    // With the paper's formulation (h₀ = 0), P′ and h·nₑ cancel and the error is ≈ 2⁻²⁴·9 000 m,
    // thousands of times the limit; folding h₀ into the f64 corners removes it.
    let e = Ellipsoid::WGS84;
    for face in [Face::Front, Face::Top, Face::Left] {
        let quad = QuadId::containing(FacePoint { face, x: 0.3, y: -0.6 }, 26).unwrap();
        let g = QuadGeometry::compute(&e, QSC, quad, 33);
        let peak = 9_000.0;
        let heights = |i: u32, j: u32| peak - 0.01 * f64::from(i) - 0.02 * f64::from(j);
        let foot = g.exact_position(&e, QSC, DVec3::ZERO, 16, 16, heights(16, 16));
        let camera = foot + g.normal(16, 16).unwrap().as_dvec3() * 1.0;
        let h0 = reference_height(&e, camera, (peak - 1.0, peak));
        let (ours, _) = worst_ratio(&e, &g, camera, h0, heights);
        assert!(ours <= 2.0, "{face}: ECM with reference height: {ours} × the f32 limit");
        let (paper, paper_m) = worst_ratio(&e, &g, camera, 0.0, heights);
        assert!(paper > 100.0 && paper_m > 1e-5, "{face}: paper's formulation: {paper} × ({paper_m} m)");
    }
}

#[test]
fn extreme_cameras_and_heights_stay_finite_and_near_the_limit() {
    // Cameras 1 mm above the surface and 10⁹ m away, heights of −11 km and +9 km, on quads at the
    // stress points down to level 30. Beyond level 30 a quad is wider than a 1 mm camera distance:
    // the corner cast then costs 2⁻²⁴ of the corners' distance, which bounds the error instead.
    let e = Ellipsoid::WGS84;
    for p in stress_points().into_iter().step_by(5) {
        for level in [0u8, 7, 18, 24, 30] {
            let g = QuadGeometry::compute(&e, QSC, QuadId::containing(p, level).unwrap(), 17);
            for h in [-11_000.0, 9_000.0] {
                let foot = g.exact_position(&e, QSC, DVec3::ZERO, 8, 8, h);
                let up = g.normal(8, 8).unwrap().as_dvec3();
                for distance in [1e-3, 1e9] {
                    let camera = foot + up * distance;
                    let h0 = reference_height(&e, camera, (h, h));
                    let frame = g.frame(camera, h0);
                    let corner_reach = frame.corners.iter().map(|c| f64::from(c.length())).fold(0.0, f64::max);
                    for (i, j) in [(8u32, 8u32), (0, 0), (16, 3), (5, 16)] {
                        let exact = g.exact_position(&e, QSC, camera, i, j, h);
                        let ours = g.position_f32(&frame, i, j, h as f32).as_dvec3();
                        assert!(ours.is_finite(), "{p:?} level {level}");
                        let err = (ours - exact).length();
                        let limit = exact.length() * F32_EPS;
                        let bound = 2.0 * limit + 4.0 * corner_reach * F32_EPS;
                        assert!(err <= bound, "{p:?} L{level} h {h} d {distance}: err {err} bound {bound}");
                    }
                }
            }
        }
    }
}

#[test]
fn the_flat_rule_only_drops_maps_that_are_below_tolerance() {
    let e = Ellipsoid::MOON;
    let rule = FlatRule::fit(&e, QSC, FlatRule::DEFAULT_TOLERANCE_M, HeightRange::for_body(&e));
    assert!(rule.cone_m > 0.0 && rule.curvature_m > 0.0, "{rule:?}");
    let first = rule.first_flat_level().expect("some level is flat");
    let levels = [first - 1, first, first + 1, first + 3, 24, 30];
    for &level in &levels {
        let row = &cutoff_table(&e, QSC, &rule, level, 9)[level as usize];
        assert!(row.max_flat_error_m < row.tolerance_m, "level {level}: {row:?}");
    }
    // Capped at a quarter of the f32 limit where each level is drawn (1 000 km for level 0):
    // the tolerance shrinks with the level, flat quads start later, and the rule still holds.
    let capped = rule.with_draw_limit(0.25, 1e6);
    assert!(capped.level_tolerance_m(25) < capped.level_tolerance_m(20) && capped.level_tolerance_m(0) == 1e-4);
    let capped_first = capped.first_flat_level().expect("deep levels are flat");
    assert!(capped_first > first, "{capped_first} vs {first}");
    let row = &cutoff_table(&e, QSC, &capped, capped_first, 9)[capped_first as usize];
    assert!(row.max_flat_error_m < row.tolerance_m, "{row:?}");
    assert!(rule.flat_ring(first - 1).is_none());
    assert!(rule.flat_share(24) > 0.99 && rule.flat_share(first) < rule.flat_share(first + 1));
    // The centre quads never drop their maps.
    assert!(!rule.is_flat(QuadId::new(Face::Top, 30, 1 << 29, 1 << 29).unwrap()));
    // A flat quad's f32 position is within tolerance plus the f32 limit of the exact one.
    let quad = QuadId::containing(FacePoint { face: Face::Right, x: 0.7, y: 0.2 }, first + 2).unwrap();
    assert!(rule.is_flat(quad));
    let cache = MapCache::new();
    let g = QuadGeometry::cached(&e, QSC, quad, 33, &cache, Some(&rule));
    assert!(g.maps.is_none() && cache.is_empty());
    let camera = g.exact_position(&e, QSC, DVec3::ZERO, 0, 0, 3_010.0);
    let (_, err) = worst_ratio(&e, &g, camera, 3_000.0, |i, j| 3_000.0 + 0.01 * f64::from(i + j));
    assert!(err < rule.tolerance_m + 1e-5, "flat path error {err} m");
}

#[test]
fn bounds_hold_every_vertex_for_every_height_in_range_and_are_tight() {
    let e = Ellipsoid::WGS84;
    for quad in [
        QuadId::new(Face::Top, 0, 0, 0).unwrap(),
        QuadId::new(Face::Front, 5, 16, 16).unwrap(),
        QuadId::new(Face::Bottom, 12, 4095, 0).unwrap(),
    ] {
        let g = QuadGeometry::compute(&e, QSC, quad, 17);
        let b = QuadBounds::compute(&g, -500.0, 4_000.0);
        for j in 0..17 {
            for i in 0..17 {
                for h in [-500.0, 1234.5, 4_000.0] {
                    let p = g.exact_position(&e, QSC, DVec3::ZERO, i, j, h);
                    assert!(b.contains(p), "{quad} ({i},{j}) h {h}");
                    assert_eq!(b.distance_m(p), 0.0);
                }
            }
        }
        // Tight: the box is no thicker than the height range plus the surface's sagitta.
        let sagitta = g.max_displacement_m() as f64;
        assert!(2.0 * b.half_extents_m.z < 4_500.0 + 2.0 * sagitta + 1.0, "{b:?}");
        let above = g.exact_position(&e, QSC, DVec3::ZERO, 8, 8, 10_000.0);
        assert!(!b.contains(above) && b.distance_m(above) > 5_000.0);
    }
}

#[test]
fn the_exact_position_is_the_geodetic_point_at_height_h() {
    // S + h·nₑ for a sample equals geodetic → ECEF of the sample's latitude and longitude at h
    // (the conversion tested against GeographicLib's CartConvert in tests/references.rs).
    for e in BODIES {
        let quad = QuadId::new(Face::Bottom, 7, 100, 3).unwrap();
        let g = QuadGeometry::compute(&e, QSC, quad, 5);
        for (i, j, h) in [(0u32, 0u32, -11_000.0), (2, 3, 0.0), (4, 4, 8_848.0)] {
            let (x, y) = quad.sample_xy(5, i, j);
            let (lat_rad, lon_rad) = QSC.geodetic_from_face_point(&e, FacePoint { face: quad.face, x, y }).unwrap();
            let reference = geodesy::ecef_from_geodetic(&e, geodesy::Geodetic { lat_rad, lon_rad, height_m: h });
            let ours = g.exact_position(&e, QSC, DVec3::ZERO, i, j, h);
            assert!((ours - reference).length() < 2e-8, "{} ({i},{j}): {ours} vs {reference}", e.name());
        }
    }
}
