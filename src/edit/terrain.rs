//! What `smooth`, `flatten` and `ramp` read: the terrain H = B + δ, B the heights of the stack
//! below the edit layer (composed by the CPU reference at the raster's level) and δ the edit
//! layer's own deltas before the stroke. A stroke reads a snapshot of H taken before its first
//! dab over every quad it can read, so what it writes depends on the strokes before it and the
//! layers below, never on the order quads are computed in.
//!
//! H is held in f64 (B and δ are f32; their sum is exact in f64). H between samples is bilinear within the quad of the raster's level that holds the point (a
//! point on a quad's edge reads the same value from either side, the edge's samples being
//! shared). Where B has no data H is NaN: samples without terrain are left as they are.

use std::collections::{BTreeSet, HashMap};

use glam::DVec3;
use rayon::prelude::*;

use super::stroke::{Stroke, Tool};
use crate::ecm::grid::{GRID, spacing_m};
use crate::ecm::{CubeProjection, FacePoint, QuadId};
use crate::errors::Failure;
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic, geodetic_from_ecef};

const N: usize = GRID as usize;

/// The heights of the stack below an edit layer at a quad of the raster's level: 257² row by
/// row from the south, NaN where no layer below has data. Errors are the caller's (a store that
/// cannot be read), passed through.
pub type Below<'a> = dyn Fn(QuadId) -> Result<Vec<f32>, Failure> + Sync + 'a;

/// A [`Below`] that keeps what it read (the terrain below does not change while a layer's strokes
/// are replayed, and terrain-reading strokes read the same quads again and again).
pub struct KeptBelow<'a> {
    below: &'a Below<'a>,
    kept: std::sync::Mutex<HashMap<QuadId, std::sync::Arc<Vec<f32>>>>,
}

impl<'a> KeptBelow<'a> {
    /// Keeps what `below` gives.
    pub fn new(below: &'a Below<'a>) -> KeptBelow<'a> {
        KeptBelow { below, kept: Default::default() }
    }

    /// The terrain below `quad`, read once.
    pub fn get(&self, quad: QuadId) -> Result<Vec<f32>, Failure> {
        if let Some(t) = self.kept.lock().expect("not poisoned").get(&quad) {
            return Ok(t.to_vec());
        }
        let t = (self.below)(quad)?;
        self.kept.lock().expect("not poisoned").insert(quad, std::sync::Arc::new(t.clone()));
        Ok(t)
    }
}

/// A [`Below`] for layers with nothing under them: the ellipsoid (B = 0 everywhere).
pub fn ellipsoid_below(_quad: QuadId) -> Result<Vec<f32>, Failure> {
    Ok(vec![0.0; N * N])
}

/// Points on the ring a smoothing sample averages over.
pub const SMOOTH_RING: usize = 8;

/// The radius of the ring `smooth` averages over, metres: a quarter of the brush, and never less
/// than one sample spacing of the raster's level (so that it always reaches the neighbours).
pub fn smooth_ring_m(ellipsoid: &Ellipsoid, stroke: &Stroke, level: u8) -> f64 {
    (stroke.radius_m / 4.0).max(spacing_m(ellipsoid, level))
}

/// H over the quads a stroke reads, at one level.
pub struct Snapshot {
    ellipsoid: Ellipsoid,
    level: u8,
    tiles: HashMap<QuadId, Vec<f64>>,
}

impl Snapshot {
    /// H = B + δ over `quads` (δ from `delta`, absent = 0), read in parallel.
    pub fn take(
        ellipsoid: Ellipsoid,
        level: u8,
        quads: &BTreeSet<QuadId>,
        delta: &(dyn Fn(QuadId) -> Option<Vec<f32>> + Sync),
        below: &Below,
    ) -> Result<Snapshot, Failure> {
        let tiles = quads
            .par_iter()
            .map(|&q| {
                let b = below(q)?;
                if b.len() != N * N {
                    return Err(format!("the terrain below {q} has {} samples, not {}", b.len(), N * N).into());
                }
                let mut h: Vec<f64> = b.into_iter().map(f64::from).collect();
                if let Some(d) = delta(q) {
                    for (h, d) in h.iter_mut().zip(d) {
                        *h += f64::from(d);
                    }
                }
                Ok((q, h))
            })
            .collect::<Result<HashMap<_, _>, Failure>>()?;
        Ok(Snapshot { ellipsoid, level, tiles })
    }

    /// H at a point of the surface (its height above the ellipsoid ignored), bilinear in the
    /// quad that holds it; NaN where that quad is not in the snapshot or has no terrain.
    pub fn height_at(&self, p: DVec3) -> f64 {
        let g = geodetic_from_ecef(&self.ellipsoid, p);
        let at = CubeProjection::Qsc.face_point_from_geodetic(&self.ellipsoid, g.lat_rad, g.lon_rad);
        self.height_at_face_point(at)
    }

    fn height_at_face_point(&self, at: FacePoint) -> f64 {
        let n = f64::from(1u32 << self.level);
        let cells = (N - 1) as f64;
        let locate = |x: f64| {
            let f = ((x + 1.0) * 0.5 * n).clamp(0.0, n);
            let q = f.floor().min(n - 1.0);
            let u = (f - q) * cells;
            let i = u.floor().min(cells - 1.0);
            (q as u32, i as usize, u - i)
        };
        let (qx, i, fu) = locate(at.x);
        let (qy, j, fv) = locate(at.y);
        let quad = QuadId { face: at.face, level: self.level, x: qx, y: qy };
        let Some(t) = self.tiles.get(&quad) else { return f64::NAN };
        let v = |i: usize, j: usize| t[j * N + i];
        let south = v(i, j) + (v(i + 1, j) - v(i, j)) * fu;
        let north = v(i, j + 1) + (v(i + 1, j + 1) - v(i, j + 1)) * fu;
        south + (north - south) * fv
    }

