//! A dataset layer's bias corrections (its `correction` field, what `terrafuse coregister
//! --pipeline … --apply` writes): functions of where a sample is and of the layer's own height
//! there, summed and taken off the layer's value after scale and offset. The co-registration
//! pipeline (`crate::compare::pipeline`) fits them with the same evaluation, so what a fit
//! reported is what the composed layer shows.
//!
//! ```json
//! "correction": [
//!   { "name": "deramp", "origin_deg": [41.2, 39.9], "order": 1,
//!     "coefficients": [0.02, 0.5, -0.3], "box_km": [-30.1, -22.0, 29.8, 22.3] },
//!   { "name": "terrain_bias", "attribute": "elevation", "bins": [[1510.0, -0.4], [1530.0, -0.2]] },
//!   { "name": "directional", "origin_deg": [41.2, 39.9], "azimuth_deg": 30.0, "offset_m": 0.1,
//!     "sinusoids": [{ "wavelength_m": 3000.0, "amplitude_m": 2.0, "phase_rad": 0.4 }],
//!     "range_m": [-35000.0, 36000.0] }
//! ]
//! ```
//!
//! Positions are east and north metres in the tangent frame at `origin_deg` (longitude,
//! latitude on the body's ellipsoid), as the fit measured them. Beyond the samples a fit saw a
//! correction is held, not extrapolated: a ramp at its value at the nearest point of `box_km`,
//! sinusoids at the ends of `range_m`, a binned bias at its end bins. So each is bounded
//! ([`Bias::bound_m`]), which the height bounds of culling add.
//!
//! The composition kernel sees one quad's samples, so a layer's terrain bias reads its own
//! elevation only; one by slope or curvature (which need the neighbours' heights) is refused by
//! [`Bias::check`].

use glam::DVec3;
use serde::{Deserialize, Serialize};

use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic, local_axes};

/// An attribute of the terrain that a binned bias is a function of.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(rename_all = "snake_case")]
pub enum Attribute {
    /// Elevation, metres.
    Elevation,
    /// Maximal curvature, 100/m (xDEM's `max_curvature`).
    MaxCurvature,
    /// Slope, degrees.
    Slope,
}

impl Attribute {
    /// The name `--pipeline` and files use.
    pub fn name(self) -> &'static str {
        match self {
            Attribute::Elevation => "elevation",
            Attribute::MaxCurvature => "max_curvature",
            Attribute::Slope => "slope",
        }
    }
}

/// One sinusoid of a directional bias: amplitude · sin(2π·x / wavelength + phase).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
pub struct Sinusoid {
    /// Wavelength along the azimuth, metres.
    pub wavelength_m: f64,
    /// Amplitude, metres.
    pub amplitude_m: f64,
    /// Phase at x = 0, radians.
    pub phase_rad: f64,
}

/// Most sinusoids of a directional bias (xDEM's `DirectionalBias` default `max_nb_frequencies`).
pub const MAX_SINUSOIDS: usize = 3;

/// One bias correction (field names are the files' and the JSON's: scripts rely on them). Each
/// is what the layer is too high by, taken off it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, schemars::JsonSchema)]
#[serde(tag = "name", rename_all = "snake_case", deny_unknown_fields)]
pub enum Bias {
    /// A polynomial of local east and north kilometres from `origin_deg`.
    Deramp {
        /// The local frame's origin: longitude, latitude, degrees.
        origin_deg: [f64; 2],
        /// The order, 1–3.
        order: u8,
        /// The coefficients, metres per km^(i + j), in the order of [`polynomial_terms`]
        /// (1, e, n, e², e·n, n², e³, e²·n, e·n², n³).
        coefficients: Vec<f64>,
        /// Where it was fitted: west, south, east, north km in the frame; held beyond.
        box_km: [f64; 4],
    },
    /// A bias binned by an attribute, linear between bin centres, held beyond the end ones.
    TerrainBias {
        /// The attribute.
        attribute: Attribute,
        /// (attribute at the bin's centre, bias there in metres), ascending.
        bins: Vec<[f64; 2]>,
    },
    /// A sum of sinusoids of the distance from the origin along an azimuth, and a constant.
    Directional {
        /// The local frame's origin: longitude, latitude, degrees.
        origin_deg: [f64; 2],
        /// Degrees clockwise from north.
        azimuth_deg: f64,
        /// The constant, metres.
        offset_m: f64,
        /// The sinusoids, strongest first.
        sinusoids: Vec<Sinusoid>,
        /// Where it was fitted: the distances along the azimuth, metres; held beyond.
        range_m: [f64; 2],
    },
}

