//! The sample grid of the cube map (the store's tiles, the edit and erosion rasters and the
//! composed quads all use it): per face and level a corner-inclusive grid of
//! `M + 1` × `M + 1` samples, M = 256·2^level, which is exactly the union of the ECM geometry's
//! per-quad grids (`QuadId::sample_xy(257, i, j)`): quad (x, y) owns samples 256x ..= 256x + 256.
//!
//! Global sample indices (i, j) count from the face's west and south edges. A GeoPackage tile
//! holds the 256 × 256 samples i ∈ 256x..256x + 255, j ∈ 256y..256y + 255 (the lower-left corner of
//! each pixel, `grid-value-is-corner`); the tile's *rim* (north row and east column, 513 samples)
//! is stored beside it, so one quad's full 257² grid is one tile plus one rim.

use super::{Face, MAX_LEVEL, QuadId, fold_onto_face};
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

/// Bicubic interpolation in a 257² grid at grid coordinates (u, v) ∈ [0, 256]²: cubic Lagrange
/// through the 4 × 4 samples around the point (the window shifted inwards at the grid's edges),
/// exact at the samples and for bicubic surfaces, NaN where a sample with weight has none (a
/// sample with weight 0, as at a node, is not read). Where bilinear interpolation flattens
/// curvature between samples, this keeps it: co-registration samples A with it (see
/// `compare::mosaic`).
pub fn bicubic(grid: &[f32], u: f64, v: f64) -> f64 {
    let n = GRID as usize;
    // At a sample every other weight is 0 and its own 1: what the sum gives, 0 + the sample
    // (−0 included), without the weights.
    let last = (n - 1) as f64;
    if u.fract() == 0.0 && v.fract() == 0.0 && (0.0..=last).contains(&u) && (0.0..=last).contains(&v) {
        return 0.0 + f64::from(grid[v as usize * n + u as usize]);
    }
    let (bu, wu) = cubic_weights(u, n);
    let (bv, wv) = cubic_weights(v, n);
    let mut h = 0.0;
    for (dj, &w_v) in wv.iter().enumerate() {
        if w_v == 0.0 {
            continue;
        }
        let row = &grid[(bv + dj) * n + bu..][..4];
        let mut across = 0.0;
        for (&value, &w_u) in row.iter().zip(&wu) {
            if w_u != 0.0 {
                across += w_u * f64::from(value);
            }
        }
        h += w_v * across;
    }
    h
}

/// Cubic Lagrange interpolation at a fractional node index `f` among `n ≥ 4` nodes: the first of
/// the four nodes used (the two either side of `f`, shifted inwards at the ends) and their
/// weights. Exact for cubics; the error of a smooth function falls as the fourth power of the
/// node spacing. At a node, the other three weights are exactly 0.
pub(crate) fn cubic_weights(f: f64, n: usize) -> (usize, [f64; 4]) {
    let f = f.clamp(0.0, (n - 1) as f64);
    let base = (f.floor() as usize).saturating_sub(1).min(n - 4);
    let t = f - base as f64;
    let w = [
        -(t - 1.0) * (t - 2.0) * (t - 3.0) / 6.0,
        t * (t - 2.0) * (t - 3.0) / 2.0,
        -t * (t - 1.0) * (t - 3.0) / 2.0,
        t * (t - 1.0) * (t - 2.0) / 6.0,
    ];
    (base, w)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn cubic_weights_reproduce_cubics_and_sum_to_one() {
        for n in [4usize, 5, 18] {
            for k in 0..=100 {
                let f = (n - 1) as f64 * k as f64 / 100.0;
                let (base, w) = cubic_weights(f, n);
                assert!(base + 3 < n);
                let cubic = |x: f64| 2.0 - 0.5 * x + 0.25 * x * x - 0.125 * x * x * x;
                let got: f64 = (0..4).map(|j| w[j] * cubic((base + j) as f64)).sum();
                assert!((got - cubic(f)).abs() < 1e-9 * (1.0 + cubic(f).abs()), "n {n}, f {f}: {got} vs {}", cubic(f));
                assert!((w.iter().sum::<f64>() - 1.0).abs() < 1e-12);
            }
        }
    }

    #[test]
    fn bicubic_is_exact_for_bicubics_and_at_the_samples() {
        let n = GRID as usize;
        let surface = |u: f64, v: f64| {
            let (x, y) = (u / 64.0, v / 64.0);
            100.0 + 3.0 * x - 2.0 * y + 0.5 * x * x * y - 0.25 * x * x * x + 0.125 * y * y * y * x
        };
        let grid: Vec<f32> = (0..n * n).map(|k| surface((k % n) as f64, (k / n) as f64) as f32).collect();
        let stored = |u: usize, v: usize| f64::from(grid[v * n + u]);
        for (u, v) in [(0.0, 0.0), (0.5, 255.5), (17.25, 3.75), (128.0, 200.4), (255.9, 256.0), (256.0, 0.3)] {
            // f32 storage rounds each sample by at most 2⁻²⁴ relative; the weights sum to 1 with
            // absolute sums below 1.7 per axis, so the error is that rounding, amplified ≤ 3×.
            let (got, want) = (bicubic(&grid, u, v), surface(u, v));
            assert!((got - want).abs() < 3.0 * 200.0 * f64::from(f32::EPSILON), "({u}, {v}): {got} vs {want}");
        }
        for (u, v) in [(0usize, 0usize), (1, 255), (256, 256), (77, 3)] {
            assert_eq!(bicubic(&grid, u as f64, v as f64), stored(u, v));
            assert_eq!(bicubic(&grid, u as f64, v as f64), bilinear(&grid, u as f64, v as f64));
        }
    }

    #[test]
    fn bicubic_reads_only_the_samples_with_weight() {
        let n = GRID as usize;
        let mut grid = vec![10.0f32; n * n];
        grid[20 * n + 30] = f32::NAN;
        // A sample in the 4 × 4 window makes the value NaN ...
        assert!(bicubic(&grid, 29.5, 19.5).is_nan());
        assert!(bicubic(&grid, 31.5, 21.5).is_nan());
        // ... outside it, or at a node (the other weights are 0), it is not read.
        assert_eq!(bicubic(&grid, 32.5, 19.5), 10.0);
        assert_eq!(bicubic(&grid, 30.0, 21.0), 10.0);
        assert!((bicubic(&grid, 27.5, 22.5) - 10.0).abs() < 1e-12);
    }

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
