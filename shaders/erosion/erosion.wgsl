// One erosion step on the GPU, three passes, gather-only, written to read like the CPU
// reference in src/erosion/sim.rs (see its notes for the model):
//
// 1. `outflow`: per cell, each pipe's flux from the state at the step's start, scaled so that a
//    cell never sends more water than it holds; the whole units of water, sediment and sliding
//    soil it sends through each pipe.
// 2. `update`: per cell, what it sent subtracted and what its neighbours sent it added (integers:
//    one cell loses exactly what the other gains); velocity, capacity, dissolving or deposition,
//    evaporation, rain, the ceiling of units; then the workgroup's budget sums (fixed tree) and
//    its bound on the next step.
// 3. `reduce`: one workgroup sums the workgroups' partials in a fixed order into the run's 64-bit
//    totals, logs the step taken and sets the next step from the CFL bound.
//
// Volumes are i32 units; every sum stays within i32 because a cell holds at most MAX_UNITS = 2²⁷
// of each and a neighbour sends at most what it holds. No float atomics, no integer atomics: the
// same inputs give the same result bit for bit on one device.

//!include shared/hash.wgsl

struct Params {
    width: u32,
    height: u32,
    n: u32,
    groups_x: u32,
    seed: u32,
    open_border: u32,
    groups: u32,
    // Cells per chunk of the per-cell arrays: 2^chunk_shift (a shift and a mask per access,
    // not a division).
    chunk_shift: u32,
    unit_m3: f32,
    g: f32,
    friction: f32,
    tan_talus: f32,
    thermal: f32,
    hardness: f32,
    capacity: f32,
    capacity_depth_m: f32,
    min_slope: f32,
    dissolve: f32,
    deposit: f32,
    evaporation: f32,
    rain_m_s: f32,
    cfl: f32,
    dt_asked: f32,
    weight_sum: f32,
    weights: array<vec4<f32>, 2>,
}

// The run's control block: the step to take now, the counters and the 64-bit totals (lo, hi).
struct Control {
    dt: f32,
    step: u32,
    batch_step: u32,
    _pad: u32,
    // rain in, evaporated, water out, soil out
    totals: array<vec2<u32>, 4>,
    bound: f32,
    max_speed: f32,
    max_depth: f32,
    _pad2: f32,
}

// A workgroup's sums: each budget term as (Σ low 16 bits, Σ high bits), its bound and maxima.
struct Partial {
    sums: array<u32, 8>,
    bound: f32,
    max_speed: f32,
    max_depth: f32,
    _pad: f32,
}

const MAX_UNITS: i32 = 134217728;
// The depth below which the speed estimate is desingularised (src/erosion/sim.rs).
const DESINGULARISE_M: f32 = 1e-3;
const BIG: f32 = 3.0e38;
const WG: u32 = 256u;
// Whether the per-cell arrays are bound in chunks (a pipeline constant: the pipelines for grids
// within one binding index the first chunk directly, without the chunk's switch).
override chunked: bool = false;

