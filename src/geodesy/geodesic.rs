//! Geodesics on the ellipsoid by Vincenty's formulae (1975): the inverse problem (distance and
//! azimuths between two points) and the direct one (the point at a distance along an azimuth),
//! iterated to 10⁻¹² rad, which is about 0.1 mm; Vincenty's inverse does not converge for nearly
//! antipodal points, which are refused. Tested against GeographicLib's `GeodSolve`.

use super::Ellipsoid;

/// A geodesic that cannot be computed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("the geodesic from ({lat1}°, {lon1}°) to ({lat2}°, {lon2}°) does not converge (nearly antipodal points)")]
pub struct GeodesicError {
    /// Latitude of the first point, degrees.
    pub lat1: f64,
    /// Longitude of the first point, degrees.
    pub lon1: f64,
    /// Latitude of the second point, degrees.
    pub lat2: f64,
    /// Longitude of the second point, degrees.
    pub lon2: f64,
}

/// The inverse problem: (distance metres, forward azimuth at 1 radians, azimuth at 2 radians)
/// between two points given in radians.
pub fn inverse(e: &Ellipsoid, lat1: f64, lon1: f64, lat2: f64, lon2: f64) -> Result<(f64, f64, f64), GeodesicError> {
    let (a, b) = (e.a_m(), e.b_m());
    let f = (a - b) / a;
    let u1 = ((1.0 - f) * lat1.tan()).atan();
    let u2 = ((1.0 - f) * lat2.tan()).atan();
    let l = lon2 - lon1;
    let (su1, cu1) = u1.sin_cos();
    let (su2, cu2) = u2.sin_cos();
    let mut lambda = l;
    for _ in 0..200 {
        let (sl, cl) = lambda.sin_cos();
        let sin_sigma = ((cu2 * sl).powi(2) + (cu1 * su2 - su1 * cu2 * cl).powi(2)).sqrt();
        if sin_sigma == 0.0 {
            return Ok((0.0, 0.0, 0.0));
        }
        let cos_sigma = su1 * su2 + cu1 * cu2 * cl;
        let sigma = sin_sigma.atan2(cos_sigma);
        let sin_alpha = cu1 * cu2 * sl / sin_sigma;
        let cos2_alpha = 1.0 - sin_alpha * sin_alpha;
        let cos_2sm = if cos2_alpha != 0.0 { cos_sigma - 2.0 * su1 * su2 / cos2_alpha } else { 0.0 };
        let c = f / 16.0 * cos2_alpha * (4.0 + f * (4.0 - 3.0 * cos2_alpha));
        let previous = lambda;
        lambda = l
            + (1.0 - c)
                * f
                * sin_alpha
                * (sigma + c * sin_sigma * (cos_2sm + c * cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)));
        if (lambda - previous).abs() < 1e-12 {
            let u2sq = cos2_alpha * (a * a - b * b) / (b * b);
            let big_a = 1.0 + u2sq / 16384.0 * (4096.0 + u2sq * (-768.0 + u2sq * (320.0 - 175.0 * u2sq)));
            let big_b = u2sq / 1024.0 * (256.0 + u2sq * (-128.0 + u2sq * (74.0 - 47.0 * u2sq)));
            let delta_sigma = big_b
                * sin_sigma
                * (cos_2sm
                    + big_b / 4.0
                        * (cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)
                            - big_b / 6.0
                                * cos_2sm
                                * (-3.0 + 4.0 * sin_sigma * sin_sigma)
                                * (-3.0 + 4.0 * cos_2sm * cos_2sm)));
            let s = b * big_a * (sigma - delta_sigma);
            let (sl, cl) = lambda.sin_cos();
            let az1 = (cu2 * sl).atan2(cu1 * su2 - su1 * cu2 * cl);
            let az2 = (cu1 * sl).atan2(-su1 * cu2 + cu1 * su2 * cl);
            return Ok((s, az1, az2));
        }
    }
    let d = f64::to_degrees;
    Err(GeodesicError { lat1: d(lat1), lon1: d(lon1), lat2: d(lat2), lon2: d(lon2) })
}

