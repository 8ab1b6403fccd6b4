//! One quad's samples: the 257² grid in memory, and its two stored parts: the GeoPackage tile
//! (256² float32 TIFF, row 0 north) and the rim (north row and east column, little-endian f32).

use std::io::Cursor;

use tiff::decoder::{Decoder, DecodingResult};
use tiff::encoder::{Compression, TiffEncoder, colortype::Gray32Float};

use crate::ecm::grid::{GRID, RIM, TILE};

/// A stored tile that cannot be decoded.
#[derive(Debug, thiserror::Error)]
pub enum TileError {
    /// The tile is not a TIFF the decoder reads.
    #[error("tile is not a TIFF the decoder reads")]
    Tiff(#[source] tiff::TiffError),
    /// The tile or its rim has the wrong size or sample type.
    #[error("{0}")]
    Damaged(String),
}

/// A quad's corner-inclusive grid: 257 × 257 heights, index `j · 257 + i` with i east and j north
/// (the geometry's `sample_xy(257, i, j)` order); NaN is no data.
#[derive(Clone)]
pub struct QuadGrid {
    /// The samples, row by row from the south.
    pub values: Vec<f32>,
}

/// Equal when every sample has the same bits (so no data equals no data).
impl PartialEq for QuadGrid {
    fn eq(&self, other: &QuadGrid) -> bool {
        self.values.len() == other.values.len()
            && self.values.iter().zip(&other.values).all(|(a, b)| a.to_bits() == b.to_bits())
    }
}

/// A summary, not 66 049 numbers.
impl std::fmt::Debug for QuadGrid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let valid = self.values.iter().filter(|v| !v.is_nan()).count();
        write!(f, "QuadGrid({valid} of {} samples with data)", self.values.len())
    }
}

/// A quad's grid as the store keeps it.
#[derive(Clone, Debug)]
pub struct EncodedQuad {
    /// The GeoPackage tile (float32 baseline TIFF, uncompressed).
    pub tile: Vec<u8>,
    /// The rim.
    pub rim: Vec<u8>,
    /// Tile statistics.
    pub stats: TileStats,
}

/// Statistics of a tile's stored samples, as the GeoPackage tile ancillary table keeps them.
#[derive(Clone, Copy, Debug, Default, PartialEq)]
pub struct TileStats {
    /// Smallest height.
    pub min: f64,
    /// Largest height.
    pub max: f64,
    /// Mean height.
    pub mean: f64,
    /// Standard deviation.
    pub std_dev: f64,
    /// Samples with data.
    pub valid: u32,
}

impl QuadGrid {
    /// A grid of no data.
    pub fn empty() -> QuadGrid {
        QuadGrid { values: vec![f32::NAN; (GRID * GRID) as usize] }
    }

    /// Sample (i, j), i east, j north, both in 0..=256.
    pub fn get(&self, i: u32, j: u32) -> f32 {
        self.values[(j * GRID + i) as usize]
    }

    /// Whether no sample has data.
    pub fn is_empty(&self) -> bool {
        self.values.iter().all(|v| v.is_nan())
    }

    /// The GeoPackage tile: samples i, j ∈ 0..256 as a float32 TIFF, pixel row 0 the northernmost
    /// (j = 255), each pixel's value at its lower-left corner. Uncompressed: the GeoPackage
    /// gridded-coverage extension (OGC 17-066r1) allows a baseline TIFF with IEEE floats and, as
    /// its only compression, LZW, which shrinks float heights by about 5 % (deflate, which
    /// earlier stores used and which is still read, by about a quarter, for more CPU time than
    /// all the rest of an import). Reading and writing an uncompressed tile is a copy.
    pub fn encode_tile(&self) -> Vec<u8> {
        let mut pixels = Vec::with_capacity((TILE * TILE) as usize);
        for row in 0..TILE {
            let j = TILE - 1 - row;
            pixels.extend((0..TILE).map(|i| self.get(i, j)));
        }
        let mut bytes = Cursor::new(Vec::new());
        let mut encoder = TiffEncoder::new(&mut bytes)
            .expect("a TIFF header fits in memory")
            .with_compression(Compression::Uncompressed);
        encoder.write_image::<Gray32Float>(TILE, TILE, &pixels).expect("a float image encodes in memory");
        bytes.into_inner()
    }

    /// The tile, its statistics and its rim, ready to be written (encoded by the worker that
    /// computed the grid, not by the one thread that writes).
    pub fn encode(&self) -> EncodedQuad {
        EncodedQuad { tile: self.encode_tile(), rim: self.encode_rim(), stats: self.tile_stats().unwrap_or_default() }
    }

    /// The rim: the north row (i = 0..=256 at j = 256), then the east column (j = 0..256 at
    /// i = 256), as little-endian f32.
    pub fn encode_rim(&self) -> Vec<u8> {
        let north = (0..GRID).map(|i| self.get(i, TILE));
        let east = (0..TILE).map(|j| self.get(TILE, j));
        north.chain(east).flat_map(f32::to_le_bytes).collect()
    }