@group(0) @binding(0) var<storage, read> P: Params;
// Each per-cell array is bound as four chunks of 2^P.chunk_shift cells (so that a grid larger than one
// binding may hold still runs: the device's binding limit applies to a chunk); a grid within one
// binding uses the first chunk, the others are stand-ins.
// Per cell, two: terrain height at the start less the region's offset, area, dx, dy (metres,
// m²); then rain mask, erosion mask, hardness (0: the run's), sink (1) or not (0).
@group(0) @binding(1) var<storage, read> cell0: array<vec4<f32>>;
@group(0) @binding(2) var<storage, read> cell1: array<vec4<f32>>;
@group(0) @binding(3) var<storage, read> cell2: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> cell3: array<vec4<f32>>;
// Per cell: water, sediment, soil (the terrain's change), units.
@group(0) @binding(5) var<storage, read_write> state0: array<vec4<i32>>;
@group(0) @binding(6) var<storage, read_write> state1: array<vec4<i32>>;
@group(0) @binding(7) var<storage, read_write> state2: array<vec4<i32>>;
@group(0) @binding(8) var<storage, read_write> state3: array<vec4<i32>>;
// Per cell, two: the flux through pipes 0–3 and 4–7, m³/s.
@group(0) @binding(9) var<storage, read_write> flux0: array<vec4<f32>>;
@group(0) @binding(10) var<storage, read_write> flux1: array<vec4<f32>>;
@group(0) @binding(11) var<storage, read_write> flux2: array<vec4<f32>>;
@group(0) @binding(12) var<storage, read_write> flux3: array<vec4<f32>>;
// Per cell, two each (pipes 0–3, 4–7): the water, sediment and soil it sends, units.
@group(0) @binding(13) var<storage, read_write> sent_water0: array<vec4<i32>>;
@group(0) @binding(14) var<storage, read_write> sent_water1: array<vec4<i32>>;
@group(0) @binding(15) var<storage, read_write> sent_water2: array<vec4<i32>>;
@group(0) @binding(16) var<storage, read_write> sent_water3: array<vec4<i32>>;
@group(0) @binding(17) var<storage, read_write> sent_sediment0: array<vec4<i32>>;
@group(0) @binding(18) var<storage, read_write> sent_sediment1: array<vec4<i32>>;
@group(0) @binding(19) var<storage, read_write> sent_sediment2: array<vec4<i32>>;
@group(0) @binding(20) var<storage, read_write> sent_sediment3: array<vec4<i32>>;
@group(0) @binding(21) var<storage, read_write> sent_soil0: array<vec4<i32>>;
@group(0) @binding(22) var<storage, read_write> sent_soil1: array<vec4<i32>>;
@group(0) @binding(23) var<storage, read_write> sent_soil2: array<vec4<i32>>;
@group(0) @binding(24) var<storage, read_write> sent_soil3: array<vec4<i32>>;
@group(0) @binding(25) var<storage, read_write> partials: array<Partial>;
@group(0) @binding(26) var<storage, read_write> control: Control;
// The step taken at each step since the last read-back, seconds.
@group(0) @binding(27) var<storage, read_write> dt_log: array<f32>;
// Per cell, sin α of the terrain's slope at the step's start (the outflow pass writes it: the
// update pass changes the neighbours' terrain as it reads).
@group(0) @binding(28) var<storage, read_write> slope: array<f32>;

