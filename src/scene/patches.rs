//! Per-patch density and culling: a drawn quad is drawn as 8 × 8 patches of 32 × 32 sample
//! spacings, each culled against the frustum and the horizon on its own and drawn at the
//! coarsest stride (1, 2, 4 … 32 samples) whose geometric error δ (the largest vertical miss
//! between the data under the patch and the mesh that stride draws: [`super::patch_error`])
//! projects under the pixel error τ at the patch's nearest point, so that a quad much larger than
//! the view costs only the part of it that shows, and flat or smooth ground costs few triangles
//! whatever its sampling. What the pixels show is read from the data in the fragment stage, so
//! the mesh needs only to stand where the surface is. Patches of different strides meet at
//! T-junctions; each patch has its own skirt ring, as quads do, so the seams stay closed.

use super::camera::Camera;
use super::select::{SelectParams, cull_box, tally};
use crate::ecm::geometry::{QuadBounds, QuadGeometry};

/// Patches along a quad's edge.
pub const PATCHES_PER_EDGE: u32 = 8;
/// Sample spacings along a patch's edge (256 / 8).
pub const PATCH_CELLS: u32 = 32;
/// The strides a patch may be drawn at, in samples, finest first.
pub const STRIDES: [u32; 6] = [1, 2, 4, 8, 16, 32];

/// Where the morph band ends: a vertex of a patch at stride s morphs toward the mesh at 2s by
/// ρ = reach / d, its distance d against the patch's reach (where the coarser mesh's error,
/// projected, is τ / [`MORPH_BAND_START`]): fully up to ρ = 1.1 (the band's start), not at all
/// from ρ = 1.6 on.
/// A patch takes stride s when ρ of stride s passes 1.1 at its nearest point, where every vertex
/// of it has morphed fully toward what the patch at 2s draws, that patch's own morph toward 4s
/// included ([`morph_weights`]): the change draws what was drawn before, however much of its
/// distance the patch spans (up to half of it at grazing views, where the coarser patch is still
/// morphing at its far side). Its errors at least double per stride ([`effective_errors`]), so
/// the 4s patch's own morph toward 8s is 0 there (ρ ≥ 4 × 1.1 × near/far ≥ 1.6 while the patch's
/// far side lies at most 2.75 × as far as its near one): one step of the chain is enough.
pub const MORPH_BAND_END: f64 = 1.6;
/// Where the morph band starts: up to ρ = 1.1 a vertex has morphed fully, so that a change of
/// stride or level that ρ passed by less than 10 % since the last frame (the camera's step) still
/// finds every vertex of the finer patch on the coarser mesh. A stride is taken where its error
/// projects to at most τ / 1.1, so that a vertex morphed fully at ρ = 1.1 is within τ.
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
/// stride (0 … 1): `reach_m` the patch's reach ([`morph_reach`]), `distance_m` the vertex's
/// distance from the eye. The terrain shader's `morph_factor` twin.
pub fn morph_factor(stride: u32, reach_m: f64, distance_m: f64) -> f64 {
    if stride >= PATCH_CELLS {
        return 0.0;
    }
    let rho = reach_m / distance_m.max(1e-6);
    ((MORPH_BAND_END - rho) / (MORPH_BAND_END - MORPH_BAND_START)).clamp(0.0, 1.0)
}

/// A patch's reach at a stride whose next coarser stride has the (effective) error `coarser_m`:
/// the distance at which that error, seen with a focal length of `focal_px`, projects to
/// τ / [`MORPH_BAND_START`] pixels (`max_pixel_error_px` = τ); nearer, ρ = reach / d exceeds 1.
pub fn morph_reach(coarser_m: f64, focal_px: f64, max_pixel_error_px: f64) -> f64 {
    MORPH_BAND_START * coarser_m * focal_px / max_pixel_error_px.max(1e-6)
}

