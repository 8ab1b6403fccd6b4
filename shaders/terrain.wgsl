// The ECM terrain: one instanced draw per stride of the selected quads' patches (32 × 32 sample
// spacings of a quad, drawn every stride samples). Vertex stage: geometry only, the
// camera-centric single-precision reconstruction P = A′ + (patch + oₑ + h₀·δn + (h − h₀)·nₑ) with
// skirts and geomorphing. Fragment stage: what the user reads, from the composed data at the
// pixel, not from the vertices: the quad's heights at the pixel's sample coordinates (bilinear,
// by hand: storage reads), their gradient for the normal, and from those the colour ramp (over
// the height or a terrain attribute: slope, aspect and hillshade from the normal, curvatures,
// TPI, TRI and roughness from the samples' 3 × 3 windows), isolines, hillshade and the drawn
// difference layer's dh in a diverging colour map with its own isolines. A coarse mesh and the
// finest one therefore show the same colours and lines but within a pixel of silhouettes.
//!include shared/ecm.wgsl
//!include shared/shading.wgsl
//!include shared/attributes.wgsl
//!include generated/codes.wgsl

// Samples per quad edge; sample spacings per patch edge.
const N: u32 = 257u;
const PATCH_CELLS: u32 = 32u;
// Whether this build of the pipeline geomorphs: the renderer builds it twice and draws patches
// none of whose vertices can morph without it (the morph's samples cost as much as the vertex's
// own even where no lane takes the branch, on a CPU rasteriser).
const MORPH: bool = true;
// A height slot of no data, and the value a sample without data is stored as.
const NODATA_BELOW: f32 = -1.0e37;
// A sample that is not there: past a quad whose neighbour there is not current (read as no data).
const MISSING: f32 = -3.0e38;
// Newton steps that carry a pixel from the mesh's point to the data's along its ray (on_data).
const PARALLAX_STEPS: u32 = 3u;

struct Frame {
    // Camera-relative ECEF metres to reversed-Z clip space.
    view_proj: mat4x4<f32>,
    // width, height (pixels), vertical exaggeration, number of ramp stops.
    viewport: vec4<f32>,
    // sun azimuth, sun elevation (radians), strength, lighting on (1) or off (0).
    sun: vec4<f32>,
    // isoline interval, offset (metres), major every k (0: none), isolines on (1) or off (0).
    iso: vec4<f32>,
    // minor width, major width, minimum width (pixels), what the ramp colours (0 height, else 1 +
    // the attribute's ATTRIBUTE_* code: 1 slope, 2 aspect, 3 hillshade, 4 curvature, …).
    iso_width: vec4<f32>,
    // sRGB colours 0–1 with alpha: isolines, below the ramp, above it, no data.
    iso_colour: vec4<f32>,
    below: vec4<f32>,
    above: vec4<f32>,
    nodata: vec4<f32>,
    // The drawn difference layer: range (metres: ±range are the colour map's ends), isoline
    // interval (metres, 0: none), opacity over the ramp, drawn (1) or not (0).
    difference: vec4<f32>,
    // The brush's footprint: its centre relative to the camera (metres) and radius (0: none).
    brush: vec4<f32>,
    // Geomorphing: focal length over t (pixels per pixel), the morph band's end, on (1) or off
    // (0), the band's start.
    morph: vec4<f32>,
}

struct Quad {
    // A′ = A − C (xyz) and the reference height h₀ (w, exaggerated metres).
    anchor: vec4<f32>,
    // Corners raised to h₀, relative to A, with A′'s rounding (SW, SE, NW, NE).
    corners: array<vec4<f32>, 4>,
    // Unit ellipsoid normals at the corners.
    normals: array<vec4<f32>, 4>,
    // Columns of the signed permutation from the canonical quad's axes to this quad's.
    sym: array<vec4<f32>, 3>,
    // split code, map slot (NO_SLOT: flat), height slot (NO_SLOT: no data), symmetry flags.
    slots: vec4<u32>,
    // skirt depth (metres), level, height drawn where there is no data, the deepest skirt a
    // coarser stride may need (relief and roughness, metres).
    params: vec4<f32>,
    // The quad's sample spacing (its longest edge / 256, metres), unused ×3.
    lod: vec4<f32>,
    // The height slots of the ancestors 1 … 5 levels up (NO_SLOT: none current), unused, and the
    // quad's x and y (their low bits place it in each ancestor).
    ancestry: array<vec4<u32>, 2>,
    // The height slots of the eight quads around it at its level (south-west, south, south-east,
    // west, east, north-west, north, north-east; NO_SLOT where one is not current or over the
    // face's edge): a pixel near the quad's edge reads the samples past it there (block).
    around: array<vec4<u32>, 2>,
}

struct Patch {
    // The quad's index in `quads`.
    quad: u32,
    // The sample (i, j) of the patch's first corner.
    i0: u32,
    j0: u32,
    // Samples between two vertices.
    stride: u32,
    // Where its vertices morph toward twice the stride: ρ = reach / distance (metres).
    reach: f32,
    // Where the mesh at twice the stride morphs toward four times it (metres).
    reach_up: f32,
    pad: array<f32, 2>,
    // Per side (south, east, north, west) the index in `patches` of the neighbour in the quad
    // that owns the shared edge (drawn coarser, or at the stride morphing otherwise and earlier in
    // the quad), NO_PATCH where the patch owns it: the vertices on that side stand on its edge.
    edge_owner: vec4<u32>,
}

const NO_PATCH: u32 = 0xffffffffu;

struct RampStop {
    // x: height in metres.
    value: vec4<f32>,
    // sRGB 0–1 with alpha.
    colour: vec4<f32>,
}

@group(0) @binding(0) var<uniform> frame: Frame;
@group(0) @binding(1) var<storage, read> quads: array<Quad>;
@group(0) @binding(2) var<storage, read> heights: array<f32>;
@group(0) @binding(3) var<storage, read> map_o: array<f32>;
@group(0) @binding(4) var<storage, read> map_n: array<f32>;
@group(0) @binding(5) var<storage, read> map_dn: array<f32>;
@group(0) @binding(6) var<storage, read> ramp: array<RampStop>;
// A − B of the drawn difference layer per height slot (NODATA_BELOW where either has no data).
@group(0) @binding(7) var<storage, read> overlay: array<f32>;
@group(0) @binding(8) var<storage, read> patches: array<Patch>;

