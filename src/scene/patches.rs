//! Per-patch density and culling: a drawn quad is drawn as 8 × 8 patches of 32 × 32 sample
//! spacings, each culled against the frustum and the horizon on its own and drawn at the stride
//! (1, 2, 4 … 32 samples) that its projected sample size needs under the threshold t, so that a
//! quad much larger than the view costs only the part of it that shows, at the density that part
//! needs. Patches of different strides meet at T-junctions; each patch has its own skirt ring,
//! as quads do, so the seams stay closed.

use super::camera::Camera;
use super::select::{QuadInfo, SelectParams, cull_box, pixels_per_sample, tally};
use crate::ecm::geometry::{QuadBounds, QuadGeometry};

/// Patches along a quad's edge.
pub const PATCHES_PER_EDGE: u32 = 8;
/// Sample spacings along a patch's edge (256 / 8).
pub const PATCH_CELLS: u32 = 32;
/// The strides a patch may be drawn at, in samples, finest first.
pub const STRIDES: [u32; 6] = [1, 2, 4, 8, 16, 32];

/// Where the morph band ends: a vertex of a patch at stride s whose coarser spacing 2s covers ρ
/// times t pixels has morphed fully to the coarser mesh up to ρ = 1.1 (the band's start) and not
/// at all from ρ = 1.6 on.
/// A patch takes stride s when ρ passes 1 at its nearest point, where its farthest vertex, at most
/// 16 % farther (a patch spans 32t/f ≈ 0.11 of its distance at t = 1.5 and a 60° view, with its
/// diagonal and relief), has ρ ≥ 0.86; the coarser patch it replaces had 2ρ ≥ 1.72 > 1.6 there,
/// unmorphed: so the change draws what was drawn before.
pub const MORPH_BAND_END: f64 = 1.6;
/// Where the morph band starts: up to ρ = 1.1 a vertex has morphed fully, so that a change of
/// stride or level that ρ passed by less than 10 % since the last frame (the camera's step) still
/// finds every vertex of the finer patch on the coarser mesh.
pub const MORPH_BAND_START: f64 = 1.1;
/// Levels above a quad whose data its coarser strides show (stride 32 shows the data 5 levels up).
pub const DATA_LEVELS_UP: u32 = 5;

/// The sample that holds the data a patch drawn every 2^k samples shows at sample (i, j) of
/// `quad` (i and j multiples of 2^k): the same point in the ancestor k levels up, or the quad's
/// own sample where it has no such ancestor. The shader's `data_index` twin.
pub fn data_sample(quad: crate::ecm::QuadId, i: u32, j: u32, k: u32) -> (crate::ecm::QuadId, u32, u32) {
    if k == 0 || k > u32::from(quad.level) {
        return (quad, i, j);
    }
    let mask = (1u32 << k) - 1;
    let ancestor = quad.ancestor_at(quad.level - k as u8);
    ((ancestor), (i + 256 * (quad.x & mask)) >> k, (j + 256 * (quad.y & mask)) >> k)
}

/// How far a vertex of a patch at `stride` has morphed toward the patch's mesh at twice the
/// stride (0 … 1): `spacing_m` the quad's sample spacing, `distance_m` the vertex's from the eye,
/// `focal_px` the camera's focal length in pixels. The terrain shader's `morph_factor` twin.
pub fn morph_factor(stride: u32, spacing_m: f64, distance_m: f64, focal_px: f64, threshold_px: f64) -> f64 {
    if stride >= PATCH_CELLS {
        return 0.0;
    }
    let rho = 2.0 * f64::from(stride) * spacing_m * focal_px / (threshold_px * distance_m.max(1e-6));
    ((MORPH_BAND_END - rho) / (MORPH_BAND_END - MORPH_BAND_START)).clamp(0.0, 1.0)
}

/// The two samples a vertex at patch grid position (a, b) slides toward when its patch morphs to
/// twice its stride (offsets in samples, from the vertex): along the edge for odd a or b, along the
/// cell's diagonal for both odd; none for a vertex the coarser mesh has.
pub fn morph_neighbours(a: u32, b: u32, stride: u32) -> Option<[(i64, i64); 2]> {
    let (da, db) = (i64::from(a % 2), i64::from(b % 2));
    if da + db == 0 {
        return None;
    }
    let s = i64::from(stride);
    Some([(-da * s, -db * s), (da * s, db * s)])
}

