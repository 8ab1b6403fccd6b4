//! Distortion of global grids by Tissot's indicatrix: how much cells of one quadtree level vary
//! in shape (maximum angular deformation ω) and in area (ratio of largest to smallest areal
//! scale) over the whole sphere.
//!
//! Each system is a set of charts, maps from a flat parameter domain (a cube face, an
//! octahedron face, a lat/lon square) to the unit sphere. At a fine level a cell is the image of
//! a small parameter square or triangle, so its shape and area ratios tend to the pointwise
//! Tissot values of the chart's Jacobian: the singular values a ≥ b of the 3×2 Jacobian give
//! ω = 2·asin((a − b)/(a + b)) and the areal scale s = a·b. Charts of one system are scaled so
//! that their cells at the same level have the same parameter area, so s is comparable across
//! them. The Jacobian is taken by central differences (step 1e-7, relative error < 1e-9).
//!
//! Systems: the three cube projections (the ECM paper, section 3), the octahedral Quaternary
//! Triangular Mesh with lat/lon midpoint subdivision (Bai, Zhao & Chen) and the six-face
//! 90°×90° lat/lon quadtree with circular polar faces (Porwal). See each chart for the exact
//! construction where the papers leave it open.

use std::f64::consts::{FRAC_PI_2, FRAC_PI_4};

use glam::DVec3;
use rayon::prelude::*;

use super::{CubeProjection, Face};

/// The grids compared by [`analyze`].
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum GridSystem {
    /// A cube map with one of the cube projections on every face.
    Cube(CubeProjection),
    /// Octahedral Quaternary Triangular Mesh, vertices subdivided at lat/lon midpoints.
    OctahedralQtm,
    /// Four 90°×90° lat/lon faces on the equator and two circular polar faces above ±45°.
    LatLonPolarCaps,
}

impl GridSystem {
    /// Every system, in the order of the printed table.
    pub const ALL: [GridSystem; 5] = [
        GridSystem::Cube(CubeProjection::Gnomonic),
        GridSystem::Cube(CubeProjection::AdjustedGnomonic),
        GridSystem::Cube(CubeProjection::Qsc),
        GridSystem::OctahedralQtm,
        GridSystem::LatLonPolarCaps,
    ];

    /// A short description for tables.
    pub fn label(self) -> &'static str {
        match self {
            GridSystem::Cube(CubeProjection::Gnomonic) => "cube, gnomonic",
            GridSystem::Cube(CubeProjection::AdjustedGnomonic) => "cube, adjusted gnomonic",
            GridSystem::Cube(CubeProjection::Qsc) => "cube, QSC (ECM)",
            GridSystem::OctahedralQtm => "octahedral QTM (lat/lon midpoints)",
            GridSystem::LatLonPolarCaps => "90x90 lat/lon faces + polar caps",
        }
    }

    /// The figures published for this system, (ω in degrees, area ratio), where a paper gives them.
    pub fn published(self) -> Option<(f64, f64)> {
        match self {
            GridSystem::Cube(CubeProjection::Gnomonic) => Some((31.1, 5.19)),
            GridSystem::Cube(CubeProjection::AdjustedGnomonic) => Some((31.1, 1.41)),
            GridSystem::Cube(CubeProjection::Qsc) => Some((24.9, 1.00)),
            _ => None,
        }
    }
}

/// Tissot's indicatrix at one point of a chart.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tissot {
    /// Maximum angular deformation ω in radians.
    pub omega_rad: f64,
    /// Areal scale a·b: sphere area per unit parameter area.
    pub areal_scale: f64,
}

/// A sample point where an extreme was found: the chart, its parameter coordinates and the
/// spherical latitude and longitude (degrees) of the point.
#[derive(Clone, Debug, PartialEq)]
pub struct Location {
    /// Which chart of the system (e.g. "face" or "polar cap quarter").
    pub chart: &'static str,
    /// Parameter coordinates in the chart (face x, y; or chart u, v).
    pub uv: (f64, f64),
    /// Spherical latitude in degrees.
    pub lat_deg: f64,
    /// Longitude in degrees.
    pub lon_deg: f64,
}