struct VertexOut {
    @builtin(position) clip: vec4<f32>,
    // Camera-relative position, metres.
    @location(0) rel: vec3<f32>,
    // Ellipsoid normal.
    @location(1) up: vec3<f32>,
    // The ellipsoid's tangents along the sample axes (∂P/∂i, ∂P/∂j), metres per sample.
    @location(2) along_i: vec3<f32>,
    @location(3) along_j: vec3<f32>,
    // The vertex's sample coordinates in its quad (the fragment reads the data there).
    @location(4) coords: vec2<f32>,
    // Which quad; bit 0 a skirt vertex, the patch's stride above it (probe output).
    @location(5) @interpolate(flat) quad: u32,
    @location(6) @interpolate(flat) kind: u32,
}

fn map_value(which: u32, slot: u32, c: vec2<u32>) -> vec3<f32> {
    let k = 3u * (slot * N * N + c.y * N + c.x);
    var v: vec3<f32>;
    switch which {
        case 0u: { v = vec3<f32>(map_o[k], map_o[k + 1u], map_o[k + 2u]); }
        case 1u: { v = vec3<f32>(map_n[k], map_n[k + 1u], map_n[k + 2u]); }
        default: { v = vec3<f32>(map_dn[k], map_dn[k + 1u], map_dn[k + 2u]); }
    }
    return v;
}

fn turn(q: Quad, v: vec3<f32>) -> vec3<f32> {
    // Entries are 0 and ±1: exact.
    return q.sym[0].xyz * v.x + q.sym[1].xyz * v.y + q.sym[2].xyz * v.z;
}

fn st(i: u32, j: u32) -> vec2<f32> {
    return vec2<f32>(f32(i), f32(j)) / f32(N - 1u);
}

// Raw stored height of sample (i, j) (NODATA_BELOW where none).
fn raw_height(q: Quad, i: u32, j: u32) -> f32 {
    if q.slots.z == NO_SLOT {
        return NODATA_BELOW * 2.0;
    }
    return heights[q.slots.z * N * N + j * N + i];
}

// The height the geometry stands on at sample (i, j) (exaggerated; the no-data fill where there
// is none): the quad's own data at every stride, so that what a stride draws, and its error, are
// a function of the quad's composed heights alone, whatever else is resident.
fn geometry_height(q: Quad, i: u32, j: u32) -> f32 {
    let raw = raw_height(q, i, j);
    return select(q.params.z, raw, raw > NODATA_BELOW) * frame.viewport.z;
}

// The ellipsoid normal at a sample (the map, or the normalised patch past the flat rule).
fn ellipsoid_normal(q: Quad, i: u32, j: u32) -> vec3<f32> {
    let uv = st(i, j);
    if q.slots.y == NO_SLOT {
        return normalize(ecm_interpolate(q.slots.x, q.normals[0].xyz, q.normals[1].xyz, q.normals[2].xyz, q.normals[3].xyz, uv.x, uv.y));
    }
    return turn(q, map_value(1u, q.slots.y, ecm_canonical_sample(q.slots.w, N, i, j)));
}

// The ellipsoid point of a sample relative to A′ (corners at h₀): patch + oₑ, for tangents.
fn surface_point(q: Quad, i: u32, j: u32) -> vec3<f32> {
    let uv = st(i, j);
    let base = ecm_interpolate(q.slots.x, q.corners[0].xyz, q.corners[1].xyz, q.corners[2].xyz, q.corners[3].xyz, uv.x, uv.y);
    if q.slots.y == NO_SLOT {
        return base;
    }
    return base + turn(q, map_value(0u, q.slots.y, ecm_canonical_sample(q.slots.w, N, i, j)));
}

// The vertex position relative to A′ at height h (exaggerated metres): vertex_f32 less A′.
fn local_position(q: Quad, i: u32, j: u32, h: f32) -> vec3<f32> {
    let uv = st(i, j);
    let base = ecm_interpolate(q.slots.x, q.corners[0].xyz, q.corners[1].xyz, q.corners[2].xyz, q.corners[3].xyz, uv.x, uv.y);
    let h0 = q.anchor.w;
    if q.slots.y == NO_SLOT {
        let n = ecm_interpolate(q.slots.x, q.normals[0].xyz, q.normals[1].xyz, q.normals[2].xyz, q.normals[3].xyz, uv.x, uv.y);
        return ecm_local_flat(base, n, h0, h);
    }
    let c = ecm_canonical_sample(q.slots.w, N, i, j);
    let o = turn(q, map_value(0u, q.slots.y, c));
    let n = turn(q, map_value(1u, q.slots.y, c));
    let dn = turn(q, map_value(2u, q.slots.y, c));
    return ecm_local_with_maps(base, o, n, dn, h0, h);
}

// The attribute the ramp colours (ATTRIBUTE_*), or none (the height).
fn coloured_attribute() -> u32 {
    return select(NO_SLOT, u32(frame.iso_width.w + 0.5) - 1u, frame.iso_width.w > 0.5);
}

// The stored height of the data k levels above the quad's (0: its own) at that level's sample
// (a, b), which may lie outside the quad but inside its ancestor (NODATA_BELOW·2 where none).
fn ancestor_height(q: Quad, k: u32, a: u32, b: u32) -> f32 {
    var slot = q.slots.z;
    if k > 0u {
        slot = select(q.ancestry[1].x, q.ancestry[0][min(k, 4u) - 1u], k <= 4u);
    }
    if slot == NO_SLOT {
        return NODATA_BELOW * 2.0;
    }
    return heights[slot * N * N + b * N + a];
}

// The window attribute `code` of the data k levels above the quad's at that level's sample
// (a, b), with the centre's axes at that level, and 1 where all nine samples have data (0, 0
// where one has none). At the ancestor's edges the window moves inside it, so that the value
// there is the neighbouring sample's. CPU reference: attributes::attribute_at of the same window
// (tests/render.rs: a dome's curvature).
fn level_window(q: Quad, k: u32, a: u32, b: u32, axes: vec4<f32>, code: u32) -> vec2<f32> {
    let ca = clamp(a, 1u, N - 2u);
    let cb = clamp(b, 1u, N - 2u);
    var z: array<f32, 9>;
    var ok = true;
    // Row 0 at the top: b + 1.
    for (var m = 0u; m < 9u; m++) {
        let h = ancestor_height(q, k, ca + m % 3u - 1u, cb + 1u - m / 3u);
        ok = ok && h > NODATA_BELOW;
        z[m] = h;
    }
    if !ok {
        return vec2<f32>(0.0, 0.0);
    }
    return vec2<f32>(attribute_at(code, z, axes, HILLSHADE_LIGHT), 1.0);
}