/// The exponents (i of east, j of north) of a polynomial's terms: by total degree, then
/// falling i.
pub fn polynomial_terms(order: u8) -> Vec<[u8; 2]> {
    (0..=order).flat_map(|d| (0..=d).rev().map(move |i| [i, d - i])).collect()
}

/// Σ c_k · e^i · n^j over the terms of `order` (east and north in kilometres), in the order of
/// [`polynomial_terms`] (without building them: it runs per sample when a layer is composed).
pub fn polynomial_at(order: u8, coefficients: &[f64], east_km: f64, north_km: f64) -> f64 {
    let mut sum = 0.0;
    let mut k = 0;
    for d in 0..=i32::from(order) {
        for i in (0..=d).rev() {
            sum += coefficients.get(k).copied().unwrap_or(0.0) * east_km.powi(i) * north_km.powi(d - i);
            k += 1;
        }
    }
    sum
}

/// A binned function at `x`: linear between bin centres, the end bins' values beyond them.
pub fn binned_at(bins: &[[f64; 2]], x: f64) -> f64 {
    let k = bins.partition_point(|p| p[0] <= x);
    if k == 0 {
        return bins[0][1];
    }
    if k == bins.len() {
        return bins[k - 1][1];
    }
    let (p, q) = (bins[k - 1], bins[k]);
    p[1] + (x - p[0]) / (q[0] - p[0]) * (q[1] - p[1])
}

/// A constant and a sum of sinusoids at `x` metres.
pub fn sinusoids_at(offset_m: f64, sinusoids: &[Sinusoid], x: f64) -> f64 {
    offset_m
        + sinusoids
            .iter()
            .map(|s| s.amplitude_m * (std::f64::consts::TAU * x / s.wavelength_m + s.phase_rad).sin())
            .sum::<f64>()
}

impl Bias {
    /// The bias at a sample `east_m`, `north_m` from its frame's origin where `attribute` gives
    /// the terrain's attributes, metres (a terrain bias is 0 where its attribute is unknown).
    pub fn at(&self, east_m: f64, north_m: f64, attribute: impl Fn(Attribute) -> f64) -> f64 {
        match self {
            Bias::Deramp { order, coefficients, box_km, .. } => {
                let e = (east_m / 1000.0).clamp(box_km[0], box_km[2]);
                let n = (north_m / 1000.0).clamp(box_km[1], box_km[3]);
                polynomial_at(*order, coefficients, e, n)
            }
            Bias::TerrainBias { attribute: a, bins } => {
                let x = attribute(*a);
                if x.is_finite() { binned_at(bins, x) } else { 0.0 }
            }
            Bias::Directional { azimuth_deg, offset_m, sinusoids, range_m, .. } => {
                let (s, c) = azimuth_deg.to_radians().sin_cos();
                sinusoids_at(*offset_m, sinusoids, (east_m * s + north_m * c).clamp(range_m[0], range_m[1]))
            }
        }
    }

    /// The step's name as `--pipeline` spells it.
    pub fn step_name(&self) -> String {
        match self {
            Bias::Deramp { order, .. } => format!("deramp:{order}"),
            Bias::TerrainBias { attribute, .. } => format!("terrain_bias:{}", attribute.name()),
            Bias::Directional { azimuth_deg, .. } => format!("directional:{azimuth_deg}"),
        }
    }

    /// Its frame's origin (longitude, latitude, degrees), for the biases of position.
    pub fn origin_deg(&self) -> Option<[f64; 2]> {
        match self {
            Bias::Deramp { origin_deg, .. } | Bias::Directional { origin_deg, .. } => Some(*origin_deg),
            Bias::TerrainBias { .. } => None,
        }
    }

