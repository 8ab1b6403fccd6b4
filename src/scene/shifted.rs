//! Datasets moved horizontally (`shift_m`, what `terrafuse coregister --apply` writes): a shifted
//! dataset's tile at a quad holds, at each sample p, the dataset's value at p moved back by the
//! shift in p's local east-north frame (metres on the ellipsoid), interpolated bicubically from
//! the tiles of the level (across quad and face edges), as co-registration read it when it fitted
//! the shift (`compare::mosaic`): bilinear interpolation would flatten the terrain between
//! samples, and a comparison after `--apply` would no longer see what the fit reported. The loader makes these tiles; composition
//! on the GPU and the CPU reference then use them like any other, so a shift is composed like
//! every other parameter. Which quads a shifted dataset covers is still decided by its unshifted
//! tiles: at the data's outer edge a shift of s leaves up to s uncovered.

use std::collections::HashMap;

use glam::DVec3;

use super::dataset::DatasetInfo;
use crate::ecm::grid::{GRID, bicubic};
use crate::ecm::points::sample_point;
use crate::ecm::{CubeProjection, QuadId};
use crate::geodesy::{Ellipsoid, geodetic_from_ecef};
use crate::store::{Store, StoreError};

const N: usize = GRID as usize;

pub use crate::geodesy::local_axes;

/// The quad of `level` holding the point above or below `p` on the ellipsoid, and the point's
/// grid coordinates in it (u, v ∈ [0, 256]).
pub fn locate(ellipsoid: &Ellipsoid, level: u8, p: DVec3) -> Option<(QuadId, f64, f64)> {
    let g = geodetic_from_ecef(ellipsoid, p);
    let fp = CubeProjection::Qsc.face_point_from_geodetic(ellipsoid, g.lat_rad, g.lon_rad);
    let q = QuadId::containing(fp, level).ok()?;
    let n = f64::from(1u32 << level);
    let u = ((fp.x + 1.0) * 0.5 * n - f64::from(q.x)) * 256.0;
    let v = ((fp.y + 1.0) * 0.5 * n - f64::from(q.y)) * 256.0;
    Some((q, u.clamp(0.0, 256.0), v.clamp(0.0, 256.0)))
}

/// The shifted dataset's 257² grid at `quad` (sampled at the level min(quad's, finest)).
pub fn shifted_grid(dataset: &DatasetInfo, store: &Store, quad: QuadId) -> Result<Vec<f32>, StoreError> {
    let level = quad.level.min(dataset.finest_level);
    let [east_m, north_m] = dataset.shift_m;
    let body = dataset.body;
    let mut tiles: HashMap<QuadId, Option<Vec<f32>>> = HashMap::new();
    let mut out = Vec::with_capacity(N * N);
    for k in 0..N * N {
        let (p, lon, lat) = sample_point(&body, quad, GRID, (k % N) as u32, (k / N) as u32);
        let (east, north) = local_axes(lon, lat);
        let moved = p - east_m * east - north_m * north;
        let Some((q, u, v)) = locate(&body, level, moved) else {
            out.push(f32::NAN);
            continue;
        };
        let tile = match tiles.entry(q) {
            std::collections::hash_map::Entry::Occupied(e) => e.into_mut(),
            std::collections::hash_map::Entry::Vacant(e) => {
                e.insert(if dataset.has(q) { store.read_grid(&dataset.dataset, q)?.map(|t| t.values) } else { None })
            }
        };
        out.push(tile.as_deref().map_or(f32::NAN, |g| bicubic(g, u, v) as f32));
    }
    Ok(out)
}
