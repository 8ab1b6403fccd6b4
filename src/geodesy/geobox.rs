//! A longitude/latitude box, the one order every command and file uses for one:
//! `WEST,SOUTH,EAST,NORTH` in degrees, as GDAL's `-te` and `export --bounds` order their values.
//! A box whose west is greater than its east crosses the antimeridian.

use std::borrow::Cow;
use std::str::FromStr;

use serde::{Deserialize, Serialize};

/// `[west, south, east, north]`, degrees; west > east crosses the antimeridian.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(try_from = "[f64; 4]", into = "[f64; 4]")]
pub struct GeoBox {
    /// Western edge, degrees east (−180 … 180).
    pub west_deg: f64,
    /// Southern edge, degrees north (−90 … 90).
    pub south_deg: f64,
    /// Eastern edge, degrees east (−180 … 180); below `west_deg` across the antimeridian.
    pub east_deg: f64,
    /// Northern edge, degrees north, above `south_deg`.
    pub north_deg: f64,
}

/// What makes four numbers not a box.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum BoxError {
    /// Not four comma-separated numbers.
    #[error("'{text}' is not WEST,SOUTH,EAST,NORTH in degrees (four numbers)")]
    NotFourNumbers {
        /// What was given.
        text: String,
    },
    /// A value is NaN or infinite.
    #[error("[{0:?}]: every value must be a finite number of degrees", .values)]
    NotFinite {
        /// The values.
        values: [f64; 4],
    },
    /// A latitude beyond ±90°, or south not below north.
    #[error(
        "south {south} and north {north} must be latitudes within ±90 with south < north (the order is WEST,SOUTH,EAST,NORTH)"
    )]
    Latitudes {
        /// The southern edge given.
        south: f64,
        /// The northern edge given.
        north: f64,
    },
    /// A longitude beyond ±180°.
    #[error("west {west} and east {east} must be longitudes within ±180 (the order is WEST,SOUTH,EAST,NORTH)")]
    Longitudes {
        /// The western edge given.
        west: f64,
        /// The eastern edge given.
        east: f64,
    },
    /// West equals east.
    #[error("west and east are both {0}: the box has no width", .west)]
    NoWidth {
        /// The longitude given twice.
        west: f64,
    },
}

impl GeoBox {
    /// A checked box from its edges in `WEST,SOUTH,EAST,NORTH` order, degrees.
    pub fn new(west_deg: f64, south_deg: f64, east_deg: f64, north_deg: f64) -> Result<GeoBox, BoxError> {
        let values = [west_deg, south_deg, east_deg, north_deg];
        if !values.iter().all(|v| v.is_finite()) {
            return Err(BoxError::NotFinite { values });
        }
        if !(south_deg.abs() <= 90.0 && north_deg.abs() <= 90.0 && south_deg < north_deg) {
            return Err(BoxError::Latitudes { south: south_deg, north: north_deg });
        }
        if !(west_deg.abs() <= 180.0 && east_deg.abs() <= 180.0) {
            return Err(BoxError::Longitudes { west: west_deg, east: east_deg });
        }
        if west_deg == east_deg {
            return Err(BoxError::NoWidth { west: west_deg });
        }
        Ok(GeoBox { west_deg, south_deg, east_deg, north_deg })
    }

    /// A box from edges that may run past the poles or ±180° (a box grown around a point or a
    /// path): latitudes clamped to ±90°, longitudes wrapped into ±180° (a box wider than 360°
    /// is refused as having no width).
    pub fn wrapped(west_deg: f64, south_deg: f64, east_deg: f64, north_deg: f64) -> Result<GeoBox, BoxError> {
        let wrap = |lon: f64| (lon + 180.0).rem_euclid(360.0) - 180.0;
        if east_deg - west_deg >= 360.0 {
            return Err(BoxError::NoWidth { west: west_deg });
        }
        GeoBox::new(wrap(west_deg), south_deg.max(-90.0), wrap(east_deg), north_deg.min(90.0))
    }

    /// Whether the box crosses the antimeridian (west > east).
    pub fn crosses_antimeridian(&self) -> bool {
        self.west_deg > self.east_deg
    }

    /// The eastern edge continuous with the western one: east + 360° across the antimeridian,
    /// so that west … east_unwrapped runs eastward through the box.
    pub fn east_unwrapped_deg(&self) -> f64 {
        if self.crosses_antimeridian() { self.east_deg + 360.0 } else { self.east_deg }
    }

    /// Its width in longitude, degrees (0 … 360).
    pub fn width_deg(&self) -> f64 {
        self.east_unwrapped_deg() - self.west_deg
    }