/// The direct problem: the point (lat, lon radians) at distance `s` metres from (lat1, lon1)
/// along azimuth `az1` (radians from north, clockwise).
pub fn direct(e: &Ellipsoid, lat1: f64, lon1: f64, az1: f64, s: f64) -> (f64, f64) {
    let (a, b) = (e.a_m(), e.b_m());
    let f = (a - b) / a;
    let (sa1, ca1) = az1.sin_cos();
    let tan_u1 = (1.0 - f) * lat1.tan();
    let cu1 = 1.0 / (1.0 + tan_u1 * tan_u1).sqrt();
    let su1 = tan_u1 * cu1;
    let sigma1 = tan_u1.atan2(ca1);
    let sin_alpha = cu1 * sa1;
    let cos2_alpha = 1.0 - sin_alpha * sin_alpha;
    let u2sq = cos2_alpha * (a * a - b * b) / (b * b);
    let big_a = 1.0 + u2sq / 16384.0 * (4096.0 + u2sq * (-768.0 + u2sq * (320.0 - 175.0 * u2sq)));
    let big_b = u2sq / 1024.0 * (256.0 + u2sq * (-128.0 + u2sq * (74.0 - 47.0 * u2sq)));
    let mut sigma = s / (b * big_a);
    let (mut sin_sigma, mut cos_sigma, mut cos_2sm);
    loop {
        cos_2sm = (2.0 * sigma1 + sigma).cos();
        (sin_sigma, cos_sigma) = sigma.sin_cos();
        let delta_sigma = big_b
            * sin_sigma
            * (cos_2sm
                + big_b / 4.0
                    * (cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)
                        - big_b / 6.0
                            * cos_2sm
                            * (-3.0 + 4.0 * sin_sigma * sin_sigma)
                            * (-3.0 + 4.0 * cos_2sm * cos_2sm)));
        let next = s / (b * big_a) + delta_sigma;
        if (next - sigma).abs() < 1e-12 {
            sigma = next;
            break;
        }
        sigma = next;
    }
    (sin_sigma, cos_sigma) = sigma.sin_cos();
    cos_2sm = (2.0 * sigma1 + sigma).cos();
    let x = su1 * sin_sigma - cu1 * cos_sigma * ca1;
    let lat2 = (su1 * cos_sigma + cu1 * sin_sigma * ca1).atan2((1.0 - f) * (sin_alpha * sin_alpha + x * x).sqrt());
    let lambda = (sin_sigma * sa1).atan2(cu1 * cos_sigma - su1 * sin_sigma * ca1);
    let c = f / 16.0 * cos2_alpha * (4.0 + f * (4.0 - 3.0 * cos2_alpha));
    let l = lambda
        - (1.0 - c)
            * f
            * sin_alpha
            * (sigma + c * sin_sigma * (cos_2sm + c * cos_sigma * (-1.0 + 2.0 * cos_2sm * cos_2sm)));
    let lon2 = (lon1 + l + std::f64::consts::PI).rem_euclid(std::f64::consts::TAU) - std::f64::consts::PI;
    (lat2, lon2)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn direct_undoes_inverse_and_a_meridian_arc_matches_its_series() {
        let e = Ellipsoid::WGS84;
        let r = f64::to_radians;
        let (s, az1, _) = inverse(&e, r(39.2), r(40.1), r(39.9), r(40.7)).unwrap();
        let (lat, lon) = direct(&e, r(39.2), r(40.1), az1, s);
        assert!((lat - r(39.9)).abs() < 1e-11 && (lon - r(40.7)).abs() < 1e-11, "{lat} {lon}");
        // Equator to pole along a meridian: the quarter meridian of WGS84, 10 001 965.729 m.
        let (q, _, _) = inverse(&e, 0.0, 0.0, r(90.0), 0.0).unwrap();
        assert!((q - 10_001_965.729).abs() < 1e-3, "{q}");
    }
}
