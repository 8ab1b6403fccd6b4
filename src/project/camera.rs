//! A camera in geodetic terms: a named view of a project, or `--camera` on the command line.

use serde::{Deserialize, Serialize};

use super::Invalid;

/// A camera in geodetic terms, all f64: where it is and where it looks.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct CameraSpec {
    /// Geodetic latitude, degrees.
    pub lat: f64,
    /// Longitude, degrees east.
    pub lon: f64,
    /// Height above the ellipsoid, metres.
    pub alt: f64,
    /// Heading, degrees clockwise from north.
    #[serde(default)]
    pub heading: f64,
    /// Pitch, degrees: −90 looks straight down, 0 at the horizon.
    #[serde(default = "default_pitch")]
    pub pitch: f64,
    /// Vertical field of view, degrees.
    #[serde(default = "default_fov")]
    pub fov: f64,
}

fn default_pitch() -> f64 {
    -90.0
}

fn default_fov() -> f64 {
    45.0
}

impl CameraSpec {
    /// Parses `lat,lon,alt,heading,pitch[,fov]` (degrees and metres).
    pub fn parse(text: &str) -> Result<CameraSpec, Invalid> {
        let values: Vec<f64> = text
            .split(',')
            .map(|v| v.trim().parse::<f64>().map_err(|_| Invalid(format!("'{}' is not a number", v.trim()))))
            .collect::<Result<_, _>>()?;
        if !(5..=6).contains(&values.len()) {
            return Err(format!("a camera is lat,lon,alt,heading,pitch[,fov]; got {} values", values.len()).into());
        }
        let camera = CameraSpec {
            lat: values[0],
            lon: values[1],
            alt: values[2],
            heading: values[3],
            pitch: values[4],
            fov: values.get(5).copied().unwrap_or_else(default_fov),
        };
        camera.check()?;
        Ok(camera)
    }

    /// Checks the ranges: latitude within ±90°, longitude within ±180°, pitch within [−90°, 90°], field of view in
    /// (0°, 170°), everything finite.
    pub fn check(&self) -> Result<(), Invalid> {
        let all = [self.lat, self.lon, self.alt, self.heading, self.pitch, self.fov];
        if all.iter().any(|v| !v.is_finite()) {
            return Err("camera values must be finite numbers".into());
        }
        if self.lat.abs() > 90.0 {
            return Err(format!("camera latitude {} is outside [-90, 90]", self.lat).into());
        }
        if self.lon.abs() > 180.0 {
            return Err(format!("camera longitude {} is outside [-180, 180] (as boxes are)", self.lon).into());
        }
        if self.pitch.abs() > 90.0 {
            return Err(format!("camera pitch {} is outside [-90, 90] (-90 looks straight down)", self.pitch).into());
        }
        if !(self.fov > 0.0 && self.fov < 170.0) {
            return Err(format!("camera field of view {} must lie between 0 and 170 degrees", self.fov).into());
        }
        Ok(())
    }
}
