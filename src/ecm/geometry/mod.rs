//! Static per-quad geometry of the ECM (paper, section 4): the quad's corners on the ellipsoid in
//! ECEF (f64), and per sample the displacement from the corner patch to the ellipsoid surface and
//! the ellipsoid normal, computed in f64 and stored as f32. Also the single-precision
//! reconstruction that the vertex shader performs, written here as the CPU reference it is tested
//! against.
//!
//! Samples: an n×n grid that spans the quad corner to corner ([`QuadId::sample_xy`]), so that
//! neighbouring quads share their edge samples exactly, across face edges too.
//!
//! Three departures from the paper, each measured (see docs/decisions.md):
//! - **Split along the face diagonal.** QSC is only piecewise smooth: kinked along the face
//!   diagonals. A bilinear patch across the kink misses it by O(L) (the displacement only halves
//!   per level); the quads the diagonal crosses are interpolated as two triangles split along it
//!   ([`Split`]), which restores the O(L²) convergence.
//! - **Reference height.** The shader adds h₀·δn and (h − h₀)·nₑ to corners raised to h₀ in f64,
//!   instead of h·nₑ to corners on the ellipsoid, so a camera close to high terrain does not lose
//!   2⁻²⁴·|h| to cancellation ([`QuadGeometry::frame`]).
//! - **Per-quad flat rule.** QSC is not differentiable at the face centres either, so quads near
//!   them converge only linearly; the maps are dropped per quad, not per level ([`FlatRule`]).

mod bounds;
mod cutoff;
mod symmetry;

use std::collections::HashMap;
use std::sync::{Arc, Mutex};

use glam::{DVec3, Vec3};

pub use bounds::QuadBounds;
pub use cutoff::{CutoffRow, FlatRule, HeightRange, QuadExtremes, cutoff_table, quad_extremes};
pub use symmetry::{MapSymmetry, distinct_maps_per_level};

use super::{CubeProjection, FacePoint, QuadId};
use crate::geodesy::{self, Ellipsoid};

/// 2⁻²⁴: the relative rounding error of an f32, and so the f32 limit of a camera-relative
/// position P − C is |P − C|·2⁻²⁴.
pub const F32_EPSILON: f64 = 1.0 / 16_777_216.0;

/// Default samples along a quad edge: 2^8 + 1, the paper's 256 cells per quad edge.
pub const DEFAULT_SAMPLES: u32 = 257;

/// How the corner patch of a quad is interpolated between its four corners.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Split {
    /// Bilinear: the quad is crossed by no face diagonal, or by both (level 0).
    Bilinear,
    /// Two triangles split along the south-west–north-east diagonal, which is the face diagonal
    /// y = x: (SW, SE, NE) where s ≥ t, (SW, NW, NE) where t > s.
    MainDiagonal,
    /// Two triangles split along the south-east–north-west diagonal, the face diagonal y = −x:
    /// (SW, SE, NW) where s + t ≤ 1, (NE, NW, SE) beyond.
    AntiDiagonal,
}

impl Split {
    /// The split of a quad: along the face diagonal that passes through two of its corners.
    pub fn of(quad: QuadId) -> Split {
        let last = (1u64 << quad.level) - 1;
        match (quad.x == quad.y, u64::from(quad.x) + u64::from(quad.y) == last) {
            (true, false) => Split::MainDiagonal,
            (false, true) => Split::AntiDiagonal,
            _ => Split::Bilinear,
        }
    }

    /// Shader code for the split (keep in sync with `shaders/`): 0, 1, 2.
    pub fn code(self) -> u32 {
        self as u32
    }
}

/// Interpolates four corner values (SW, SE, NW, NE) at (s, t) ∈ [0, 1]² in f64. The triangles
/// use barycentric weights, so that corners come out exactly and the values on the quad's edges
/// are bit-identical to the bilinear patch's (neighbours of either kind agree on them).
pub fn interpolate_f64(split: Split, q: &[DVec3; 4], s: f64, t: f64) -> DVec3 {
    match split {
        Split::Bilinear => bilerp_f64(q, s, t),
        Split::MainDiagonal if s >= t => q[0] * (1.0 - s) + q[1] * (s - t) + q[3] * t,
        Split::MainDiagonal => q[0] * (1.0 - t) + q[2] * (t - s) + q[3] * s,
        Split::AntiDiagonal if s + t <= 1.0 => q[0] * ((1.0 - s) - t) + q[1] * s + q[2] * t,
        Split::AntiDiagonal => q[1] * (1.0 - t) + q[2] * (1.0 - s) + q[3] * ((s + t) - 1.0),
    }
}