    /// A bound on |bias| anywhere, metres: Σ |c|·E^i·N^j with E, N the box's largest |east|,
    /// |north| for a ramp; the largest |bin| for a binned bias; |offset| + Σ |amplitude| for
    /// sinusoids.
    pub fn bound_m(&self) -> f64 {
        match self {
            Bias::Deramp { order, coefficients, box_km, .. } => {
                let (e, n) = (box_km[0].abs().max(box_km[2].abs()), box_km[1].abs().max(box_km[3].abs()));
                polynomial_terms(*order)
                    .iter()
                    .zip(coefficients)
                    .map(|(t, c)| c.abs() * e.powi(i32::from(t[0])) * n.powi(i32::from(t[1])))
                    .sum()
            }
            Bias::TerrainBias { bins, .. } => bins.iter().map(|b| b[1].abs()).fold(0.0, f64::max),
            Bias::Directional { offset_m, sinusoids, .. } => {
                offset_m.abs() + sinusoids.iter().map(|s| s.amplitude_m.abs()).sum::<f64>()
            }
        }
    }

    /// A bound on how much the bias changes between samples `spacing_m` apart whose values
    /// differ by at most `value_step_m`, metres (it widens the skirts that hide cracks): the
    /// gradient bound × spacing for a ramp (Σ |c|·(i·E^(i−1)·N^j + j·E^i·N^(j−1)) per km) and
    /// for sinusoids (Σ |amplitude|·2π / wavelength), the steepest bin-to-bin slope × the value
    /// step for a binned bias.
    pub fn step_bound_m(&self, spacing_m: f64, value_step_m: f64) -> f64 {
        match self {
            Bias::Deramp { order, coefficients, box_km, .. } => {
                let (e, n) = (box_km[0].abs().max(box_km[2].abs()), box_km[1].abs().max(box_km[3].abs()));
                let per_km: f64 = polynomial_terms(*order)
                    .iter()
                    .zip(coefficients)
                    .map(|(t, c)| {
                        let (i, j) = (i32::from(t[0]), i32::from(t[1]));
                        let d_e = if i > 0 { f64::from(i) * e.powi(i - 1) * n.powi(j) } else { 0.0 };
                        let d_n = if j > 0 { f64::from(j) * e.powi(i) * n.powi(j - 1) } else { 0.0 };
                        c.abs() * (d_e + d_n)
                    })
                    .sum();
                per_km * spacing_m / 1000.0
            }
            Bias::TerrainBias { bins, .. } => {
                let steepest =
                    bins.windows(2).map(|w| ((w[1][1] - w[0][1]) / (w[1][0] - w[0][0])).abs()).fold(0.0, f64::max);
                steepest * value_step_m
            }
            Bias::Directional { sinusoids, .. } => {
                let per_m: f64 =
                    sinusoids.iter().map(|s| s.amplitude_m.abs() * std::f64::consts::TAU / s.wavelength_m).sum();
                per_m * spacing_m
            }
        }
    }

    /// Checks what a type cannot: finite numbers, the order and its coefficients, bins ascending,
    /// the ranges, and that a layer's terrain bias reads its elevation.
    pub fn check(&self) -> Result<(), BiasError> {
        let step = || self.step_name();
        let finite = |what: &'static str, v: &[f64]| match v.iter().all(|x| x.is_finite()) {
            true => Ok(()),
            false => Err(BiasError::NotFinite { step: step(), what }),
        };
        if let Some([lon, lat]) = self.origin_deg()
            && !(lon.is_finite() && (-90.0..=90.0).contains(&lat))
        {
            return Err(BiasError::Origin { step: step(), lon, lat });
        }
        match self {
            Bias::Deramp { order, coefficients, box_km, .. } => {
                if !(1..=3).contains(order) {
                    return Err(BiasError::Order(*order));
                }
                let terms = polynomial_terms(*order).len();
                if coefficients.len() != terms {
                    return Err(BiasError::Coefficients { order: *order, given: coefficients.len(), terms });
                }
                finite("coefficients", coefficients)?;
                finite("box_km", box_km)?;
                if box_km[0] > box_km[2] || box_km[1] > box_km[3] {
                    return Err(BiasError::BoxOrder { order: *order, box_km: *box_km });
                }
            }
            Bias::TerrainBias { attribute, bins } => {
                if *attribute != Attribute::Elevation {
                    return Err(BiasError::NotElevation(attribute.name()));
                }
                if bins.len() < 2 {
                    return Err(BiasError::TooFewBins);
                }
                finite("bins", bins.as_flattened())?;
                if bins.windows(2).any(|w| w[0][0] >= w[1][0]) {
                    return Err(BiasError::BinsNotRising);
                }
            }
            Bias::Directional { azimuth_deg, offset_m, sinusoids, range_m, .. } => {
                finite("azimuth_deg and offset_m", &[*azimuth_deg, *offset_m])?;
                finite("range_m", range_m)?;
                if range_m[0] > range_m[1] {
                    return Err(BiasError::RangeNotRising { step: step(), range_m: *range_m });
                }
                if sinusoids.len() > MAX_SINUSOIDS {
                    return Err(BiasError::TooManySinusoids { step: step() });
                }
                for s in sinusoids {
                    finite("the sinusoids", &[s.wavelength_m, s.amplitude_m, s.phase_rad])?;
                    if s.wavelength_m <= 0.0 {
                        return Err(BiasError::Wavelength { step: step(), wavelength_m: s.wavelength_m });
                    }
                }
            }
        }
        Ok(())
    }
}

