//! A camera flight: waypoints `LAT,LON,ALT,HEADING,PITCH[,FOV]` joined by geodesics on the
//! ellipsoid, the altitude interpolated geometrically (a constant climb rate in scale, so a
//! descent from 500 km to 5 km spends as many frames on each factor of ten), heading along the
//! shorter turn, pitch and field of view linearly; each leg gets the same number of frames.

use crate::geodesy::Ellipsoid;
use crate::geodesy::geodesic::{GeodesicError, direct, inverse};
use crate::project::CameraSpec;

/// A flight that cannot be flown: the waypoint (from 1) and what is wrong with it.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum FlightError {
    /// A waypoint that does not read.
    #[error("waypoint {index} '{text}': {why}")]
    Waypoint {
        /// Its place in the list, from 1.
        index: usize,
        /// Its text.
        text: String,
        /// What is wrong.
        why: String,
    },
    /// Fewer than two waypoints.
    #[error("a flight needs at least two waypoints separated by ';' (got {0})")]
    TooFew(usize),
    /// No frames.
    #[error("a flight needs at least 2 frames (got {0})")]
    Frames(usize),
    /// Two waypoints without a geodesic between them.
    #[error(transparent)]
    Geodesic(#[from] GeodesicError),
}

/// The waypoints of a flight.
#[derive(Clone, Debug, PartialEq)]
pub struct Flight {
    /// The cameras to pass through, in order.
    pub waypoints: Vec<CameraSpec>,
}

impl Flight {
    /// Reads `LAT,LON,ALT,HEADING,PITCH[,FOV];…` (degrees and metres; the field of view
    /// `default_fov` where not given).
    pub fn parse(text: &str, default_fov: f64) -> Result<Flight, FlightError> {
        let mut waypoints = Vec::new();
        for (k, part) in text.split(';').map(str::trim).filter(|p| !p.is_empty()).enumerate() {
            let bad = |why: String| FlightError::Waypoint { index: k + 1, text: part.to_string(), why };
            // A waypoint is a camera as `--camera` reads it, its field of view the project's
            // where not given; the altitude is interpolated geometrically, so it must be > 0.
            let mut camera = CameraSpec::parse(part).map_err(|e| bad(e.to_string()))?;
            if part.split(',').count() == 5 {
                camera.fov = default_fov;
            }
            if camera.alt <= 0.0 {
                return Err(bad(format!("altitude {} m must be above the ellipsoid (> 0)", camera.alt)));
            }
            waypoints.push(camera);
        }
        if waypoints.len() < 2 {
            return Err(FlightError::TooFew(waypoints.len()));
        }
        Ok(Flight { waypoints })
    }

    /// The camera of each of `frames` frames, the first at the first waypoint and the last at the
    /// last.
    pub fn cameras(&self, ellipsoid: &Ellipsoid, frames: usize) -> Result<Vec<CameraSpec>, FlightError> {
        if frames < 2 {
            return Err(FlightError::Frames(frames));
        }
        let legs = self.waypoints.len() - 1;
        let mut geodesics = Vec::with_capacity(legs);
        for w in self.waypoints.windows(2) {
            let r = f64::to_radians;
            let (s, az, _) = inverse(ellipsoid, r(w[0].lat), r(w[0].lon), r(w[1].lat), r(w[1].lon))?;
            geodesics.push((s, az));
        }
        Ok((0..frames)
            .map(|k| {
                let u = k as f64 / (frames - 1) as f64 * legs as f64;
                let leg = (u.floor() as usize).min(legs - 1);
                let f = u - leg as f64;
                let (a, b) = (&self.waypoints[leg], &self.waypoints[leg + 1]);
                let (s, az) = geodesics[leg];
                let (lat, lon) = if f >= 1.0 {
                    (b.lat, b.lon)
                } else if s > 1e-6 && f > 0.0 {
                    let (lat, lon) = direct(ellipsoid, a.lat.to_radians(), a.lon.to_radians(), az, f * s);
                    (lat.to_degrees(), lon.to_degrees())
                } else {
                    (a.lat, a.lon)
                };
                let turn = (b.heading - a.heading + 540.0).rem_euclid(360.0) - 180.0;
                CameraSpec {
                    lat,
                    lon,
                    alt: a.alt * (b.alt / a.alt).powf(f),
                    heading: (a.heading + f * turn).rem_euclid(360.0),
                    pitch: a.pitch + f * (b.pitch - a.pitch),
                    fov: a.fov + f * (b.fov - a.fov),
                }
            })
            .collect())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_flight_passes_through_its_waypoints_along_the_geodesic() {
        let e = Ellipsoid::WGS84;
        let flight = Flight::parse("39.3,40.4,50000,350,-90; 39.5,40.6,5000,10,-30", 50.0).unwrap();
        let cams = flight.cameras(&e, 11).unwrap();
        assert_eq!(cams.len(), 11);
        assert_eq!((cams[0].lat, cams[0].lon, cams[0].alt), (39.3, 40.4, 50000.0));
        let last = cams[10];
        assert!((last.lat - 39.5).abs() < 1e-9 && (last.lon - 40.6).abs() < 1e-9, "{last:?}");
        assert!((last.alt - 5000.0).abs() < 1e-6 && (last.heading - 10.0).abs() < 1e-9);
        // Halfway: the geodesic's midpoint (equal distances to both ends), the altitude's
        // geometric mean, the heading across north (350° → 10°: 0°).
        let mid = cams[5];
        let d = |c: &CameraSpec, lat: f64, lon: f64| {
            inverse(&e, c.lat.to_radians(), c.lon.to_radians(), lat.to_radians(), lon.to_radians()).unwrap().0
        };
        assert!((d(&mid, 39.3, 40.4) - d(&mid, 39.5, 40.6)).abs() < 1e-3);
        assert!((mid.alt - (50000.0f64 * 5000.0).sqrt()).abs() < 1e-6);
        assert!(mid.heading.abs() < 1e-9 || (mid.heading - 360.0).abs() < 1e-9, "{}", mid.heading);
        assert!((mid.pitch + 60.0).abs() < 1e-9 && mid.fov == 50.0);
    }

    #[test]
    fn bad_waypoints_are_named() {
        let err = |t: &str| Flight::parse(t, 50.0).unwrap_err().to_string();
        assert!(err("39,40,100,0,-90").contains("at least two waypoints"));
        assert!(err("39,40,100,0,-90;39,40,x,0,-90").contains("waypoint 2 '39,40,x,0,-90': 'x'"));
        assert!(err("39,40,100,0,-90;39,40,-5,0,-90").contains("altitude -5 m"));
        assert!(err("39,40,100,0,-90;39,40,100,0").contains("got 4 values"));
        assert!(err("95,40,100,0,-90;39,40,100,0,-90").contains("waypoint 1"));
        let f = Flight::parse("39,40,100,0,-90;39,40,100,0,-90", 50.0).unwrap();
        assert_eq!(f.cameras(&Ellipsoid::WGS84, 1).unwrap_err(), FlightError::Frames(1));
        // Two waypoints at the same place: the camera stays, only altitude and angles change.
        assert_eq!(f.cameras(&Ellipsoid::WGS84, 3).unwrap()[1].lat, 39.0);
    }
}
