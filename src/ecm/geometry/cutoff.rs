//! When the static maps can be dropped: the flat rule, and the per-level table that justifies it.
//!
//! The paper drops the maps from the level on which the largest displacement is negligible. For
//! QSC that level never comes for two families of quads, because QSC is smooth only piecewise:
//! - along the face diagonals it is kinked, which [`Split`] absorbs by splitting those quads along
//!   the diagonal (their displacement then quarters per level like everyone else's);
//! - at the face centre it is not differentiable (its Jacobian depends on the direction of
//!   approach): near the centre the map is homogeneous of degree one, so the interpolation error of
//!   a quad of side w at ring distance k from the centre is ≈ B·w/k, halving per level, not
//!   quartering.
//!
//! The rule is therefore per quad: the error of the flat patch is bounded by A·w² + B·w/k (w the
//! quad's side in face units, k its ring distance from the four centre quads, A the curvature term,
//! B the cone term), both constants fitted per ellipsoid by [`FlatRule::fit`] and checked against
//! the measured maximum on every level by [`cutoff_table`].

use glam::DVec3;
use rayon::prelude::*;

use super::{Split, bilerp_f64, interpolate_f64, quad_corners, sample_st, surface_and_normal};
use crate::ecm::{CubeProjection, Face, FacePoint, QuadId};
use crate::geodesy::Ellipsoid;

/// The heights a body's terrain spans, metres above the ellipsoid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct HeightRange {
    /// Lowest height (metres).
    pub min_m: f64,
    /// Highest height (metres).
    pub max_m: f64,
}

impl HeightRange {
    /// The preset bodies' terrain with a margin: Earth −11 000 … 9 000 m (Challenger Deep
    /// −10 935 m, Everest 8 849 m; geoid undulation ±110 m), the Moon −9 200 … 10 800 m (LOLA),
    /// Mars −8 300 … 21 300 m (MOLA, Hellas to Olympus Mons); any other body ±25 000 m.
    pub fn for_body(ellipsoid: &Ellipsoid) -> HeightRange {
        let (min_m, max_m) = match ellipsoid.name() {
            "wgs84" => (-11_000.0, 9_000.0),
            "moon" => (-9_200.0, 10_800.0),
            "mars" => (-8_300.0, 21_300.0),
            _ => (-25_000.0, 25_000.0),
        };
        HeightRange { min_m, max_m }
    }

    /// The largest |h| in the range.
    pub fn max_abs_m(self) -> f64 {
        self.min_m.abs().max(self.max_m.abs())
    }
}

/// The largest effects of the static maps over one quad, measured on a sample grid.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct QuadExtremes {
    /// Largest |oₑ| against the bilinear corner patch (the paper's), metres.
    pub displacement_bilinear_m: f64,
    /// Largest |oₑ| against the patch split along the face diagonal where one crosses, metres.
    pub displacement_m: f64,
    /// Largest angle between the ellipsoid normal and the bilinear patch's normal (the paper's
    /// measure), radians.
    pub normal_vs_patch_rad: f64,
    /// Largest |δn| = |nₑ − patch(n_Q)|, unitless.
    pub normal_delta: f64,
}

impl QuadExtremes {
    /// The most the flat path can be off by for heights up to `max_abs_height_m`:
    /// |oₑ| + |h₀·δn| + |(h − h₀)·(n̂ − nₑ)| ≤ |oₑ| + (1 + 2·2)·H·|δn| (normalising moves the
    /// interpolated normal by at most 2|δn|, and |h − h₀| ≤ 2H).
    pub fn flat_error_m(&self, max_abs_height_m: f64) -> f64 {
        self.displacement_m + 5.0 * max_abs_height_m * self.normal_delta
    }

    fn max(self, o: QuadExtremes) -> QuadExtremes {
        QuadExtremes {
            displacement_bilinear_m: self.displacement_bilinear_m.max(o.displacement_bilinear_m),
            displacement_m: self.displacement_m.max(o.displacement_m),
            normal_vs_patch_rad: self.normal_vs_patch_rad.max(o.normal_vs_patch_rad),
            normal_delta: self.normal_delta.max(o.normal_delta),
        }
    }
}

