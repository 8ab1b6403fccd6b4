//! A layer's extent and its feathered mask: 0 outside, 1 at `feather_m` inside the edge and
//! beyond, smoothstep between; the distance to the edge is measured in metres on the ellipsoid,
//! so a feather looks the same at every latitude and across cube face edges.
//!
//! The edge is straight in longitude and latitude (a box's edges follow parallels and meridians).
//! Inside/outside is decided in longitude and latitude (even–odd rule); the distance is the
//! shortest 3-D distance from the sample to the edge densified into chords of at most
//! [`DENSIFY_DEG`] between points on the ellipsoid. Two approximations, both bounded: a chord of
//! length c sags c²/(8R) below the surface (≤ 0.6 m on Earth, 0.16 m on the Moon at 0.05°), and a
//! straight-line distance d is shorter than the arc by d³/(24R²) (1 m at 100 km on Earth).
//! Where the mask matters, between 0 and `feather_m`, both are far below any feather worth
//! setting. CPU reference of `extent_mask` in `shaders/compose/compose.wgsl` (keep in sync).

use crate::maths::{segment_distance_m, smoothstep};
use glam::DVec3;

use super::spec::ExtentSpec;
use crate::geodesy::{Ellipsoid, Geodetic, ecef_from_geodetic};

/// Longest step, in degrees of longitude or latitude, of the densified edge.
pub const DENSIFY_DEG: f64 = 0.05;
/// Segments a block of the GPU's nearest-segment search (`extent_mask` in compose.wgsl): the
/// 7 200 segments of a circle of latitude cost each sample 225 sphere tests and the few blocks
/// near it, not 7 200 segment distances.
pub const MASK_BLOCK: usize = 32;

/// A compiled extent.
#[derive(Clone, Debug, PartialEq)]
pub struct Extent {
    /// Vertices (lon, lat) in radians, longitudes continuous (no jump of 2π between neighbours).
    pub ring_rad: Vec<[f64; 2]>,
    /// The smallest longitude of the ring: sample longitudes are wrapped into
    /// [lon_min, lon_min + 2π) before the inside test.
    pub lon_min_rad: f64,
    /// The edge as chords between points on the ellipsoid, ECEF metres.
    pub segments: Vec<[DVec3; 2]>,
    /// The fade-in distance, metres.
    pub feather_m: f64,
    /// For a box: west, south, east (≥ west, unwrapped), north in radians, tested directly
    /// (so a cap up to a pole contains the pole).
    pub box_rad: Option<[f64; 4]>,
}

/// How an extent meets a quad.
#[derive(Clone, Debug, PartialEq)]
pub enum Relation {
    /// No sample is inside: the layer adds nothing to the quad.
    Outside,
    /// Every sample is inside and at least `feather_m` from the edge: the mask is 1.
    Inside,
    /// The edge or its feather crosses the quad: these segments are the only ones within the
    /// feather of any sample.
    Partial(NearEdge),
}

/// The segments of an extent's edge near a quad, and a sphere (centre, radius) around each
/// block of [`MASK_BLOCK`] of them, which [`Extent::nearest_m`] and the GPU's `extent_mask`
/// search block by block.
#[derive(Clone, Debug, PartialEq)]
pub struct NearEdge {
    /// Indices into [`Extent::segments`], ascending.
    pub segments: Vec<u32>,
    /// One sphere a block of `segments` ([`Extent::block_sphere`]).
    pub spheres: Vec<(DVec3, f64)>,
}

