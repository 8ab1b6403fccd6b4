// Composition of a quad's heights from its layer stack: one invocation per sample of a 257²
// grid, one workgroup layer (z) per quad. The GPU twin of terrafuse::layers::compose (keep in
// sync): per layer a value and a coverage, folded by the blend modes; consecutive mean layers
// gathered and applied with over. Reads the quads' raw source tiles and static maps; writes the
// composed heights into the height pool the terrain's vertex stage reads.
//!include shared/ecm.wgsl
//!include shared/noise.wgsl
//!include generated/codes.wgsl

const N: u32 = 257u;
// A sample without data, in the source and height pools (the terrain shader tests < -1e37).
const NODATA_STORED: f32 = -3.0e37;
const NODATA_BELOW: f32 = -1.0e37;
const FAR: f32 = 3.0e38;
const TAU: f32 = 6.283185307179586;

// One quad to compose (ComposeJob in src/gpu/compose.rs; keep in sync).
struct Job {
    // Corners (SW, SE, NW, NE) on the ellipsoid relative to the origin O, metres.
    corners: array<vec4<f32>, 4>,
    // Columns of the signed permutation from the canonical quad's axes to this quad's.
    sym: array<vec4<f32>, 3>,
    // O in ECEF metres (f32: used only for longitude and latitude); w: the body's e².
    origin: vec4<f32>,
    // Output height slot, split code, map slot (NO_SLOT: flat patch), symmetry flags.
    slots: vec4<u32>,
    // First layer, the heights' layer count, then A's and B's (a difference's operands, listed
    // after the heights' layers).
    layers: vec4<u32>,
    // Sample spacing for octave weights (0: every octave), 1 where the job writes a difference
    // into the overlay pool, unused ×2.
    params: vec4<f32>,
}

// One planned layer of a job (JobLayer in src/gpu/compose.rs; keep in sync).
struct JobLayer {
    // What the layer's value is (KIND_*), how it folds into the heights below it (BLEND_*), its
    // source slot (datasets and edits), and whether its extent masks it partly (1) or not (0).
    kind: u32,
    blend: u32,
    source: u32,
    partial: u32,
    // The extent's mask in `shapes`: its first segment and their count, its ring's first vertex
    // and their count (a box has no ring: its bounds west, south, east, north are the one entry
    // at the ring's start).
    segment_first: u32,
    segments: u32,
    ring_first: u32,
    rings: u32,
    // Procedural: the first octave in `octaves`, their count, the noise type (0 fBm, 1 ridged)
    // and where it adds detail (0 everywhere, 1 beyond the data).
    octave_first: u32,
    octaves: u32,
    noise_type: u32,
    placement: u32,
    // Datasets: the edge slot (no-data edge distances, metres, in the source pool; NO_SLOT: no
    // edge feather), and the bias corrections' first entry in `shapes` and their count.
    edge_slot: u32,
    bias_first: u32,
    biases: u32,
    pad0: u32,
    // Opacity, the mean's weight, the scale and offset applied to the value (metres).
    opacity: f32,
    weight: f32,
    scale: f32,
    offset_m: f32,
    // The valid range (metres; ±FAR: none), the extent's feather (metres) and its ring's
    // smallest longitude.
    valid_lo_m: f32,
    valid_hi_m: f32,
    feather_m: f32,
    ring_lon_min: f32,
    // A constant layer's height, a procedural layer's amplitude and gain (metres; per octave),
    // a dataset's feather at its no-data edge and data spacing (metres; FAR: none), and the
    // ring's orientation (+1: counter-clockwise in longitude and latitude).
    height_m: f32,
    amplitude_m: f32,
    gain: f32,
    feather_edge_m: f32,
    data_spacing_m: f32,
    orientation: f32,
    pad1: f32,
    pad2: f32,
}

// One octave of one procedural layer at one quad: the lattice cell of O (xyz) and the octave's
// seed (w); the fraction of O/λ (xyz) and the wavelength λ (w, metres).
struct Octave {
    cell: vec4<u32>,
    frac: vec4<f32>,
}

