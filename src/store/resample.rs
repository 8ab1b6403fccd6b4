//! The import's sampling: which quads a source may cover, resampling a finest-level quad from
//! its sources (face point → geodetic → source pixel through PROJ, interpolated, heights
//! converted to the ellipsoid), and averaging a coarser quad from the level below.

use std::collections::HashSet;
use std::str::FromStr;

use gdal::spatial_ref::CoordTransform;

use super::StoreError;
use super::lattice::{LatticeRow, LatticeStats, PixelLattice, QuadPositions, Transform, exact_positions};
use super::read::GridReader;
use super::source::{SourceReader, Window};
use super::tile::QuadGrid;
use crate::Invalid;
use crate::ecm::area_mean::{AREA_MEAN_SPAN, area_mean};
use crate::ecm::grid::{self, GRID, TILE, face_xy, spacing_m};
use crate::ecm::{CubeProjection, Edge, FacePoint, QuadId};
use crate::geodesy::Ellipsoid;

/// How a sample is interpolated from the source pixels around it.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Resampling {
    /// Bilinear over the 2×2 pixel centres around the point (weights renormalised over pixels
    /// with data, as gdalwarp does).
    Bilinear,
    /// Cubic convolution (Keys, a = −0.5) over 4×4; bilinear where one of them has no data.
    Cubic,
    /// The nearest pixel.
    Nearest,
}

impl Resampling {
    /// The name used on the command line and in the store.
    pub fn name(self) -> &'static str {
        match self {
            Resampling::Bilinear => "bilinear",
            Resampling::Cubic => "cubic",
            Resampling::Nearest => "nearest",
        }
    }
}

impl FromStr for Resampling {
    type Err = Invalid;
    fn from_str(s: &str) -> Result<Self, Invalid> {
        match s {
            "bilinear" => Ok(Resampling::Bilinear),
            "cubic" => Ok(Resampling::Cubic),
            "nearest" => Ok(Resampling::Nearest),
            _ => Err(format!("unknown resampling '{s}': use bilinear, cubic or nearest").into()),
        }
    }
}

/// How the finest level is resampled.
pub(crate) struct Plan {
    pub(crate) supersample: u32,
    pub(crate) resampling: Resampling,
    pub(crate) transform: Transform,
    pub(crate) lattice: LatticeStats,
    pub(crate) window_cap_bytes: usize,
    pub(crate) geoid_grid: Option<String>,
}

/// One worker's handles: a reader per source, and the geoid transform.
pub(crate) struct Worker {
    pub(crate) readers: Vec<SourceReader>,
    pub(crate) geoid: Option<CoordTransform>,
}

/// The quads at `level` that a source may cover: under a grid of source points spaced at most
/// a quarter quad apart (edges included), with their eight neighbours.
pub(super) fn footprint(reader: &SourceReader, body: &Ellipsoid, level: u8) -> Result<HashSet<QuadId>, StoreError> {
    let info = reader.info();
    let (w, h) = (info.size.0 as f64, info.size.1 as f64);
    let quad_m = spacing_m(body, level) * f64::from(TILE);
    let step = (quad_m / 4.0 / info.resolution_m).clamp(0.5, f64::MAX);
    let along = |n: f64| -> Vec<f64> {
        let count = (n / step).ceil().max(1.0) as usize;
        (0..=count).map(|k| n * k as f64 / count as f64).collect()
    };
    let (xs, ys) = (along(w), along(h));
    let mut quads = HashSet::new();
    let mut batch = Vec::with_capacity(1 << 16);
    let flush = |batch: &mut Vec<(f64, f64)>, quads: &mut HashSet<QuadId>| {
        for (lon, lat) in reader.lonlat_of_pixels(batch) {
            if lon.is_finite() {
                let p = CubeProjection::Qsc.face_point_from_geodetic(body, lat.to_radians(), lon.to_radians());
                if let Ok(q) = QuadId::containing(p, level) {
                    quads.insert(q);
                }
            }
        }
        batch.clear();
    };
    for &y in &ys {
        for &x in &xs {
            batch.push((x, y));
            if batch.len() == batch.capacity() {
                flush(&mut batch, &mut quads);
            }
        }
    }
    flush(&mut batch, &mut quads);
    if quads.is_empty() {
        return Err(StoreError::new(&info.path, "none of its pixels lies on the body: is its CRS right?"));
    }
    let mut with_neighbours = quads.clone();
    for q in &quads {
        for e in Edge::ALL {
            let n = q.neighbour(e).quad;
            with_neighbours.insert(n);
            for e2 in [Edge::North, Edge::South] {
                if matches!(e, Edge::East | Edge::West) {
                    with_neighbours.insert(n.neighbour(e2).quad);
                }
            }
        }
    }
    Ok(with_neighbours)
}

