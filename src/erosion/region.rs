//! A region of the planet as one erosion grid: the samples of a level over a box of one face's
//! global sample indices, the box allowed to run past the face's edges (the indices are folded
//! onto the adjacent faces with the store's fold, so the grid is contiguous across a face edge;
//! beyond a cube corner there is no sample and the cell is a no-data sink). Cell lengths are the
//! chords to the next samples on the ellipsoid, areas their products; terrain heights come from
//! the caller (the composed elevation below the erosion layer, per quad).

use std::collections::HashMap;

use glam::DVec3;

use super::grid::Grid;
use crate::ecm::grid::{GRID, TILE, fold_sample, quad_of_sample, spacing_m};
use crate::ecm::points::sample_point;
use crate::ecm::{Face, QuadId};
use crate::errors::{Failure, Invalid};
use crate::geodesy::{Ellipsoid, GeoBox};

/// The longest side between two points of a region's outline, metres (see [`Region::outline`]).
pub const OUTLINE_STEP_M: f64 = 4000.0;

/// A box of global sample indices of one face at one level (it may run past the face's edges).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Region {
    /// The face whose index space the box is in.
    pub face: Face,
    /// The level of the samples.
    pub level: u8,
    /// The first sample along x (may be negative: on the adjacent face).
    pub i0: i64,
    /// The first sample along y.
    pub j0: i64,
    /// Samples along x.
    pub width: usize,
    /// Samples along y.
    pub height: usize,
}

/// Sample (i, j) of face `other` in the extended index space of `face` (beyond one of its
/// edges), or None when `other` is not adjacent to `face`. The fold is a rigid map of the integer
/// lattice across each edge: it is found by folding three points just beyond the edge, then
/// inverted.
fn unfold(face: Face, other: Face, level: u8, i: i64, j: i64) -> Option<(i64, i64)> {
    let m = crate::ecm::grid::intervals_per_face_edge(level);
    let c = m / 2;
    // Three points just beyond each edge: a base, one step further out, one step along.
    let edges = [
        [(m + 1, c), (m + 2, c), (m + 1, c + 1)],
        [(-1, c), (-2, c), (-1, c + 1)],
        [(c, m + 1), (c, m + 2), (c + 1, m + 1)],
        [(c, -1), (c, -2), (c + 1, -1)],
    ];
    for [p0, p1, p2] in edges {
        let (Some((f0, a0, b0)), Some((_, a1, b1)), Some((_, a2, b2))) = (
            fold_sample(face, level, p0.0, p0.1),
            fold_sample(face, level, p1.0, p1.1),
            fold_sample(face, level, p2.0, p2.1),
        ) else {
            continue;
        };
        if f0 != other {
            continue;
        }
        // folded = q0 + A·(ext − p0), A's columns the images of the steps out and along.
        let (e_out, e_along) = ((p1.0 - p0.0, p1.1 - p0.1), (p2.0 - p0.0, p2.1 - p0.1));
        let (img_out, img_along) = ((a1 - a0, b1 - b0), (a2 - a0, b2 - b0));
        // A maps e_out → img_out and e_along → img_along; both bases are orthonormal integer
        // vectors, so A⁻¹ takes d = (i − a0, j − b0) to its components along the images.
        let d = (i - a0, j - b0);
        let s_out = d.0 * img_out.0 + d.1 * img_out.1;
        let s_along = d.0 * img_along.0 + d.1 * img_along.1;
        return Some((p0.0 + s_out * e_out.0 + s_along * e_along.0, p0.1 + s_out * e_out.1 + s_along * e_along.1));
    }
    None
}

/// Where one cell of a region lives: its folded face, sample indices there, and its quad.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CellAt {
    /// The quad holding the sample.
    pub quad: QuadId,
    /// The sample's column in the quad's 257² grid.
    pub i: u32,
    /// Its row.
    pub j: u32,
}

/// The most cells a region may have along each side (the GPU's buffers for 4096² cells are
/// 537 MB each; the CPU reference takes seconds per step there).
pub const MAX_SIDE: usize = 4096;

