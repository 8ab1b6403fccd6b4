//! The *Flight* section of the view settings: record the camera as waypoints while flying, replay
//! the path (the interpolation `terrafuse render --flight` uses: geodesics, the altitude
//! geometrically), and the path as the command line's `--flight` text.

use super::*;
use crate::scene::flight::Flight;

/// Waypoints are recorded at most this often while the camera moves.
const RECORD_EVERY: Duration = Duration::from_millis(500);

/// The flight being recorded, edited or replayed.
pub(super) struct FlightTool {
    /// The path: `LAT,LON,ALT,HEADING,PITCH,FOV;…`, recorded or typed.
    pub(super) text: String,
    /// Frames a replay takes.
    pub(super) frames: usize,
    /// While recording: when the last waypoint was taken, and its camera.
    recording: Option<(Instant, CameraSpec)>,
    /// While replaying: the cameras and the next one.
    playing: Option<(Vec<CameraSpec>, usize)>,
    /// What the last replay drew, or why it could not start.
    pub(super) report: String,
    /// The most triangles per pixel of the replay so far, and its frames.
    drawn: (f64, usize),
}

impl Default for FlightTool {
    fn default() -> Self {
        FlightTool {
            text: String::new(),
            frames: 120,
            recording: None,
            playing: None,
            report: String::new(),
            drawn: (0.0, 0),
        }
    }
}

/// A camera as one waypoint of `--flight`.
fn waypoint(c: &CameraSpec) -> String {
    format!("{:.6},{:.6},{:.1},{:.2},{:.2},{:.1}", c.lat, c.lon, c.alt, c.heading, c.pitch, c.fov)
}

impl App {
    pub(super) fn flight_ui(&mut self, ui: &mut egui::Ui) {
        egui::CollapsingHeader::new("Flight").default_open(false).show(ui, |ui| {
            ui.horizontal(|ui| {
                let label = if self.flight.recording.is_some() { "stop recording" } else { "record" };
                if ui
                    .button(label)
                    .on_hover_text("adds the camera as a waypoint as it moves, twice a second at most")
                    .clicked()
                {
                    self.toggle_recording();
                }
                if ui.button("add waypoint").clicked() {
                    self.add_waypoint();
                }
                if ui.button("clear").clicked() {
                    self.flight.text.clear();
                    self.flight.recording = None;
                }
            });
            ui.add(
                egui::TextEdit::multiline(&mut self.flight.text)
                    .hint_text("LAT,LON,ALT,HEADING,PITCH[,FOV];…")
                    .desired_rows(3)
                    .font(egui::TextStyle::Monospace),
            );
            ui.horizontal(|ui| {
                ui.add(egui::DragValue::new(&mut self.flight.frames).range(2..=100_000).suffix(" frames"));
                let label = if self.flight.playing.is_some() { "stop" } else { "play" };
                if ui.button(label).on_hover_text("flies the path, one camera a frame").clicked() {
                    if self.flight.playing.is_some() {
                        self.flight.playing = None;
                    } else if let Err(e) = self.play_flight() {
                        self.flight.report = e.to_string();
                    }
                }
            });
            ui.label(
                egui::RichText::new("terrafuse render … --flight \"<the path above>\" --frames N --out-dir DIR")
                    .small(),
            );
            if !self.flight.report.is_empty() {
                ui.label(&self.flight.report);
            }
        });
    }

    fn toggle_recording(&mut self) {
        if self.flight.recording.take().is_none() {
            self.flight.text.clear();
            self.add_waypoint();
            self.flight.recording = Some((Instant::now(), self.camera));
        }
    }

    fn add_waypoint(&mut self) {
        if !self.flight.text.trim().is_empty() {
            self.flight.text.push_str(";\n");
        }
        self.flight.text.push_str(&waypoint(&self.camera));
        if let Some(r) = &mut self.flight.recording {
            *r = (Instant::now(), self.camera);
        }
    }

    /// Starts replaying the path; the error says what is wrong with it.
    pub fn play_flight(&mut self) -> Result<(), GuiError> {
        let flight = Flight::parse(&self.flight.text, self.camera.fov)?;
        let cameras = flight.cameras(&self.renderer.scene().ellipsoid, self.flight.frames)?;
        self.flight.recording = None;
        self.flight.playing = Some((cameras, 0));
        self.flight.drawn = (0.0, 0);
        self.flight.report = "playing".into();
        Ok(())
    }

    /// Per frame: while recording, the camera joins the path when it has moved (at most twice a
    /// second); while replaying, the next camera of the path.
    pub(super) fn flight_frame(&mut self, ctx: &egui::Context) {
        if let Some((at, last)) = self.flight.recording
            && self.camera != last
            && at.elapsed() >= RECORD_EVERY
        {
            self.flight.text.push_str(";\n");
            self.flight.text.push_str(&waypoint(&self.camera));
            self.flight.recording = Some((Instant::now(), self.camera));
        }
        if self.flight.recording.is_some() {
            ctx.request_repaint_after(RECORD_EVERY);
        }
        let Some((cameras, next)) = &mut self.flight.playing else { return };
        if *next > 0 {
            let pixels = self.viewport_px.map_or(1.0, |r| f64::from(r.width() * r.height())).max(1.0);
            let density = self.stats.triangles as f64 / pixels;
            self.flight.drawn = (self.flight.drawn.0.max(density), self.flight.drawn.1 + 1);
        }
        match cameras.get(*next).copied() {
            Some(c) => {
                *next += 1;
                self.set_camera(c);
                self.dirty = true;
                ctx.request_repaint();
            }
            None => {
                self.flight.report = format!(
                    "played {} frames; at most {:.2} triangles a pixel of the view",
                    self.flight.drawn.1, self.flight.drawn.0
                );
                self.flight.playing = None;
            }
        }
    }

    /// The flight's path text, frames and whether it is replaying (tests and tools).
    pub fn flight_state(&self) -> (&str, usize, bool, bool) {
        (&self.flight.text, self.flight.frames, self.flight.recording.is_some(), self.flight.playing.is_some())
    }

    /// Sets the path and the frames a replay takes (tests and tools).
    pub fn set_flight(&mut self, text: &str, frames: usize) {
        self.flight.text = text.to_string();
        self.flight.frames = frames;
    }

    /// Starts or stops recording (tests and tools).
    pub fn record_flight(&mut self, on: bool) {
        if on != self.flight.recording.is_some() {
            self.toggle_recording();
        }
    }
}