/// A patch's errors as selection and morphing use them, from δ per stride (metres, as drawn:
/// exaggerated): monotone, and at least doubling from one stride to the next, as the sample
/// spacing does, so that the morph bands of two strides never overlap (see [`MORPH_BAND_END`]).
/// Never below δ, so a bound on these is a bound on the error.
pub fn effective_errors(delta_m: &[f64; STRIDES.len()]) -> [f64; STRIDES.len()] {
    let mut out = [0f64; STRIDES.len()];
    for k in 0..STRIDES.len() {
        // Twice the finer effective error is already at least every finer δ.
        out[k] = if k == 0 { delta_m[0] } else { delta_m[k].max(2.0 * out[k - 1]) };
    }
    out
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
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Patch {
    /// The stride, samples (one of [`STRIDES`]).
    pub stride: u32,
    /// Whether any of its vertices may morph this frame (drawn by the pipeline that morphs;
    /// the others by one without the morph's work).
    pub morphs: bool,
    /// The sides with a skirt ([`SOUTH`] | [`EAST`] | [`NORTH`] | [`WEST`]): those on the quad's
    /// edge, and those whose neighbour in the quad is drawn at another stride or reach, or not at
    /// all. Two patches of one quad at one stride and reach compute their shared edge's vertices
    /// identically, so no gap can open between them.
    pub skirts: u8,
    /// The quad's index in the frame's drawn quads.
    pub quad: u32,
    /// The patch's row and column in the quad (0 … 7).
    pub py: u32,
    /// The patch's column.
    pub px: u32,
    /// Where its vertices morph toward twice the stride ([`morph_reach`], metres; 0 at the
    /// coarsest stride, which does not morph).
    pub reach_m: f32,
    /// Where the mesh at twice the stride morphs toward four times it: the reach the patch
    /// would have at twice the stride (0 where that is the coarsest). A vertex morphs toward
    /// what the coarser patch draws, itself morphed ([`morph_weights`]).
    pub reach_up_m: f32,
    /// The largest projected geometric error of what it draws this frame, pixels.
    pub error_px: f32,
    /// Per side (south, east, north, west, as [`SIDES`]), the index in
    /// [`PatchSelection::patches`] of the neighbour in the quad that owns the shared edge, whose
    /// edge the patch's vertices on that side then stand on ([`vertex_weights`]): one drawn at a
    /// coarser stride, or at the same stride morphing otherwise and earlier in the quad (row by
    /// row); [`NO_PATCH`] where the patch owns the edge itself, or the neighbour is not drawn.
    pub edge_owner: [u32; 4],
}

/// No patch (a side whose edge the patch owns).
pub const NO_PATCH: u32 = u32::MAX;

/// The sides in the order of [`Patch::edge_owner`], with the step to the neighbour across each.
pub const SIDES: [(u8, (i32, i32)); 4] = [(SOUTH, (0, -1)), (EAST, (1, 0)), (NORTH, (0, 1)), (WEST, (-1, 0))];

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
    /// Patches to draw, sorted by stride, skirts and morphing, then quad, row and column.
    pub patches: Vec<Patch>,
    /// Patches of drawn quads dropped outside the frustum.
    pub culled_frustum: usize,
    /// Patches of drawn quads dropped behind the horizon.
    pub culled_horizon: usize,
    /// The largest projected geometric error of what is drawn, pixels.
    pub max_error_px: f64,
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

/// The stride a patch needs: the coarsest of [`STRIDES`] whose effective error `errors_m[k]`,
/// seen at `distance_m` with a focal length of `focal_px`, projects to at most τ / 1.1 pixels
/// (`max_pixel_error_px` = τ; 1 when even stride 2 would not).
pub fn stride_for(errors_m: &[f64; STRIDES.len()], distance_m: f64, focal_px: f64, max_pixel_error_px: f64) -> u32 {
    let allowed = max_pixel_error_px / MORPH_BAND_START;
    let k = (0..STRIDES.len()).rev().find(|&k| errors_m[k] * focal_px / distance_m.max(1e-6) <= allowed).unwrap_or(0);
    STRIDES[k]
}

/// The largest projected error of a patch drawn at `stride` with effective errors `errors_m`
/// (metres) whose vertices lie between `near_m` and `far_m` from the eye: each vertex draws its
/// stride's mesh blended by its morph factor m toward what the coarser patch draws there, itself
/// blended by m′ toward the mesh at four times the stride (`reach_up_m`), so its error is at most
/// (1 − m)·δₛ + m·((1 − m′)·δ₂ₛ + m′·δ₄ₛ), seen at its distance. Over a band's part of the
/// distances one of m and m′ varies, as 1/d does, and the other is 0 or 1, so the projected error
/// is a concave quadratic in 1/d there: the largest is at the nearest or farthest point, where a
/// band starts or ends, or at a quadratic's summit.
pub fn drawn_error_px(
    errors_m: &[f64; STRIDES.len()],
    stride: u32,
    reach_m: f64,
    reach_up_m: f64,
    near_m: f64,
    far_m: f64,
    focal_px: f64,
) -> f64 {
    let k = stride_index(stride);
    let e = |n: usize| errors_m.get(n).copied().unwrap_or(errors_m[errors_m.len() - 1]);
    let at = |d: f64| {
        let m = morph_factor(stride, reach_m, d);
        let up = morph_factor(2 * stride, reach_up_m, d);
        ((1.0 - m) * e(k) + m * ((1.0 - up) * e(k + 1) + up * e(k + 2))) * focal_px / d.max(1e-6)
    };
    // A band's summit: d·(e₀ + Δ·(ρ_end − R/d)/w) has its largest 1/d·… at d = 2RΔ / (w·e₀ + ρ_end·Δ)
    // (w the band's width, Δ the errors' step), where that lies inside the band.
    let width = MORPH_BAND_END - MORPH_BAND_START;
    let summit = |reach: f64, low: f64, high: f64| {
        let step = high - low;
        2.0 * reach * step / (width * low + MORPH_BAND_END * step).max(1e-300)
    };
    let mut worst = at(near_m).max(at(far_m));
    for d in [
        reach_m / MORPH_BAND_START,
        reach_m / MORPH_BAND_END,
        reach_up_m / MORPH_BAND_START,
        reach_up_m / MORPH_BAND_END,
        summit(reach_m, e(k), e(k + 1)),
        summit(reach_up_m, e(k + 1), e(k + 2)),
    ] {
        if d > near_m && d < far_m {
            worst = worst.max(at(d));
        }
    }
    worst
}

/// What a patch at `stride` draws at its vertex (a, b), sample (i, j): the samples it blends and
/// their weights (summing to 1). Its own sample by 1 − m and, by m (its [`morph_factor`] at its
/// distance), what the patch at twice the stride draws there: at a sample that mesh has, that
/// sample morphed toward four times the stride by its own factor m′ (`reach_up_m`), and at one
/// it lacks, the midpoint of its two neighbours there ([`morph_neighbours`]) each so morphed. So a
/// change of stride draws what was drawn before even where the coarser patch was itself
/// morphing. `distance_m` gives a sample's distance from the eye (its unmorphed position's);
/// (a, b) in the patch's vertices, `origin` its first sample. The terrain shader's `vs_main`
/// twin.
pub fn morph_weights(
    stride: u32,
    reach_m: f64,
    reach_up_m: f64,
    origin: (u32, u32),
    (a, b): (u32, u32),
    mut distance_m: impl FnMut(u32, u32) -> f64,
) -> Vec<((u32, u32), f64)> {
    let at = |base: (u32, u32), d: (i64, i64)| ((i64::from(base.0) + d.0) as u32, (i64::from(base.1) + d.1) as u32);
    let own = (origin.0 + a * stride, origin.1 + b * stride);
    let m = morph_factor(stride, reach_m, distance_m(own.0, own.1));
    let mut out = vec![(own, 1.0 - m)];
    if m <= 0.0 {
        return out;
    }
    let coarse = match morph_neighbours(a, b, stride) {
        Some([n1, n2]) => vec![(at(own, n1), 0.5 * m), (at(own, n2), 0.5 * m)],
        None => vec![(own, m)],
    };
    let up = 2 * stride;
    for (sample, w) in coarse {
        let m2 = morph_factor(up, reach_up_m, distance_m(sample.0, sample.1));
        out.push((sample, w * (1.0 - m2)));
        if m2 > 0.0 {
            let (a2, b2) = ((sample.0 - origin.0) / up, (sample.1 - origin.1) / up);
            match morph_neighbours(a2, b2, up) {
                Some([n1, n2]) => out.extend([(at(sample, n1), 0.5 * w * m2), (at(sample, n2), 0.5 * w * m2)]),
                None => out.push((sample, w * m2)),
            }
        }
    }
    out
}

/// A patch as [`vertex_weights`] needs it to place vertices: the patch itself, or the neighbour
/// that owns the edge on one of its sides ([`owns_edge`]).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PatchMorph {
    /// Its stride, samples.
    pub stride: u32,
    /// Its reaches ([`Patch::reach_m`], [`Patch::reach_up_m`]; infinite where it does not morph).
    pub reach_m: f64,
    /// Where its coarser mesh morphs.
    pub reach_up_m: f64,
    /// Its first sample.
    pub origin: (u32, u32),
}