@group(0) @binding(0) var<storage, read> jobs: array<Job>;
@group(0) @binding(1) var<storage, read> job_layers: array<JobLayer>;
@group(0) @binding(2) var<storage, read> octaves: array<Octave>;
// Extent edges: segments (two entries each, relative to the job's O) and ring vertices
// (longitude, latitude in radians); datasets' bias corrections (see `correction`).
@group(0) @binding(3) var<storage, read> shapes: array<vec4<f32>>;
@group(0) @binding(4) var<storage, read> sources: array<f32>;
@group(0) @binding(5) var<storage, read> map_o: array<f32>;
@group(0) @binding(6) var<storage, read_write> heights: array<f32>;
// A − B of the drawn difference layer, per height slot (NODATA_STORED where either has no data).
@group(0) @binding(7) var<storage, read_write> overlay: array<f32>;

fn turn(job: Job, v: vec3<f32>) -> vec3<f32> {
    return job.sym[0].xyz * v.x + job.sym[1].xyz * v.y + job.sym[2].xyz * v.z;
}

// The sample's point on the ellipsoid relative to O: patch + oₑ (the patch alone past the flat
// rule, where it is within its tolerance).
fn sample_local(job: Job, i: u32, j: u32) -> vec3<f32> {
    let s = f32(i) / f32(N - 1u);
    let t = f32(j) / f32(N - 1u);
    let base = ecm_interpolate(job.slots.y, job.corners[0].xyz, job.corners[1].xyz, job.corners[2].xyz, job.corners[3].xyz, s, t);
    if job.slots.z == NO_SLOT {
        return base;
    }
    let c = ecm_canonical_sample(job.slots.w, N, i, j);
    let k = 3u * (job.slots.z * N * N + c.y * N + c.x);
    return base + turn(job, vec3<f32>(map_o[k], map_o[k + 1u], map_o[k + 2u]));
}

// atan2 to ≈ 2 ulp (Cephes' atanf: range reduction by tan(π/8) and tan(3π/8), then a degree-9
// odd polynomial). WGSL's built-in may err by thousands of ulp (Vulkan allows 4096 for atan;
// lavapipe's was 30 ulp off at 0.7 rad, 9 m on Earth), which moved samples across extent edges.
fn precise_atan(v: f32) -> f32 {
    let a = abs(v);
    var base = 0.0;
    var x = a;
    if a > 2.414213562373095 {
        base = 1.5707963267948966;
        x = -1.0 / a;
    } else if a > 0.4142135623730950 {
        base = 0.7853981633974483;
        x = (a - 1.0) / (a + 1.0);
    }
    let z = x * x;
    let r = base + ((((8.05374449538e-2 * z - 1.38776856032e-1) * z + 1.99777106478e-1) * z - 3.33329491539e-1) * z * x + x);
    return select(r, -r, v < 0.0);
}

fn precise_atan2(y: f32, x: f32) -> f32 {
    if x > 0.0 {
        return precise_atan(y / x);
    }
    if x < 0.0 {
        let t = precise_atan(y / x);
        return select(t - 3.141592653589793, t + 3.141592653589793, y >= 0.0);
    }
    if y > 0.0 {
        return 1.5707963267948966;
    }
    if y < 0.0 {
        return -1.5707963267948966;
    }
    return 0.0;
}

fn segment_distance(p: vec3<f32>, a: vec3<f32>, b: vec3<f32>) -> f32 {
    let ab = b - a;
    let len2 = dot(ab, ab);
    var t = 0.0;
    if len2 > 0.0 {
        t = clamp(dot(p - a, ab) / len2, 0.0, 1.0);
    }
    return length(p - (a + ab * t));
}

// Closer to the edge than this, inside/outside is the side of the nearest edge segment
// (quad-local f32: millimetres) rather than the longitude/latitude test (f32 absolute positions:
// ≈ 0.5 m on Earth), so the two agree with the CPU's exact test everywhere but within this
// distance of a vertex.
const SIDE_TEST_M: f32 = 8.0;

// Segments a block of the nearest-segment search (layers::extent::MASK_BLOCK).
const MASK_BLOCK: u32 = 32u;

