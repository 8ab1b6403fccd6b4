// The geometric error δ of each patch of a quad at each stride: the largest vertical distance, in
// metres, between the quad's composed heights under the patch and the surface the patch's mesh
// draws at that stride (each cell cut along its (0, 0)–(1, 1) diagonal, as terrain.rs's
// patch_indices draws it, its vertices standing on the quad's own samples, as the terrain's
// geometry_height reads them). One workgroup per (patch, quad); each lane takes every 64th
// of the patch's 33 × 33 samples against the cell that holds it at each stride, keeps its own
// worst, and the group takes the worst of its lanes. Samples and
// vertices without data stand at the fill height. CPU reference: scene::patch_error::patch_errors (the same
// meshes in f64; tests/render.rs compares the two).

const N: u32 = 257u;
const PATCH_CELLS: u32 = 32u;
const PATCHES_PER_EDGE: u32 = 8u;
const STRIDES: u32 = 6u;
const NODATA_BELOW: f32 = -1.0e37;
//!include generated/codes.wgsl

struct Job {
    // The quad's height slot, the height drawn where a vertex has no data (f32 bits: the
    // terrain's Quad.params.z), unused ×2.
    slot: vec4<u32>,
}

@group(0) @binding(0) var<storage, read> heights: array<f32>;
@group(0) @binding(1) var<storage, read> jobs: array<Job>;
// Per job, patch (row-major from the south) and stride: δ as the bits of a non-negative f32.
@group(0) @binding(2) var<storage, read_write> errors: array<u32>;

// The patch's worst miss at each stride, as f32 bits.
var<workgroup> worst: array<atomic<u32>, STRIDES>;

// The height the mesh stands on at sample (i, j): the quad's own, or the fill the terrain draws
// where it has no data (the terrain shader's geometry_height).
fn vertex_height(job: Job, i: u32, j: u32) -> f32 {
    let h = heights[job.slot.x * N * N + j * N + i];
    return select(bitcast<f32>(job.slot.y), h, h > NODATA_BELOW);
}

// The mesh's height at (u, v) ∈ [0, 1]² of a cell (scene::patch_error::mesh_height).
fn mesh_height(h00: f32, h10: f32, h01: f32, h11: f32, u: f32, v: f32) -> f32 {
    if u >= v {
        return h00 + u * (h10 - h00) + v * (h11 - h10);
    }
    return h00 + v * (h01 - h00) + u * (h11 - h01);
}

@compute @workgroup_size(64)
fn patch_errors(@builtin(workgroup_id) group: vec3<u32>, @builtin(local_invocation_index) lane: u32) {
    let index = group.x;
    let job = jobs[group.z];
    if lane < STRIDES {
        atomicStore(&worst[lane], 0u);
    }
    workgroupBarrier();
    let i0 = (index % PATCHES_PER_EDGE) * PATCH_CELLS;
    let j0 = (index / PATCHES_PER_EDGE) * PATCH_CELLS;
    let own = job.slot.x;
    // This lane's worst at each stride (stride 1 draws every sample: its error stays 0).
    var lane_worst = array<f32, STRIDES>(0.0, 0.0, 0.0, 0.0, 0.0, 0.0);
    for (var n = lane; n < (PATCH_CELLS + 1u) * (PATCH_CELLS + 1u); n += 64u) {
        let di = n % (PATCH_CELLS + 1u);
        let dj = n / (PATCH_CELLS + 1u);
        let h = heights[own * N * N + (j0 + dj) * N + i0 + di];
        if h <= NODATA_BELOW {
            continue;
        }
        for (var k = 1u; k < STRIDES; k++) {
            let s = 1u << k;
            let cells = PATCH_CELLS / s;
            // The cell that holds the sample (the last one for the patch's far edges).
            let ci = min(di / s, cells - 1u) * s;
            let cj = min(dj / s, cells - 1u) * s;
            let a = i0 + ci;
            let b = j0 + cj;
            let h00 = vertex_height(job, a, b);
            let h10 = vertex_height(job, a + s, b);
            let h01 = vertex_height(job, a, b + s);
            let h11 = vertex_height(job, a + s, b + s);
            let e = abs(h - mesh_height(h00, h10, h01, h11, f32(di - ci) / f32(s), f32(dj - cj) / f32(s)));
            lane_worst[k] = max(lane_worst[k], e);
        }
    }
    for (var k = 1u; k < STRIDES; k++) {
        // Non-negative floats order as their bits.
        atomicMax(&worst[k], bitcast<u32>(lane_worst[k]));
    }
    workgroupBarrier();
    if lane < STRIDES {
        errors[(group.z * PATCHES_PER_EDGE * PATCHES_PER_EDGE + index) * STRIDES + lane] = atomicLoad(&worst[lane]);
    }
}
