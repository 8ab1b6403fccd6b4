// The 32-bit integer hash of PCG's output permutation (O'Neill 2014): the GPU twin of
// terrafuse::maths::pcg, which the noise lattice and the erosion dither draw from.

fn pcg(v: u32) -> u32 {
    let state = v * 747796405u + 2891336453u;
    let word = ((state >> ((state >> 28u) + 4u)) ^ state) * 277803737u;
    return (word >> 22u) ^ word;
}
