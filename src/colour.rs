//! Colour ramps for elevation: presets (perceptually uniform and hypsometric), gdaldem
//! colour-relief files and GMT `.cpt` palettes, and the CPU reference of the fragment stage's
//! colour lookup.
//!
//! A ramp is a list of stops (height, sRGB colour) in non-decreasing height order; between two
//! stops the colour is interpolated linearly in sRGB bytes (as gdaldem and GMT do); two stops at
//! the same height make a step (GMT slices). Below the first stop the `below` colour is used,
//! above the last the `above` colour (the end colours unless a `.cpt` says B or F), and NaN gets
//! the no-data colour.

use std::path::{Path, PathBuf};

/// A colour map that could not be made.
#[derive(Debug, thiserror::Error)]
pub enum ColourError {
    /// A preset name that is not one of [`preset_names`].
    #[error("unknown colour map '{name}'; the presets are {}", preset_names().join(", "))]
    UnknownPreset {
        /// The name that was given.
        name: String,
    },
    /// A colour file that could not be read.
    #[error("{}: cannot read", path.display())]
    Read {
        /// The file.
        path: PathBuf,
        /// Why.
        #[source]
        source: std::io::Error,
    },
    /// A colour file whose text is not a ramp.
    #[error("{}: {problem}", path.display())]
    File {
        /// The file.
        path: PathBuf,
        /// The line and what is wrong with it.
        problem: Problem,
    },
}

/// What is wrong in a colour file's text: the line (1-based; none for the whole file) and the
/// problem in words.
#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// The line, from 1.
    pub line: Option<usize>,
    /// The problem.
    pub what: String,
}

impl std::fmt::Display for Problem {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.line {
            Some(line) => write!(f, "line {line}: {}", self.what),
            None => f.write_str(&self.what),
        }
    }
}

impl From<String> for Problem {
    fn from(what: String) -> Problem {
        Problem { line: None, what }
    }
}

impl From<&str> for Problem {
    fn from(what: &str) -> Problem {
        Problem { line: None, what: what.into() }
    }
}

/// The names of the presets.
pub fn preset_names() -> Vec<&'static str> {
    PRESETS.iter().map(|p| p.0).collect()
}

/// One stop of a ramp.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Stop {
    /// Height, metres.
    pub value_m: f64,
    /// sRGB colour and alpha, 0–255.
    pub rgba: [u8; 4],
}

/// A colour ramp over heights.
#[derive(Clone, Debug, PartialEq)]
pub struct Ramp {
    /// The stops, heights non-decreasing; at least one.
    pub stops: Vec<Stop>,
    /// Colour below the first stop.
    pub below: [u8; 4],
    /// Colour above the last stop.
    pub above: [u8; 4],
    /// Colour where there is no data.
    pub nodata: [u8; 4],
}

