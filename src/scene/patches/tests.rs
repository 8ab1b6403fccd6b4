//! The patch selection's tests: strides by error, morph weights, edge owners, skirts.

use super::*;
use crate::ecm::{CubeProjection, Face, QuadId};
use crate::geodesy::Ellipsoid;
use crate::project::CameraSpec;

fn params(t: f64) -> SelectParams {
    SelectParams { threshold_px: t, max_quads: 128, width: 640, height: 512, occluder_m: (1_737_000.0, 1_737_000.0) }
}

/// A quad's patch boxes, and errors of a smooth surface: δ = 5·s² m at stride s (a
/// parabola's), 0 at stride 1.
fn quad_patches(quad: QuadId) -> (f64, Vec<StrideBoxes>, Vec<[f64; STRIDES.len()]>) {
    let g = QuadGeometry::compute(&Ellipsoid::MOON, CubeProjection::Qsc, quad, 17);
    let q = g.corners_ecef;
    let edge = (q[1] - q[0]).length().max((q[2] - q[0]).length());
    let boxes = patch_bounds(&g, &[(-100.0, 100.0); 64], 1.0);
    let delta = STRIDES.map(|s| if s == 1 { 0.0 } else { 5.0 * f64::from(s * s) });
    (edge, boxes.into_iter().map(|b| [b; STRIDES.len()]).collect(), vec![effective_errors(&delta); 64])
}

#[test]
fn strides_are_the_coarsest_whose_error_projects_under_the_pixel_error() {
    // δ̂ = 0, 1, 2, 4, 8, 16 m: seen from 10 km with f = 1000 px, 0.1 px a metre.
    let errors = effective_errors(&[0.0, 1.0, 1.5, 4.0, 4.0, 16.0]);
    assert_eq!(errors, [0.0, 1.0, 2.0, 4.0, 8.0, 16.0], "monotone and at least doubling");
    assert_eq!(stride_for(&errors, 10_000.0, 1000.0, 1.0), 16, "1.6 px > 1/1.1 at 32");
    assert_eq!(stride_for(&errors, 10_000.0, 1000.0, 0.5), 8);
    assert_eq!(stride_for(&errors, 10.0, 1000.0, 1.0), 1, "already too coarse: the finest");
    assert_eq!(stride_for(&[0.0; 6], 1.0, 1000.0, 1.0), 32, "a plane: one cell a patch");
    // What a patch drawn there shows is within τ (with the morph toward the coarser mesh).
    let reach = morph_reach(errors[5], 1000.0, 1.0);
    let e = drawn_error_px(&errors, 16, reach, 0.0, 10_000.0, 11_000.0, 1000.0);
    assert!(e <= 1.0 && e > 0.5, "{e}");
    assert_eq!(triangles_at(1, ALL_SIDES), 2 * 32 * 32 + 8 * 32);
    assert_eq!(triangles_at(32, ALL_SIDES), 2 + 8);
    assert_eq!(triangles_at(1, SOUTH | WEST), 2 * 32 * 32 + 4 * 32);
}

#[test]
fn a_vertex_is_within_the_pixel_error_all_through_the_morph_band() {
    // Between the band's ends a vertex blends the two meshes; its error seen at its distance
    // never exceeds τ, whatever the errors' ratio (≥ 2 by construction).
    for (fine, coarse) in [(1.0, 2.0), (1.0, 4.0), (0.1, 8.0), (0.0, 1.0)] {
        let mut errors = [0.0; 6];
        (errors[2], errors[3]) = (fine, coarse);
        let reach = morph_reach(coarse, 800.0, 1.0);
        for k in 1..400 {
            let d = reach / MORPH_BAND_END * (1.0 + f64::from(k) / 100.0);
            let e = drawn_error_px(&errors, 4, reach, 0.0, d, d, 800.0);
            let at_stride = fine * 800.0 / d;
            // Where stride 4 is taken at all (its own error within τ / 1.1).
            if at_stride <= 1.0 / MORPH_BAND_START {
                assert!(e <= 1.0 + 1e-9, "{fine}/{coarse} at {d}: {e}");
            }
        }
    }
}