impl Region {
    /// The region covering a box (a checked [`GeoBox`]: it may cross the antimeridian) rounded
    /// out to whole quads of `level`, in the index space of the face under the box's centre;
    /// quads on adjacent faces are placed there by inverting the store's fold (exact, integer),
    /// so a box across a face edge or a cube corner is one contiguous grid. Errors name the
    /// problem.
    pub fn from_box(ellipsoid: &Ellipsoid, bounds: GeoBox, level: u8) -> Result<Region, Invalid> {
        let (lat0, lon0, lat1, lon1) =
            (bounds.south_deg, bounds.west_deg, bounds.north_deg, bounds.east_unwrapped_deg());
        if level > crate::ecm::MAX_LEVEL {
            return Err(format!("level {level} is past the finest, {}", crate::ecm::MAX_LEVEL).into());
        }
        let projection = crate::ecm::CubeProjection::Qsc;
        let m = crate::ecm::grid::intervals_per_face_edge(level);
        let index = |lat: f64, lon: f64| {
            let p = projection.face_point_from_geodetic(ellipsoid, lat.to_radians(), lon.to_radians());
            let i = (((p.x + 1.0) / 2.0 * m as f64).floor() as i64).clamp(0, m - 1);
            let j = (((p.y + 1.0) / 2.0 * m as f64).floor() as i64).clamp(0, m - 1);
            (p.face, i, j)
        };
        let (face, ..) = index(0.5 * (lat0 + lat1), 0.5 * (lon0 + lon1));
        // Points along the box's edges and inside it, a quarter quad apart at most (and at
        // least 65 a side).
        let quad_deg = (spacing_m(ellipsoid, level) * f64::from(TILE) / ellipsoid.a_m()).to_degrees();
        // A box far too large is refused before it is walked (QSC stretches a quad's side by
        // well under a factor of 4 from its mean, so this refuses nothing the walk would accept).
        let rough_cells = (lat1 - lat0) / quad_deg * f64::from(TILE);
        if rough_cells > 4.0 * MAX_SIDE as f64 {
            return Err(format!(
                "the box {bounds} (W,S,E,N) at level {level} is about {rough_cells:.0} cells from south to north; a region has at most {MAX_SIDE} a side (choose a smaller box or a coarser level)"
            )
            .into());
        }
        let along = |span: f64| ((span / (0.25 * quad_deg)).ceil() as usize).clamp(64, 4 * MAX_SIDE);
        let (na, nb) =
            (along(lat1 - lat0), along((lon1 - lon0) * lat0.abs().max(lat1.abs()).to_radians().cos().max(0.01)));
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for a in 0..=na {
            for b in 0..=nb {
                let lat = lat0 + (lat1 - lat0) * a as f64 / na as f64;
                let lon = lon0 + (lon1 - lon0) * b as f64 / nb as f64;
                let (f, i, j) = index(lat, lon);
                let (i, j) = if f == face {
                    (i, j)
                } else {
                    unfold(face, f, level, i, j).ok_or_else(|| {
                    format!("the box {bounds} (W,S,E,N) reaches the face opposite the one under its centre: too large for one region")
                })?
                };
                lo = (lo.0.min(i), lo.1.min(j));
                hi = (hi.0.max(i), hi.1.max(j));
            }
        }
        let tile = i64::from(TILE);
        let (qx0, qy0) = (lo.0.div_euclid(tile), lo.1.div_euclid(tile));
        let (qx1, qy1) = (hi.0.div_euclid(tile), hi.1.div_euclid(tile));
        let (width, height) = (((qx1 - qx0 + 1) * tile) as usize, ((qy1 - qy0 + 1) * tile) as usize);
        if width > MAX_SIDE || height > MAX_SIDE {
            return Err(format!(
                "the box {bounds} (W,S,E,N) at level {level} is {width} × {height} cells; a region has at most {MAX_SIDE} a side (choose a smaller box or a coarser level)"
            ).into());
        }
        Ok(Region { face, level, i0: qx0 * tile, j0: qy0 * tile, width, height })
    }