/// A preset: name, what it is, stops (fraction of the height range, sRGB colour).
pub type Preset = (&'static str, &'static str, &'static [(f64, [u8; 3])]);

/// The presets.
pub const PRESETS: &[Preset] = &[
    (
        "hypsometric",
        "classic hypsometric tints: lowland green, yellow, tan, brown, grey rock, snow",
        &[
            (0.00, [38, 115, 77]),
            (0.15, [104, 160, 90]),
            (0.30, [182, 204, 120]),
            (0.45, [236, 226, 152]),
            (0.60, [214, 176, 110]),
            (0.75, [160, 112, 68]),
            (0.90, [176, 168, 160]),
            (1.00, [255, 255, 255]),
        ],
    ),
    (
        "viridis",
        "perceptually uniform (matplotlib's viridis, 9 stops, linear between them)",
        &[
            (0.000, [68, 1, 84]),
            (0.125, [72, 40, 120]),
            (0.250, [62, 73, 137]),
            (0.375, [49, 104, 142]),
            (0.500, [38, 130, 142]),
            (0.625, [31, 158, 137]),
            (0.750, [53, 183, 121]),
            (0.875, [110, 206, 88]),
            (1.000, [253, 231, 37]),
        ],
    ),
    (
        "cividis",
        "perceptually uniform and colour-vision-deficiency friendly (cividis, 5 stops)",
        &[
            (0.00, [0, 34, 78]),
            (0.25, [65, 77, 107]),
            (0.50, [124, 123, 120]),
            (0.75, [188, 175, 111]),
            (1.00, [254, 232, 56]),
        ],
    ),
    ("grey", "linear grey, black to white", &[(0.0, [0, 0, 0]), (1.0, [255, 255, 255])]),
    (
        "lunar",
        "muted regolith browns to pale grey, for airless bodies",
        &[(0.0, [46, 40, 38]), (0.35, [110, 98, 88]), (0.7, [170, 162, 150]), (1.0, [236, 234, 228])],
    ),
];

impl Ramp {
    /// A preset spread over `range_m`.
    pub fn preset(name: &str, range_m: (f64, f64), nodata: [u8; 4]) -> Result<Ramp, ColourError> {
        let (_, _, stops) = PRESETS
            .iter()
            .find(|(n, _, _)| n.eq_ignore_ascii_case(name))
            .ok_or_else(|| ColourError::UnknownPreset { name: name.into() })?;
        let (lo, hi) = range_m;
        let stops: Vec<Stop> =
            stops.iter().map(|&(f, [r, g, b])| Stop { value_m: lo + f * (hi - lo), rgba: [r, g, b, 255] }).collect();
        Ok(Ramp::from_stops(stops, nodata))
    }

    /// A ramp from stops; the end colours hold beyond them.
    pub fn from_stops(stops: Vec<Stop>, nodata: [u8; 4]) -> Ramp {
        let below = stops.first().map_or([0; 4], |s| s.rgba);
        let above = stops.last().map_or([0; 4], |s| s.rgba);
        Ramp { stops, below, above, nodata }
    }

    /// Reads a gdaldem colour-relief file or a GMT `.cpt` (by extension, or by content when a
    /// line has 8 columns); `range_m` resolves gdaldem's percentages.
    pub fn from_file(path: &Path, range_m: (f64, f64), nodata: [u8; 4]) -> Result<Ramp, ColourError> {
        let text = std::fs::read_to_string(path).map_err(|source| ColourError::Read { path: path.into(), source })?;
        let cpt = path.extension().is_some_and(|e| e.eq_ignore_ascii_case("cpt"));
        let ramp = if cpt { parse_cpt(&text, nodata) } else { parse_gdaldem(&text, range_m, nodata) };
        ramp.map_err(|problem| ColourError::File { path: path.into(), problem })
    }

    /// The colour at height `h` (sRGB, 0–255 as reals, before rounding): the CPU reference of
    /// the shader's lookup.
    pub fn colour_at(&self, h: f64) -> [f64; 4] {
        let f = |c: [u8; 4]| c.map(f64::from);
        if h.is_nan() {
            return f(self.nodata);
        }
        let first = self.stops[0];
        let last = self.stops[self.stops.len() - 1];
        if h < first.value_m {
            return f(self.below);
        }
        if h > last.value_m {
            return f(self.above);
        }
        // The last stop at or below h; a step (equal heights) takes the upper slice.
        let k = self.stops.partition_point(|s| s.value_m <= h).saturating_sub(1);
        if k + 1 >= self.stops.len() {
            return f(last.rgba);
        }
        let (a, b) = (self.stops[k], self.stops[k + 1]);
        let w = if b.value_m > a.value_m { (h - a.value_m) / (b.value_m - a.value_m) } else { 0.0 };
        std::array::from_fn(|c| f64::from(a.rgba[c]) + (f64::from(b.rgba[c]) - f64::from(a.rgba[c])) * w)
    }

    /// The height range the stops span.
    pub fn range_m(&self) -> (f64, f64) {
        (self.stops[0].value_m, self.stops[self.stops.len() - 1].value_m)
    }
}

fn named_colour(name: &str) -> Option<[u8; 4]> {
    let c = match name.to_ascii_lowercase().as_str() {
        "white" => [255, 255, 255],
        "black" => [0, 0, 0],
        "red" => [255, 0, 0],
        "green" => [0, 255, 0],
        "blue" => [0, 0, 255],
        "yellow" => [255, 255, 0],
        "magenta" => [255, 0, 255],
        "cyan" | "aqua" => [0, 255, 255],
        "grey" | "gray" => [190, 190, 190],
        "orange" => [255, 165, 0],
        "brown" => [165, 42, 42],
        "purple" => [160, 32, 240],
        _ => return None,
    };
    Some([c[0], c[1], c[2], 255])
}

fn byte(text: &str, what: &str) -> Result<u8, Problem> {
    let v: f64 = text.trim().parse().map_err(|_| Problem::from(format!("{what} '{text}' is not a number")))?;
    if !(0.0..=255.0).contains(&v) {
        return Err(format!("{what} {v} is outside 0–255").into());
    }
    Ok(v.round() as u8)
}

/// gdaldem colour-relief text: `value R G B [A]` per line (separators: space, tab, comma, colon),
/// `value` a height, `P%` of the range, or `nv` for no data; or `value name` with a colour name.
fn parse_gdaldem(text: &str, range_m: (f64, f64), nodata: [u8; 4]) -> Result<Ramp, Problem> {
    let mut stops = Vec::new();
    let mut nodata = nodata;
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        if line.is_empty() || line.starts_with('#') {
            continue;
        }
        let at = |e: Problem| Problem { line: Some(number + 1), what: e.what };
        let fields: Vec<&str> =
            line.split(|c: char| c.is_whitespace() || c == ',' || c == ':').filter(|f| !f.is_empty()).collect();
        let rgba = match fields.len() {
            2 => named_colour(fields[1]).ok_or_else(|| at(format!("unknown colour name '{}'", fields[1]).into()))?,
            4 | 5 => {
                let mut c = [255u8; 4];
                for (k, f) in fields[1..].iter().enumerate() {
                    c[k] = byte(f, ["red", "green", "blue", "alpha"][k]).map_err(at)?;
                }
                c
            }
            n => return Err(at(format!("expected 'value R G B [A]', found {n} fields").into())),
        };
        let value = fields[0];
        if value.eq_ignore_ascii_case("nv") {
            nodata = rgba;
            continue;
        }
        let value_m = if let Some(p) = value.strip_suffix('%') {
            let p: f64 = p.parse().map_err(|_| at(format!("'{value}' is not a percentage").into()))?;
            range_m.0 + p / 100.0 * (range_m.1 - range_m.0)
        } else {
            value.parse::<f64>().map_err(|_| at(format!("'{value}' is not a height").into()))?
        };
        stops.push(Stop { value_m, rgba });
    }
    finish(stops, nodata)
}