/// [`interpolate_f64`] in f32: the same expressions, in the same order, as the vertex shader.
pub fn interpolate_f32(split: Split, q: &[Vec3; 4], s: f32, t: f32) -> Vec3 {
    match split {
        Split::Bilinear => bilerp_f32(q, s, t),
        Split::MainDiagonal if s >= t => q[0] * (1.0 - s) + q[1] * (s - t) + q[3] * t,
        Split::MainDiagonal => q[0] * (1.0 - t) + q[2] * (t - s) + q[3] * s,
        Split::AntiDiagonal if s + t <= 1.0 => q[0] * ((1.0 - s) - t) + q[1] * s + q[2] * t,
        Split::AntiDiagonal => q[1] * (1.0 - t) + q[2] * (1.0 - s) + q[3] * ((s + t) - 1.0),
    }
}

/// Bilinear interpolation of four corners (SW, SE, NW, NE) at (s, t) ∈ [0, 1]², in f64.
pub fn bilerp_f64(q: &[DVec3; 4], s: f64, t: f64) -> DVec3 {
    (q[0] * (1.0 - s) + q[1] * s) * (1.0 - t) + (q[2] * (1.0 - s) + q[3] * s) * t
}

/// Bilinear interpolation in f32, the same expression as the vertex shader.
pub fn bilerp_f32(q: &[Vec3; 4], s: f32, t: f32) -> Vec3 {
    (q[0] * (1.0 - s) + q[1] * s) * (1.0 - t) + (q[2] * (1.0 - s) + q[3] * s) * t
}

/// The ellipsoid surface point and unit normal (ECEF) for face coordinates.
pub fn surface_and_normal(ellipsoid: &Ellipsoid, projection: CubeProjection, p: FacePoint) -> (DVec3, DVec3) {
    let s = geodesy::surface_point_from_direction(ellipsoid, projection.direction_from_face_point(p));
    let (a2, b2) = (ellipsoid.a_m() * ellipsoid.a_m(), ellipsoid.b_m() * ellipsoid.b_m());
    let n = DVec3::new(s.x / a2, s.y / a2, s.z / b2).normalize();
    (s, n)
}

/// Quad-relative coordinates (s, t) of sample (i, j) of an n×n grid.
pub fn sample_st(samples: u32, i: u32, j: u32) -> (f64, f64) {
    let cells = f64::from(samples - 1);
    (f64::from(i) / cells, f64::from(j) / cells)
}

/// The corners of a quad on the ellipsoid (SW, SE, NW, NE) and the ellipsoid normals there.
pub fn quad_corners(ellipsoid: &Ellipsoid, projection: CubeProjection, quad: QuadId) -> ([DVec3; 4], [DVec3; 4]) {
    let mut points = [DVec3::ZERO; 4];
    let mut normals = [DVec3::ZERO; 4];
    // The exact dyadic corners, bit-identical to the corner samples of any grid.
    for (k, (i, j)) in [(0, 0), (1, 0), (0, 1), (1, 1)].into_iter().enumerate() {
        let (x, y) = quad.sample_xy(2, i, j);
        (points[k], normals[k]) = surface_and_normal(ellipsoid, projection, FacePoint { face: quad.face, x, y });
    }
    (points, normals)
}

/// The static maps of one sample, in f64: displacement oₑ = S − patch(Q), normal nₑ, and the
/// normal's departure from the interpolated corner normals δn = nₑ − patch(n_Q).
pub fn sample_maps_f64(
    ellipsoid: &Ellipsoid,
    projection: CubeProjection,
    quad: QuadId,
    corners: &([DVec3; 4], [DVec3; 4]),
    samples: u32,
    i: u32,
    j: u32,
) -> [DVec3; 3] {
    let split = Split::of(quad);
    let (x, y) = quad.sample_xy(samples, i, j);
    let (point, normal) = surface_and_normal(ellipsoid, projection, FacePoint { face: quad.face, x, y });
    let (s, t) = sample_st(samples, i, j);
    [point - interpolate_f64(split, &corners.0, s, t), normal, normal - interpolate_f64(split, &corners.1, s, t)]
}

