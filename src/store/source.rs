//! A source raster, read through GDAL: checked on open (so bad input is refused before the store
//! is touched), then read by each worker thread through its own handle, in windows.

use std::path::{Path, PathBuf};

use gdal::Dataset;
use gdal::Metadata;
use gdal::raster::GdalDataType;
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};

use super::StoreError;
use crate::geodesy::{self, Ellipsoid, Geodetic};

/// The largest raster accepted: 2⁴⁰ pixels (a global 1″ grid has 8·10¹¹).
pub const MAX_PIXELS: u64 = 1 << 40;

/// What is known about a source once it has been checked.
#[derive(Clone, Debug)]
pub struct SourceInfo {
    /// The file, absolute.
    pub path: PathBuf,
    /// GDAL driver short name.
    pub driver: String,
    /// Width and height in pixels.
    pub size: (usize, usize),
    /// GDAL geotransform (pixel corners, whatever the file's pixel convention).
    pub geo_transform: [f64; 6],
    inverse: [f64; 6],
    /// The CRS as WKT.
    pub crs_wkt: String,
    /// The CRS in PROJ syntax.
    pub crs_proj: String,
    /// Whether the CRS is geographic (degrees).
    pub geographic: bool,
    /// Whether columns wrap around (a geographic grid spanning 360°).
    pub wraps: bool,
    /// Declared nodata.
    pub nodata: Option<f64>,
    /// Sample type of band 1.
    pub data_type: String,
    /// `Area` or `Point` (GDAL's AREA_OR_POINT; GDAL has already moved a pixel-is-point
    /// geotransform to pixel corners, so both are placed by the same rule).
    pub pixel_convention: String,
    /// Ground resolution at the raster's centre, metres (geometric mean of both axes).
    pub resolution_m: f64,
    /// West, south, east, north in degrees (sampled along the border and inside).
    pub bounds_deg: [f64; 4],
    /// The source's vertical CRS, if it declares one.
    pub vertical_crs: Option<String>,
}

/// The geographic CRS of a body, longitude first.
pub fn body_geographic(body: &Ellipsoid) -> Result<SpatialRef, gdal::errors::GdalError> {
    let mut srs = if body.name() == "wgs84" {
        SpatialRef::from_epsg(4326)?
    } else {
        SpatialRef::from_proj4(&format!("+proj=longlat +a={} +b={} +no_defs", body.a_m(), body.b_m()))?
    };
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    Ok(srs)
}

fn invert(gt: &[f64; 6]) -> Option<[f64; 6]> {
    let det = gt[1] * gt[5] - gt[2] * gt[4];
    if !(det.is_finite() && det.abs() > 0.0) {
        return None;
    }
    let (a, b, d, e) = (gt[5] / det, -gt[2] / det, -gt[4] / det, gt[1] / det);
    Some([-(a * gt[0] + b * gt[3]), a, b, -(d * gt[0] + e * gt[3]), d, e])
}