/// What a patch draws at one vertex: the samples its own morph blends ([`morph_weights`]), and on
/// a side whose edge a neighbour owns the samples of the owner's edge point there.
#[derive(Clone, Debug, PartialEq)]
pub struct VertexWeights {
    /// The vertex as the patch morphs it.
    pub own: Vec<((u32, u32), f64)>,
    /// The point of the owner's edge, linear between its two vertices around, each as the owner
    /// draws it; None off an owned side (and at a corner, which every stride has and none moves).
    pub edge: Option<Vec<((u32, u32), f64)>>,
}

/// Where a vertex stands: its own morphed place `own`, moved across to the owner's edge point
/// `edge` where it has one, at its own height along its normal `up` (the vertical is left to
/// the patch's own morph, so that an owner's change of stride moves a vertex only sideways, by
/// at most the gap it closes). The terrain shader's `vertex_place` twin.
pub fn stand_on_edge(own: glam::DVec3, edge: Option<glam::DVec3>, up: glam::DVec3) -> glam::DVec3 {
    edge.map_or(own, |e| e + up * (own - e).dot(up))
}

/// What patch `p` draws at its vertex (a, b), with the owners of its sides' edges (`sides`, in
/// the order of [`SIDES`]): its own morph ([`morph_weights`]) and, on a side a neighbour owns,
/// the point of that neighbour's edge ([`VertexWeights`]; [`stand_on_edge`] combines them). The
/// terrain shader's `vs_main` twin.
pub fn vertex_weights(
    p: PatchMorph,
    (a, b): (u32, u32),
    sides: [Option<PatchMorph>; 4],
    mut distance_m: impl FnMut(u32, u32) -> f64,
) -> VertexWeights {
    let PatchMorph { stride, reach_m, reach_up_m, origin } = p;
    let own = morph_weights(stride, reach_m, reach_up_m, origin, (a, b), &mut distance_m);
    let n = PATCH_CELLS / stride;
    let on = [b == 0, a == n, b == n, a == 0];
    let (i, j) = (origin.0 + a * stride, origin.1 + b * stride);
    let side = on.iter().position(|&s| s).filter(|_| on.iter().filter(|&&s| s).count() == 1);
    let Some(c) = side.and_then(|side| sides[side]) else {
        return VertexWeights { own, edge: None };
    };
    // Along the side: i on the south and north sides, j on the east and west ones.
    let along_i = side.is_some_and(|side| side % 2 == 0);
    let u = if along_i { i } else { j };
    let lo = u - u % c.stride;
    let t = f64::from(u - lo) / f64::from(c.stride);
    let vertex = |u: u32| {
        let (vi, vj) = if along_i { (u, j) } else { (i, u) };
        ((vi - c.origin.0) / c.stride, (vj - c.origin.1) / c.stride)
    };
    let mut edge = morph_weights(c.stride, c.reach_m, c.reach_up_m, c.origin, vertex(lo), &mut distance_m);
    if t > 0.0 {
        edge.iter_mut().for_each(|(_, w)| *w *= 1.0 - t);
        let hi = morph_weights(c.stride, c.reach_m, c.reach_up_m, c.origin, vertex(lo + c.stride), &mut distance_m);
        edge.extend(hi.into_iter().map(|(s, w)| (s, w * t)));
    }
    VertexWeights { own, edge: Some(edge) }
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

/// One drawn quad as patch selection sees it: its 64 patches' boxes and errors at each stride.
pub struct QuadPatches<'a> {
    /// Per patch (row-major), its boxes at each stride.
    pub bounds: &'a [StrideBoxes],
    /// Per patch (row-major), its effective errors at each stride ([`effective_errors`],
    /// metres as drawn).
    pub errors_m: &'a [[f64; STRIDES.len()]],
}