// The chunked arrays' accessors (cell `i` lives in chunk i >> P.chunk_shift).
fn cell_at(i: u32, k: u32) -> vec4<f32> {
    if !chunked {
        return cell0[2u * i + k];
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + k;
    switch i >> P.chunk_shift {
        case 0u: { return cell0[at]; }
        case 1u: { return cell1[at]; }
        case 2u: { return cell2[at]; }
        default: { return cell3[at]; }
    }
}

fn geo_of(i: u32) -> vec4<f32> {
    return cell_at(i, 0u);
}

fn masks_of(i: u32) -> vec4<f32> {
    return cell_at(i, 1u);
}

fn state_of(i: u32) -> vec4<i32> {
    if !chunked {
        return state0[i];
    }
    let at = i & ((1u << P.chunk_shift) - 1u);
    switch i >> P.chunk_shift {
        case 0u: { return state0[at]; }
        case 1u: { return state1[at]; }
        case 2u: { return state2[at]; }
        default: { return state3[at]; }
    }
}

fn state_set(i: u32, v: vec4<i32>) {
    if !chunked {
        state0[i] = v;
        return;
    }
    let at = i & ((1u << P.chunk_shift) - 1u);
    switch i >> P.chunk_shift {
        case 0u: { state0[at] = v; }
        case 1u: { state1[at] = v; }
        case 2u: { state2[at] = v; }
        default: { state3[at] = v; }
    }
}

fn flux_of(i: u32, half: u32) -> vec4<f32> {
    if !chunked {
        return flux0[2u * i + half];
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { return flux0[at]; }
        case 1u: { return flux1[at]; }
        case 2u: { return flux2[at]; }
        default: { return flux3[at]; }
    }
}

fn flux_set(i: u32, half: u32, v: vec4<f32>) {
    if !chunked {
        flux0[2u * i + half] = v;
        return;
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { flux0[at] = v; }
        case 1u: { flux1[at] = v; }
        case 2u: { flux2[at] = v; }
        default: { flux3[at] = v; }
    }
}

fn sent_water_of(i: u32, half: u32) -> vec4<i32> {
    if !chunked {
        return sent_water0[2u * i + half];
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { return sent_water0[at]; }
        case 1u: { return sent_water1[at]; }
        case 2u: { return sent_water2[at]; }
        default: { return sent_water3[at]; }
    }
}

fn sent_water_set(i: u32, half: u32, v: vec4<i32>) {
    if !chunked {
        sent_water0[2u * i + half] = v;
        return;
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { sent_water0[at] = v; }
        case 1u: { sent_water1[at] = v; }
        case 2u: { sent_water2[at] = v; }
        default: { sent_water3[at] = v; }
    }
}

fn sent_sediment_of(i: u32, half: u32) -> vec4<i32> {
    if !chunked {
        return sent_sediment0[2u * i + half];
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { return sent_sediment0[at]; }
        case 1u: { return sent_sediment1[at]; }
        case 2u: { return sent_sediment2[at]; }
        default: { return sent_sediment3[at]; }
    }
}

fn sent_sediment_set(i: u32, half: u32, v: vec4<i32>) {
    if !chunked {
        sent_sediment0[2u * i + half] = v;
        return;
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { sent_sediment0[at] = v; }
        case 1u: { sent_sediment1[at] = v; }
        case 2u: { sent_sediment2[at] = v; }
        default: { sent_sediment3[at] = v; }
    }
}

fn sent_soil_of(i: u32, half: u32) -> vec4<i32> {
    if !chunked {
        return sent_soil0[2u * i + half];
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { return sent_soil0[at]; }
        case 1u: { return sent_soil1[at]; }
        case 2u: { return sent_soil2[at]; }
        default: { return sent_soil3[at]; }
    }
}

fn sent_soil_set(i: u32, half: u32, v: vec4<i32>) {
    if !chunked {
        sent_soil0[2u * i + half] = v;
        return;
    }
    let at = 2u * (i & ((1u << P.chunk_shift) - 1u)) + half;
    switch i >> P.chunk_shift {
        case 0u: { sent_soil0[at] = v; }
        case 1u: { sent_soil1[at] = v; }
        case 2u: { sent_soil2[at] = v; }
        default: { sent_soil3[at] = v; }
    }
}


// The eight pipes as (dx, dy): east, west, north, south, then the diagonals; k ^ 1 is k's
// opposite.
const PIPES = array<vec2<i32>, 8>(
    vec2<i32>(1, 0), vec2<i32>(-1, 0), vec2<i32>(0, 1), vec2<i32>(0, -1),
    vec2<i32>(1, 1), vec2<i32>(-1, -1), vec2<i32>(1, -1), vec2<i32>(-1, 1),
);

// u ∈ [0, 1) for (step, cell, stream): src/erosion/dither.rs.
fn uniform(step: u32, cell: u32, stream: u32) -> f32 {
    let h = pcg(pcg(pcg(P.seed ^ (stream * 0x9e3779b9u)) ^ step) ^ cell);
    return f32(h >> 8u) / 16777216.0;
}

// ⌊x + u⌋ as whole units (x ≥ 0, held below 2³⁰ before the conversion).
fn round_units(x: f32, cell: u32, stream: u32) -> i32 {
    return i32(floor(min(x, 1.0e9) + uniform(control.step, cell, stream)));
}

fn units_floor(x: f32) -> i32 {
    return i32(floor(clamp(x, 0.0, 1.0e9)));
}

fn cell_index(wid: vec3<u32>, lid: u32) -> u32 {
    return (wid.y * P.groups_x + wid.x) * WG + lid;
}

// The neighbour through pipe k, or -1 beyond the border.
fn neighbour(i: u32, k: u32) -> i32 {
    let x = i32(i % P.width) + PIPES[k].x;
    let y = i32(i / P.width) + PIPES[k].y;
    if x < 0 || y < 0 || x >= i32(P.width) || y >= i32(P.height) {
        return -1;
    }
    return y * i32(P.width) + x;
}

fn is_sink(i: u32) -> bool {
    return masks_of(i).w > 0.5;
}

fn height_m(i: u32) -> f32 {
    return geo_of(i).x + f32(state_of(i).z) * P.unit_m3 / geo_of(i).y;
}

fn depth_m(i: u32) -> f32 {
    return f32(state_of(i).x) * P.unit_m3 / geo_of(i).y;
}

fn pipe_length_m(i: u32, k: u32) -> f32 {
    let lx = select(geo_of(i).z, 0.0, PIPES[k].x == 0);
    let ly = select(geo_of(i).w, 0.0, PIPES[k].y == 0);
    return sqrt(lx * lx + ly * ly);
}

fn weight(k: u32) -> f32 {
    return P.weights[k / 4u][k % 4u];
}

fn hardness(i: u32) -> f32 {
    let h = masks_of(i).z;
    return select(P.hardness, max(h, 1.0), h > 0.0);
}

// sin α of the terrain's slope at cell i (central differences).
fn sin_slope(i: u32) -> f32 {
    let h = height_m(i);
    var at = array<f32, 4>(h, h, h, h);
    for (var k = 0u; k < 4u; k++) {
        let nb = neighbour(i, k);
        if nb >= 0 && !is_sink(u32(nb)) {
            at[k] = height_m(u32(nb));
        }
    }
    let gx = (at[0] - at[1]) / (2.0 * geo_of(i).z);
    let gy = (at[2] - at[3]) / (2.0 * geo_of(i).w);
    let t = sqrt(gx * gx + gy * gy);
    return t / sqrt(1.0 + t * t);
}

@compute @workgroup_size(256)
fn outflow(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = cell_index(wid, lid);
    if i >= P.n {
        return;
    }
    var f = array<f32, 8>();
    var w = array<i32, 8>();
    var s = array<i32, 8>();
    var l = array<i32, 8>();
    if !is_sink(i) {
        let dt = control.dt;
        let h = height_m(i);
        let d = depth_m(i);
        let old0 = flux_of(i, 0u);
        let old1 = flux_of(i, 1u);
        let keep = 1.0 - min(P.friction * dt, 1.0);
        var total_m3 = 0.0;
        for (var k = 0u; k < 8u; k++) {
            // The neighbour's water surface (a sink: a dry cell at this cell's terrain height;
            // an open border: a dry cell continuing the slope from the opposite neighbour, never
            // above this cell); no pipe at a closed border.
            let nb = neighbour(i, k);
            var surface = h;
            if nb >= 0 {
                if !is_sink(u32(nb)) {
                    surface = height_m(u32(nb)) + depth_m(u32(nb));
                }
            } else if P.open_border == 0u {
                continue;
            } else {
                let opp = neighbour(i, k ^ 1u);
                var opposite = h;
                if opp >= 0 && !is_sink(u32(opp)) {
                    opposite = height_m(u32(opp));
                }
                surface = min(h, 2.0 * h - opposite);
            }
            let len = pipe_length_m(i, k);
            var across = 0.5 * len;
            if PIPES[k].x == 0 {
                across = geo_of(i).z;
            } else if PIPES[k].y == 0 {
                across = geo_of(i).w;
            }
            let section = weight(k) * across * d;
            var old = old0[k];
            if k >= 4u {
                old = old1[k - 4u];
            }
            f[k] = max(0.0, old * keep + dt * P.g * section * (h + d - surface) / len);
            total_m3 += f[k] * dt;
        }
        let water = state_of(i).x;
        let held_m3 = f32(water) * P.unit_m3;
        if total_m3 > held_m3 {
            let scale = select(0.0, held_m3 / total_m3, total_m3 > 0.0);
            for (var k = 0u; k < 8u; k++) {
                f[k] *= scale;
            }
        }
        var sent_w = 0;
        for (var k = 0u; k < 8u; k++) {
            w[k] = clamp(round_units(f[k] * dt / P.unit_m3, i, 8u + k), 0, water - sent_w);
            sent_w += w[k];
        }
        if water > 0 {
            let sediment = state_of(i).y;
            var sent_s = 0;
            for (var k = 0u; k < 8u; k++) {
                let share = units_floor(f32(sediment) * f32(w[k]) / f32(water));
                s[k] = min(share, sediment - sent_s);
                sent_s += s[k];
            }
        }
        // Thermal sliding towards lower neighbours beyond the talus angle.
        let rate = min(P.thermal * dt, 1.0) / hardness(i);
        if rate > 0.0 {
            var sum = 0;
            for (var k = 0u; k < 8u; k++) {
                let nb = neighbour(i, k);
                if nb < 0 || is_sink(u32(nb)) {
                    continue;
                }
                let excess = h - height_m(u32(nb)) - pipe_length_m(i, k) * P.tan_talus;
                if excess > 0.0 {
                    let volume_m3 = rate * weight(k) / P.weight_sum * 0.5 * excess * geo_of(i).y;
                    l[k] = units_floor(min(volume_m3 / P.unit_m3, f32(MAX_UNITS)));
                    sum += l[k];
                }
            }
            let room = max(min(state_of(i).z + MAX_UNITS, MAX_UNITS), 0);
            if sum > room {
                var sent_l = 0;
                for (var k = 0u; k < 8u; k++) {
                    l[k] = min(units_floor(f32(l[k]) * f32(room) / f32(sum)), room - sent_l);
                    sent_l += l[k];
                }
            }
        }
    }
    slope[i] = sin_slope(i);
    flux_set(i, 0u, vec4<f32>(f[0], f[1], f[2], f[3]));
    flux_set(i, 1u, vec4<f32>(f[4], f[5], f[6], f[7]));
    sent_water_set(i, 0u, vec4<i32>(w[0], w[1], w[2], w[3]));
    sent_water_set(i, 1u, vec4<i32>(w[4], w[5], w[6], w[7]));
    sent_sediment_set(i, 0u, vec4<i32>(s[0], s[1], s[2], s[3]));
    sent_sediment_set(i, 1u, vec4<i32>(s[4], s[5], s[6], s[7]));
    sent_soil_set(i, 0u, vec4<i32>(l[0], l[1], l[2], l[3]));
    sent_soil_set(i, 1u, vec4<i32>(l[4], l[5], l[6], l[7]));
}

// What cell i sent through pipe k: water (0), sediment (1) or soil (2).
fn sent_by(i: u32, what: u32, k: u32) -> i32 {
    let half = k / 4u;
    if what == 0u {
        return sent_water_of(i, half)[k % 4u];
    }
    if what == 1u {
        return sent_sediment_of(i, half)[k % 4u];
    }
    return sent_soil_of(i, half)[k % 4u];
}

var<workgroup> wg_sums: array<array<u32, 8>, 256>;
var<workgroup> wg_bound: array<f32, 256>;
var<workgroup> wg_speed: array<f32, 256>;
var<workgroup> wg_depth: array<f32, 256>;

@compute @workgroup_size(256)
fn update(@builtin(workgroup_id) wid: vec3<u32>, @builtin(local_invocation_index) lid: u32) {
    let i = cell_index(wid, lid);
    // This cell's budget terms: rain in, evaporated, water out, soil out.
    var budget = vec4<i32>(0, 0, 0, 0);
    var bound = BIG;
    var speed = 0.0;
    var depth_after = 0.0;
    if i < P.n {
        let dt = control.dt;
        var water_in = 0;
        var sediment_in = 0;
        var soil_in = 0;
        var flow = vec2<f32>(0.0, 0.0);
        var sent_w = 0;
        var sent_s = 0;
        var sent_l = 0;
        for (var k = 0u; k < 8u; k++) {
            sent_w += sent_by(i, 0u, k);
            sent_s += sent_by(i, 1u, k);
            sent_l += sent_by(i, 2u, k);
            let nb = neighbour(i, k);
            if nb >= 0 {
                let back = k ^ 1u;
                let w_back = sent_by(u32(nb), 0u, back);
                water_in += w_back;
                sediment_in += sent_by(u32(nb), 1u, back);
                soil_in += sent_by(u32(nb), 2u, back);
                flow += f32(sent_by(i, 0u, k) - w_back) * vec2<f32>(PIPES[k]);
            }
        }
        let cell = geo_of(i);
        if is_sink(i) {
            // Everything that flows in leaves the run here.
            budget.z += water_in;
            budget.w += sediment_in + soil_in;
            state_set(i, vec4<i32>(0, 0, 0, 0));
        } else {
            // Through an open border: what went out through pipes with no cell beyond.
            for (var k = 0u; k < 8u; k++) {
                if neighbour(i, k) < 0 {
                    budget.z += sent_by(i, 0u, k);
                    budget.w += sent_by(i, 1u, k);
                }
            }
            let before = state_of(i);
            var water = before.x - sent_w + water_in;
            var sediment = before.y - sent_s + sediment_in;
            var soil = before.z - sent_l + soil_in;
            let area = cell.y;
            let mean_depth = 0.5 * f32(before.x + water) * P.unit_m3 / area;
            if dt > 0.0 {
                // The discharge per unit width, m²/s, and |v| desingularised (Kurganov & Petrova).
                let qx = 0.5 * flow.x * P.unit_m3 / dt / cell.w;
                let qy = 0.5 * flow.y * P.unit_m3 / dt / cell.z;
                let d4 = mean_depth * mean_depth * mean_depth * mean_depth;
                let e2 = DESINGULARISE_M * DESINGULARISE_M;
                let denominator = sqrt(d4 + max(d4, e2 * e2));
                if denominator > 0.0 {
                    speed = 1.41421356 * mean_depth * sqrt(qx * qx + qy * qy) / denominator;
                }
            }
            // Capacity (a depth of sediment, at most the water's): speed, slope and depth.
            let sin_a = max(slope[i], P.min_slope);
            let capacity_m = min(P.capacity * sin_a * speed * min(mean_depth, P.capacity_depth_m), mean_depth);
            let carried_m = f32(sediment) * P.unit_m3 / area;
            let erodes = clamp(masks_of(i).y, 0.0, 1.0);
            if capacity_m > carried_m {
                let rate = min(P.dissolve * dt, 1.0) * erodes / hardness(i);
                let taken = max(min(round_units((capacity_m - carried_m) * rate * area / P.unit_m3, i, 1u), soil + MAX_UNITS), 0);
                soil -= taken;
                sediment += taken;
            } else {
                let rate = min(P.deposit * dt, 1.0);
                let laid = clamp(round_units((carried_m - capacity_m) * rate * area / P.unit_m3, i, 2u), 0, sediment);
                sediment -= laid;
                soil += laid;
            }
            // Evaporation; water gone, its sediment settles.
            let evaporated = clamp(round_units(f32(water) * min(P.evaporation * dt, 1.0), i, 3u), 0, water);
            water -= evaporated;
            budget.y += evaporated;
            if water == 0 && sediment > 0 {
                soil += sediment;
                sediment = 0;
            }
            // Rain, within the units a cell may hold.
            let mask = clamp(masks_of(i).x, 0.0, 1.0);
            let rain = max(min(round_units(P.rain_m_s * dt * mask * area / P.unit_m3, i, 4u), MAX_UNITS - water), 0);
            water += rain;
            budget.x += rain;
            // Beyond what a cell may hold: water and soil spill out (counted), sediment settles.
            if water > MAX_UNITS {
                budget.z += water - MAX_UNITS;
                water = MAX_UNITS;
            }
            if sediment > MAX_UNITS {
                soil += sediment - MAX_UNITS;
                sediment = MAX_UNITS;
            }
            if soil > MAX_UNITS {
                budget.w += soil - MAX_UNITS;
                soil = MAX_UNITS;
            }
            state_set(i, vec4<i32>(water, sediment, soil, 0));
            depth_after = f32(water) * P.unit_m3 / area;
        }
        // The next step's CFL bound here (with the rain it will add).
        let wave = speed + sqrt(P.g * (depth_after + P.rain_m_s * P.dt_asked));
        if wave > 0.0 {
            bound = P.cfl * min(cell.z, cell.w) / wave;
        }
    }
    // The workgroup's sums, in a fixed tree.
    let b = vec4<u32>(budget);
    wg_sums[lid] = array<u32, 8>(b.x & 0xffffu, b.x >> 16u, b.y & 0xffffu, b.y >> 16u,
                                 b.z & 0xffffu, b.z >> 16u, b.w & 0xffffu, b.w >> 16u);
    wg_bound[lid] = bound;
    wg_speed[lid] = speed;
    wg_depth[lid] = depth_after;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half /= 2u) {
        if lid < half {
            for (var t = 0u; t < 8u; t++) {
                wg_sums[lid][t] += wg_sums[lid + half][t];
            }
            wg_bound[lid] = min(wg_bound[lid], wg_bound[lid + half]);
            wg_speed[lid] = max(wg_speed[lid], wg_speed[lid + half]);
            wg_depth[lid] = max(wg_depth[lid], wg_depth[lid + half]);
        }
        workgroupBarrier();
    }
    let g = wid.y * P.groups_x + wid.x;
    if lid == 0u && g < P.groups {
        partials[g] = Partial(wg_sums[0], wg_bound[0], wg_speed[0], wg_depth[0], 0.0);
    }
}

