//! `terrafuse export`: a project's composed elevation (the whole layer stack, as drawn) written as
//! a float32 GeoTIFF in any CRS, atomically, with NaN as nodata. Each pixel centre is taken
//! through PROJ to the body, onto the cube map at the chosen level, and interpolated bilinearly
//! from the composed grid of the quad that holds it (as `store export` does for one dataset).
//! The quads are composed on the GPU (the renderer's pass) or with the CPU reference.

use super::{CliError, Within};
use crate::attributes::Attribute;
use std::collections::{BTreeSet, HashMap};
use std::path::PathBuf;

use crate::ecm::grid::{intervals_per_face_edge, level_for_resolution};
use crate::ecm::{CubeProjection, QuadId};
use crate::gpu::{GpuContext, IMAGE_FORMAT, Renderer};
use crate::progress::Watch;
use crate::project::Project;
use crate::scene::Scene;
use crate::store::export::RasterSpec;

pub use crate::gpu::compose::ComposeOn;

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
pub fn export_composed(opts: &ComposedExport) -> Result<ComposedReport, CliError> {
    export_composed_watched(opts, &Watch::default())
}

/// [`export_composed`], the quads composed counted on `watch` (and stopped when it is cancelled,
/// before anything is written).
pub fn export_composed_watched(opts: &ComposedExport, watch: &Watch) -> Result<ComposedReport, CliError> {
    let project = Project::load(&opts.project)?;
    let raster = RasterSpec::new(&opts.crs, opts.bounds, opts.resolution, &opts.out)?;
    if let Some(l) = opts.level
        && l > crate::ecm::MAX_LEVEL
    {
        return Err(format!("--level {l}: levels run 0–{}", crate::ecm::MAX_LEVEL).into());
    }
    let (scene, _) = Scene::open(&project).within(opts.project.display())?;
    let body = scene.ellipsoid;
    let level = match opts.level {
        Some(l) => l,
        None => {
            let r = raster.pixel_ground_m(&opts.crs, &body, &opts.out)?;
            crate::layers::default_level(level_for_resolution(&body, r), scene.detail_level())
        }
    };
    let points = raster.pixel_lat_lon(&opts.crs, &body, &opts.out)?;

    // Where each pixel falls: the quad, and the sample cell inside it.
    let m = intervals_per_face_edge(level);
    let cells: Vec<Option<Cell>> = points
        .iter()
        .map(|&(lat, lon)| {
            if lat.is_nan() {
                return None;
            }
            let p = CubeProjection::Qsc.face_point_from_geodetic(&body, lat, lon);
            let (u, v) = ((p.x + 1.0) * 0.5 * m as f64, (p.y + 1.0) * 0.5 * m as f64);
            let (i, j) = ((u.floor() as i64).clamp(0, m - 1), (v.floor() as i64).clamp(0, m - 1));
            let quad = QuadId { face: p.face, level, x: (i / 256) as u32, y: (j / 256) as u32 };
            Some((quad, (i % 256) as usize, (j % 256) as usize, u - i as f64, v - j as f64))
        })
        .collect();
    let quads: Vec<QuadId> = cells.iter().flatten().map(|c| c.0).collect::<BTreeSet<_>>().into_iter().collect();

    let alone = |name: &str| {
        let operand = crate::layers::Operand::Layer(name.into());
        crate::compare::sample::operand_scene(&scene, &project, &operand).within(opts.project.display())
    };
    let (grids, composer) = match &opts.difference {
        None => match &opts.layer {
            None => compose_grids(scene, &quads, opts.compose_on, watch)?,
            Some(name) => compose_grids(alone(name)?, &quads, opts.compose_on, watch)?,
        },
        Some((a, b)) => {
            let (mut grids, composer) = compose_grids(alone(a)?, &quads, opts.compose_on, watch)?;
            let (minus, _) = compose_grids(alone(b)?, &quads, opts.compose_on, watch)?;
            for (q, g) in grids.iter_mut() {
                for (v, w) in g.iter_mut().zip(&minus[q]) {
                    *v -= w; // NaN where either has none
                }
            }
            (grids, composer)
        }
    };

    let data: Vec<f32> = cells
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
        .collect();
    // A terrain attribute of the heights, with each pixel's steps measured on the body.
    let data = match opts.attribute {
        None => data,
        Some(a) => {
            let (w, h) = raster.size;
            let axes = crate::attributes::pixel_axes(&body, w, h, &points);
            match opts.compose_on {
                ComposeOn::Cpu => crate::attributes::attribute_raster(a, w, h, &data, &axes),
                ComposeOn::Gpu => {
                    crate::gpu::attributes::attribute_raster(&GpuContext::headless()?, a, w, h, &data, &axes)?
                }
            }
        }
    };
    let valid = data.iter().filter(|v| !v.is_nan()).count() as u64;
    let layers: Vec<String> = match (&opts.difference, &opts.layer) {
        (Some((a, b)), _) => vec![format!("{a} - {b} (difference)")],
        (None, Some(name)) => vec![format!("{name} (alone)")],
        (None, None) => project.layers.iter().filter(|l| l.visible).map(|l| l.name.clone()).collect(),
    };
    let mut metadata = vec![
        ("TERRAFUSE_PROJECT", opts.project.to_string_lossy().into_owned()),
        ("TERRAFUSE_LAYERS", layers.join(",")),
        ("TERRAFUSE_LEVEL", level.to_string()),
        ("TERRAFUSE_COMPOSED_ON", composer.clone()),
    ];
    if let Some(a) = opts.attribute {
        metadata.push(("TERRAFUSE_ATTRIBUTE", format!("{} ({})", a.name(), a.unit())));
    }
    raster.write(&opts.out, &metadata, data)?;
    Ok(ComposedReport { size: raster.size, level, quads: quads.len(), valid, composer })
}

/// Composes quads of a scene where asked: their 257² grids (all no data where the stack gives
/// none) and what composed them.
fn compose_grids(
    scene: Scene,
    quads: &[QuadId],
    compose_on: ComposeOn,
    watch: &Watch,
) -> Result<(HashMap<QuadId, Vec<f32>>, String), CliError> {
    watch.start_phase("quads", quads.len() as u64);
    let cancelled = |_| CliError::from("the export was cancelled; nothing was written");
    match compose_on {
        ComposeOn::Cpu => {
            // In batches, for the progress (each quad is composed alone: the same heights).
            let mut grids = HashMap::new();
            for batch in quads.chunks(4 * GPU_BATCH) {
                watch.check().map_err(cancelled)?;
                grids.extend(scene.compose_cpu(batch)?);
                watch.advance_by(batch.len() as u64);
            }
            Ok((grids, "CPU reference".to_string()))
        }
        ComposeOn::Gpu => {
            let ctx = GpuContext::headless()?;
            let name = ctx.describe();
            let mut renderer = Renderer::new(&ctx, scene, IMAGE_FORMAT)?;
            let mut grids = HashMap::new();
            for batch in quads.chunks(GPU_BATCH) {
                watch.check().map_err(cancelled)?;
                watch.advance_by(batch.len() as u64);
                renderer.compose_now(batch)?;
                for &q in batch {
                    let grid = renderer.read_heights(q)?;
                    grids.insert(q, grid.unwrap_or_else(|| vec![f32::NAN; 257 * 257]));
                }
            }
            Ok((grids, format!("GPU, {name}")))
        }
    }
}