impl Extent {
    /// Compiles an extent (checked by `LayerSpec::check`) on a body.
    pub fn new(spec: &ExtentSpec, feather_m: f64, ellipsoid: &Ellipsoid) -> Extent {
        let ring_deg: Vec<[f64; 2]> = match spec {
            ExtentSpec::Box([w, s, e, n]) => {
                let e = if e < w { e + 360.0 } else { *e };
                vec![[*w, *s], [e, *s], [e, *n], [*w, *n]]
            }
            ExtentSpec::Polygon(ring) => ring.clone(),
        };
        let ring_rad: Vec<[f64; 2]> = ring_deg.iter().map(|[lon, lat]| [lon.to_radians(), lat.to_radians()]).collect();
        let lon_min_rad = ring_rad.iter().map(|v| v[0]).fold(f64::INFINITY, f64::min);
        // A box around the whole parallel is a latitude band: its meridian sides are no edge.
        let band = matches!(spec, ExtentSpec::Box(_)) && ring_deg[1][0] - ring_deg[0][0] >= 360.0;
        let mut segments = Vec::new();
        for k in 0..ring_deg.len() {
            let (a, b) = (ring_deg[k], ring_deg[(k + 1) % ring_deg.len()]);
            let on_pole = a[1] == b[1] && a[1].abs() == 90.0;
            let meridian_of_band = band && a[0] == b[0];
            if on_pole || meridian_of_band {
                continue; // a pole is a point, not an edge
            }
            let steps = ((b[0] - a[0]).abs().max((b[1] - a[1]).abs()) / DENSIFY_DEG).ceil().max(1.0) as usize;
            let point = |t: f64| {
                let (lon, lat) = (a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t);
                ecef_from_geodetic(ellipsoid, Geodetic::from_degrees(lat, lon, 0.0))
            };
            let mut prev = point(0.0);
            for s in 1..=steps {
                let next = point(s as f64 / steps as f64);
                segments.push([prev, next]);
                prev = next;
            }
        }
        let box_rad = match spec {
            ExtentSpec::Box(_) => Some([ring_rad[0][0], ring_rad[0][1], ring_rad[2][0], ring_rad[2][1]]),
            ExtentSpec::Polygon(_) => None,
        };
        Extent { ring_rad, lon_min_rad, segments, feather_m, box_rad }
    }

    /// Whether a point (radians) is inside: a box by its bounds (edges included), a polygon by
    /// the even–odd rule in longitude and latitude.
    pub fn contains(&self, lon_rad: f64, lat_rad: f64) -> bool {
        let tau = std::f64::consts::TAU;
        let lon = self.lon_min_rad + (lon_rad - self.lon_min_rad).rem_euclid(tau);
        if let Some([w, s, e, n]) = self.box_rad {
            return lat_rad >= s && lat_rad <= n && lon >= w && lon <= e;
        }
        let mut inside = false;
        let n = self.ring_rad.len();
        for k in 0..n {
            let [x0, y0] = self.ring_rad[k];
            let [x1, y1] = self.ring_rad[(k + 1) % n];
            if (y0 > lat_rad) != (y1 > lat_rad) {
                let x = x0 + (lat_rad - y0) / (y1 - y0) * (x1 - x0);
                if lon < x {
                    inside = !inside;
                }
            }
        }
        inside
    }

    /// +1 where the ring runs counter-clockwise in (longitude, latitude), so that the inside is
    /// on the left of each edge; −1 otherwise (the GPU's side test near the edge needs it).
    pub fn orientation(&self) -> f64 {
        let n = self.ring_rad.len();
        let area: f64 = (0..n)
            .map(|k| {
                let ([x0, y0], [x1, y1]) = (self.ring_rad[k], self.ring_rad[(k + 1) % n]);
                x0 * y1 - x1 * y0
            })
            .sum();
        if area >= 0.0 { 1.0 } else { -1.0 }
    }

    /// The distance from `p` to the nearest of the given segments, metres (∞ for none).
    pub fn distance_m(&self, p: DVec3, segments: &[u32]) -> f64 {
        segments
            .iter()
            .map(|&k| {
                let [a, b] = self.segments[k as usize];
                segment_distance_m(p, a, b)
            })
            .fold(f64::INFINITY, f64::min)
    }

    /// A sphere around the given segments (their endpoints' mean, and the largest distance
    /// from it, widened by a millimetre a kilometre and half a metre so that the GPU's f32
    /// test of a point against it never skips the nearest segment): a segment lies inside the
    /// sphere around its endpoints, so no point of a block is nearer to p than |p − centre| −
    /// radius, and the GPU skips blocks that are farther than the nearest segment found yet
    /// ([`MASK_BLOCK`] segments a block).
    pub fn block_sphere(&self, block: &[u32]) -> (DVec3, f64) {
        let ends = || block.iter().flat_map(|&k| self.segments[k as usize]);
        let centre = ends().sum::<DVec3>() / (2 * block.len().max(1)) as f64;
        let radius = ends().map(|p| p.distance(centre)).fold(0.0, f64::max);
        (centre, radius * (1.0 + 1e-6) + 0.5)
    }

    /// The segments near a quad with their blocks' spheres.
    pub fn near_edge(&self, segments: Vec<u32>) -> NearEdge {
        let spheres = segments.chunks(MASK_BLOCK).map(|b| self.block_sphere(b)).collect();
        NearEdge { segments, spheres }
    }