    /// Rebuilds the grid from a stored tile and rim. Errors name what is wrong with them.
    pub fn decode(tile: &[u8], rim: &[u8]) -> Result<QuadGrid, TileError> {
        let mut decoder = Decoder::new(Cursor::new(tile)).map_err(TileError::Tiff)?;
        let (w, h) = decoder.dimensions().map_err(TileError::Tiff)?;
        if (w, h) != (TILE, TILE) {
            return Err(TileError::Damaged(format!("tile is {w}×{h} pixels, not {TILE}×{TILE}")));
        }
        let pixels = match decoder.read_image().map_err(TileError::Tiff)? {
            DecodingResult::F32(v) => v,
            other => {
                return Err(TileError::Damaged(format!("tile holds {} samples, not float32", result_kind(&other))));
            }
        };
        if rim.len() != RIM * 4 {
            return Err(TileError::Damaged(format!("rim has {} bytes, not {}", rim.len(), RIM * 4)));
        }
        let rim: Vec<f32> = rim.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        let mut grid = QuadGrid::empty();
        for row in 0..TILE {
            let j = TILE - 1 - row;
            let src = &pixels[(row * TILE) as usize..((row + 1) * TILE) as usize];
            grid.values[(j * GRID) as usize..(j * GRID + TILE) as usize].copy_from_slice(src);
        }
        grid.values[(TILE * GRID) as usize..].copy_from_slice(&rim[..GRID as usize]);
        for j in 0..TILE {
            grid.values[(j * GRID + TILE) as usize] = rim[GRID as usize + j as usize];
        }
        Ok(grid)
    }

    /// Statistics over the samples the tile stores (not the rim), or `None` without data.
    pub fn tile_stats(&self) -> Option<TileStats> {
        let (mut n, mut sum, mut sum2) = (0u32, 0.0f64, 0.0f64);
        let (mut min, mut max) = (f64::INFINITY, f64::NEG_INFINITY);
        for j in 0..TILE {
            for i in 0..TILE {
                let v = f64::from(self.get(i, j));
                if v.is_nan() {
                    continue;
                }
                n += 1;
                sum += v;
                sum2 += v * v;
                min = min.min(v);
                max = max.max(v);
            }
        }
        (n > 0).then(|| {
            let mean = sum / f64::from(n);
            TileStats { min, max, mean, std_dev: (sum2 / f64::from(n) - mean * mean).max(0.0).sqrt(), valid: n }
        })
    }
}

fn result_kind(r: &DecodingResult) -> &'static str {
    match r {
        DecodingResult::U8(_) => "uint8",
        DecodingResult::U16(_) => "uint16",
        DecodingResult::I16(_) => "int16",
        DecodingResult::F64(_) => "float64",
        _ => "other",
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_and_rim_round_trip_bit_for_bit() {
        let mut g = QuadGrid::empty();
        for (k, v) in g.values.iter_mut().enumerate() {
            *v = if k % 97 == 0 { f32::NAN } else { (k as f32).sin() * 8_000.0 };
        }
        let back = QuadGrid::decode(&g.encode_tile(), &g.encode_rim()).unwrap();
        for (a, b) in g.values.iter().zip(&back.values) {
            assert!(a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan()));
        }
        assert!(QuadGrid::decode(b"not a tiff", &g.encode_rim()).unwrap_err().to_string().contains("not a TIFF"));
        assert!(QuadGrid::decode(&g.encode_tile(), &[0u8; 12]).unwrap_err().to_string().contains("rim"));
        let s = g.tile_stats().unwrap();
        assert!(s.min >= -8_000.0 && s.max <= 8_000.0 && s.valid < 256 * 256);
    }

    /// The tile is what the GeoPackage gridded-coverage extension allows (a baseline TIFF, one
    /// IEEE float per pixel, no compression), and the deflated tiles of earlier stores still read.
    #[test]
    fn tiles_are_uncompressed_float_tiffs_and_deflated_ones_still_read() {
        use tiff::decoder::Decoder;
        use tiff::tags::Tag;
        let mut g = QuadGrid::empty();
        for (k, v) in g.values.iter_mut().enumerate() {
            *v = (k as f32 * 0.37).cos() * 900.0;
        }
        let tile = g.encode_tile();
        let mut d = Decoder::new(Cursor::new(&tile)).unwrap();
        assert_eq!(d.get_tag_u32(Tag::Compression).unwrap(), 1, "uncompressed");
        assert_eq!(d.get_tag_u32(Tag::SampleFormat).unwrap(), 3, "IEEE float");
        assert_eq!(d.get_tag_u32(Tag::BitsPerSample).unwrap(), 32);
        assert_eq!(d.dimensions().unwrap(), (TILE, TILE));

        let pixels: Vec<f32> =
            (0..TILE).flat_map(|row| (0..TILE).map(move |i| (i, TILE - 1 - row))).map(|(i, j)| g.get(i, j)).collect();
        let mut deflated = Cursor::new(Vec::new());
        TiffEncoder::new(&mut deflated)
            .unwrap()
            .with_compression(Compression::Deflate(tiff::encoder::DeflateLevel::Fast))
            .write_image::<Gray32Float>(TILE, TILE, &pixels)
            .unwrap();
        let deflated = deflated.into_inner();
        assert!(deflated.len() < tile.len());
        let (a, b) =
            (QuadGrid::decode(&tile, &g.encode_rim()).unwrap(), QuadGrid::decode(&deflated, &g.encode_rim()).unwrap());
        assert!(a.values.iter().zip(&b.values).all(|(x, y)| x.to_bits() == y.to_bits()));
    }
}
