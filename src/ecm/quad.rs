//! Quadtree quads on the cube faces: ids down to level 30, parents, children, neighbours across
//! face edges, extents in face coordinates and sample grids.

use std::fmt;

use glam::I64Vec3;

use super::face::Edge;
use super::{EcmError, Face, FacePoint};

/// The deepest quadtree level: 2³⁰ quads along a face edge (≈ 1 cm on Earth).
pub const MAX_LEVEL: u8 = 30;

/// A quad of the quadtree on one face. Level 0 is the whole face. `x` counts columns from the
/// face's west edge (x = −1) and `y` rows from its south edge (y = −1), both in [0, 2^level).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct QuadId {
    /// The cube face this quad lies on.
    pub face: Face,
    /// Quadtree level, 0 ..= [`MAX_LEVEL`].
    pub level: u8,
    /// Column index from the face's west edge.
    pub x: u32,
    /// Row index from the face's south edge.
    pub y: u32,
}

/// An axis-aligned rectangle in face coordinates.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct FaceRect {
    /// West bound of x.
    pub x_min: f64,
    /// East bound of x.
    pub x_max: f64,
    /// South bound of y.
    pub y_min: f64,
    /// North bound of y.
    pub y_max: f64,
}

/// How a neighbour across an edge sees our frame: the number of counter-clockwise quarter turns
/// that take a vector in our face frame to the neighbour's face frame (0 when both quads are on
/// the same face).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Neighbour {
    /// The neighbouring quad, at the same level.
    pub quad: QuadId,
    /// Counter-clockwise quarter turns from our frame to the neighbour's, 0..=3.
    pub quarter_turns: u8,
}

impl QuadId {
    /// A quad, checked: level ≤ 30 and x, y < 2^level.
    pub fn new(face: Face, level: u8, x: u32, y: u32) -> Result<QuadId, EcmError> {
        if level > MAX_LEVEL || u64::from(x) >= 1u64 << level || u64::from(y) >= 1u64 << level {
            return Err(EcmError::InvalidQuad { level, x, y });
        }
        Ok(QuadId { face, level, x, y })
    }

    /// The root quad of a face.
    pub fn root(face: Face) -> QuadId {
        QuadId { face, level: 0, x: 0, y: 0 }
    }

    /// Quads along one face edge at this level: 2^level.
    pub fn quads_per_edge(self) -> u64 {
        1u64 << self.level
    }

    /// The parent quad, or `None` for a root.
    pub fn parent(self) -> Option<QuadId> {
        (self.level > 0).then(|| QuadId { face: self.face, level: self.level - 1, x: self.x / 2, y: self.y / 2 })
    }

    /// The quad at `level` that contains this one: itself at its own level or a finer `level`.
    pub fn ancestor_at(self, level: u8) -> QuadId {
        if level >= self.level {
            return self;
        }
        let k = self.level - level;
        QuadId { face: self.face, level, x: self.x >> k, y: self.y >> k }
    }

    /// Its ancestors, the parent first, up to its face's root.
    pub fn ancestors(self) -> impl Iterator<Item = QuadId> {
        std::iter::successors(self.parent(), |q| q.parent())
    }

    /// The four children in the order south-west, south-east, north-west, north-east, or `None`
    /// at [`MAX_LEVEL`].
    pub fn children(self) -> Option<[QuadId; 4]> {
        if self.level >= MAX_LEVEL {
            return None;
        }
        let c = |dx: u32, dy: u32| QuadId {
            face: self.face,
            level: self.level + 1,
            x: 2 * self.x + dx,
            y: 2 * self.y + dy,
        };
        Some([c(0, 0), c(1, 0), c(0, 1), c(1, 1)])
    }

    /// The quad's extent in face coordinates. Exact: the bounds are dyadic fractions.
    pub fn extent(self) -> FaceRect {
        let n = self.quads_per_edge() as f64;
        FaceRect {
            x_min: -1.0 + 2.0 * f64::from(self.x) / n,
            x_max: -1.0 + 2.0 * f64::from(self.x + 1) / n,
            y_min: -1.0 + 2.0 * f64::from(self.y) / n,
            y_max: -1.0 + 2.0 * f64::from(self.y + 1) / n,
        }
    }

    /// Face coordinates of sample (i, j) of an `n`×`n` grid that spans the quad corner to corner
    /// (i along x, j along y, both in 0..n; n ≥ 2). Neighbouring quads compute bit-identical
    /// coordinates for their shared edge samples, because both evaluate the same integer
    /// numerator over the same denominator; with n − 1 a power of two every value is exact.
    pub fn sample_xy(self, n: u32, i: u32, j: u32) -> (f64, f64) {
        let cells = u64::from(n.max(2) - 1);
        let denominator = (cells << self.level) as f64;
        let sx = (u64::from(self.x) * cells + u64::from(i)) as f64;
        let sy = (u64::from(self.y) * cells + u64::from(j)) as f64;
        (-1.0 + 2.0 * sx / denominator, -1.0 + 2.0 * sy / denominator)
    }

