//! How a project looks: colour map, isolines, lighting, level of detail, saved comparisons.

use std::collections::BTreeMap;
use std::path::PathBuf;

use serde::{Deserialize, Serialize};

use super::{MAX_CACHE_MIB, MAX_EDIT_TILES, MAX_LINE_WIDTH_PX, MAX_QUADS};
use crate::attributes::Attribute;
use crate::errors::Invalid;

/// The colour map: a preset or a user's ramp file, over a height range.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ColourMapSpec {
    /// A preset name (`terrafuse render --list-colour-maps` lists them), used unless `file` is set.
    #[serde(default = "default_preset")]
    pub preset: String,
    /// A gdaldem colour-relief file or a GMT `.cpt` (relative to the project file); its values are
    /// heights in metres.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub file: Option<PathBuf>,
    /// Heights the preset spans, metres; default: the datasets' height range.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range_m: Option<[f64; 2]>,
    /// Colour where there is no data, sRGB bytes with alpha.
    #[serde(default = "default_nodata_colour")]
    pub nodata_colour: [u8; 4],
    /// What the ramp colours: the height (default), or a terrain attribute of the surface as
    /// drawn (`range_m` is then in the attribute's unit).
    #[serde(default, skip_serializing_if = "ColourBy::is_height")]
    pub by: ColourBy,
}

/// What the colour ramp is a function of: the height, or a terrain attribute of the surface as
/// drawn, with the definitions of `export --attribute` ([`Attribute`], which knows each one's
/// range, unit and title). Written as the attribute's name, or `height`.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum ColourBy {
    /// The height, metres.
    #[default]
    Height,
    /// A terrain attribute of the true heights (whatever the exaggeration), per pixel: slope,
    /// aspect and hillshade from the data's normal, the others from the 3 × 3 windows there.
    Attribute(Attribute),
}

impl ColourBy {
    /// Every choice: the height, then the attributes in their order.
    pub fn all() -> impl Iterator<Item = ColourBy> {
        std::iter::once(ColourBy::Height).chain(Attribute::ALL.map(ColourBy::Attribute))
    }

    fn is_height(&self) -> bool {
        *self == ColourBy::Height
    }

    /// The attribute it colours; None for the height.
    pub fn attribute(self) -> Option<Attribute> {
        match self {
            ColourBy::Height => None,
            ColourBy::Attribute(a) => Some(a),
        }
    }

    /// Its name: the attribute's (as `export --attribute` spells it), or `height`.
    pub fn name(self) -> &'static str {
        self.attribute().map_or("height", Attribute::name)
    }

    /// The choice of a name; None for another.
    pub fn parse(name: &str) -> Option<ColourBy> {
        if name == "height" { Some(ColourBy::Height) } else { Attribute::parse(name).map(ColourBy::Attribute) }
    }

    /// The range the ramp spans by default: the data's heights, or the attribute's
    /// ([`Attribute::default_range`]).
    pub fn default_range(self, data_range_m: (f64, f64)) -> (f64, f64) {
        self.attribute().map_or(data_range_m, Attribute::default_range)
    }

    /// The unit of its values, short.
    pub fn unit(self) -> &'static str {
        self.attribute().map_or("m", Attribute::symbol)
    }

    /// The legend's title: what the ramp shows, with its unit.
    pub fn title(self) -> &'static str {
        self.attribute().map_or("elevation (m)", Attribute::title)
    }
}

impl Serialize for ColourBy {
    fn serialize<S: serde::Serializer>(&self, serializer: S) -> Result<S::Ok, S::Error> {
        serializer.serialize_str(self.name())
    }
}

impl<'de> Deserialize<'de> for ColourBy {
    fn deserialize<D: serde::Deserializer<'de>>(deserializer: D) -> Result<ColourBy, D::Error> {
        let name = String::deserialize(deserializer)?;
        ColourBy::parse(&name).ok_or_else(|| {
            let names: Vec<&str> = ColourBy::all().map(ColourBy::name).collect();
            serde::de::Error::custom(format!("unknown variant `{name}`, expected one of `{}`", names.join("`, `")))
        })
    }
}

