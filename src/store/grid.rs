//! The store's sample grid: per face and level a corner-inclusive grid of
//! `M + 1` × `M + 1` samples, M = 256·2^level, which is exactly the union of the ECM geometry's
//! per-quad grids (`QuadId::sample_xy(257, i, j)`): quad (x, y) owns samples 256x ..= 256x + 256.
//!
//! Global sample indices (i, j) count from the face's west and south edges. A GeoPackage tile
//! holds the 256 × 256 samples i ∈ 256x..256x + 255, j ∈ 256y..256y + 255 (the lower-left corner of
//! each pixel, `grid-value-is-corner`); the tile's *rim* (north row and east column, 513 samples)
//! is stored beside it, so one quad's full 257² grid is one tile plus one rim.

use crate::ecm::{Face, MAX_LEVEL, QuadId, fold_onto_face};
use crate::geodesy::Ellipsoid;

/// Samples per tile edge in the GeoPackage (the pixel count).
pub const TILE: u32 = 256;
/// Samples per quad edge in the geometry's corner-inclusive grid.
pub const GRID: u32 = TILE + 1;
/// Samples of a tile's rim: its north row (257) and its east column below it (256).
pub const RIM: usize = (2 * TILE + 1) as usize;

/// Sample intervals along a face edge at a level: 256·2^level.
pub fn intervals_per_face_edge(level: u8) -> i64 {
    i64::from(TILE) << level
}

/// Face coordinates (x, y) ∈ [−1, 1] of global sample (i, j) at a level. Bit-identical to
/// `QuadId::sample_xy(257, …)` of the quad that holds the sample.
pub fn face_xy(level: u8, i: i64, j: i64) -> (f64, f64) {
    let m = intervals_per_face_edge(level) as f64;
    (-1.0 + 2.0 * i as f64 / m, -1.0 + 2.0 * j as f64 / m)
}

/// The mean spacing of samples at a level, in metres: the edge of the equal-area cell,
/// R·√(2π/3) / (256·2^level) with R the semi-major axis (QSC is equal-area: every cell of a
/// level has the same area on the sphere).
pub fn spacing_m(ellipsoid: &Ellipsoid, level: u8) -> f64 {
    ellipsoid.a_m() * (2.0 * std::f64::consts::PI / 3.0).sqrt() / intervals_per_face_edge(level) as f64
}

/// The finest level for a source of ground resolution `resolution_m`: the coarsest level whose
/// sample spacing is at most the source's pixel size, so no source detail is lost (the store
/// oversamples by less than 2× per axis); clamped to 0 ..= 30.
pub fn level_for_resolution(ellipsoid: &Ellipsoid, resolution_m: f64) -> u8 {
    (0..=MAX_LEVEL).find(|&l| spacing_m(ellipsoid, l) <= resolution_m).unwrap_or(MAX_LEVEL)
}

/// Where a global sample index lives: on which face (after folding indices that fall off the
/// face across an edge onto the adjacent face) and at which index there. `None` beyond a cube
/// corner, where no face has the point.
pub fn fold_sample(face: Face, level: u8, i: i64, j: i64) -> Option<(Face, i64, i64)> {
    let m = intervals_per_face_edge(level);
    let (f, u, v) = fold_onto_face(face, m, 2 * i - m, 2 * j - m)?;
    Some((f, (u + m) / 2, (v + m) / 2))
}

/// The quad whose 257² grid is read for sample (i, j) of a face, and the sample's place in it:
/// the tile that stores it, or for the face's last row and column the quad before, whose rim
/// holds it. `i`, `j` must lie in 0 ..= 256·2^level.
pub fn quad_of_sample(face: Face, level: u8, i: i64, j: i64) -> (QuadId, u32, u32) {
    let last = (1i64 << level) - 1;
    let qx = (i / i64::from(TILE)).min(last);
    let qy = (j / i64::from(TILE)).min(last);
    let quad = QuadId { face, level, x: qx as u32, y: qy as u32 };
    (quad, (i - qx * i64::from(TILE)) as u32, (j - qy * i64::from(TILE)) as u32)
}