// layers::extent::Extent::{contains, nearest_m, mask}.
fn extent_mask(l: JobLayer, job: Job, local: vec3<f32>, lon: f32, lat: f32) -> f32 {
    if l.partial == 0u {
        return 1.0;
    }
    // The nearest segment, block by block (after the segments, a sphere a block: centre,
    // radius), as layers::extent::Extent::nearest_m searches: no segment of a block is farther
    // than |p − centre| + radius, so the nearest of those bounds the search before it starts,
    // and a block whose sphere lies farther than that bound or the nearest segment found yet
    // cannot hold a nearer one: the result is the full search's, from a few blocks.
    var d = FAR;
    var nearest = 0u;
    let spheres = l.segment_first + 2u * l.segments;
    let blocks = (l.segments + MASK_BLOCK - 1u) / MASK_BLOCK;
    var bound = FAR;
    for (var b = 0u; b < blocks; b++) {
        let sphere = shapes[spheres + b];
        bound = min(bound, length(local - sphere.xyz) + sphere.w);
    }
    for (var b = 0u; b < blocks; b++) {
        let sphere = shapes[spheres + b];
        if length(local - sphere.xyz) - sphere.w > min(d, bound) {
            continue;
        }
        for (var k = b * MASK_BLOCK; k < min(b * MASK_BLOCK + MASK_BLOCK, l.segments); k++) {
            let s = l.segment_first + 2u * k;
            let dk = segment_distance(local, shapes[s].xyz, shapes[s + 1u].xyz);
            if dk < d {
                d = dk;
                nearest = s;
            }
        }
    }
    var inside = false;
    if d < SIDE_TEST_M {
        let a = shapes[nearest].xyz;
        let up = normalize(job.origin.xyz + a);
        let left = cross(up, shapes[nearest + 1u].xyz - a);
        inside = dot(local - a, left) * l.orientation > 0.0;
    } else {
        let lon_min = l.ring_lon_min;
        let x = lon_min + (lon - lon_min) - TAU * floor((lon - lon_min) / TAU);
        let first = l.ring_first;
        let count = l.rings;
        if count == 0u {
            // A box: west, south, east (unwrapped), north.
            let b = shapes[first];
            inside = lat >= b.y && lat <= b.w && x >= b.x && x <= b.z;
        }
        for (var k = 0u; k < count; k++) {
            let v0 = shapes[first + k].xy;
            let v1 = shapes[first + (k + 1u) % count].xy;
            if (v0.y > lat) != (v1.y > lat) {
                let cross_lon = v0.x + (lat - v0.y) / (v1.y - v0.y) * (v1.x - v0.x);
                if x < cross_lon {
                    inside = !inside;
                }
            }
        }
    }
    if !inside {
        return 0.0;
    }
    let feather = l.feather_m;
    if feather <= 0.0 {
        return 1.0;
    }
    return smoothstep(0.0, 1.0, d / feather);
}

// layers::correction::binned_at: linear between bin centres (two bins to an entry), the end
// bins' values beyond them.
fn binned_at(first: u32, count: u32, x: f32) -> f32 {
    var prev = shapes[first].xy;
    if x < prev.x {
        return prev.y;
    }
    for (var b = 1u; b < count; b++) {
        let entry = shapes[first + b / 2u];
        let q = select(entry.xy, entry.zw, b % 2u == 1u);
        if x < q.x {
            return prev.y + (x - prev.x) / (q.x - prev.x) * (q.y - prev.y);
        }
        prev = q;
    }
    return prev.y;
}

// layers::correction::polynomial_at: the terms by total degree, then falling power of east;
// the coefficients four to an entry from `first`.
fn polynomial_at(first: u32, order: u32, e: f32, n: f32) -> f32 {
    let ep = array<f32, 4>(1.0, e, e * e, e * e * e);
    let np = array<f32, 4>(1.0, n, n * n, n * n * n);
    var sum = 0.0;
    var t = 0u;
    for (var d = 0u; d <= order; d++) {
        for (var j = 0u; j <= d; j++) {
            sum += shapes[first + t / 4u][t % 4u] * ep[d - j] * np[j];
            t++;
        }
    }
    return sum;
}

