//! Terrain attributes of a height raster on the ellipsoid (`terrafuse export --attribute`): the
//! CPU reference of `shaders/attributes/attributes.wgsl` (keep in sync), in f64, deterministic
//! (each pixel alone; rows in parallel, which changes no result).
//!
//! Distances are true metres on the body: each pixel's grid steps are measured between its
//! neighbours' points on the ellipsoid and expressed in the east-north tangent plane there
//! ([`PixelAxes`]), whatever the raster's CRS (degrees, a projection's scale factor, a cube
//! face). The definitions are xDEM's, which are those of GDAL's `gdaldem` where both have them:
//!
//! - `slope`, `aspect`, `hillshade`: Horn (1981): the gradient from the 3 × 3 weighted differences
//!   (1, 2, 1), mapped to east and north through the pixel's two axes; slope in degrees, aspect
//!   the downslope direction in degrees clockwise from north, hillshade 1 + 254 · max(0, sin h ·
//!   cos s + cos h · sin s · cos(A − aspect)) with the light at azimuth A = 315° and height
//!   h = 45° (gdaldem's byte value before rounding);
//! - `curvature`, `planform_curvature`, `profile_curvature`: Zevenbergen & Thorne (1987)'s
//!   derivatives z_x, z_y, z_xx, z_yy, z_xy along the pixel's axes (lengths Lx, Ly; their shear,
//!   under 10⁻³ in the usual CRSs, is ignored here), curvature −2(z_xx + z_yy) and xDEM's
//!   geometric planform (Sobolevsky) and profile (Evans) curvatures, all in 100/m;
//! - `tpi`: Weiss (2001), the height less the mean of its 8 neighbours, metres;
//! - `tri`: Riley et al. (1999), √Σ (zᵢ − z)² over the 8 neighbours, metres;
//! - `roughness`: Wilson et al. (2007), the largest less the smallest of the 3 × 3, metres.
//!
//! A pixel whose 3 × 3 window leaves the raster or holds no data has none.

use glam::DVec3;
use rayon::prelude::*;

use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic, local_axes};

/// A terrain attribute.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Attribute {
    /// Degrees (Horn).
    Slope,
    /// Degrees clockwise from north, the direction the slope faces (Horn).
    Aspect,
    /// 1–255, lit from 315° at 45° (Horn).
    Hillshade,
    /// −2(z_xx + z_yy), 100/m (Zevenbergen & Thorne).
    Curvature,
    /// Geometric planform curvature, 100/m.
    PlanformCurvature,
    /// Geometric profile curvature, 100/m.
    ProfileCurvature,
    /// Topographic position index, metres.
    Tpi,
    /// Terrain ruggedness index (Riley), metres.
    Tri,
    /// Roughness, metres.
    Roughness,
}

impl Attribute {
    /// Every attribute, in the order the command line lists them.
    pub const ALL: [Attribute; 9] = [
        Attribute::Slope,
        Attribute::Aspect,
        Attribute::Hillshade,
        Attribute::Curvature,
        Attribute::PlanformCurvature,
        Attribute::ProfileCurvature,
        Attribute::Tpi,
        Attribute::Tri,
        Attribute::Roughness,
    ];

