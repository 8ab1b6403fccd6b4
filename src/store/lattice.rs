//! Where a quad's samples fall in a source, fast: the exact chain (face point → QSC inverse →
//! geodetic → PROJ → source pixel) evaluated on a coarse lattice over the quad and interpolated
//! in between (tensor-product cubic Lagrange), with the interpolation error measured on every
//! quad.
//!
//! The mapping is smooth within a quad, so cubic interpolation with nodes `h` samples apart errs
//! by about h⁴ times its fourth derivative (bilinear would err by h²/8 times the second: 10⁻⁴
//! pixel at 16 samples on SRTM, millimetres of height on steep slopes). Every cell's centre is
//! also computed exactly and compared with the interpolated value:
//! if any differs by more than [`TOLERANCE_PX`] source pixels, the lattice is refined (16, 8, 4
//! samples), and if that is not enough (a pole, the antimeridian of a projected source, a point
//! PROJ cannot transform) the quad is computed exactly, sample by sample, as before. So the
//! lattice's error is bounded by a measurement on the quad itself, not assumed.
//!
//! gdalwarp's default approximate transformer interpolates linearly along rows with an error
//! threshold of 0.125 pixel; this one is held to 10⁻⁶ pixel.

use std::sync::atomic::{AtomicU64, Ordering};

use super::source::SourceReader;
use crate::ecm::grid::{self, TILE, cubic_weights};
use crate::ecm::{CubeProjection, FacePoint, QuadId};
use crate::geodesy::Ellipsoid;

/// The largest difference allowed between an interpolated and an exact position, in source
/// pixels, at the centres of the lattice cells.
pub const TOLERANCE_PX: f64 = 1e-6;

/// Lattice spacings tried, in samples, coarsest first.
pub const SPACINGS: [usize; 3] = [16, 8, 4];

/// How positions in a source are computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transform {
    /// Every sample's position exactly.
    Exact,
    /// The exact positions on a lattice, interpolated within the tolerance (else exact).
    Lattice,
}

impl Transform {
    /// The name used on the command line and in the store.
    pub fn name(self) -> &'static str {
        match self {
            Transform::Exact => "exact",
            Transform::Lattice => "lattice",
        }
    }
}

impl std::str::FromStr for Transform {
    type Err = crate::Invalid;
    fn from_str(s: &str) -> Result<Self, crate::Invalid> {
        match s {
            "exact" => Ok(Transform::Exact),
            "lattice" => Ok(Transform::Lattice),
            _ => Err(format!("unknown transform '{s}': use lattice or exact").into()),
        }
    }
}

/// What the lattice did over an import, gathered from every worker.
#[derive(Debug, Default)]
pub struct LatticeStats {
    /// Quads (per source) interpolated at each of [`SPACINGS`].
    pub by_spacing: [AtomicU64; 3],
    /// Quads (per source) computed exactly because no lattice met the tolerance anywhere in them.
    pub exact: AtomicU64,
    /// Cells of 16² samples of split quads computed exactly.
    pub exact_cells: AtomicU64,
    /// Quads (per source) whose lattice did not meet the tolerance and were split into
    /// [`BLOCKS`]² blocks, each with its own lattice (counted in `by_spacing`) or split again
    /// into cells with a lattice or exact.
    pub split: AtomicU64,
    /// The largest error measured at a cell centre of an accepted lattice, pixels (f64 bits).
    max_error_bits: AtomicU64,
}

impl LatticeStats {
    /// The largest error measured at an accepted lattice's cell centres, source pixels.
    pub fn max_error_px(&self) -> f64 {
        f64::from_bits(self.max_error_bits.load(Ordering::Relaxed))
    }

    fn record_error(&self, e: f64) {
        // Non-negative floats order as their bits do.
        self.max_error_bits.fetch_max(e.to_bits(), Ordering::Relaxed);
    }

    /// A copy of the counts: lattices per spacing (whole quads, blocks or cells), exact quads
    /// and cells, quads split into blocks, and the largest error.
    pub fn summary(&self) -> LatticeSummary {
        LatticeSummary {
            by_spacing: self.by_spacing.each_ref().map(|a| a.load(Ordering::Relaxed)),
            exact: self.exact.load(Ordering::Relaxed),
            exact_cells: self.exact_cells.load(Ordering::Relaxed),
            split: self.split.load(Ordering::Relaxed),
            max_error_px: self.max_error_px(),
        }
    }
}