#[test]
fn exactly_one_of_two_neighbours_owns_their_edge_and_the_other_stands_on_it_sideways() {
    let key = |stride: u32, r: f32, u: f32| (stride, r.to_bits(), u.to_bits());
    let (fine, coarse) = (key(1, 10.0, 20.0), key(4, 10.0, 20.0));
    assert!(owns_edge(coarse, 0, fine, 1) && !owns_edge(fine, 1, coarse, 0));
    // The same stride: none where they morph alike, the earlier where they do not.
    assert!(!owns_edge(fine, 0, fine, 1) && !owns_edge(fine, 1, fine, 0));
    let other = key(1, 30.0, 20.0);
    assert!(owns_edge(other, 0, fine, 1) && !owns_edge(fine, 1, other, 0));
    // A stride-1 patch at (32, 0) whose west neighbour (origin (0, 0)) is drawn every 4
    // samples: its vertex (0, 3) stands on that edge between samples (32, 0) and (32, 4).
    let owner = PatchMorph { stride: 4, reach_m: f64::INFINITY, reach_up_m: f64::INFINITY, origin: (0, 0) };
    let patch = PatchMorph { stride: 1, origin: (32, 0), ..owner };
    let w = vertex_weights(patch, (0, 3), [None, None, None, Some(owner)], |_, _| 1.0);
    assert_eq!(w.own, vec![((32, 3), 1.0)]);
    assert_eq!(w.edge, Some(vec![((32, 0), 0.25), ((32, 4), 0.75)]));
    // Off that side, and at a corner, it stands where its own morph puts it.
    for (a, b) in [(1, 3), (0, 0), (0, 32)] {
        let w = vertex_weights(patch, (a, b), [None, None, None, Some(owner)], |_, _| 1.0);
        assert_eq!(w.edge, None, "({a}, {b})");
    }
    // Moved across to the edge, at its own height along the normal.
    let (edge, up) = (glam::DVec3::new(1.0, 2.0, 3.0), glam::DVec3::Z);
    let own = edge + glam::DVec3::new(0.5, -0.25, 0.0) + up * 2.0;
    assert_eq!(stand_on_edge(own, Some(edge), up), edge + up * 2.0);
    assert_eq!(stand_on_edge(own, None, up), own);
}

#[test]
fn a_patch_fully_morphed_draws_what_the_coarser_patch_draws_while_that_one_morphs() {
    // Heights of a rough field, distances growing across the patch so that the stride-4
    // patch is fully morphed (ρ ≤ 1.1) while the stride-8 patch it replaces morphs toward 16
    // by a factor that varies from vertex to vertex.
    let height = |i: u32, j: u32| ((i * 7919 + j * 104_729) % 1000) as f64 * 0.37;
    let distance = |i: u32, j: u32| 1000.0 + 10.0 * f64::from(i - 64) + 7.0 * f64::from(j - 96);
    let drawn = |w: Vec<((u32, u32), f64)>| w.iter().map(|((i, j), w)| height(*i, *j) * w).sum::<f64>();
    let origin = (64, 96);
    let (reach, reach_up) = (500.0, 1.35 * 1300.0);
    let mut partly = 0;
    for b in 0..=8u32 {
        for a in 0..=8u32 {
            let weights = morph_weights(4, reach, reach_up, origin, (a, b), distance);
            assert!((weights.iter().map(|w| w.1).sum::<f64>() - 1.0).abs() < 1e-12);
            assert!(weights.iter().all(|w| w.1 >= 0.0), "{weights:?}");
            let fine = drawn(weights);
            // The stride-8 patch (its own coarser reach infinite: it morphs toward 16 alone).
            let coarse_vertex =
                |a: u32, b: u32| drawn(morph_weights(8, reach_up, f64::INFINITY, origin, (a, b), distance));
            let coarse = match (a % 2, b % 2) {
                (0, 0) => coarse_vertex(a / 2, b / 2),
                (1, 0) => 0.5 * (coarse_vertex(a / 2, b / 2) + coarse_vertex(a / 2 + 1, b / 2)),
                (0, 1) => 0.5 * (coarse_vertex(a / 2, b / 2) + coarse_vertex(a / 2, b / 2 + 1)),
                _ => 0.5 * (coarse_vertex(a / 2, b / 2) + coarse_vertex(a / 2 + 1, b / 2 + 1)),
            };
            assert!((fine - coarse).abs() < 1e-9, "({a},{b}): {fine} vs {coarse}");
            let (i, j) = (origin.0 + 4 * a, origin.1 + 4 * b);
            let m2 = morph_factor(8, reach_up, distance(i, j));
            partly += usize::from(m2 > 0.0 && m2 < 1.0);
        }
    }
    assert!(partly > 10, "the coarser patch morphs partly at {partly} vertices");
    // Unmorphed, a vertex is its own sample.
    assert_eq!(morph_weights(4, 100.0, 200.0, origin, (3, 5), |_, _| 10.0), vec![((76, 116), 1.0)]);
}

