// One brush stroke on an edit layer's tiles: one invocation per sample of a 257² tile, one
// workgroup layer (z) per tile. The GPU twin of terrafuse::edit::kernel::apply_to_tile (keep in
// sync): each sample within the radius of a dab is folded through the stroke's dabs in order.
// Differences from the CPU reference, which the tolerance of the test covers: the fold is in f32
// (the CPU's in f64), and the sample's position is interpolated between exact points every 1 to 8
// samples (the CPU's is exact), relative to the tile's origin O. Smooth reads the terrain H on its
// ring through the tile's grid extended by a margin from its neighbours (the CPU, through the
// geodetic position of each ring point): each ring point's offset in the tangent plane is turned
// into grid steps by the local Jacobian of the sample positions.
//!include shared/noise.wgsl
//!include generated/codes.wgsl

const N: u32 = 257u;
// No diagonal of the face crosses the tile (Tile.diag).
const NO_DIAGONAL: i32 = -2147483647;
// No terrain below (the `below` buffer): samples there are left as they are.
const NODATA: f32 = -1.0e37;

// One tile (StrokeTile in src/gpu/brush.rs; keep in sync).
struct Tile {
    // The samples a dab can reach: i0, i1, j0, j1 (inclusive; i0 > i1: none).
    window: vec4<u32>,
    // First dab (in `dabs`), dab count, tool (0 raise, 1 lower, 2 noise, 3 restore, 4 flatten,
    // 5 ramp, 6 smooth), falloff (0 smooth, 1 linear, 2 spherical, 3 tip).
    head: vec4<u32>,
    // Noise: the lattice cell of O at the stroke's wavelength (xyz) and its seed (w).
    cell: vec4<u32>,
    // Noise: the fraction of O / λ (xyz) and λ (w, metres).
    frac: vec4<f32>,
    // Radius (metres), strength, flatten height (metres), unused.
    params: vec4<f32>,
    // Ramp: its first point relative to O (xyz) and the height there (w).
    ramp_a: vec4<f32>,
    // Ramp: its last point relative to O and the height there.
    ramp_b: vec4<f32>,
    // The tile's exact points: the first (in `lattice`), the step between them in samples (1,
    // 2, 4 or 8), points per edge, unused.
    lat: vec4<u32>,
    // Where the face's diagonals cross the tile, in samples: a point (i, j) of the tile is on
    // the main diagonal where i − j = x, on the other where i + j = y (NO_DIAGONAL: nowhere).
    diag: vec4<i32>,
    // Smooth: O in ECEF (xyz, metres) and a²/b² (w), for the ellipsoid normal.
    origin: vec4<f32>,
    // Smooth: the first value of the tile's extended H grid (in `ext`), its edge in samples, its
    // margin in samples; the ring's radius in metres (bitcast).
    ext_grid: vec4<u32>,
}

@group(0) @binding(0) var<storage, read> tiles: array<Tile>;
// Per tile, L² exact sample points relative to its O, metres.
@group(0) @binding(1) var<storage, read> lattice: array<vec4<f32>>;
// Per tile, the stroke's dab centres relative to its O, metres.
@group(0) @binding(2) var<storage, read> dabs: array<vec4<f32>>;
// Per tile (flatten and ramp), the terrain below the edit layer B, metres (NODATA: none).
@group(0) @binding(3) var<storage, read> below: array<f32>;
// Per tile, δ: read before the stroke, written after it.
@group(0) @binding(4) var<storage, read_write> delta: array<f32>;
// Smooth: per tile, H over its grid and a margin around it (NODATA: none).
@group(0) @binding(5) var<storage, read> ext: array<f32>;

// H at a fractional position of a tile's extended grid (bilinear; NODATA where a corner has none).
fn ext_height(tile: Tile, u: f32, v: f32) -> f32 {
    let e = tile.ext_grid.y;
    let uc = clamp(u, 0.0, f32(e - 1u) - 0.001);
    let vc = clamp(v, 0.0, f32(e - 1u) - 0.001);
    let a = u32(floor(uc));
    let b = u32(floor(vc));
    let s = uc - f32(a);
    let t = vc - f32(b);
    let base = tile.ext_grid.x;
    let h00 = ext[base + b * e + a];
    let h10 = ext[base + b * e + a + 1u];
    let h01 = ext[base + (b + 1u) * e + a];
    let h11 = ext[base + (b + 1u) * e + a + 1u];
    if min(min(h00, h10), min(h01, h11)) <= NODATA {
        return NODATA;
    }
    return mix(mix(h00, h10, s), mix(h01, h11, s), t);
}

// Smooth: the mean of H over 8 points on the ring around sample (i, j) at `p` (NODATA: none has
// terrain). Ring offsets in the ellipsoid's tangent plane become grid steps through the local
// Jacobian of the sample positions (least squares: the plane's two axes onto the grid's).
fn ring_mean(tile: Tile, i: u32, j: u32, p: vec3<f32>) -> f32 {
    let i0 = select(i - 1u, i, i == 0u);
    let i1 = min(i + 1u, N - 1u);
    let j0 = select(j - 1u, j, j == 0u);
    let j1 = min(j + 1u, N - 1u);
    let dpi = (sample_local(tile, i1, j) - sample_local(tile, i0, j)) / f32(i1 - i0);
    let dpj = (sample_local(tile, i, j1) - sample_local(tile, i, j0)) / f32(j1 - j0);
    let q = tile.origin.xyz + p;
    let n = normalize(vec3<f32>(q.x, q.y, q.z * tile.origin.w));
    var east = cross(vec3<f32>(0.0, 0.0, 1.0), n);
    if length(east) < 1e-6 {
        east = vec3<f32>(0.0, 1.0, 0.0);
    }
    east = normalize(east);
    let north = cross(n, east);
    let a11 = dot(dpi, dpi);
    let a12 = dot(dpi, dpj);
    let a22 = dot(dpj, dpj);
    let det = a11 * a22 - a12 * a12;
    let ring = bitcast<f32>(tile.ext_grid.w);
    let margin = f32(tile.ext_grid.z);
    var sum = 0.0;
    var count = 0.0;
    for (var k = 0u; k < 8u; k++) {
        let theta = 6.283185307179586 * f32(k) / 8.0;
        let o = ring * (cos(theta) * east + sin(theta) * north);
        let b1 = dot(dpi, o);
        let b2 = dot(dpj, o);
        let di = (a22 * b1 - a12 * b2) / det;
        let dj = (a11 * b2 - a12 * b1) / det;
        let h = ext_height(tile, margin + f32(i) + di, margin + f32(j) + dj);
        if h > NODATA {
            sum += h;
            count += 1.0;
        }
    }
    if count == 0.0 {
        return NODATA;
    }
    return sum / count;
}