/// Resamples one quad's 257² grid from the sources (first source with data wins).
pub(super) fn resample_quad(
    worker: &mut Worker,
    body: &Ellipsoid,
    plan: &Plan,
    quad: QuadId,
) -> Result<Option<QuadGrid>, StoreError> {
    let k = plan.supersample;
    let n = GRID as usize;
    let mut grid = QuadGrid::empty();
    let j0 = i64::from(quad.y) * i64::from(TILE);
    let i0 = i64::from(quad.x) * i64::from(TILE);
    let m = grid::intervals_per_face_edge(quad.level) as f64;
    // Sub-samples lie within half a sample of the quad's samples, on the face.
    let span = |c0: i64| {
        let t = f64::from(TILE);
        if k == 1 { [0.0, t] } else { [(-0.5f64).max(-c0 as f64), (t + 0.5).min(m - c0 as f64)] }
    };
    let (span_u, span_v) = (span(i0), span(j0));
    let positions: Vec<QuadPositions> = match plan.transform {
        Transform::Exact => worker.readers.iter().map(|_| QuadPositions::Exact).collect(),
        Transform::Lattice => {
            worker.readers.iter().map(|r| QuadPositions::build(r, body, quad, span_u, span_v, &plan.lattice)).collect()
        }
    };
    // Rows of samples in bands, each band's positions computed once and read per source.
    let band_rows = (16_384 / (n * (k * k) as usize)).max(1);
    let mut row = 0usize;
    while row < n {
        let rows = band_rows.min(n - row);
        let mut geodetic = None;
        let mut values = vec![f64::NAN; rows * n];
        for (reader, positions) in worker.readers.iter().zip(&positions) {
            if values.iter().all(|v| !v.is_nan()) {
                break;
            }
            let (fx, fy) = match positions {
                QuadPositions::Whole(l) => band_pixels(l, quad, j0 + row as i64, rows, k, m),
                QuadPositions::Blocks { .. } => {
                    band_pixels_split(positions, reader, body, quad, j0 + row as i64, rows, k, m)
                }
                QuadPositions::Exact => {
                    let (lons, lats) =
                        geodetic.get_or_insert_with(|| band_positions(body, quad, j0 + row as i64, rows, k));
                    let (mut fx, mut fy) = (lons.clone(), lats.clone());
                    reader.centre_coords(&mut fx, &mut fy);
                    (fx, fy)
                }
            };
            fill_from_source(reader, plan, &fx, &fy, 0, rows, n, k, &mut values)?;
        }
        if let Some(t) = &worker.geoid {
            convert_heights(t, body, quad, j0 + row as i64, rows, &mut values);
        }
        for r in 0..rows {
            for i in 0..n {
                grid.values[(row + r) * n + i] = values[r * n + i] as f32;
            }
        }
        row += rows;
    }
    Ok((!grid.is_empty()).then_some(grid))
}

/// Sub-sample offsets within a sample's cell, in samples, for k×k sub-samples.
fn sub_offset(s: u32, k: u32) -> f64 {
    (f64::from(s) + 0.5) / f64::from(k) - 0.5
}