fn finish(mut stops: Vec<Stop>, nodata: [u8; 4]) -> Result<Ramp, Problem> {
    if stops.is_empty() {
        return Err("no colour entries".into());
    }
    if stops.iter().any(|s| !s.value_m.is_finite()) {
        return Err("a colour entry's height is not finite".into());
    }
    // gdaldem sorts its entries; keep equal heights in file order (steps).
    stops.sort_by(|a, b| a.value_m.total_cmp(&b.value_m));
    Ok(Ramp::from_stops(stops, nodata))
}

/// A GMT colour: `r g b` (three fields), `r/g/b`, `#rrggbb`, a name, or a grey level.
fn cpt_colour(fields: &[&str]) -> Result<[u8; 4], Problem> {
    match fields {
        [r, g, b] => Ok([byte(r, "red")?, byte(g, "green")?, byte(b, "blue")?, 255]),
        [one] if one.contains('/') => {
            let parts: Vec<&str> = one.split('/').collect();
            if parts.len() != 3 {
                return Err(format!("colour '{one}' is not r/g/b").into());
            }
            cpt_colour(&parts)
        }
        [one] if one.starts_with('#') && one.len() == 7 => {
            let h = |k: usize| {
                u8::from_str_radix(&one[k..k + 2], 16)
                    .map_err(|_| Problem::from(format!("colour '{one}' is not #rrggbb")))
            };
            Ok([h(1)?, h(3)?, h(5)?, 255])
        }
        [one] if one.contains('-') && !one.starts_with('-') => {
            Err(format!("colour '{one}' is HSV (h-s-v); convert the palette to RGB with gmt makecpt -M").into())
        }
        [one] => match one.parse::<f64>() {
            Ok(_) => {
                let g = byte(one, "grey")?;
                Ok([g, g, g, 255])
            }
            Err(_) => named_colour(one).ok_or_else(|| format!("unknown colour '{one}'").into()),
        },
        _ => Err(format!("cannot read a colour from '{}'", fields.join(" ")).into()),
    }
}