/// The static maps of one quad, computed in f64 and stored in f32, in ECEF axes of that quad.
/// Shared by every quad that [`MapSymmetry`] folds onto it.
#[derive(Clone, Debug, PartialEq)]
pub struct StaticMaps {
    /// The quad they were computed for.
    pub quad: QuadId,
    /// Samples along an edge (n ≥ 2).
    pub samples: u32,
    /// Per sample (row-major, j·n + i): oₑ = S − patch(Q, s, t), metres.
    pub displacement_m: Vec<Vec3>,
    /// Per sample: the unit ellipsoid normal nₑ.
    pub normal: Vec<Vec3>,
    /// Per sample: δn = nₑ − patch(n_Q, s, t), the normal's departure from the interpolated
    /// corner normals (unitless); the reference-height term h₀·δn needs it.
    pub normal_delta: Vec<Vec3>,
}

impl StaticMaps {
    /// Computes the maps of `quad` with `samples` per edge.
    pub fn compute(ellipsoid: &Ellipsoid, projection: CubeProjection, quad: QuadId, samples: u32) -> StaticMaps {
        let n = samples.max(2);
        let corners = quad_corners(ellipsoid, projection, quad);
        let count = (n * n) as usize;
        let (mut displacement_m, mut normal, mut normal_delta) =
            (Vec::with_capacity(count), Vec::with_capacity(count), Vec::with_capacity(count));
        for j in 0..n {
            for i in 0..n {
                let [o, nn, dn] = sample_maps_f64(ellipsoid, projection, quad, &corners, n, i, j);
                displacement_m.push(o.as_vec3());
                normal.push(nn.as_vec3());
                normal_delta.push(dn.as_vec3());
            }
        }
        StaticMaps { quad, samples: n, displacement_m, normal, normal_delta }
    }

    /// Bytes the three maps take (what a GPU copy costs).
    pub fn size_bytes(&self) -> usize {
        3 * self.displacement_m.len() * std::mem::size_of::<Vec3>()
    }
}

/// A cache of shared static maps, keyed by canonical quad and sample count. Thread-safe; the
/// maps are computed outside the lock, so two threads may compute the same maps once each.
#[derive(Default)]
pub struct MapCache {
    maps: Mutex<HashMap<(QuadId, u32), Arc<StaticMaps>>>,
}

impl MapCache {
    /// An empty cache.
    pub fn new() -> MapCache {
        MapCache::default()
    }

    /// The shared maps for the canonical quad of `symmetry`, computed on first use.
    pub fn get(
        &self,
        ellipsoid: &Ellipsoid,
        projection: CubeProjection,
        symmetry: MapSymmetry,
        samples: u32,
    ) -> Arc<StaticMaps> {
        let key = (symmetry.canonical, samples);
        if let Some(maps) = self.lock().get(&key) {
            return maps.clone();
        }
        let maps = Arc::new(StaticMaps::compute(ellipsoid, projection, symmetry.canonical, samples));
        self.lock().entry(key).or_insert(maps).clone()
    }

    /// Distinct maps held.
    pub fn len(&self) -> usize {
        self.lock().len()
    }

    /// Whether the cache holds no maps.
    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, HashMap<(QuadId, u32), Arc<StaticMaps>>> {
        // A panic while holding the lock cannot leave the map half-written (insert is atomic
        // from the map's point of view), so a poisoned lock is still usable.
        self.maps.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
    }
}

/// Everything the renderer needs to place one quad's vertices: exact corners and corner
/// normals, the split, and (unless the quad is past the flat rule) the shared static maps.
#[derive(Clone, Debug)]
pub struct QuadGeometry {
    /// The quad.
    pub quad: QuadId,
    /// Samples along an edge (n ≥ 2).
    pub samples: u32,
    /// How the corner patch is interpolated.
    pub split: Split,
    /// Corners on the ellipsoid surface in ECEF metres: SW (s = 0, t = 0), SE, NW, NE.
    pub corners_ecef: [DVec3; 4],
    /// Unit ellipsoid normals at the corners, ECEF.
    pub corner_normals: [DVec3; 4],
    /// The shared maps, or `None` where the flat patch is within tolerance.
    pub maps: Option<Arc<StaticMaps>>,
    /// How this quad reads the shared maps.
    pub symmetry: MapSymmetry,
}

