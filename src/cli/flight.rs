//! `terrafuse render --flight`: frames along a camera path, each drawn complete as `render` draws
//! one, with what each drew, what it cost and how far the terrain popped (`frames.csv`).

use super::{CliError, Within};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use super::render::{open_renderer, write_png};
use crate::gpu::pops::{DensityLayout, pop_px};
use crate::gpu::{DrawMode, FrameStats};
use crate::project::Project;
use crate::scene::flight::Flight;

/// What to fly.
#[derive(Clone, Debug)]
pub struct FlightRequest<'a> {
    /// The project file.
    pub project: &'a Path,
    /// `LAT,LON,ALT,HEADING,PITCH[,FOV];…`
    pub flight: &'a str,
    /// Frames along the path (≥ 2).
    pub frames: usize,
    /// Folder for `frame_0000.png` … and `frames.csv`.
    pub out_dir: &'a Path,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Overrides the project's level-of-detail threshold.
    pub lod_threshold: Option<f64>,
    /// `--pixel-error` (else the project's).
    pub pixel_error: Option<f64>,
    /// `--compose`: where frames compose the layer stack (None: by the adapter).
    pub compose_on: Option<super::ComposeOn>,
    /// Whether vertices morph between strides (off: to measure what morphing hides).
    pub geomorph: bool,
}

/// One frame of a flight, as `frames.csv` has it.
#[derive(Clone, Debug)]
pub struct FlightFrame {
    /// Frame number from 0.
    pub frame: usize,
    /// Quads drawn.
    pub quads: usize,
    /// Patches drawn.
    pub patches: usize,
    /// Triangles drawn.
    pub triangles: u64,
    /// Pixels showing terrain.
    pub terrain_pixels: usize,
    /// Quads per level, `L6:1 L9:21`.
    pub levels: String,
    /// The largest on-screen jump of the terrain from a change of density since the last frame.
    pub pop_px: f64,
    /// The largest projected geometric error of what was drawn, pixels.
    pub max_error_px: f64,
    /// The GPU terrain pass, ms (NaN without timestamp queries).
    pub gpu_ms: f64,
    /// CPU frame preparation, ms.
    pub cpu_ms: f64,
}

/// The CSV of a flight's frames.
pub fn frames_csv(frames: &[FlightFrame]) -> String {
    let mut out =
        String::from("frame,quads,patches,triangles,terrain_pixels,levels,pop_px,max_error_px,gpu_ms,cpu_ms\n");
    for f in frames {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{:.4},{:.4},{:.3},{:.3}",
            f.frame,
            f.quads,
            f.patches,
            f.triangles,
            f.terrain_pixels,
            f.levels,
            f.pop_px,
            f.max_error_px,
            f.gpu_ms,
            f.cpu_ms
        );
    }
    out
}

fn levels(stats: &FrameStats) -> String {
    stats.selection.per_level().iter().map(|(l, n)| format!("L{l}:{n}")).collect::<Vec<_>>().join(" ")
}

/// Renders the flight; writes the frames and `frames.csv`; returns the report.
pub fn render_flight(request: &FlightRequest, log: &mut dyn FnMut(&str)) -> Result<String, CliError> {
    if request.width == 0 || request.height == 0 || request.width > 16384 || request.height > 16384 {
        return Err(format!("image size {}x{} must lie within 1–16384 pixels", request.width, request.height).into());
    }
    super::render::check_detail(request.lod_threshold, request.pixel_error)?;
    let project = Project::load(request.project)?;
    let fov = project.camera(None, None)?.fov;
    let flight = Flight::parse(request.flight, fov).within("--flight")?;
    let ellipsoid = project.ellipsoid()?;
    let cameras = flight.cameras(&ellipsoid, request.frames).within("--frames")?;
    std::fs::create_dir_all(request.out_dir).map_err(CliError::file(request.out_dir, "cannot create"))?;
    let (_, mut renderer, lines) = open_renderer(request.project)?;
    super::render::apply_detail(&mut renderer, request.lod_threshold, request.pixel_error, request.compose_on);
    renderer.set_geomorph(request.geomorph);
    let mut frames = Vec::with_capacity(cameras.len());
    let mut previous: Option<DensityLayout> = None;
    for (k, camera) in cameras.iter().enumerate() {
        let stats = renderer.settle(camera, request.width, request.height, Duration::from_secs(300));
        for e in &stats.errors {
            log(&format!("frame {k}: {e}"));
        }
        let image = renderer.render_image(DrawMode::Colour)?;
        let probe = renderer.render_image(DrawMode::Probe)?;
        let layout = DensityLayout::of(&renderer);
        let pop = match &previous {
            Some(old) => pop_px(&renderer, old, &layout)?,
            None => 0.0,
        };
        previous = Some(layout);
        write_png(&request.out_dir.join(format!("frame_{k:04}.png")), &image)?;
        frames.push(FlightFrame {
            frame: k,
            quads: stats.selection.quads.len(),
            patches: stats.patches.patches.len(),
            triangles: stats.triangles,
            terrain_pixels: probe.ids.as_ref().map_or(0, |ids| ids.iter().filter(|id| id[0] > 0).count()),
            levels: levels(&stats),
            pop_px: pop,
            max_error_px: stats.max_error_px,
            gpu_ms: image.gpu_ms.unwrap_or(f64::NAN),
            cpu_ms: stats.prepare_ms,
        });
    }
    let csv = request.out_dir.join("frames.csv");
    crate::files::write_atomic(&csv, frames_csv(&frames).as_bytes()).map_err(CliError::file(&csv, "cannot write"))?;
    let mut out = String::new();
    for l in lines {
        let _ = writeln!(out, "{l}");
    }
    let n = frames.len() as f64;
    let worst_pop = frames.iter().map(|f| f.pop_px).fold(0.0, f64::max);
    let density = frames.iter().map(|f| f.triangles as f64 / f.terrain_pixels.max(1) as f64).fold(0.0, f64::max);
    let worst_error = frames.iter().map(|f| f.max_error_px).fold(0.0, f64::max);
    let _ = writeln!(
        out,
        "flight: {} frames of {}x{} at t = {} px per sample, geomorphing {}",
        frames.len(),
        request.width,
        request.height,
        renderer.scene().detail.lod_threshold_px,
        if renderer.geomorphs() { "on" } else { "off" }
    );
    let _ = writeln!(
        out,
        "triangles per terrain pixel: at most {density:.2}; max_error_px: at most {worst_error:.3} (pixel error {} px); pop: at most {worst_pop:.3} px; gpu {:.2} ms, cpu {:.3} ms a frame on average",
        renderer.scene().detail.max_pixel_error,
        frames.iter().map(|f| f.gpu_ms).sum::<f64>() / n,
        frames.iter().map(|f| f.cpu_ms).sum::<f64>() / n
    );
    let _ = writeln!(out, "wrote {} frames and {}", frames.len(), csv.display());
    Ok(out)
}
