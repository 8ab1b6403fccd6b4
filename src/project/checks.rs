//! Expected digests: what a replay of the project must rebuild, bit for bit, so that a saved
//! project checks itself (`terrafuse replay --check`).
//!
//! A check names what is hashed and where:
//! - `{"layer": "sculpt"}` on an edit or erosion layer: the layer's own tiles of height change,
//!   every tile it holds, at its level;
//! - `{"layer": "srtm", "level": 9, "region": [w, s, e, n]}`: that layer composed alone over the
//!   region's quads at `level`;
//! - `{"level": 9, "view": "close"}` (no layer): the visible stack as drawn, over the 3 × 3 quads
//!   at `level` around the point the view looks at.
//!
//! The digest is FNV-1a (64 bits) over the tiles in quad order, each tile's id and its 257² f32
//! heights (every NaN counted as one pattern); `tiles` keeps each tile's own digest so that a
//! mismatch names the first tile that differs. `terrafuse replay --record` fills both in.

use std::collections::BTreeMap;

use serde::{Deserialize, Serialize};

use super::Invalid;

/// Most tiles one check may hash (each is 257² samples composed on the CPU).
pub const MAX_CHECK_TILES: usize = 256;

/// One expected digest.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CheckSpec {
    /// The layer hashed: an edit or erosion layer's own tiles (without `level`), or any layer
    /// composed alone at `level`; absent: the visible stack, as drawn.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layer: Option<String>,
    /// The quadtree level of the composed tiles (0–24); absent only for an edit or erosion
    /// layer's own tiles.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub level: Option<u8>,
    /// Where: `[west, south, east, north]`, degrees (east < west crosses ±180°).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub region: Option<[f64; 4]>,
    /// Or a named view: the 3 × 3 quads at `level` around the point its centre looks at.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<String>,
    /// The digest over every tile, 16 hex digits (absent: not recorded yet).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub digest: Option<String>,
    /// Each tile's digest by quad (`face/level/x/y`), 16 hex digits.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub tiles: BTreeMap<String, String>,
    /// What the check read when it was recorded, each a digest of 16 hex digits: `layers.NAME`
    /// (a layer's settings and operations: the layer checked and those below it, or every layer
    /// for the stack) and `views.NAME` (the view it is placed by). A mismatch names what changed
    /// since.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub inputs: BTreeMap<String, String>,
}

/// What a check hashes, once its fields are checked.
#[derive(Clone, Debug, PartialEq)]
pub enum CheckTarget<'a> {
    /// An edit or erosion layer's own tiles.
    LayerTiles(&'a str),
    /// A layer composed alone (`Some`) or the visible stack (`None`) over a region's quads.
    Region {
        /// The layer composed alone (None: the visible stack).
        layer: Option<&'a str>,
        /// The level.
        level: u8,
        /// `[west, south, east, north]`, degrees.
        region: [f64; 4],
    },
    /// The same around a view's target.
    View {
        /// The layer composed alone (None: the visible stack).
        layer: Option<&'a str>,
        /// The level.
        level: u8,
        /// The view's name.
        view: &'a str,
    },
}

impl CheckSpec {
    /// What the check hashes; the error names the field. `holds_deltas(name)` says whether a
    /// layer is an edit or erosion layer (None: no such layer).
    pub fn target(&self, holds_deltas: &dyn Fn(&str) -> Option<bool>) -> Result<CheckTarget<'_>, Invalid> {
        let layer = self.layer.as_deref();
        if let Some(name) = layer
            && holds_deltas(name).is_none()
        {
            return Err(format!("layer: '{name}' is not a layer of the project").into());
        }
        if let Some(d) = &self.digest {
            check_hex("digest", d)?;
        }
        if self.tiles.len() > MAX_CHECK_TILES {
            return Err(format!("tiles: {} tiles; a check hashes at most {MAX_CHECK_TILES}", self.tiles.len()).into());
        }
        for (quad, d) in &self.tiles {
            check_hex(&format!("tiles.{quad}"), d)?;
        }
        for (input, d) in &self.inputs {
            check_hex(&format!("inputs.{input}"), d)?;
        }
        match (self.level, self.region, self.view.as_deref()) {
            (None, None, None) => match layer {
                Some(name) if holds_deltas(name) == Some(true) => Ok(CheckTarget::LayerTiles(name)),
                Some(name) => Err(format!(
                    "level: layer '{name}' holds no tiles of its own (not an edit or erosion layer): give a level and a region or view"
                ).into()),
                None => Err("level: a check of the stack needs a level and a region or a view".into()),
            },
            (None, _, _) => Err("level: a region or a view is composed at a level: give one".into()),
            (Some(level), region, view) => {
                if level > crate::edit::stroke::MAX_LEVEL {
                    return Err(format!("level: {level} must be at most {}", crate::edit::stroke::MAX_LEVEL).into());
                }
                match (region, view) {
                    (Some(region), None) => {
                        check_region(region)?;
                        Ok(CheckTarget::Region { layer, level, region })
                    }
                    (None, Some(view)) => Ok(CheckTarget::View { layer, level, view }),
                    (Some(_), Some(_)) => Err("region: give a region or a view, not both".into()),
                    (None, None) => Err("region: a check at a level needs a region or a view".into()),
                }
            }
        }
    }
}