/// [`LatticeStats`] read out.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct LatticeSummary {
    /// Lattices at 16, 8 and 4 samples (whole quads, or blocks and cells of split quads).
    pub by_spacing: [u64; 3],
    /// Quads computed exactly.
    pub exact: u64,
    /// Cells (16² samples) of split quads computed exactly.
    pub exact_cells: u64,
    /// Quads split into blocks.
    pub split: u64,
    /// The largest error at a cell centre of an accepted lattice, source pixels.
    pub max_error_px: f64,
}

/// Blocks per axis of a quad whose whole lattice misses the tolerance: 4 (64 samples each); a
/// block whose own lattices miss it too is split again into 4×4 cells of 16 samples.
pub const BLOCKS: usize = 4;

/// Cells per axis of a split quad: [`BLOCKS`]² (16 samples each), the finest split.
const CELLS: usize = BLOCKS * BLOCKS;

/// Where a quad's samples fall in one source: one lattice over the quad; or, where that misses
/// the tolerance (a pole, a seam, the kinks of the QSC projection along a face's diagonals,
/// points PROJ cannot transform), a lattice per block of 64 samples, or per cell of 16 samples
/// within the blocks that miss it, with the exact chain only in the cells that still miss it; or
/// the exact chain everywhere.
pub enum QuadPositions {
    /// One lattice.
    Whole(PixelLattice),
    /// A split quad: the lattices of its blocks and cells, and per cell (row-major, [`CELLS`]²)
    /// the lattice that covers it, or `None` for the exact chain.
    Blocks {
        /// The quad's span along u and v, samples from its corner.
        span: [[f64; 2]; 2],
        /// The lattices.
        lattices: Vec<PixelLattice>,
        /// Per cell, its lattice's index.
        cells: Vec<Option<u16>>,
    },
    /// The exact chain everywhere (`--transform exact`, or a geometry a lattice cannot follow).
    Exact,
}

impl QuadPositions {
    /// The positions of a quad in a source, counted in `stats`.
    pub fn build(
        reader: &SourceReader,
        body: &Ellipsoid,
        quad: QuadId,
        span_u: [f64; 2],
        span_v: [f64; 2],
        stats: &LatticeStats,
    ) -> QuadPositions {
        // The whole quad at 16 and 8 samples; what misses the tolerance there is split.
        if let Some(l) = PixelLattice::build(reader, body, quad, span_u, span_v, &SPACINGS[..2], stats) {
            return QuadPositions::Whole(l);
        }
        let part = |s: [f64; 2], b: usize, parts: usize| {
            let w = (s[1] - s[0]) / parts as f64;
            [s[0] + b as f64 * w, s[0] + (b + 1) as f64 * w]
        };
        let mut lattices = Vec::new();
        let mut cells = vec![None; CELLS * CELLS];
        for k in 0..BLOCKS * BLOCKS {
            let (bu, bv) = (k % BLOCKS, k / BLOCKS);
            let block = PixelLattice::build(
                reader,
                body,
                quad,
                part(span_u, bu, BLOCKS),
                part(span_v, bv, BLOCKS),
                &SPACINGS,
                stats,
            );
            for c in 0..BLOCKS * BLOCKS {
                let (cu, cv) = (bu * BLOCKS + c % BLOCKS, bv * BLOCKS + c / BLOCKS);
                let cell = match &block {
                    Some(_) => Some(lattices.len()),
                    // A cell of 16 samples takes a lattice of 4 (5 nodes per axis) or none.
                    None => PixelLattice::build(
                        reader,
                        body,
                        quad,
                        part(span_u, cu, CELLS),
                        part(span_v, cv, CELLS),
                        &SPACINGS[2..],
                        stats,
                    )
                    .map(|l| {
                        lattices.push(l);
                        lattices.len() - 1
                    }),
                };
                cells[cv * CELLS + cu] = cell.map(|i| i as u16);
            }
            if let Some(l) = block {
                lattices.push(l);
            }
        }
        let exact = cells.iter().filter(|c| c.is_none()).count() as u64;
        if exact == (CELLS * CELLS) as u64 {
            // Not one cell could be interpolated: the quad counts once, as exact.
            stats.exact.fetch_add(1, Ordering::Relaxed);
            return QuadPositions::Exact;
        }
        stats.exact_cells.fetch_add(exact, Ordering::Relaxed);
        stats.split.fetch_add(1, Ordering::Relaxed);
        QuadPositions::Blocks { span: [span_u, span_v], lattices, cells }
    }

    /// The lattice of a split quad that covers a point `(u, v)`, if any.
    pub fn block(&self, u: f64, v: f64) -> Option<&PixelLattice> {
        match self {
            QuadPositions::Blocks { span, lattices, cells } => {
                let index = |x: f64, s: [f64; 2]| {
                    (((x - s[0]) / (s[1] - s[0]) * CELLS as f64).floor().max(0.0) as usize).min(CELLS - 1)
                };
                cells[index(v, span[1]) * CELLS + index(u, span[0])].map(|i| &lattices[usize::from(i)])
            }
            _ => None,
        }
    }
}

