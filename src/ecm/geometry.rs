//! Static per-quad geometry of the ECM (paper, section 4): the quad's corners on the ellipsoid in
//! ECEF (f64), and per sample the displacement from the bilinear corner patch to the ellipsoid
//! surface and the ellipsoid normal, computed in f64 and stored as f32. Also the single-precision
//! reconstruction that the vertex shader performs, written here as the CPU reference it is tested
//! against.
//!
//! Samples: an n×n grid that spans the quad corner to corner ([`QuadId::sample_xy`]), so that
//! neighbouring quads share their edge samples exactly, across face edges too.

use glam::{DVec3, Vec3};

use super::{CubeProjection, FacePoint, QuadId};
use crate::geodesy::{self, Ellipsoid};

/// Default samples along a quad edge: 2^8 + 1, the paper's 256 cells per quad edge.
pub const DEFAULT_SAMPLES: u32 = 257;

/// The static double-precision data of one quad.
#[derive(Clone, Debug, PartialEq)]
pub struct QuadGeometry {
    /// The quad.
    pub quad: QuadId,
    /// Samples along an edge (n ≥ 2).
    pub samples: u32,
    /// Corners on the ellipsoid surface in ECEF metres: south-west (s = 0, t = 0), south-east,
    /// north-west, north-east.
    pub corners_ecef: [DVec3; 4],
    /// Per sample (row-major, j·n + i), the offset in metres from the bilinear corner patch to
    /// the ellipsoid surface point, oₑ = S − bilerp(Q, s, t).
    pub displacement_m: Vec<Vec3>,
    /// Per sample, the unit ellipsoid normal at the surface point, ECEF axes.
    pub normal: Vec<Vec3>,
}

/// The ellipsoid surface point and unit normal (ECEF) for face coordinates.
pub fn surface_and_normal(ellipsoid: &Ellipsoid, projection: CubeProjection, p: FacePoint) -> (DVec3, DVec3) {
    let s = geodesy::surface_point_from_direction(ellipsoid, projection.direction_from_face_point(p));
    let (a2, b2) = (ellipsoid.a_m() * ellipsoid.a_m(), ellipsoid.b_m() * ellipsoid.b_m());
    let n = DVec3::new(s.x / a2, s.y / a2, s.z / b2).normalize();
    (s, n)
}

/// Bilinear interpolation of four corners (SW, SE, NW, NE) at (s, t) ∈ [0, 1]², in f64.
pub fn bilerp_f64(q: &[DVec3; 4], s: f64, t: f64) -> DVec3 {
    (q[0] * (1.0 - s) + q[1] * s) * (1.0 - t) + (q[2] * (1.0 - s) + q[3] * s) * t
}

/// Bilinear interpolation in f32, the same expression as the vertex shader.
pub fn bilerp_f32(q: &[Vec3; 4], s: f32, t: f32) -> Vec3 {
    (q[0] * (1.0 - s) + q[1] * s) * (1.0 - t) + (q[2] * (1.0 - s) + q[3] * s) * t
}

impl QuadGeometry {
    /// Computes the corners and the displacement and normal maps of a quad in f64.
    pub fn compute(ellipsoid: &Ellipsoid, projection: CubeProjection, quad: QuadId, samples: u32) -> QuadGeometry {
        let n = samples.max(2);
        let at = |i: u32, j: u32| {
            let (x, y) = quad.sample_xy(n, i, j);
            surface_and_normal(ellipsoid, projection, FacePoint { face: quad.face, x, y })
        };
        let corners_ecef = [at(0, 0).0, at(n - 1, 0).0, at(0, n - 1).0, at(n - 1, n - 1).0];
        let count = (n * n) as usize;
        let mut displacement_m = Vec::with_capacity(count);
        let mut normal = Vec::with_capacity(count);
        for j in 0..n {
            for i in 0..n {
                let (s_point, n_vec) = at(i, j);
                let (s, t) = Self::st(n, i, j);
                displacement_m.push((s_point - bilerp_f64(&corners_ecef, s, t)).as_vec3());
                normal.push(n_vec.as_vec3());
            }
        }
        QuadGeometry { quad, samples: n, corners_ecef, displacement_m, normal }
    }

    /// Quad-relative coordinates (s, t) of sample (i, j).
    pub fn st(samples: u32, i: u32, j: u32) -> (f64, f64) {
        let cells = f64::from(samples - 1);
        (f64::from(i) / cells, f64::from(j) / cells)
    }

    /// The camera-relative corners Q′ = Q − C, subtracted in f64 and then cast to f32: what the
    /// renderer uploads per quad and per frame.
    pub fn camera_relative_corners(&self, camera_ecef: DVec3) -> [Vec3; 4] {
        self.corners_ecef.map(|q| (q - camera_ecef).as_vec3())
    }

    /// The exact (f64) camera-relative position of sample (i, j) at height `height_m` along the
    /// normal: the truth that the single-precision path is measured against.
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