/// The patches of the drawn quads (in their order) to draw: each culled on its own and at the
/// stride its nearest point needs under the pixel error `max_pixel_error_px`. With `adaptive`
/// false every patch is drawn at stride 1 and none is culled: the quads drawn whole, as before
/// patches (for comparisons and the vertex tests that want every sample). With `morph`
/// (geomorphing on, adaptive patches), a patch `morphs` unless even its farthest point is past
/// the morph band ([`morph_factor`] 0 there, so at every vertex).
pub fn select_patches(
    camera: &Camera,
    params: &SelectParams,
    quads: &[QuadPatches],
    adaptive: bool,
    morph: bool,
    max_pixel_error_px: f64,
) -> PatchSelection {
    let focal = camera.focal_px(params.height);
    let mut out = PatchSelection::default();
    let planes = camera.frustum(params.width, params.height);
    for (k, q) in quads.iter().enumerate() {
        for (n, bounds) in q.bounds.iter().enumerate() {
            let (px, py) = (n as u32 % PATCHES_PER_EDGE, n as u32 / PATCHES_PER_EDGE);
            let errors = &q.errors_m[n];
            let near = bounds[0].distance_m(camera.position).max(camera.near_m);
            let stride = if adaptive {
                // The stride from the patch's own surface; culled by what it draws at that stride.
                let stride = stride_for(errors, near, focal, max_pixel_error_px);
                let culled = cull_box(camera, &planes, params.occluder_m, &bounds[stride_index(stride)]);
                if tally(culled, &mut out.culled_frustum, &mut out.culled_horizon) {
                    continue;
                }
                stride
            } else {
                1
            };
            let b = &bounds[stride_index(stride)];
            let far = b.corners().iter().map(|c| (*c - camera.position).length()).fold(0.0, f64::max);
            let reach_at = |k: usize| match errors.get(k) {
                Some(&e) if STRIDES[k - 1] < PATCH_CELLS => morph_reach(e, focal, max_pixel_error_px),
                _ => 0.0,
            };
            let (reach, reach_up) = (reach_at(stride_index(stride) + 1), reach_at(stride_index(stride) + 2));
            // The shader measures from f32 positions: 1 % nearer counts as morphing.
            let morphs = morph && adaptive && morph_factor(stride, reach, far * 1.01) > 0.0;
            let (drawn_reach, drawn_up) = if morphs { (reach, reach_up) } else { (f64::INFINITY, f64::INFINITY) };
            let error_px = drawn_error_px(errors, stride, drawn_reach, drawn_up, near, far.max(near), focal);
            out.max_error_px = out.max_error_px.max(error_px);
            out.patches.push(Patch {
                stride,
                morphs,
                skirts: ALL_SIDES,
                quad: k as u32,
                py,
                px,
                reach_m: reach as f32,
                reach_up_m: reach_up as f32,
                error_px: error_px as f32,
                edge_owner: [NO_PATCH; 4],
            });
        }
    }
    hang_skirts(&mut out.patches);
    stand_on_owned_edges(&mut out.patches);
    out
}

