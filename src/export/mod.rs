//! A project's composed elevation (the whole layer stack as drawn, a layer alone, a difference, a
//! terrain attribute) written as a float32 GeoTIFF in any CRS, atomically, with NaN as nodata
//! (`terrafuse export`). Each pixel centre is taken through PROJ to the body, onto the cube map at
//! the chosen level, and interpolated bilinearly from the composed grid of the quad that holds it
//! (as `store export` does for one dataset). The quads are composed on the GPU (the renderer's
//! pass) or with the CPU reference, band by band of the raster, so memory stays bounded whatever
//! its size.

use crate::attributes::Attribute;
use std::collections::{BTreeSet, HashMap, HashSet};
use std::ops::Range;
use std::path::PathBuf;

use crate::ecm::grid::{intervals_per_face_edge, level_for_resolution};
use crate::ecm::{CubeProjection, QuadId};
use crate::gpu::{GpuContext, IMAGE_FORMAT, Renderer};
use crate::progress::Watch;
use crate::project::Project;
use crate::scene::Scene;
use crate::store::export::RasterSpec;

pub use crate::gpu::compose::ComposeOn;

pub mod sharded;

/// Why an export was not written (nothing was: the output is moved into place only when whole).
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The project could not be read.
    #[error(transparent)]
    Project(#[from] crate::project::ProjectError),
    /// The output raster (its CRS, bounds, folder) or its writing.
    #[error(transparent)]
    Store(#[from] crate::store::StoreError),
    /// The project's layers could not be opened or composed.
    #[error("{project}: {source}")]
    Scene {
        /// The project file.
        project: PathBuf,
        /// What went wrong.
        source: Box<crate::scene::SceneError>,
    },
    /// A layer named by `--layer` or `--difference`.
    #[error("{project}: {source}")]
    Layer {
        /// The project file.
        project: PathBuf,
        /// What went wrong.
        source: Box<crate::compare::CompareError>,
    },
    /// A quad could not be composed.
    #[error(transparent)]
    Composing(Box<crate::scene::SceneError>),
    /// The GPU's composition or attributes.
    #[error(transparent)]
    Gpu(#[from] crate::gpu::GpuError),
    /// A level past the finest.
    #[error("--level {0}: levels run 0–{max}", max = crate::ecm::MAX_LEVEL)]
    Level(u8),
    /// A shard plan, or a file it names.
    #[error(transparent)]
    Plan(#[from] crate::plan::PlanError),
    /// Cancelled.
    #[error("the export was cancelled; nothing was written")]
    Cancelled,
}

impl From<crate::scene::SceneError> for ExportError {
    fn from(e: crate::scene::SceneError) -> ExportError {
        ExportError::Composing(Box::new(e))
    }
}

/// What to export.
#[derive(Clone, Debug)]
pub struct ComposedExport {
    /// The project.
    pub project: PathBuf,
    /// The GeoTIFF to write.
    pub out: PathBuf,
    /// Output CRS (anything GDAL's SetFromUserInput takes).
    pub crs: String,
    /// xmin, ymin, xmax, ymax in the output CRS.
    pub bounds: [f64; 4],
    /// Pixel size in CRS units (x, y).
    pub resolution: (f64, f64),
    /// Level to compose (default: the level of the output's pixel size, no finer than the finest
    /// level at which a shown layer adds detail: datasets, strokes, erosion runs, noise octaves).
    pub level: Option<u8>,
    /// Where to compose.
    pub compose_on: ComposeOn,
    /// Write A − B of these two layers (each composed alone, as `compare` takes them) instead of
    /// the stack: the difference raster.
    pub difference: Option<(String, String)>,
    /// Write this terrain attribute of the heights instead of the heights.
    pub attribute: Option<Attribute>,
    /// Compose this layer alone instead of the visible stack.
    pub layer: Option<String>,
    /// Write a Cloud-Optimized GeoTIFF (GDAL's COG driver) instead of a plain tiled one.
    pub cog: bool,
}

/// What was written.
#[derive(Clone, Debug)]
pub struct ComposedReport {
    /// Width and height, pixels.
    pub size: (usize, usize),
    /// Level composed.
    pub level: u8,
    /// Quads composed.
    pub quads: usize,
    /// Pixels with data.
    pub valid: u64,
    /// What composed them.
    pub composer: String,
}

/// Where a pixel falls: the quad, the sample cell (i, j) inside it and the fractions in the cell.
type Cell = (QuadId, usize, usize, f64, f64);

/// Quads composed per batch on the GPU (within the renderer's smallest pools).
const GPU_BATCH: usize = 16;

/// Exports the composed elevation of a project. Errors name the file and the problem.
pub fn export_composed(opts: &ComposedExport) -> Result<ComposedReport, ExportError> {
    export_composed_watched(opts, &Watch::default())
}

/// [`export_composed`], the rows written counted on `watch` (and stopped when it is cancelled,
/// with nothing written).
///
/// The raster is made band by band, a band at most [`BAND_PIXELS`] pixels (with a row above and
/// below for an attribute's 3 × 3 window): its pixels taken through PROJ, the quads they fall in
/// composed (those the band before composed kept, the rest dropped), sampled and written at their
/// rows, so memory stays bounded whatever the export's size. A band's pixels are those the whole
/// raster at once gives, bit for bit.
pub fn export_composed_watched(opts: &ComposedExport, watch: &Watch) -> Result<ComposedReport, ExportError> {
    export_composed_in_bands(opts, watch, BAND_PIXELS)
}

/// [`export_composed_watched`] in bands of at most `band_pixels` pixels (at least a row).
pub fn export_composed_in_bands(
    opts: &ComposedExport,
    watch: &Watch,
    band_pixels: usize,
) -> Result<ComposedReport, ExportError> {
    let mut exporter = Exporter::new(opts)?;
    let h = exporter.raster.size.1;
    let mut writer = exporter.raster.create_as(&opts.out, &exporter.metadata, opts.cog)?;
    let made = exporter.rows(0..h, band_pixels, watch, &mut |row, band| Ok(writer.write_rows(row, band)?))?;
    watch.check().map_err(cancelled)?;
    writer.finish()?;
    Ok(exporter.report(made))
}

/// An export's grid, level and composers, ready to make any run of its rows.
pub(crate) struct Exporter {
    pub(crate) raster: RasterSpec,
    pub(crate) level: u8,
    /// The output's metadata items (the project, the layers, the level, the composer).
    pub(crate) metadata: Vec<(&'static str, String)>,
    crs: String,
    out: PathBuf,
    attribute: Option<Attribute>,
    body: crate::geodesy::Ellipsoid,
    main: Composer,
    minus: Option<Composer>,
    attribute_gpu: Option<GpuContext>,
}

/// The output's metadata items: the project, the layers written, the level and the composer.
fn metadata(opts: &ComposedExport, project: &Project, level: u8, composer: &str) -> Vec<(&'static str, String)> {
    let layers: Vec<String> = match (&opts.difference, &opts.layer) {
        (Some((a, b)), _) => vec![format!("{a} - {b} (difference)")],
        (None, Some(name)) => vec![format!("{name} (alone)")],
        (None, None) => project.layers.iter().filter(|l| l.visible).map(|l| l.name.clone()).collect(),
    };
    let mut metadata = vec![
        ("TERRAFUSE_PROJECT", opts.project.to_string_lossy().into_owned()),
        ("TERRAFUSE_LAYERS", layers.join(",")),
        ("TERRAFUSE_LEVEL", level.to_string()),
        ("TERRAFUSE_COMPOSED_ON", composer.to_owned()),
    ];
    if let Some(a) = opts.attribute {
        metadata.push(("TERRAFUSE_ATTRIBUTE", format!("{} ({})", a.name(), a.unit())));
    }
    metadata
}

/// What a run of rows made: the pixels with data and the quads composed.
pub(crate) struct Made {
    pub(crate) valid: u64,
    pub(crate) quads: BTreeSet<QuadId>,
}

impl Exporter {
    /// Loads the project, checks the grid and the level, and opens the composers.
    pub(crate) fn new(opts: &ComposedExport) -> Result<Exporter, ExportError> {
        let project = Project::load(&opts.project)?;
        let raster = RasterSpec::new(&opts.crs, opts.bounds, opts.resolution, &opts.out)?;
        if let Some(l) = opts.level
            && l > crate::ecm::MAX_LEVEL
        {
            return Err(ExportError::Level(l));
        }
        let scene_error = |source| ExportError::Scene { project: opts.project.clone(), source: Box::new(source) };
        let (scene, _) = Scene::open(&project).map_err(scene_error)?;
        let body = scene.ellipsoid;
        let level = match opts.level {
            Some(l) => l,
            None => {
                let r = raster.pixel_ground_m(&opts.crs, &body, &opts.out)?;
                crate::layers::default_level(level_for_resolution(&body, r), scene.detail_level())
            }
        };
        let alone = |name: &str| {
            let operand = crate::layers::Operand::Layer(name.into());
            crate::compare::sample::operand_scene(&scene, &project, &operand)
                .map_err(|source| ExportError::Layer { project: opts.project.clone(), source: Box::new(source) })
        };
        // One composer, and a second whose heights are taken away for a difference.
        let (main, minus) = match (&opts.difference, &opts.layer) {
            (Some((a, b)), _) => {
                (Composer::new(alone(a)?, opts.compose_on)?, Some(Composer::new(alone(b)?, opts.compose_on)?))
            }
            (None, Some(name)) => (Composer::new(alone(name)?, opts.compose_on)?, None),
            (None, None) => (Composer::new(scene, opts.compose_on)?, None),
        };
        let attribute_gpu = match (opts.attribute, opts.compose_on) {
            (Some(_), ComposeOn::Gpu) => Some(GpuContext::headless()?),
            _ => None,
        };
        let metadata = metadata(opts, &project, level, &main.name);
        Ok(Exporter {
            raster,
            level,
            metadata,
            crs: opts.crs.clone(),
            out: opts.out.clone(),
            attribute: opts.attribute,
            body,
            main,
            minus,
            attribute_gpu,
        })
    }

    /// What composed the quads.
    pub(crate) fn composer(&self) -> &str {
        &self.main.name
    }

    fn report(&self, made: Made) -> ComposedReport {
        ComposedReport {
            size: self.raster.size,
            level: self.level,
            quads: made.quads.len(),
            valid: made.valid,
            composer: self.main.name.clone(),
        }
    }

    /// Makes rows `rows` band by band (at most `band_pixels` pixels a band), each band handed to
    /// `sink` with its first row. A row's pixels do not depend on the bands it was made in.
    pub(crate) fn rows(
        &mut self,
        rows: Range<usize>,
        band_pixels: usize,
        watch: &Watch,
        sink: &mut dyn FnMut(usize, Vec<f32>) -> Result<(), ExportError>,
    ) -> Result<Made, ExportError> {
        let (w, h) = self.raster.size;
        let band_rows = (band_pixels / w.max(1)).clamp(1, h.max(1));
        let halo = usize::from(self.attribute.is_some());
        let mut made = Made { valid: 0, quads: BTreeSet::new() };
        watch.start_phase("rows", rows.len() as u64);
        for first in rows.clone().step_by(band_rows) {
            watch.check().map_err(cancelled)?;
            let band = first..(first + band_rows).min(rows.end);
            // The band's rows with the halo an attribute's window reads.
            let read = first.saturating_sub(halo)..(band.end + halo).min(h);
            let points = self.raster.pixel_lat_lon_rows(&self.crs, &self.body, &self.out, read.clone())?;
            let cells = pixel_cells(&self.body, self.level, &points);
            let band_quads: Vec<QuadId> =
                cells.iter().flatten().map(|c| c.0).collect::<BTreeSet<_>>().into_iter().collect();
            made.quads.extend(band_quads.iter().copied());
            self.main.compose(&band_quads, watch)?;
            let mut data = match self.minus.as_mut() {
                None => sampled(&cells, &self.main.grids),
                Some(minus) => {
                    minus.compose(&band_quads, watch)?;
                    let (a, b) = (&self.main.grids, &minus.grids);
                    let difference: HashMap<QuadId, Vec<f32>> = band_quads
                        .iter()
                        .map(|q| (*q, a[q].iter().zip(&b[q]).map(|(x, y)| x - y).collect())) // NaN where either has none
                        .collect();
                    sampled(&cells, &difference)
                }
            };
            // A terrain attribute of the heights, with each pixel's steps measured on the body.
            if let Some(a) = self.attribute {
                let axes = crate::attributes::pixel_axes(&self.body, w, read.len(), &points);
                data = match &self.attribute_gpu {
                    None => crate::attributes::attribute_raster(a, w, read.len(), &data, &axes),
                    Some(ctx) => crate::gpu::attributes::attribute_raster(ctx, a, w, read.len(), &data, &axes)?,
                };
            }
            let kept: Vec<f32> = data[(band.start - read.start) * w..(band.end - read.start) * w].to_vec();
            made.valid += kept.iter().filter(|v| !v.is_nan()).count() as u64;
            sink(band.start, kept)?;
            watch.advance_by(band.len() as u64);
        }
        Ok(made)
    }
}

/// Most pixels of one band of an export (4·10⁶: with their positions, cells and heights about
/// 150 MB, and the grids of the quads they read).
pub(crate) const BAND_PIXELS: usize = 1 << 22;

/// An export cancelled: nothing written.
pub(crate) fn cancelled(_: crate::progress::Cancelled) -> ExportError {
    ExportError::Cancelled
}

/// Where each pixel (lat, lon, radians; NaN off the body) falls at `level`: the quad and the
/// sample cell inside it.
fn pixel_cells(body: &crate::geodesy::Ellipsoid, level: u8, points: &[(f64, f64)]) -> Vec<Option<Cell>> {
    let m = intervals_per_face_edge(level);
    points
        .iter()
        .map(|&(lat, lon)| {
            if lat.is_nan() {
                return None;
            }
            let p = CubeProjection::Qsc.face_point_from_geodetic(body, lat, lon);
            let (u, v) = ((p.x + 1.0) * 0.5 * m as f64, (p.y + 1.0) * 0.5 * m as f64);
            let (i, j) = ((u.floor() as i64).clamp(0, m - 1), (v.floor() as i64).clamp(0, m - 1));
            let quad = QuadId { face: p.face, level, x: (i / 256) as u32, y: (j / 256) as u32 };
            Some((quad, (i % 256) as usize, (j % 256) as usize, u - i as f64, v - j as f64))
        })
        .collect()
}

/// What composes an export's quads (the CPU reference, or the GPU's renderer), with the grids of
/// the band before kept: a band's quads are mostly the next one's.
struct Composer {
    compose: Compose,
    grids: HashMap<QuadId, Vec<f32>>,
    name: String,
}

enum Compose {
    Cpu(Box<Scene>),
    Gpu(Box<Renderer>),
}

impl Composer {
    fn new(scene: Scene, compose_on: ComposeOn) -> Result<Composer, ExportError> {
        Ok(match compose_on {
            ComposeOn::Cpu => {
                Composer { compose: Compose::Cpu(Box::new(scene)), grids: HashMap::new(), name: "CPU reference".into() }
            }
            ComposeOn::Gpu => {
                let ctx = GpuContext::headless()?;
                let name = format!("GPU, {}", ctx.describe());
                Composer {
                    compose: Compose::Gpu(Box::new(Renderer::new(&ctx, scene, IMAGE_FORMAT)?)),
                    grids: HashMap::new(),
                    name,
                }
            }
        })
    }

    /// Composes `quads` (those kept from the band before aside) and drops the grids of the rest.
    fn compose(&mut self, quads: &[QuadId], watch: &Watch) -> Result<(), ExportError> {
        let wanted: HashSet<QuadId> = quads.iter().copied().collect();
        self.grids.retain(|q, _| wanted.contains(q));
        let missing: Vec<QuadId> = quads.iter().copied().filter(|q| !self.grids.contains_key(q)).collect();
        match &mut self.compose {
            // In batches, for the cancel (each quad is composed alone: the same heights).
            Compose::Cpu(scene) => {
                for batch in missing.chunks(4 * GPU_BATCH) {
                    watch.check().map_err(cancelled)?;
                    self.grids.extend(scene.compose_cpu(batch)?);
                }
            }
            Compose::Gpu(renderer) => {
                for batch in missing.chunks(GPU_BATCH) {
                    watch.check().map_err(cancelled)?;
                    renderer.compose_now(batch)?;
                    for &q in batch {
                        let grid = renderer.read_heights(q)?;
                        self.grids.insert(q, grid.unwrap_or_else(|| vec![f32::NAN; 257 * 257]));
                    }
                }
            }
        }
        Ok(())
    }
}

/// The heights at `cells` from the grids of their quads: bilinear in each cell, NaN off the body.
fn sampled(cells: &[Option<Cell>], grids: &HashMap<QuadId, Vec<f32>>) -> Vec<f32> {
    cells
        .iter()
        .map(|cell| {
            let Some((quad, i, j, tx, ty)) = *cell else { return f32::NAN };
            let g = &grids[&quad];
            let mut h = 0.0;
            for (di, dj, w) in
                [(0, 0, (1.0 - tx) * (1.0 - ty)), (1, 0, tx * (1.0 - ty)), (0, 1, (1.0 - tx) * ty), (1, 1, tx * ty)]
            {
                if w > 0.0 {
                    h += w * f64::from(g[(j + dj) * 257 + i + di]);
                }
            }
            h as f32
        })
        .collect()
}
