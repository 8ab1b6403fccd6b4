//! Digests of tiles of heights, and the comparison of a check's recorded digests with a
//! replay's (naming the first tile that differs).

use std::collections::BTreeMap;

use crate::ecm::QuadId;
use crate::edit::cache::Digest;
use crate::project::CheckSpec;

/// A digest over tiles, and each tile's own.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Digests {
    /// Over every tile, in quad order.
    pub total: u64,
    /// Each tile's.
    pub tiles: BTreeMap<QuadId, u64>,
}

/// One tile's digest: FNV-1a over its quad (`face/level/x/y`) and its heights' bits (every NaN
/// as one pattern, so that NaN payloads from different code paths hash alike).
pub fn tile(quad: QuadId, heights: &[f32]) -> u64 {
    let bytes: Vec<u8> =
        heights.iter().flat_map(|h| if h.is_nan() { f32::NAN.to_bits() } else { h.to_bits() }.to_le_bytes()).collect();
    Digest::default().with(quad.to_string().as_bytes()).with(&bytes).value()
}

/// The digests of tiles (any order in; quad order out).
pub fn of_tiles<'a>(tiles: impl IntoIterator<Item = (QuadId, &'a [f32])>) -> Digests {
    let tiles: BTreeMap<QuadId, u64> = tiles.into_iter().map(|(q, h)| (q, tile(q, h))).collect();
    let mut total = Digest::default();
    for (q, d) in &tiles {
        total = total.with(q.to_string().as_bytes()).with(&d.to_le_bytes());
    }
    Digests { total: total.value(), tiles }
}

/// A digest as written in a project: 16 hex digits.
pub fn hex(value: u64) -> String {
    format!("{value:016x}")
}

impl Digests {
    /// Writes these digests into a check (what `terrafuse replay --record` saves).
    pub fn record(&self, check: &mut CheckSpec) {
        check.digest = Some(hex(self.total));
        check.tiles = self.tiles.iter().map(|(q, d)| (q.to_string(), hex(*d))).collect();
    }
}

/// How a replay's digests differ from a check's.
#[derive(Clone, Debug, PartialEq)]
pub enum Mismatch {
    /// The check has no digest yet.
    NotRecorded,
    /// The digests differ; the first tile (in quad order) that differs or is on one side only,
    /// and how many do.
    Differs {
        /// The recorded digest.
        expected: String,
        /// The replay's.
        got: String,
        /// The first differing tile (`face/level/x/y`; None when only the total was recorded).
        first_tile: Option<String>,
        /// How many tiles differ.
        differing: usize,
    },
}

impl std::fmt::Display for Mismatch {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Mismatch::NotRecorded => write!(f, "no digest recorded (terrafuse replay --record writes it)"),
            Mismatch::Differs { expected, got, first_tile, differing } => {
                write!(f, "digest {got}, expected {expected}")?;
                if let Some(t) = first_tile {
                    write!(f, "; first differing tile {t} ({differing} differ)")?;
                }
                Ok(())
            }
        }
    }
}

/// Compares a replay's digests with a check's recorded ones.
pub fn compare(check: &CheckSpec, got: &Digests) -> Result<(), Mismatch> {
    let Some(expected) = &check.digest else {
        return Err(Mismatch::NotRecorded);
    };
    if *expected == hex(got.total) {
        return Ok(());
    }
    let got_tiles: BTreeMap<String, String> = got.tiles.iter().map(|(q, d)| (q.to_string(), hex(*d))).collect();
    // The keys as quads, so that "first" is quad order (not the strings' order).
    let mut keys: Vec<(Option<QuadId>, &String)> =
        check.tiles.keys().chain(got_tiles.keys()).map(|k| (parse_quad(k), k)).collect();
    keys.sort();
    keys.dedup();
    let differing: Vec<&String> =
        keys.into_iter().filter(|(_, k)| check.tiles.get(*k) != got_tiles.get(*k)).map(|(_, k)| k).collect();
    Err(Mismatch::Differs {
        expected: expected.clone(),
        got: hex(got.total),
        first_tile: differing.first().map(|k| k.to_string()),
        differing: differing.len(),
    })
}

fn parse_quad(text: &str) -> Option<QuadId> {
    let parts: Vec<&str> = text.split('/').collect();
    let [face, level, x, y] = parts.as_slice() else {
        return None;
    };
    let face: crate::ecm::Face = face.parse().ok()?;
    QuadId::new(face, level.parse().ok()?, x.parse().ok()?, y.parse().ok()?).ok()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::ecm::Face;

    #[test]
    fn a_changed_sample_changes_its_tile_and_is_named() {
        let quads: Vec<QuadId> = (0..3).map(|x| QuadId::new(Face::Front, 4, x, 2).unwrap()).collect();
        let tiles: Vec<Vec<f32>> = (0..3).map(|k| vec![k as f32; 257 * 257]).collect();
        let a = of_tiles(quads.iter().copied().zip(tiles.iter().map(Vec::as_slice)));
        let mut check = CheckSpec::default();
        assert_eq!(compare(&check, &a), Err(Mismatch::NotRecorded));
        a.record(&mut check);
        assert_eq!(compare(&check, &a), Ok(()));
        let mut changed = tiles.clone();
        changed[1][1000] += 1e-6;
        changed[2][5] = f32::NAN;
        let b = of_tiles(quads.iter().copied().zip(changed.iter().map(Vec::as_slice)));
        match compare(&check, &b) {
            Err(Mismatch::Differs { first_tile, differing, .. }) => {
                assert_eq!(first_tile.as_deref(), Some(quads[1].to_string().as_str()));
                assert_eq!(differing, 2);
            }
            other => panic!("{other:?}"),
        }
        // Every NaN hashes alike.
        let mut other_nan = changed.clone();
        other_nan[2][5] = f32::from_bits(0x7fc0_0001);
        let c = of_tiles(quads.iter().copied().zip(other_nan.iter().map(Vec::as_slice)));
        assert_eq!(b, c);
        assert_eq!(parse_quad(&quads[2].to_string()), Some(quads[2]));
    }
}