// layers::correction::Correction::at: the sum of a dataset layer's biases at a sample (`local`
// from O) where its scaled value is `value` (an elevation bias reads it as the biases before it
// left it). Entries from l.bias_first (see push_correction in
// src/gpu/compose.rs): a head (code, count, sin, cos of the azimuth), for the biases of position
// the frame ((east, e₀), (north, n₀)), then the terms. Sinusoids are evaluated on the fraction
// of turns (x / λ + phase / 2π), so that sin sees an argument within one turn.
fn correction(l: JobLayer, local: vec3<f32>, value: f32) -> f32 {
    var k = l.bias_first;
    var sum = 0.0;
    for (var b = 0u; b < l.biases; b++) {
        let head = shapes[k];
        let code = u32(head.x);
        let count = u32(head.y);
        if code == BIAS_ELEVATION {
            sum += binned_at(k + 1u, count, value - sum);
            k += 1u + (count + 1u) / 2u;
            continue;
        }
        let east = shapes[k + 1u];
        let north = shapes[k + 2u];
        let e = east.w + dot(local, east.xyz);
        let n = north.w + dot(local, north.xyz);
        let terms = shapes[k + 3u];
        if code == BIAS_DERAMP {
            let ek = clamp(e / 1000.0, terms.x, terms.z);
            let nk = clamp(n / 1000.0, terms.y, terms.w);
            sum += polynomial_at(k + 4u, count, ek, nk);
            k += 4u + ((count + 1u) * (count + 2u) / 2u + 3u) / 4u;
        } else {
            let x = clamp(e * head.z + n * head.w, terms.y, terms.z);
            var s = terms.x;
            for (var q = 0u; q < count; q++) {
                let w = shapes[k + 4u + q];
                s += w.y * sin(TAU * fract(x / w.x + w.z));
            }
            sum += s;
            k += 4u + count;
        }
    }
    return sum;
}

// layers::noise::{octave_weights, fractal}.
fn procedural(l: JobLayer, job: Job, local: vec3<f32>, data_spacing: f32, data_coverage: f32) -> f32 {
    var sum = 0.0;
    var amplitude = l.amplitude_m;
    var ridge_weight = 1.0;
    for (var k = 0u; k < l.octaves; k++) {
        let o = octaves[l.octave_first + k];
        let wavelength = o.frac.w;
        var w = noise_resolved_weight(wavelength, job.params.x);
        if l.placement == 1u {
            w = w * ((1.0 - data_coverage) + data_coverage * noise_beyond_data_weight(wavelength, data_spacing));
        }
        if l.noise_type == 0u {
            if w > 0.0 {
                sum += amplitude * w * noise_octave(o.cell.xyz, o.frac.xyz, local, wavelength, o.cell.w);
            }
        } else {
            let n = noise_octave(o.cell.xyz, o.frac.xyz, local, wavelength, o.cell.w);
            let s = (1.0 - abs(n)) * (1.0 - abs(n)) * ridge_weight;
            ridge_weight = clamp(2.0 * s, 0.0, 1.0);
            sum += amplitude * w * s;
        }
        amplitude *= l.gain;
    }
    return sum;
}

// The running height: value, whether it has data, the data's sample spacing and share.
struct Running {
    h: f32,
    has: bool,
    spacing: f32,
    coverage: f32,
}

// layers::compose::fold and apply ((1 − α)·h + α·x, so that α = 1 gives x exactly).
fn apply(r: Running, blend: u32, v: f32, a: f32, spacing: f32, data_share: f32) -> Running {
    var out = r;
    switch blend {
        case BLEND_ADD: {
            if r.has {
                out.h = r.h + a * v;
            }
        }
        case BLEND_MIN: {
            out.h = select(v, (1.0 - a) * r.h + a * min(r.h, v), r.has);
            out.has = true;
        }
        case BLEND_MAX: {
            out.h = select(v, (1.0 - a) * r.h + a * max(r.h, v), r.has);
            out.has = true;
        }
        default: {
            out.h = select(v, (1.0 - a) * r.h + a * v, r.has);
            out.has = true;
        }
    }
    if !out.has || blend == BLEND_ADD {
        return out;
    }
    let share = select(1.0, a, r.has);
    out.coverage = (1.0 - share) * r.coverage + share * data_share;
    if data_share > 0.0 {
        out.spacing = min(out.spacing, spacing);
    }
    return out;
}

