//! An edit raster saved beside its project, so that a long session opens without replaying every
//! stroke: `stores/edits-<layer>-<digest>.tiles`, the digest (FNV-1a, 64 bits) over what the
//! raster is a function of: the body, the layer's strokes in effect and, when one of them reads
//! the terrain, the layers below it (their specs and their stores' sizes and modification times).
//! A cache whose name has another digest is stale and never read; one that cannot be read (cut
//! short, another format) is ignored and the raster rebuilt. Files are written atomically; the
//! layer's older caches are removed after a new one is written.
//!
//! Format (little-endian): `TFEDITS1`, the level (u8), the tile count (u32), then per tile its
//! face (u8), level (u8), x and y (u32) and its 257² δ (f32).

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use super::raster::EditRaster;
use crate::ecm::grid::GRID;
use crate::ecm::{Face, QuadId};
use crate::geodesy::Ellipsoid;

const MAGIC: &[u8; 8] = b"TFEDITS1";
const N: usize = (GRID * GRID) as usize;

/// What can go wrong writing a cache (reading never fails: an unreadable cache is rebuilt).
#[derive(Debug, thiserror::Error)]
#[error("{path}: {problem}")]
pub struct CacheError {
    /// The file.
    pub path: PathBuf,
    /// What went wrong.
    pub problem: String,
}

/// FNV-1a over bytes, for the digest.
#[derive(Clone, Copy, Debug)]
pub struct Digest(u64);

impl Default for Digest {
    fn default() -> Digest {
        Digest(0xcbf2_9ce4_8422_2325)
    }
}

impl Digest {
    /// Folds in bytes (each part's length first, so that parts cannot run into each other).
    pub fn with(mut self, bytes: &[u8]) -> Digest {
        for b in (bytes.len() as u64).to_le_bytes().iter().chain(bytes) {
            self.0 = (self.0 ^ u64::from(*b)).wrapping_mul(0x100_0000_01b3);
        }
        self
    }

    /// The value.
    pub fn value(self) -> u64 {
        self.0
    }
}

/// The cache file of layer `name` under `dir` for `digest`.
pub fn cache_path(dir: &Path, name: &str, digest: u64) -> PathBuf {
    dir.join(format!("edits-{}-{digest:016x}.tiles", file_safe(name)))
}

fn file_safe(name: &str) -> String {
    name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect()
}

/// Caches kept per layer: the current one and the most recent others (undo and redo positions).
pub const KEPT: usize = 4;

/// The raster saved at `path`, if it is there and readable.
pub fn read(path: &Path, ellipsoid: Ellipsoid) -> Option<EditRaster> {
    let bytes = std::fs::read(path).ok()?;
    let rest = bytes.strip_prefix(MAGIC)?;
    let (&level, rest) = rest.split_first()?;
    let count = u32::from_le_bytes(rest.get(..4)?.try_into().ok()?) as usize;
    let mut rest = &rest[4..];
    let tile_bytes = 10 + 4 * N;
    if rest.len() != count.checked_mul(tile_bytes)? {
        return None;
    }
    let mut tiles = BTreeMap::new();
    for _ in 0..count {
        let (head, values) = rest[..tile_bytes].split_at(10);
        let face = *Face::ALL.get(usize::from(head[0]))?;
        let x = u32::from_le_bytes(head[2..6].try_into().ok()?);
        let y = u32::from_le_bytes(head[6..10].try_into().ok()?);
        let quad = QuadId::new(face, head[1], x, y).ok()?;
        if quad.level != level {
            return None;
        }
        let tile: Vec<f32> = values.chunks_exact(4).map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])).collect();
        tiles.insert(quad, tile);
        rest = &rest[tile_bytes..];
    }
    Some(EditRaster::from_tiles(ellipsoid, level, tiles))
}

/// Saves `raster` at `path` atomically and removes the layer's other caches in the folder.
pub fn write(path: &Path, raster: &EditRaster) -> Result<(), CacheError> {
    let err = |problem: String| CacheError { path: path.to_path_buf(), problem };
    let mut bytes = Vec::with_capacity(13 + raster.tiles.len() * (10 + 4 * N));
    bytes.extend_from_slice(MAGIC);
    bytes.push(raster.level);
    bytes.extend_from_slice(&(raster.tiles.len() as u32).to_le_bytes());
    for (q, tile) in &raster.tiles {
        let face = Face::ALL.iter().position(|f| *f == q.face).expect("a face") as u8;
        bytes.extend_from_slice(&[face, q.level]);
        bytes.extend_from_slice(&q.x.to_le_bytes());
        bytes.extend_from_slice(&q.y.to_le_bytes());
        for v in tile {
            bytes.extend_from_slice(&v.to_le_bytes());
        }
    }
    if let Some(dir) = path.parent() {
        std::fs::create_dir_all(dir).map_err(|e| err(format!("cannot create the folder: {e}")))?;
    }
    crate::files::write_atomic(path, &bytes).map_err(|e| err(e.to_string()))?;
    // The layer's older caches: `edits-<layer>-<16 hex digits>.tiles` other than this one; the
    // most recent are kept (undo and redo within them read a cache), the rest removed.
    let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
    let prefix = &name[..name.len().saturating_sub(16 + ".tiles".len())];
    let mut older: Vec<(std::time::SystemTime, PathBuf)> = Vec::new();
    if let Some(entries) = path.parent().and_then(|d| std::fs::read_dir(d).ok()) {
        for entry in entries.flatten() {
            let other = entry.file_name().to_string_lossy().to_string();
            let stale = other != name
                && other.len() == name.len()
                && other.starts_with(prefix)
                && other.ends_with(".tiles")
                && other[prefix.len()..other.len() - 6].chars().all(|c| c.is_ascii_hexdigit());
            if stale {
                let modified = entry.metadata().and_then(|m| m.modified()).unwrap_or(std::time::UNIX_EPOCH);
                older.push((modified, entry.path()));
            }
        }
    }
    older.sort_by(|a, b| b.0.cmp(&a.0).then_with(|| a.1.cmp(&b.1)));
    for (_, stale) in older.iter().skip(KEPT - 1) {
        let _ = std::fs::remove_file(stale);
    }
    // Half-written caches of any layer that a killed process left (a cache is written whole or
    // not at all; its temporary is what a kill leaves).
    if let Some(dir) = path.parent() {
        for orphan in crate::files::orphans_of(dir, |f| f.starts_with("edits-") && f.ends_with(".tiles")) {
            let _ = std::fs::remove_file(orphan);
        }
    }
    Ok(())
}
