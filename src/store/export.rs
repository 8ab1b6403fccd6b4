//! `terrafuse store export`: a dataset resampled to a GeoTIFF in any CRS GDAL/PROJ know, written
//! atomically (a temporary file beside the output, renamed when complete).

use std::ops::Range;
use std::path::{Path, PathBuf};

use gdal::DriverManager;
use gdal::Metadata;
use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use rayon::prelude::*;

use super::StoreError;
use super::gpkg::Store;
use super::read::GridReader;
use super::source::body_geographic;
use crate::ecm::grid;
use crate::geodesy::{self, Geodetic};

/// What to export.
#[derive(Clone, Debug)]
pub struct ExportOptions {
    /// The store.
    pub store: PathBuf,
    /// Dataset (the only one when `None`).
    pub dataset: Option<String>,
    /// Output CRS: anything GDAL's SetFromUserInput takes (EPSG:32637, a PROJ string, WKT).
    pub crs: String,
    /// xmin, ymin, xmax, ymax in the output CRS.
    pub bounds: [f64; 4],
    /// Pixel size in CRS units (x, y).
    pub resolution: (f64, f64),
    /// Level to read (default: the finest level not finer than the output pixels need).
    pub level: Option<u8>,
    /// Output GeoTIFF.
    pub out: PathBuf,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct ExportReport {
    /// Width and height in pixels.
    pub size: (usize, usize),
    /// Level read.
    pub level: u8,
    /// Pixels with data.
    pub valid: u64,
}

/// An output raster: its CRS, size and geotransform, checked.
pub struct RasterSpec {
    /// The output CRS (traditional GIS axis order).
    pub srs: SpatialRef,
    /// Width, height in pixels.
    pub size: (usize, usize),
    /// GDAL geotransform (north up).
    pub geotransform: [f64; 6],
}

impl RasterSpec {
    /// Checks a CRS, bounds (xmin, ymin, xmax, ymax) and pixel size; errors name `out`.
    pub fn new(crs: &str, bounds: [f64; 4], resolution: (f64, f64), out: &Path) -> Result<RasterSpec, StoreError> {
        let out_err = |m: String| StoreError::new(out, m);
        let mut srs =
            SpatialRef::from_definition(crs).map_err(|e| StoreError::caused(out, format!("unknown CRS '{crs}'"), e))?;
        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
        let [x0, y0, x1, y1] = bounds;
        let (rx, ry) = resolution;
        if !(x1 > x0 && y1 > y0 && rx > 0.0 && ry > 0.0 && [x0, y0, x1, y1, rx, ry].iter().all(|v| v.is_finite())) {
            return Err(out_err(format!(
                "bounds {bounds:?} and resolution {rx},{ry} do not make a raster (need xmin<xmax, ymin<ymax, resolution > 0)"
            )));
        }
        let (w, h) = (((x1 - x0) / rx).round().max(1.0), ((y1 - y0) / ry).round().max(1.0));
        if w * h > 4e9 {
            return Err(out_err(format!("{w}×{h} pixels is too large an export (more than 4·10⁹ pixels)")));
        }
        Ok(RasterSpec { srs, size: (w as usize, h as usize), geotransform: [x0, rx, 0.0, y1, 0.0, -ry] })
    }

    /// The ground size of a pixel at the raster's centre on a body, metres (through PROJ).
    pub fn pixel_ground_m(&self, crs: &str, body: &crate::geodesy::Ellipsoid, out: &Path) -> Result<f64, StoreError> {
        let geo = body_geographic(body).map_err(|e| StoreError::caused(out, "the body's geographic CRS", e))?;
        let to_geo = CoordTransform::new(&self.srs, &geo)
            .map_err(|e| StoreError::caused(out, format!("PROJ cannot go from {crs} to the body"), e))?;
        let [x0, rx, _, y1, _, ry] = self.geotransform;
        let (cx, cy) = (x0 + rx * self.size.0 as f64 / 2.0, y1 + ry * self.size.1 as f64 / 2.0);
        let (mut xs, mut ys) = (vec![cx, cx + rx, cx], vec![cy, cy, cy - ry]);
        to_geo
            .transform_coords(&mut xs, &mut ys, &mut [])
            .map_err(|e| StoreError::caused(out, "the bounds' centre is not on the body", e))?;
        let p = |k: usize| geodesy::ecef_from_geodetic(body, Geodetic::from_degrees(ys[k], xs[k], 0.0));
        Ok(((p(1) - p(0)).length() * (p(2) - p(0)).length()).sqrt())
    }

