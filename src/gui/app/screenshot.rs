//! Screenshot mode (`terrafuse view --screenshot`): once the frame has settled and been shown,
//! the window's picture is written (atomically) with a report of what it showed, and the window
//! closes.

use std::path::PathBuf;
use std::time::Duration;

use super::*;

/// A screenshot the window is asked to take once its frame has settled, then close.
pub struct ScreenshotJob {
    /// Where to write the PNG.
    pub path: PathBuf,
    /// Give up (and report failure) after this long.
    pub timeout: Duration,
}

/// What a screenshot run reports: the report, or why it failed.
pub type Outcome = Arc<Mutex<Option<Result<String, GuiError>>>>;

impl App {
    /// In screenshot mode: once the frame has settled and been shown, take the window's picture,
    /// write it and close.
    pub(super) fn screenshot(&mut self, ui: &egui::Ui) {
        let Some(job) = &self.screenshot else { return };
        let ctx = ui.ctx();
        let image = self.shot.lock().map(|mut s| s.take()).unwrap_or(None);
        if let Some(image) = image {
            let result = write_screenshot(&job.path, &image).map(|()| {
                let r = self.viewport_px.unwrap_or(egui::Rect::NOTHING);
                let (w, h) = self.viewport.as_ref().map_or((0, 0), |v| v.size());
                let l = self.legend_px.unwrap_or(egui::Rect::ZERO);
                let legend = format!("legend: {} {} {} {} (x y width height, pixels)", l.min.x, l.min.y, l.width(), l.height());
                format!(
                    "{}\nwindow: {}x{} pixels, written to {}\nviewport: {} {} {} {} (x y width height, pixels; rendered {w}x{h})\n{legend}\ncamera: {:.6},{:.6},{:.3},{:.4},{:.4},{:.3}\nframe: {}\ngpu: {}\nframes rendered: {}, {:.1} s\n",
                    self.device,
                    image.size[0],
                    image.size[1],
                    job.path.display(),
                    r.min.x,
                    r.min.y,
                    r.width(),
                    r.height(),
                    self.camera.lat,
                    self.camera.lon,
                    self.camera.alt,
                    self.camera.heading,
                    self.camera.pitch,
                    self.camera.fov,
                    frame_line(&self.stats),
                    self.viewport
                        .as_ref()
                        .and_then(|v| v.gpu_ms)
                        .map_or("pass time unavailable".into(), |ms| format!("terrain pass {ms:.3} ms")),
                    self.frames,
                    self.started.elapsed().as_secs_f64()
                )
            });
            if let Ok(mut o) = self.outcome.lock() {
                *o = Some(result);
            }
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
            return;
        }
        let settled = self.settled();
        self.settled_frames = if settled { self.settled_frames + 1 } else { 0 };
        if self.settled_frames >= 3 && !self.shot_requested {
            let shot = self.shot.clone();
            ctx.request_screenshot(move |image| {
                if let Ok(mut s) = shot.lock() {
                    *s = Some(image);
                }
            });
            self.shot_requested = true;
        }
        if self.started.elapsed() > job.timeout
            && let Ok(mut o) = self.outcome.lock()
            && o.is_none()
        {
            *o = Some(Err(format!(
                "the view did not settle within {:.0} s ({})",
                job.timeout.as_secs_f64(),
                frame_line(&self.stats)
            )
            .into()));
            ctx.send_viewport_cmd(egui::ViewportCommand::Close);
        }
        ctx.request_repaint_after(Duration::from_millis(20));
    }
}

/// Writes the window's picture as PNG, atomically.
pub(super) fn write_screenshot(path: &std::path::Path, image: &egui::ColorImage) -> Result<(), GuiError> {
    let rgba: Vec<u8> = image.pixels.iter().flat_map(|c| c.to_srgba_unmultiplied()).collect();
    let picture = crate::gpu::RenderedImage {
        width: image.size[0] as u32,
        height: image.size[1] as u32,
        rgba,
        surface: None,
        ids: None,
        gpu_ms: None,
    };
    Ok(picture.write_png(path)?)
}