/// The result of [`analyze`] for one system.
#[derive(Clone, Debug, PartialEq)]
pub struct DistortionSummary {
    /// The system analysed.
    pub system: GridSystem,
    /// How it was sampled.
    pub sampling: Sampling,
    /// Largest ω over the sphere, in degrees.
    pub max_omega_deg: f64,
    /// Where the largest ω was found.
    pub max_omega_at: Location,
    /// Largest areal scale divided by the smallest.
    pub area_ratio: f64,
    /// Where the areal scale is largest.
    pub max_area_at: Location,
    /// Where the areal scale is smallest.
    pub min_area_at: Location,
    /// Number of points evaluated.
    pub samples: usize,
}

/// Tissot's indicatrix of a map from a parameter plane to the unit sphere at (u, v), from
/// central differences with step `h`. With a small `h` (1e-7) this is the pointwise indicatrix;
/// with `h` half a cell's width it is the indicatrix of the cell itself, the linear map that
/// takes the parameter cell to the one spanned by the midpoints of its edges on the sphere.
pub fn tissot(map: impl Fn(f64, f64) -> DVec3, u: f64, v: f64, h: f64) -> Tissot {
    let du = (map(u + h, v) - map(u - h, v)) / (2.0 * h);
    let dv = (map(u, v + h) - map(u, v - h)) / (2.0 * h);
    let (e, f, g) = (du.dot(du), du.dot(dv), dv.dot(dv));
    let areal_scale = du.cross(dv).length();
    let a = (0.5 * (e + g + ((e - g).powi(2) + 4.0 * f * f).sqrt())).sqrt();
    let b = areal_scale / a;
    Tissot { omega_rad: 2.0 * ((a - b) / (a + b)).clamp(-1.0, 1.0).asin(), areal_scale }
}

/// How a system is sampled.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Sampling {
    /// The pointwise indicatrix on about n×n points per chart, boundaries and corners
    /// approached to within 1e-5 (the supremum over the sphere, as in the ECM paper).
    Pointwise(usize),
    /// The indicatrix of every cell of this quadtree level (cells of 1/2^level of a root edge).
    Cells(u8),
}

/// Step of the pointwise central differences: relative error below 1e-8.
const POINT_STEP: f64 = 1e-7;

/// Distance kept from the boundaries where a chart is not smooth (QSC's diagonals, the QTM
/// apex), larger than the difference step.
const MARGIN: f64 = 1e-5;

/// One chart: a map from parameter (u, v) to a unit direction, the points where it is
/// evaluated with their difference step, and the factor that makes its areal scale comparable
/// with the system's other charts.
struct Chart {
    name: &'static str,
    map: Box<dyn Fn(f64, f64) -> DVec3 + Sync>,
    points: Vec<(f64, f64)>,
    step: f64,
    area_factor: f64,
    /// For square cells: integrate the areal scale over the cell (2×2 Gauss points) instead of
    /// taking it from the edge midpoints, so that an equal-area map gives exactly equal cells.
    square_cells: bool,
}

/// Cell centres of a square [lo, hi]² cut into `cells`² cells, and the half cell width.
fn cell_centres(lo: f64, hi: f64, cells: usize) -> (Vec<(f64, f64)>, f64) {
    let width = (hi - lo) / cells as f64;
    let centre = |i: usize| lo + (i as f64 + 0.5) * width;
    ((0..cells).flat_map(|i| (0..cells).map(move |j| (centre(i), centre(j)))).collect(), 0.5 * width)
}