    /// Per pixel centre, row by row from the north: (lat, lon) in radians on the body, NaN where
    /// the point is not on it. Rows in parallel, each worker with its own PROJ transform.
    pub fn pixel_lat_lon(
        &self,
        crs: &str,
        body: &crate::geodesy::Ellipsoid,
        out: &Path,
    ) -> Result<Vec<(f64, f64)>, StoreError> {
        self.pixel_lat_lon_rows(crs, body, out, 0..self.size.1)
    }

    /// [`RasterSpec::pixel_lat_lon`] of the rows `rows` only (an export made band by band).
    pub fn pixel_lat_lon_rows(
        &self,
        crs: &str,
        body: &crate::geodesy::Ellipsoid,
        out: &Path,
        rows: Range<usize>,
    ) -> Result<Vec<(f64, f64)>, StoreError> {
        let w = self.size.0;
        let [x0, rx, _, y1, _, ry] = self.geotransform;
        let rows: Vec<Vec<(f64, f64)>> = rows
            .into_par_iter()
            .map_init(
                || {
                    let make = || -> Result<CoordTransform, StoreError> {
                        let mut srs = SpatialRef::from_definition(crs)
                            .map_err(|e| StoreError::caused(out, format!("unknown CRS '{crs}'"), e))?;
                        srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
                        let geo = body_geographic(body)
                            .map_err(|e| StoreError::caused(out, "the body's geographic CRS", e))?;
                        CoordTransform::new(&srs, &geo)
                            .map_err(|e| StoreError::caused(out, format!("PROJ cannot go from {crs} to the body"), e))
                    };
                    make().map_err(std::sync::Arc::new)
                },
                |t, r| -> Result<Vec<(f64, f64)>, StoreError> {
                    let t = t.as_mut().map_err(|e| StoreError::caused(out, "a worker could not start", e.clone()))?;
                    let y = y1 + (r as f64 + 0.5) * ry;
                    let mut xs: Vec<f64> = (0..w).map(|c| x0 + (c as f64 + 0.5) * rx).collect();
                    let mut ys = vec![y; w];
                    let ok = t.transform_coords(&mut xs, &mut ys, &mut []).is_ok();
                    Ok((0..w)
                        .map(|c| {
                            if !ok || !xs[c].is_finite() || !ys[c].is_finite() || ys[c].abs() > 90.0 {
                                (f64::NAN, f64::NAN)
                            } else {
                                (ys[c].to_radians(), xs[c].to_radians())
                            }
                        })
                        .collect())
                },
            )
            .collect::<Result<_, _>>()?;
        Ok(rows.into_iter().flatten().collect())
    }

    /// Writes `data` (row by row from the north, NaN no data) as a float32 GeoTIFF with the
    /// metadata items, atomically: a temporary file beside `out`, synced, renamed.
    pub fn write(&self, out: &Path, metadata: &[(&str, String)], data: Vec<f32>) -> Result<(), StoreError> {
        let mut writer = self.create(out, metadata)?;
        writer.write_rows(0, data)?;
        writer.finish()
    }