/// The per-frame, per-quad values the renderer uploads. The quad's corners, raised to the
/// reference height h₀, are split in f64 into an anchor A (their mean) and small offsets from it;
/// only the anchor is made camera-relative, so the f32 sum adds one large term, once.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadFrame {
    /// A′ = A − C, subtracted in f64, cast to f32.
    pub anchor: Vec3,
    /// Qₖ + h₀·n_Qₖ − A plus the rounding of A′ (A − C − A′), in f64, cast to f32: quad-sized,
    /// so rounded to 2⁻²⁴ of the quad.
    pub corners: [Vec3; 4],
    /// Corner normals n_Qₖ in f32.
    pub corner_normals: [Vec3; 4],
    /// The reference height h₀, metres.
    pub reference_height_m: f32,
}

impl QuadFrame {
    /// The frame for a camera at `camera_ecef` and reference height `h0_m`. h₀ is rounded to f32
    /// first, so that the f64 corners and the shader's h − h₀ use the same value.
    pub fn new(corners_ecef: &[DVec3; 4], corner_normals: &[DVec3; 4], camera_ecef: DVec3, h0_m: f64) -> QuadFrame {
        let h0 = f64::from(h0_m as f32);
        let raised: [DVec3; 4] = std::array::from_fn(|k| corners_ecef[k] + corner_normals[k] * h0);
        let anchor = raised.iter().sum::<DVec3>() * 0.25;
        let anchor_relative = anchor - camera_ecef;
        let anchor_f32 = anchor_relative.as_vec3();
        // The cast's rounding goes into the small offsets (the patch weights sum to one), so the
        // large term carries no rounding of its own: only the final sum rounds at camera scale.
        let residual = anchor_relative - anchor_f32.as_dvec3();
        QuadFrame {
            anchor: anchor_f32,
            corners: raised.map(|q| ((q - anchor) + residual).as_vec3()),
            corner_normals: corner_normals.map(|n| n.as_vec3()),
            reference_height_m: h0 as f32,
        }
    }
}

/// The vertex shader's computation in f32 (keep in sync with `shaders/`), with the maps
/// `[oₑ, nₑ, δn]` of the vertex (ECEF axes):
/// P = A′ + (patch(Q − A, s, t) + oₑ + h₀·δn + (h − h₀)·nₑ), and past the flat rule (no maps)
/// P = A′ + (patch(Q − A, s, t) + (h − h₀)·normalize(patch(n_Q, s, t))).
/// Everything inside the brackets is quad-sized; A′ is added last, once.
pub fn vertex_f32(split: Split, frame: &QuadFrame, s: f32, t: f32, maps: Option<[Vec3; 3]>, height_m: f32) -> Vec3 {
    let base = interpolate_f32(split, &frame.corners, s, t);
    let h0 = frame.reference_height_m;
    let local = match maps {
        Some([o, n, dn]) => base + o + dn * h0 + n * (height_m - h0),
        None => base + interpolate_f32(split, &frame.corner_normals, s, t).normalize() * (height_m - h0),
    };
    frame.anchor + local
}

impl QuadGeometry {
    /// A quad's geometry with its maps computed now (through the symmetry, unshared).
    pub fn compute(ellipsoid: &Ellipsoid, projection: CubeProjection, quad: QuadId, samples: u32) -> QuadGeometry {
        let symmetry = MapSymmetry::of(quad);
        let maps = Arc::new(StaticMaps::compute(ellipsoid, projection, symmetry.canonical, samples.max(2)));
        QuadGeometry::with_maps(ellipsoid, projection, quad, samples, Some(maps))
    }

    /// A quad's geometry with its maps from `cache`, or none if `rule` says the quad is flat.
    pub fn cached(
        ellipsoid: &Ellipsoid,
        projection: CubeProjection,
        quad: QuadId,
        samples: u32,
        cache: &MapCache,
        rule: Option<&FlatRule>,
    ) -> QuadGeometry {
        let flat = rule.is_some_and(|r| r.is_flat(quad));
        let maps = (!flat).then(|| cache.get(ellipsoid, projection, MapSymmetry::of(quad), samples.max(2)));
        QuadGeometry::with_maps(ellipsoid, projection, quad, samples, maps)
    }