// edit::stroke::Falloff::weight.
fn falloff_weight(falloff: u32, t: f32) -> f32 {
    if t >= 1.0 {
        return 0.0;
    }
    let u = max(t, 0.0);
    switch falloff {
        case FALLOFF_SMOOTH: { return 1.0 - u * u * (3.0 - 2.0 * u); }
        case FALLOFF_LINEAR: { return 1.0 - u; }
        case FALLOFF_SPHERICAL: { return sqrt(1.0 - u * u); }
        default: { return (1.0 - u) * (1.0 - u) * (1.0 - u); }
    }
}

// The sample's point relative to O, interpolated between the exact points around it: bilinear,
// except in a cell a diagonal of the face runs through, where QSC's mapping has a kink (its
// sectors meet there): there linear in the cell's triangle on the sample's side of it.
fn sample_local(tile: Tile, i: u32, j: u32) -> vec3<f32> {
    let step = tile.lat.y;
    let m = tile.lat.z;
    let a = min(i / step, m - 2u);
    let b = min(j / step, m - 2u);
    let s = f32(i - a * step) / f32(step);
    let t = f32(j - b * step) / f32(step);
    let base = tile.lat.x;
    let p00 = lattice[base + b * m + a].xyz;
    let p10 = lattice[base + b * m + a + 1u].xyz;
    let p01 = lattice[base + (b + 1u) * m + a].xyz;
    let p11 = lattice[base + (b + 1u) * m + a + 1u].xyz;
    let ci = i32(a * step);
    let cj = i32(b * step);
    if ci - cj == tile.diag.x {
        // The main diagonal runs from p00 to p11.
        if s >= t {
            return p00 + s * (p10 - p00) + t * (p11 - p10);
        }
        return p00 + t * (p01 - p00) + s * (p11 - p01);
    }
    if ci + cj + i32(step) == tile.diag.y {
        // The other runs from p10 to p01.
        if s + t <= 1.0 {
            return p00 + s * (p10 - p00) + t * (p01 - p00);
        }
        return p11 + (1.0 - s) * (p01 - p11) + (1.0 - t) * (p10 - p11);
    }
    return mix(mix(p00, p10, s), mix(p01, p11, s), t);
}

@compute @workgroup_size(16, 16, 1)
fn apply_stroke(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let j = id.y;
    let tile = tiles[id.z];
    if i < tile.window.x || i > tile.window.y || j < tile.window.z || j > tile.window.w {
        return;
    }
    let p = sample_local(tile, i, j);
    let k = id.z * N * N + j * N + i;
    let before = delta[k];
    let r = tile.params.x;
    let strength = tile.params.y;
    let tool = tile.head.z;
    // Flatten, ramp and smooth (the codes from TOOL_FLATTEN up, src/gpu/codes.rs): the δ that
    // brings the terrain to the target (T − B).
    var goal = 0.0;
    if tool >= TOOL_FLATTEN {
        let b = below[k];
        if b <= NODATA {
            return;
        }
        var aim = tile.params.z;
        if tool == TOOL_SMOOTH {
            // Only where a dab reaches (the ring costs eight reads).
            var reached = false;
            for (var d = 0u; d < tile.head.y; d++) {
                reached = reached || length(p - dabs[tile.head.x + d].xyz) < tile.params.x;
            }
            if !reached {
                return;
            }
            aim = ring_mean(tile, i, j, p);
            if aim <= NODATA {
                return;
            }
        }
        if tool == TOOL_RAMP {
            let ab = tile.ramp_b.xyz - tile.ramp_a.xyz;
            let t = clamp(dot(p - tile.ramp_a.xyz, ab) / dot(ab, ab), 0.0, 1.0);
            aim = tile.ramp_a.w + (tile.ramp_b.w - tile.ramp_a.w) * t;
        }
        goal = aim - b;
    }
    var value = before;
    var touched = false;
    for (var d = 0u; d < tile.head.y; d++) {
        let dist = length(p - dabs[tile.head.x + d].xyz);
        if dist >= r {
            continue;
        }
        touched = true;
        let s = strength * falloff_weight(tile.head.w, dist / r);
        switch tool {
            case TOOL_RAISE: { value = value + s; }
            case TOOL_LOWER: { value = value - s; }
            case TOOL_NOISE: { value = value + s * noise_octave(tile.cell.xyz, tile.frac.xyz, p, tile.frac.w, tile.cell.w); }
            case TOOL_RESTORE: { value = value * (1.0 - s); }
            default: { value = value + s * (goal - value); }
        }
    }
    if touched {
        delta[k] = value;
    }
}
