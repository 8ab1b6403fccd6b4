//! Fading a dataset in from its own no-data edge (`feather_edge_m`): per sample the distance on
//! the surface to the dataset's nearest no-data sample, d, and the edge mask smoothstep(d / F).
//!
//! The distance is measured on a fixed level of the dataset's pyramid, the *edge level* L_F: the
//! finest level whose quads are at least F across, so that one quad's 8 neighbours hold every
//! point within F of it. A quad at level ℓ gets its distances from the field computed at level
//! e = min(ℓ, L_F, finest) for its ancestor A at level e (bilinearly resampled below it), over A
//! and its neighbours (across face edges and cube corners) and capped at the edge level's
//! quad width W(L_F) ≥ F. So a sample's distance depends on where it is, the dataset and F, not
//! on the quad it is composed in: neighbouring quads agree on their shared edge and the mask
//! has no seam.
//!
//! The field is a *dead-reckoning* distance transform (Grevera 2004, "The dead reckoning signed
//! distance transform"): two raster passes over the 3 × 3-quad neighbourhood propagate each
//! sample's nearest no-data sample from its 8 neighbours, always measuring the true distance
//! between the two ECEF points (a chord: shorter than the geodesic by d³/24R², 0.2 mm at 12 km
//! on Earth). The edge itself lies somewhere between the last sample with data and the first
//! without, so d is known to half a sample spacing of level e: the spacing of L_F is under F/64,
//! which bounds the mask's error by 1.5 · 1/128 < 1.2 % (smoothstep's slope is at most 1.5).

use glam::DVec3;
use rayon::prelude::*;
use std::collections::HashMap;

use crate::ecm::grid::{GRID, face_xy, fold_sample, quad_of_sample};
use crate::ecm::{CubeProjection, FacePoint, MAX_LEVEL, QuadId};
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};

/// Samples along a quad edge.
const N: usize = GRID as usize;
/// Samples of margin around the centre quad: one quad on every side.
const MARGIN: i64 = (GRID - 1) as i64;
/// Samples along the neighbourhood's edge.
const W: usize = N + 2 * MARGIN as usize;

/// The least distance across a quad at `level` (between opposite edges), metres, for a body of
/// semi-major axis `a_m`: half the edge of the equal-area quad, a·√(2π/3)/2^level. QSC stretches
/// quads near the cube corners by up to ~1.3× one way and squeezes them the other; the half
/// leaves room for that (`tests` measures real quads against it).
pub fn quad_width_m(a_m: f64, level: u8) -> f64 {
    0.5 * a_m * (2.0 * std::f64::consts::PI / 3.0).sqrt() / f64::from(1u32 << level.min(31)).max(1.0)
}

/// The edge level of a feather F: the finest level whose quads are at least F across (0 for
/// feathers wider than a level-0 quad, which [`crate::layers::LayerSpec::check`] refuses).
pub fn edge_level(a_m: f64, feather_m: f64) -> u8 {
    (0..=MAX_LEVEL).take_while(|&l| quad_width_m(a_m, l) >= feather_m).last().unwrap_or(0)
}

/// The level at which the field of a quad at `quad_level` is computed.
pub fn field_level(quad_level: u8, edge_level: u8, finest_level: u8) -> u8 {
    quad_level.min(edge_level).min(finest_level)
}

/// The edge mask at distance d from the no-data edge: smoothstep(d / F) (1 where F is 0).
pub fn edge_mask(distance_m: f64, feather_m: f64) -> f64 {
    if feather_m <= 0.0 { 1.0 } else { crate::maths::smoothstep(distance_m / feather_m) }
}