impl schemars::JsonSchema for ColourBy {
    fn schema_name() -> std::borrow::Cow<'static, str> {
        "ColourBy".into()
    }

    fn json_schema(_: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let choices: Vec<serde_json::Value> = ColourBy::all()
            .map(|by| serde_json::json!({ "description": by.title(), "type": "string", "const": by.name() }))
            .collect();
        schemars::json_schema!({
            "description": "What the colour ramp is a function of: `height`, or a terrain attribute of the true heights (whatever the exaggeration), per pixel, as `export --attribute` defines it.",
            "oneOf": choices,
        })
    }
}

fn default_preset() -> String {
    "hypsometric".into()
}

fn default_nodata_colour() -> [u8; 4] {
    [96, 96, 104, 255]
}

impl Default for ColourMapSpec {
    fn default() -> ColourMapSpec {
        ColourMapSpec {
            preset: default_preset(),
            file: None,
            range_m: None,
            nodata_colour: default_nodata_colour(),
            by: ColourBy::Height,
        }
    }
}

/// Isolines (contour lines) computed per pixel from the elevation.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct IsolineSpec {
    /// Whether they are drawn.
    pub enabled: bool,
    /// Height between lines, metres.
    pub interval_m: f64,
    /// Heights of lines are offset + k·interval, metres.
    pub offset_m: f64,
    /// Every k-th line is a major line (0: none).
    pub major_every: u32,
    /// Width of a minor line, pixels.
    pub width_px: f32,
    /// Width of a major line, pixels.
    pub major_width_px: f32,
    /// Lines thinner than this are drawn this wide with proportionally less opacity, so that they
    /// neither alias nor vanish; pixels.
    pub min_width_px: f32,
    /// Line colour, sRGB bytes with alpha.
    pub colour: [u8; 4],
}

impl Default for IsolineSpec {
    fn default() -> IsolineSpec {
        IsolineSpec {
            enabled: false,
            interval_m: 100.0,
            offset_m: 0.0,
            major_every: 5,
            width_px: 1.0,
            major_width_px: 2.0,
            min_width_px: 1.0,
            colour: [20, 20, 20, 220],
        }
    }
}

/// Per-pixel lighting from the elevation gradient and the ellipsoid normal (a hillshade: the
/// sun's direction is given in each point's local east-north-up frame, as gdaldem does).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct LightingSpec {
    /// Whether the terrain is shaded.
    pub enabled: bool,
    /// Sun azimuth, degrees clockwise from north.
    pub sun_azimuth_deg: f64,
    /// Sun elevation above the horizon, degrees.
    pub sun_elevation_deg: f64,
    /// How much the shading darkens: 0 none, 1 full hillshade.
    pub strength: f64,
}

impl Default for LightingSpec {
    fn default() -> LightingSpec {
        LightingSpec { enabled: true, sun_azimuth_deg: 315.0, sun_elevation_deg: 45.0, strength: 0.7 }
    }
}

/// Everything about how the terrain looks.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct Visuals {
    /// Colour gradient.
    pub colour_map: ColourMapSpec,
    /// Isolines.
    pub isolines: IsolineSpec,
    /// Lighting.
    pub lighting: LightingSpec,
    /// Vertical exaggeration (1: true heights).
    pub exaggeration: f64,
    /// Sky colour behind the planet, sRGB bytes.
    pub background: [u8; 4],
}

impl Default for Visuals {
    fn default() -> Visuals {
        Visuals {
            colour_map: ColourMapSpec::default(),
            isolines: IsolineSpec::default(),
            lighting: LightingSpec::default(),
            exaggeration: 1.0,
            background: [0, 0, 0, 255],
        }
    }
}

