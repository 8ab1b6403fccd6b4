//! The height ranges of a source tile's blocks of 8 × 8 cells, so that a patch's height range can
//! be read from the tiles its samples come from (the quad's own, and its ancestors' for strided
//! patches) without keeping the tiles' grids.

use crate::ecm::grid::GRID as SAMPLES;

/// Cells along a block's edge.
pub const BLOCK_CELLS: u32 = 8;
/// Blocks along a tile's edge.
const BLOCKS: u32 = (SAMPLES - 1) / BLOCK_CELLS;

/// One block's lowest and highest sample with data (`lo > hi` when it has none) and whether any
/// of its samples has no data.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Block {
    lo: f32,
    hi: f32,
    gaps: bool,
}

/// What a rectangle of a tile holds: its lowest and highest height with data (metres; `None`
/// when no sample has data) and whether some sample has no data.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SpanRange {
    /// Lowest and highest height with data.
    pub range_m: Option<(f32, f32)>,
    /// Some sample in the rectangle has no data.
    pub gaps: bool,
}

/// A tile's 32 × 32 block ranges; block (bx, by) covers samples 8·bx … 8·bx + 8 and 8·by …
/// 8·by + 8 (both ends: neighbouring blocks share their edge samples).
#[derive(Debug)]
pub struct BlockRanges {
    blocks: Vec<Block>,
}

impl BlockRanges {
    /// The block ranges of a 257² grid, row by row from the south, NaN where there is no data.
    pub fn new(grid: &[f32]) -> BlockRanges {
        let n = SAMPLES as usize;
        debug_assert_eq!(grid.len(), n * n);
        let mut blocks = Vec::with_capacity((BLOCKS * BLOCKS) as usize);
        for by in 0..BLOCKS {
            for bx in 0..BLOCKS {
                let mut b = Block { lo: f32::INFINITY, hi: f32::NEG_INFINITY, gaps: false };
                for j in by * BLOCK_CELLS..=(by + 1) * BLOCK_CELLS {
                    for i in bx * BLOCK_CELLS..=(bx + 1) * BLOCK_CELLS {
                        let h = grid[j as usize * n + i as usize];
                        if h.is_nan() {
                            b.gaps = true;
                        } else {
                            b.lo = b.lo.min(h);
                            b.hi = b.hi.max(h);
                        }
                    }
                }
                blocks.push(b);
            }
        }
        BlockRanges { blocks }
    }

    /// What samples `i.0 ..= i.1` × `j.0 ..= j.1` hold, bounded by the blocks that cover them
    /// (exact when the ends are multiples of 8, wider otherwise).
    pub fn over(&self, i: (u32, u32), j: (u32, u32)) -> SpanRange {
        let blocks = |(a, b): (u32, u32)| {
            let first = (a / BLOCK_CELLS).min(BLOCKS - 1);
            let last = (b.saturating_sub(1) / BLOCK_CELLS).clamp(first, BLOCKS - 1);
            first..=last
        };
        let (mut lo, mut hi, mut gaps) = (f32::INFINITY, f32::NEG_INFINITY, false);
        for by in blocks(j) {
            for bx in blocks(i) {
                let b = self.blocks[(by * BLOCKS + bx) as usize];
                (lo, hi, gaps) = (lo.min(b.lo), hi.max(b.hi), gaps || b.gaps);
            }
        }
        SpanRange { range_m: (lo <= hi).then_some((lo, hi)), gaps }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The range of samples `i` × `j` read sample by sample.
    fn brute(grid: &[f32], i: (u32, u32), j: (u32, u32)) -> SpanRange {
        let n = SAMPLES as usize;
        let (mut lo, mut hi, mut gaps) = (f32::INFINITY, f32::NEG_INFINITY, false);
        for y in j.0..=j.1 {
            for x in i.0..=i.1 {
                let h = grid[y as usize * n + x as usize];
                if h.is_nan() {
                    gaps = true;
                } else {
                    (lo, hi) = (lo.min(h), hi.max(h));
                }
            }
        }
        SpanRange { range_m: (lo <= hi).then_some((lo, hi)), gaps }
    }

    fn grid() -> Vec<f32> {
        let n = SAMPLES as usize;
        (0..n * n)
            .map(|k| {
                let (x, y) = ((k % n) as f32, (k / n) as f32);
                if x > 200.0 && y < 20.0 { f32::NAN } else { (x * 0.37).sin() * 50.0 + y * 3.0 - (x * y).sqrt() }
            })
            .collect()
    }

    #[test]
    fn aligned_spans_are_exact_and_others_hold_every_sample() {
        let g = grid();
        let blocks = BlockRanges::new(&g);
        // A patch (32 cells, both ends), as strided patches see it in ancestors (16, 8 cells).
        for (i, j) in [((32, 64), (96, 128)), ((224, 256), (0, 32)), ((16, 32), (8, 16)), ((0, 256), (0, 256))] {
            assert_eq!(blocks.over(i, j), brute(&g, i, j), "{i:?} × {j:?}");
        }
        // Unaligned and degenerate spans: a superset of the samples' range.
        for (i, j) in [((3, 5), (250, 256)), ((7, 7), (9, 9)), ((100, 131), (33, 40)), ((256, 256), (256, 256))] {
            let (wide, exact) = (blocks.over(i, j), brute(&g, i, j));
            let ((a, b), (c, d)) = (wide.range_m.unwrap(), exact.range_m.unwrap());
            assert!(a <= c && b >= d, "{i:?} × {j:?}: {wide:?} vs {exact:?}");
            assert!(wide.gaps || !exact.gaps);
        }
        // The no-data corner shows as gaps, and an all-gap span has no range.
        assert!(blocks.over((224, 256), (0, 16)).gaps);
        let empty = BlockRanges::new(&vec![f32::NAN; g.len()]);
        assert_eq!(empty.over((0, 32), (0, 32)), SpanRange { range_m: None, gaps: true });
    }
}