/// The same for a split quad: each point from its block's lattice, or exactly where its block
/// has none.
#[allow(clippy::too_many_arguments)]
fn band_pixels_split(
    positions: &QuadPositions,
    reader: &SourceReader,
    body: &Ellipsoid,
    quad: QuadId,
    j0: i64,
    rows: usize,
    k: u32,
    m: f64,
) -> (Vec<f64>, Vec<f64>) {
    let n = GRID as usize;
    let i0 = i64::from(quad.x) * i64::from(TILE);
    let jq = i64::from(quad.y) * i64::from(TILE);
    let along = |c: i64, s: u32, c0: i64| {
        if k == 1 { (c - c0) as f64 } else { (c as f64 + sub_offset(s, k)).clamp(0.0, m) - c0 as f64 }
    };
    let mut fx = Vec::with_capacity(rows * n * (k * k) as usize);
    let mut fy = Vec::with_capacity(fx.capacity());
    let (mut exact, mut exact_u, mut exact_v) = (Vec::new(), Vec::new(), Vec::new());
    // With one point per sample, a row of points crosses each block once: its lattice is
    // interpolated along v once per block and row, as in `band_pixels`.
    let mut row: Option<(&PixelLattice, f64, LatticeRow)> = None;
    for r in 0..rows {
        for i in 0..n {
            for a in 0..k {
                for b in 0..k {
                    let (u, v) = (along(i0 + i as i64, b, i0), along(j0 + r as i64, a, jq));
                    let (x, y) = match positions.block(u, v) {
                        Some(l) if k == 1 => {
                            if !matches!(&row, Some((c, cv, _)) if std::ptr::eq(*c, l) && *cv == v) {
                                row = Some((l, v, l.row(v)));
                            }
                            row.as_ref().map_or((f64::NAN, f64::NAN), |(_, _, lr)| lr.at(u))
                        }
                        Some(l) => l.at(u, v),
                        None => {
                            exact.push(fx.len());
                            exact_u.push(u);
                            exact_v.push(v);
                            (f64::NAN, f64::NAN)
                        }
                    };
                    fx.push(x);
                    fy.push(y);
                }
            }
        }
    }
    let (xs, ys) = exact_positions(reader, body, quad, &exact_u, &exact_v);
    for (t, &at) in exact.iter().enumerate() {
        (fx[at], fy[at]) = (xs[t], ys[t]);
    }
    (fx, fy)
}

/// The source pixel-centre coordinates of a band's sub-sample points, interpolated from the
/// quad's lattice; the same points, in the same order, as [`band_positions`] gives.
fn band_pixels(l: &PixelLattice, quad: QuadId, j0: i64, rows: usize, k: u32, m: f64) -> (Vec<f64>, Vec<f64>) {
    let n = GRID as usize;
    let i0 = i64::from(quad.x) * i64::from(TILE);
    let jq = i64::from(quad.y) * i64::from(TILE);
    let mut fx = Vec::with_capacity(rows * n * (k * k) as usize);
    let mut fy = Vec::with_capacity(fx.capacity());
    let u_of = |i: usize, b: u32| {
        if k == 1 { i as f64 } else { ((i0 + i as i64) as f64 + sub_offset(b, k)).clamp(0.0, m) - i0 as f64 }
    };
    // The weights along u are the same on every row.
    let weights: Vec<_> =
        (0..n).flat_map(|i| (0..k).map(move |b| (i, b))).map(|(i, b)| l.u_weights(u_of(i, b))).collect();
    if k == 1 {
        fx.resize(rows * n, 0.0);
        fy.resize(rows * n, 0.0);
        for (r, (xs, ys)) in fx.chunks_exact_mut(n).zip(fy.chunks_exact_mut(n)).enumerate() {
            l.row((j0 - jq + r as i64) as f64).fill(&weights, xs, ys);
        }
        return (fx, fy);
    }
    for r in 0..rows {
        // The lattice interpolated along v once per row of sub-samples.
        let lattice_rows: Vec<_> = (0..k)
            .map(|a| {
                let v = if k == 1 {
                    (j0 - jq + r as i64) as f64
                } else {
                    ((j0 + r as i64) as f64 + sub_offset(a, k)).clamp(0.0, m) - jq as f64
                };
                l.row(v)
            })
            .collect();
        for i in 0..n {
            for row in &lattice_rows {
                for w in &weights[i * k as usize..(i + 1) * k as usize] {
                    let (x, y) = row.at_weights(w);
                    fx.push(x);
                    fy.push(y);
                }
            }
        }
    }
    (fx, fy)
}

/// Longitudes and latitudes (degrees) of the sub-sample points of `rows` rows of the quad's
/// 257 samples, starting at global row j0; k×k sub-samples per sample, spread over its cell.
fn band_positions(body: &Ellipsoid, quad: QuadId, j0: i64, rows: usize, k: u32) -> (Vec<f64>, Vec<f64>) {
    let n = GRID as usize;
    let i0 = i64::from(quad.x) * i64::from(TILE);
    let mut lons = Vec::with_capacity(rows * n * (k * k) as usize);
    let mut lats = Vec::with_capacity(lons.capacity());
    let m = grid::intervals_per_face_edge(quad.level) as f64;
    let off = |s: u32| sub_offset(s, k);
    for r in 0..rows {
        for i in 0..n {
            for a in 0..k {
                for b in 0..k {
                    let (x, y) = if k == 1 {
                        face_xy(quad.level, i0 + i as i64, j0 + r as i64)
                    } else {
                        let x = -1.0 + 2.0 * ((i0 + i as i64) as f64 + off(b)) / m;
                        let y = -1.0 + 2.0 * ((j0 + r as i64) as f64 + off(a)) / m;
                        (x.clamp(-1.0, 1.0), y.clamp(-1.0, 1.0))
                    };
                    let (lat, lon) = CubeProjection::Qsc
                        .geodetic_from_face_point(body, FacePoint { face: quad.face, x, y })
                        .unwrap_or((f64::NAN, f64::NAN));
                    lons.push(lon.to_degrees());
                    lats.push(lat.to_degrees());
                }
            }
        }
    }
    (lons, lats)
}