    /// The vertex shader's computation in f32: P = bilerp(Q′, s, t) + oₑ + h·nₑ.
    pub fn position_f32(&self, corners_relative: &[Vec3; 4], i: u32, j: u32, height_m: f32) -> Vec3 {
        let index = (j * self.samples + i) as usize;
        let (s, t) = Self::st(self.samples, i, j);
        bilerp_f32(corners_relative, s as f32, t as f32) + self.displacement_m[index] + self.normal[index] * height_m
    }

    /// Largest |oₑ| over the quad, metres.
    pub fn max_displacement_m(&self) -> f32 {
        self.displacement_m.iter().map(|o| o.length()).fold(0.0, f32::max)
    }
}

/// The largest effects of the static maps on one quadtree level.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelExtremes {
    /// Quadtree level.
    pub level: u8,
    /// Largest |oₑ| in metres.
    pub max_displacement_m: f64,
    /// Largest angle in radians between the ellipsoid normal and the bilinear patch's normal.
    pub max_normal_angle_rad: f64,
    /// Quads evaluated.
    pub quads: usize,
}

/// Quad indices along one axis that the level scan visits: all of them up to 16, else both
/// edges, the centre and an even stride between (the extremes of a smooth, symmetric quantity).
fn scan_indices(level: u8) -> Vec<u32> {
    let n = 1u64 << level;
    if n <= 16 {
        return (0..n as u32).collect();
    }
    let mut v: Vec<u32> = (0..=16).map(|k| ((n - 1) * k / 16) as u32).collect();
    v.extend([1, (n / 2 - 1) as u32, (n / 2) as u32, (n - 2) as u32]);
    v.sort_unstable();
    v.dedup();
    v
}

/// Scans a level for the largest displacement and normal deviation. The ellipsoid is symmetric
/// about its axis and its equator, and the equatorial faces map onto each other by rotations
/// about the axis, as the top face maps onto the bottom by the reflection z → −z; so the front
/// and top faces represent all six. `samples` per quad edge (17 is plenty: both quantities are
/// smooth inside a quad).
pub fn level_extremes(ellipsoid: &Ellipsoid, projection: CubeProjection, level: u8, samples: u32) -> LevelExtremes {
    use rayon::prelude::*;
    let indices = scan_indices(level);
    let quads: Vec<QuadId> = [super::Face::Front, super::Face::Top]
        .into_iter()
        .flat_map(|face| {
            let indices = &indices;
            indices.iter().flat_map(move |&x| indices.iter().map(move |&y| QuadId { face, level, x, y }))
        })
        .collect();
    let (max_displacement_m, max_normal_angle_rad) = quads
        .par_iter()
        .map(|&quad| {
            let n = samples.max(3);
            let g = QuadGeometry::compute(ellipsoid, projection, quad, n);
            let q = g.corners_ecef;
            let mut worst = (0.0f64, 0.0f64);
            for j in 0..n {
                for i in 0..n {
                    let (s, t) = QuadGeometry::st(n, i, j);
                    let ds = (q[1] - q[0]) * (1.0 - t) + (q[3] - q[2]) * t;
                    let dt = (q[2] - q[0]) * (1.0 - s) + (q[3] - q[1]) * s;
                    let patch_normal = ds.cross(dt);
                    let (x, y) = quad.sample_xy(n, i, j);
                    let (point, normal) =
                        surface_and_normal(ellipsoid, projection, FacePoint { face: quad.face, x, y });
                    let displacement = (point - bilerp_f64(&q, s, t)).length();
                    let angle = normal.cross(patch_normal).length().atan2(normal.dot(patch_normal));
                    worst = (worst.0.max(displacement), worst.1.max(angle));
                }
            }
            worst
        })
        .reduce(|| (0.0, 0.0), |a, b| (a.0.max(b.0), a.1.max(b.1)));
    LevelExtremes { level, max_displacement_m, max_normal_angle_rad, quads: quads.len() }
}