    /// The region's outline as `[lon, lat]` degrees (GeoJSON order), counter-clockwise from the
    /// south-west corner, longitudes continuous (they may pass ±180): for an extent that covers
    /// the region. A side has a point every [`OUTLINE_STEP_M`] (at most 16, at least one): the
    /// side is straight on the face, and a chord that long strays from it by well under a metre
    /// (L²·tan φ / 8R: 0.3 m on Earth at 45°, 1.2 m on the Moon), while every point costs each
    /// sample a composing GPU tests in a quad the outline crosses. Points beyond a cube corner
    /// are left out.
    pub fn outline(&self, ellipsoid: &Ellipsoid) -> Vec<[f64; 2]> {
        let (w, h) = (self.width - 1, self.height - 1);
        let at = |x: usize, y: usize| self.cell(x, y).map(|c| sample_point(ellipsoid, c.quad, GRID, c.i, c.j).0);
        let points = |a: Option<DVec3>, b: Option<DVec3>| match (a, b) {
            (Some(a), Some(b)) => ((a.distance(b) / OUTLINE_STEP_M).ceil() as usize).clamp(1, 16),
            _ => 16,
        };
        let (nx, ny) = (
            points(at(0, 0), at(w, 0)).max(points(at(0, h), at(w, h))),
            points(at(0, 0), at(0, h)).max(points(at(w, 0), at(w, h))),
        );
        let side = |k: usize, cells: usize, n: usize| k * cells / n;
        let mut cells: Vec<(usize, usize)> = Vec::new();
        cells.extend((0..nx).map(|k| (side(k, w, nx), 0)));
        cells.extend((0..ny).map(|k| (w, side(k, h, ny))));
        cells.extend((0..nx).map(|k| (w - side(k, w, nx), h)));
        cells.extend((0..ny).map(|k| (0, h - side(k, h, ny))));
        let mut out: Vec<[f64; 2]> = Vec::new();
        for (x, y) in cells {
            let Some(c) = self.cell(x, y) else { continue };
            let (_, lon, lat) = sample_point(ellipsoid, c.quad, GRID, c.i, c.j);
            let mut lon = lon.to_degrees();
            if let Some(prev) = out.last() {
                lon += 360.0 * ((prev[0] - lon) / 360.0).round();
            }
            out.push([lon, lat.to_degrees()]);
        }
        out
    }

    /// The region of a quad and `ring` quads around it (in the quad's face's index space).
    pub fn around(quad: QuadId, ring: u32) -> Region {
        let tile = i64::from(TILE);
        let r = i64::from(ring) * tile;
        let side = (2 * i64::from(ring) + 1) * tile;
        Region {
            face: quad.face,
            level: quad.level,
            i0: i64::from(quad.x) * tile - r,
            j0: i64::from(quad.y) * tile - r,
            width: side as usize,
            height: side as usize,
        }
    }

    /// Cell (x, y)'s sample (None beyond a cube corner).
    pub fn cell(&self, x: usize, y: usize) -> Option<CellAt> {
        let (f, i, j) = fold_sample(self.face, self.level, self.i0 + x as i64, self.j0 + y as i64)?;
        let (quad, i, j) = quad_of_sample(f, self.level, i, j);
        Some(CellAt { quad, i, j })
    }

    /// The quads the region's cells read.
    pub fn quads(&self) -> Vec<QuadId> {
        let mut quads: Vec<QuadId> = (0..self.height)
            .flat_map(|y| (0..self.width).map(move |x| (x, y)))
            .filter_map(|(x, y)| self.cell(x, y).map(|c| c.quad))
            .collect();
        quads.sort();
        quads.dedup();
        quads
    }