    /// The quad at `level` that contains a face point. Points on a boundary between quads go
    /// to the quad east or north of it; x = 1 or y = 1 go to the last quad.
    pub fn containing(p: FacePoint, level: u8) -> Result<QuadId, EcmError> {
        if level > MAX_LEVEL {
            return Err(EcmError::InvalidQuad { level, x: 0, y: 0 });
        }
        if !(p.x.abs() <= 1.0 && p.y.abs() <= 1.0) {
            return Err(EcmError::OutsideFace { x: p.x, y: p.y });
        }
        let n = 1u64 << level;
        let index = |v: f64| (((v + 1.0) * 0.5 * n as f64).floor() as u64).min(n - 1) as u32;
        Ok(QuadId { face: p.face, level, x: index(p.x), y: index(p.y) })
    }

    /// The neighbour at the same level across one edge, on this face or on the adjacent face,
    /// with the rotation between the two frames. Exact integer arithmetic at every level.
    pub fn neighbour(self, edge: Edge) -> Neighbour {
        let s = 1i64 << self.level;
        // Quad centre in units of 1/2^level of the half face: odd integers in (−s, s).
        let (dx, dy) = edge.step();
        let u = 2 * i64::from(self.x) + 1 - s + 2 * dx;
        let v = 2 * i64::from(self.y) + 1 - s + 2 * dy;
        if u.abs() < s && v.abs() < s {
            return Neighbour { quad: self.with_centre(self.face, u, v), quarter_turns: 0 };
        }
        let (new_face, nu, nv) = fold_onto_face(self.face, s, u, v).expect("one step crosses one edge");
        let quad = self.with_centre(new_face, nu, nv);
        let c = ivec(self.face.center());
        let e = ivec(self.face.x_axis());
        let beyond = if u.abs() >= s { e * u.signum() } else { ivec(self.face.y_axis()) * v.signum() };
        let new_e = ivec(new_face.x_axis());
        let new_n = ivec(new_face.y_axis());
        // Rotation: where our x axis (pointing along the surface) goes on the new face.
        let our_x_there = fold_direction(e, beyond, c);
        let (ex, ey) = (our_x_there.dot(new_e), our_x_there.dot(new_n));
        let quarter_turns = match (ex, ey) {
            (1, 0) => 0,
            (0, 1) => 1,
            (-1, 0) => 2,
            _ => 3,
        };
        Neighbour { quad, quarter_turns }
    }

    fn with_centre(self, face: Face, u: i64, v: i64) -> QuadId {
        let s = 1i64 << self.level;
        QuadId { face, level: self.level, x: ((u + s - 1) / 2) as u32, y: ((v + s - 1) / 2) as u32 }
    }
}

/// Folds a point given in integer face units (the face spans −s..=s along both axes) that lies
/// off the face across one edge onto the adjacent face, keeping its distance from the shared edge
/// and its position along it: returns the adjacent face and the point's coordinates there, in
/// the same units. Points on the face come back unchanged; points beyond a cube corner (off the
/// face along both axes) have no such fold and give `None`. Exact integer arithmetic.
pub fn fold_onto_face(face: Face, s: i64, u: i64, v: i64) -> Option<(Face, i64, i64)> {
    match (u.abs() > s, v.abs() > s) {
        (false, false) => return Some((face, u, v)),
        (true, true) => return None,
        _ => {}
    }
    let c = ivec(face.center());
    let e = ivec(face.x_axis());
    let n = ivec(face.y_axis());
    let (beyond, excess, along) =
        if u.abs() > s { (e * u.signum(), u.abs() - s, n * v) } else { (n * v.signum(), v.abs() - s, e * u) };
    let new_face = Face::of_direction(beyond.as_dvec3());
    let point = beyond * s + c * (s - excess) + along;
    Some((new_face, point.dot(ivec(new_face.x_axis())), point.dot(ivec(new_face.y_axis()))))
}

fn ivec(v: glam::DVec3) -> I64Vec3 {
    I64Vec3::new(v.x as i64, v.y as i64, v.z as i64)
}

/// A tangent direction `t` of the old face, carried over the edge whose outward direction is
/// `beyond` onto the new face (whose outward centre is `beyond`): the component along `beyond`
/// turns into the inward direction −c of the old centre.
fn fold_direction(t: I64Vec3, beyond: I64Vec3, old_centre: I64Vec3) -> I64Vec3 {
    let along_edge = t - beyond * t.dot(beyond);
    along_edge - old_centre * t.dot(beyond)
}

