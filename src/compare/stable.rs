//! Stable terrain: the samples a co-registration fits its corrections on, where the ground did
//! not change. Either a layer's coverage (stable where that layer has data: a mask layer of
//! bedrock, say) or a vector file GDAL/OGR reads with polygons of *unstable* terrain (glacier
//! outlines, landslides), left out, as xDEM's `inlier_mask = ~outlines` does. The same selection
//! gives the area an uncertainty is propagated over (`compare --uncertainty --area`), with the
//! polygons' insides kept instead.
//!
//! Polygons are read in any CRS GDAL knows and transformed to the body's geographic CRS; a point
//! is inside by the even-odd rule over every ring of a polygon (so holes are stable), in
//! longitude and latitude (rings crossing ±180° are not supported and are refused).

use std::path::{Path, PathBuf};

use gdal::vector::LayerAccess;

use super::CompareError;
use super::coreg::RefSample;
use super::sample::operand_scene;
use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::geodesy::{Ellipsoid, geodetic_from_ecef};
use crate::layers::Operand;
use crate::project::Project;
use crate::scene::Scene;

/// Where stable terrain is.
#[derive(Clone, Debug, PartialEq)]
pub enum Stable {
    /// Where this layer of the project has data.
    Layer(String),
    /// Outside the polygons of this vector file.
    Outlines(PathBuf),
}

impl Stable {
    /// `--stable`'s value: a layer of the project by name, else a file.
    pub fn parse(layer_names: &[&str], text: &str) -> Stable {
        if layer_names.contains(&text) { Stable::Layer(text.into()) } else { Stable::Outlines(text.into()) }
    }

    /// How the JSON names it.
    pub fn describe(&self) -> String {
        match self {
            Stable::Layer(name) => format!("layer '{name}' (where it has data)"),
            Stable::Outlines(path) => format!("outside the polygons of {}", path.display()),
        }
    }

    /// How the JSON names it as an area (`--area`).
    pub fn describe_area(&self) -> String {
        match self {
            Stable::Layer(name) => format!("layer '{name}' (where it has data)"),
            Stable::Outlines(path) => format!("inside the polygons of {}", path.display()),
        }
    }
}

impl Stable {
    /// Per reference sample, whether the selection holds it: where the layer has data, or inside
    /// the outlines (`inside`) or outside them (stable terrain).
    pub(super) fn select(
        &self,
        scene: &Scene,
        project: &Project,
        quads: &[QuadId],
        reference: &[RefSample],
        inside: bool,
    ) -> Result<Vec<bool>, CompareError> {
        match self {
            Stable::Layer(name) => {
                let layer = operand_scene(scene, project, &Operand::Layer(name.clone()))?;
                let mut has_data = std::collections::HashMap::new();
                for chunk in quads.chunks(16) {
                    for (q, grid) in layer.compose_cpu(chunk)? {
                        has_data.insert(q, grid.iter().map(|v| !v.is_nan()).collect::<Vec<bool>>());
                    }
                }
                let n = GRID as usize;
                Ok(reference
                    .iter()
                    .map(|r| has_data.get(&r.quad).is_some_and(|g| g[usize::from(r.j) * n + usize::from(r.i)]))
                    .collect())
            }
            Stable::Outlines(path) => {
                let outlines = Outlines::read(path, &scene.ellipsoid)?;
                Ok(reference
                    .iter()
                    .map(|r| {
                        let g = geodetic_from_ecef(&scene.ellipsoid, r.p);
                        outlines.contains(g.lon_rad.to_degrees(), g.lat_rad.to_degrees()) == inside
                    })
                    .collect())
            }
        }
    }
}

/// A polygon: its rings (outer and holes) as closed lists of (lon, lat) degrees, and its box
/// (west, south, east, north).
type Polygon = (Vec<Vec<(f64, f64)>>, [f64; 4]);

/// A polygon wider than 180° of longitude: one that crosses ±180°, which outlines do not take.
#[derive(Clone, Copy, Debug, PartialEq, thiserror::Error)]
#[error("a polygon spans {span_deg:.1}° of longitude (one crossing ±180° is not supported)")]
pub struct AcrossAntimeridian {
    /// Its span, degrees.
    pub span_deg: f64,
}

/// The polygons of unstable terrain, in degrees of the body's geographic CRS.
#[derive(Clone, Debug, Default)]
pub struct Outlines {
    polygons: Vec<Polygon>,
}

