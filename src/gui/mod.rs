//! The workstation: an eframe window whose viewport is the wgpu terrain renderer, embedded
//! through egui-wgpu on eframe's own device.

pub mod add_dataset;
pub mod app;
pub mod background;
pub mod cluster_compare;
pub mod cluster_import;
pub mod compare_panel;
pub mod difference_ui;
mod error;
pub mod export_panel;
pub mod file_pick;
pub mod layers_panel;
pub mod navigate;
pub mod recent;
pub mod uncertainty_ui;
pub mod viewport;
mod widgets;

pub use error::{GuiError, Within};
use std::path::{Path, PathBuf};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use crate::gpu::{GpuContext, IMAGE_FORMAT, Renderer};
use crate::project::Project;
use crate::scene::Scene;

/// What `terrafuse view` opens.
#[derive(Clone, Debug)]
pub struct ViewOptions {
    /// The project file.
    pub project: PathBuf,
    /// A named view of the project.
    pub view: Option<String>,
    /// Or an explicit camera `lat,lon,alt,heading,pitch[,fov]`.
    pub camera: Option<String>,
    /// Overrides the project's level-of-detail threshold.
    pub lod_threshold: Option<f64>,
    /// Overrides the project's pixel error (`detail.max_pixel_error`).
    pub pixel_error: Option<f64>,
    /// Window size, logical pixels.
    pub width: u32,
    /// Window size, logical pixels.
    pub height: u32,
    /// Take a picture of the window once the view has settled, write it here and close.
    pub screenshot: Option<PathBuf>,
    /// How long a screenshot run may wait for the view to settle.
    pub timeout: Duration,
    /// The workstation's configuration folder (the recent projects); None keeps nothing.
    pub config_dir: Option<PathBuf>,
    /// Driven from a folder, frames slowed (the real-window tests; `TERRAFUSE_DEBUG_WINDOW`).
    pub debug: Option<app::DebugHook>,
}

/// The device eframe asks for: the adapter's own limits (large storage buffers for the GPU
/// cache) and timestamp queries where the adapter has them; egui-wgpu's default asks for
/// `Limits::default()` and no features.
fn device_descriptor(adapter: &wgpu::Adapter) -> wgpu::DeviceDescriptor<'static> {
    wgpu::DeviceDescriptor {
        label: Some("terrafuse window"),
        required_features: adapter.features() & wgpu::Features::TIMESTAMP_QUERY,
        required_limits: adapter.limits(),
        ..Default::default()
    }
}

/// A project checked and opened for the window (datasets imported), before any window exists.
pub struct Opened {
    project: Project,
    project_path: PathBuf,
    scene: Scene,
    camera: crate::project::CameraSpec,
    screenshot: Option<app::ScreenshotJob>,
    outcome: app::Outcome,
    imported: Vec<String>,
    recent: recent::Recent,
    recovery: Option<crate::project::recovery::Recovery>,
    on_disk: crate::project::editing::OnDisk,
    debug: Option<app::DebugHook>,
}

impl Opened {
    /// One line per dataset imported from its sources while opening.
    pub fn imported(&self) -> &[String] {
        &self.imported
    }
}

/// Checks the request and opens the project: everything that can fail before a window opens.
pub fn open(opts: &ViewOptions) -> Result<Opened, GuiError> {
    if opts.width < 200 || opts.height < 150 || opts.width > 16384 || opts.height > 16384 {
        return Err(format!("window size {}x{} must lie within 200x150 … 16384x16384", opts.width, opts.height).into());
    }
    let (project, on_disk) = Project::load_seen(&opts.project)?;
    let camera = if opts.view.is_none() && opts.camera.is_none() {
        app::file::opening_camera(&project)
    } else {
        project.camera(opts.view.as_deref(), opts.camera.as_deref())?
    };
    crate::project::check_detail_overrides(opts.lod_threshold, opts.pixel_error).map_err(|e| e.to_string())?;
    if let Some(path) = &opts.screenshot {
        check_writable(path)?;
    }
    let (mut scene, report) = Scene::open(&project).within(opts.project.display())?;
    if let Some(t) = opts.lod_threshold {
        scene.detail.lod_threshold_px = t;
    }
    if let Some(e) = opts.pixel_error {
        scene.detail.max_pixel_error = e;
    }
    let mut recent = recent::Recent::load(opts.config_dir.as_deref());
    // A screenshot run is scripted: it neither lists the project nor offers a recovery.
    let recovery = match &opts.screenshot {
        Some(_) => None,
        None => {
            // The list is a convenience: a folder that cannot be written loses nothing else.
            let _ = recent.add(&opts.project);
            crate::project::recovery::find(&opts.project)
        }
    };
    Ok(Opened {
        recent,
        recovery,
        project,
        project_path: opts.project.clone(),
        scene,
        camera,
        screenshot: opts.screenshot.clone().map(|path| app::ScreenshotJob { path, timeout: opts.timeout }),
        outcome: Arc::new(Mutex::new(None)),
        imported: report.imported,
        on_disk,
        debug: opts.debug.clone(),
    })
}