    /// The name the command line and files use.
    pub fn name(self) -> &'static str {
        match self {
            Attribute::Slope => "slope",
            Attribute::Aspect => "aspect",
            Attribute::Hillshade => "hillshade",
            Attribute::Curvature => "curvature",
            Attribute::PlanformCurvature => "planform_curvature",
            Attribute::ProfileCurvature => "profile_curvature",
            Attribute::Tpi => "tpi",
            Attribute::Tri => "tri",
            Attribute::Roughness => "roughness",
        }
    }

    /// The attribute of a name; None for another.
    pub fn parse(name: &str) -> Option<Attribute> {
        Attribute::ALL.into_iter().find(|a| a.name() == name)
    }

    /// The range a colour ramp over it spans by default: 0–45° of slope, 0–360° of aspect,
    /// hillshade's 1–255, and for the window attributes a span that shows the relief of a DEM of
    /// tens of metres (they scale with the sample spacing drawn; a project's `range_m` sets
    /// another).
    pub fn default_range(self) -> (f64, f64) {
        match self {
            Attribute::Slope => (0.0, 45.0),
            Attribute::Aspect => (0.0, 360.0),
            Attribute::Hillshade => (1.0, 255.0),
            Attribute::Curvature => (-2.0, 2.0),
            Attribute::PlanformCurvature | Attribute::ProfileCurvature => (-1.0, 1.0),
            Attribute::Tpi => (-5.0, 5.0),
            Attribute::Tri => (0.0, 30.0),
            Attribute::Roughness => (0.0, 50.0),
        }
    }

    /// Its unit as a symbol, for a legend or a slider.
    pub fn symbol(self) -> &'static str {
        match self {
            Attribute::Tpi | Attribute::Tri | Attribute::Roughness => "m",
            Attribute::Slope | Attribute::Aspect => "°",
            Attribute::Hillshade => "",
            Attribute::Curvature | Attribute::PlanformCurvature | Attribute::ProfileCurvature => "1/(100 m)",
        }
    }

    /// A legend's title: what it is, with its unit.
    pub fn title(self) -> &'static str {
        match self {
            Attribute::Slope => "slope (°)",
            Attribute::Aspect => "aspect (° from north)",
            Attribute::Hillshade => "hillshade (1–255)",
            Attribute::Curvature => "curvature (1/(100 m))",
            Attribute::PlanformCurvature => "planform curvature (1/(100 m))",
            Attribute::ProfileCurvature => "profile curvature (1/(100 m))",
            Attribute::Tpi => "TPI (m)",
            Attribute::Tri => "TRI (m)",
            Attribute::Roughness => "roughness (m)",
        }
    }

    /// Its unit, for a raster's metadata.
    pub fn unit(self) -> &'static str {
        match self {
            Attribute::Slope | Attribute::Aspect => "degrees",
            Attribute::Hillshade => "1-255",
            Attribute::Curvature | Attribute::PlanformCurvature | Attribute::ProfileCurvature => "1/(100 m)",
            Attribute::Tpi | Attribute::Tri | Attribute::Roughness => "metres",
        }
    }
}

/// The light of `hillshade`: azimuth, degrees clockwise from north.
pub const LIGHT_AZIMUTH_DEG: f64 = 315.0;
/// And its height above the horizon, degrees.
pub const LIGHT_ALTITUDE_DEG: f64 = 45.0;

/// A pixel's grid steps in its tangent plane: x (to the next column) and y (to the row above),
/// each as (east, north) metres.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PixelAxes {
    /// One column on, (east, north) metres.
    pub x: [f64; 2],
    /// One row up, (east, north) metres.
    pub y: [f64; 2],
}

impl PixelAxes {
    /// The gradient (∂z/∂east, ∂z/∂north) from the derivatives per step along x and y.
    pub fn gradient(&self, dz_dx: f64, dz_dy: f64) -> [f64; 2] {
        let [[a, b], [c, d]] = [self.x, self.y];
        let det = a * d - b * c;
        [(dz_dx * d - dz_dy * b) / det, (dz_dy * a - dz_dx * c) / det]
    }

    /// The steps' lengths, metres.
    pub fn lengths(&self) -> [f64; 2] {
        [self.x[0].hypot(self.x[1]), self.y[0].hypot(self.y[1])]
    }
}

/// Each pixel's axes from the pixels' geodetic points (latitude, longitude, radians; NaN outside
/// the CRS), row 0 at the top: half the chord to the neighbours on either side, projected on
/// the tangent plane (None at the border and next to a point outside the CRS).
pub fn pixel_axes(
    ellipsoid: &Ellipsoid,
    width: usize,
    height: usize,
    lat_lon: &[(f64, f64)],
) -> Vec<Option<PixelAxes>> {
    let points: Vec<DVec3> = lat_lon
        .iter()
        .map(|&(lat, lon)| ecef_from_geodetic(ellipsoid, Geodetic { lat_rad: lat, lon_rad: lon, height_m: 0.0 }))
        .collect();
    (0..width * height)
        .into_par_iter()
        .map(|k| {
            let (i, j) = (k % width, k / width);
            if i == 0 || j == 0 || i + 1 == width || j + 1 == height {
                return None;
            }
            let (lat, lon) = lat_lon[k];
            let (east, north) = local_axes(lon, lat);
            let x = (points[k + 1] - points[k - 1]) / 2.0;
            let y = (points[k - width] - points[k + width]) / 2.0;
            let axes = PixelAxes { x: [x.dot(east), x.dot(north)], y: [y.dot(east), y.dot(north)] };
            let ok = [axes.x, axes.y].as_flattened().iter().all(|v| v.is_finite());
            (ok && axes.x[0] * axes.y[1] - axes.x[1] * axes.y[0] != 0.0).then_some(axes)
        })
        .collect()
}

