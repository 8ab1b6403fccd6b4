//! A brush stroke as a project file holds it, and the falloff curves.
//!
//! ```json
//! { "tool": "raise", "radius_m": 500, "strength": 20, "falloff": "smooth", "spacing": 0.25,
//!   "level": 12, "path": [[39.5, 40.4], [39.52, 40.43]] }
//! ```
//!
//! Every dab of a stroke changes the edit layer's height delta δ at each sample within `radius_m`
//! of its centre, weighted by the falloff w = f(d / r) (d the chord from the dab's centre to the
//! sample in ECEF; on the ellipsoid's surface the geodesic is longer by d³/24R², 1.3·10⁻⁷ m for a
//! 500 m brush on Earth, so the two are the same brush):
//! - `raise`: δ ← δ + strength·w (metres per dab); `lower`: δ ← δ − strength·w;
//! - `noise`: δ ← δ + strength·w·n(P), n the gradient noise of `layers::noise` at the sample, of
//!   wavelength `radius_m` / 2 and the stroke's `seed` (values in about ±1);
//! - `restore`: δ ← δ·(1 − strength·w) (strength a fraction 0–1: fades the edit back to zero).
//!
//! `smooth`, `flatten` and `ramp` move δ towards the δ that brings the terrain to a target height
//! T(P): δ ← δ + strength·w·((T − B) − δ), B the terrain below the edit layer at the sample (see
//! [`super::terrain`] for exactly what they read: the stack below composed at the raster's
//! level, plus this layer's δ, both as they were before the stroke):
//! - `smooth`: T is the mean of H over 8 points on a ring of radius max(r/4, one sample spacing)
//!   around the sample;
//! - `flatten`: T is `height_m`, or H under the path's first point;
//! - `ramp`: T runs linearly from H under the path's first point to H under its last, by the
//!   sample's position along the chord between them (clamped beyond both).

use crate::errors::{AtField, FieldProblem};
use serde::{Deserialize, Serialize};

/// What a stroke does.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Tool {
    /// Adds height.
    Raise,
    /// Removes height.
    Lower,
    /// Moves heights towards their neighbourhood's mean (reads the terrain below).
    Smooth,
    /// Moves heights towards a height (reads the terrain below).
    Flatten,
    /// Moves heights towards the plane between two points (reads the terrain below).
    Ramp,
    /// Adds gradient noise.
    Noise,
    /// Fades the edit layer back to zero.
    Restore,
}

impl Tool {
    /// Every tool, in the order panels list them.
    pub const ALL: [Tool; 7] =
        [Tool::Raise, Tool::Lower, Tool::Smooth, Tool::Flatten, Tool::Ramp, Tool::Noise, Tool::Restore];

    /// The name used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            Tool::Raise => "raise",
            Tool::Lower => "lower",
            Tool::Smooth => "smooth",
            Tool::Flatten => "flatten",
            Tool::Ramp => "ramp",
            Tool::Noise => "noise",
            Tool::Restore => "restore",
        }
    }

    /// Whether `strength` is metres per dab (else a fraction 0–1 per dab).
    pub fn strength_in_metres(self) -> bool {
        matches!(self, Tool::Raise | Tool::Lower | Tool::Noise)
    }

    /// Whether the tool reads the terrain below the edit layer.
    pub fn reads_terrain(self) -> bool {
        matches!(self, Tool::Smooth | Tool::Flatten | Tool::Ramp)
    }
}

/// The brush's profile from its centre (t = 0) to its rim (t = 1); 0 beyond.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Falloff {
    /// f(t) = 1 − t²(3 − 2t) (smoothstep, flat at both ends).
    #[default]
    Smooth,
    /// f(t) = 1 − t.
    Linear,
    /// f(t) = √(1 − t²) (a hemisphere's profile).
    Spherical,
    /// f(t) = (1 − t)³ (a sharp tip).
    Tip,
}

impl Falloff {
    /// Every falloff, in the order panels list them.
    pub const ALL: [Falloff; 4] = [Falloff::Smooth, Falloff::Linear, Falloff::Spherical, Falloff::Tip];

    /// The name used in files.
    pub fn name(self) -> &'static str {
        match self {
            Falloff::Smooth => "smooth",
            Falloff::Linear => "linear",
            Falloff::Spherical => "spherical",
            Falloff::Tip => "tip",
        }
    }

    /// The weight at t = d / r (1 at the centre, 0 at and beyond the rim).
    pub fn weight(self, t: f64) -> f64 {
        if t.is_nan() || t >= 1.0 {
            return 0.0;
        }
        let t = t.max(0.0);
        match self {
            Falloff::Smooth => 1.0 - t * t * (3.0 - 2.0 * t),
            Falloff::Linear => 1.0 - t,
            Falloff::Spherical => (1.0 - t * t).sqrt(),
            Falloff::Tip => (1.0 - t) * (1.0 - t) * (1.0 - t),
        }
    }
}