/// The sides of a patch, as bits of [`Patch::skirts`] (and the order of the skirt ring).
pub const SOUTH: u8 = 1;
/// The east side (+i).
pub const EAST: u8 = 2;
/// The north side (+j).
pub const NORTH: u8 = 4;
/// The west side (−i).
pub const WEST: u8 = 8;
/// Every side.
pub const ALL_SIDES: u8 = 15;

/// One patch to draw: which drawn quad, where in it, how densely, and which sides hang a skirt.
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub struct Patch {
    /// The stride, samples (one of [`STRIDES`]); first, so that sorting groups the draws.
    pub stride: u32,
    /// Whether any of its vertices may morph this frame (drawn by the pipeline that morphs;
    /// the others by one without the morph's work).
    pub morphs: bool,
    /// The sides with a skirt ([`SOUTH`] | [`EAST`] | [`NORTH`] | [`WEST`]): those on the quad's
    /// edge, and those whose neighbour in the quad is drawn at another stride or not at all. Two
    /// patches of one quad at one stride compute their shared edge's vertices identically, so
    /// no gap can open between them.
    pub skirts: u8,
    /// The quad's index in the frame's drawn quads.
    pub quad: u32,
    /// The patch's row and column in the quad (0 … 7).
    pub py: u32,
    /// The patch's column.
    pub px: u32,
}

impl Patch {
    /// Cells along the patch's edge at its stride.
    pub fn cells(&self) -> u32 {
        PATCH_CELLS / self.stride
    }

    /// The sample (i, j) of the patch's first corner in its quad.
    pub fn origin(&self) -> (u32, u32) {
        (self.px * PATCH_CELLS, self.py * PATCH_CELLS)
    }

    /// Triangles the patch draws: its grid and its skirts.
    pub fn triangles(&self) -> u64 {
        triangles_at(self.stride, self.skirts)
    }
}

/// Triangles a patch draws at `stride` with skirts on `skirts`: 2n² for the grid of n cells a
/// side, 2n for each side's skirt (two per cell).
pub fn triangles_at(stride: u32, skirts: u8) -> u64 {
    let n = u64::from(PATCH_CELLS / stride);
    2 * n * n + 2 * n * u64::from(skirts.count_ones())
}

/// The patches of one frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PatchSelection {
    /// Patches to draw, sorted by stride, then quad, row and column.
    pub patches: Vec<Patch>,
    /// Patches of drawn quads dropped outside the frustum.
    pub culled_frustum: usize,
    /// Patches of drawn quads dropped behind the horizon.
    pub culled_horizon: usize,
}

impl PatchSelection {
    /// Triangles drawn.
    pub fn triangles(&self) -> u64 {
        self.patches.iter().map(Patch::triangles).sum()
    }

    /// Patches drawn per stride, in the order of [`STRIDES`].
    pub fn per_stride(&self) -> [usize; STRIDES.len()] {
        let mut counts = [0; STRIDES.len()];
        for p in &self.patches {
            if let Some(k) = STRIDES.iter().position(|&s| s == p.stride) {
                counts[k] += 1;
            }
        }
        counts
    }

    /// The runs of patches of one stride, set of skirts and morphing: (stride, skirts, morphs,
    /// first, count), for one instanced draw each.
    pub fn groups(&self) -> Vec<(u32, u8, bool, u32, u32)> {
        let mut out: Vec<(u32, u8, bool, u32, u32)> = Vec::new();
        for (k, p) in self.patches.iter().enumerate() {
            match out.last_mut() {
                Some(g) if g.0 == p.stride && g.1 == p.skirts && g.2 == p.morphs => g.4 += 1,
                _ => out.push((p.stride, p.skirts, p.morphs, k as u32, 1)),
            }
        }
        out
    }
}

/// The stride a patch needs: the largest of [`STRIDES`] whose spacing still covers at most
/// `threshold_px` pixels at the patch's nearest point (1 when even one sample covers more).
pub fn stride_for(pixels_per_sample: f64, threshold_px: f64) -> u32 {
    STRIDES.iter().rev().copied().find(|&s| f64::from(s) * pixels_per_sample <= threshold_px).unwrap_or(1)
}