/// The heights of `quad` bilinearly interpolated from the grid of its ancestor `source` (both
/// corner-inclusive 257² grids); NaN where a sample with weight has no data.
pub fn upsample(grid: &[f32], source: QuadId, quad: QuadId) -> Vec<f32> {
    let n = GRID as usize;
    let k = quad.level - source.level;
    let scale = 1.0 / f64::from(1u32 << k);
    let (ox, oy) = (f64::from(quad.x - (source.x << k)), f64::from(quad.y - (source.y << k)));
    let cells = f64::from(GRID - 1);
    let mut out = Vec::with_capacity(n * n);
    for j in 0..n {
        let v = (oy * cells + j as f64) * scale;
        for i in 0..n {
            let u = (ox * cells + i as f64) * scale;
            out.push(bilinear(grid, u, v) as f32);
        }
    }
    out
}

/// Bilinear interpolation in a 257² grid at grid coordinates (u, v) ∈ [0, 256]² (NaN where a
/// sample with weight has none; a sample with weight 0 is not read).
pub fn bilinear(grid: &[f32], u: f64, v: f64) -> f64 {
    let n = GRID as usize;
    let (i0, j0) = ((u.floor() as usize).min(n - 2), (v.floor() as usize).min(n - 2));
    let (fu, fv) = (u - i0 as f64, v - j0 as f64);
    let mut h = 0.0;
    for (di, dj, w) in
        [(0, 0, (1.0 - fu) * (1.0 - fv)), (1, 0, fu * (1.0 - fv)), (0, 1, (1.0 - fu) * fv), (1, 1, fu * fv)]
    {
        if w > 0.0 {
            h += w * f64::from(grid[(j0 + dj) * n + i0 + di]);
        }
    }
    h
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn face_xy_matches_the_geometry_grid() {
        for level in [0u8, 3, 17, 30] {
            let q = QuadId::new(Face::Top, level, ((1u64 << level) - 1) as u32, 0).unwrap();
            for (i, j) in [(0, 0), (256, 256), (17, 200)] {
                let (gi, gj) = (i64::from(q.x) * 256 + i64::from(i), i64::from(q.y) * 256 + i64::from(j));
                assert_eq!(face_xy(level, gi, gj), q.sample_xy(GRID, i, j));
                // The quad that holds it (on a quad boundary, either of the two is right).
                let (back, li, lj) = quad_of_sample(q.face, level, gi, gj);
                assert_eq!(back.sample_xy(GRID, li, lj), q.sample_xy(GRID, i, j));
                assert!(li <= 256 && lj <= 256 && (li < 256 || back.x as u64 == (1u64 << level) - 1));
            }
        }
    }

    #[test]
    fn folded_samples_are_the_same_surface_point() {
        for face in Face::ALL {
            for level in [0u8, 2, 9] {
                let m = intervals_per_face_edge(level);
                for (i, j) in [(-1, 5), (m + 2, m / 3), (m / 2, -3), (7, m + 1), (m, m), (0, m / 2)] {
                    let (f, fi, fj) = fold_sample(face, level, i, j).unwrap();
                    assert!((0..=m).contains(&fi) && (0..=m).contains(&fj), "{face} {level} {i} {j}");
                    let cube = |f: Face, i: i64, j: i64| {
                        let (x, y) = face_xy(level, i, j);
                        f.center() + f.x_axis() * x + f.y_axis() * y
                    };
                    let on_face = |v: i64| (0..=m).contains(&v);
                    if on_face(i) && on_face(j) {
                        assert_eq!((f, fi, fj), (face, i, j));
                    } else {
                        // The fold keeps the distance from the edge: the folded point is as far inside
                        // the new face as the old one was outside, along the same edge position.
                        let excess = if on_face(i) { (j - m).max(-j) } else { (i - m).max(-i) };
                        let edge_point = cube(face, i.clamp(0, m), j.clamp(0, m));
                        let back = cube(f, fi, fj);
                        let d = (back - edge_point).length();
                        assert!((d - 2.0 * excess as f64 / m as f64).abs() < 1e-12, "{face} {i} {j}: {d}");
                    }
                }
                assert!(fold_sample(face, level, -1, -1).is_none());
            }
        }
    }

    #[test]
    fn level_rule_never_loses_source_detail() {
        let e = Ellipsoid::WGS84;
        for r in [90.0, 30.0, 1.0, 7_580.0, 1e6] {
            let l = level_for_resolution(&e, r);
            assert!(spacing_m(&e, l) <= r || l == 0);
            if l > 0 {
                assert!(spacing_m(&e, l - 1) > r);
            }
        }
        assert_eq!(level_for_resolution(&e, 90.0), 9);
        assert_eq!(level_for_resolution(&Ellipsoid::MOON, 7_580.0), 1);
    }
}