/// Interpolates the samples of rows r0..r0 + rows (of `n` samples, k² sub-samples each) that
/// are still NaN, reading the source in windows no larger than the plan's cap (halving the band
/// of rows until the window fits).
#[allow(clippy::too_many_arguments)]
fn fill_from_source(
    reader: &SourceReader,
    plan: &Plan,
    fx: &[f64],
    fy: &[f64],
    r0: usize,
    rows: usize,
    n: usize,
    k: u32,
    values: &mut [f64],
) -> Result<(), StoreError> {
    let kk = (k * k) as usize;
    let info = reader.info();
    let width = info.size.0 as f64;
    let range = r0 * n * kk..(r0 + rows) * n * kk;
    let mut xs: Vec<f64> = fx[range.clone()].to_vec();
    let ys = &fy[range];
    // Unwrap the columns of a 360° source around the band's first valid point.
    if info.wraps
        && let Some(&reference) = xs.iter().find(|v| v.is_finite())
    {
        {
            for x in &mut xs {
                *x -= width * ((*x - reference) / width).round();
            }
        }
    }
    let margin = if plan.resampling == Resampling::Cubic { 2 } else { 1 };
    let ((x_min, x_max), (y_min, y_max)) = (finite_range(&xs), finite_range(ys));
    if x_min > x_max {
        return Ok(());
    }
    let (c0, c1) = (x_min.floor() as i64 - margin, x_max.floor() as i64 + margin);
    let (rr0, rr1) = (y_min.floor() as i64 - margin, y_max.floor() as i64 + margin);
    let (h, w) = (info.size.1 as i64, info.size.0 as i64);
    if rr1 < 0 || rr0 >= h || (!info.wraps && (c1 < 0 || c0 >= w)) {
        return Ok(());
    }
    let cols = if info.wraps { (c1 - c0 + 1).min(w) } else { c1.min(w - 1) - c0.max(0) + 1 };
    let bytes = (cols.max(1) * (rr1.min(h - 1) - rr0.max(0) + 1).max(1)) as usize * 8;
    if bytes > plan.window_cap_bytes && rows > 1 {
        let half = rows / 2;
        fill_from_source(reader, plan, fx, fy, r0, half, n, k, values)?;
        return fill_from_source(reader, plan, fx, fy, r0 + half, rows - half, n, k, values);
    }
    let win = reader.window(c0, c1, rr0, rr1)?;
    if kk == 1 {
        // One point per sample: its value, or NaN (what the loop below gives, without the mean).
        let bilinear = plan.resampling == Resampling::Bilinear;
        for (s, target) in values[r0 * n..(r0 + rows) * n].iter_mut().enumerate() {
            if target.is_nan() {
                let (x, y) = (xs[s], ys[s]);
                *target = match bilinear.then(|| bilinear_inside(&win, info.size, x, y)).flatten() {
                    Some(v) => v,
                    None => interpolate(&win, info.size, info.wraps, x, y, plan.resampling),
                };
            }
        }
        return Ok(());
    }
    for s in 0..rows * n {
        let target = &mut values[r0 * n + s];
        if !target.is_nan() {
            continue;
        }
        let mut sum = 0.0;
        let mut count = 0u32;
        for sub in 0..kk {
            let v = interpolate(&win, info.size, info.wraps, xs[s * kk + sub], ys[s * kk + sub], plan.resampling);
            if !v.is_nan() {
                sum += v;
                count += 1;
            }
        }
        if 2 * count as usize >= kk.max(1) && count > 0 {
            *target = sum / f64::from(count);
        }
    }
    Ok(())
}