/// Measures [`QuadExtremes`] of one quad on a `samples`×`samples` grid (17 resolves them: all
/// four quantities are smooth inside each triangle of the split).
pub fn quad_extremes(ellipsoid: &Ellipsoid, projection: CubeProjection, quad: QuadId, samples: u32) -> QuadExtremes {
    let n = samples.max(3);
    let (q, qn) = quad_corners(ellipsoid, projection, quad);
    let split = Split::of(quad);
    let mut e = QuadExtremes::default();
    for j in 0..n {
        for i in 0..n {
            let (s, t) = sample_st(n, i, j);
            let (x, y) = quad.sample_xy(n, i, j);
            let (point, normal) = surface_and_normal(ellipsoid, projection, FacePoint { face: quad.face, x, y });
            let ds = (q[1] - q[0]) * (1.0 - t) + (q[3] - q[2]) * t;
            let dt = (q[2] - q[0]) * (1.0 - s) + (q[3] - q[1]) * s;
            let patch_normal: DVec3 = ds.cross(dt);
            e = e.max(QuadExtremes {
                displacement_bilinear_m: (point - bilerp_f64(&q, s, t)).length(),
                displacement_m: (point - interpolate_f64(split, &q, s, t)).length(),
                normal_vs_patch_rad: normal.cross(patch_normal).length().atan2(normal.dot(patch_normal)),
                normal_delta: (normal - interpolate_f64(split, &qn, s, t)).length(),
            });
        }
    }
    e
}

/// Chebyshev distance of a quad, in quads, from the four quads that touch the face centre
/// (0 for those four; level 0 is the centre quad itself).
pub fn centre_ring(quad: QuadId) -> u64 {
    if quad.level == 0 {
        return 0;
    }
    let m = 1u64 << (quad.level - 1);
    let d = |v: u32| if u64::from(v) >= m { u64::from(v) - m } else { m - 1 - u64::from(v) };
    d(quad.x).max(d(quad.y))
}

/// Side of a quad in face units (the face spans 2).
fn side(level: u8) -> f64 {
    2.0 / (1u64 << level) as f64
}

/// Which quads may drop their static maps: those whose flat patch is provably (by the fitted
/// bound A·w² + B·w/k) within `tolerance_m` of the ellipsoid for every height in the body's range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FlatRule {
    /// Tolerance on the position error of the flat path, metres.
    pub tolerance_m: f64,
    /// Largest |h| the rule covers, metres.
    pub max_abs_height_m: f64,
    /// A: curvature term, metres per face unit².
    pub curvature_m: f64,
    /// B: cone term (the face centre's kink), metres per face unit.
    pub cone_m: f64,
    /// If positive, the tolerance on level L is also at most this fraction of the f32 limit at
    /// the distance from which the renderer draws level L, so the flat path never costs more
    /// than the rounding the renderer cannot avoid there.
    pub limit_fraction: f64,
    /// The distance from which the renderer draws level 0, metres (level L: this / 2^L).
    pub draw_distance_level0_m: f64,
    /// The finest tolerance the f64 geometry can resolve: 8 ulp of the semi-major axis
    /// (a·2⁻⁵⁰, 5.7 nm on Earth); the draw limit never pushes the tolerance below it.
    pub resolution_m: f64,
}

/// Safety factor on the fitted constants: the largest measured ratio times 1.25.
const FIT_MARGIN: f64 = 1.25;

impl FlatRule {
    /// The default tolerance: a tenth of a millimetre.
    pub const DEFAULT_TOLERANCE_M: f64 = 1e-4;