/// One stroke.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Stroke {
    /// What it does.
    pub tool: Tool,
    /// Brush radius on the surface, metres.
    pub radius_m: f64,
    /// Metres per dab (raise, lower, noise) or a fraction 0–1 per dab (the others).
    pub strength: f64,
    /// The profile.
    #[serde(default)]
    pub falloff: Falloff,
    /// Distance between dabs along the path, as a fraction of the radius (dabs by arc length, so
    /// the result does not depend on how fast the pointer moved).
    #[serde(default = "default_spacing")]
    pub spacing: f64,
    /// The cube-map level it is rasterised at (the edit layer's tiles live at its finest).
    pub level: u8,
    /// The path: `[lat, lon]` degrees, at least one point.
    pub path: Vec<[f64; 2]>,
    /// Noise: its seed.
    #[serde(default)]
    pub seed: u32,
    /// Flatten: the height to flatten to, metres (absent: the height under the first dab).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub height_m: Option<f64>,
}

fn default_spacing() -> f64 {
    0.25
}

impl Stroke {
    /// An upper bound on the tiles the stroke writes when rasterised at `level` (an edit layer
    /// rasterises every stroke at the finest level of any of them), from its path's length L on
    /// the ellipsoid and its radius r (a tile's side s = 256 samples): (L/s + 2r/s + 2) ×
    /// (2r/s + 2), the tiles a band of width 2r along the path can meet. It costs one geodesic
    /// per path segment, so a stroke too large to make is refused before any of it is made.
    /// Errors name the path segment whose geodesic cannot be computed.
    pub fn footprint_tiles(&self, ellipsoid: &crate::geodesy::Ellipsoid, level: u8) -> Result<f64, crate::Invalid> {
        let side_m = crate::ecm::grid::spacing_m(ellipsoid, level) * f64::from(crate::ecm::grid::TILE);
        let mut length_m = 0.0;
        for (k, pair) in self.path.windows(2).enumerate() {
            let ([lat1, lon1], [lat2, lon2]) = (pair[0], pair[1]);
            let (l, ..) = crate::geodesy::geodesic::inverse(
                ellipsoid,
                lat1.to_radians(),
                lon1.to_radians(),
                lat2.to_radians(),
                lon2.to_radians(),
            )
            .at_field(format_args!("path segment {k}–{}", k + 1))?;
            length_m += l;
        }
        let across = 2.0 * self.radius_m / side_m + 2.0;
        Ok((length_m / side_m + across) * across)
    }
}

/// Most points a stroke's path may have.
pub const MAX_PATH_POINTS: usize = 100_000;
/// Most dabs one stroke may place.
pub const MAX_DABS: usize = 1_000_000;
/// The finest level a stroke may be rasterised at (the store's grid goes to 30).
pub const MAX_LEVEL: u8 = 24;

impl Stroke {
    /// Checks what serde cannot; `radius_m` is the body's semi-major axis.
    pub fn check(&self, body_radius_m: f64) -> Result<(), FieldProblem> {
        if !(self.radius_m.is_finite() && self.radius_m > 0.0 && self.radius_m <= body_radius_m) {
            return Err(FieldProblem::new(
                "radius_m",
                format!(
                    "{} must be a distance in metres within (0, {body_radius_m:.0}] (the body's radius)",
                    self.radius_m
                ),
            ));
        }
        let strength_ok = if self.tool.strength_in_metres() {
            self.strength.is_finite() && self.strength.abs() <= 1e5
        } else {
            (0.0..=1.0).contains(&self.strength)
        };
        if !strength_ok {
            let unit =
                if self.tool.strength_in_metres() { "metres per dab within ±100000" } else { "a fraction in [0, 1]" };
            return Err(FieldProblem::new(
                "strength",
                format!("{} must be {unit} for {}", self.strength, self.tool.name()),
            ));
        }
        if !(self.spacing.is_finite() && self.spacing >= 0.01 && self.spacing <= 10.0) {
            return Err(FieldProblem::new(
                "spacing",
                format!("{} must be a fraction of the radius within [0.01, 10]", self.spacing),
            ));
        }
        if self.level > MAX_LEVEL {
            return Err(FieldProblem::new("level", format!("{} must be at most {MAX_LEVEL}", self.level)));
        }
        if self.path.is_empty() || self.path.len() > MAX_PATH_POINTS {
            return Err(FieldProblem::new(
                "path",
                format!("{} points: a path has 1 to {MAX_PATH_POINTS}", self.path.len()),
            ));
        }
        for (k, [lat, lon]) in self.path.iter().enumerate() {
            if !(lat.is_finite() && lon.is_finite() && lat.abs() <= 90.0 && lon.abs() <= 180.0) {
                return Err(FieldProblem::new(
                    "path",
                    format!(
                        "point {k} [{lat}, {lon}] is not [lat, lon] in degrees (latitude within ±90, longitude within ±180)"
                    ),
                ));
            }
        }
        if let Some(h) = self.height_m
            && !h.is_finite()
        {
            return Err(FieldProblem::new("height_m", format!("{h} must be finite")));
        }
        if self.tool == Tool::Ramp && (self.path.len() < 2 || self.path.first() == self.path.last()) {
            return Err(FieldProblem::new(
                "path",
                "a ramp runs from the path's first point to its last: give two different points",
            ));
        }
        if self.height_m.is_some() && self.tool != Tool::Flatten {
            return Err(FieldProblem::new(
                "height_m",
                format!("is the flatten height; a {} stroke has none", self.tool.name()),
            ));
        }
        Ok(())
    }
}