/// The first level from which the static maps may be replaced by the flat patch and its normal:
/// the largest displacement is below `tolerance_m` and the normal deviation moves a point at
/// `max_height_m` by less than `tolerance_m` too. Returns the level and the scanned table.
pub fn negligible_level(
    ellipsoid: &Ellipsoid,
    projection: CubeProjection,
    tolerance_m: f64,
    max_height_m: f64,
    max_level: u8,
) -> (Option<u8>, Vec<LevelExtremes>) {
    let table: Vec<LevelExtremes> =
        (0..=max_level.min(super::MAX_LEVEL)).map(|level| level_extremes(ellipsoid, projection, level, 17)).collect();
    let cutoff = table
        .iter()
        .find(|e| e.max_displacement_m < tolerance_m && e.max_normal_angle_rad * max_height_m < tolerance_m)
        .map(|e| e.level);
    (cutoff, table)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::{Edge, Face};

    #[test]
    fn corners_have_no_displacement_and_maps_are_finite_at_the_stress_points() {
        let e = Ellipsoid::WGS84;
        let quads = [
            QuadId::root(Face::Top),
            QuadId::new(Face::Front, 1, 1, 1).unwrap(),
            QuadId::new(Face::Bottom, 12, 0, 4095).unwrap(),
            QuadId::new(Face::Left, 30, (1 << 30) - 1, (1 << 30) - 1).unwrap(),
            QuadId::new(Face::Back, 30, 1 << 29, 1 << 29).unwrap(),
        ];
        for quad in quads {
            let g = QuadGeometry::compute(&e, CubeProjection::Qsc, quad, 17);
            for (o, n) in g.displacement_m.iter().zip(&g.normal) {
                assert!(o.is_finite() && n.is_finite() && (n.length() - 1.0).abs() < 1e-6, "{quad}: {o} {n}");
            }
            for corner in [0usize, 16, 16 * 17, 17 * 17 - 1] {
                assert_eq!(g.displacement_m[corner], Vec3::ZERO, "{quad}");
            }
        }
    }

    #[test]
    fn displacement_converges_quadratically_off_the_diagonals_and_linearly_on_them() {
        // Off the face diagonals a patch of side L on a sphere of radius R deviates by O(L²/R):
        // one level down divides the displacement by 4. QSC is only piecewise smooth (kinked
        // along the face diagonals), so in the quads the diagonals cross, the bilinear patch
        // misses the kink by O(L): one level down only halves it, and those quads dominate the
        // level maximum.
        let e = Ellipsoid::MOON;
        let off = |level: u8| {
            let quad = QuadId::new(Face::Front, level, 3 << (level - 3), 1 << (level - 3)).unwrap();
            QuadGeometry::compute(&e, CubeProjection::Qsc, quad, 17).max_displacement_m() as f64
        };
        let ratio_off = off(8) / off(9);
        assert!((ratio_off - 4.0).abs() < 0.2, "off-diagonal ratio {ratio_off}");
        let d8 = level_extremes(&e, CubeProjection::Qsc, 8, 9).max_displacement_m;
        let d9 = level_extremes(&e, CubeProjection::Qsc, 9, 9).max_displacement_m;
        assert!((d8 / d9 - 2.0).abs() < 0.1, "level maxima {d8} {d9}");
    }

    #[test]
    fn neighbours_share_their_edge_exactly_across_a_face_edge() {
        let e = Ellipsoid::MARS;
        let q = QuadId::new(Face::Front, 6, 63, 20).unwrap();
        let nb = q.neighbour(Edge::East);
        assert_eq!(nb.quad.face, Face::Right);
        let a = QuadGeometry::compute(&e, CubeProjection::Qsc, q, 9);
        let b = QuadGeometry::compute(&e, CubeProjection::Qsc, nb.quad, 9);
        // East edge of `a` is the west edge of `b` (the right face's x axis continues ours).
        for j in 0..9 {
            let pa =
                bilerp_f64(&a.corners_ecef, 1.0, j as f64 / 8.0) + a.displacement_m[(j * 9 + 8) as usize].as_dvec3();
            let pb = bilerp_f64(&b.corners_ecef, 0.0, j as f64 / 8.0) + b.displacement_m[(j * 9) as usize].as_dvec3();
            assert!((pa - pb).length() < 1e-6, "sample {j}: {pa} vs {pb}");
        }
    }

    #[test]
    fn single_precision_path_is_near_the_f32_limit_close_to_the_camera() {
        let e = Ellipsoid::WGS84;
        let quad = QuadId::new(Face::Right, 14, 5000, 9000).unwrap();
        let g = QuadGeometry::compute(&e, CubeProjection::Qsc, quad, 33);
        let centre = g.exact_position(&e, CubeProjection::Qsc, DVec3::ZERO, 16, 16, 0.0);
        let up = centre.normalize();
        let camera = centre + up * 100.0;
        let q_rel = g.camera_relative_corners(camera);
        let mut worst_ratio = 0.0f64;
        for j in 0..33 {
            for i in 0..33 {
                let exact = g.exact_position(&e, CubeProjection::Qsc, camera, i, j, 0.0);
                let ours = g.position_f32(&q_rel, i, j, 0.0).as_dvec3();
                let limit = exact.length() * 2f64.powi(-24);
                worst_ratio = worst_ratio.max((ours - exact).length() / limit);
            }
        }
        // A few roundings of camera-relative values of the same size: a small multiple of the limit.
        assert!(worst_ratio < 4.0, "worst error / f32 limit = {worst_ratio}");
        // The naive path: absolute f32 ECEF coordinates err by metres at this distance.
        let naive = (g.corners_ecef[0].as_vec3().as_dvec3() - g.corners_ecef[0]).length();
        assert!(naive > 0.01, "{naive}");
    }
}