// The ellipsoid tangents along the quad's sample axes at sample (i, j), metres per sample
// (central differences of the ellipsoid points, one-sided at the quad's edges): the fragment
// stage adds the data's slope along the normal to them.
fn ellipsoid_tangents(q: Quad, i: u32, j: u32) -> array<vec3<f32>, 2> {
    let i0 = max(i, 1u) - 1u;
    let i1 = min(i + 1u, N - 1u);
    let j0 = max(j, 1u) - 1u;
    let j1 = min(j + 1u, N - 1u);
    return array<vec3<f32>, 2>(
        (surface_point(q, i1, j) - surface_point(q, i0, j)) / f32(i1 - i0),
        (surface_point(q, i, j1) - surface_point(q, i, j0)) / f32(j1 - j0),
    );
}

// Where a vertex lies, before its skirt: relative to A′, and its ellipsoid normal.
struct Place {
    local: vec3<f32>,
    up: vec3<f32>,
    // The height it stands at (metres, exaggerated).
    h: f32,
}

fn place_at(q: Quad, i: u32, j: u32) -> Place {
    var out: Place;
    out.up = ellipsoid_normal(q, i, j);
    out.h = geometry_height(q, i, j);
    out.local = local_position(q, i, j, out.h);
    return out;
}

// Geomorphing (CDLOD, Strugar 2009, with the morph distance from the patch's error as
// Ulrich's chunked LOD has it): how far a vertex of a patch has moved toward the patch's mesh at
// twice the stride, from ρ = reach / d, the distance at which the coarser mesh's error projects
// to τ / 1.1 over the vertex's own: 1 up to the band's start (1.1), 0 from its end on. CPU twin:
// scene::patches::morph_factor.
fn morph_factor(stride: u32, reach: f32, distance: f32) -> f32 {
    if frame.morph.z < 0.5 || stride >= PATCH_CELLS {
        return 0.0;
    }
    let rho = reach / max(distance, 1e-6);
    return clamp((frame.morph.y - rho) / (frame.morph.y - frame.morph.w), 0.0, 1.0);
}

// Two places blended: `b` by m (its normal renormalised).
fn blend(a: Place, b: Place, m: f32) -> Place {
    return Place(mix(a.local, b.local, m), normalize(mix(a.up, b.up, m)), mix(a.h, b.h, m));
}

// The midpoint of two places (what the coarser mesh draws between them).
fn midpoint(a: Place, b: Place) -> Place {
    return Place(0.5 * (a.local + b.local), 0.5 * (a.up + b.up), 0.5 * (a.h + b.h));
}

// What the patch at twice p's stride draws at its sample (i, j) (one of its own): the sample,
// morphed toward four times the stride by its own factor, to the midpoint of its two neighbours
// there where that mesh lacks it.
fn coarser_place(q: Quad, p: Patch, i: u32, j: u32) -> Place {
    var s = place_at(q, i, j);
    let up = 2u * p.stride;
    let m = morph_factor(up, p.reach_up, length(q.anchor.xyz + s.local));
    let da = ((i - p.i0) / up) % 2u;
    let db = ((j - p.j0) / up) % 2u;
    if m > 0.0 && da + db > 0u {
        s = blend(s, midpoint(place_at(q, i - da * up, j - db * up), place_at(q, i + da * up, j + db * up)), m);
    }
    return s;
}

// Sample (i, j) of patch p's grid as p draws it: toward what the patch at twice the stride
// draws (coarser_place: itself morphed toward four times the stride), a vertex the coarser mesh
// lacks (odd a or b) slides to the midpoint of its two neighbours at twice the stride along the
// edge, or along the cell's cut for a cell centre; one it has follows that patch's own morph. At
// m = 1 the patch draws what the coarser patch draws, so a change of stride moves nothing even
// where the coarser patch was morphing (a patch spans up to half its distance at grazing views).
// CPU twin: scene::patches::morph_weights. Only the geometry morphs: what the pixels show is read
// from the data in the fragment stage.
fn drawn_place(q: Quad, p: Patch, i: u32, j: u32) -> Place {
    var s = place_at(q, i, j);
    let da = ((i - p.i0) / p.stride) % 2u;
    let db = ((j - p.j0) / p.stride) % 2u;
    let m = morph_factor(p.stride, p.reach, length(q.anchor.xyz + s.local));
    if MORPH && m > 0.0 {
        var toward: Place;
        if da + db > 0u {
            let n1 = coarser_place(q, p, i - da * p.stride, j - db * p.stride);
            let n2 = coarser_place(q, p, i + da * p.stride, j + db * p.stride);
            toward = midpoint(n1, n2);
        } else {
            toward = coarser_place(q, p, i, j);
        }
        s = blend(s, toward, m);
    }
    return s;
}

// Sample (i, j), the patch's vertex (a, b) of nv a side, as the patch draws it: on a side whose
// edge a neighbour owns (a corner excepted: every stride has it and none moves it), moved across
// to the point of that neighbour's edge (linear between its two vertices around as it draws
// them) at its own height along its sample's normal, so that no gap opens sideways at a T-junction or
// between two reaches (a chord's point lies beside the ellipsoid's horizontally too on a large
// quad, which no vertical skirt covers from above); heights stay the patch's own, which the
// skirts close, so an owner's change of stride moves nothing vertically. CPU twins:
// scene::patches::vertex_weights and stand_on_edge.
fn vertex_place(q: Quad, p: Patch, i: u32, j: u32, a: u32, b: u32, nv: u32) -> Place {
    let own = drawn_place(q, p, i, j);
    let on = vec4<bool>(b == 0u, a == nv - 1u, b == nv - 1u, a == 0u);
    let count = u32(on.x) + u32(on.y) + u32(on.z) + u32(on.w);
    if count != 1u {
        return own;
    }
    let side = select(select(select(3u, 2u, on.z), 1u, on.y), 0u, on.x);
    let c = p.edge_owner[side];
    if c == NO_PATCH {
        return own;
    }
    let n = patches[c];
    let along_i = side % 2u == 0u;
    let u = select(j, i, along_i);
    let lo = u - u % n.stride;
    let t = f32(u - lo) / f32(n.stride);
    var edge = drawn_place(q, n, select(i, lo, along_i), select(lo, j, along_i)).local;
    if t > 0.0 {
        let hi = lo + n.stride;
        edge = mix(edge, drawn_place(q, n, select(i, hi, along_i), select(hi, j, along_i)).local, t);
    }
    let up = ellipsoid_normal(q, i, j);
    return Place(edge + up * dot(own.local - edge, up), own.up, own.h);
}

