//! Elevation profiles: every visible layer (each composed alone, as `compare` composes it) and the
//! composed stack, sampled along the geodesic between two points on the ellipsoid at one level.

use glam::DVec3;
use serde::Serialize;

use super::CompareError;
use super::mosaic::{Interpolation, Mosaic};
use super::sample::operand_scene;
use crate::ecm::grid::spacing_m;
use crate::geodesy::geodesic::{direct, inverse};
use crate::geodesy::{Geodetic, ecef_from_geodetic};
use crate::layers::Operand;
use crate::project::Project;
use crate::scene::Scene;

/// Most samples along a profile.
pub const MAX_SAMPLES: usize = 100_000;

/// Where and how finely to sample.
#[derive(Clone, Debug)]
pub struct ProfileOptions {
    /// Start: latitude, longitude, degrees.
    pub from: [f64; 2],
    /// End: latitude, longitude, degrees.
    pub to: [f64; 2],
    /// Samples along the line (default: one per sample spacing of the level).
    pub samples: Option<usize>,
    /// The level (default: the finest level at which a shown layer adds detail).
    pub level: Option<u8>,
}

/// A profile (field names are the CSV's columns and the JSON's).
#[derive(Clone, Debug, Serialize)]
pub struct Profile {
    /// The level sampled.
    pub level: u8,
    /// The geodesic's length, metres.
    pub length_m: f64,
    /// Distance of each sample from the start, metres.
    pub distance_m: Vec<f64>,
    /// Latitude of each sample, degrees.
    pub lat_deg: Vec<f64>,
    /// Longitude of each sample, degrees.
    pub lon_deg: Vec<f64>,
    /// Each visible layer alone: its name and heights (NaN: no data).
    pub layers: Vec<(String, Vec<f64>)>,
    /// The composed stack, as drawn.
    pub composed: Vec<f64>,
}

impl Profile {
    /// The profile as CSV: distance_m, lat_deg, lon_deg, one column per layer, composed.
    pub fn csv(&self) -> String {
        let mut out = String::from("distance_m,lat_deg,lon_deg");
        for (name, _) in &self.layers {
            out.push(',');
            out.push_str(name);
        }
        out.push_str(",composed\n");
        for k in 0..self.distance_m.len() {
            out.push_str(&format!("{:.3},{:.8},{:.8}", self.distance_m[k], self.lat_deg[k], self.lon_deg[k]));
            for (_, h) in &self.layers {
                out.push_str(&format!(",{}", h[k]));
            }
            out.push_str(&format!(",{}\n", self.composed[k]));
        }
        out
    }
}

/// Samples the profile.
pub fn profile(project: &Project, opts: &ProfileOptions) -> Result<Profile, CompareError> {
    let bad = |option: &str, problem: String| CompareError::Option { option: option.into(), problem };
    for (name, [lat, lon]) in [("--from", opts.from), ("--to", opts.to)] {
        if !(lat.abs() <= 90.0 && lon.abs() <= 180.0) {
            return Err(bad(name, format!("{lat},{lon} is not a latitude, longitude in degrees")));
        }
    }
    let e = project.ellipsoid()?;
    let r = f64::to_radians;
    let (length, azimuth, _) = inverse(&e, r(opts.from[0]), r(opts.from[1]), r(opts.to[0]), r(opts.to[1]))
        .map_err(|err| bad("--to", err.to_string()))?;
    if length == 0.0 {
        return Err(bad("--to", "the line has no length (--from and --to are the same point)".into()));
    }
    let (stack, _) = Scene::open(project)?;
    // Layers with heights (a difference layer has none).
    let visible: Vec<String> =
        project.layers.iter().filter(|l| l.visible && l.gives_heights()).map(|l| l.name.clone()).collect();
    let level = match opts.level {
        Some(l) => l,
        None => stack.detail_level().ok_or_else(|| {
            bad(
                "--level",
                "no shown layer adds detail at any level (no dataset, stroke, run or noise): give one".into(),
            )
        })?,
    };
    let samples = opts.samples.unwrap_or(((length / spacing_m(&e, level)).ceil() as usize + 1).min(MAX_SAMPLES));
    if !(2..=MAX_SAMPLES).contains(&samples) {
        return Err(bad("--samples", format!("{samples} must lie within 2–{MAX_SAMPLES}")));
    }
    let mut distance_m = Vec::with_capacity(samples);
    let (mut lat_deg, mut lon_deg, mut points): (Vec<f64>, Vec<f64>, Vec<DVec3>) = (Vec::new(), Vec::new(), Vec::new());
    for k in 0..samples {
        let s = length * k as f64 / (samples - 1) as f64;
        let (lat, lon) = if k == 0 {
            (r(opts.from[0]), r(opts.from[1]))
        } else {
            direct(&e, r(opts.from[0]), r(opts.from[1]), azimuth, s)
        };
        distance_m.push(s);
        lat_deg.push(lat.to_degrees());
        lon_deg.push(lon.to_degrees());
        points.push(ecef_from_geodetic(&e, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 }));
    }
    let sample = |scene: Scene| -> Result<Vec<f64>, CompareError> {
        let mut mosaic = Mosaic::new(scene, level, Interpolation::Bilinear);
        mosaic.prefetch(&points)?;
        Ok(points.iter().map(|p| mosaic.value(*p)).collect())
    };
    let mut layers = Vec::new();
    for name in &visible {
        layers.push((name.clone(), sample(operand_scene(&stack, project, &Operand::Layer(name.clone()))?)?));
    }
    let composed = sample(stack)?;
    Ok(Profile { level, length_m: length, distance_m, lat_deg, lon_deg, layers, composed })
}