    /// The region's grid: lengths and areas from the cells' points on `ellipsoid`, terrain from
    /// `heights(quad)` (257² heights, NaN where no data; errors passed through).
    pub fn grid(
        &self,
        ellipsoid: &Ellipsoid,
        heights: &dyn Fn(QuadId) -> Result<Vec<f32>, Failure>,
    ) -> Result<Grid, Failure> {
        let mut tiles: HashMap<QuadId, Vec<f32>> = HashMap::new();
        for q in self.quads() {
            let t = heights(q)?;
            if t.len() != (GRID * GRID) as usize {
                return Err(format!("the heights of {q} have {} samples, not {}", t.len(), GRID * GRID).into());
            }
            tiles.insert(q, t);
        }
        // Points one sample beyond the box on the +x and +y sides too, for the last lengths.
        let (w, h) = (self.width, self.height);
        let point = |x: usize, y: usize| -> Option<DVec3> {
            let c = self.cell(x, y)?;
            Some(sample_point(ellipsoid, c.quad, GRID, c.i, c.j).0)
        };
        let mut points = Vec::with_capacity((w + 1) * (h + 1));
        for y in 0..=h {
            for x in 0..=w {
                points.push(point(x, y));
            }
        }
        let at = |x: usize, y: usize| points[y * (w + 1) + x];
        let n = w * h;
        let (mut base, mut dx, mut dy) = (vec![f64::NAN; n], vec![0.0; n], vec![0.0; n]);
        // The level's mean spacing stands in where a neighbour is missing (beyond a corner).
        let mean = crate::ecm::grid::spacing_m(ellipsoid, self.level);
        for y in 0..h {
            for x in 0..w {
                let k = y * w + x;
                let p = at(x, y);
                dx[k] = match (p, at(x + 1, y)) {
                    (Some(a), Some(b)) => (b - a).length(),
                    _ => mean,
                };
                dy[k] = match (p, at(x, y + 1)) {
                    (Some(a), Some(b)) => (b - a).length(),
                    _ => mean,
                };
                if let Some(c) = self.cell(x, y) {
                    base[k] = f64::from(tiles[&c.quad][c.j as usize * GRID as usize + c.i as usize]);
                }
            }
        }
        let area_m2 = dx.iter().zip(&dy).map(|(a, b)| a * b).collect();
        Ok(Grid {
            width: w,
            height: h,
            base_m: base,
            area_m2,
            dx_m: dx,
            dy_m: dy,
            rain_mask: None,
            erosion_mask: None,
            hardness: None,
            pipe_weight: super::grid::PIPE_WEIGHT,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::{Geodetic, ecef_from_geodetic};

    /// The distance from `p` to the segment from `a` to `b`, metres.
    fn to_segment(p: DVec3, a: DVec3, b: DVec3) -> f64 {
        let t = ((p - a).dot(b - a) / (b - a).length_squared()).clamp(0.0, 1.0);
        p.distance(a + (b - a) * t)
    }

    #[test]
    fn the_outline_follows_the_regions_edge_within_a_metre_with_a_point_every_4_km() {
        for (e, bounds, level) in [
            (Ellipsoid::MOON, GeoBox::new(20.0, 44.9, 20.25, 45.05), 10),
            (Ellipsoid::WGS84, GeoBox::new(40.5, 39.6, 40.53, 39.62), 9),
        ] {
            let region = Region::from_box(&e, bounds.unwrap(), level).unwrap();
            let outline = region.outline(&e);
            let ring: Vec<DVec3> = outline
                .iter()
                .map(|[lon, lat]| {
                    let g = Geodetic { lat_rad: lat.to_radians(), lon_rad: lon.to_radians(), height_m: 0.0 };
                    ecef_from_geodetic(&e, g)
                })
                .collect();
            let (w, h) = (region.width - 1, region.height - 1);
            let edge = (0..=w).flat_map(|x| [(x, 0), (x, h)]).chain((0..=h).flat_map(|y| [(0, y), (w, y)]));
            let mut worst = 0f64;
            for (x, y) in edge {
                let c = region.cell(x, y).unwrap();
                let p = sample_point(&e, c.quad, GRID, c.i, c.j).0;
                let d = (0..ring.len())
                    .map(|k| to_segment(p, ring[k], ring[(k + 1) % ring.len()]))
                    .fold(f64::MAX, f64::min);
                worst = worst.max(d);
            }
            assert!(worst < 1.0, "{} points, the edge up to {worst:.3} m away", ring.len());
            let longest = (0..ring.len()).map(|k| ring[k].distance(ring[(k + 1) % ring.len()])).fold(0f64, f64::max);
            assert!(longest <= OUTLINE_STEP_M, "a side of {longest:.0} m between points");
            assert!(ring.len() < 64, "{} points for a region {w} × {h} cells", ring.len());
        }
    }
}