    /// H at a global sample (i, j) of a face at the snapshot's level, indices off the face folded
    /// onto the adjacent one (NaN beyond a cube corner or outside the snapshot).
    pub fn sample_global(&self, face: crate::ecm::Face, i: i64, j: i64) -> f64 {
        let Some((f, i, j)) = crate::ecm::grid::fold_sample(face, self.level, i, j) else { return f64::NAN };
        let (q, li, lj) = crate::ecm::grid::quad_of_sample(f, self.level, i, j);
        self.tiles.get(&q).map_or(f64::NAN, |t| t[lj as usize * N + li as usize])
    }

    /// H at sample k of `quad` (a snapshot quad: exact, no interpolation).
    pub fn sample(&self, quad: QuadId, k: usize) -> f64 {
        self.tiles.get(&quad).map_or(f64::NAN, |t| t[k])
    }

    /// The mean of H over the ring of `SMOOTH_RING` points at `ring_m` around the surface point
    /// `p` (longitude, latitude in radians), in its local east–north plane; the points without
    /// terrain are left out (NaN when none has any).
    pub fn ring_mean(&self, p: DVec3, lon: f64, lat: f64, ring_m: f64) -> f64 {
        let east = DVec3::new(-lon.sin(), lon.cos(), 0.0);
        let north = DVec3::new(-lat.sin() * lon.cos(), -lat.sin() * lon.sin(), lat.cos());
        let (mut sum, mut count) = (0.0, 0u32);
        for k in 0..SMOOTH_RING {
            let theta = std::f64::consts::TAU * k as f64 / SMOOTH_RING as f64;
            let h = self.height_at(p + ring_m * (theta.cos() * east + theta.sin() * north));
            if h.is_finite() {
                sum += h;
                count += 1;
            }
        }
        if count == 0 { f64::NAN } else { sum / f64::from(count) }
    }
}

/// What a terrain-reading stroke moves heights towards, fixed before its first dab.
#[derive(Clone, Copy, Debug)]
pub enum Target {
    /// Raise, lower, noise, restore: no target.
    None,
    /// Smooth: each sample's ring mean.
    Smooth {
        /// The ring's radius, metres.
        ring_m: f64,
    },
    /// Flatten: one height.
    Flatten {
        /// Metres (NaN: the first dab had no terrain under it; nothing moves).
        height_m: f64,
    },
    /// Ramp: linear along the chord from the path's first point to its last (clamped beyond).
    Ramp {
        /// The first point (ECEF, on the ellipsoid).
        a: DVec3,
        /// The last point.
        b: DVec3,
        /// H under `a`, metres.
        height_a_m: f64,
        /// H under `b`, metres.
        height_b_m: f64,
    },
}

impl Target {
    /// The points whose terrain the target itself reads (beyond each sample's own).
    pub fn points(ellipsoid: &Ellipsoid, stroke: &Stroke) -> Vec<DVec3> {
        let at = |[lat, lon]: [f64; 2]| {
            ecef_from_geodetic(
                ellipsoid,
                Geodetic { lat_rad: lat.to_radians(), lon_rad: lon.to_radians(), height_m: 0.0 },
            )
        };
        match stroke.tool {
            Tool::Flatten if stroke.height_m.is_none() => vec![at(stroke.path[0])],
            Tool::Ramp => vec![at(stroke.path[0]), at(*stroke.path.last().expect("checked: a path has points"))],
            _ => Vec::new(),
        }
    }

    /// The stroke's target, read from the snapshot (`level`: the raster's).
    pub fn of(ellipsoid: &Ellipsoid, stroke: &Stroke, level: u8, snapshot: Option<&Snapshot>) -> Target {
        let points = Target::points(ellipsoid, stroke);
        let height = |p: DVec3| snapshot.map_or(f64::NAN, |s| s.height_at(p));
        match stroke.tool {
            Tool::Smooth => Target::Smooth { ring_m: smooth_ring_m(ellipsoid, stroke, level) },
            Tool::Flatten => Target::Flatten { height_m: stroke.height_m.unwrap_or_else(|| height(points[0])) },
            Tool::Ramp => Target::Ramp {
                a: points[0],
                b: points[1],
                height_a_m: height(points[0]),
                height_b_m: height(points[1]),
            },
            _ => Target::None,
        }
    }

    /// The height a sample at `p` moves towards (NaN: none), given its ring mean for smooth.
    pub fn height_m(&self, p: DVec3, ring_mean: impl FnOnce() -> f64) -> f64 {
        match *self {
            Target::None => f64::NAN,
            Target::Smooth { .. } => ring_mean(),
            Target::Flatten { height_m } => height_m,
            Target::Ramp { a, b, height_a_m, height_b_m } => {
                let ab = b - a;
                let t = ((p - a).dot(ab) / ab.length_squared()).clamp(0.0, 1.0);
                height_a_m + (height_b_m - height_a_m) * t
            }
        }
    }
}