/// The distance field of `quad` (257², row by row from the south), metres, capped at `cap_m`:
/// for each sample the distance to the nearest sample without data at the quad's level, over the
/// quad and its neighbours. `tile(q)` gives a quad's raw 257² grid at the same level (NaN: no
/// data; `None`: no tile, no data anywhere in it); its errors are passed on.
pub fn distance_field<E>(
    ellipsoid: &Ellipsoid,
    quad: QuadId,
    cap_m: f64,
    mut tile: impl FnMut(QuadId) -> Result<Option<std::sync::Arc<Vec<f32>>>, E>,
) -> Result<Vec<f32>, E> {
    let level = quad.level;
    let (x0, y0) = (i64::from(quad.x) * MARGIN - MARGIN, i64::from(quad.y) * MARGIN - MARGIN);
    // Where each cell of the neighbourhood is: its face and global sample there (None beyond a
    // cube corner, where the surface has no such point).
    let cells: Vec<Option<(crate::ecm::Face, i64, i64)>> =
        (0..W * W).map(|c| fold_sample(quad.face, level, x0 + (c % W) as i64, y0 + (c / W) as i64)).collect();
    let mut tiles: HashMap<QuadId, Option<std::sync::Arc<Vec<f32>>>> = HashMap::new();
    let mut no_data = vec![false; W * W];
    for (c, cell) in cells.iter().enumerate() {
        let Some((face, i, j)) = *cell else { continue };
        let (q, li, lj) = quad_of_sample(face, level, i, j);
        let t = match tiles.entry(q) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => e.insert(tile(q)?),
        };
        no_data[c] = t.as_ref().is_none_or(|t| t[lj as usize * N + li as usize].is_nan());
    }
    if !no_data.iter().any(|&v| v) {
        return Ok(vec![cap_m as f32; N * N]);
    }
    // The exact points (a void cell keeps NaN and is never read).
    let mut points = vec![DVec3::NAN; W * W];
    points.par_chunks_mut(W).enumerate().for_each(|(y, row)| {
        for (x, p) in row.iter_mut().enumerate() {
            if let Some((face, i, j)) = cells[y * W + x] {
                let (fx, fy) = face_xy(level, i, j);
                let (lat, lon) = CubeProjection::Qsc
                    .geodetic_from_face_point(ellipsoid, FacePoint { face, x: fx, y: fy })
                    .unwrap_or((0.0, 0.0));
                *p = ecef_from_geodetic(ellipsoid, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 });
            }
        }
    });
    let nearest = dead_reckoning(&points, &no_data, cells.iter().map(Option::is_some));
    let margin = MARGIN as usize;
    let mut out = Vec::with_capacity(N * N);
    for j in 0..N {
        for i in 0..N {
            let c = (j + margin) * W + i + margin;
            let d = nearest[c].map_or(f64::INFINITY, |f| (points[c] - points[f as usize]).length());
            out.push(d.min(cap_m) as f32);
        }
    }
    Ok(out)
}