    /// Starts writing the raster to `out` (a float32 GeoTIFF, tiled and compressed, with the
    /// metadata items): a temporary file beside it, filled band by band
    /// ([`RasterWriter::write_rows`]) and moved into place by [`RasterWriter::finish`]; dropped
    /// unfinished (an error, a cancel), the temporary file is removed and `out` never touched.
    pub fn create(&self, out: &Path, metadata: &[(&str, String)]) -> Result<RasterWriter, StoreError> {
        self.create_as(out, metadata, false)
    }

    /// [`RasterSpec::create`], finished as a Cloud-Optimized GeoTIFF (GDAL's COG driver: tiled,
    /// overviews, the header first) where `cog`.
    pub fn create_as(&self, out: &Path, metadata: &[(&str, String)], cog: bool) -> Result<RasterWriter, StoreError> {
        let out_err = |m: String| StoreError::new(out, m);
        let (w, h) = self.size;
        let dir = out.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
        if !dir.is_dir() {
            return Err(out_err(format!("folder {} does not exist", dir.display())));
        }
        let name = out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
        let tmp = dir.join(format!(".{name}.tmp-{}.tif", std::process::id()));
        let mut writer = RasterWriter { dataset: None, tmp, out: out.to_path_buf(), size: self.size, cog };
        let cannot = |e| StoreError::caused(out, "cannot write the GeoTIFF", e);
        let driver = DriverManager::get_driver_by_name("GTiff").map_err(cannot)?;
        let options = RasterCreationOptions::from_iter(["COMPRESS=DEFLATE", "TILED=YES", "BIGTIFF=IF_SAFER"]);
        let mut ds = driver
            .create_with_band_type_with_options::<f32, _>(&writer.tmp, w, h, 1, &options)
            .map_err(|e| StoreError::caused(out, "cannot create the GeoTIFF", e))?;
        // Held from here: an error below drops the writer, which removes the file.
        ds.set_geo_transform(&self.geotransform).map_err(cannot)?;
        ds.set_spatial_ref(&self.srs).map_err(cannot)?;
        for (k, v) in metadata {
            ds.set_metadata_item(k, v, "").map_err(cannot)?;
        }
        ds.rasterband(1).and_then(|mut band| band.set_no_data_value(Some(f64::NAN))).map_err(cannot)?;
        writer.dataset = Some(ds);
        Ok(writer)
    }
}

/// An export being written ([`RasterSpec::create`]).
pub struct RasterWriter {
    dataset: Option<gdal::Dataset>,
    tmp: PathBuf,
    out: PathBuf,
    size: (usize, usize),
    cog: bool,
}

impl RasterWriter {
    /// Writes whole rows from `row` on (`data` row by row from the north, NaN no data).
    pub fn write_rows(&mut self, row: usize, data: Vec<f32>) -> Result<(), StoreError> {
        let (w, h) = self.size;
        let rows = data.len() / w.max(1);
        if rows * w != data.len() || row + rows > h {
            return Err(StoreError::new(
                &self.out,
                format!("{} values from row {row} are not whole rows of {w}×{h}", data.len()),
            ));
        }
        let Some(ds) = self.dataset.as_mut() else {
            return Err(StoreError::new(&self.out, "the GeoTIFF is already finished"));
        };
        let mut band = ds.rasterband(1).map_err(|e| StoreError::caused(&self.out, "cannot write the GeoTIFF", e))?;
        let mut buffer = Buffer::new((w, rows), data);
        band.write((0, row as isize), (w, rows), &mut buffer)
            .map_err(|e| StoreError::caused(&self.out, "cannot write pixels", e))
    }