/// Level-of-detail settings.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields, default)]
pub struct DetailSpec {
    /// Split a quad while a sample covers more than this many pixels (the paper's t): the data's
    /// level at each place, and a floor for the geometry, never drawn finer than that data.
    pub lod_threshold_px: f64,
    /// Draw each patch of the terrain's mesh as coarsely as keeps its geometric error (the
    /// largest vertical miss between the data under it and the mesh) under this many pixels on
    /// screen (τ). What the pixels show is read from the data whatever the mesh.
    #[serde(skip_serializing_if = "is_default_pixel_error")]
    pub max_pixel_error: f64,
    /// Most quads drawn in one frame.
    pub max_quads: usize,
    /// CPU cache budget, MiB.
    pub cpu_cache_mib: u64,
    /// GPU cache budget, MiB.
    pub gpu_cache_mib: u64,
    /// Most tiles (257² heights, 258 KiB each) one brush stroke or erosion run may write: a
    /// larger one is refused before it starts (`brush` and `erode` take `--max-tiles` to raise
    /// it once).
    pub max_edit_tiles: u64,
}

/// A level-of-detail threshold or pixel error given on a command line that is not a positive
/// number of pixels.
#[derive(Debug, thiserror::Error)]
#[error("{flag} {value} must be a positive number of pixels")]
pub struct BadDetailOverride {
    /// The flag, `--lod-threshold` or `--pixel-error`.
    pub flag: &'static str,
    /// What it was given.
    pub value: f64,
}

/// Checks `--lod-threshold` and `--pixel-error` where given (the command line and the window share
/// the rule).
pub fn check_detail_overrides(lod_threshold: Option<f64>, pixel_error: Option<f64>) -> Result<(), BadDetailOverride> {
    for (flag, value) in [("--lod-threshold", lod_threshold), ("--pixel-error", pixel_error)] {
        if let Some(value) = value
            && !(value.is_finite() && value > 0.0)
        {
            return Err(BadDetailOverride { flag, value });
        }
    }
    Ok(())
}

/// The default of [`DetailSpec::max_pixel_error`]: a pixel.
pub const DEFAULT_MAX_PIXEL_ERROR: f64 = 1.0;

fn is_default_pixel_error(v: &f64) -> bool {
    *v == DEFAULT_MAX_PIXEL_ERROR
}

/// The default of [`DetailSpec::max_edit_tiles`]: 2 048 tiles, about 530 MiB of heights.
pub const DEFAULT_MAX_EDIT_TILES: u64 = 2048;

impl Default for DetailSpec {
    fn default() -> DetailSpec {
        DetailSpec {
            lod_threshold_px: 1.5,
            max_pixel_error: DEFAULT_MAX_PIXEL_ERROR,
            max_quads: 128,
            cpu_cache_mib: 1024,
            gpu_cache_mib: 768,
            max_edit_tiles: DEFAULT_MAX_EDIT_TILES,
        }
    }
}

/// Saved comparison settings: swipes (`terrafuse render --swipe NAME`) and profile lines
/// (`terrafuse profile --line NAME`), by name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ComparisonSpec {
    /// Swipes by name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub swipes: BTreeMap<String, SwipeSpec>,
    /// Profile lines by name.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub profiles: BTreeMap<String, ProfileLine>,
}

impl ComparisonSpec {
    /// Whether nothing is saved.
    pub fn is_empty(&self) -> bool {
        self.swipes.is_empty() && self.profiles.is_empty()
    }
}

/// A swipe: layer `a` left of a vertical line, layer `b` right of it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct SwipeSpec {
    /// The layer left of the line.
    pub a: String,
    /// The layer right of the line.
    pub b: String,
    /// Where the line is, 0–1 of the width.
    #[serde(default = "half")]
    pub position: f64,
    /// The view to show it from (default: the project's default view).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub view: Option<String>,
}

fn half() -> f64 {
    0.5
}

/// A profile line: from and to, `[lat, lon]` in degrees.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct ProfileLine {
    /// Start, `[lat, lon]` degrees.
    pub from: [f64; 2],
    /// End, `[lat, lon]` degrees.
    pub to: [f64; 2],
}