@vertex
fn vs_main(@builtin(vertex_index) vertex: u32, @builtin(instance_index) instance: u32) -> VertexOut {
    // Vertex b·(n+1) + a is the patch's sample (a, b) at its stride; (n+1)² more, the same sample
    // lowered by the skirt depth (the index buffers of terrain.rs's patch_indices).
    let p = patches[instance];
    let q = quads[p.quad];
    let nv = PATCH_CELLS / p.stride + 1u;
    let skirt = vertex >= nv * nv;
    let v = select(vertex, vertex - nv * nv, skirt);
    let a = v % nv;
    let b = v / nv;
    let i = p.i0 + a * p.stride;
    let j = p.j0 + b * p.stride;
    let s = vertex_place(q, p, i, j, a, b, nv);
    var local = s.local;
    if skirt {
        // Deeper at coarser strides, where a neighbour's finer edge may leave its line by the
        // height change over a stride, at most the quad's relief (params.w).
        local = local - s.up * max(q.params.x, min(q.params.x * f32(p.stride), q.params.w));
    }
    let tangents = ellipsoid_tangents(q, i, j);

    var out: VertexOut;
    out.rel = q.anchor.xyz + local;
    out.clip = frame.view_proj * vec4<f32>(out.rel, 1.0);
    out.up = s.up;
    out.along_i = tangents[0];
    out.along_j = tangents[1];
    out.coords = vec2<f32>(f32(i), f32(j));
    out.quad = p.quad;
    // Bit 0 a skirt vertex, the stride above it (the probe's id.w carries both).
    out.kind = select(0u, 1u, skirt) | (p.stride << 1u);
    return out;
}

// The composed data at a pixel: its quad's heights at the pixel's sample coordinates.
struct Pixel {
    // Metres (not exaggerated): bilinear between the four samples around, or the nearest one
    // where one of them has no data; the no-data fill where that has none either.
    height: f32,
    // 1 where the pixel has data.
    valid: f32,
    // ∂h/∂i and ∂h/∂j, metres per sample: the four samples' central differences, bilinear.
    gradient: vec2<f32>,
    // The drawn difference A − B (metres), and 1 where it has data.
    dh: f32,
    dh_valid: f32,
    // ∂dh/∂i and ∂dh/∂j of its bilinear cell, metres per sample (0 where a corner has no data).
    dh_gradient: vec2<f32>,
}

// Where a pixel may read: within a quad's width around its quad (a ray followed past the quad's
// edge reads the neighbour's samples).
fn held_coords(c: vec2<f32>) -> vec2<f32> {
    return clamp(c, vec2<f32>(-f32(N - 1u)), vec2<f32>(2.0 * f32(N - 1u)));
}

// The data cell of coordinates x: the sample at or below it, and inside the quad its last cell
// at the far edges (so that a pixel there reads only the quad's own samples).
fn data_cell(x: vec2<f32>) -> vec2<i32> {
    let c = vec2<i32>(floor(x));
    let inside = (x >= vec2<f32>(0.0)) & (x <= vec2<f32>(f32(N - 1u)));
    return select(c, min(c, vec2<i32>(i32(N) - 2)), inside);
}

// Which quad along each axis sample indices lie in: −1 before the quad, 0 in it (its edges
// included), 1 past it.
fn side_of(i: vec2<i32>) -> vec2<i32> {
    return select(vec2<i32>(0), vec2<i32>(-1), i < vec2<i32>(0)) + select(vec2<i32>(0), vec2<i32>(1), i > vec2<i32>(i32(N) - 1));
}

// The height slot of the quad at side s of q at its level (0, 0: q's own): Quad.around.
fn slot_beside(q: Quad, s: vec2<i32>) -> u32 {
    let k = (s.y + 1) * 3 + s.x + 1;
    var slot = q.slots.z;
    slot = select(slot, q.around[0].x, k == 0);
    slot = select(slot, q.around[0].y, k == 1);
    slot = select(slot, q.around[0].z, k == 2);
    slot = select(slot, q.around[0].w, k == 3);
    slot = select(slot, q.around[1].x, k == 5);
    slot = select(slot, q.around[1].y, k == 6);
    slot = select(slot, q.around[1].z, k == 7);
    slot = select(slot, q.around[1].w, k == 8);
    return slot;
}

// Where sample `corner` of the quad's level lies in the quad at side s: the index of that
// sample in its slot, or NO_SLOT where that quad is not current.
fn index_beside(q: Quad, s: vec2<i32>, corner: vec2<i32>) -> u32 {
    let slot = slot_beside(q, s);
    let local = corner - s * i32(N - 1u);
    return select(NO_SLOT, slot * N * N + u32(local.y) * N + u32(local.x), slot != NO_SLOT);
}

// The samples of the quad's level in the 4 × 4 block from sample `corner` (row by row from the
// south, columns from the west), inside the quad or around it: each from the quad that holds it
// (its own, or the one beside it through Quad.around), MISSING where that one is not current.
// `which` 0 the heights, 1 the drawn difference; `size` 2 reads the 2 × 2 block (0, 1, 4, 5).
// Without branches on the pixel (a CPU rasteriser runs every branch any lane of a block takes):
// a block spans at most two quads along each axis, the corner's and the far corner's, and each
// sample picks its quad's index by its column and row.
fn block(which: u32, q: Quad, corner: vec2<i32>, size: i32) -> array<f32, 16> {
    let s0 = side_of(corner);
    let s1 = side_of(corner + size - 1);
    let base = array<u32, 4>(
        index_beside(q, s0, corner),
        index_beside(q, vec2<i32>(s1.x, s0.y), corner),
        index_beside(q, vec2<i32>(s0.x, s1.y), corner),
        index_beside(q, s1, corner),
    );
    // Per column and row, whether its samples lie in the far corner's quad.
    let far = array<vec2<bool>, 4>(
        side_of(corner) != s0,
        side_of(corner + 1) != s0,
        side_of(corner + 2) != s0,
        side_of(corner + 3) != s0,
    );
    var z: array<f32, 16>;
    for (var r = 0u; r < u32(size); r++) {
        for (var c = 0u; c < u32(size); c++) {
            // Each base counts from the block's corner in its quad's samples (wrapping where the
            // corner lies before that quad: the sample's own index is what the sum comes to).
            let at = base[u32(far[c].x) + 2u * u32(far[r].y)];
            let v = select(heights[at + r * N + c], overlay[at + r * N + c], which == 1u);
            z[4u * r + c] = select(MISSING, v, at != NO_SLOT);
        }
    }
    return z;
}

// The central difference between the samples lo and hi either side of h, metres per sample:
// one-sided beside a sample without data or not current, 0 with neither.
fn central_difference(lo: f32, h: f32, hi: f32) -> f32 {
    let lo_ok = lo > NODATA_BELOW;
    let hi_ok = hi > NODATA_BELOW;
    let span = f32(u32(lo_ok) + u32(hi_ok));
    return select(0.0, (select(h, hi, hi_ok) - select(h, lo, lo_ok)) / max(span, 1.0), span > 0.0);
}