    /// A quad's geometry with the given maps (computed for its canonical quad), or flat.
    pub fn with_maps(
        ellipsoid: &Ellipsoid,
        projection: CubeProjection,
        quad: QuadId,
        samples: u32,
        maps: Option<Arc<StaticMaps>>,
    ) -> QuadGeometry {
        let (corners_ecef, corner_normals) = quad_corners(ellipsoid, projection, quad);
        QuadGeometry {
            quad,
            samples: samples.max(2),
            split: Split::of(quad),
            corners_ecef,
            corner_normals,
            maps,
            symmetry: MapSymmetry::of(quad),
        }
    }

    fn map_value(&self, map: impl Fn(&StaticMaps) -> &Vec<Vec3>, i: u32, j: u32) -> Option<Vec3> {
        let maps = self.maps.as_ref()?;
        let (ci, cj) = self.symmetry.canonical_sample(self.samples, i, j);
        let v = map(maps)[(cj * self.samples + ci) as usize];
        Some(self.symmetry.ecef_from_canonical_f32(v))
    }

    /// The three maps [oₑ, nₑ, δn] at sample (i, j) in ECEF axes (f32, as stored), or `None` for
    /// a flat quad: what the vertex stage reads.
    pub fn maps_at(&self, i: u32, j: u32) -> Option<[Vec3; 3]> {
        let maps = self.maps.as_ref()?;
        let (ci, cj) = self.symmetry.canonical_sample(self.samples, i, j);
        let k = (cj * self.samples + ci) as usize;
        Some(
            [maps.displacement_m[k], maps.normal[k], maps.normal_delta[k]]
                .map(|v| self.symmetry.ecef_from_canonical_f32(v)),
        )
    }

    /// oₑ at sample (i, j) in ECEF axes (f32, as stored), or `None` for a flat quad.
    pub fn displacement(&self, i: u32, j: u32) -> Option<Vec3> {
        self.map_value(|m| &m.displacement_m, i, j)
    }

    /// nₑ at sample (i, j) in ECEF axes, or `None` for a flat quad.
    pub fn normal(&self, i: u32, j: u32) -> Option<Vec3> {
        self.map_value(|m| &m.normal, i, j)
    }

    /// δn at sample (i, j) in ECEF axes, or `None` for a flat quad.
    pub fn normal_delta(&self, i: u32, j: u32) -> Option<Vec3> {
        self.map_value(|m| &m.normal_delta, i, j)
    }

    /// The per-frame values for a camera at `camera_ecef` and a reference height h₀: the
    /// renderer picks h₀ per quad as the camera's height clamped to the quad's height range, so
    /// that h − h₀ is small wherever the terrain is close to the camera. h₀ = 0 is the paper's
    /// formulation.
    pub fn frame(&self, camera_ecef: DVec3, reference_height_m: f64) -> QuadFrame {
        QuadFrame::new(&self.corners_ecef, &self.corner_normals, camera_ecef, reference_height_m)
    }

    /// The vertex shader's computation for sample (i, j) at `height_m`: see [`vertex_f32`].
    pub fn position_f32(&self, frame: &QuadFrame, i: u32, j: u32, height_m: f32) -> Vec3 {
        let (s, t) = sample_st(self.samples, i, j);
        vertex_f32(self.split, frame, s as f32, t as f32, self.maps_at(i, j), height_m)
    }

    /// The exact (f64) camera-relative position of sample (i, j) at `height_m` along the
    /// normal: the truth that the single-precision paths are measured against.
    pub fn exact_position(
        &self,
        ellipsoid: &Ellipsoid,
        projection: CubeProjection,
        camera_ecef: DVec3,
        i: u32,
        j: u32,
        height_m: f64,
    ) -> DVec3 {
        let (x, y) = self.quad.sample_xy(self.samples, i, j);
        let (s, n) = surface_and_normal(ellipsoid, projection, FacePoint { face: self.quad.face, x, y });
        (s - camera_ecef) + n * height_m
    }

    /// Largest |oₑ| over the quad, metres (0 for a flat quad).
    pub fn max_displacement_m(&self) -> f32 {
        self.maps.as_ref().map_or(0.0, |m| m.displacement_m.iter().map(|o| o.length()).fold(0.0, f32::max))
    }
}

#[cfg(test)]
mod tests;
