//! `terrafuse render`: one frame of a project to a PNG, with what it drew and what it cost.

use super::error::Context;
use super::{CliError, ComposeOn, Within};
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use crate::gpu::{DrawMode, FrameStats, GpuContext, IMAGE_FORMAT, RenderedImage, Renderer};
use crate::project::{CameraSpec, Project};
use crate::scene::Scene;

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
    /// `--pixel-error`: the geometric error allowed on screen, pixels (else the project's).
    pub pixel_error: Option<f64>,
    /// `--compose`: where frames compose the layer stack (None: by the adapter).
    pub compose_on: Option<ComposeOn>,
    /// `A,B[,POSITION]`: layer A left of a vertical line at POSITION (0–1 of the width, default
    /// 0.5), layer B right of it.
    pub swipe: Option<&'a str>,
    /// What to report while the frame settles (to `render`'s `log`).
    pub trace: Trace,
    /// Whether vertices morph between strides.
    pub geomorph: bool,
}

/// What `render` reports while the frame settles (`TERRAFUSE_DEBUG`, `TERRAFUSE_DEBUG_QUADS` on
/// the command line).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Trace {
    /// Nothing.
    Off,
    /// Each waiting step: drawn, pending, uploads, requests, culling.
    Steps,
    /// The steps and the quads drawn and wanted.
    Quads,
}

/// A parsed `--swipe A,B[,POSITION]`.
struct Swipe {
    a: String,
    b: String,
    position: f64,
}

fn parse_swipe(text: &str, project: &Project) -> Result<Swipe, CliError> {
    if let Some(saved) = project.comparison.swipes.get(text) {
        return Ok(Swipe { a: saved.a.clone(), b: saved.b.clone(), position: saved.position });
    }
    let parts: Vec<&str> = text.split(',').map(str::trim).collect();
    let (a, b, position) = match parts[..] {
        [a, b] => (a, b, 0.5),
        [a, b, p] => (a, b, p.parse::<f64>().context(format_args!("--swipe {text}: position {p}"))?),
        _ => {
            let saved: Vec<&str> = project.comparison.swipes.keys().map(String::as_str).collect();
            return Err(format!(
                "--swipe {text}: give A,B or A,B,POSITION (layer names, position 0–1) or a saved swipe ({})",
                if saved.is_empty() { "the project saves none".to_string() } else { saved.join(", ") }
            )
            .into());
        }
    };
    if !(0.0..=1.0).contains(&position) {
        return Err(format!("--swipe {text}: position {position} must lie within 0–1 of the width").into());
    }
    for name in [a, b] {
        if !project.layers.iter().any(|l| l.name == name) {
            let known: Vec<&str> = project.layers.iter().map(|l| l.name.as_str()).collect();
            return Err(format!(
                "--swipe {text}: layer '{name}' is not in the project (its layers: {})",
                known.join(", ")
            )
            .into());
        }
    }
    if a == b {
        return Err(format!("--swipe {text}: A and B are the same layer").into());
    }
    Ok(Swipe { a: a.into(), b: b.into(), position })
}

/// The project with layer `show` shown and layer `hide` hidden, and no difference layer drawn (a
/// swipe shows the layers themselves).
fn show_only(project: &Project, show: &str, hide: &str) -> Project {
    let mut p = project.clone();
    for layer in &mut p.layers {
        if layer.name == show {
            layer.visible = true;
        } else if layer.name == hide || !layer.gives_heights() {
            layer.visible = false;
        }
    }
    p
}

/// The two images side by side at `position` (0–1 of the width), with a white line between.
fn composite(left: &RenderedImage, right: &RenderedImage, position: f64) -> RenderedImage {
    let split = (position * f64::from(left.width)).round() as u32;
    let mut out = left.clone();
    for y in 0..left.height {
        for x in 0..left.width {
            let k = ((y * left.width + x) * 4) as usize;
            if x.abs_diff(split) <= 1 {
                out.rgba[k..k + 4].copy_from_slice(&[255, 255, 255, 255]);
            } else if x > split {
                out.rgba[k..k + 4].copy_from_slice(&right.rgba[k..k + 4]);
            }
        }
    }
    out.gpu_ms = match (left.gpu_ms, right.gpu_ms) {
        (Some(a), Some(b)) => Some(a + b),
        _ => None,
    };
    out
}

