//! `terrafuse render`: one frame of a project to a PNG, with what it drew and what it cost.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use crate::gpu::{DrawMode, FrameStats, GpuContext, IMAGE_FORMAT, RenderedImage, Renderer, Scene};
use crate::project::{CameraSpec, Project};

/// What to render.
#[derive(Clone, Debug)]
pub struct RenderRequest<'a> {
    /// The project file.
    pub project: &'a Path,
    /// The PNG to write.
    pub out: &'a Path,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// A named view of the project.
    pub view: Option<&'a str>,
    /// Or an explicit camera `lat,lon,alt,heading,pitch[,fov]`.
    pub camera: Option<&'a str>,
    /// Overrides the project's level-of-detail threshold.
    pub lod_threshold: Option<f64>,
}

/// Opens a project for rendering: the project, its scene (importing missing datasets), the
/// device and the renderer; the lines say what was imported and on what device.
pub fn open_renderer(project_path: &Path) -> Result<(Project, Renderer, Vec<String>), String> {
    let project = Project::load(project_path).map_err(|e| e.to_string())?;
    let (scene, report) = Scene::open(&project).map_err(|e| format!("{}: {e}", project_path.display()))?;
    let ctx = GpuContext::headless().map_err(|e| e.to_string())?;
    let mut lines = report.imported;
    lines.push(format!("device: {}", ctx.describe()));
    let renderer = Renderer::new(&ctx, scene, IMAGE_FORMAT).map_err(|e| e.to_string())?;
    Ok((project, renderer, lines))
}

/// The camera of a request: `--camera`, else `--view`, else the project's default view.
pub fn request_camera(project: &Project, view: Option<&str>, camera: Option<&str>) -> Result<CameraSpec, String> {
    project.camera(view, camera)
}

/// Writes an image as PNG, atomically.
pub fn write_png(path: &Path, image: &RenderedImage) -> Result<(), String> {
    image.write_png(path)
}

/// Renders one frame and writes it; returns the report.
pub fn render(request: &RenderRequest) -> Result<String, String> {
    if request.width == 0 || request.height == 0 || request.width > 16384 || request.height > 16384 {
        return Err(format!("image size {}x{} must lie within 1–16384 pixels", request.width, request.height));
    }
    // Check the request before importing anything or opening the GPU.
    let project = Project::load(request.project).map_err(|e| e.to_string())?;
    let camera = request_camera(&project, request.view, request.camera)?;
    if let Some(t) = request.lod_threshold
        && !(t.is_finite() && t > 0.0)
    {
        return Err(format!("--lod-threshold {t} must be a positive number of pixels"));
    }
    let (_, mut renderer, lines) = open_renderer(request.project)?;
    if let Some(t) = request.lod_threshold {
        renderer.set_threshold(t);
    }
    let debug = std::env::var_os("TERRAFUSE_DEBUG").is_some();
    let quads = std::env::var_os("TERRAFUSE_DEBUG_QUADS").is_some();
    let stats = renderer.settle_traced(&camera, request.width, request.height, Duration::from_secs(300), &mut |s, busy| {
        if debug {
            eprintln!(
                "settle: {} drawn, {} pending, {} uploads, {} requested, {} blocked, loader {busy} / culled {} {} visited {}",
                s.selection.quads.len(),
                s.pending,
                s.uploads,
                s.requested,
                s.blocked,
                s.selection.culled_frustum,
                s.selection.culled_horizon,
                s.selection.visited
            );
        }
        if debug && quads {
            eprintln!(
                "  drawn {:?}\n  wanted {:?}",
                s.selection.quads.iter().map(|q| q.to_string()).collect::<Vec<_>>(),
                s.selection.wanted.iter().map(|q| q.to_string()).collect::<Vec<_>>()
            );
        }
    });
    let image = renderer.render_image(DrawMode::Colour).map_err(|e| e.to_string())?;
    write_png(request.out, &image)?;
    let mut out = String::new();
    for l in lines {
        let _ = writeln!(out, "{l}");
    }
    let _ = writeln!(
        out,
        "camera: lat {} lon {} alt {} m heading {} pitch {} fov {}",
        camera.lat, camera.lon, camera.alt, camera.heading, camera.pitch, camera.fov
    );
    out.push_str(&frame_report(&stats, image.gpu_ms, renderer.scene().detail.lod_threshold_px));
    let _ = writeln!(out, "wrote {} ({}x{})", request.out.display(), image.width, image.height);
    Ok(out)
}

/// The lines that describe a frame.
pub fn frame_report(stats: &FrameStats, gpu_ms: Option<f64>, threshold_px: f64) -> String {
    let mut out = String::new();
    let s = &stats.selection;
    let levels: Vec<String> = s.per_level().iter().map(|(l, n)| format!("L{l}:{n}")).collect();
    let _ = writeln!(out, "quads: {} ({}), t = {threshold_px} px per sample", s.quads.len(), levels.join(" "));
    let _ = writeln!(
        out,
        "culled: {} outside the frustum, {} behind the horizon; {} visited{}",
        s.culled_frustum,
        s.culled_horizon,
        s.visited,
        if s.capped { "; the quad cap stopped refinement" } else { "" }
    );
    let _ = writeln!(out, "triangles: {} ({} quads without static maps)", stats.triangles, stats.flat_quads);
    let _ = writeln!(out, "cpu: selection {:.3} ms, frame preparation {:.3} ms", stats.select_ms, stats.prepare_ms);
    match gpu_ms {
        Some(ms) => {
            let _ = writeln!(out, "gpu: terrain pass {ms:.3} ms");
        }
        None => {
            let _ = writeln!(out, "gpu: pass times unavailable (the adapter has no timestamp queries)");
        }
    }
    let (h, hc, m, mc) = stats.gpu_slots;
    let _ = writeln!(
        out,
        "caches: gpu {h}/{hc} height slots, {m}/{mc} map slots; cpu {:.1} MiB",
        stats.cpu_bytes as f64 / (1 << 20) as f64
    );
    if stats.pending > 0 {
        let _ = writeln!(
            out,
            "warning: {} quads are drawn coarser than asked (data not ready or the GPU cache full)",
            stats.pending
        );
    }
    for e in &stats.errors {
        let _ = writeln!(out, "error: {e}");
    }
    out
}
