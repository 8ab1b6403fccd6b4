//! A window driven from outside, for the tests that drive the real window under Xvfb with
//! xdotool (`tests/gui.rs`): each frame the window writes what it shows to `state.json` in a
//! folder (the camera, the viewport's place in the window, the strokes and runs of its layers,
//! the last stroke's path, the frame's number and the time the frame's work took, the delay
//! aside), and takes one-line commands from a file
//! `commands` there (a tab to show, the brush on or off, an erosion run to start) that set up
//! what the test then does with the real pointer and keys. Frames can be slowed to about one a
//! second, as on a software GPU with a big scene, so that input arrives between frames.
//! `terrafuse view` sets it from `TERRAFUSE_DEBUG_WINDOW` (the folder) and
//! `TERRAFUSE_FRAME_DELAY_MS`; nothing of it runs otherwise.

use std::path::PathBuf;

use super::*;

/// Where the window reports and takes commands, and how slow its frames are.
#[derive(Clone, Debug, Default)]
pub struct DebugHook {
    /// The folder of `state.json` and `commands`.
    pub dir: PathBuf,
    /// Each frame lasts at least this long.
    pub frame_delay: Duration,
    /// Frames the window has run through (drawn or not).
    pub frames: u64,
    /// The work of the last [`RECENT`] frames, ms (the delay aside).
    pub recent_ms: std::collections::VecDeque<f64>,
}

/// How many frames' times the state keeps.
const RECENT: usize = 16;

impl App {
    /// Drives the window from the debug folder (a command a frame) and reports its state.
    pub(super) fn debug_frame(&mut self, ctx: &egui::Context, frame_time: Duration) {
        let Some(hook) = self.debug.as_mut() else { return };
        hook.frames += 1;
        if hook.recent_ms.len() == RECENT {
            hook.recent_ms.pop_front();
        }
        hook.recent_ms.push_back(frame_time.as_secs_f64() * 1e3);
        let hook = hook.clone();
        let commands = hook.dir.join("commands");
        if let Ok(text) = std::fs::read_to_string(&commands) {
            let _ = std::fs::remove_file(&commands);
            for line in text.lines() {
                self.debug_command(ctx, line.trim());
            }
        }
        let strokes: serde_json::Map<String, serde_json::Value> = self
            .project
            .layers
            .iter()
            .filter(|l| l.holds_deltas())
            .map(|l| {
                (
                    l.name.clone(),
                    serde_json::json!([l.operations(), l.applied_strokes().len() + l.applied_runs().len()]),
                )
            })
            .collect();
        let last_path = self
            .project
            .layers
            .iter()
            .find(|l| l.name == self.brush.layer_name())
            .and_then(|l| l.applied_strokes().last())
            .map(|s| s.path.clone());
        let c = self.camera;
        let state = serde_json::json!({
            "frame": hook.frames,
            "frame_ms": frame_time.as_secs_f64() * 1e3,
            "recent_ms": hook.recent_ms,
            "drawn": self.frames,
            "draw_ms": self.last_frame_ms,
            "composed": self.stats.composed.len(),
            "camera": [c.lat, c.lon, c.alt, c.heading, c.pitch, c.fov],
            "viewport_px": self.viewport_px.map(|r| [r.min.x, r.min.y, r.width(), r.height()]),
            "target": self.viewport.as_ref().map(|v| v.size()),
            "layers": strokes,
            "last_stroke_path": last_path,
            "erosion": self.erosion_progress(),
            "tab": format!("{:?}", self.tab),
            "brush_armed": self.brush_armed(),
            "message": self.message,
        });
        let _ = crate::files::write_atomic(&hook.dir.join("state.json"), state.to_string().as_bytes());
        ctx.request_repaint();
        std::thread::sleep(hook.frame_delay);
    }

    /// One command: `tab NAME`, `brush on|off`, `drape on|off` (the run's overlay on the terrain), `shot PATH` (the window as a PNG), `erosion STEPS HALF_M` (a run started and run).
    fn debug_command(&mut self, ctx: &egui::Context, line: &str) {
        let words: Vec<&str> = line.split_whitespace().collect();
        match words.as_slice() {
            ["tab", name] => {
                if let Some(tab) = side_panel::Tab::named(name) {
                    self.tab = tab;
                }
            }
            ["brush", on] => self.brush.on = *on == "on",
            ["drape", on] => self.erosion.drape = *on == "on",
            ["shot", path] => {
                let path = std::path::PathBuf::from(path);
                ctx.request_screenshot(move |image| {
                    let _ = write_screenshot(&path, &image);
                });
            }
            ["erosion", steps, half_m] => {
                if let (Ok(steps), Ok(half_m)) = (steps.parse(), half_m.parse()) {
                    self.set_erosion(steps, half_m);
                    self.start_erosion(None);
                    if let Some(s) = &mut self.erosion.session {
                        s.set_running(true);
                    }
                }
            }
            _ => self.message = format!("debug: unknown command '{line}'"),
        }
    }
}