/// Source pixel-centre coordinates over a quad, interpolated from a lattice.
pub struct PixelLattice {
    /// Nodes per axis.
    n: usize,
    /// The first node and the distance between nodes along each axis, in samples from the
    /// quad's corner.
    origin: [f64; 2],
    step: [f64; 2],
    xs: Vec<f64>,
    ys: Vec<f64>,
    /// A geographic source's 360° in pixels: interpolated columns are brought into the
    /// source's own range as the exact path brings longitudes.
    period_px: Option<f64>,
    /// The error measured at the cell centres, pixels.
    pub error_px: f64,
    /// The spacing used, samples.
    pub spacing: usize,
}

/// The exact pixel-centre coordinates of points given in samples from a quad's corner
/// (clamped to the face), NaN where PROJ cannot transform them.
pub fn exact_positions(
    reader: &SourceReader,
    body: &Ellipsoid,
    quad: QuadId,
    us: &[f64],
    vs: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let m = grid::intervals_per_face_edge(quad.level) as f64;
    let (i0, j0) = (f64::from(quad.x) * f64::from(TILE), f64::from(quad.y) * f64::from(TILE));
    let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = us
        .iter()
        .zip(vs)
        .map(|(&u, &v)| {
            let x = (-1.0 + 2.0 * (i0 + u) / m).clamp(-1.0, 1.0);
            let y = (-1.0 + 2.0 * (j0 + v) / m).clamp(-1.0, 1.0);
            let (lat, lon) = CubeProjection::Qsc
                .geodetic_from_face_point(body, FacePoint { face: quad.face, x, y })
                .unwrap_or((f64::NAN, f64::NAN));
            (lon.to_degrees(), lat.to_degrees())
        })
        .unzip();
    reader.centre_coords(&mut xs, &mut ys);
    (xs, ys)
}

impl PixelLattice {
    /// The coarsest lattice over the quad's samples `span_u × span_v` (samples from its
    /// corner) whose cell centres all lie within the tolerance; `None` when none does or the
    /// source's geometry does not allow one (a rotated geographic grid).
    pub fn build(
        reader: &SourceReader,
        body: &Ellipsoid,
        quad: QuadId,
        span_u: [f64; 2],
        span_v: [f64; 2],
        spacings: &[usize],
        stats: &LatticeStats,
    ) -> Option<PixelLattice> {
        let info = reader.info();
        let period_px = if info.geographic {
            // Pixel columns per degree of longitude, and the other terms of the inverse
            // geotransform, which must be zero (no rotation) for the period to be a column shift.
            let (o, east, north) = (info.pixel(0.0, 0.0), info.pixel(1.0, 0.0), info.pixel(0.0, 1.0));
            let per_degree = east.0 - o.0;
            if !(per_degree > 0.0 && east.1 == o.1 && north.0 == o.0) {
                return None;
            }
            Some(360.0 * per_degree)
        } else {
            None
        };
        for &spacing in spacings {
            let longest = (span_u[1] - span_u[0]).max(span_v[1] - span_v[0]);
            let cells = (longest / spacing as f64).ceil().max(1.0) as usize;
            let n = cells + 1;
            let origin = [span_u[0], span_v[0]];
            let step = [(span_u[1] - span_u[0]) / cells as f64, (span_v[1] - span_v[0]) / cells as f64];
            let mut us = Vec::with_capacity(n * n + cells * cells);
            let mut vs = Vec::with_capacity(us.capacity());
            for b in 0..n {
                for a in 0..n {
                    us.push(origin[0] + a as f64 * step[0]);
                    vs.push(origin[1] + b as f64 * step[1]);
                }
            }
            for b in 0..cells {
                for a in 0..cells {
                    us.push(origin[0] + (a as f64 + 0.5) * step[0]);
                    vs.push(origin[1] + (b as f64 + 0.5) * step[1]);
                }
            }
            let (mut xs, ys) = exact_positions(reader, body, quad, &us, &vs);
            if xs.iter().chain(&ys).any(|v| !v.is_finite()) {
                break;
            }
            if let Some(p) = period_px {
                // Columns continuous across the source's own seam, relative to the first node.
                let reference = xs[0];
                for x in &mut xs {
                    *x -= p * ((*x - reference) / p).round();
                }
            }
            let mut lattice = PixelLattice {
                n,
                origin,
                step,
                xs: xs[..n * n].to_vec(),
                ys: ys[..n * n].to_vec(),
                period_px: None,
                error_px: 0.0,
                spacing,
            };
            let mut error = 0.0f64;
            for c in 0..cells * cells {
                let (x, y) = lattice.at(us[n * n + c], vs[n * n + c]);
                error = error.max((x - xs[n * n + c]).abs()).max((y - ys[n * n + c]).abs());
            }
            if error <= TOLERANCE_PX {
                lattice.period_px = period_px;
                lattice.error_px = error;
                let k = SPACINGS.iter().position(|&s| s == spacing).unwrap_or(SPACINGS.len() - 1);
                stats.by_spacing[k].fetch_add(1, Ordering::Relaxed);
                stats.record_error(error);
                return Some(lattice);
            }
        }
        None
    }