/// GMT `.cpt`: slices `z0 colour0 z1 colour1 [L|U|B]`, and `B`, `F`, `N` lines for the colours
/// below, above and at no data. RGB only (an HSV palette is refused with how to convert it).
fn parse_cpt(text: &str, nodata: [u8; 4]) -> Result<Ramp, Problem> {
    let mut stops = Vec::new();
    let (mut below, mut above, mut nodata) = (None, None, nodata);
    for (number, line) in text.lines().enumerate() {
        let line = line.trim();
        let at = |e: Problem| Problem { line: Some(number + 1), what: e.what };
        if let Some(comment) = line.strip_prefix('#') {
            if comment.replace(' ', "").eq_ignore_ascii_case("COLOR_MODEL=HSV") {
                return Err(at("the palette is HSV; convert it to RGB (gmt makecpt -M -Fr)".into()));
            }
            continue;
        }
        if line.is_empty() {
            continue;
        }
        let fields: Vec<&str> = line.split_whitespace().collect();
        match fields[0] {
            "B" | "F" | "N" => {
                let c = cpt_colour(&fields[1..]).map_err(at)?;
                match fields[0] {
                    "B" => below = Some(c),
                    "F" => above = Some(c),
                    _ => nodata = c,
                }
                continue;
            }
            _ => {}
        }
        // Drop a trailing annotation flag and a ;label.
        let fields: Vec<&str> = fields.iter().take_while(|f| !f.starts_with(';')).copied().collect();
        let fields: &[&str] = match fields.last() {
            Some(&"L" | &"U" | &"B") => &fields[..fields.len() - 1],
            _ => &fields,
        };
        let (z0, c0, z1, c1) = match fields.len() {
            4 => (fields[0], &fields[1..2], fields[2], &fields[3..4]),
            8 => (fields[0], &fields[1..4], fields[4], &fields[5..8]),
            n => return Err(at(format!("expected 'z0 colour z1 colour', found {n} fields").into())),
        };
        let z = |t: &str| t.parse::<f64>().map_err(|_| at(format!("'{t}' is not a height").into()));
        let (z0, z1) = (z(z0)?, z(z1)?);
        if z1 < z0 {
            return Err(at(format!("slice {z0} to {z1} runs backwards").into()));
        }
        stops.push(Stop { value_m: z0, rgba: cpt_colour(c0).map_err(at)? });
        stops.push(Stop { value_m: z1, rgba: cpt_colour(c1).map_err(at)? });
    }
    if stops.windows(2).any(|w| w[1].value_m < w[0].value_m) {
        return Err("slices are not in increasing order".into());
    }
    let mut ramp = finish(stops, nodata)?;
    ramp.below = below.unwrap_or(ramp.below);
    ramp.above = above.unwrap_or(ramp.above);
    Ok(ramp)
}

/// sRGB byte value (0–255) to linear light (0–1), the standard transfer function.
pub fn srgb_to_linear(c: f64) -> f64 {
    let c = c / 255.0;
    if c <= 0.04045 { c / 12.92 } else { ((c + 0.055) / 1.055).powf(2.4) }
}

/// Linear light (0–1) to sRGB (0–1).
pub fn linear_to_srgb(c: f64) -> f64 {
    let c = c.clamp(0.0, 1.0);
    if c <= 0.003_130_8 { c * 12.92 } else { 1.055 * c.powf(1.0 / 2.4) - 0.055 }
}

/// ColorBrewer's RdBu, 11 classes, red to blue (sRGB): the diverging map difference layers draw
/// dh with, as xDEM plots it (A below B red, above blue, equal white). The terrain shader's
/// `DIVERGING` holds the same stops.
pub const DIVERGING: [[u8; 3]; 11] = [
    [0x67, 0x00, 0x1f],
    [0xb2, 0x18, 0x2b],
    [0xd6, 0x60, 0x4d],
    [0xf4, 0xa5, 0x82],
    [0xfd, 0xdb, 0xc7],
    [0xf7, 0xf7, 0xf7],
    [0xd1, 0xe5, 0xf0],
    [0x92, 0xc5, 0xde],
    [0x43, 0x93, 0xc3],
    [0x21, 0x66, 0xac],
    [0x05, 0x30, 0x61],
];