    /// Flushes, syncs and moves the file into place.
    pub fn finish(mut self) -> Result<(), StoreError> {
        let out = self.out.clone();
        if let Some(mut ds) = self.dataset.take() {
            ds.flush_cache().map_err(|e| StoreError::caused(&out, "cannot write the GeoTIFF", e))?;
            if self.cog {
                // The tiled GeoTIFF copied through the COG driver beside it, which then replaces it.
                let cog = self.tmp.with_extension("cog.tif");
                let copied = (|| {
                    let driver = DriverManager::get_driver_by_name("COG")?;
                    let options =
                        RasterCreationOptions::from_iter(["COMPRESS=DEFLATE", "BIGTIFF=IF_SAFER", "PREDICTOR=YES"]);
                    ds.create_copy(&driver, &cog, &options).map(drop)
                })();
                drop(ds);
                if let Err(e) = copied {
                    let _ = std::fs::remove_file(&cog);
                    return Err(StoreError::caused(&out, "cannot write the Cloud-Optimized GeoTIFF", e));
                }
                std::fs::rename(&cog, &self.tmp)
                    .map_err(|e| StoreError::caused(&out, "cannot write the Cloud-Optimized GeoTIFF", e))?;
            }
        }
        std::fs::File::open(&self.tmp)
            .and_then(|f| f.sync_all())
            .map_err(|e| StoreError::caused(&out, "cannot write the GeoTIFF", e))?;
        std::fs::rename(&self.tmp, &out)
            .map_err(|e| StoreError::caused(&out, "cannot move the export into place", e))?;
        self.tmp = PathBuf::new();
        Ok(())
    }
}

impl Drop for RasterWriter {
    /// Unfinished: the temporary file goes (`out` was never touched).
    fn drop(&mut self) {
        drop(self.dataset.take());
        if !self.tmp.as_os_str().is_empty() {
            let _ = std::fs::remove_file(&self.tmp);
        }
    }
}

/// Exports a dataset. Errors name the store, the CRS or the output file.
pub fn export(opts: &ExportOptions) -> Result<ExportReport, StoreError> {
    let store = Store::open_read_only(&opts.store)?;
    let body = *store.body();
    let record = store.resolve_dataset(opts.dataset.as_deref())?;
    let raster = RasterSpec::new(&opts.crs, opts.bounds, opts.resolution, &opts.out)?;
    let (w, h) = raster.size;
    let level = match opts.level {
        Some(l) if l > record.settings.finest_level => {
            return Err(StoreError::new(
                &opts.store,
                format!("dataset {} has levels 0–{}, not {l}", record.name, record.settings.finest_level),
            ));
        }
        Some(l) => l,
        None => {
            let r = raster.pixel_ground_m(&opts.crs, &body, &opts.out)?;
            grid::level_for_resolution(&body, r).min(record.settings.finest_level)
        }
    };
    let points = raster.pixel_lat_lon(&opts.crs, &body, &opts.out)?;
    // Rows in parallel, each worker with its own store connection.
    let rows: Vec<Vec<f32>> =
        points
            .par_chunks(w)
            .map_init(
                || {
                    let open = || GridReader::new(Store::open_read_only(&opts.store)?, &record.name);
                    open().map_err(std::sync::Arc::new)
                },
                |reader, row| -> Result<Vec<f32>, StoreError> {
                    let reader = reader
                        .as_mut()
                        .map_err(|e| StoreError::caused(&opts.store, "a worker could not start", e.clone()))?;
                    row.iter()
                        .map(|&(lat, lon)| {
                            if lat.is_nan() {
                                Ok(f32::NAN)
                            } else {
                                reader.height_at(lat, lon, level).map(|v| v as f32)
                            }
                        })
                        .collect()
                },
            )
            .collect::<Result<_, _>>()?;
    let data: Vec<f32> = rows.into_iter().flatten().collect();
    let valid = data.iter().filter(|v| !v.is_nan()).count() as u64;
    let metadata = [
        ("TERRAFUSE_STORE", opts.store.to_string_lossy().into_owned()),
        ("TERRAFUSE_DATASET", record.name.clone()),
        ("TERRAFUSE_LEVEL", level.to_string()),
        ("TERRAFUSE_VERTICAL_DATUM", record.settings.vertical_datum.clone()),
    ];
    raster.write(&opts.out, &metadata, data)?;
    debug_assert_eq!(h, points.len() / w.max(1));
    Ok(ExportReport { size: (w, h), level, valid })
}