fn pixel_data(q: Quad, coords: vec2<f32>) -> Pixel {
    var out: Pixel;
    let x = held_coords(coords);
    let cell = data_cell(x);
    let f = x - vec2<f32>(cell);
    out.height = q.params.z;
    out.valid = 0.0;
    out.gradient = vec2<f32>(0.0);
    out.dh = 0.0;
    out.dh_valid = 0.0;
    out.dh_gradient = vec2<f32>(0.0);
    if q.slots.z == NO_SLOT {
        return out;
    }
    // The 4 × 4 samples around the cell, its corners 5, 6, 9 and 10: the central differences at
    // the corners read past the quad's edge where the quad beside it is current.
    let z = block(0u, q, cell - 1, 4);
    let h = array<f32, 4>(z[5], z[6], z[9], z[10]);
    let w = array<f32, 4>((1.0 - f.x) * (1.0 - f.y), f.x * (1.0 - f.y), (1.0 - f.x) * f.y, f.x * f.y);
    let all = h[0] > NODATA_BELOW && h[1] > NODATA_BELOW && h[2] > NODATA_BELOW && h[3] > NODATA_BELOW;
    if all {
        var sum = 0.0;
        var g = vec2<f32>(0.0);
        for (var c = 0u; c < 4u; c++) {
            let m = 5u + (c & 1u) + 4u * (c / 2u);
            sum += w[c] * h[c];
            g += w[c] * vec2<f32>(central_difference(z[m - 1u], h[c], z[m + 1u]), central_difference(z[m - 4u], h[c], z[m + 4u]));
        }
        out.height = sum;
        out.valid = 1.0;
        out.gradient = g;
    } else {
        // The nearest sample: its height, flat.
        let c = u32(f.x >= 0.5) + 2u * u32(f.y >= 0.5);
        if h[c] > NODATA_BELOW {
            out.height = h[c];
            out.valid = 1.0;
        }
    }
    if frame.difference.w > 0.5 {
        let o = block(1u, q, cell, 2);
        let d = array<f32, 4>(o[0], o[1], o[4], o[5]);
        if d[0] > NODATA_BELOW && d[1] > NODATA_BELOW && d[2] > NODATA_BELOW && d[3] > NODATA_BELOW {
            out.dh = w[0] * d[0] + w[1] * d[1] + w[2] * d[2] + w[3] * d[3];
            out.dh_valid = 1.0;
            out.dh_gradient = vec2<f32>((d[1] - d[0]) * (1.0 - f.y) + (d[3] - d[2]) * f.y, (d[2] - d[0]) * (1.0 - f.x) + (d[3] - d[1]) * f.x);
        } else {
            let c = u32(f.x >= 0.5) + 2u * u32(f.y >= 0.5);
            out.dh = select(0.0, d[c], d[c] > NODATA_BELOW);
            out.dh_valid = select(0.0, 1.0, d[c] > NODATA_BELOW);
        }
    }
    return out;
}

// Whether the data k ≤ 5 levels above the quad's is held (k = 0: the quad's own).
fn held(q: Quad, k: u32) -> bool {
    if k == 0u {
        return q.slots.z != NO_SLOT;
    }
    return k <= 5u && select(q.ancestry[1].x, q.ancestry[0][min(k, 4u) - 1u], k <= 4u) != NO_SLOT;
}

// The window attribute of the data k levels above the quad's at the point of its sample
// coordinates `coords`: bilinear between the windows of the four samples of that level around it.
fn level_attribute(q: Quad, coords: vec2<f32>, k: u32, axes: vec4<f32>, code: u32) -> vec2<f32> {
    let m = (1u << k) - 1u;
    let offset = f32(N - 1u) * vec2<f32>(f32(q.ancestry[1].z & m), f32(q.ancestry[1].w & m));
    let g = clamp((coords + offset) / f32(1u << k), vec2<f32>(0.0), vec2<f32>(f32(N - 1u)));
    let cell = min(vec2<u32>(floor(g)), vec2<u32>(N - 2u));
    let f = g - vec2<f32>(cell);
    let scaled = axes * f32(1u << k);
    var sum = vec2<f32>(0.0, 0.0);
    for (var c = 0u; c < 4u; c++) {
        let w = select(1.0 - f.x, f.x, (c & 1u) == 1u) * select(1.0 - f.y, f.y, c >= 2u);
        if w > 0.0 {
            let v = level_window(q, k, cell.x + (c & 1u), cell.y + c / 2u, scaled, code);
            sum += vec2<f32>(w * v.x, select(0.0, w, v.y > 0.5));
        }
    }
    // Valid only where every window that counts is.
    return vec2<f32>(sum.x, select(0.0, 1.0, sum.y > 0.999));
}

// The window attribute `code` (curvatures, TPI, TRI, roughness) at the pixel, at `distance` from
// the camera, and 1 where its windows have data. The attribute is a function of the place and
// the camera, not of the quad or stride that draws it (TPI, TRI and roughness grow with the
// window's spacing, curvature is smoothed by it): it is taken at the level whose samples cover
// the level-of-detail threshold there (which the quads drawn there are never coarser than),
// continuous between the two levels around it, so no quad or patch boundary shows and nothing
// pops as the camera moves. Its windows step over that level's samples (the steps along i and j
// measured on the ellipsoid); its heights are the true ones, whatever the exaggeration. Data
// more than five levels up is not held: the attribute is then that level's. CPU reference:
// attributes::attribute_at of the same windows (tests/render.rs: a dome's curvature).
fn pixel_attribute(q: Quad, coords: vec2<f32>, along_i: vec3<f32>, along_j: vec3<f32>, distance: f32, code: u32) -> vec2<f32> {
    if q.slots.z == NO_SLOT {
        return vec2<f32>(0.0, 0.0);
    }
    // The steps along i and j in an orthonormal frame of the tangent plane (x along i).
    let ex = normalize(along_i);
    let axes = vec4<f32>(length(along_i), 0.0, dot(along_j, ex), length(along_j - ex * dot(along_j, ex)));
    // Levels up to the one whose sample spans the threshold here.
    let up = clamp(log2(max(distance / (length(along_i) * frame.morph.x), 1.0)), 0.0, 5.0);
    // Down to the nearest level held (an ancestor whose composition is not current is not).
    var k0 = u32(min(floor(up), q.params.y));
    while k0 > 0u && !held(q, k0) {
        k0 -= 1u;
    }
    let t = select(clamp(up - f32(k0), 0.0, 1.0), 0.0, k0 + 1u > u32(min(floor(up) + 1.0, q.params.y)) || !held(q, k0 + 1u));
    var v = level_attribute(q, coords, k0, axes, code);
    if t > 0.0 {
        let w = level_attribute(q, coords, k0 + 1u, axes, code);
        v = vec2<f32>(mix(v.x, w.x, t), min(v.y, w.y));
    }
    return v;
}

