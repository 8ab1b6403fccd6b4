//! Reference ellipsoids of revolution (oblate or spherical), in metres.

use std::fmt;
use std::str::FromStr;

use super::GeodesyError;

/// An ellipsoid of revolution with equatorial semi-axis `a_m` ≥ polar semi-axis `b_m` > 0.
///
/// Derived constants are precomputed because every transform uses them. All lengths are metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Ellipsoid {
    name: &'static str,
    a_m: f64,
    b_m: f64,
    /// Flattening f = (a − b) / a.
    f: f64,
    /// First eccentricity squared e² = f (2 − f).
    e2: f64,
    /// (1 − f)² = b² / a².
    e2m: f64,
}

impl Ellipsoid {
    /// WGS84: a = 6 378 137 m, 1/f = 298.257223563.
    pub const WGS84: Ellipsoid = Ellipsoid::from_a_inv_f("wgs84", 6_378_137.0, 298.257_223_563);

    /// The Moon as the sphere of radius 1 737 400 m used by the LOLA products.
    pub const MOON: Ellipsoid = Ellipsoid::sphere("moon", 1_737_400.0);

    /// Mars, IAU 2000 ellipsoid: a = 3 396 190 m, b = 3 376 200 m.
    pub const MARS: Ellipsoid = Ellipsoid::from_axes_const("mars", 3_396_190.0, 3_376_200.0);

    const fn from_a_inv_f(name: &'static str, a_m: f64, inv_f: f64) -> Ellipsoid {
        let f = 1.0 / inv_f;
        let b_m = a_m * (1.0 - f);
        Ellipsoid { name, a_m, b_m, f, e2: f * (2.0 - f), e2m: (1.0 - f) * (1.0 - f) }
    }

    const fn from_axes_const(name: &'static str, a_m: f64, b_m: f64) -> Ellipsoid {
        let f = (a_m - b_m) / a_m;
        Ellipsoid { name, a_m, b_m, f, e2: f * (2.0 - f), e2m: (1.0 - f) * (1.0 - f) }
    }

    const fn sphere(name: &'static str, radius_m: f64) -> Ellipsoid {
        Ellipsoid { name, a_m: radius_m, b_m: radius_m, f: 0.0, e2: 0.0, e2m: 1.0 }
    }

    /// A user's ellipsoid from its two semi-axes in metres. Requires finite `a_m ≥ b_m > 0`
    /// (prolate bodies are refused: the cube-map shift assumes an oblate or spherical body).
    pub fn from_axes(a_m: f64, b_m: f64) -> Result<Ellipsoid, GeodesyError> {
        if !(a_m.is_finite() && b_m.is_finite() && b_m > 0.0 && a_m >= b_m) {
            return Err(GeodesyError::InvalidEllipsoid { a_m, b_m });
        }
        if a_m == b_m {
            Ok(Ellipsoid::sphere("custom", a_m))
        } else {
            Ok(Ellipsoid::from_axes_const("custom", a_m, b_m))
        }
    }

    /// Short name: `wgs84`, `moon`, `mars` or `custom`.
    pub fn name(&self) -> &'static str {
        self.name
    }
    /// Equatorial semi-axis a in metres.
    pub fn a_m(&self) -> f64 {
        self.a_m
    }
    /// Polar semi-axis b in metres.
    pub fn b_m(&self) -> f64 {
        self.b_m
    }
    /// Flattening f = (a − b)/a, dimensionless.
    pub fn flattening(&self) -> f64 {
        self.f
    }
    /// First eccentricity squared e² = (a² − b²)/a².
    pub fn e2(&self) -> f64 {
        self.e2
    }
    /// b²/a² = (1 − f)².
    pub fn b2_over_a2(&self) -> f64 {
        self.e2m
    }
    /// True when a = b.
    pub fn is_sphere(&self) -> bool {
        self.e2 == 0.0
    }

    /// A PROJ string for this body (`+R=` for spheres, `+a= +b=` otherwise), usable with
    /// `+proj=qsc` or `+proj=cart`.
    pub fn proj_params(&self) -> String {
        match self.name {
            "wgs84" => "+ellps=WGS84".to_string(),
            _ if self.is_sphere() => format!("+R={}", self.a_m),
            _ => format!("+a={} +b={}", self.a_m, self.b_m),
        }
    }
}

impl fmt::Display for Ellipsoid {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        if self.is_sphere() {
            write!(f, "{} (sphere R = {} m)", self.name, self.a_m)
        } else {
            write!(f, "{} (a = {} m, b = {} m, 1/f = {})", self.name, self.a_m, self.b_m, 1.0 / self.f)
        }
    }
}

impl FromStr for Ellipsoid {
    type Err = GeodesyError;

    /// Parses `wgs84`, `moon`, `mars` (any case), `a=A,b=B`, `a=A,rf=1/F` or `r=R` (metres).
    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let lower = text.trim().to_ascii_lowercase();
        match lower.as_str() {
            "wgs84" | "earth" => return Ok(Ellipsoid::WGS84),
            "moon" => return Ok(Ellipsoid::MOON),
            "mars" => return Ok(Ellipsoid::MARS),
            _ => {}
        }
        let unknown = || GeodesyError::UnknownBody(text.to_string());
        let (mut a, mut b, mut rf, mut r) = (None, None, None, None);
        for part in lower.split(',') {
            let (key, value) = part.split_once('=').ok_or_else(unknown)?;
            let value: f64 = value.trim().parse().map_err(|_| unknown())?;
            match key.trim() {
                "a" => a = Some(value),
                "b" => b = Some(value),
                "rf" => rf = Some(value),
                "r" => r = Some(value),
                _ => return Err(unknown()),
            }
        }
        match (a, b, rf, r) {
            (Some(a), Some(b), None, None) => Ellipsoid::from_axes(a, b),
            (Some(a), None, Some(rf), None) if rf.is_finite() && rf >= 1.0 => {
                Ellipsoid::from_axes(a, a * (1.0 - 1.0 / rf))
            }
            (None, None, None, Some(r)) => Ellipsoid::from_axes(r, r),
            _ => Err(unknown()),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn presets_have_published_axes() {
        assert_eq!(Ellipsoid::WGS84.a_m(), 6_378_137.0);
        // b of WGS84 is 6 356 752.314 245 179 m (NIMA TR8350.2, table 3.3).
        assert!((Ellipsoid::WGS84.b_m() - 6_356_752.314_245_179).abs() < 1e-8);
        assert!(Ellipsoid::MOON.is_sphere());
        assert_eq!(Ellipsoid::MARS.b_m(), 3_376_200.0);
    }

    #[test]
    fn parses_bodies_and_refuses_nonsense() {
        assert_eq!("WGS84".parse::<Ellipsoid>().unwrap(), Ellipsoid::WGS84);
        let custom: Ellipsoid = "a=7000000,b=6900000".parse().unwrap();
        assert_eq!(custom.b_m(), 6_900_000.0);
        let sphere: Ellipsoid = "r=1000".parse().unwrap();
        assert!(sphere.is_sphere());
        assert!("pluto".parse::<Ellipsoid>().is_err());
        assert!("a=1,b=2".parse::<Ellipsoid>().is_err(), "prolate must be refused");
        assert!("a=nan,b=1".parse::<Ellipsoid>().is_err());
        assert!("a=0,b=0".parse::<Ellipsoid>().is_err());
    }
}