// layers::compose::compose_sample: folds job layers [first, first + count) into a running height.
fn compose_layers(job: Job, first: u32, count: u32, i: u32, j: u32, local: vec3<f32>, lon: f32, lat: f32) -> Running {
    var r = Running(0.0, false, FAR, 0.0);
    var group_sum = 0.0;
    var group_weight = 0.0;
    var group_data_weight = 0.0;
    var group_alpha = 0.0;
    var group_spacing = FAR;
    for (var k = 0u; k < count; k++) {
        let l = job_layers[first + k];
        var base = 0.0;
        var valid = true;
        switch l.kind {
            // A dataset's raw heights, or an edit layer's deltas.
            case KIND_STORE_TILE, KIND_DELTAS: {
                base = sources[l.source * N * N + j * N + i];
                valid = base > NODATA_BELOW;
            }
            case KIND_NOISE: {
                base = procedural(l, job, local, r.spacing, r.coverage);
            }
            default: {
                base = l.height_m;
            }
        }
        var v = base * l.scale + l.offset_m;
        if l.kind == KIND_STORE_TILE && l.biases > 0u && valid {
            v -= correction(l, local, v);
        }
        valid = valid && v >= l.valid_lo_m && v <= l.valid_hi_m;
        var alpha = 0.0;
        if valid {
            alpha = l.opacity * extent_mask(l, job, local, lon, lat);
            if l.kind == KIND_STORE_TILE && l.edge_slot != NO_SLOT {
                // layers::edge::edge_mask: smoothstep(d / F) of the distance to the no-data edge.
                alpha *= smoothstep(0.0, 1.0, sources[l.edge_slot * N * N + j * N + i] / l.feather_edge_m);
            }
        }
        let dataset = l.kind == KIND_STORE_TILE;
        let spacing = select(FAR, l.data_spacing_m, dataset);
        if l.blend == BLEND_MEAN {
            if alpha > 0.0 {
                let w = l.weight * alpha;
                group_sum += w * v;
                group_weight += w;
                if dataset {
                    group_data_weight += w;
                }
                group_alpha = max(group_alpha, alpha);
                group_spacing = min(group_spacing, spacing);
            }
            var closes = k + 1u == count;
            if !closes {
                closes = job_layers[first + k + 1u].blend != BLEND_MEAN;
            }
            if closes {
                if group_weight > 0.0 {
                    r = apply(r, BLEND_OVER, group_sum / group_weight, group_alpha, group_spacing, group_data_weight / group_weight);
                }
                group_sum = 0.0;
                group_weight = 0.0;
                group_data_weight = 0.0;
                group_alpha = 0.0;
                group_spacing = FAR;
            }
        } else if alpha > 0.0 {
            r = apply(r, l.blend, v, alpha, spacing, select(0.0, 1.0, dataset));
        }
    }
    return r;
}

struct SamplePosition {
    local: vec3<f32>,
    lon: f32,
    lat: f32,
}

// The sample's position relative to O, its longitude and latitude.
fn sample_position(job: Job, i: u32, j: u32) -> SamplePosition {
    let local = sample_local(job, i, j);
    let p = job.origin.xyz + local;
    let lon = precise_atan2(p.y, p.x);
    let lat = precise_atan2(p.z, (1.0 - job.origin.w) * length(p.xy));
    return SamplePosition(local, lon, lat);
}

// The heights: every job's layers folded into its height slot.
@compute @workgroup_size(16, 16, 1)
fn compose(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let j = id.y;
    if i >= N || j >= N {
        return;
    }
    let job = jobs[id.z];
    let at = sample_position(job, i, j);
    let r = compose_layers(job, job.layers.x, job.layers.y, i, j, at.local, at.lon, at.lat);
    heights[job.slots.x * N * N + j * N + i] = select(NODATA_STORED, r.h, r.has);
}

// The drawn difference (a second dispatch, only when a job has one, so that the heights' kernel
// stays as small as it was): A and B each composed from their layers, listed after the heights',
// A − B into the overlay slot (layers::compose::compose_difference).
@compute @workgroup_size(16, 16, 1)
fn compose_difference(@builtin(global_invocation_id) id: vec3<u32>) {
    let i = id.x;
    let j = id.y;
    let job = jobs[id.z];
    if i >= N || j >= N || job.params.y < 0.5 {
        return;
    }
    let at = sample_position(job, i, j);
    let first = job.layers.x + job.layers.y;
    let a = compose_layers(job, first, job.layers.z, i, j, at.local, at.lon, at.lat);
    let b = compose_layers(job, first + job.layers.z, job.layers.w, i, j, at.local, at.lon, at.lat);
    overlay[job.slots.x * N * N + j * N + i] = select(NODATA_STORED, a.h - b.h, a.has && b.has);
}