/// The smallest and largest finite values of `v` (∞ and −∞ when it has none), in four
/// independent lanes: a single fold is one long chain of dependent min/max.
fn finite_range(v: &[f64]) -> (f64, f64) {
    let mut lo = [f64::INFINITY; 4];
    let mut hi = [f64::NEG_INFINITY; 4];
    let chunks = v.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..4 {
            let x = c[k];
            if x.abs() < f64::INFINITY {
                if x < lo[k] {
                    lo[k] = x;
                }
                if x > hi[k] {
                    hi[k] = x;
                }
            }
        }
    }
    for &x in rest {
        if x.abs() < f64::INFINITY {
            lo[0] = lo[0].min(x);
            hi[0] = hi[0].max(x);
        }
    }
    (lo.into_iter().fold(f64::INFINITY, f64::min), hi.into_iter().fold(f64::NEG_INFINITY, f64::max))
}

/// Interpolates a window at fractional pixel-centre coordinates (fx, fy). NaN outside the
/// raster's area; within half a pixel of its edge the edge pixels are extended.
#[inline]
pub fn interpolate(win: &Window, size: (usize, usize), wraps: bool, fx: f64, fy: f64, how: Resampling) -> f64 {
    let (w, h) = (size.0 as f64, size.1 as f64);
    if !(fx.is_finite() && fy.is_finite()) || fy < -0.5 || fy > h - 0.5 || (!wraps && (fx < -0.5 || fx > w - 0.5)) {
        return f64::NAN;
    }
    let col = |c: i64| if wraps { c } else { c.clamp(0, size.0 as i64 - 1) };
    let row = |r: i64| r.clamp(0, size.1 as i64 - 1);
    let px = |c: i64, r: i64| win.get(col(c), row(r));
    match how {
        Resampling::Nearest => px((fx + 0.5).floor() as i64, (fy + 0.5).floor() as i64),
        Resampling::Bilinear => {
            // Inside the raster and the window with four samples of data: the same sum as
            // `bilinear`, in the same order, without its per-sample checks.
            bilinear_inside(win, size, fx, fy).unwrap_or_else(|| bilinear(&px, fx, fy))
        }
        Resampling::Cubic => {
            let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
            let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
            let (wx, wy) = (keys(tx), keys(ty));
            let mut sum = 0.0;
            for (b, wyb) in wy.iter().enumerate() {
                for (a, wxa) in wx.iter().enumerate() {
                    let v = px(x0 - 1 + a as i64, y0 - 1 + b as i64);
                    if v.is_nan() {
                        return bilinear(&px, fx, fy);
                    }
                    sum += wxa * wyb * v;
                }
            }
            sum
        }
    }
}

/// Bilinear interpolation where the four pixels around (fx, fy) lie inside the raster and the
/// window and all have data: the same sum as [`bilinear`], in the same order, without its
/// per-pixel checks (None elsewhere). A zero weight adds ±0 to a sum that starts at +0: skipping
/// it, as `bilinear` does, gives the same bits.
#[inline(always)]
fn bilinear_inside(win: &Window, size: (usize, usize), fx: f64, fy: f64) -> Option<f64> {
    // Also false for NaN; for x ≥ 0 the truncation is the floor.
    if !(fx >= 0.0 && fy >= 0.0 && fx < (size.0 - 1) as f64 && fy < (size.1 - 1) as f64) {
        return None;
    }
    let (c, r) = (fx as i64, fy as i64);
    let v = win.block(c, r)?;
    if (v[0] + v[1] + v[2] + v[3]).is_nan() {
        return None;
    }
    let (tx, ty) = (fx - c as f64, fy - r as f64);
    let w = [(1.0 - tx) * (1.0 - ty), tx * (1.0 - ty), (1.0 - tx) * ty, tx * ty];
    let sum = 0.0 + w[0] * v[0] + w[1] * v[1] + w[2] * v[2] + w[3] * v[3];
    let weight = w[0] + w[1] + w[2] + w[3];
    (weight >= 1e-5).then(|| sum / weight)
}