/// The attribute of a 3 × 3 window `z` (row 0 at the top: z[0] north-west … z[8] south-east)
/// with the centre pixel's axes.
pub fn attribute_at(attribute: Attribute, z: &[f64; 9], axes: &PixelAxes) -> f64 {
    let [nw, n, ne, w, c, e, sw, s, se] = *z;
    match attribute {
        Attribute::Slope | Attribute::Aspect | Attribute::Hillshade => {
            // Horn: the weighted differences per step along x (east-ish) and y (north-ish).
            let dz_dx = ((ne + 2.0 * e + se) - (nw + 2.0 * w + sw)) / 8.0;
            let dz_dy = ((nw + 2.0 * n + ne) - (sw + 2.0 * s + se)) / 8.0;
            let [ge, gn] = axes.gradient(dz_dx, dz_dy);
            let slope = ge.hypot(gn).atan();
            let aspect = (-ge).atan2(-gn).to_degrees().rem_euclid(360.0);
            match attribute {
                Attribute::Slope => slope.to_degrees(),
                Attribute::Aspect => aspect,
                _ => {
                    let (h, a) = (LIGHT_ALTITUDE_DEG.to_radians(), (LIGHT_AZIMUTH_DEG - aspect).to_radians());
                    let shade = h.sin() * slope.cos() + h.cos() * slope.sin() * a.cos();
                    1.0 + 254.0 * shade.max(0.0)
                }
            }
        }
        Attribute::Curvature | Attribute::PlanformCurvature | Attribute::ProfileCurvature => {
            let [lx, ly] = axes.lengths();
            let zx = (e - w) / (2.0 * lx);
            let zy = (n - s) / (2.0 * ly);
            let zxx = (w - 2.0 * c + e) / (lx * lx);
            let zyy = (n - 2.0 * c + s) / (ly * ly);
            let zxy = (ne - nw - se + sw) / (4.0 * lx * ly);
            let p = zx * zx + zy * zy;
            100.0
                * match attribute {
                    Attribute::Curvature => -2.0 * (zxx + zyy),
                    Attribute::PlanformCurvature if p >= 1e-14 => {
                        -(zxx * zy * zy - 2.0 * zxy * zx * zy + zyy * zx * zx) / p.powf(1.5)
                    }
                    Attribute::ProfileCurvature if p > 0.0 => {
                        -(zxx * zx * zx + 2.0 * zxy * zx * zy + zyy * zy * zy) / (p * (1.0 + p).powf(1.5))
                    }
                    _ => 0.0,
                }
        }
        Attribute::Tpi => c - (nw + n + ne + w + e + sw + s + se) / 8.0,
        Attribute::Tri => [nw, n, ne, w, e, sw, s, se].iter().map(|v| (v - c).powi(2)).sum::<f64>().sqrt(),
        Attribute::Roughness => {
            let (lo, hi) = z.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), &v| (l.min(v), h.max(v)));
            hi - lo
        }
    }
}

