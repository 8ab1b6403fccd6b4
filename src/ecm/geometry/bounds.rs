//! Per-quad bounding volumes for culling and screen-space size: an oriented box around every
//! vertex the renderer can place, for every height in the quad's range.

use glam::DVec3;

use super::{QuadGeometry, interpolate_f64, sample_st};

/// An oriented bounding box in ECEF metres that holds the quad's rendered surface for every
/// height in `height_range_m` (vertices and, the box being convex, the triangles between them).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct QuadBounds {
    /// Centre of the box, ECEF metres.
    pub center_ecef: DVec3,
    /// Unit axes: along the quad's s direction, along its t direction (orthogonalised), and up
    /// (the mean of the corner normals).
    pub axes: [DVec3; 3],
    /// Half extents along the axes, metres.
    pub half_extents_m: DVec3,
    /// The heights the box holds, metres.
    pub height_range_m: (f64, f64),
}

impl QuadBounds {
    /// The box of a quad's vertices for heights in `min_m ..= max_m`, from the same data the
    /// renderer draws: exact corners, the f32 maps (or the flat patch), every sample. Padded by
    /// 1 mm + 10⁻⁶ of its size for the f32 rounding of the maps.
    pub fn compute(geometry: &QuadGeometry, min_m: f64, max_m: f64) -> QuadBounds {
        let last = geometry.samples - 1;
        QuadBounds::compute_within(geometry, (0, last), (0, last), min_m, max_m)
    }

    /// The box of the samples `i.0 ..= i.1` × `j.0 ..= j.1` of the geometry (a patch of the
    /// quad), for heights in `min_m ..= max_m`, in the quad's axes.
    pub fn compute_within(geometry: &QuadGeometry, i: (u32, u32), j: (u32, u32), min_m: f64, max_m: f64) -> QuadBounds {
        let q = geometry.corners_ecef;
        let up = geometry.corner_normals.iter().sum::<DVec3>().normalize();
        let along_s = (q[1] - q[0]) + (q[3] - q[2]);
        let along_s = (along_s - up * along_s.dot(up)).normalize();
        let along_t = up.cross(along_s);
        let axes = [along_s, along_t, up];
        let origin = q.iter().sum::<DVec3>() * 0.25;
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        let n = geometry.samples;
        for j in j.0..=j.1 {
            for i in i.0..=i.1 {
                let (s, t) = sample_st(n, i, j);
                let patch = interpolate_f64(geometry.split, &q, s, t);
                let (surface, normal) = match geometry.maps_at(i, j) {
                    Some([o, nn, _]) => (patch + o.as_dvec3(), nn.as_dvec3()),
                    None => (patch, interpolate_f64(geometry.split, &geometry.corner_normals, s, t).normalize()),
                };
                for h in [min_m, max_m] {
                    let r = surface + normal * h - origin;
                    let p = DVec3::new(r.dot(axes[0]), r.dot(axes[1]), r.dot(axes[2]));
                    lo = lo.min(p);
                    hi = hi.max(p);
                }
            }
        }
        let mid = (lo + hi) * 0.5;
        let half = (hi - lo) * 0.5;
        let pad = 1e-3 + 1e-6 * half.max_element();
        QuadBounds {
            center_ecef: origin + axes[0] * mid.x + axes[1] * mid.y + axes[2] * mid.z,
            axes,
            half_extents_m: half + DVec3::splat(pad),
            height_range_m: (min_m, max_m),
        }
    }

    /// `p` (ECEF) in the box's axes, relative to its centre.
    fn local(&self, p: DVec3) -> DVec3 {
        let r = p - self.center_ecef;
        DVec3::new(r.dot(self.axes[0]), r.dot(self.axes[1]), r.dot(self.axes[2]))
    }

    /// Whether the box holds `p` (ECEF).
    pub fn contains(&self, p: DVec3) -> bool {
        let l = self.local(p).abs();
        l.x <= self.half_extents_m.x && l.y <= self.half_extents_m.y && l.z <= self.half_extents_m.z
    }

    /// Distance from `p` (ECEF) to the box, metres; 0 inside. The renderer's screen-space size of
    /// a quad uses it.
    pub fn distance_m(&self, p: DVec3) -> f64 {
        (self.local(p).abs() - self.half_extents_m).max(DVec3::ZERO).length()
    }

    /// The eight corners, ECEF.
    pub fn corners(&self) -> [DVec3; 8] {
        std::array::from_fn(|k| {
            let sign = |bit: usize| if k >> bit & 1 == 1 { 1.0 } else { -1.0 };
            self.center_ecef
                + self.axes[0] * (sign(0) * self.half_extents_m.x)
                + self.axes[1] * (sign(1) * self.half_extents_m.y)
                + self.axes[2] * (sign(2) * self.half_extents_m.z)
        })
    }

    /// Radius of the sphere around the box's centre that holds it, metres.
    pub fn radius_m(&self) -> f64 {
        self.half_extents_m.length()
    }

    /// Whether the box lies entirely on the negative side of a plane n·p + d < 0 (n a unit
    /// normal, ECEF), the frustum test.
    pub fn outside_plane(&self, normal: DVec3, d: f64) -> bool {
        let reach = self.half_extents_m.x * normal.dot(self.axes[0]).abs()
            + self.half_extents_m.y * normal.dot(self.axes[1]).abs()
            + self.half_extents_m.z * normal.dot(self.axes[2]).abs();
        normal.dot(self.center_ecef) + d < -reach
    }
}