/// The wgpu set-up of the window: eframe's, with [`device_descriptor`].
pub fn wgpu_setup() -> egui_wgpu::WgpuSetup {
    egui_wgpu::WgpuSetup::CreateNew(egui_wgpu::WgpuSetupCreateNew {
        device_descriptor: Arc::new(device_descriptor),
        ..egui_wgpu::WgpuSetupCreateNew::without_display_handle()
    })
}

/// The workstation on the device eframe created (the renderer shares it).
pub fn build_app(cc: &eframe::CreationContext<'_>, opened: Opened) -> Result<app::App, GuiError> {
    let rs = cc.wgpu_render_state.as_ref().ok_or("eframe started without its wgpu renderer")?;
    let ctx = context_of(rs);
    let device = format!("device: {}", ctx.describe());
    let renderer = Renderer::new(&ctx, opened.scene, IMAGE_FORMAT)?;
    let editor = crate::gpu::Editor::new(&ctx)?;
    Ok(app::App::new(
        opened.project,
        opened.project_path,
        (renderer, editor),
        opened.camera,
        opened.screenshot,
        opened.outcome,
        device,
    )
    .with_file(opened.recent, opened.recovery)
    .with_disk(Some(opened.on_disk))
    .with_debug(opened.debug))
}

/// The renderer's view of eframe's device.
pub fn context_of(rs: &egui_wgpu::RenderState) -> GpuContext {
    GpuContext {
        device: rs.device.clone(),
        queue: rs.queue.clone(),
        info: rs.adapter.get_info(),
        timestamps: rs.device.features().contains(wgpu::Features::TIMESTAMP_QUERY),
    }
}

/// Opens the workstation on a project; returns the screenshot run's report (empty when the
/// user closed the window).
pub fn run(opts: &ViewOptions, opened: Opened) -> Result<String, GuiError> {
    let outcome = opened.outcome.clone();
    let name = opts.project.file_stem().map_or("project".into(), |s| s.to_string_lossy().into_owned());
    let native = eframe::NativeOptions {
        viewport: egui::ViewportBuilder::default()
            .with_title(format!("Terrafuse — {name}"))
            .with_inner_size([opts.width as f32, opts.height as f32])
            .with_min_inner_size([400.0, 300.0]),
        wgpu_options: egui_wgpu::WgpuConfiguration { wgpu_setup: wgpu_setup(), ..Default::default() },
        ..Default::default()
    };
    let failed: Arc<Mutex<Option<GuiError>>> = Arc::new(Mutex::new(None));
    let failed_in = failed.clone();
    let result = eframe::run_native(
        "terrafuse",
        native,
        Box::new(move |cc| match build_app(cc, opened) {
            Ok(app) => Ok(Box::new(app)),
            Err(e) => {
                let text = e.to_string();
                if let Ok(mut f) = failed_in.lock() {
                    *f = Some(e);
                }
                Err(text.into())
            }
        }),
    );
    if let Some(e) = failed.lock().ok().and_then(|mut f| f.take()) {
        return Err(e);
    }
    result.map_err(|e| GuiError::Failure(Box::new(e))).within("the window could not be opened")?;
    let outcome = outcome.lock().ok().and_then(|mut o| o.take());
    match outcome {
        Some(result) => result,
        None if opts.screenshot.is_some() => Err("the window was closed before the screenshot was taken".into()),
        None => Ok(String::new()),
    }
}

/// Fails early, naming the file, when a screenshot could not be written.
fn check_writable(path: &Path) -> Result<(), GuiError> {
    let dir = crate::files::folder_of(path);
    if !dir.is_dir() {
        return Err(format!("{}: the folder {} does not exist", path.display(), dir.display()).into());
    }
    Ok(())
}