/// Whether a neighbour owns the edge it shares with a patch: drawn coarser, or at the same stride
/// morphing otherwise (their [`MorphKey`]s) and earlier in the quad (`index`: py · 8 + px), so
/// that of two patches that would place the edge's vertices apart exactly one defers to the other.
pub fn owns_edge(neighbour: MorphKey, neighbour_index: u32, own: MorphKey, index: u32) -> bool {
    neighbour.0 > own.0 || (neighbour.0 == own.0 && neighbour != own && neighbour_index < index)
}

/// Sorts the patches for drawing and points each side at the neighbour in the quad that owns the
/// edge ([`owns_edge`]). The patch's vertices on that side then stand on the owner's edge
/// sideways ([`stand_on_edge`]): without it, a vertex a coarser edge lacks stands on the
/// ellipsoid at its own sample while the coarser edge is a chord between its vertices, which on
/// a large quad lies beside it horizontally too (the projection is not linear along it), and two
/// patches morphing by other reaches place their shared vertices apart: gaps no vertical skirt
/// covers from above (pixels of background through the Moon's globe). Heights stay the patch's
/// own, whose differences the skirts close, so nothing pops vertically when an owner changes its
/// stride. A patch computes its owner's vertices as the owner does, so it morphs where the owner
/// does.
fn stand_on_owned_edges(patches: &mut Vec<Patch>) {
    let n = PATCHES_PER_EDGE as i32;
    let at: std::collections::HashMap<(u32, i32, i32), usize> =
        patches.iter().enumerate().map(|(k, p)| ((p.quad, p.px as i32, p.py as i32), k)).collect();
    let neighbour = |p: &Patch, (dx, dy): (i32, i32)| {
        let (x, y) = (p.px as i32 + dx, p.py as i32 + dy);
        ((0..n).contains(&x) && (0..n).contains(&y)).then(|| at.get(&(p.quad, x, y)).copied()).flatten()
    };
    let index = |p: &Patch| p.py * PATCHES_PER_EDGE + p.px;
    let sides: Vec<[Option<usize>; 4]> = patches
        .iter()
        .map(|p| {
            SIDES.map(|(_, step)| {
                neighbour(p, step)
                    .filter(|&k| owns_edge(morph_key(&patches[k]), index(&patches[k]), morph_key(p), index(p)))
            })
        })
        .collect();
    for k in 0..patches.len() {
        if sides[k].iter().flatten().any(|&c| patches[c].morphs) {
            patches[k].morphs = true;
        }
    }
    let mut order: Vec<usize> = (0..patches.len()).collect();
    order.sort_unstable_by_key(|&k| {
        let p = &patches[k];
        (p.stride, p.skirts, p.morphs, p.quad, p.py, p.px)
    });
    let mut rank = vec![0u32; patches.len()];
    for (r, &k) in order.iter().enumerate() {
        rank[k] = r as u32;
    }
    let sorted: Vec<Patch> = order
        .iter()
        .map(|&k| Patch { edge_owner: sides[k].map(|c| c.map_or(NO_PATCH, |c| rank[c])), ..patches[k] })
        .collect();
    *patches = sorted;
}