fn bilinear(px: &dyn Fn(i64, i64) -> f64, fx: f64, fy: f64) -> f64 {
    let (x0, y0) = (fx.floor() as i64, fy.floor() as i64);
    let (tx, ty) = (fx - x0 as f64, fy - y0 as f64);
    let mut sum = 0.0;
    let mut weight = 0.0;
    for (dx, dy, wgt) in
        [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
    {
        let v = px(x0 + dx, y0 + dy);
        if !v.is_nan() && wgt > 0.0 {
            sum += wgt * v;
            weight += wgt;
        }
    }
    if weight < 1e-5 { f64::NAN } else { sum / weight }
}

/// Keys' cubic convolution weights (a = −0.5) for the four pixels around a fraction t.
fn keys(t: f64) -> [f64; 4] {
    let a = -0.5;
    let near = |x: f64| ((a + 2.0) * x - (a + 3.0)) * x * x + 1.0;
    let far = |x: f64| ((a * x - 5.0 * a) * x + 8.0 * a) * x - 4.0 * a;
    [far(1.0 + t), near(t), near(1.0 - t), far(2.0 - t)]
}

/// Geoid heights → ellipsoidal heights (h = H + N) through PROJ, at the samples' positions.
fn convert_heights(t: &CoordTransform, body: &Ellipsoid, quad: QuadId, j0: i64, rows: usize, values: &mut [f64]) {
    let (mut xs, mut ys) = band_positions(body, quad, j0, rows, 1);
    let mut zs: Vec<f64> = values.iter().map(|v| if v.is_nan() { 0.0 } else { *v }).collect();
    if t.transform_coords(&mut xs, &mut ys, &mut zs).is_ok() {
        for (v, z) in values.iter_mut().zip(zs) {
            if !v.is_nan() {
                *v = z;
            }
        }
    } else {
        values.iter_mut().for_each(|v| *v = f64::NAN);
    }
}

/// A coarser quad from its level below: each sample the area mean of its cell (weights ¼ ½ ¼
/// per axis over the child samples at and beside it, across quad and face edges:
/// [`crate::ecm::area_mean`]), ignoring no data; no data where less than half the cell has data.
pub fn average_quad(reader: &mut GridReader, quad: QuadId) -> Result<Option<QuadGrid>, StoreError> {
    // The region `ecm::area_mean::fill_area_mean_region` describes, read as `GridReader::sample` reads each
    // sample (the same quad and place for every sample, so the same values), but along a row a
    // run of samples in one quad takes one look-up of its grid instead of one per sample.
    let span = AREA_MEAN_SPAN;
    let child = quad.level + 1;
    let m = grid::intervals_per_face_edge(child);
    let last = (1i64 << child) - 1;
    let (ci0, cj0) = (2 * i64::from(quad.x) * i64::from(TILE) - 1, 2 * i64::from(quad.y) * i64::from(TILE) - 1);
    let mut region = vec![f32::NAN; span * span];
    for b in 0..span {
        let j = cj0 + b as i64;
        let row = &mut region[b * span..(b + 1) * span];
        let mut a = 0;
        while a < span {
            let i = ci0 + a as i64;
            if !((0..=m).contains(&i) && (0..=m).contains(&j)) {
                // Off the face: folded onto the next one, sample by sample.
                row[a] = reader.sample(quad.face, child, i, j)?;
                a += 1;
                continue;
            }
            let (q, li, lj) = grid::quad_of_sample(quad.face, child, i, j);
            // The samples of this row that `quad_of_sample` puts in the same quad: up to its
            // last column, or the face's last sample for the face's last quad.
            let end = if i64::from(q.x) == last { m } else { (i64::from(q.x) + 1) * i64::from(TILE) - 1 };
            let len = ((end - i + 1) as usize).min(span - a);
            match reader.grid(q)? {
                Some(g) => {
                    for (t, v) in row[a..a + len].iter_mut().enumerate() {
                        *v = g.get(li + t as u32, lj);
                    }
                }
                None => row[a..a + len].fill(f32::NAN),
            }
            a += len;
        }
    }
    let grid = QuadGrid { values: area_mean(quad, &region) };
    Ok((!grid.is_empty()).then_some(grid))
}

#[cfg(test)]
mod tests {
    #[test]
    fn the_finite_range_is_the_fold_over_finite_values() {
        let fold = |v: &[f64]| {
            v.iter()
                .filter(|x| x.is_finite())
                .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &x| (a.min(x), b.max(x)))
        };
        let cases: [&[f64]; 5] = [
            &[],
            &[f64::NAN, f64::INFINITY, f64::NEG_INFINITY],
            &[3.0, f64::NAN, -2.0, 7.5, f64::INFINITY, 0.25, -9.0],
            &[1.0, 2.0, 3.0, 4.0, 5.0, 6.0, 7.0, 8.0, -1e300],
            &[-0.0, 0.0, f64::NAN, 1e-300],
        ];
        for v in cases {
            assert_eq!(super::finite_range(v), fold(v), "{v:?}");
        }
    }
}