/// What [`Bias::check`] refuses; `step` is the bias's step name (`deramp:2`, `directional:30` …).
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BiasError {
    /// A number that must be finite is not.
    #[error("{step}: {what} must be finite")]
    NotFinite {
        /// The step.
        step: String,
        /// Which numbers.
        what: &'static str,
    },
    /// The frame's origin is not a longitude and latitude.
    #[error("{step}: origin_deg [{lon}, {lat}] is not a longitude and latitude")]
    Origin {
        /// The step.
        step: String,
        /// The longitude given.
        lon: f64,
        /// The latitude given.
        lat: f64,
    },
    /// A deramp's order outside 1–3.
    #[error("deramp: order {0} must be 1, 2 or 3")]
    Order(u8),
    /// A deramp's coefficients do not match its order.
    #[error("deramp:{order}: has {given} coefficients, its order has {terms} terms")]
    Coefficients {
        /// The order.
        order: u8,
        /// Coefficients given.
        given: usize,
        /// Terms of the order.
        terms: usize,
    },
    /// A deramp's box is not west, south, east, north.
    #[error("deramp:{order}: box_km {box_km:?} must be [west, south, east, north]")]
    BoxOrder {
        /// The order.
        order: u8,
        /// The box given.
        box_km: [f64; 4],
    },
    /// A layer's terrain bias over another attribute than the elevation.
    #[error(
        "terrain_bias:{0}: a layer's terrain bias can read only its elevation (slope and curvature need the \
         neighbouring samples, which composition does not read)"
    )]
    NotElevation(&'static str),
    /// Fewer than two bins.
    #[error("terrain_bias: needs at least two bins")]
    TooFewBins,
    /// Bins not in rising order of their centres.
    #[error("terrain_bias: the bins' centres must rise")]
    BinsNotRising,
    /// A directional bias's range that falls.
    #[error("{step}: range_m {range_m:?} must rise")]
    RangeNotRising {
        /// The step.
        step: String,
        /// The range given.
        range_m: [f64; 2],
    },
    /// More sinusoids than a layer carries.
    #[error("{step}: at most {MAX_SINUSOIDS} sinusoids")]
    TooManySinusoids {
        /// The step.
        step: String,
    },
    /// A wavelength that is not positive.
    #[error("{step}: wavelength_m {wavelength_m} must be positive")]
    Wavelength {
        /// The step.
        step: String,
        /// The wavelength given.
        wavelength_m: f64,
    },
}

/// A local east-north tangent frame on the ellipsoid.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Frame {
    /// The origin, ECEF metres (on the ellipsoid).
    pub origin: DVec3,
    /// The east unit vector there.
    pub east: DVec3,
    /// The north unit vector there.
    pub north: DVec3,
}

impl Frame {
    /// The frame at longitude, latitude (degrees).
    pub fn at(ellipsoid: &Ellipsoid, origin_deg: [f64; 2]) -> Frame {
        let g = Geodetic::from_degrees(origin_deg[1], origin_deg[0], 0.0);
        let (east, north) = local_axes(g.lon_rad, g.lat_rad);
        Frame { origin: ecef_from_geodetic(ellipsoid, g), east, north }
    }

    /// East and north metres of a point.
    pub fn local(&self, p: DVec3) -> (f64, f64) {
        let d = p - self.origin;
        (d.dot(self.east), d.dot(self.north))
    }
}