    /// The interpolated pixel-centre coordinates of a point `(u, v)` samples from the quad's
    /// corner.
    pub fn at(&self, u: f64, v: f64) -> (f64, f64) {
        let (bu, wu) = self.u_weights(u);
        let (bv, wv) = cubic_weights((v - self.origin[1]) / self.step[1], self.n);
        let n = self.n;
        let mix = |g: &[f64]| -> f64 {
            (0..4).map(|b| wv[b] * (0..4).map(|a| wu[a] * g[(bv + b) * n + bu + a]).sum::<f64>()).sum()
        };
        (self.own_column(mix(&self.xs)), mix(&self.ys))
    }

    /// An interpolated column brought into a geographic source's own 360° range, as the exact
    /// path brings longitudes (unchanged for other sources).
    #[inline(always)]
    fn own_column(&self, x: f64) -> f64 {
        match self.period_px {
            Some(p) if !(-0.5..p - 0.5).contains(&x) => (x + 0.5).rem_euclid(p) - 0.5,
            _ => x,
        }
    }

    /// The first node and weights of the cubic along u at `u` samples from the quad's corner.
    pub fn u_weights(&self, u: f64) -> (usize, [f64; 4]) {
        cubic_weights((u - self.origin[0]) / self.step[0], self.n)
    }

    /// The lattice interpolated along v at one row of points: what [`LatticeRow::at`] then
    /// interpolates along u (the tensor-product cubic, done once per row).
    pub fn row(&self, v: f64) -> LatticeRow<'_> {
        let (base, w) = cubic_weights((v - self.origin[1]) / self.step[1], self.n);
        let n = self.n;
        let mix =
            |g: &[f64]| -> Vec<f64> { (0..n).map(|a| (0..4).map(|j| w[j] * g[(base + j) * n + a]).sum()).collect() };
        LatticeRow { lattice: self, xs: mix(&self.xs), ys: mix(&self.ys) }
    }
}

/// One row of a lattice, interpolated along v.
pub struct LatticeRow<'a> {
    lattice: &'a PixelLattice,
    xs: Vec<f64>,
    ys: Vec<f64>,
}

impl LatticeRow<'_> {
    /// The interpolated pixel-centre coordinates at `u` samples from the quad's corner.
    pub fn at(&self, u: f64) -> (f64, f64) {
        self.at_weights(&self.lattice.u_weights(u))
    }

    /// [`LatticeRow::at_weights`] at every point of a row at once, into `xs` and `ys` (the
    /// same arithmetic, so the same bits; one pass without the column wrap's branch, then the
    /// wrap where the source has one).
    pub fn fill(&self, weights: &[(usize, [f64; 4])], xs: &mut [f64], ys: &mut [f64]) {
        let mix = |g: &[f64], &(base, w): &(usize, [f64; 4])| {
            let g = &g[base..base + 4];
            w[0] * g[0] + w[1] * g[1] + w[2] * g[2] + w[3] * g[3]
        };
        for ((x, y), w) in xs.iter_mut().zip(ys.iter_mut()).zip(weights) {
            *x = mix(&self.xs, w);
            *y = mix(&self.ys, w);
        }
        if self.lattice.period_px.is_some() {
            for x in xs {
                *x = self.lattice.own_column(*x);
            }
        }
    }

    /// The same at a point whose weights along u ([`PixelLattice::u_weights`]) are known: the
    /// same for every row, so computed once per quad.
    #[inline(always)]
    pub fn at_weights(&self, &(base, w): &(usize, [f64; 4])) -> (f64, f64) {
        let mix = |g: &[f64]| w[0] * g[base] + w[1] * g[base + 1] + w[2] * g[base + 2] + w[3] * g[base + 3];
        (self.lattice.own_column(mix(&self.xs)), mix(&self.ys))
    }
}