/// What decides where a patch's edge vertices stand: its stride, and the bits of its reaches
/// where it morphs (`u32::MAX` twice where it does not). Two neighbours of equal keys place their
/// shared vertices alike (no skirt, no owner between them); the stride comes first, so a larger
/// key's patch is the coarser.
pub type MorphKey = (u32, u32, u32);

/// A patch's [`MorphKey`].
fn morph_key(p: &Patch) -> MorphKey {
    if p.morphs { (p.stride, p.reach_m.to_bits(), p.reach_up_m.to_bits()) } else { (p.stride, u32::MAX, u32::MAX) }
}

/// Keeps the skirts a patch needs: on the quad's edge (where another quad, drawn from other
/// values, meets it), and toward a neighbour drawn at another stride (a T-junction), morphing by
/// other reaches, or not at all.
fn hang_skirts(patches: &mut [Patch]) {
    let n = PATCHES_PER_EDGE as usize;
    let mut strides: std::collections::HashMap<u32, Vec<(u32, u32, u32)>> = std::collections::HashMap::new();
    for p in patches.iter() {
        strides.entry(p.quad).or_insert_with(|| vec![(0, 0, 0); n * n])[p.py as usize * n + p.px as usize] =
            morph_key(p);
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
            if neighbour(dx, dy) != Some(morph_key(p)) {
                skirts |= side;
            }
        }
        p.skirts = skirts;
    }
}

#[cfg(test)]
mod tests;