/// The attribute of a raster of heights (`width` × `height`, row 0 at the top, NaN no data)
/// with its pixels' axes ([`pixel_axes`]).
pub fn attribute_raster(
    attribute: Attribute,
    width: usize,
    height: usize,
    heights: &[f32],
    axes: &[Option<PixelAxes>],
) -> Vec<f32> {
    (0..width * height)
        .into_par_iter()
        .map(|k| {
            let Some(a) = axes[k] else { return f32::NAN };
            let mut z = [0.0; 9];
            for (m, v) in z.iter_mut().enumerate() {
                let (di, dj) = (m % 3, m / 3);
                *v = f64::from(heights[k + di - 1 + (dj * width) - width]);
            }
            if z.iter().any(|v| v.is_nan()) {
                return f32::NAN;
            }
            attribute_at(attribute, &z, &a) as f32
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Axes of a square grid of `step` metres aligned with east and north.
    fn square(step: f64) -> PixelAxes {
        PixelAxes { x: [step, 0.0], y: [0.0, step] }
    }

    /// The window of z = f(east, north) around the origin on a grid of `axes`.
    fn window(axes: &PixelAxes, f: impl Fn(f64, f64) -> f64) -> [f64; 9] {
        let mut z = [0.0; 9];
        for (m, v) in z.iter_mut().enumerate() {
            let (dx, dy) = ((m % 3) as f64 - 1.0, 1.0 - (m / 3) as f64);
            *v = f(dx * axes.x[0] + dy * axes.y[0], dx * axes.x[1] + dy * axes.y[1]);
        }
        z
    }

    #[test]
    fn a_plane_has_its_slope_and_aspect_on_any_grid() {
        // z = −0.3·east: 16.7° facing east, on a square grid and on a sheared, rotated one.
        let sheared = PixelAxes { x: [25.0, 10.0], y: [-5.0, 40.0] };
        for axes in [square(30.0), sheared] {
            let z = window(&axes, |e, _| -0.3 * e);
            assert!((attribute_at(Attribute::Slope, &z, &axes) - 0.3f64.atan().to_degrees()).abs() < 1e-9);
            assert!((attribute_at(Attribute::Aspect, &z, &axes) - 90.0).abs() < 1e-9);
        }
        // Facing north-west, towards the light: the brightest hillshade for its slope.
        let axes = square(30.0);
        let z = window(&axes, |e, n| 0.2 * e - 0.2 * n);
        assert!((attribute_at(Attribute::Aspect, &z, &axes) - 315.0).abs() < 1e-9);
        let s = (0.2f64 * 2f64.sqrt()).atan();
        let want =
            1.0 + 254.0 * (std::f64::consts::FRAC_PI_4.sin() * s.cos() + std::f64::consts::FRAC_PI_4.cos() * s.sin());
        assert!((attribute_at(Attribute::Hillshade, &z, &axes) - want).abs() < 1e-9);
    }

    #[test]
    fn a_paraboloid_has_its_curvatures_and_the_windowed_indices_their_sums() {
        // z = −(e² + n²)/(2R), a dome of radius R = 500 m: curvature −2(z_xx + z_yy) = 4/R per metre.
        let axes = square(10.0);
        let r = 500.0;
        let z = window(&axes, |e, n| -(e * e + n * n) / (2.0 * r));
        assert!((attribute_at(Attribute::Curvature, &z, &axes) - 100.0 * 4.0 / r).abs() < 1e-9);
        // At the top the gradient is 0: planform and profile are 0 by definition.
        assert_eq!(attribute_at(Attribute::ProfileCurvature, &z, &axes), 0.0);
        // TPI: the centre 0 less the neighbours' mean −(4·100 + 4·200)/(8·1000).
        assert!((attribute_at(Attribute::Tpi, &z, &axes) - 0.15).abs() < 1e-12);
        assert!((attribute_at(Attribute::Roughness, &z, &axes) - 0.2).abs() < 1e-12);
        let tri = (4.0f64 * 0.1 * 0.1 + 4.0 * 0.2 * 0.2).sqrt();
        assert!((attribute_at(Attribute::Tri, &z, &axes) - tri).abs() < 1e-12);
        // On a slope across a dome's flank, the profile curvature of a sphere of radius R is 1/R.
        let z = window(&axes, |e, n| (r * r - (e + 200.0).powi(2) - n * n).sqrt());
        let k = attribute_at(Attribute::ProfileCurvature, &z, &axes);
        assert!((k - 100.0 / r).abs() < 1e-3, "{k}");
    }

    #[test]
    fn every_name_parses_back() {
        for a in Attribute::ALL {
            assert_eq!(Attribute::parse(a.name()), Some(a));
        }
        assert_eq!(Attribute::parse("slopes"), None);
    }
}