#[test]
fn patch_boxes_tile_the_quad_box() {
    let quad = QuadId::root(Face::Front).children().unwrap()[3];
    let g = QuadGeometry::compute(&Ellipsoid::MOON, CubeProjection::Qsc, quad, 17);
    let whole = QuadBounds::compute(&g, -100.0, 100.0);
    let patches = patch_bounds(&g, &[(-100.0, 100.0); 64], 0.0);
    assert_eq!(patches.len(), 64);
    // Every sample of the coarse geometry is in the patch boxes that share it, and every
    // patch box is much smaller than the quad's.
    for (n, b) in patches.iter().enumerate() {
        assert!(b.radius_m() < whole.radius_m() / 4.0, "patch {n}: {} vs {}", b.radius_m(), whole.radius_m());
        let (px, py) = (n as u32 % 8, n as u32 / 8);
        for (i, j) in [(2 * px, 2 * py), (2 * px + 2, 2 * py + 2), (2 * px + 1, 2 * py + 1)] {
            let (s, t) = crate::ecm::geometry::sample_st(17, i, j);
            let p = crate::ecm::geometry::interpolate_f64(g.split, &g.corners_ecef, s, t)
                + g.maps_at(i, j).map_or(glam::DVec3::ZERO, |m| m[0].as_dvec3());
            assert!(b.contains(p), "patch {n} lacks its sample ({i},{j})");
        }
    }
}

