//! `terrafuse store export`: a dataset resampled to a GeoTIFF in any CRS GDAL/PROJ know, written
//! atomically (a temporary file beside the output, renamed when complete).

use std::path::{Path, PathBuf};

use gdal::DriverManager;
use gdal::Metadata;
use gdal::raster::{Buffer, RasterCreationOptions};
use gdal::spatial_ref::{AxisMappingStrategy, CoordTransform, SpatialRef};
use rayon::prelude::*;

use super::StoreError;
use super::gpkg::Store;
use super::grid;
use super::read::GridReader;
use super::source::body_geographic;
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

/// Exports a dataset. Errors name the store, the CRS or the output file.
pub fn export(opts: &ExportOptions) -> Result<ExportReport, StoreError> {
    let store = Store::open_read_only(&opts.store)?;
    let body = *store.body();
    let record = store.resolve_dataset(opts.dataset.as_deref())?;
    let out_err = |m: String| StoreError::new(&opts.out, m);
    let mut srs =
        SpatialRef::from_definition(&opts.crs).map_err(|e| out_err(format!("unknown CRS '{}': {e}", opts.crs)))?;
    srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
    let [x0, y0, x1, y1] = opts.bounds;
    let (rx, ry) = opts.resolution;
    if !(x1 > x0 && y1 > y0 && rx > 0.0 && ry > 0.0 && [x0, y0, x1, y1, rx, ry].iter().all(|v| v.is_finite())) {
        return Err(out_err(format!(
            "bounds {:?} and resolution {rx},{ry} do not make a raster (need xmin<xmax, ymin<ymax, resolution > 0)",
            opts.bounds
        )));
    }
    let (w, h) = (((x1 - x0) / rx).round().max(1.0), ((y1 - y0) / ry).round().max(1.0));
    if w * h > 4e9 {
        return Err(out_err(format!("{w}×{h} pixels is too large an export (more than 4·10⁹ pixels)")));
    }
    let (w, h) = (w as usize, h as usize);
    let geo = body_geographic(&body).map_err(|e| out_err(e.to_string()))?;
    let to_geo = CoordTransform::new(&srs, &geo)
        .map_err(|e| out_err(format!("PROJ cannot go from {} to the body: {e}", opts.crs)))?;
    let level = match opts.level {
        Some(l) if l > record.settings.finest_level => {
            return Err(StoreError::new(
                &opts.store,
                format!("dataset {} has levels 0–{}, not {l}", record.name, record.settings.finest_level),
            ));
        }
        Some(l) => l,
        None => {
            // Ground size of an output pixel at the centre, through PROJ.
            let (cx, cy) = ((x0 + x1) / 2.0, (y0 + y1) / 2.0);
            let (mut xs, mut ys) = (vec![cx, cx + rx, cx], vec![cy, cy, cy + ry]);
            to_geo
                .transform_coords(&mut xs, &mut ys, &mut [])
                .map_err(|e| out_err(format!("the bounds' centre is not on the body: {e}")))?;
            let p = |k: usize| geodesy::ecef_from_geodetic(&body, Geodetic::from_degrees(ys[k], xs[k], 0.0));
            let r = ((p(1) - p(0)).length() * (p(2) - p(0)).length()).sqrt();
            grid::level_for_resolution(&body, r).min(record.settings.finest_level)
        }
    };
    // Rows in parallel, each worker with its own store connection and PROJ transform.
    let rows: Vec<Vec<f32>> = (0..h)
        .into_par_iter()
        .map_init(
            || -> Result<(GridReader, CoordTransform), StoreError> {
                let reader = GridReader::new(Store::open_read_only(&opts.store)?, &record.name)?;
                let mut srs = SpatialRef::from_definition(&opts.crs).map_err(|e| out_err(e.to_string()))?;
                srs.set_axis_mapping_strategy(AxisMappingStrategy::TraditionalGisOrder);
                let geo = body_geographic(&body).map_err(|e| out_err(e.to_string()))?;
                let t = CoordTransform::new(&srs, &geo).map_err(|e| out_err(e.to_string()))?;
                Ok((reader, t))
            },
            |state, r| -> Result<Vec<f32>, StoreError> {
                let (reader, t) = state.as_mut().map_err(|e| e.clone())?;
                let y = y1 - (r as f64 + 0.5) * ry;
                let mut xs: Vec<f64> = (0..w).map(|c| x0 + (c as f64 + 0.5) * rx).collect();
                let mut ys = vec![y; w];
                let ok = t.transform_coords(&mut xs, &mut ys, &mut []).is_ok();
                (0..w)
                    .map(|c| {
                        if !ok || !xs[c].is_finite() || !ys[c].is_finite() || ys[c].abs() > 90.0 {
                            return Ok(f32::NAN);
                        }
                        reader.height_at(ys[c].to_radians(), xs[c].to_radians(), level).map(|v| v as f32)
                    })
                    .collect()
            },
        )
        .collect::<Result<_, _>>()?;
    let mut data: Vec<f32> = rows.into_iter().flatten().collect();
    let valid = data.iter().filter(|v| !v.is_nan()).count() as u64;

    let dir = opts.out.parent().filter(|d| !d.as_os_str().is_empty()).unwrap_or(Path::new("."));
    if !dir.is_dir() {
        return Err(out_err(format!("folder {} does not exist", dir.display())));
    }
    let name = opts.out.file_name().map(|n| n.to_string_lossy().into_owned()).unwrap_or_default();
    let tmp = dir.join(format!(".{name}.tmp-{}.tif", std::process::id()));
    let result = (|| -> Result<(), StoreError> {
        let driver = DriverManager::get_driver_by_name("GTiff").map_err(|e| out_err(e.to_string()))?;
        let options = RasterCreationOptions::from_iter(["COMPRESS=DEFLATE", "TILED=YES", "BIGTIFF=IF_SAFER"]);
        let mut ds = driver
            .create_with_band_type_with_options::<f32, _>(&tmp, w, h, 1, &options)
            .map_err(|e| out_err(format!("cannot create the GeoTIFF: {e}")))?;
        ds.set_geo_transform(&[x0, rx, 0.0, y1, 0.0, -ry]).map_err(|e| out_err(e.to_string()))?;
        ds.set_spatial_ref(&srs).map_err(|e| out_err(e.to_string()))?;
        for (k, v) in [
            ("TERRAFUSE_STORE", opts.store.to_string_lossy().into_owned()),
            ("TERRAFUSE_DATASET", record.name.clone()),
            ("TERRAFUSE_LEVEL", level.to_string()),
            ("TERRAFUSE_VERTICAL_DATUM", record.settings.vertical_datum.clone()),
        ] {
            ds.set_metadata_item(k, &v, "").map_err(|e| out_err(e.to_string()))?;
        }
        let mut band = ds.rasterband(1).map_err(|e| out_err(e.to_string()))?;
        band.set_no_data_value(Some(f64::NAN)).map_err(|e| out_err(e.to_string()))?;
        let mut buffer = Buffer::new((w, h), std::mem::take(&mut data));
        band.write((0, 0), (w, h), &mut buffer).map_err(|e| out_err(format!("cannot write pixels: {e}")))?;
        ds.flush_cache().map_err(|e| out_err(e.to_string()))?;
        drop(ds);
        std::fs::File::open(&tmp).and_then(|f| f.sync_all()).map_err(|e| out_err(e.to_string()))?;
        std::fs::rename(&tmp, &opts.out).map_err(|e| out_err(format!("cannot move the export into place: {e}")))
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result?;
    Ok(ExportReport { size: (w, h), level, valid })
}