// The ramp's sRGB colour at height h: below/above beyond the stops, linear between them, a step
// where two stops share a height (the upper one wins). CPU reference: Ramp::colour_at.
fn ramp_colour(h: f32) -> vec4<f32> {
    let count = u32(frame.viewport.w);
    if h < ramp[0].value.x {
        return frame.below;
    }
    if h > ramp[count - 1u].value.x {
        return frame.above;
    }
    var lo = 0u;
    var hi = count;
    loop {
        if lo >= hi {
            break;
        }
        let mid = (lo + hi) / 2u;
        if ramp[mid].value.x <= h {
            lo = mid + 1u;
        } else {
            hi = mid;
        }
    }
    let k = max(lo, 1u) - 1u;
    if k + 1u >= count {
        return ramp[count - 1u].colour;
    }
    let a = ramp[k];
    let b = ramp[k + 1u];
    var w = 0.0;
    if b.value.x > a.value.x {
        w = (h - a.value.x) / (b.value.x - a.value.x);
    }
    return a.colour + (b.colour - a.colour) * w;
}

// The bilinear height of the quad's level at sample coordinates c (inside the quad or around it:
// block) and its derivatives along i and j (metres, metres per sample); w 1 where the cell's
// four samples have data.
fn cell_height(q: Quad, c: vec2<f32>) -> vec4<f32> {
    let x = held_coords(c);
    let cell = data_cell(x);
    let f = x - vec2<f32>(cell);
    let z = block(0u, q, cell, 2);
    let h00 = z[0];
    let h10 = z[1];
    let h01 = z[4];
    let h11 = z[5];
    let valid = min(min(h00, h10), min(h01, h11)) > NODATA_BELOW;
    let h = mix(mix(h00, h10, f.x), mix(h01, h11, f.x), f.y);
    let di = mix(h10 - h00, h11 - h01, f.y);
    let dj = mix(h01 - h00, h11 - h10, f.x);
    return vec4<f32>(h, di, dj, select(0.0, 1.0, valid));
}

// The ellipsoid at sample coordinates c: its point (relative to A′, at h₀) bilinear between the
// four samples' points around it, the tangents along the sample axes (metres per sample) and
// the unit normal, from the samples themselves rather than from the vertices' values, which a
// large triangle interpolates linearly across a curved, non-linearly projected surface: so that
// a pixel's normal, slope and light are the data's whatever mesh drew it.
struct GroundFrame {
    point: vec3<f32>,
    along_i: vec3<f32>,
    along_j: vec3<f32>,
    up: vec3<f32>,
}

// The cell of sample coordinates c: the sample at or below it, inside the quad.
fn cell_of(c: vec2<f32>) -> vec2<u32> {
    let x = clamp(c, vec2<f32>(0.0), vec2<f32>(f32(N - 1u)));
    return min(vec2<u32>(floor(x)), vec2<u32>(N - 2u));
}

// A cell's four ellipsoid points (surface_point): what every frame inside it is bilinear
// between, read once where a pixel's steps stay in the cell.
struct GroundCell {
    cell: vec2<u32>,
    p00: vec3<f32>,
    p10: vec3<f32>,
    p01: vec3<f32>,
    p11: vec3<f32>,
}

fn ground_cell(q: Quad, cell: vec2<u32>) -> GroundCell {
    return GroundCell(
        cell,
        surface_point(q, cell.x, cell.y),
        surface_point(q, cell.x + 1u, cell.y),
        surface_point(q, cell.x, cell.y + 1u),
        surface_point(q, cell.x + 1u, cell.y + 1u),
    );
}

// The cell of c: `known` where c lies in it, else read.
fn cell_at(q: Quad, known: GroundCell, c: vec2<f32>) -> GroundCell {
    let cell = cell_of(c);
    if all(cell == known.cell) {
        return known;
    }
    return ground_cell(q, cell);
}

// The frame at c, from cell g: bilinear inside it, and carried on from the quad's edge cell g
// where c lies past the quad (a pixel reading its neighbour's data: the ellipsoid's frame turns
// by a sample's angle over a sample, which the extrapolation follows to first order).
fn frame_in(q: Quad, g: GroundCell, c: vec2<f32>) -> GroundFrame {
    let f = held_coords(c) - vec2<f32>(g.cell);
    let along_i = mix(g.p10 - g.p00, g.p11 - g.p01, f.y);
    let along_j = mix(g.p01 - g.p00, g.p11 - g.p10, f.x);
    let n = normalize(cross(along_i, along_j));
    let outward = select(-n, n, dot(n, q.normals[0].xyz + q.normals[3].xyz) >= 0.0);
    return GroundFrame(mix(mix(g.p00, g.p10, f.x), mix(g.p01, g.p11, f.x), f.y), along_i, along_j, outward);
}

// Where the mesh's point a pixel's ray met stands over the ellipsoid: the sample coordinates of
// the ellipsoid's point under it (`coords`) and its height above that point (`height`, metres,
// exaggerated), with the cell there. Neither is what the vertices' values interpolate to across
// a large triangle: its chord sags below the ellipsoid's curve between its vertices by L²/8R
// (2 km across a 170 km cell of the Moon seen whole), and the projection's coordinates are not
// linear along the chord, so the point under the chord lies beside the interpolated coordinates
// (a third of a sample across a stride-32 cell of a face-sized quad). Two steps of a fixed-point
// iteration: the horizontal offset from the ellipsoid's point at the coordinates, taken back to
// coordinates through the tangents (`to_coords`, the inverse of the tangents' basis on the
// tangent plane).
struct Under {
    coords: vec2<f32>,
    height: f32,
    cell: GroundCell,
}

fn under_mesh(q: Quad, in: VertexOut, up: vec3<f32>, to_coords: mat2x3<f32>) -> Under {
    var c = in.coords;
    var g = ground_cell(q, cell_of(c));
    var off = in.rel - (q.anchor.xyz + frame_in(q, g, c).point);
    for (var k = 0u; k < 2u; k++) {
        let across = off - up * dot(off, up);
        c = clamp(c + across * to_coords, vec2<f32>(0.0), vec2<f32>(f32(N - 1u)));
        g = cell_at(q, g, c);
        off = in.rel - (q.anchor.xyz + frame_in(q, g, c).point);
    }
    return Under(c, dot(off, up) + q.anchor.w, g);
}

// The pixel's ray in the quad's terms: metres of height per metre along it (climb), sample
// coordinates per metre along it (rate: its horizontal part in the tangents' basis), and the
// rows of the tangents' inverse on the tangent plane (a horizontal offset · to_coords is its
// offset in sample coordinates); not ok where the tangents are degenerate.
struct Ray {
    climb: f32,
    rate: vec2<f32>,
    to_coords: mat2x3<f32>,
    ok: bool,
}

