//! Sharing the static maps by symmetry.
//!
//! The ellipsoid is symmetric under rotations about its axis and reflections in its equator and
//! in any meridian plane; QSC is defined face by face with the same formulas in every face frame.
//! So a quad's displacement and normal maps are those of one canonical quad, read at permuted
//! samples and turned by a signed permutation of the axes:
//!
//! - the four equatorial faces are images of the front face under quarter turns about the axis,
//!   and within a face the reflections x → −x (a meridian plane) and y → −y (the equator) fold
//!   every quad into the face's south-west quarter;
//! - the bottom face is the image of the top face under a half turn about an equatorial axis, and
//!   within the top face the eight symmetries of the square (reflections in meridian planes) fold
//!   every quad into the triangle x ≤ y of the south-west quarter.
//!
//! Signed permutations are exact in f32, so a shared map is read back bit for bit as stored.

use glam::{DMat3, DVec3, Vec3};

use crate::ecm::{Face, QuadId};

/// How a quad's static maps are read from those of its canonical quad.
///
/// In face coordinates, canonical → target is: first swap x and y (if `swap`), then negate x
/// (if `flip_x`) and y (if `flip_y`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct MapSymmetry {
    /// The quad whose maps are computed and shared: on the front face for the equatorial faces,
    /// on the top face for the polar ones.
    pub canonical: QuadId,
    /// The face of the quad that reads the maps.
    pub target_face: Face,
    /// Swap x and y first (polar faces only; the equator is not symmetric under it).
    pub swap: bool,
    /// Then negate face x.
    pub flip_x: bool,
    /// Then negate face y.
    pub flip_y: bool,
}

impl MapSymmetry {
    /// The symmetry that folds `quad` onto its canonical quad.
    pub fn of(quad: QuadId) -> MapSymmetry {
        let n = 1u64 << quad.level;
        // A quad is in the upper half when its index is past the middle (never at level 0).
        let upper = |v: u32| 2 * u64::from(v) + 1 > n;
        let fold = |v: u32, flip: bool| if flip { (n - 1 - u64::from(v)) as u32 } else { v };
        let (flip_x, flip_y) = (upper(quad.x), upper(quad.y));
        let (x1, y1) = (fold(quad.x, flip_x), fold(quad.y, flip_y));
        let polar = matches!(quad.face, Face::Top | Face::Bottom);
        let swap = polar && x1 > y1;
        let (x, y) = if swap { (y1, x1) } else { (x1, y1) };
        let face = if polar { Face::Top } else { Face::Front };
        MapSymmetry {
            canonical: QuadId { face, level: quad.level, x, y },
            target_face: quad.face,
            swap,
            flip_x,
            flip_y,
        }
    }

    /// Whether the quad is its own canonical quad (nothing to permute).
    pub fn is_identity(self) -> bool {
        !self.swap && !self.flip_x && !self.flip_y && self.canonical.face == self.target_face
    }

    /// The canonical quad's sample that corresponds to the target's sample (i, j) of an n×n grid.
    pub fn canonical_sample(self, n: u32, i: u32, j: u32) -> (u32, u32) {
        let i1 = if self.flip_x { n - 1 - i } else { i };
        let j1 = if self.flip_y { n - 1 - j } else { j };
        if self.swap { (j1, i1) } else { (i1, j1) }
    }

    /// A vector of the canonical quad's maps (ECEF axes) as the target quad sees it. Exact.
    pub fn ecef_from_canonical(self, v: DVec3) -> DVec3 {
        let l = self.canonical.face.local_from_ecef(v);
        let (x, y) = if self.swap { (l.y, l.x) } else { (l.x, l.y) };
        let x = if self.flip_x { -x } else { x };
        let y = if self.flip_y { -y } else { y };
        self.target_face.ecef_from_local(DVec3::new(x, y, l.z))
    }

    /// [`MapSymmetry::ecef_from_canonical`] in f32, as the vertex shader applies it. Exact.
    pub fn ecef_from_canonical_f32(self, v: Vec3) -> Vec3 {
        self.ecef_from_canonical(v.as_dvec3()).as_vec3()
    }

    /// The same map as a matrix (entries 0 and ±1), for the renderer's per-quad uniforms.
    pub fn matrix(self) -> DMat3 {
        DMat3::from_cols(
            self.ecef_from_canonical(DVec3::X),
            self.ecef_from_canonical(DVec3::Y),
            self.ecef_from_canonical(DVec3::Z),
        )
    }
}

/// How many distinct static maps one whole level needs: (without sharing, with sharing).
///
/// Without: one per quad, 6·4^L. With: the equatorial faces need the front face's south-west
/// quarter, m² maps for m = 2^(L−1), and the polar faces the top face's triangle x ≤ y in its
/// south-west quarter, m(m+1)/2; level 0 needs two (front and top).
pub fn distinct_maps_per_level(level: u8) -> (u128, u128) {
    let all = 6 * (1u128 << (2 * u32::from(level)));
    if level == 0 {
        return (all, 2);
    }
    let m = 1u128 << (level - 1);
    (all, m * m + m * (m + 1) / 2)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::CubeProjection;
    use std::collections::HashSet;

    #[test]
    fn canonical_quads_are_counted_by_the_formula() {
        for level in 0..=5u8 {
            let n = 1u32 << level;
            let mut keys = HashSet::new();
            for face in Face::ALL {
                for x in 0..n {
                    for y in 0..n {
                        let s = MapSymmetry::of(QuadId { face, level, x, y });
                        assert!(2 * u64::from(s.canonical.x) < u64::from(n).max(2), "{s:?}");
                        keys.insert(s.canonical);
                    }
                }
            }
            let (all, shared) = distinct_maps_per_level(level);
            assert_eq!(all, 6 * u128::from(n) * u128::from(n));
            assert_eq!(keys.len() as u128, shared, "level {level}");
        }
    }

    #[test]
    fn the_symmetry_maps_sample_directions_onto_each_other() {
        // For QSC the direction of the target's sample is the turned direction of the canonical
        // quad's corresponding sample, on every face and in every fold of the square.
        let p = CubeProjection::Qsc;
        for face in Face::ALL {
            for (level, x, y) in
                [(0u8, 0u32, 0u32), (1, 1, 0), (3, 6, 1), (3, 2, 7), (4, 9, 12), (5, 30, 1), (5, 17, 17)]
            {
                let quad = QuadId { face, level, x, y };
                let s = MapSymmetry::of(quad);
                for (i, j) in [(0u32, 0u32), (3, 1), (8, 8), (2, 7)] {
                    let (tx, ty) = quad.sample_xy(9, i, j);
                    let (ci, cj) = s.canonical_sample(9, i, j);
                    let (cx, cy) = s.canonical.sample_xy(9, ci, cj);
                    let target = p.direction_from_face_point(crate::ecm::FacePoint { face, x: tx, y: ty });
                    let canon =
                        p.direction_from_face_point(crate::ecm::FacePoint { face: s.canonical.face, x: cx, y: cy });
                    let turned = s.ecef_from_canonical(canon);
                    assert!((turned - target).length() < 1e-15, "{quad} ({i},{j}): {turned} vs {target}");
                    assert!((s.matrix() * canon - turned).length() == 0.0);
                }
            }
        }
    }
}