/// The boxes of a quad's 64 patches (row-major: patch (px, py) at `py * 8 + px`) from its coarse
/// bounding geometry (whose cells must tile the patches: 17² samples give 2 × 2 a patch), each for
/// the heights in its own range of `ranges_m`, widened by `pad_m` (the sagitta of the surface
/// between the coarse samples, as the quad's box is).
pub fn patch_bounds(geometry: &QuadGeometry, ranges_m: &[(f64, f64)], pad_m: f64) -> Vec<QuadBounds> {
    let cells = geometry.samples - 1;
    debug_assert_eq!(cells % PATCHES_PER_EDGE, 0, "the bounding geometry's cells must tile the patches");
    debug_assert_eq!(ranges_m.len(), (PATCHES_PER_EDGE * PATCHES_PER_EDGE) as usize);
    let per = cells / PATCHES_PER_EDGE;
    let mut out = Vec::with_capacity(ranges_m.len());
    for (n, &(lo, hi)) in ranges_m.iter().enumerate() {
        let (px, py) = (n as u32 % PATCHES_PER_EDGE, n as u32 / PATCHES_PER_EDGE);
        let mut b =
            QuadBounds::compute_within(geometry, (px * per, (px + 1) * per), (py * per, (py + 1) * per), lo, hi);
        b.half_extents_m += glam::DVec3::splat(pad_m);
        out.push(b);
    }
    out
}

/// A patch's boxes, one per stride of [`STRIDES`]: what it draws at that stride (its own data's
/// heights, and the data of the levels above that the stride shows and morphs toward).
pub type StrideBoxes = [QuadBounds; STRIDES.len()];

/// Which of [`STRIDES`] `stride` is (its log2).
pub fn stride_index(stride: u32) -> usize {
    stride.trailing_zeros() as usize
}

/// The levels above a quad whose data a patch at stride 2^k draws: its own (where an ancestor is
/// not composed yet), the level k up it shows and the level k + 1 up it morphs toward (none past
/// the coarsest stride, which does not morph).
pub fn levels_drawn_at(k: usize) -> impl Iterator<Item = usize> {
    let morph = (k + 1 < STRIDES.len()).then_some(k + 1);
    [0, k].into_iter().chain(morph)
}

/// One drawn quad as patch selection sees it: the quad's longest edge (metres) and its 64
/// patches' boxes at each stride.
pub struct QuadPatches<'a> {
    /// The quad's longest edge, metres (its sample spacing is this / 256).
    pub edge_m: f64,
    /// Per patch (row-major), its boxes at each stride.
    pub bounds: &'a [StrideBoxes],
}

/// The patches of the drawn quads (in their order) to draw: each culled on its own and at the
/// stride its nearest point needs. With `adaptive` false every patch is drawn at stride 1 and
/// none is culled: the quads drawn whole, as before patches (for comparisons and the vertex
/// tests that want every sample). With `morph` (geomorphing on, adaptive patches), a patch
/// `morphs` unless even its farthest point is past the morph band ([`morph_factor`] 0 there, so at
/// every vertex).
pub fn select_patches(
    camera: &Camera,
    params: &SelectParams,
    quads: &[QuadPatches],
    adaptive: bool,
    morph: bool,
) -> PatchSelection {
    let focal = camera.focal_px(params.height);
    let mut out = PatchSelection::default();
    let planes = camera.frustum(params.width, params.height);
    for (k, q) in quads.iter().enumerate() {
        for (n, bounds) in q.bounds.iter().enumerate() {
            let (px, py) = (n as u32 % PATCHES_PER_EDGE, n as u32 / PATCHES_PER_EDGE);
            let stride = if adaptive {
                // The stride from the patch's own surface; culled by what it draws at that stride.
                let info = QuadInfo { bounds: bounds[0], edge_m: q.edge_m };
                let stride = stride_for(pixels_per_sample(camera, &info, params.height), params.threshold_px);
                let culled = cull_box(camera, &planes, params.occluder_m, &bounds[stride_index(stride)]);
                if tally(culled, &mut out.culled_frustum, &mut out.culled_horizon) {
                    continue;
                }
                stride
            } else {
                1
            };
            let morphs = morph && adaptive && {
                // The shader measures from f32 positions: 1 % nearer counts as morphing.
                let b = &bounds[stride_index(stride)];
                let far = b.corners().iter().map(|c| (*c - camera.position).length()).fold(0.0, f64::max);
                morph_factor(stride, q.edge_m / 256.0, far * 1.01, focal, params.threshold_px) > 0.0
            };
            out.patches.push(Patch { stride, morphs, skirts: ALL_SIDES, quad: k as u32, py, px });
        }
    }
    hang_skirts(&mut out.patches);
    out.patches.sort_unstable();
    out
}