fn cube_chart(projection: CubeProjection, sampling: Sampling) -> Chart {
    // All three projections are symmetric under the face's 8 rotations and reflections, so the
    // triangle 0 ≤ y ≤ x ≤ 1 (QSC's smooth area of definition, up to its diagonal) covers a face,
    // and all faces are alike. x = 1 is the face edge, approached exactly (the formulas extend
    // smoothly past it); the diagonal y = x is approached to within MARGIN. QSC is not
    // differentiable at the face centre (its scale there depends on the direction), so the
    // pointwise grid starts at x = CENTRE_GAP, where the difference step is 1e-4 of the distance
    // and the values have converged to their limits at the centre. Cells: the quadrant x, y ≥ 0.
    const CENTRE_GAP: f64 = 1e-3;
    let (points, step) = match sampling {
        Sampling::Pointwise(n) => {
            let mut points = Vec::new();
            for i in 0..=n {
                let x = CENTRE_GAP + (1.0 - CENTRE_GAP) * i as f64 / n as f64;
                for j in 0..=n {
                    points.push((x, (x - MARGIN) * j as f64 / n as f64));
                }
            }
            (points, POINT_STEP)
        }
        Sampling::Cells(level) => cell_centres(0.0, 1.0, 1usize << level.saturating_sub(1)),
    };
    Chart {
        name: "cube face",
        map: Box::new(move |x, y| Face::Front.ecef_from_local(projection.local_from_xy(x, y))),
        points,
        step,
        area_factor: 1.0,
        square_cells: matches!(sampling, Sampling::Cells(_)),
    }
}

fn sphere_point(lat: f64, lon: f64) -> DVec3 {
    let (sl, cl) = lat.sin_cos();
    let (so, co) = lon.sin_cos();
    DVec3::new(cl * co, cl * so, sl)
}

/// The QTM octant with vertices (0°, 0°), (0°, 90°) and the north pole, as an equilateral
/// triangle A = (0, 0), B = (1, 0), C = (½, √3/2). Recursive midpoint subdivision of latitudes
/// and longitudes (the pole taking the longitude of its partner) makes the barycentric weight γ
/// of C the latitude fraction and β/(α + β) the longitude fraction: lat = 90°·γ,
/// lon = 90°·β/(α + β). All eight octants are alike. Cells: the centroids of the 4^level
/// triangles, differenced over a third of their edge.
fn qtm_chart(sampling: Sampling) -> Chart {
    let h = 3f64.sqrt() / 2.0;
    let map = move |px: f64, py: f64| {
        let gamma = py / h;
        let beta = px - 0.5 * gamma;
        let alpha = 1.0 - beta - gamma;
        sphere_point(FRAC_PI_2 * gamma, FRAC_PI_2 * beta / (alpha + beta))
    };
    let mut points = Vec::new();
    let step = match sampling {
        Sampling::Pointwise(n) => {
            for i in 0..=n {
                // γ up to 1 − MARGIN: the apex itself is a singular point of the chart.
                let gamma = (1.0 - MARGIN) * i as f64 / n as f64;
                for j in 0..=n {
                    let beta = (1.0 - gamma) * j as f64 / n as f64;
                    points.push((beta + 0.5 * gamma, gamma * h));
                }
            }
            POINT_STEP
        }
        Sampling::Cells(level) => {
            let n = 1usize << level;
            let edge = 1.0 / n as f64;
            for row in 0..n {
                let gamma0 = row as f64 * edge;
                for k in 0..(n - row) {
                    let beta0 = k as f64 * edge;
                    // Upward triangle (β0, γ0), (β0 + e, γ0), (β0, γ0 + e): centroid at +e/3.
                    let up = (beta0 + edge / 3.0, gamma0 + edge / 3.0);
                    points.push((up.0 + 0.5 * up.1, up.1 * h));
                    if k + 1 < n - row {
                        let down = (beta0 + 2.0 * edge / 3.0, gamma0 + 2.0 * edge / 3.0);
                        points.push((down.0 + 0.5 * down.1, down.1 * h));
                    }
                }
            }
            edge / 3.0
        }
    };
    Chart { name: "octant", map: Box::new(map), points, step, area_factor: 1.0, square_cells: false }
}

/// Porwal's equatorial face: u, v in [0, 1] → lon 90°·u, lat −45° + 90°·v.
fn latlon_face_chart(sampling: Sampling) -> Chart {
    let map = |u: f64, v: f64| sphere_point(-FRAC_PI_4 + FRAC_PI_2 * v, FRAC_PI_2 * u);
    let (points, step) = match sampling {
        Sampling::Pointwise(n) => (grid_points(n), POINT_STEP),
        Sampling::Cells(level) => cell_centres(0.0, 1.0, 1usize << level),
    };
    Chart {
        name: "equatorial face",
        map: Box::new(map),
        points,
        step,
        area_factor: 1.0,
        square_cells: matches!(sampling, Sampling::Cells(_)),
    }
}

