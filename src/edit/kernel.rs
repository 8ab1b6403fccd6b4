//! The CPU reference of a stroke on one tile: every sample within reach of a dab folded through
//! the stroke's dabs in order, in f64 from its stored f32 value, and rounded to f32 once. The GPU
//! rasteriser (`shaders/edit/stroke.wgsl`) reads like it.

use glam::DVec3;
use rayon::prelude::*;

use super::stroke::{Stroke, Tool};
use super::terrain::{Snapshot, Target};
use crate::ecm::grid::{GRID, spacing_m};
use crate::ecm::points::sample_point;
use crate::ecm::{CubeProjection, FacePoint, QuadId};
use crate::errors::Failure;
use crate::geodesy::{Ellipsoid, geodetic_from_ecef};
use crate::maths::noise;

const N: usize = GRID as usize;

/// One dab, ready to apply: its centre and where that lies on the cube.
#[derive(Clone, Copy, Debug)]
pub struct Dab {
    /// On the ellipsoid, ECEF metres.
    pub centre: DVec3,
    /// Its face point.
    pub at: FacePoint,
}

impl Dab {
    /// The dab centred at `centre`.
    pub fn new(ellipsoid: &Ellipsoid, centre: DVec3) -> Dab {
        let g = geodetic_from_ecef(ellipsoid, centre);
        Dab { centre, at: CubeProjection::Qsc.face_point_from_geodetic(ellipsoid, g.lat_rad, g.lon_rad) }
    }
}

/// The samples of a quad a stroke's dabs can reach: `[i0, i1, j0, j1]`, inclusive. Each dab on
/// the quad's face reaches at most 2r / s + 2 samples from its own grid position (s the level's
/// mean spacing: QSC's grid spacing stays within a factor 2 of it over a face); a dab on another
/// face gives the whole quad. Samples outside the window are beyond every dab (the tests check
/// every sample of the touched quads against the formula).
pub fn window(ellipsoid: &Ellipsoid, quad: QuadId, dabs: &[Dab], r: f64) -> [usize; 4] {
    let whole = [0, N - 1, 0, N - 1];
    let reach = 2.0 * r / spacing_m(ellipsoid, quad.level) + 2.0;
    let cells = (N - 1) as f64;
    let n = f64::from(1u32 << quad.level);
    let (mut lo_i, mut hi_i, mut lo_j, mut hi_j) = (f64::INFINITY, f64::NEG_INFINITY, f64::INFINITY, f64::NEG_INFINITY);
    for dab in dabs {
        if dab.at.face != quad.face {
            return whole;
        }
        let u = ((dab.at.x + 1.0) * 0.5 * n - f64::from(quad.x)) * cells;
        let v = ((dab.at.y + 1.0) * 0.5 * n - f64::from(quad.y)) * cells;
        (lo_i, hi_i, lo_j, hi_j) = (lo_i.min(u - reach), hi_i.max(u + reach), lo_j.min(v - reach), hi_j.max(v + reach));
    }
    let clamp = |x: f64| x.clamp(0.0, cells);
    if hi_i < 0.0 || hi_j < 0.0 || lo_i > cells || lo_j > cells {
        return [1, 0, 1, 0]; // empty
    }
    [
        clamp(lo_i).floor() as usize,
        clamp(hi_i).ceil() as usize,
        clamp(lo_j).floor() as usize,
        clamp(hi_j).ceil() as usize,
    ]
}

/// Folds one stroke's dabs, in order, into a tile: each sample in f64 from its stored f32 value,
/// rounded to f32 once at the end. `target` and `snapshot` are the stroke's (terrain-reading
/// tools; the snapshot holds H before the stroke over every quad the stroke reads).
pub fn apply_to_tile(
    ellipsoid: &Ellipsoid,
    quad: QuadId,
    tile: &mut [f32],
    stroke: &Stroke,
    dabs: &[Dab],
    target: Target,
    snapshot: Option<&Snapshot>,
) {
    let r = stroke.radius_m;
    let wavelength = r / 2.0;
    let [i0, i1, j0, j1] = window(ellipsoid, quad, dabs, r);
    for k in (j0..=j1).flat_map(|j| (i0..=i1).map(move |i| j * N + i)) {
        let value = &mut tile[k];
        let (p, lon, lat) = sample_point(ellipsoid, quad, GRID, (k % N) as u32, (k / N) as u32);
        let mut delta = f64::from(*value);
        // What the terrain-reading tools move towards: the target height minus the terrain below
        // the edit layer (B = H − δ, both before the stroke), i.e. the δ that reaches the target.
        let mut goal: Option<f64> = None;
        let mut touched = false;
        for dab in dabs {
            let d = (p - dab.centre).length();
            if d >= r {
                continue;
            }
            let w = stroke.falloff.weight(d / r);
            let s = stroke.strength * w;
            delta = match stroke.tool {
                Tool::Raise => delta + s,
                Tool::Lower => delta - s,
                Tool::Noise => delta + s * noise::octave_at(p, wavelength, stroke.seed),
                Tool::Restore => delta * (1.0 - s),
                Tool::Smooth | Tool::Flatten | Tool::Ramp => {
                    let goal = *goal.get_or_insert_with(|| {
                        let s = snapshot.expect("terrain-reading strokes have a snapshot");
                        let h = s.sample(quad, k);
                        let below = h - f64::from(*value);
                        let height = target.height_m(p, || match target {
                            Target::Smooth { ring_m } => s.ring_mean(p, lon, lat, ring_m),
                            _ => f64::NAN,
                        });
                        height - below
                    });
                    if !goal.is_finite() {
                        // No terrain here (or no target): left as it is.
                        continue;
                    }
                    delta + s * (goal - delta)
                }
            };
            touched = true;
        }
        if touched {
            *value = delta as f32;
        }
    }
}

/// One stroke as a rasteriser receives it: everything fixed before its first dab.
pub struct StrokeJob<'a> {
    /// The body.
    pub ellipsoid: &'a Ellipsoid,
    /// The stroke.
    pub stroke: &'a Stroke,
    /// Its dabs, in order.
    pub dabs: &'a [Dab],
    /// What a terrain-reading stroke moves towards.
    pub target: Target,
    /// H before the stroke over every quad it reads (terrain-reading strokes).
    pub snapshot: Option<&'a Snapshot>,
}

/// Applies a stroke to tiles (each δ before the stroke, changed in place): the CPU reference
/// ([`CpuRasteriser`]) or the GPU's (`gpu::brush`).
pub trait Rasteriser: Sync {
    /// Applies `job` to every tile; an error is the rasteriser's (a GPU that failed).
    fn rasterise(&self, job: &StrokeJob, tiles: &mut [(QuadId, Vec<f32>)]) -> Result<(), Failure>;
}

/// The CPU reference: [`apply_to_tile`] per tile, tiles in parallel (each tile's result does
/// not depend on the others' or on the order).
pub struct CpuRasteriser;

impl Rasteriser for CpuRasteriser {
    fn rasterise(&self, job: &StrokeJob, tiles: &mut [(QuadId, Vec<f32>)]) -> Result<(), Failure> {
        tiles.par_iter_mut().for_each(|(q, tile)| {
            apply_to_tile(job.ellipsoid, *q, tile, job.stroke, job.dabs, job.target, job.snapshot);
        });
        Ok(())
    }
}