    /// The centre (lat, lon), degrees, longitude within ±180.
    pub fn centre_deg(&self) -> (f64, f64) {
        let lon = self.west_deg + 0.5 * self.width_deg();
        (0.5 * (self.south_deg + self.north_deg), if lon > 180.0 { lon - 360.0 } else { lon })
    }

    /// Whether a point (lon, lat, degrees) lies inside or on the edge.
    pub fn contains(&self, lon_deg: f64, lat_deg: f64) -> bool {
        if !(self.south_deg..=self.north_deg).contains(&lat_deg) {
            return false;
        }
        let east_of_west = (lon_deg - self.west_deg).rem_euclid(360.0);
        east_of_west <= self.width_deg()
    }

    /// Whether a ball of angular radius `radius_deg` around (lon, lat) may reach the box
    /// (conservative: it may say yes for a ball just outside a corner, never no for one inside).
    pub fn may_reach(&self, lon_deg: f64, lat_deg: f64, radius_deg: f64) -> bool {
        if lat_deg + radius_deg < self.south_deg || lat_deg - radius_deg > self.north_deg {
            return false;
        }
        let widest = (lat_deg.abs() + radius_deg).min(90.0);
        if widest >= 89.0 {
            return true;
        }
        let d_lon = radius_deg / widest.to_radians().cos();
        (lon_deg - (self.west_deg - d_lon)).rem_euclid(360.0) <= self.width_deg() + 2.0 * d_lon
    }

    /// Its values in file order.
    pub fn to_array(self) -> [f64; 4] {
        [self.west_deg, self.south_deg, self.east_deg, self.north_deg]
    }
}

impl TryFrom<[f64; 4]> for GeoBox {
    type Error = BoxError;

    fn try_from([w, s, e, n]: [f64; 4]) -> Result<GeoBox, BoxError> {
        GeoBox::new(w, s, e, n)
    }
}

impl From<GeoBox> for [f64; 4] {
    fn from(b: GeoBox) -> [f64; 4] {
        b.to_array()
    }
}

impl FromStr for GeoBox {
    type Err = BoxError;

    /// `WEST,SOUTH,EAST,NORTH`, degrees.
    fn from_str(text: &str) -> Result<GeoBox, BoxError> {
        let values: Result<Vec<f64>, _> = text.split(',').map(|v| v.trim().parse::<f64>()).collect();
        match values.as_deref() {
            Ok(&[w, s, e, n]) => GeoBox::new(w, s, e, n),
            _ => Err(BoxError::NotFourNumbers { text: text.into() }),
        }
    }
}

impl std::fmt::Display for GeoBox {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{},{},{},{}", self.west_deg, self.south_deg, self.east_deg, self.north_deg)
    }
}

impl schemars::JsonSchema for GeoBox {
    fn schema_name() -> Cow<'static, str> {
        "GeoBox".into()
    }

    fn json_schema(generator: &mut schemars::SchemaGenerator) -> schemars::Schema {
        let mut schema = <[f64; 4]>::json_schema(generator);
        schema.insert(
            "description".into(),
            "`[west, south, east, north]`, degrees (GDAL's -te order); west > east crosses the antimeridian.".into(),
        );
        schema
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_box_reads_in_one_order_and_refuses_what_cannot_be_one() {
        let b: GeoBox = "40.2, 39.4, 40.5, 39.7".parse().unwrap();
        assert_eq!(b.to_array(), [40.2, 39.4, 40.5, 39.7]);
        assert_eq!(b.to_string(), "40.2,39.4,40.5,39.7");
        let across: GeoBox = "170,-10,-170,10".parse().unwrap();
        assert!(across.crosses_antimeridian() && (across.width_deg() - 20.0).abs() < 1e-12);
        assert!(across.contains(179.0, 0.0) && across.contains(-175.0, 5.0) && !across.contains(0.0, 0.0));
        assert_eq!(across.centre_deg(), (0.0, 180.0));
        let cases = [
            ("40,39.5,41", "four numbers"),
            ("a,b,c,d", "four numbers"),
            ("40,39.9,41,39.5", "south 39.9 and north 39.5"),
            ("39.6,40.5,39.7,95", "within ±90"),
            ("200,0,210,1", "west 200 and east 210"),
            ("5,0,5,1", "no width"),
            ("NaN,0,1,1", "finite"),
        ];
        for (text, expected) in cases {
            let e = text.parse::<GeoBox>().unwrap_err().to_string();
            assert!(e.contains(expected), "{text}: {e}");
        }
        let json: GeoBox = serde_json::from_str("[1, 2, 3, 4]").unwrap();
        assert_eq!(serde_json::to_string(&json).unwrap(), "[1.0,2.0,3.0,4.0]");
        assert!(serde_json::from_str::<GeoBox>("[1, 4, 3, 2]").unwrap_err().to_string().contains("south 4"));
    }
}