impl SourceInfo {
    /// Opens and checks a source for a body. Every refusal names the file and the problem.
    pub fn open(path: &Path, body: &Ellipsoid) -> Result<SourceInfo, StoreError> {
        let fail = |m: String| StoreError::new(path, m);
        if !path.exists() {
            return Err(fail("no such file".into()));
        }
        let abs = std::fs::canonicalize(path).map_err(|e| StoreError::caused(path, "cannot resolve", e))?;
        let ds = Dataset::open(&abs).map_err(|e| {
            // GDAL often has nothing to add ("Error msg: ''"): say so only when it has.
            let detail = e.to_string();
            if detail.ends_with("Error msg: ''") {
                fail("not a raster GDAL can read".into())
            } else {
                fail(format!("not a raster GDAL can read ({detail})"))
            }
        })?;
        if ds.raster_count() == 0 {
            return Err(fail("has no raster bands (a vector file?)".into()));
        }
        let (w, h) = ds.raster_size();
        if w == 0 || h == 0 {
            return Err(fail(format!("zero-size raster ({w}×{h} pixels)")));
        }
        if (w as u64) * (h as u64) > MAX_PIXELS || w > i32::MAX as usize || h > i32::MAX as usize {
            return Err(fail(format!("absurd raster size {w}×{h} pixels (more than 2^40 pixels)")));
        }
        let band = ds.rasterband(1).map_err(|e| StoreError::caused(path, "band 1", e))?;
        let data_type = band.band_type();
        if matches!(data_type, GdalDataType::Unknown) {
            return Err(fail("band 1 has a sample type that is not a real number".into()));
        }
        let nodata = band.no_data_value();
        let gt = ds.geo_transform().map_err(|_| fail("has no georeferencing (no geotransform)".into()))?;
        let inverse = invert(&gt)
            .filter(|_| gt.iter().all(|v| v.is_finite()))
            .ok_or_else(|| fail(format!("has a degenerate geotransform {gt:?}")))?;
        let mut srs = ds.spatial_ref().map_err(|_| fail("has no coordinate reference system".into()))?;
        let crs_wkt = srs.to_wkt().unwrap_or_default();
        if crs_wkt.is_empty() {
            return Err(fail("has no coordinate reference system".into()));
        }
        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let crs_proj = srs.to_proj4().unwrap_or_default();
        let a = srs.semi_major().map_err(|e| StoreError::caused(path, "its CRS has no ellipsoid", e))?;
        if ((a - body.a_m()) / body.a_m()).abs() > 0.01 {
            return Err(fail(format!(
                "its CRS lies on a body of radius {a} m, but the store's body {} has a = {} m: wrong --body?",
                body.name(),
                body.a_m()
            )));
        }
        let geographic = srs.is_geographic();
        let wraps =
            geographic && gt[2] == 0.0 && gt[4] == 0.0 && (w as f64 * gt[1].abs() - 360.0).abs() < 0.5 * gt[1].abs();
        let vertical_crs = srs.is_compound().then(|| srs.name().unwrap_or_else(|| "compound CRS".into()));
        let pixel_convention = ds.metadata_item("AREA_OR_POINT", "").unwrap_or_else(|| "Area".into());
        let driver = ds.driver().short_name();
        let mut info = SourceInfo {
            path: abs,
            driver,
            size: (w, h),
            geo_transform: gt,
            inverse,
            crs_wkt,
            crs_proj,
            geographic,
            wraps,
            nodata,
            data_type: data_type.name(),
            pixel_convention,
            resolution_m: 0.0,
            bounds_deg: [0.0; 4],
            vertical_crs,
        };
        let reader = SourceReader::new(&info, body)?;
        info.resolution_m = reader.resolution_m(body)?;
        info.bounds_deg = reader.bounds_deg()?;
        Ok(info)
    }

    /// Georeferenced coordinates of a point given in pixel units (0, 0 the raster's corner).
    pub fn georef(&self, px: f64, py: f64) -> (f64, f64) {
        let g = &self.geo_transform;
        (g[0] + px * g[1] + py * g[2], g[3] + px * g[4] + py * g[5])
    }

    /// Pixel units of georeferenced coordinates.
    pub fn pixel(&self, x: f64, y: f64) -> (f64, f64) {
        let g = &self.inverse;
        (g[0] + x * g[1] + y * g[2], g[3] + x * g[4] + y * g[5])
    }
}

/// A window of source samples (nodata already NaN), in source pixel rows and columns.
pub struct Window {
    /// First column (may be negative or past the width for wrapping sources).
    pub c0: i64,
    /// First row.
    pub r0: i64,
    /// Columns held.
    pub w: usize,
    /// Rows held.
    pub h: usize,
    full_wrap: Option<i64>,
    data: Vec<f64>,
}

impl Window {
    /// The sample at column c, row r, both already inside the raster (or wrapped columns).
    #[inline]
    pub fn get(&self, c: i64, r: i64) -> f64 {
        let k = match self.full_wrap {
            Some(width) => c.rem_euclid(width),
            None => c - self.c0,
        };
        let row = r - self.r0;
        if k < 0 || row < 0 || k >= self.w as i64 || row >= self.h as i64 {
            return f64::NAN;
        }
        self.data[row as usize * self.w + k as usize]
    }

    /// The 2×2 samples at columns c, c + 1 and rows r, r + 1 (row-major), when the window holds
    /// them without wrapping: the bilinear fast path.
    #[inline(always)]
    pub fn block(&self, c: i64, r: i64) -> Option<[f64; 4]> {
        let (k, row) = (c - self.c0, r - self.r0);
        if self.full_wrap.is_some() || k < 0 || row < 0 || k + 1 >= self.w as i64 || row + 1 >= self.h as i64 {
            return None;
        }
        let i = row as usize * self.w + k as usize;
        Some([self.data[i], self.data[i + 1], self.data[i + self.w], self.data[i + self.w + 1]])
    }

    /// Bytes held.
    pub fn bytes(&self) -> usize {
        self.data.len() * 8
    }
}

/// One thread's handle on a source.
pub struct SourceReader {
    info: SourceInfo,
    ds: Dataset,
    to_source: CoordTransform,
    to_body: CoordTransform,
    /// The source CRS is the body's own geographic CRS: longitude and latitude pass unchanged
    /// (PROJ would do the same, slower).
    identity: bool,
}