    /// The distance from `p` to the nearest segment near the quad, metres (∞ for none): the
    /// GPU's `extent_mask` search. No segment of a block is farther than |p − centre| + radius,
    /// so the nearest of those bounds the search before it starts, and a block whose sphere
    /// lies farther than that bound or the nearest segment found yet cannot hold a nearer one:
    /// the result is [`Extent::distance_m`]'s over all of them, from a few blocks.
    pub fn nearest_m(&self, p: DVec3, near: &NearEdge) -> f64 {
        let bound = near.spheres.iter().map(|&(c, r)| p.distance(c) + r).fold(f64::INFINITY, f64::min);
        let mut d = f64::INFINITY;
        for (block, &(centre, radius)) in near.segments.chunks(MASK_BLOCK).zip(&near.spheres) {
            if p.distance(centre) - radius > d.min(bound) {
                continue;
            }
            d = d.min(self.distance_m(p, block));
        }
        d
    }

    /// The mask at a sample: 0 outside, smoothstep(d / feather) inside.
    pub fn mask(&self, inside: bool, distance_m: f64) -> f64 {
        if !inside {
            0.0
        } else if self.feather_m <= 0.0 {
            1.0
        } else {
            smoothstep(distance_m / self.feather_m)
        }
    }

    /// How the extent meets the region within `radius_m` of `centre` (a point on the ellipsoid
    /// at `centre_lon_lat_rad`).
    pub fn relation(&self, centre: DVec3, centre_lon_lat_rad: (f64, f64), radius_m: f64) -> Relation {
        let reach = radius_m + self.feather_m;
        let near: Vec<u32> = (0..self.segments.len() as u32)
            .filter(|&k| {
                let [a, b] = self.segments[k as usize];
                segment_distance_m(centre, a, b) <= reach
            })
            .collect();
        if !near.is_empty() {
            Relation::Partial(self.near_edge(near))
        } else if self.contains(centre_lon_lat_rad.0, centre_lon_lat_rad.1) {
            Relation::Inside
        } else {
            Relation::Outside
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::geodesy::geodetic_from_ecef;

    fn at(lat: f64, lon: f64) -> DVec3 {
        ecef_from_geodetic(&Ellipsoid::WGS84, Geodetic::from_degrees(lat, lon, 0.0))
    }

    #[test]
    fn boxes_contain_what_they_should_also_across_the_antimeridian() {
        let e = Extent::new(&ExtentSpec::Box([170.0, -10.0, -170.0, 10.0]), 0.0, &Ellipsoid::WGS84);
        let r = |d: f64| d.to_radians();
        assert!(e.contains(r(179.0), 0.0));
        assert!(e.contains(r(-175.0), r(5.0)));
        assert!(!e.contains(r(0.0), 0.0));
        assert!(!e.contains(r(175.0), r(11.0)));
        let p = Extent::new(&ExtentSpec::Polygon(vec![[0.0, 0.0], [10.0, 0.0], [0.0, 10.0]]), 0.0, &Ellipsoid::WGS84);
        assert!(p.contains(r(2.0), r(2.0)));
        assert!(!p.contains(r(6.0), r(6.0)));
    }

    #[test]
    fn the_distance_is_metres_on_the_ellipsoid_at_any_latitude() {
        // 0.1° of latitude north of a box's southern edge, at the equator and at 70°N: the
        // meridian arc (computed independently by geodesy) is the distance, within a millimetre.
        for lat0 in [0.0, 70.0] {
            let e = Extent::new(&ExtentSpec::Box([10.0, lat0, 11.0, lat0 + 1.0]), 0.0, &Ellipsoid::WGS84);
            let all: Vec<u32> = (0..e.segments.len() as u32).collect();
            let p = at(lat0 + 0.1, 10.5);
            let d = e.distance_m(p, &all);
            // Meridian arc: integrate M(φ) dφ numerically.
            let wgs = Ellipsoid::WGS84;
            let arc: f64 = (0..1000)
                .map(|k| {
                    let phi = (lat0 + 0.1 * (k as f64 + 0.5) / 1000.0).to_radians();
                    let m = wgs.a_m() * (1.0 - wgs.e2()) / (1.0 - wgs.e2() * phi.sin().powi(2)).powf(1.5);
                    m * (0.1f64).to_radians() / 1000.0
                })
                .sum();
            assert!((d - arc).abs() < 1e-3 * arc.max(1.0) + 0.01, "lat {lat0}: {d} vs {arc}");
            let g = geodetic_from_ecef(&wgs, p);
            assert!(e.contains(g.lon_rad, g.lat_rad));
        }
    }

    #[test]
    fn a_polar_cap_has_one_edge_its_parallel() {
        let cap = Extent::new(&ExtentSpec::Box([-180.0, 70.0, 180.0, 90.0]), 30_000.0, &Ellipsoid::MOON);
        let all: Vec<u32> = (0..cap.segments.len() as u32).collect();
        let moon = Ellipsoid::MOON;
        let p = |lat: f64, lon: f64| ecef_from_geodetic(&moon, Geodetic::from_degrees(lat, lon, 0.0));
        // The pole and the antimeridian are deep inside; the distance is to the 70° parallel.
        let arc = |lat: f64| moon.a_m() * (lat - 70.0f64).to_radians();
        for (lat, lon) in [(90.0, 0.0), (80.0, 180.0), (80.0, -179.99), (71.0, 45.0)] {
            let d = cap.distance_m(p(lat, lon), &all);
            let chord = 2.0 * moon.a_m() * ((lat - 70.0f64).to_radians() / 2.0).sin();
            assert!((d - chord).abs() < 1.0, "({lat}, {lon}): {d} vs chord {chord} (arc {})", arc(lat));
            assert!(cap.contains(lon.to_radians(), lat.to_radians()));
        }
        assert!(!cap.contains(0.0, 69f64.to_radians()));
    }

    #[test]
    fn a_blocks_sphere_holds_its_segments_and_skipping_far_blocks_finds_the_nearest() {
        // Every point of every segment of a block lies inside its sphere, and the block search
        // (nearest_m, the GPU's extent_mask) finds the full search's distance, near the cap's
        // parallel and far from it, searching under a tenth of the blocks.
        let cap = Extent::new(&ExtentSpec::Box([-180.0, 70.6, 180.0, 90.0]), 30_000.0, &Ellipsoid::MOON);
        let all: Vec<u32> = (0..cap.segments.len() as u32).collect();
        assert_eq!(all.len(), 7200);
        let spheres: Vec<(DVec3, f64)> = all.chunks(MASK_BLOCK).map(|b| cap.block_sphere(b)).collect();
        for (block, &(centre, radius)) in all.chunks(MASK_BLOCK).zip(&spheres) {
            for &k in block {
                let [a, b] = cap.segments[k as usize];
                for t in [0.0, 0.25, 0.5, 0.75, 1.0] {
                    assert!((a + (b - a) * t).distance(centre) <= radius);
                }
            }
        }
        let moon = Ellipsoid::MOON;
        let near = cap.near_edge(all.clone());
        assert_eq!(near.spheres, spheres);
        for (lat, lon) in [(70.61, 10.0), (71.0, -179.99), (80.0, 33.3), (90.0, 0.0), (60.0, 120.0)] {
            let p = ecef_from_geodetic(&moon, Geodetic::from_degrees(lat, lon, 0.0));
            assert_eq!(cap.nearest_m(p, &near), cap.distance_m(p, &all), "({lat}, {lon})");
            // Few blocks are searched but at the pole, where every segment is as near.
            let bound = spheres.iter().map(|&(c, r)| p.distance(c) + r).fold(f64::INFINITY, f64::min);
            let searched = spheres.iter().filter(|&&(c, r)| p.distance(c) - r <= bound).count();
            assert!(lat == 90.0 || searched * 10 < spheres.len(), "({lat}, {lon}): {searched} blocks searched");
        }
        // The GPU's search uses the same block size.
        let shader = include_str!("../../shaders/compose/compose.wgsl");
        assert!(shader.contains(&format!("const MASK_BLOCK: u32 = {MASK_BLOCK}u;")));
    }

    #[test]
    fn relations_cull_and_the_mask_feathers() {
        let e = Extent::new(&ExtentSpec::Box([10.0, 10.0, 12.0, 12.0]), 20_000.0, &Ellipsoid::WGS84);
        let r = |d: f64| d.to_radians();
        assert_eq!(e.relation(at(11.0, 11.0), (r(11.0), r(11.0)), 10_000.0), Relation::Inside);
        assert_eq!(e.relation(at(0.0, 0.0), (0.0, 0.0), 10_000.0), Relation::Outside);
        assert!(matches!(e.relation(at(10.1, 11.0), (r(11.0), r(10.1)), 10_000.0), Relation::Partial(_)));
        assert_eq!(e.mask(false, 5.0), 0.0);
        assert_eq!(e.mask(true, 0.0), 0.0);
        assert_eq!(e.mask(true, 10_000.0), 0.5);
        assert_eq!(e.mask(true, 30_000.0), 1.0);
    }
}