impl Visuals {
    /// Refuses settings no frame can draw with, naming the field.
    pub(crate) fn check(&self) -> Result<(), Invalid> {
        let v = self;
        if !(v.exaggeration.is_finite() && v.exaggeration > 0.0) {
            return Err(format!("visuals.exaggeration {} must be a positive number", v.exaggeration).into());
        }
        let iso = &v.isolines;
        if !(iso.interval_m.is_finite() && iso.interval_m > 0.0) {
            return Err(format!("visuals.isolines.interval_m {} must be positive", iso.interval_m).into());
        }
        for (field, px) in
            [("width_px", iso.width_px), ("major_width_px", iso.major_width_px), ("min_width_px", iso.min_width_px)]
        {
            // An f32 read from a JSON number beyond 3.4·10³⁸ is infinite: refused here, or the
            // project would save as `null` and never load again.
            if !(0.0..=MAX_LINE_WIDTH_PX).contains(&px) {
                return Err(
                    format!("visuals.isolines.{field} {px} must lie within 0 … {MAX_LINE_WIDTH_PX} pixels").into()
                );
            }
        }
        let preset = &v.colour_map.preset;
        if v.colour_map.file.is_none() && !crate::colour::preset_names().iter().any(|n| n.eq_ignore_ascii_case(preset))
        {
            let close = crate::errors::closest(preset, crate::colour::preset_names())
                .map_or_else(String::new, |c| format!(" (did you mean '{c}'?)"));
            return Err(format!(
                "visuals.colour_map.preset: '{preset}' is not a colour map{close}; the presets are {} (terrafuse render --list-colour-maps)",
                crate::colour::preset_names().join(", ")
            )
            .into());
        }
        if let Some([lo, hi]) = v.colour_map.range_m
            && !(lo.is_finite() && hi.is_finite() && lo < hi)
        {
            return Err(format!("visuals.colour_map.range_m [{lo}, {hi}] must be increasing").into());
        }
        if !(v.lighting.strength >= 0.0 && v.lighting.strength <= 1.0) {
            return Err(format!("visuals.lighting.strength {} must lie in [0, 1]", v.lighting.strength).into());
        }
        Ok(())
    }
}

impl DetailSpec {
    /// Refuses detail settings out of their ranges, naming the field.
    pub(crate) fn check(&self) -> Result<(), Invalid> {
        let d = self;
        if !(d.lod_threshold_px.is_finite() && d.lod_threshold_px > 0.0) {
            return Err(format!("detail.lod_threshold_px {} must be positive", d.lod_threshold_px).into());
        }
        if !(d.max_pixel_error.is_finite() && d.max_pixel_error > 0.0) {
            return Err(
                format!("detail.max_pixel_error {} must be a positive number of pixels", d.max_pixel_error).into()
            );
        }
        if !(6..=MAX_QUADS).contains(&d.max_quads) {
            return Err(
                format!("detail.max_quads {} must lie within 6 (the cube's faces) … {MAX_QUADS}", d.max_quads).into()
            );
        }
        if !(1..=MAX_EDIT_TILES).contains(&d.max_edit_tiles) {
            return Err(
                format!("detail.max_edit_tiles {} must lie within 1 … {MAX_EDIT_TILES}", d.max_edit_tiles).into()
            );
        }
        for (field, mib) in [("cpu_cache_mib", d.cpu_cache_mib), ("gpu_cache_mib", d.gpu_cache_mib)] {
            if mib > MAX_CACHE_MIB {
                return Err(format!("detail.{field} {mib} must be at most {MAX_CACHE_MIB} (1 TiB)").into());
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_colour_but_the_height_is_the_attribute_of_its_name() {
        for by in ColourBy::all() {
            assert_eq!(by.attribute().map(Attribute::name), (by != ColourBy::Height).then(|| by.name()));
            // The project file spells it as the command line does, and reads it back.
            let text = serde_json::to_string(&by).unwrap();
            assert_eq!(text, format!("\"{}\"", by.name()));
            assert_eq!(serde_json::from_str::<ColourBy>(&text).unwrap(), by);
        }
        assert_eq!(ColourBy::Height.name(), "height");
        assert_eq!(Attribute::ALL.len() + 1, ColourBy::all().count());
        let wrong = serde_json::from_str::<ColourBy>("\"slpoe\"").unwrap_err().to_string();
        assert!(wrong.contains("unknown variant `slpoe`") && wrong.contains("`slope`"), "{wrong}");
    }
}