fn ray_in_quad(in: VertexOut, along_i: vec3<f32>, along_j: vec3<f32>, normal: vec3<f32>) -> Ray {
    let up = normalize(normal);
    let ray = normalize(in.rel);
    let climb = dot(ray, up);
    let across = ray - up * climb;
    let ii = dot(along_i, along_i);
    let ij = dot(along_i, along_j);
    let jj = dot(along_j, along_j);
    let det = ii * jj - ij * ij;
    if det <= 0.0 {
        return Ray(climb, vec2<f32>(0.0), mat2x3<f32>(vec3<f32>(0.0), vec3<f32>(0.0)), false);
    }
    let to_coords = mat2x3<f32>((along_i * jj - along_j * ij) / det, (along_j * ii - along_i * ij) / det);
    return Ray(climb, across * to_coords, to_coords, true);
}

// The body's radius of curvature across a quad, metres: its corners' distance over their
// normals' (the sphere's; the ellipsoid's differ by its flattening, a third of a per cent for the
// Earth, which the term it serves does not feel). Infinite where the normals are too close to
// tell apart in f32 (quads under a few hundred metres, where no ray runs far enough to bend).
fn radius_of(q: Quad) -> f32 {
    let turn = length(q.normals[3].xyz - q.normals[0].xyz);
    if turn < 1e-5 {
        return 3.4e38;
    }
    return length(q.corners[3].xyz - q.corners[0].xyz) / turn;
}

// Where a pixel reads the data (on_data): its sample coordinates, and the ray there in sample
// coordinates per metre (rate) and metres of height per metre (climb), where it `moved` off the
// mesh's point.
struct Follow {
    coords: vec2<f32>,
    rate: vec2<f32>,
    climb: f32,
    moved: bool,
}

// Where the pixel's ray meets the data's surface, in the quad's sample coordinates. The mesh
// stands within its error δ of the data, so where the ray meets the mesh is not the point of the
// data the eye sees through the pixel, but δ·tan θ beside it (θ the ray's angle from the
// vertical). Newton's method along the ray, from the mesh's point, on the data's bilinear
// surface: the ray's height is the mesh's height there plus its climb, the data's height is read
// where the ray is. Each step moves at most a few strides (a far root is a ridge in front, which
// the mesh, within δ, already shows). Skirts, cells without data and rays along the surface keep
// the point under the mesh's (under_mesh), never the vertices' interpolated coordinates. Checked
// against f64 rather than a twin: tests/render.rs places the point each pixel read on the
// ellipsoid and measures its distance from the pixel's ray, and compares the height read with
// the CPU composition there.
fn on_data(q: Quad, in: VertexOut, ray: Ray, under: Under) -> Follow {
    var out = Follow(under.coords, vec2<f32>(0.0), 0.0, false);
    let slot = q.slots.z;
    if (in.kind & 1u) != 0u || slot == NO_SLOT || !ray.ok {
        return out;
    }
    let rate = ray.rate;
    let climb = ray.climb;
    let e = frame.viewport.z;
    let start = under.coords;
    let mesh_h = under.height;
    let reach = 2.0 * f32(max(in.kind >> 1u, 1u)) + 1.0;
    let most = reach / max(length(rate), 1e-12);
    // The body falls away under a straight ray: over a horizontal run x its height above the
    // ellipsoid grows by x²/2R, which a face-sized quad's grazing rays feel (30 m over 10 km of
    // the Moon, a tenth of a sample where the ground slopes by a tenth).
    let bend = 0.5 * (1.0 - climb * climb) / radius_of(q);
    var t = 0.0;
    for (var k = 0u; k < PARALLAX_STEPS; k++) {
        let d = cell_height(q, start + rate * t);
        if d.w < 0.5 {
            return out;
        }
        let miss = e * d.x - (mesh_h + climb * t + bend * t * t);
        let slope = e * dot(d.yz, rate) - climb - 2.0 * bend * t;
        if abs(slope) < 1e-4 {
            return out;
        }
        t = clamp(t - miss / slope, -most, most);
    }
    out.coords = held_coords(start + rate * t);
    out.rate = rate;
    out.climb = climb;
    out.moved = true;
    return out;
}

// The pixel's colour, sRGB-encoded 0–1, from the data at the pixel. fw_iso, fw_dh and fw_brush:
// the pixel's footprint in height and dh isoline intervals and in metres from the brush's centre.
fn shade(in: VertexOut, q: Quad, px: Pixel, coords: vec2<f32>, g: GroundFrame, fw_iso: f32, fw_dh: f32, fw_brush: f32) -> vec4<f32> {
    if px.valid < 0.5 {
        return frame.nodata;
    }
    // The surface normal of the data at the pixel, with the exaggeration drawn, on the
    // ellipsoid's own tangents there (g: not the vertices' interpolated ones).
    let up = g.up;
    let e = frame.viewport.z;
    var n = normalize(cross(g.along_i + up * (e * px.gradient.x), g.along_j + up * (e * px.gradient.y)));
    if dot(n, up) < 0.0 {
        n = -n;
    }
    // The ramp over the height, or over an attribute of the data: slope, aspect and hillshade
    // from the normal, the others from the samples' windows.
    var base = frame.nodata;
    let code = coloured_attribute();
    if code == NO_SLOT {
        base = ramp_colour(px.height);
    } else if code >= ATTRIBUTE_CURVATURE {
        let a = pixel_attribute(q, coords, g.along_i, g.along_j, length(in.rel), code);
        if a.y > 0.5 {
            base = ramp_colour(a.x);
        }
    } else {
        let sa = slope_aspect(n, up, e);
        var value = select(sa.x, sa.y, code == ATTRIBUTE_ASPECT);
        if code == ATTRIBUTE_HILLSHADE {
            value = hillshade_value(radians(sa.x), sa.y, HILLSHADE_LIGHT);
        }
        base = ramp_colour(value);
    }
    var colour = srgb_to_linear(base.rgb);
    if frame.difference.w > 0.5 {
        // dh draped over the ramp by the layer's opacity; where A or B has no data, the ramp in grey.
        var over = vec3<f32>(dot(colour, vec3<f32>(0.2126, 0.7152, 0.0722)));
        if px.dh_valid > 0.5 {
            over = srgb_to_linear(diverging_colour(px.dh / frame.difference.x));
        }
        colour = mix(colour, over, frame.difference.z);
    }
    if frame.sun.w > 0.5 {
        colour = colour * hillshade(n, up, frame.sun.x, frame.sun.y, frame.sun.z);
    }
    if frame.iso.w > 0.5 {
        let x = (px.height - frame.iso.y) / frame.iso.x;
        let k = round(x);
        let every = frame.iso.z;
        let major = every > 0.5 && abs(k - every * round(k / every)) < 0.5;
        let width = select(frame.iso_width.x, frame.iso_width.y, major);
        let spacing = select(1.0, every, major);
        let coverage = isoline_coverage(x, fw_iso, width, frame.iso_width.z, spacing) * frame.iso_colour.a;
        colour = mix(colour, srgb_to_linear(frame.iso_colour.rgb), coverage);
    }
    if frame.brush.w > 0.0 {
        // The brush's rim: where the chord from its centre is its radius, 1.5 px wide, white.
        let d = length(in.rel - frame.brush.xyz);
        let coverage = clamp(1.5 - abs(d - frame.brush.w) / max(fw_brush, 1e-6), 0.0, 1.0);
        colour = mix(colour, vec3<f32>(1.0), coverage);
    }
    if frame.difference.w > 0.5 && frame.difference.y > 0.0 && px.dh_valid > 0.5 {
        // Isolines of dh at ±k·interval, k ≥ 1, dark grey (zero is the map's white already; its
        // line would trace the noise of two equal surfaces).
        let x = px.dh / frame.difference.y;
        let zero = abs(round(x)) < 0.5;
        let coverage = select(isoline_coverage(x, fw_dh, frame.iso_width.x, frame.iso_width.z, 1.0), 0.0, zero);
        colour = mix(colour, vec3<f32>(0.02), coverage);
    }
    return vec4<f32>(linear_to_srgb(colour), 1.0);
}