/// A layer's corrections placed on its body: each bias with its frame.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Correction {
    /// The biases, in order, each with its frame (None for a terrain bias).
    pub biases: Vec<(Bias, Option<Frame>)>,
}

impl Correction {
    /// Places the biases on the ellipsoid.
    pub fn new(biases: &[Bias], ellipsoid: &Ellipsoid) -> Correction {
        let biases = biases.iter().map(|b| (b.clone(), b.origin_deg().map(|o| Frame::at(ellipsoid, o)))).collect();
        Correction { biases }
    }

    /// Whether there is nothing to take off.
    pub fn is_empty(&self) -> bool {
        self.biases.is_empty()
    }

    /// The sum of the biases at the point `p` (ECEF) where the layer's value is `value_m`, in
    /// order: a terrain bias reads the value as the biases before it left it (as the pipeline
    /// fitted it).
    pub fn at(&self, p: DVec3, value_m: f64) -> f64 {
        let mut sum = 0.0;
        for (bias, frame) in &self.biases {
            let (e, n) = frame.map_or((0.0, 0.0), |f| f.local(p));
            let left = value_m - sum;
            sum += bias.at(e, n, |a| if a == Attribute::Elevation { left } else { f64::NAN });
        }
        sum
    }

    /// A bound on |Σ bias|, metres.
    pub fn bound_m(&self) -> f64 {
        self.biases.iter().map(|(b, _)| b.bound_m()).sum()
    }

    /// A bound on the change of Σ bias between neighbouring samples ([`Bias::step_bound_m`]).
    pub fn step_bound_m(&self, spacing_m: f64, value_step_m: f64) -> f64 {
        self.biases.iter().map(|(b, _)| b.step_bound_m(spacing_m, value_step_m)).sum()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ramp() -> Bias {
        Bias::Deramp {
            origin_deg: [41.0, 40.0],
            order: 1,
            coefficients: vec![0.25, 0.5, -0.3],
            box_km: [-10.0, -5.0, 10.0, 5.0],
        }
    }

    #[test]
    fn a_ramp_is_exact_inside_its_box_and_held_beyond_it() {
        let r = ramp();
        assert_eq!(r.at(2000.0, 1000.0, |_| f64::NAN), 0.25 + 0.5 * 2.0 - 0.3 * 1.0);
        // 30 km east is held at the box's east edge, 10 km.
        assert_eq!(r.at(30_000.0, 0.0, |_| f64::NAN), r.at(10_000.0, 0.0, |_| f64::NAN));
        assert!((r.bound_m() - (0.25 + 5.0 + 1.5)).abs() < 1e-12);
    }

    #[test]
    fn a_placed_correction_reads_position_in_its_frame_and_the_layers_own_elevation() {
        let e = Ellipsoid::WGS84;
        let binned = Bias::TerrainBias { attribute: Attribute::Elevation, bins: vec![[1000.0, 0.0], [2000.0, 1.0]] };
        let c = Correction::new(&[ramp(), binned], &e);
        let f = Frame::at(&e, [41.0, 40.0]);
        let p = f.origin + 3000.0 * f.east - 2000.0 * f.north;
        // The ramp, then the elevation bias at the value the ramp left (1500 m less the ramp).
        let ramp = 0.25 + 0.5 * 3.0 + 0.3 * 2.0;
        let want = ramp + ((1500.0 - ramp) - 1000.0) / 1000.0;
        assert!((c.at(p, 1500.0) - want).abs() < 1e-9, "{}", c.at(p, 1500.0));
    }

    #[test]
    fn bad_corrections_say_what_is_wrong() {
        let mut r = ramp();
        if let Bias::Deramp { coefficients, .. } = &mut r {
            coefficients.push(1.0);
        }
        assert!(r.check().unwrap_err().to_string().contains("has 4 coefficients, its order has 3 terms"));
        let slope = Bias::TerrainBias { attribute: Attribute::Slope, bins: vec![[0.0, 0.0], [1.0, 1.0]] };
        assert!(slope.check().unwrap_err().to_string().contains("can read only its elevation"));
        let falling = Bias::TerrainBias { attribute: Attribute::Elevation, bins: vec![[2.0, 0.0], [1.0, 1.0]] };
        assert!(falling.check().unwrap_err().to_string().contains("must rise"));
        assert!(ramp().check().is_ok());
    }
}