/// Opens a project for rendering: the project, its scene (importing missing datasets), the
/// device and the renderer; the lines say what was imported and on what device.
pub fn open_renderer(project_path: &Path) -> Result<(Project, Renderer, Vec<String>), CliError> {
    let project = Project::load(project_path)?;
    let (scene, report) = Scene::open(&project).within(project_path.display())?;
    let ctx = GpuContext::headless()?;
    let mut lines = report.imported;
    lines.extend(report.edits);
    lines.push(format!("device: {}", ctx.describe()));
    let mut renderer = Renderer::new(&ctx, scene, IMAGE_FORMAT)?;
    if let Some(line) = resolve_difference_range(&project, &mut renderer)? {
        lines.push(line);
    }
    Ok((project, renderer, lines))
}

/// Gives the renderer the drawn difference layer's range: its `range_m`, or the percentile of
/// |dh| computed here; the line says which.
pub fn resolve_difference_range(project: &Project, renderer: &mut Renderer) -> Result<Option<String>, CliError> {
    let Some(d) = renderer.scene().stack.drawn_difference() else { return Ok(None) };
    let spec = renderer.scene().stack.layers[d].spec.clone();
    let style = spec.difference_style();
    if style.range_m.is_none() {
        let range = crate::compare::difference_range(project, &spec)
            .within(format_args!("difference layer '{}'", spec.name))?;
        renderer.set_difference_range(range);
    }
    let how = match style.range_m {
        Some(_) => "its range_m".to_string(),
        None => format!("the {}th percentile of |dh|", style.percentile),
    };
    let of = spec.as_difference().map_or(String::new(), |d| format!("{} - {}", d.of[0], d.of[1]));
    Ok(Some(format!(
        "difference '{}' ({of}): red -{r:.2} m … white 0 … blue +{r:.2} m ({how})",
        spec.name,
        r = renderer.difference_range_m()
    )))
}

/// The camera of a request: `--camera`, else `--view`, else the project's default view.
pub fn request_camera(project: &Project, view: Option<&str>, camera: Option<&str>) -> Result<CameraSpec, CliError> {
    Ok(project.camera(view, camera)?)
}

/// Writes an image as PNG, atomically.
pub fn write_png(path: &Path, image: &RenderedImage) -> Result<(), CliError> {
    Ok(image.write_png(path)?)
}

/// Renders one frame and writes it; returns the report.
pub fn render(request: &RenderRequest, log: &mut dyn FnMut(&str)) -> Result<String, CliError> {
    if request.width == 0 || request.height == 0 || request.width > 16384 || request.height > 16384 {
        return Err(format!("image size {}x{} must lie within 1–16384 pixels", request.width, request.height).into());
    }
    // Check the request before importing anything or opening the GPU.
    let project = Project::load(request.project)?;
    let swipe = request.swipe.map(|s| parse_swipe(s, &project)).transpose()?;
    // A saved swipe brings its view, unless the command names one.
    let saved_view = request.swipe.and_then(|s| project.comparison.swipes.get(s)).and_then(|s| s.view.as_deref());
    let camera = request_camera(&project, request.view.or(saved_view), request.camera)?;
    check_detail(request.lod_threshold, request.pixel_error)?;
    let (_, mut renderer, lines) = open_renderer(request.project)?;
    apply_detail(&mut renderer, request.lod_threshold, request.pixel_error, request.compose_on);
    renderer.set_geomorph(request.geomorph);
    if let Some(s) = &swipe {
        // Each side is rendered as its own project would be, by a renderer of its own (a
        // difference layer shown on it with its colour range).
        let side = show_only(&project, &s.a, &s.b);
        let (scene, _) = Scene::open(&side)?;
        renderer = Renderer::new(&GpuContext::headless()?, scene, IMAGE_FORMAT)?;
        resolve_difference_range(&side, &mut renderer)?;
        apply_detail(&mut renderer, request.lod_threshold, request.pixel_error, request.compose_on);
    }
    let (debug, quads) = (request.trace != Trace::Off, request.trace == Trace::Quads);
    let stats = renderer.settle_traced(&camera, request.width, request.height, Duration::from_secs(300), &mut |s, busy| {
        if debug {
            log(&format!(
                "settle: {} drawn, {} pending, {} uploads, {} requested, {} blocked, loader {busy} / culled {} {} visited {}",
                s.selection.quads.len(),
                s.pending,
                s.uploads,
                s.requested,
                s.blocked,
                s.selection.culled_frustum,
                s.selection.culled_horizon,
                s.selection.visited
            ));
        }
        if debug && quads {
            log(&format!(
                "  drawn {:?}\n  wanted {:?}",
                s.selection.quads.iter().map(|q| q.to_string()).collect::<Vec<_>>(),
                s.selection.wanted.iter().map(|q| q.to_string()).collect::<Vec<_>>()
            ));
        }
    });
    let mut image = renderer.render_image(DrawMode::Colour)?;
    let mut swiped = String::new();
    if let Some(s) = &swipe {
        let side = show_only(&project, &s.b, &s.a);
        let (scene, _) = Scene::open(&side)?;
        let mut right_renderer = Renderer::new(&GpuContext::headless()?, scene, IMAGE_FORMAT)?;
        resolve_difference_range(&side, &mut right_renderer)?;
        apply_detail(&mut right_renderer, request.lod_threshold, request.pixel_error, request.compose_on);
        let right_stats = right_renderer.settle(&camera, request.width, request.height, Duration::from_secs(300));
        let right = right_renderer.render_image(DrawMode::Colour)?;
        image = composite(&image, &right, s.position);
        swiped = format!(
            "swipe: '{}' left of {:.0} % of the width, '{}' right of it ({} quads drawn right)\n",
            s.a,
            s.position * 100.0,
            s.b,
            right_stats.selection.quads.len()
        );
    }
    write_png(request.out, &image)?;
    let mut out = swiped;
    for l in lines {
        let _ = writeln!(out, "{l}");
    }
    let _ = writeln!(
        out,
        "camera: lat {} lon {} alt {} m heading {} pitch {} fov {}",
        camera.lat, camera.lon, camera.alt, camera.heading, camera.pitch, camera.fov
    );
    out.push_str(&frame_report(&stats, image.gpu_ms, &renderer.scene().detail));
    let _ = writeln!(out, "composition: {}", composition_line(renderer.compose_on()));
    let _ = writeln!(out, "wrote {} ({}x{})", request.out.display(), image.width, image.height);
    Ok(out)
}