    /// Fits A and B for an ellipsoid: B as the largest error·k/w of the quads in rings 1–16
    /// around the face centres at levels 24 and 28 (where the curvature term is below 10⁻⁸ m),
    /// A as the largest (error − B·w/k)/w² over whole faces at levels 10 and 12; each times 1.25.
    pub fn fit(ellipsoid: &Ellipsoid, projection: CubeProjection, tolerance_m: f64, heights: HeightRange) -> FlatRule {
        let h = heights.max_abs_m();
        let error = |quad: QuadId| quad_extremes(ellipsoid, projection, quad, 17).flat_error_m(h);
        let cone_quads: Vec<QuadId> = [24u8, 28]
            .into_iter()
            .flat_map(|level| [Face::Front, Face::Top].map(move |face| (level, face)))
            .flat_map(|(level, face)| {
                let m = 1u32 << (level - 1);
                (1..=16u32).flat_map(move |k| {
                    (0..=k).flat_map(move |j| [(m + k, m + j), (m + j, m + k)]).map(move |(x, y)| QuadId {
                        face,
                        level,
                        x,
                        y,
                    })
                })
            })
            .collect();
        let cone_m = FIT_MARGIN
            * cone_quads.par_iter().map(|&q| error(q) * centre_ring(q) as f64 / side(q.level)).reduce(|| 0.0, f64::max);
        let curvature_quads: Vec<QuadId> = [10u8, 12].into_iter().flat_map(scan_quads).collect();
        let curvature_m = FIT_MARGIN
            * curvature_quads
                .par_iter()
                .filter(|q| centre_ring(**q) > 0)
                .map(|&q| {
                    let w = side(q.level);
                    (error(q) - cone_m * w / centre_ring(q) as f64).max(0.0) / (w * w)
                })
                .reduce(|| 0.0, f64::max);
        FlatRule {
            tolerance_m,
            max_abs_height_m: h,
            curvature_m,
            cone_m,
            limit_fraction: 0.0,
            draw_distance_level0_m: 0.0,
            resolution_m: ellipsoid.a_m() * 2f64.powi(-50),
        }
    }

    /// Also keeps the flat path's error on level L below `fraction` of the f32 limit at the
    /// distance the renderer draws level L from (`draw_distance_level0_m` / 2^L).
    pub fn with_draw_limit(self, fraction: f64, draw_distance_level0_m: f64) -> FlatRule {
        FlatRule { limit_fraction: fraction, draw_distance_level0_m, ..self }
    }

    /// The tolerance on `level`: the absolute tolerance, or less where the draw limit asks (but
    /// not below the f64 resolution).
    pub fn level_tolerance_m(&self, level: u8) -> f64 {
        let relative = self.limit_fraction * self.draw_distance_level0_m / (1u64 << level) as f64 * super::F32_EPSILON;
        if self.limit_fraction > 0.0 { self.tolerance_m.min(relative.max(self.resolution_m)) } else { self.tolerance_m }
    }

    /// The bound on the flat path's error for a quad, metres (infinite for the centre quads).
    pub fn error_bound_m(&self, quad: QuadId) -> f64 {
        let k = centre_ring(quad);
        if k == 0 {
            return f64::INFINITY;
        }
        let w = side(quad.level);
        self.curvature_m * w * w + self.cone_m * w / k as f64
    }

    /// Whether `quad` may drop its maps.
    pub fn is_flat(&self, quad: QuadId) -> bool {
        self.error_bound_m(quad) < self.level_tolerance_m(quad.level)
    }

    /// The smallest ring distance from the face centre at which quads of `level` are flat, or
    /// `None` if none is.
    pub fn flat_ring(&self, level: u8) -> Option<u64> {
        let w = side(level);
        let room = self.level_tolerance_m(level) - self.curvature_m * w * w;
        if room <= 0.0 {
            return None;
        }
        let k = (self.cone_m * w / room).floor() as u64 + 1;
        (level > 0 && k < (1u64 << (level - 1))).then_some(k)
    }

    /// The first level on which some quads are flat.
    pub fn first_flat_level(&self) -> Option<u8> {
        (0..=crate::ecm::MAX_LEVEL).find(|&l| self.flat_ring(l).is_some())
    }

    /// The share of a face's area that is flat on `level`.
    pub fn flat_share(&self, level: u8) -> f64 {
        self.flat_ring(level).map_or(0.0, |k| 1.0 - ((2 * k) as f64 / (1u64 << level) as f64).powi(2))
    }
}