/// Per cell of a W × W grid, the index of its nearest `feature` cell as propagated by two raster
/// passes (each cell tries its neighbours' nearest features, by true distance between `points`);
/// cells not `on_surface` neither take nor pass one on.
fn dead_reckoning(points: &[DVec3], feature: &[bool], on_surface: impl Iterator<Item = bool>) -> Vec<Option<u32>> {
    let on: Vec<bool> = on_surface.collect();
    let mut nearest: Vec<Option<u32>> = (0..W * W).map(|c| (on[c] && feature[c]).then_some(c as u32)).collect();
    let mut dist2: Vec<f64> = nearest.iter().map(|f| if f.is_some() { 0.0 } else { f64::INFINITY }).collect();
    let mut relax = |c: usize, n: usize, nearest: &mut Vec<Option<u32>>| {
        if !on[n] {
            return;
        }
        if let Some(f) = nearest[n] {
            let d2 = (points[c] - points[f as usize]).length_squared();
            if d2 < dist2[c] {
                dist2[c] = d2;
                nearest[c] = Some(f);
            }
        }
    };
    // Each pass sweeps its rows one way with the neighbours already visited, then back along the
    // row with the one behind (as Danielsson's 8SSEDT does), so that a nearest sample can travel
    // any direction within two passes.
    let w = W as i64;
    let mut visit = |x: i64, y: i64, steps: &[(i64, i64)], nearest: &mut Vec<Option<u32>>| {
        let c = (y * w + x) as usize;
        if !on[c] {
            return;
        }
        for (dx, dy) in steps {
            let (nx, ny) = (x + dx, y + dy);
            if (0..w).contains(&nx) && (0..w).contains(&ny) {
                relax(c, (ny * w + nx) as usize, nearest);
            }
        }
    };
    for y in 0..w {
        for x in 0..w {
            visit(x, y, &[(-1, -1), (0, -1), (1, -1), (-1, 0)], &mut nearest);
        }
        for x in (0..w).rev() {
            visit(x, y, &[(1, 0)], &mut nearest);
        }
    }
    for y in (0..w).rev() {
        for x in (0..w).rev() {
            visit(x, y, &[(1, 0), (-1, 1), (0, 1), (1, 1)], &mut nearest);
        }
        for x in 0..w {
            visit(x, y, &[(-1, 0)], &mut nearest);
        }
    }
    nearest
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::points::sample_point;
    use crate::ecm::{Edge, Face};
    use std::convert::Infallible;
    use std::sync::Arc;

    /// A synthetic dataset at a level: data everywhere except where `hole(point)` holds.
    fn synthetic(
        e: &Ellipsoid,
        hole: impl Fn(DVec3) -> bool,
    ) -> impl FnMut(QuadId) -> Result<Option<Arc<Vec<f32>>>, Infallible> {
        let e = *e;
        move |q: QuadId| {
            let grid = (0..N * N)
                .map(|k| {
                    let (p, _, _) = sample_point(&e, q, GRID, (k % N) as u32, (k / N) as u32);
                    if hole(p) { f32::NAN } else { 1.0 }
                })
                .collect();
            Ok(Some(Arc::new(grid)))
        }
    }

    /// The distance from each of a quad's samples to the nearest no-data sample of the same
    /// level within `cap`, by brute force over a block of samples around it (every 2nd one of
    /// the quad, all of its neighbourhood's no-data samples).
    fn brute_force(e: &Ellipsoid, quad: QuadId, cap: f64, hole: &dyn Fn(DVec3) -> bool) -> Vec<(usize, f64)> {
        let mut holes = Vec::new();
        let (x0, y0) = (i64::from(quad.x) * MARGIN - MARGIN, i64::from(quad.y) * MARGIN - MARGIN);
        for c in 0..W * W {
            if let Some((face, i, j)) = fold_sample(quad.face, quad.level, x0 + (c % W) as i64, y0 + (c / W) as i64) {
                let (fx, fy) = face_xy(quad.level, i, j);
                let (lat, lon) =
                    CubeProjection::Qsc.geodetic_from_face_point(e, FacePoint { face, x: fx, y: fy }).unwrap();
                let p = ecef_from_geodetic(e, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 });
                if hole(p) {
                    holes.push(p);
                }
            }
        }
        (0..N * N)
            .step_by(7)
            .map(|k| {
                let (p, _, _) = sample_point(e, quad, GRID, (k % N) as u32, (k / N) as u32);
                let d = holes.iter().map(|h| (p - *h).length()).fold(f64::INFINITY, f64::min);
                (k, d.min(cap))
            })
            .collect()
    }

    fn check_against_brute_force(e: &Ellipsoid, quad: QuadId, hole: impl Fn(DVec3) -> bool + Copy) -> f64 {
        let cap = quad_width_m(e.a_m(), quad.level);
        let field = distance_field(e, quad, cap, synthetic(e, hole)).unwrap();
        let spacing = crate::ecm::grid::spacing_m(e, quad.level);
        let mut worst = 0f64;
        for (k, d) in brute_force(e, quad, cap, &hole) {
            worst = worst.max((f64::from(field[k]) - d).abs());
        }
        // Dead reckoning errs rarely and by a small part of a sample spacing.
        assert!(worst < 0.05 * spacing, "{quad}: {worst} m against a spacing of {spacing} m");
        worst
    }

    #[test]
    fn the_field_is_the_distance_to_the_nearest_no_data_sample_across_faces_and_corners() {
        let e = Ellipsoid::MOON;
        // A disc of no data on a face edge, seen from both faces; and a cube corner's region.
        let front = Face::Front.center() * e.a_m();
        let edge_point = (Face::Front.center() + Face::Front.x_axis()).normalize() * e.a_m();
        let hole = move |p: DVec3| (p - edge_point).length() < 40_000.0;
        let q = QuadId::containing(CubeProjection::Qsc.face_point_from_direction(edge_point * 0.99 + front * 0.01), 5)
            .unwrap();
        check_against_brute_force(&e, q, hole);
        check_against_brute_force(&e, q.neighbour(Edge::East).quad, hole);
        let corner = (Face::Front.center() + Face::Front.x_axis() + Face::Front.y_axis()).normalize() * e.a_m();
        let ring = move |p: DVec3| (p - corner).length() > 30_000.0 && (p - corner).length() < 45_000.0;
        let at_corner = QuadId::new(Face::Front, 5, 31, 31).unwrap();
        check_against_brute_force(&e, at_corner, ring);
    }

    #[test]
    fn a_neighbourhood_full_of_data_is_the_cap_and_one_without_is_zero() {
        let e = Ellipsoid::WGS84;
        let q = QuadId::new(Face::Top, 6, 10, 20).unwrap();
        let full = distance_field(&e, q, 1234.0, synthetic(&e, |_| false)).unwrap();
        assert!(full.iter().all(|&d| d == 1234.0));
        let none = distance_field(&e, q, 1234.0, |_| Ok::<_, Infallible>(None)).unwrap();
        assert!(none.iter().all(|&d| d == 0.0));
    }

    #[test]
    fn the_neighbourhood_reaches_the_cap_everywhere_even_at_cube_corners() {
        // Every point of the ring of neighbours' outer boundary is at least W(level) from the
        // centre quad: what makes the capped field independent of the quad it is computed in.
        for e in [Ellipsoid::WGS84, Ellipsoid::MOON] {
            for q in [
                QuadId::new(Face::Front, 4, 0, 0).unwrap(),
                QuadId::new(Face::Front, 4, 7, 8).unwrap(),
                QuadId::new(Face::Top, 3, 7, 0).unwrap(),
                QuadId::new(Face::Back, 0, 0, 0).unwrap(),
            ] {
                let cap = quad_width_m(e.a_m(), q.level);
                let mut inner = Vec::new();
                for k in (0..N * N).step_by(3) {
                    let (i, j) = (k % N, k / N);
                    if i == 0 || j == 0 || i == N - 1 || j == N - 1 {
                        inner.push(sample_point(&e, q, GRID, i as u32, j as u32).0);
                    }
                }
                let (x0, y0) = (i64::from(q.x) * MARGIN - MARGIN, i64::from(q.y) * MARGIN - MARGIN);
                let mut least = f64::INFINITY;
                for c in (0..W * W).step_by(5) {
                    let (x, y) = (c % W, c / W);
                    if !(x == 0 || y == 0 || x == W - 1 || y == W - 1) {
                        continue;
                    }
                    let Some((face, i, j)) = fold_sample(q.face, q.level, x0 + x as i64, y0 + y as i64) else {
                        continue;
                    };
                    let (fx, fy) = face_xy(q.level, i, j);
                    let (lat, lon) =
                        CubeProjection::Qsc.geodetic_from_face_point(&e, FacePoint { face, x: fx, y: fy }).unwrap();
                    let p = ecef_from_geodetic(&e, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 });
                    least = least.min(inner.iter().map(|s| (p - *s).length()).fold(f64::INFINITY, f64::min));
                }
                assert!(least >= cap, "{q}: the ring is {least} m away, the cap {cap} m");
            }
        }
    }

    #[test]
    fn the_edge_level_is_the_finest_whose_quads_span_the_feather() {
        let a = Ellipsoid::WGS84.a_m();
        for f in [1.0, 500.0, 12_000.0, 1e6] {
            let l = edge_level(a, f);
            assert!(quad_width_m(a, l) >= f && quad_width_m(a, l + 1) < f, "{f}: level {l}");
            // Its sample spacing is under F/64 (the mask's error bound in the module docs).
            assert!(quad_width_m(a, l) * 2.0 / 256.0 < f / 64.0);
        }
        assert_eq!(field_level(12, 7, 9), 7);
        assert_eq!(field_level(3, 7, 9), 3);
        assert_eq!(field_level(12, 11, 9), 9);
        assert_eq!(edge_mask(0.0, 100.0), 0.0);
        assert_eq!(edge_mask(100.0, 100.0), 1.0);
        assert_eq!(edge_mask(50.0, 100.0), 0.5);
        assert_eq!(edge_mask(0.0, 0.0), 1.0);
    }
}