/// One quarter of Porwal's circular north polar face (the cap above 45°), corners: the pole,
/// (45°N, 0°), the arc midpoint (45°N, 45°) and (45°N, 90°). The paper subdivides it by edge
/// midpoints, so that the quarter's children have two circular and two straight sides; the
/// surface between the four edges is not specified, and here it is the Coons patch of the four
/// edges in the azimuthal equidistant plane of the pole (polar distance as radius), which is
/// the natural flat picture of a circular face. The quarter is a level-1 quad, so its cells at a
/// level have ¼ of the parameter area its own (u, v) gives them: area factor 4. Its corner at
/// the arc midpoint has a straight angle (both sides run along the 45° circle), so the chart is
/// degenerate there: pointwise, ω → 180° and the areal scale → 0; the cells touching that
/// corner are the worst of the system.
fn polar_quarter_chart(sampling: Sampling) -> Chart {
    let r = FRAC_PI_4;
    let map = move |u: f64, v: f64| {
        let arc = |angle: f64| glam::DVec2::new(r * angle.cos(), r * angle.sin());
        let c0 = glam::DVec2::new(u * r, 0.0); // pole → (45°N, 0°)
        let c1 = arc(FRAC_PI_2 - u * FRAC_PI_4); // (45°N, 90°) → midpoint
        let d0 = glam::DVec2::new(0.0, v * r); // pole → (45°N, 90°)
        let d1 = arc(v * FRAC_PI_4); // (45°N, 0°) → midpoint
        let (p10, p01, p11) = (arc(0.0), arc(FRAC_PI_2), arc(FRAC_PI_4));
        let q = (1.0 - v) * c0 + v * c1 + (1.0 - u) * d0 + u * d1
            - (u * (1.0 - v) * p10 + (1.0 - u) * v * p01 + u * v * p11);
        let rho = q.length();
        let sinc = if rho < 1e-8 { 1.0 - rho * rho / 6.0 } else { rho.sin() / rho };
        DVec3::new(q.x * sinc, q.y * sinc, rho.cos())
    };
    let (points, step) = match sampling {
        Sampling::Pointwise(n) => (grid_points(n), POINT_STEP),
        Sampling::Cells(level) => cell_centres(0.0, 1.0, 1usize << level.saturating_sub(1)),
    };
    Chart {
        name: "polar cap quarter",
        map: Box::new(map),
        points,
        step,
        area_factor: 4.0,
        square_cells: matches!(sampling, Sampling::Cells(_)),
    }
}

fn grid_points(n: usize) -> Vec<(f64, f64)> {
    (0..=n).flat_map(|i| (0..=n).map(move |j| (i as f64 / n as f64, j as f64 / n as f64))).collect()
}

fn charts(system: GridSystem, sampling: Sampling) -> Vec<Chart> {
    match system {
        GridSystem::Cube(projection) => vec![cube_chart(projection, sampling)],
        GridSystem::OctahedralQtm => vec![qtm_chart(sampling)],
        GridSystem::LatLonPolarCaps => vec![latlon_face_chart(sampling), polar_quarter_chart(sampling)],
    }
}