impl fmt::Display for QuadId {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "{}/{}/{}/{}", self.face, self.level, self.x, self.y)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::CubeProjection;

    #[test]
    fn parent_children_roundtrip_to_level_30() {
        let mut q = QuadId::root(Face::Left);
        for level in 0..MAX_LEVEL {
            let kids = q.children().unwrap();
            for k in kids {
                assert_eq!(k.parent(), Some(q));
                assert_eq!(k.level, level + 1);
            }
            q = kids[(level % 4) as usize];
        }
        assert_eq!(q.level, 30);
        assert!(q.children().is_none());
        assert!(QuadId::new(Face::Top, 31, 0, 0).is_err());
        assert!(QuadId::new(Face::Top, 2, 4, 0).is_err());
        let e = q.extent();
        assert!(e.x_max > e.x_min && e.y_max > e.y_min);
        assert_eq!(e.x_max - e.x_min, 2.0 / (1u64 << 30) as f64);
    }

    #[test]
    fn the_ancestor_at_a_level_is_the_walk_up_through_parents() {
        let q = QuadId::new(Face::Bottom, 12, 3001, 17).unwrap();
        let walked: Vec<QuadId> = q.ancestors().collect();
        assert_eq!(walked.len(), 12);
        assert_eq!(walked.last().copied(), Some(QuadId::root(Face::Bottom)));
        for (k, a) in walked.iter().enumerate() {
            assert_eq!(q.ancestor_at(11 - k as u8), *a);
        }
        assert_eq!(q.ancestor_at(12), q);
        assert_eq!(q.ancestor_at(20), q);
    }

    #[test]
    fn neighbours_are_mutual_at_every_level_and_edge() {
        for face in Face::ALL {
            for level in [0u8, 1, 3, 30] {
                let last = ((1u64 << level) - 1) as u32;
                let mid = last / 2;
                for (x, y) in [(0, 0), (last, 0), (0, last), (last, last), (mid, 0), (last, mid)] {
                    let q = QuadId::new(face, level, x, y).unwrap();
                    for edge in Edge::ALL {
                        let nb = q.neighbour(edge);
                        // Walking back from the neighbour in the rotated opposite direction returns here.
                        let back = Edge::ALL.into_iter().filter(|e2| nb.quad.neighbour(*e2).quad == q).count();
                        assert!(back >= 1, "{q} {edge:?} → {} has no way back", nb.quad);
                        assert_ne!(nb.quad, q);
                    }
                }
            }
        }
    }

    #[test]
    fn neighbour_across_face_edge_is_the_mirror_image() {
        // The cube, and QSC with it, is symmetric under reflection in the plane through the
        // body centre and a face edge; that reflection maps a quad next to the edge onto its
        // neighbour across it. Check it on every edge of every face at level 4.
        let p = CubeProjection::Qsc;
        let centre = |q: QuadId| {
            let e = q.extent();
            p.direction_from_face_point(FacePoint {
                face: q.face,
                x: 0.5 * (e.x_min + e.x_max),
                y: 0.5 * (e.y_min + e.y_max),
            })
        };
        for face in Face::ALL {
            for edge in Edge::ALL {
                let (q, beyond) = match edge {
                    Edge::East => (QuadId::new(face, 4, 15, 5).unwrap(), face.x_axis()),
                    Edge::West => (QuadId::new(face, 4, 0, 5).unwrap(), -face.x_axis()),
                    Edge::North => (QuadId::new(face, 4, 5, 15).unwrap(), face.y_axis()),
                    Edge::South => (QuadId::new(face, 4, 5, 0).unwrap(), -face.y_axis()),
                };
                let nb = q.neighbour(edge).quad;
                assert_eq!(nb.face, Face::of_direction(beyond), "{q} {edge:?}");
                let m = (face.center() - beyond).normalize();
                let d = centre(q);
                let mirrored = d - 2.0 * d.dot(m) * m;
                assert!((mirrored - centre(nb)).length() < 1e-14, "{q} {edge:?} → {nb}: {mirrored} vs {}", centre(nb));
            }
        }
    }

    #[test]
    fn shared_edge_samples_are_bit_identical() {
        let a = QuadId::new(Face::Front, 7, 10, 20).unwrap();
        let b = a.neighbour(Edge::East).quad;
        for j in 0..65 {
            assert_eq!(a.sample_xy(65, 64, j), b.sample_xy(65, 0, j));
        }
        let (x0, y0) = a.sample_xy(65, 0, 0);
        let e = a.extent();
        assert_eq!((x0, y0), (e.x_min, e.y_min));
        assert_eq!(a.sample_xy(65, 64, 64), (e.x_max, e.y_max));
    }

    #[test]
    fn containing_finds_the_quad() {
        let q = QuadId::containing(FacePoint { face: Face::Top, x: 0.3, y: -0.9 }, 5).unwrap();
        let e = q.extent();
        assert!(e.x_min <= 0.3 && 0.3 < e.x_max && e.y_min <= -0.9 && -0.9 < e.y_max);
        assert_eq!(QuadId::containing(FacePoint { face: Face::Top, x: 1.0, y: 1.0 }, 3).unwrap().x, 7);
        assert!(QuadId::containing(FacePoint { face: Face::Top, x: 1.5, y: 0.0 }, 3).is_err());
    }
}