/// What check `check` of `project` reads, by input (`layers.NAME`, `views.NAME`): a digest of
/// each one's JSON. A check of a layer reads it and the layers below it (strokes and runs read
/// the terrain below); a check of the stack reads every layer.
pub fn inputs(project: &super::Project, check: &CheckSpec) -> BTreeMap<String, String> {
    let top = match &check.layer {
        Some(name) => project.layers.iter().position(|l| &l.name == name).map_or(0, |k| k + 1),
        None => project.layers.len(),
    };
    let mut out: BTreeMap<String, String> =
        project.layers[..top].iter().map(|l| (format!("layers.{}", l.name), digest_of(l))).collect();
    if let Some(view) = check.view.as_ref().and_then(|v| project.views.get_key_value(v)) {
        out.insert(format!("views.{}", view.0), digest_of(view.1));
    }
    out
}

/// What changed between the inputs a check was recorded with and `now`'s, in words (`layer
/// 'sculpt' changed`, `layer 'x' is new`, `view 'v' changed`); empty when nothing did.
pub fn changed_inputs(recorded: &BTreeMap<String, String>, now: &BTreeMap<String, String>) -> Vec<String> {
    let words = |key: &str| match key.split_once('.') {
        Some(("layers", name)) => format!("layer '{name}'"),
        Some(("views", name)) => format!("view '{name}'"),
        _ => key.to_string(),
    };
    let mut out = Vec::new();
    for (key, d) in recorded {
        match now.get(key) {
            Some(n) if n == d => {}
            Some(_) => out.push(format!("{} changed", words(key))),
            None => out.push(format!("{} is gone", words(key))),
        }
    }
    out.extend(now.keys().filter(|k| !recorded.contains_key(*k)).map(|k| format!("{} is new", words(k))));
    out
}

/// A value's digest: FNV-1a over its JSON, 16 hex digits.
fn digest_of<T: serde::Serialize>(value: &T) -> String {
    let json = serde_json::to_string(value).unwrap_or_default();
    format!("{:016x}", crate::edit::cache::Digest::default().with(json.as_bytes()).value())
}

fn check_hex(field: &str, text: &str) -> Result<(), Invalid> {
    if text.len() == 16 && text.bytes().all(|b| b.is_ascii_hexdigit()) {
        Ok(())
    } else {
        Err(format!("{field}: '{text}' is not a digest of 16 hex digits").into())
    }
}

/// A `[west, south, east, north]` box in degrees ([`crate::geodesy::GeoBox`]'s rules).
pub fn check_region([w, s, e, n]: [f64; 4]) -> Result<(), Invalid> {
    crate::geodesy::GeoBox::new(w, s, e, n).map(|_| ()).map_err(|e| Invalid(format!("region: {e}")))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn kinds(name: &str) -> Option<bool> {
        match name {
            "sculpt" => Some(true),
            "srtm" => Some(false),
            _ => None,
        }
    }

    #[test]
    fn each_form_names_its_target_and_bad_ones_the_field() {
        let layer = CheckSpec { layer: Some("sculpt".into()), ..Default::default() };
        assert_eq!(layer.target(&kinds).unwrap(), CheckTarget::LayerTiles("sculpt"));
        let region = CheckSpec { level: Some(9), region: Some([40.0, 39.0, 41.0, 40.0]), ..Default::default() };
        assert!(matches!(region.target(&kinds).unwrap(), CheckTarget::Region { layer: None, level: 9, .. }));
        let cases = [
            (CheckSpec { layer: Some("x".into()), ..Default::default() }, "layer: 'x' is not a layer"),
            (CheckSpec { layer: Some("srtm".into()), ..Default::default() }, "holds no tiles of its own"),
            (CheckSpec::default(), "needs a level"),
            (CheckSpec { level: Some(30), view: Some("v".into()), ..Default::default() }, "level: 30"),
            (CheckSpec { level: Some(3), ..Default::default() }, "needs a region or a view"),
            (CheckSpec { level: Some(3), region: Some([0.0, 5.0, 1.0, 4.0]), ..Default::default() }, "south 5"),
            (CheckSpec { digest: Some("12".into()), ..layer.clone() }, "digest: '12'"),
        ];
        for (check, expected) in cases {
            let e = check.target(&kinds).unwrap_err();
            assert!(e.to_string().contains(expected), "{check:?}: {e}");
        }
    }
}