fn add64(a: vec2<u32>, b: vec2<u32>) -> vec2<u32> {
    let lo = a.x + b.x;
    return vec2<u32>(lo, a.y + b.y + select(0u, 1u, lo < a.x));
}

var<workgroup> red_totals: array<array<vec2<u32>, 4>, 256>;

@compute @workgroup_size(256)
fn reduce(@builtin(local_invocation_index) lid: u32) {
    var acc = array<vec2<u32>, 4>();
    var bound = BIG;
    var speed = 0.0;
    var depth = 0.0;
    for (var g = lid; g < P.groups; g += WG) {
        for (var t = 0u; t < 4u; t++) {
            // Σ low bits + (Σ high bits) · 2¹⁶, in 64 bits.
            let hi = partials[g].sums[2u * t + 1u];
            acc[t] = add64(add64(acc[t], vec2<u32>(partials[g].sums[2u * t], 0u)), vec2<u32>(hi << 16u, hi >> 16u));
        }
        bound = min(bound, partials[g].bound);
        speed = max(speed, partials[g].max_speed);
        depth = max(depth, partials[g].max_depth);
    }
    red_totals[lid] = acc;
    wg_bound[lid] = bound;
    wg_speed[lid] = speed;
    wg_depth[lid] = depth;
    workgroupBarrier();
    for (var half = WG / 2u; half > 0u; half /= 2u) {
        if lid < half {
            for (var t = 0u; t < 4u; t++) {
                red_totals[lid][t] = add64(red_totals[lid][t], red_totals[lid + half][t]);
            }
            wg_bound[lid] = min(wg_bound[lid], wg_bound[lid + half]);
            wg_speed[lid] = max(wg_speed[lid], wg_speed[lid + half]);
            wg_depth[lid] = max(wg_depth[lid], wg_depth[lid + half]);
        }
        workgroupBarrier();
    }
    if lid == 0u {
        for (var t = 0u; t < 4u; t++) {
            control.totals[t] = add64(control.totals[t], red_totals[0][t]);
        }
        dt_log[control.batch_step] = control.dt;
        control.batch_step += 1u;
        control.step += 1u;
        control.bound = wg_bound[0];
        control.max_speed = wg_speed[0];
        control.max_depth = wg_depth[0];
        control.dt = min(P.dt_asked, wg_bound[0]);
    }
}