/// Refuses a level-of-detail threshold or pixel error that is not a positive number of pixels.
pub fn check_detail(lod_threshold: Option<f64>, pixel_error: Option<f64>) -> Result<(), CliError> {
    crate::project::check_detail_overrides(lod_threshold, pixel_error).map_err(|e| e.to_string().into())
}

/// Where frames composed, in words.
pub fn composition_line(on: ComposeOn) -> &'static str {
    match on {
        ComposeOn::Gpu => "gpu (the compute pass)",
        ComposeOn::Cpu => "cpu (the reference; the default on a software adapter)",
    }
}

/// Applies `--lod-threshold`, `--pixel-error` and `--compose` where given.
pub fn apply_detail(
    renderer: &mut Renderer,
    lod_threshold: Option<f64>,
    pixel_error: Option<f64>,
    compose_on: Option<ComposeOn>,
) {
    if let Some(on) = compose_on {
        renderer.set_compose_on(on);
    }
    if let Some(t) = lod_threshold {
        renderer.set_threshold(t);
    }
    if let Some(e) = pixel_error {
        renderer.set_pixel_error(e);
    }
}

/// The lines that describe a frame.
pub fn frame_report(stats: &FrameStats, gpu_ms: Option<f64>, detail: &crate::project::DetailSpec) -> String {
    let mut out = String::new();
    let s = &stats.selection;
    let levels: Vec<String> = s.per_level().iter().map(|(l, n)| format!("L{l}:{n}")).collect();
    let threshold_px = detail.lod_threshold_px;
    let _ = writeln!(out, "quads: {} ({}), t = {threshold_px} px per sample", s.quads.len(), levels.join(" "));
    let _ = writeln!(
        out,
        "culled: {} outside the frustum, {} behind the horizon; {} visited{}",
        s.culled_frustum,
        s.culled_horizon,
        s.visited,
        if s.capped { "; the quad cap stopped refinement" } else { "" }
    );
    let p = &stats.patches;
    let strides: Vec<String> = crate::scene::patches::STRIDES
        .iter()
        .zip(p.per_stride())
        .filter(|(_, n)| *n > 0)
        .map(|(s, n)| format!("{n} at stride {s}"))
        .collect();
    let _ = writeln!(
        out,
        "patches: {} ({}); culled {} outside the frustum, {} behind the horizon",
        p.patches.len(),
        strides.join(", "),
        p.culled_frustum,
        p.culled_horizon
    );
    let _ = writeln!(out, "triangles: {} ({} quads without static maps)", stats.triangles, stats.flat_quads);
    let _ = writeln!(
        out,
        "max_error_px: {:.3} (the largest geometric error drawn, on screen; pixel error {} px)",
        stats.max_error_px, detail.max_pixel_error
    );
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