impl SourceReader {
    /// Opens a handle for one worker.
    pub fn new(info: &SourceInfo, body: &Ellipsoid) -> Result<SourceReader, StoreError> {
        let ds = Dataset::open(&info.path).map_err(|e| StoreError::caused(&info.path, "cannot reopen", e))?;
        let mut srs = ds.spatial_ref().map_err(|e| StoreError::caused(&info.path, "CRS", e))?;
        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let geo = body_geographic(body).map_err(|e| StoreError::caused(&info.path, "body CRS", e))?;
        let to_source = CoordTransform::new(&geo, &srs)
            .map_err(|e| StoreError::caused(&info.path, "PROJ cannot transform to its CRS", e))?;
        let to_body = CoordTransform::new(&srs, &geo)
            .map_err(|e| StoreError::caused(&info.path, "PROJ cannot transform from its CRS", e))?;
        let identity = srs == geo;
        Ok(SourceReader { info: info.clone(), ds, to_source, to_body, identity })
    }

    /// The checked description of the source.
    pub fn info(&self) -> &SourceInfo {
        &self.info
    }

    /// Turns longitudes and latitudes (degrees, in place) into fractional pixel-centre
    /// coordinates: (0, 0) is the centre of the first pixel. Points PROJ cannot transform
    /// become NaN.
    pub fn centre_coords(&self, xs: &mut [f64], ys: &mut [f64]) {
        if !self.identity && self.to_source.transform_coords(xs, ys, &mut []).is_err() {
            // Some points failed: transform one by one, marking the failures.
            for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
                let (mut a, mut b) = ([*x], [*y]);
                if self.to_source.transform_coords(&mut a, &mut b, &mut []).is_ok() {
                    (*x, *y) = (a[0], b[0]);
                } else {
                    (*x, *y) = (f64::NAN, f64::NAN);
                }
            }
        }
        let period = self.info.geographic.then(|| {
            let g = &self.info.geo_transform;
            let west = g[0].min(g[0] + g[1] * self.info.size.0 as f64);
            (west, 360.0)
        });
        for (x, y) in xs.iter_mut().zip(ys.iter_mut()) {
            if !(x.is_finite() && y.is_finite()) {
                (*x, *y) = (f64::NAN, f64::NAN);
                continue;
            }
            if let Some((west, p)) = period {
                // Longitudes into the raster's own 360° range (0…360 grids, or −180…180).
                *x = west + (*x - west).rem_euclid(p);
            }
            let (px, py) = self.info.pixel(*x, *y);
            (*x, *y) = (px - 0.5, py - 0.5);
        }
    }

    /// Geodetic longitude and latitude (degrees) of points given in pixel units; NaN where
    /// PROJ cannot transform them.
    pub fn lonlat_of_pixels(&self, pixels: &[(f64, f64)]) -> Vec<(f64, f64)> {
        let (mut xs, mut ys): (Vec<f64>, Vec<f64>) = pixels.iter().map(|&(px, py)| self.info.georef(px, py)).unzip();
        if self.to_body.transform_coords(&mut xs, &mut ys, &mut []).is_err() {
            for k in 0..xs.len() {
                let (px, py) = self.info.georef(pixels[k].0, pixels[k].1);
                let (mut a, mut b) = ([px], [py]);
                (xs[k], ys[k]) = if self.to_body.transform_coords(&mut a, &mut b, &mut []).is_ok() {
                    (a[0], b[0])
                } else {
                    (f64::NAN, f64::NAN)
                };
            }
        }
        xs.into_iter()
            .zip(ys)
            .map(
                |(x, y)| {
                    if x.is_finite() && y.is_finite() && y.abs() <= 90.0 + 1e-9 { (x, y) } else { (f64::NAN, f64::NAN) }
                },
            )
            .collect()
    }

    fn resolution_m(&self, body: &Ellipsoid) -> Result<f64, StoreError> {
        let (w, h) = self.info.size;
        let (cx, cy) = ((w / 2) as f64 + 0.5, (h / 2) as f64 + 0.5);
        let p = self.lonlat_of_pixels(&[(cx, cy), (cx + 1.0, cy), (cx, cy + 1.0)]);
        let ecef = |(lon, lat): (f64, f64)| geodesy::ecef_from_geodetic(body, Geodetic::from_degrees(lat, lon, 0.0));
        let (a, b, c) = (ecef(p[0]), ecef(p[1]), ecef(p[2]));
        let r = ((b - a).length() * (c - a).length()).sqrt();
        if !(r.is_finite() && r > 1e-4) {
            return Err(StoreError::new(
                &self.info.path,
                format!("has no usable ground resolution at its centre ({r} m per pixel): is its CRS right?"),
            ));
        }
        Ok(r)
    }

    fn bounds_deg(&self) -> Result<[f64; 4], StoreError> {
        let (w, h) = (self.info.size.0 as f64, self.info.size.1 as f64);
        let n = 32;
        let mut pts = Vec::new();
        for a in 0..=n {
            for b in 0..=n {
                pts.push((w * f64::from(a) / f64::from(n), h * f64::from(b) / f64::from(n)));
            }
        }
        let ll: Vec<(f64, f64)> = self.lonlat_of_pixels(&pts).into_iter().filter(|p| p.0.is_finite()).collect();
        if ll.is_empty() {
            return Err(StoreError::new(&self.info.path, "none of its area lies on the body: is its CRS right?"));
        }
        let fold = |f: fn(f64, f64) -> f64, init: f64, pick: fn(&(f64, f64)) -> f64| ll.iter().map(pick).fold(init, f);
        let mut b = [
            fold(f64::min, f64::INFINITY, |p| p.0),
            fold(f64::min, f64::INFINITY, |p| p.1),
            fold(f64::max, f64::NEG_INFINITY, |p| p.0),
            fold(f64::max, f64::NEG_INFINITY, |p| p.1),
        ];
        if self.info.wraps {
            (b[0], b[2]) = (-180.0, 180.0);
        }
        Ok(b)
    }

    /// Reads rows r0..=r1 and columns c0..=c1 (clamped to the raster; columns of a wrapping
    /// source taken modulo the width), nodata and NaN as NaN.
    pub fn window(&self, c0: i64, c1: i64, r0: i64, r1: i64) -> Result<Window, StoreError> {
        let (w, h) = (self.info.size.0 as i64, self.info.size.1 as i64);
        let (r0, r1) = (r0.clamp(0, h - 1), r1.clamp(0, h - 1));
        let rows = (r1 - r0 + 1) as usize;
        let band = self.ds.rasterband(1).map_err(|e| StoreError::caused(&self.info.path, "band 1", e))?;
        let read = |c: i64, cols: i64| -> Result<Vec<f64>, StoreError> {
            band.read_as::<f64>((c as isize, r0 as isize), (cols as usize, rows), (cols as usize, rows), None)
                .map(|b| b.into_shape_and_vec().1)
                .map_err(|e| StoreError::caused(&self.info.path, format!("read error at column {c}, row {r0}"), e))
        };
        let (c0, width, full_wrap, mut data) = if !self.info.wraps {
            let (a, b) = (c0.clamp(0, w - 1), c1.clamp(0, w - 1));
            (a, (b - a + 1) as usize, None, read(a, b - a + 1)?)
        } else if c1 - c0 + 1 >= w {
            (0, w as usize, Some(w), read(0, w)?)
        } else {
            // Up to two pieces, split where the columns wrap.
            let cols = (c1 - c0 + 1) as usize;
            let mut data = vec![0.0; cols * rows];
            let mut k = 0usize;
            while k < cols {
                let start = (c0 + k as i64).rem_euclid(w);
                let len = ((w - start) as usize).min(cols - k);
                let piece = read(start, len as i64)?;
                for r in 0..rows {
                    data[r * cols + k..r * cols + k + len].copy_from_slice(&piece[r * len..(r + 1) * len]);
                }
                k += len;
            }
            (c0, cols, None, data)
        };
        if let Some(nd) = self.info.nodata {
            for v in &mut data {
                if *v == nd {
                    *v = f64::NAN;
                }
            }
        }
        Ok(Window { c0, r0, w: width, h: rows, full_wrap, data })
    }

    /// A coarse look at the whole raster (nearest decimation to at most 1024² samples): whether
    /// any sample has data.
    pub fn any_data_coarse(&self) -> Result<bool, StoreError> {
        let (w, h) = self.info.size;
        let (bw, bh) = (w.min(1024), h.min(1024));
        let band = self.ds.rasterband(1).map_err(|e| StoreError::caused(&self.info.path, "band 1", e))?;
        let b = band
            .read_as::<f64>((0, 0), (w, h), (bw, bh), None)
            .map_err(|e| StoreError::caused(&self.info.path, "read error", e))?;
        Ok(b.data().iter().any(|v| v.is_finite() && Some(*v) != self.info.nodata))
    }

    /// Scans every row (in strips) for a sample with data.
    pub fn any_data_full(&self) -> Result<bool, StoreError> {
        let (w, h) = (self.info.size.0 as i64, self.info.size.1 as i64);
        let strip = ((1i64 << 24) / w).max(1);
        let mut r = 0;
        while r < h {
            let win = self.window(0, w - 1, r, (r + strip - 1).min(h - 1))?;
            if win.data.iter().any(|v| v.is_finite()) {
                return Ok(true);
            }
            r += strip;
        }
        Ok(false)
    }
}