impl Outlines {
    /// Reads every polygon and multipolygon of every layer of a vector file.
    pub fn read(path: &Path, body: &Ellipsoid) -> Result<Outlines, CompareError> {
        let fail = |problem: String| CompareError::File { path: path.to_path_buf(), problem };
        if !path.exists() {
            return Err(fail("no such file (and no layer of that name in the project)".into()));
        }
        let ds = gdal::Dataset::open(path)
            .map_err(|_| fail("is not a vector file GDAL/OGR can read (polygons of unstable terrain)".into()))?;
        let target = crate::store::source::body_geographic(body).map_err(|e| fail(format!("the body's CRS: {e}")))?;
        let mut out = Outlines::default();
        for mut layer in ds.layers() {
            for feature in layer.features() {
                let Some(geometry) = feature.geometry() else { continue };
                let geometry = match geometry.spatial_ref() {
                    Some(_) => geometry.transform_to(&target).map_err(|e| fail(format!("reprojecting: {e}")))?,
                    None => geometry.clone(),
                };
                out.add(&geometry).map_err(|e| fail(e.to_string()))?;
            }
        }
        if out.polygons.is_empty() {
            return Err(fail("holds no polygon".into()));
        }
        Ok(out)
    }

    fn add(&mut self, g: &gdal::vector::Geometry) -> Result<(), AcrossAntimeridian> {
        let kind = gdal::vector::geometry_type_flatten(g.geometry_type());
        match kind {
            gdal::vector::OGRwkbGeometryType::wkbPolygon => {
                let mut rings = Vec::new();
                for k in 0..g.geometry_count() {
                    let mut points = Vec::new();
                    g.get_geometry(k).get_points(&mut points);
                    rings.push(points.into_iter().map(|(x, y, _)| (x, y)).collect::<Vec<_>>());
                }
                self.push(rings)
            }
            gdal::vector::OGRwkbGeometryType::wkbMultiPolygon
            | gdal::vector::OGRwkbGeometryType::wkbGeometryCollection => {
                (0..g.geometry_count()).try_for_each(|k| self.add(&g.get_geometry(k)))
            }
            _ => Ok(()),
        }
    }

    /// Adds a polygon from its rings.
    pub fn push(&mut self, rings: Vec<Vec<(f64, f64)>>) -> Result<(), AcrossAntimeridian> {
        let mut b = [f64::INFINITY, f64::INFINITY, f64::NEG_INFINITY, f64::NEG_INFINITY];
        for &(x, y) in rings.iter().flatten() {
            b = [b[0].min(x), b[1].min(y), b[2].max(x), b[3].max(y)];
        }
        if b[2] - b[0] > 180.0 {
            return Err(AcrossAntimeridian { span_deg: b[2] - b[0] });
        }
        if b[0].is_finite() {
            self.polygons.push((rings, b));
        }
        Ok(())
    }

    /// Whether (lon, lat) degrees lies inside a polygon (even-odd over its rings).
    pub fn contains(&self, lon: f64, lat: f64) -> bool {
        self.polygons.iter().any(|(rings, b)| {
            lon >= b[0] && lon <= b[2] && lat >= b[1] && lat <= b[3] && {
                let mut inside = false;
                for ring in rings {
                    for k in 0..ring.len() {
                        let (a, c) = (ring[k], ring[(k + 1) % ring.len()]);
                        if (a.1 > lat) != (c.1 > lat) && lon < a.0 + (lat - a.1) / (c.1 - a.1) * (c.0 - a.0) {
                            inside = !inside;
                        }
                    }
                }
                inside
            }
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_polygon_with_a_hole_holds_its_ring_but_not_the_hole() {
        let square = |w: f64, e: f64| vec![(w, w), (e, w), (e, e), (w, e), (w, w)];
        let mut o = Outlines::default();
        o.push(vec![square(0.0, 10.0), square(4.0, 6.0)]).unwrap();
        assert!(o.contains(1.0, 1.0) && o.contains(9.0, 5.0));
        assert!(!o.contains(5.0, 5.0) && !o.contains(11.0, 5.0) && !o.contains(-1.0, 5.0));
        assert!(o.push(vec![vec![(-179.0, 0.0), (179.0, 0.0), (179.0, 1.0)]]).is_err());
        assert_eq!(Stable::parse(&["srtm"], "srtm"), Stable::Layer("srtm".into()));
        assert_eq!(Stable::parse(&["srtm"], "glaciers.geojson"), Stable::Outlines("glaciers.geojson".into()));
    }
}