/// Evaluates Tissot's indicatrix over a system's charts and returns the extremes.
pub fn analyze(system: GridSystem, sampling: Sampling) -> DistortionSummary {
    let sampling = match sampling {
        Sampling::Pointwise(n) => Sampling::Pointwise(n.max(4)),
        Sampling::Cells(level) => Sampling::Cells(level.clamp(2, 12)),
    };
    let charts = charts(system, sampling);
    struct Sample {
        chart: usize,
        uv: (f64, f64),
        t: Tissot,
    }
    let samples: Vec<Sample> = charts
        .iter()
        .enumerate()
        .flat_map(|(index, chart)| {
            chart
                .points
                .par_iter()
                .map(|&(u, v)| {
                    let mut t = tissot(&chart.map, u, v, chart.step);
                    if chart.square_cells {
                        // 2×2 Gauss–Legendre points of the cell [u ± step] × [v ± step].
                        let g = chart.step / 3f64.sqrt();
                        let fine = POINT_STEP.min(chart.step * 1e-3);
                        t.areal_scale = [(-g, -g), (g, -g), (-g, g), (g, g)]
                            .iter()
                            .map(|(du, dv)| tissot(&chart.map, u + du, v + dv, fine).areal_scale)
                            .sum::<f64>()
                            / 4.0;
                    }
                    t.areal_scale *= chart.area_factor;
                    Sample { chart: index, uv: (u, v), t }
                })
                .collect::<Vec<_>>()
        })
        .collect();
    let location = |s: &Sample| {
        let d = (charts[s.chart].map)(s.uv.0, s.uv.1);
        Location {
            chart: charts[s.chart].name,
            uv: s.uv,
            lat_deg: d.z.asin().to_degrees(),
            lon_deg: d.y.atan2(d.x).to_degrees(),
        }
    };
    let by = |key: fn(&Sample) -> f64| {
        let max = samples.iter().max_by(|a, b| key(a).total_cmp(&key(b))).expect("charts have points");
        let min = samples.iter().min_by(|a, b| key(a).total_cmp(&key(b))).expect("charts have points");
        (max, min)
    };
    let (omega_max, _) = by(|s| s.t.omega_rad);
    let (area_max, area_min) = by(|s| s.t.areal_scale);
    DistortionSummary {
        system,
        sampling,
        max_omega_deg: omega_max.t.omega_rad.to_degrees(),
        max_omega_at: location(omega_max),
        area_ratio: area_max.t.areal_scale / area_min.t.areal_scale,
        max_area_at: location(area_max),
        min_area_at: location(area_min),
        samples: samples.len(),
    }
}

/// ω in degrees of a cube projection at the face corner (approached along the face edge), the
/// point the ECM paper reports.
pub fn cube_corner_omega_deg(projection: CubeProjection) -> f64 {
    let map = |x: f64, y: f64| projection.local_from_xy(x, y);
    tissot(map, 1.0, 1.0 - MARGIN, POINT_STEP).omega_rad.to_degrees()
}

/// Closed forms for the gnomonic cube at a face corner, where the angular distance from the
/// face centre is c with cos c = 1/√3: areal scale sec³c = 3√3 relative to the centre and
/// ω = 2·asin((sec c − 1)/(sec c + 1)). Used to check [`analyze`].
pub fn gnomonic_corner_closed_form() -> (f64, f64) {
    let sec_c = 3f64.sqrt();
    let omega = 2.0 * ((sec_c - 1.0) / (sec_c + 1.0)).asin();
    (omega.to_degrees(), sec_c.powi(3))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tissot_of_an_isometry_is_trivial() {
        // Near the pole of the azimuthal equidistant picture the map is locally isometric.
        let map = |u: f64, v: f64| {
            let rho = u.hypot(v);
            let s = if rho < 1e-12 { 1.0 } else { rho.sin() / rho };
            DVec3::new(u * s, v * s, rho.cos())
        };
        let t = tissot(map, 1e-4, 0.0, POINT_STEP);
        assert!(t.omega_rad.abs() < 1e-6 && (t.areal_scale - 1.0).abs() < 1e-6, "{t:?}");
    }

    #[test]
    fn gnomonic_cube_matches_closed_form_at_the_corner() {
        let s = analyze(GridSystem::Cube(CubeProjection::Gnomonic), Sampling::Pointwise(60));
        let (omega, ratio) = gnomonic_corner_closed_form();
        assert!((s.max_omega_deg - omega).abs() < 1e-3, "{} vs {omega}", s.max_omega_deg);
        assert!((s.area_ratio - ratio).abs() < 1e-3, "{} vs {ratio}", s.area_ratio);
        assert!((s.max_omega_at.uv.0 - 1.0).abs() < 1e-3 && (s.max_omega_at.uv.1 - 1.0).abs() < 1e-3);
    }

    #[test]
    fn qsc_is_equal_area_everywhere() {
        let s = analyze(GridSystem::Cube(CubeProjection::Qsc), Sampling::Pointwise(60));
        assert!((s.area_ratio - 1.0).abs() < 1e-6, "{} {:?} {:?}", s.area_ratio, s.max_area_at, s.min_area_at);
    }
}