// The pixel's data and colour.
struct Shaded {
    colour: vec4<f32>,
    px: Pixel,
    // The sample coordinates it read.
    coords: vec2<f32>,
}

// `follow`: read the data where the pixel's ray meets them (on_data), or where it meets the mesh
// (the vertices' own samples, for the points the vertex tests draw).
fn shade_pixel(in: VertexOut, follow: bool) -> Shaded {
    // The mesh's point's move across the pixel, taken before any branch and from the varyings
    // alone: a derivative of anything read from storage (the data, or the ellipsoid's points)
    // differences reads across a 2 × 2 block, whose helper lanes made isolines fade on lavapipe.
    let rel_dx = dpdx(in.rel);
    let rel_dy = dpdy(in.rel);
    let q = quads[in.quad];
    // Where that point stands over the ellipsoid (under_mesh), and the ray in the ellipsoid's
    // own tangents there.
    let near = ray_in_quad(in, in.along_i, in.along_j, in.up);
    let under = under_mesh(q, in, normalize(in.up), near.to_coords);
    let g = frame_in(q, under.cell, under.coords);
    let ray = ray_in_quad(in, g.along_i, g.along_j, g.up);
    // The move in sample coordinates (its horizontal part through the tangents' inverse) and in
    // height (its vertical part).
    let mesh_dx = rel_dx * ray.to_coords;
    let mesh_dy = rel_dy * ray.to_coords;
    let mesh_hx = dot(rel_dx, g.up);
    let mesh_hy = dot(rel_dy, g.up);
    var f = Follow(in.coords, vec2<f32>(0.0), 0.0, false);
    if follow {
        f = on_data(q, in, ray, under);
    }
    let coords = f.coords;
    let px = pixel_data(q, coords);
    // The coordinates' change across the pixel where the ray meets the data, so that an
    // isoline's footprint does not depend on the mesh: moving across the pixel, the mesh's point
    // moves by (dc, dH) and the data's by dc + rate·dt, where e·∇h·(dc + rate·dt) = dH + climb·dt.
    var dx = mesh_dx;
    var dy = mesh_dy;
    let e = frame.viewport.z;
    let s = e * dot(px.gradient, f.rate) - f.climb;
    if f.moved && abs(s) > 1e-4 {
        dx = mesh_dx + f.rate * ((mesh_hx - e * dot(px.gradient, mesh_dx)) / s);
        dy = mesh_dy + f.rate * ((mesh_hy - e * dot(px.gradient, mesh_dy)) / s);
    }
    // The length of the screen gradient, not fwidth's sum of its two parts: a line is then as
    // wide in pixels whichever way it runs (fwidth's would be √2 wider on a diagonal).
    let fw_iso = length(vec2<f32>(dot(px.gradient, dx), dot(px.gradient, dy))) / frame.iso.x;
    let fw_dh = length(vec2<f32>(dot(px.dh_gradient, dx), dot(px.dh_gradient, dy))) / max(frame.difference.y, 1e-6);
    let fw_brush = fwidth(length(in.rel - frame.brush.xyz));
    // The ellipsoid's frame where the data were read, from the start's cell where it lies there.
    let at = frame_in(q, cell_at(q, under.cell, coords), coords);
    return Shaded(shade(in, q, px, coords, at, fw_iso, fw_dh, fw_brush), px, coords);
}

@fragment
fn fs_main(in: VertexOut) -> @location(0) vec4<f32> {
    return shade_pixel(in, true).colour;
}

// The probe's unit of sample coordinates: 1/256 of a sample (gpu::targets::PROBE_SUBSAMPLES).
const PROBE_SUBSAMPLES: f32 = 256.0;

struct ProbeOut {
    @location(0) colour: vec4<f32>,
    // Camera-relative position (metres) and the height the pixel read (metres).
    @location(1) surface: vec4<f32>,
    // Quad index + 1, the sample coordinates the pixel read (i, j) in 1/256 of a sample from a
    // quad's width west and south of the quad (a pixel may read past the quad's edge:
    // held_coords); w: bit 0 the pixel has data, bit 1 a skirt, the patch's stride from bit 2 on.
    @location(2) id: vec4<u32>,
}

// The test and benchmark variant: the colour and, per pixel, where the surface is and what it read.
@fragment
fn fs_probe(in: VertexOut) -> ProbeOut {
    return probe(in, true);
}

// The vertex tests' variant: each vertex as a point, reading the data at its own sample.
@fragment
fn fs_points(in: VertexOut) -> ProbeOut {
    return probe(in, false);
}

fn probe(in: VertexOut, follow: bool) -> ProbeOut {
    let s = shade_pixel(in, follow);
    var out: ProbeOut;
    out.colour = s.colour;
    out.surface = vec4<f32>(in.rel, s.px.height);
    let at = vec2<u32>(round((held_coords(s.coords) + f32(N - 1u)) * PROBE_SUBSAMPLES));
    out.id = vec4<u32>(in.quad + 1u, at.x, at.y, select(0u, 1u, s.px.valid > 0.5) + 2u * in.kind);
    return out;
}