#[test]
fn a_quad_larger_than_the_view_draws_only_the_patches_that_show_and_coarser_far_away() {
    // Looking obliquely at a level-3 quad from 20 km: part of it is off screen.
    let quad = QuadId::root(Face::Front).children().unwrap()[0].children().unwrap()[0].children().unwrap()[0];
    let (_, bounds, errors) = quad_patches(quad);
    let corner = crate::ecm::geometry::quad_corners(&Ellipsoid::MOON, CubeProjection::Qsc, quad).0[0];
    let g = crate::geodesy::geodetic_from_ecef(&Ellipsoid::MOON, corner);
    let spec = CameraSpec {
        lat: g.lat_rad.to_degrees(),
        lon: g.lon_rad.to_degrees(),
        alt: 20_000.0,
        heading: 45.0,
        pitch: -20.0,
        fov: 60.0,
    };
    let camera = Camera::new(&Ellipsoid::MOON, spec, 1.0);
    let quads = [QuadPatches { bounds: &bounds, errors_m: &errors }];
    let full = select_patches(&camera, &params(1.5), &quads, false, true, 1.0);
    assert!(full.patches.iter().all(|p| !p.morphs), "whole quads do not morph");
    assert_eq!(full.patches.len(), 64);
    // Whole: skirts only round the quad's edge (32 patch sides).
    assert_eq!(full.triangles(), 64 * triangles_at(1, 0) + 32 * 2 * 32);
    let corner = full.patches.iter().find(|p| (p.px, p.py) == (0, 0)).unwrap();
    assert_eq!(corner.skirts, SOUTH | WEST);
    assert!(full.patches.iter().any(|p| (p.px, p.py) == (3, 4) && p.skirts == 0));
    let near = select_patches(&camera, &params(1.5), &quads, true, true, 1.0);
    assert!(near.culled_frustum > 0, "{near:?}");
    assert!(near.triangles() < full.triangles(), "{} of {}", near.triangles(), full.triangles());
    assert!(near.max_error_px <= 1.0, "{}", near.max_error_px);
    // From 500 km, the parabola's error allows coarser strides, far ones coarser still.
    let camera = Camera::new(&Ellipsoid::MOON, CameraSpec { alt: 500_000.0, pitch: -40.0, ..spec }, 1.0);
    let adaptive = select_patches(&camera, &params(1.5), &quads, true, true, 1.0);
    assert!(adaptive.triangles() * 4 < full.triangles() * 3, "{} of {}", adaptive.triangles(), full.triangles());
    assert!(adaptive.max_error_px <= 1.0, "{}", adaptive.max_error_px);
    let strides: std::collections::BTreeSet<u32> = adaptive.patches.iter().map(|p| p.stride).collect();
    assert!(strides.len() >= 2, "near and far patches at different strides: {strides:?}");
    // Each drawn patch's stride keeps its error at its nearest point under τ / 1.1, and the
    // next coarser one would not.
    let focal = camera.focal_px(512);
    for p in &adaptive.patches {
        let n = (p.py * 8 + p.px) as usize;
        let d = bounds[n][0].distance_m(camera.position).max(camera.near_m);
        let k = stride_index(p.stride);
        assert!(p.stride == 1 || errors[n][k] * focal / d <= 1.0 / 1.1, "{p:?}");
        assert!(p.stride == 32 || errors[n][k + 1] * focal / d > 1.0 / 1.1, "{p:?} could be coarser");
        assert!(f64::from(p.error_px) <= 1.0 + 1e-6, "{p:?}");
    }
    // Sorted into one run per stride.
    let groups = adaptive.groups();
    let kinds: std::collections::BTreeSet<(u32, u8, bool)> = groups.iter().map(|g| (g.0, g.1, g.2)).collect();
    assert_eq!(kinds.len(), groups.len(), "one run per stride, set of skirts and morphing");
    assert_eq!(groups.iter().map(|g| g.4 as usize).sum::<usize>(), adaptive.patches.len());
    // A patch that does not morph has no point inside the band: its farthest corner's
    // factor is 0, so every vertex's is.
    for p in adaptive.patches.iter().filter(|p| !p.morphs) {
        let n = (p.py * 8 + p.px) as usize;
        let b = bounds[n][stride_index(p.stride)];
        let far = b.corners().iter().map(|c| (*c - camera.position).length()).fold(0.0, f64::max);
        let k = stride_index(p.stride);
        let reach = if p.stride < 32 { morph_reach(errors[n][k + 1], focal, 1.0) } else { 0.0 };
        assert_eq!(morph_factor(p.stride, reach, far), 0.0, "{p:?}");
    }
    // A side without a skirt has a neighbour in the quad drawn at the same stride.
    let at = |px: i32, py: i32| adaptive.patches.iter().find(|p| (p.px as i32, p.py as i32) == (px, py));
    let mut bare = 0;
    for p in &adaptive.patches {
        for (side, (dx, dy)) in [(SOUTH, (0, -1)), (EAST, (1, 0)), (NORTH, (0, 1)), (WEST, (-1, 0))] {
            if p.skirts & side == 0 {
                let n = at(p.px as i32 + dx, p.py as i32 + dy);
                assert_eq!(n.map(morph_key), Some(morph_key(p)), "{p:?}: side {side} bare");
                bare += 1;
            }
        }
    }
    assert!(bare > 0, "some sides between equal strides and reaches go without a skirt");
}