/// The diverging map's sRGB colour (0–1) at t = dh / range, clamped to [−1, 1], linear in sRGB
/// between the stops. CPU reference of `diverging_colour` in `shaders/shared/shading.wgsl`.
pub fn diverging(t: f64) -> [f64; 3] {
    let x = (t.clamp(-1.0, 1.0) + 1.0) * 5.0;
    let k = (x.floor() as usize).min(9);
    let w = x - k as f64;
    let (a, b) = (DIVERGING[k], DIVERGING[k + 1]);
    [0, 1, 2].map(|c| (f64::from(a[c]) + w * (f64::from(b[c]) - f64::from(a[c]))) / 255.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_span_the_range_and_interpolate_linearly() {
        let r = Ramp::preset("grey", (100.0, 300.0), [1, 2, 3, 4]).unwrap();
        assert_eq!(r.colour_at(200.0), [127.5, 127.5, 127.5, 255.0]);
        assert_eq!(r.colour_at(-5.0)[0], 0.0);
        assert_eq!(r.colour_at(1e9)[0], 255.0);
        assert_eq!(r.colour_at(f64::NAN), [1.0, 2.0, 3.0, 4.0]);
        for (name, _, stops) in PRESETS {
            let r = Ramp::preset(name, (0.0, 1.0), [0; 4]).unwrap();
            assert_eq!(r.stops.len(), stops.len());
            assert!(stops.windows(2).all(|w| w[0].0 < w[1].0), "{name}");
        }
        assert!(Ramp::preset("jet", (0.0, 1.0), [0; 4]).unwrap_err().to_string().contains("hypsometric"));
    }

    #[test]
    fn gdaldem_files_parse_with_percentages_names_and_nodata() {
        let text = "# elevation colours\n0 0 0 255\n50% 0,255,0\n100%:255:255:255:128\nnv 1 2 3 0\n2000 white\n";
        let r = parse_gdaldem(text, (0.0, 1000.0), [9; 4]).unwrap();
        let values: Vec<f64> = r.stops.iter().map(|s| s.value_m).collect();
        assert_eq!(values, [0.0, 500.0, 1000.0, 2000.0]);
        assert_eq!(r.nodata, [1, 2, 3, 0]);
        assert_eq!(r.colour_at(250.0), [0.0, 127.5, 127.5, 255.0]);
        assert_eq!(r.colour_at(1500.0)[3], 191.5);
        for (bad, expected) in [
            ("0 0 0\n", "line 1: expected 'value R G B [A]', found 3"),
            ("x 0 0 0\n", "line 1: 'x' is not a height"),
            ("0 0 0 300\n", "blue 300 is outside"),
            ("0 chartreuse\n", "unknown colour name"),
            ("# nothing\n", "no colour entries"),
        ] {
            let e = parse_gdaldem(bad, (0.0, 1.0), [0; 4]).unwrap_err();
            assert!(e.to_string().contains(expected), "{bad:?}: {e}");
        }
    }

    #[test]
    fn cpt_slices_make_steps_and_b_f_n_colours() {
        let text = "# COLOR_MODEL = RGB\n-100 0 0 255 0 0 255 255\n0 0/128/0 500 255/255/0 L\n500 #ff0000 1000 red\n\
                    B black\nF white\nN 128\n";
        let r = parse_cpt(text, [0; 4]).unwrap();
        assert_eq!(r.colour_at(-50.0), [0.0, 127.5, 255.0, 255.0]);
        // The slice boundary at 0 is a step: 0 belongs to the upper slice.
        assert_eq!(r.colour_at(0.0), [0.0, 128.0, 0.0, 255.0]);
        assert_eq!(r.colour_at(-1e-9)[2], 255.0);
        assert_eq!(r.colour_at(-200.0), [0.0, 0.0, 0.0, 255.0]);
        assert_eq!(r.colour_at(2000.0), [255.0; 4]);
        assert_eq!(r.nodata, [128, 128, 128, 255]);
        assert!(parse_cpt("# COLOR_MODEL = HSV\n0 0-1-1 1 0-1-1\n", [0; 4]).unwrap_err().to_string().contains("HSV"));
        assert!(parse_cpt("0 1 2\n", [0; 4]).unwrap_err().to_string().contains("line 1"));
        assert!(parse_cpt("5 red 1 blue\n", [0; 4]).unwrap_err().to_string().contains("backwards"));
    }

    #[test]
    fn srgb_transfer_round_trips() {
        for b in 0..=255 {
            let back = linear_to_srgb(srgb_to_linear(f64::from(b))) * 255.0;
            assert!((back - f64::from(b)).abs() < 1e-9, "{b}: {back}");
        }
    }
}