/// Quad indices along one axis that a level scan visits: all of them up to 16, else both edges,
/// the centre and an even stride between.
fn scan_indices(level: u8) -> Vec<u32> {
    let n = 1u64 << level;
    if n <= 16 {
        return (0..n as u32).collect();
    }
    let mut v: Vec<u32> = (0..=16).map(|k| ((n - 1) * k / 16) as u32).collect();
    v.extend([1, (n / 2 - 1) as u32, (n / 2) as u32, (n / 2 + 1) as u32, (n - 2) as u32]);
    v.sort_unstable();
    v.dedup();
    v
}

/// The quads a level scan visits on the front and top faces, which represent all six (see
/// [`super::MapSymmetry`]); the grid includes both face diagonals, the centre and the corners.
fn scan_quads(level: u8) -> Vec<QuadId> {
    let indices = scan_indices(level);
    [Face::Front, Face::Top]
        .into_iter()
        .flat_map(|face| {
            let indices = &indices;
            indices.iter().flat_map(move |&x| indices.iter().map(move |&y| QuadId { face, level, x, y }))
        })
        .collect()
}

/// One row of the per-level table.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct CutoffRow {
    /// Quadtree level.
    pub level: u8,
    /// Side of a quad along the equator, metres (a·π/2 / 2^level).
    pub quad_size_m: f64,
    /// Largest measured effects over the scanned quads.
    pub extremes: QuadExtremes,
    /// Ring distance from the face centre from which quads are flat, if any are.
    pub flat_ring: Option<u64>,
    /// Share of the level's area that is flat.
    pub flat_share: f64,
    /// The level's tolerance under the rule, metres.
    pub tolerance_m: f64,
    /// The largest measured flat-path error among the scanned quads the rule calls flat
    /// (must stay below the tolerance), metres.
    pub max_flat_error_m: f64,
    /// Quads scanned.
    pub quads: usize,
}

/// The per-level table for levels 0..=`max_level`: measured extremes over a scan of each level
/// (a 21×21 grid of quads on the front and top faces, plus the quads on both sides of the flat
/// rule's boundary), and what the rule makes of them.
pub fn cutoff_table(
    ellipsoid: &Ellipsoid,
    projection: CubeProjection,
    rule: &FlatRule,
    max_level: u8,
    samples: u32,
) -> Vec<CutoffRow> {
    (0..=max_level.min(crate::ecm::MAX_LEVEL))
        .map(|level| {
            let mut quads = scan_quads(level);
            if let Some(k) = rule.flat_ring(level) {
                let m = 1u64 << (level - 1);
                for face in [Face::Front, Face::Top] {
                    for ring in [k - 1, k, k + 1].into_iter().filter(|&r| r < m) {
                        for offset in [0, ring / 2, ring] {
                            let (a, b) = ((m + ring) as u32, (m + offset.min(ring)) as u32);
                            quads.push(QuadId { face, level, x: a, y: b });
                            quads.push(QuadId { face, level, x: b, y: a });
                        }
                    }
                }
            }
            let measured: Vec<(QuadId, QuadExtremes)> =
                quads.par_iter().map(|&q| (q, quad_extremes(ellipsoid, projection, q, samples))).collect();
            let extremes = measured.iter().fold(QuadExtremes::default(), |acc, (_, e)| acc.max(*e));
            let max_flat_error_m = measured
                .iter()
                .filter(|(q, _)| rule.is_flat(*q))
                .map(|(_, e)| e.flat_error_m(rule.max_abs_height_m))
                .fold(0.0, f64::max);
            CutoffRow {
                level,
                quad_size_m: ellipsoid.a_m() * std::f64::consts::FRAC_PI_2 / (1u64 << level) as f64,
                extremes,
                flat_ring: rule.flat_ring(level),
                flat_share: rule.flat_share(level),
                tolerance_m: rule.level_tolerance_m(level),
                max_flat_error_m,
                quads: measured.len(),
            }
        })
        .collect()
}