/// Keeps the skirts a patch needs: on the quad's edge (where another quad, drawn from other
/// values, meets it), and toward a neighbour drawn at another stride (a T-junction) or not at all.
fn hang_skirts(patches: &mut [Patch]) {
    let n = PATCHES_PER_EDGE as usize;
    let mut strides: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    for p in patches.iter() {
        strides.entry(p.quad).or_insert_with(|| vec![0; n * n])[p.py as usize * n + p.px as usize] = p.stride;
    }
    for p in patches.iter_mut() {
        let grid = &strides[&p.quad];
        let neighbour = |dx: i32, dy: i32| {
            let (x, y) = (p.px as i32 + dx, p.py as i32 + dy);
            let inside = (0..n as i32).contains(&x) && (0..n as i32).contains(&y);
            inside.then(|| grid[y as usize * n + x as usize])
        };
        let mut skirts = 0;
        for (side, (dx, dy)) in [(SOUTH, (0, -1)), (EAST, (1, 0)), (NORTH, (0, 1)), (WEST, (-1, 0))] {
            if neighbour(dx, dy) != Some(p.stride) {
                skirts |= side;
            }
        }
        p.skirts = skirts;
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::{CubeProjection, Face, QuadId};
    use crate::geodesy::Ellipsoid;
    use crate::project::CameraSpec;

    fn params(t: f64) -> SelectParams {
        SelectParams {
            threshold_px: t,
            max_quads: 128,
            width: 640,
            height: 512,
            occluder_m: (1_737_000.0, 1_737_000.0),
        }
    }

    fn quad_patches(quad: QuadId) -> (f64, Vec<StrideBoxes>) {
        let g = QuadGeometry::compute(&Ellipsoid::MOON, CubeProjection::Qsc, quad, 17);
        let q = g.corners_ecef;
        let edge = (q[1] - q[0]).length().max((q[2] - q[0]).length());
        let boxes = patch_bounds(&g, &[(-100.0, 100.0); 64], 1.0);
        (edge, boxes.into_iter().map(|b| [b; STRIDES.len()]).collect())
    }

    #[test]
    fn strides_are_the_coarsest_that_keep_a_sample_under_the_threshold() {
        assert_eq!(stride_for(2.0, 1.5), 1, "already too coarse: the finest");
        assert_eq!(stride_for(1.5, 1.5), 1);
        assert_eq!(stride_for(0.7, 1.5), 2);
        assert_eq!(stride_for(0.1, 1.5), 8);
        assert_eq!(stride_for(0.01, 1.5), 32, "never coarser than one cell a patch");
        assert_eq!(triangles_at(1, ALL_SIDES), 2 * 32 * 32 + 8 * 32);
        assert_eq!(triangles_at(32, ALL_SIDES), 2 + 8);
        assert_eq!(triangles_at(1, SOUTH | WEST), 2 * 32 * 32 + 4 * 32);
    }

    #[test]
    fn patch_boxes_tile_the_quad_box() {
        let quad = QuadId::root(Face::Front).children().unwrap()[3];
        let g = QuadGeometry::compute(&Ellipsoid::MOON, CubeProjection::Qsc, quad, 17);
        let whole = QuadBounds::compute(&g, -100.0, 100.0);
        let patches = patch_bounds(&g, &[(-100.0, 100.0); 64], 0.0);
        assert_eq!(patches.len(), 64);
        // Every sample of the coarse geometry is in the patch boxes that share it, and every
        // patch box is much smaller than the quad's.
        for (n, b) in patches.iter().enumerate() {
            assert!(b.radius_m() < whole.radius_m() / 4.0, "patch {n}: {} vs {}", b.radius_m(), whole.radius_m());
            let (px, py) = (n as u32 % 8, n as u32 / 8);
            for (i, j) in [(2 * px, 2 * py), (2 * px + 2, 2 * py + 2), (2 * px + 1, 2 * py + 1)] {
                let (s, t) = crate::ecm::geometry::sample_st(17, i, j);
                let p = crate::ecm::geometry::interpolate_f64(g.split, &g.corners_ecef, s, t)
                    + g.maps_at(i, j).map_or(glam::DVec3::ZERO, |m| m[0].as_dvec3());
                assert!(b.contains(p), "patch {n} lacks its sample ({i},{j})");
            }
        }
    }

    #[test]
    fn a_quad_larger_than_the_view_draws_only_the_patches_that_show_and_coarser_far_away() {
        // Looking obliquely at a level-3 quad from 20 km: part of it is off screen.
        let quad = QuadId::root(Face::Front).children().unwrap()[0].children().unwrap()[0].children().unwrap()[0];
        let (edge_m, bounds) = quad_patches(quad);
        let corner = crate::ecm::geometry::quad_corners(&Ellipsoid::MOON, CubeProjection::Qsc, quad).0[0];
        let g = crate::geodesy::geodetic_from_ecef(&Ellipsoid::MOON, corner);
        let spec = CameraSpec {
            lat: g.lat_rad.to_degrees(),
            lon: g.lon_rad.to_degrees(),
            alt: 20_000.0,
            heading: 45.0,
            pitch: -20.0,
            fov: 60.0,
        };
        let camera = Camera::new(&Ellipsoid::MOON, spec, 1.0);
        let quads = [QuadPatches { edge_m, bounds: &bounds }];
        let full = select_patches(&camera, &params(1.5), &quads, false, true);
        assert!(full.patches.iter().all(|p| !p.morphs), "whole quads do not morph");
        assert_eq!(full.patches.len(), 64);
        // Whole: skirts only round the quad's edge (32 patch sides).
        assert_eq!(full.triangles(), 64 * triangles_at(1, 0) + 32 * 2 * 32);
        let corner = full.patches.iter().find(|p| (p.px, p.py) == (0, 0)).unwrap();
        assert_eq!(corner.skirts, SOUTH | WEST);
        assert!(full.patches.iter().any(|p| (p.px, p.py) == (3, 4) && p.skirts == 0));
        let near = select_patches(&camera, &params(1.5), &quads, true, true);
        assert!(near.culled_frustum > 0, "{near:?}");
        assert!(near.triangles() < full.triangles(), "{} of {}", near.triangles(), full.triangles());
        // From 500 km its samples cover about one pixel at the nearest corner, less beyond.
        let camera = Camera::new(&Ellipsoid::MOON, CameraSpec { alt: 500_000.0, pitch: -40.0, ..spec }, 1.0);
        let adaptive = select_patches(&camera, &params(1.5), &quads, true, true);
        assert!(adaptive.triangles() * 4 < full.triangles() * 3, "{} of {}", adaptive.triangles(), full.triangles());
        let strides: std::collections::BTreeSet<u32> = adaptive.patches.iter().map(|p| p.stride).collect();
        assert!(strides.len() >= 2, "near and far patches at different strides: {strides:?}");
        // Each drawn patch's stride keeps a sample at its nearest point under t, unless it is 1.
        for p in &adaptive.patches {
            let info = QuadInfo { bounds: bounds[(p.py * 8 + p.px) as usize][0], edge_m };
            let px = pixels_per_sample(&camera, &info, 512);
            assert!(p.stride == 1 || f64::from(p.stride) * px <= 1.5, "{p:?}: {px}");
            assert!(p.stride == 32 || f64::from(2 * p.stride) * px > 1.5, "{p:?} could be coarser: {px}");
        }
        // Sorted into one run per stride.
        let groups = adaptive.groups();
        let kinds: std::collections::BTreeSet<(u32, u8, bool)> = groups.iter().map(|g| (g.0, g.1, g.2)).collect();
        assert_eq!(kinds.len(), groups.len(), "one run per stride, set of skirts and morphing");
        assert_eq!(groups.iter().map(|g| g.4 as usize).sum::<usize>(), adaptive.patches.len());
        // A patch that does not morph has no point inside the band: its farthest corner's
        // factor is 0, so every vertex's is; some do and some do not.
        let focal = camera.focal_px(512);
        for p in adaptive.patches.iter().filter(|p| !p.morphs) {
            let b = bounds[(p.py * 8 + p.px) as usize][stride_index(p.stride)];
            let far = b.corners().iter().map(|c| (*c - camera.position).length()).fold(0.0, f64::max);
            assert_eq!(morph_factor(p.stride, edge_m / 256.0, far, focal, 1.5), 0.0, "{p:?}");
        }
        assert!(adaptive.patches.iter().any(|p| p.morphs) && adaptive.patches.iter().any(|p| !p.morphs));
        // A side without a skirt has a neighbour in the quad drawn at the same stride.
        let at = |px: i32, py: i32| adaptive.patches.iter().find(|p| (p.px as i32, p.py as i32) == (px, py));
        let mut bare = 0;
        for p in &adaptive.patches {
            for (side, (dx, dy)) in [(SOUTH, (0, -1)), (EAST, (1, 0)), (NORTH, (0, 1)), (WEST, (-1, 0))] {
                if p.skirts & side == 0 {
                    let n = at(p.px as i32 + dx, p.py as i32 + dy);
                    assert_eq!(n.map(|n| n.stride), Some(p.stride), "{p:?}: side {side} bare");
                    bare += 1;
                }
            }
        }
        assert!(bare > 0, "some sides between equal strides go without a skirt");
    }
}
