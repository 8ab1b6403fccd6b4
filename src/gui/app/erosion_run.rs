//! A hydraulic run in progress in the workstation, off the interface thread. On the CPU
//! reference (software adapters) the run steps on a thread of its own, which publishes a
//! [`Snapshot`] of it a few times a second (the layer's tiles with the change so far, the field
//! draped over the terrain, the region's map, the figures the panel shows), so a frame costs what
//! drawing costs whatever the run's size: the window answers a click within a frame while a run
//! goes on. Pause holds the thread between steps; *keep* and *discard* stop it and take the run
//! back. On a hardware GPU the kernels step without blocking the frame, as before.

use std::sync::atomic::{AtomicBool, AtomicU8, AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::thread::JoinHandle;

use super::erosion_overlay::{Overlay, field, region_map};
use crate::edit::EditRaster;
use crate::erosion::region::Region;
use crate::erosion::sim::{Budget, Run};
use crate::gpu::erosion::GpuRun;
use crate::gui::GuiError;

/// What the panel shows of a run.
#[derive(Clone, Copy, Debug, Default)]
pub(crate) struct Figures {
    pub budget: Budget,
    pub unit_m3: f64,
    pub dt_s: f64,
    pub cfl_bound_s: f64,
    pub max_speed_m_s: f64,
    pub max_depth_m: f64,
    /// Water and soil the budget does not explain, units (as last computed).
    pub unexplained: (i64, i64),
}

impl Figures {
    /// The figures of a run on the host.
    pub(crate) fn of(run: &Run) -> Figures {
        let bound = run.cfl_bound_s();
        Figures {
            budget: run.budget,
            unit_m3: run.unit_m3(),
            dt_s: run.params.dt_s.min(bound),
            cfl_bound_s: bound,
            max_speed_m_s: run.state.speed_m_s.iter().fold(0f64, |m, v| m.max(*v)),
            max_depth_m: (0..run.grid.len()).map(|i| run.depth_m(i)).fold(0f64, f64::max),
            unexplained: run.unexplained(),
        }
    }
}

/// A run as it stood at a step: what the window shows of it.
pub(crate) struct Snapshot {
    pub figures: Figures,
    /// The layer with the change so far, its coarse levels made (on the thread that made the
    /// snapshot, so that drawing it only reads them).
    pub raster: EditRaster,
    /// The overlay's field as a raster, and its largest |value|.
    pub field: (EditRaster, f64),
    /// The region's map.
    pub map: egui::ColorImage,
}

impl Snapshot {
    /// What the window shows of `run` on `region` over `base`, the map and drape of `overlay`.
    pub(crate) fn of(run: &Run, base: &EditRaster, region: &Region, overlay: Overlay) -> Snapshot {
        let values = field(run, overlay);
        let range = values.iter().filter(|v| v.is_finite()).fold(0f64, |m, v| m.max(v.abs()));
        let mut raster = base.clone();
        raster.apply_tiles(usize::MAX, crate::erosion::layer::tiles_with(base, region, run));
        raster.clear_history();
        raster.warm();
        let field = crate::erosion::layer::field_raster(base.ellipsoid, region, &values);
        field.warm();
        Snapshot { figures: Figures::of(run), raster, field: (field, range), map: region_map(run, overlay) }
    }
}

/// Between the interface and the run's thread.
#[derive(Default)]
struct Shared {
    /// Steps asked for (the thread idles once it has taken them).
    target: AtomicU64,
    steps: AtomicU64,
    running: AtomicBool,
    stop: AtomicBool,
    overlay: AtomicU8,
    /// Seconds the steps took.
    seconds: Mutex<f64>,
    /// The latest snapshot not yet shown.
    snapshot: Mutex<Option<Snapshot>>,
    /// Wakes the thread when it idles.
    wake: (Mutex<()>, Condvar),
}

/// A CPU run stepping on its own thread.
pub(crate) struct Worker {
    shared: Arc<Shared>,
    handle: Option<JoinHandle<Run>>,
}

/// How often a running run shows itself.
const SHOW_EVERY: std::time::Duration = std::time::Duration::from_millis(300);

fn overlay_code(o: Overlay) -> u8 {
    match o {
        Overlay::Water => 0,
        Overlay::Sediment => 1,
        Overlay::Change => 2,
    }
}

fn overlay_of(code: u8) -> Overlay {
    match code {
        1 => Overlay::Sediment,
        2 => Overlay::Change,
        _ => Overlay::Water,
    }
}

impl Worker {
    /// Starts the thread on `run` over `base` (paused, no step asked).
    pub(crate) fn start(mut run: Run, base: EditRaster, region: Region, overlay: Overlay) -> Worker {
        let shared = Arc::new(Shared::default());
        shared.overlay.store(overlay_code(overlay), Ordering::Relaxed);
        let s = shared.clone();
        let handle = crate::gui::background::spawn("erosion-run", move || {
            let mut shown = std::time::Instant::now();
            let mut dirty = false;
            let mut drawn_overlay = u8::MAX;
            loop {
                dirty |= s.overlay.load(Ordering::Relaxed) != drawn_overlay && run.steps > 0;
                if s.stop.load(Ordering::Acquire) {
                    return run;
                }
                let busy = s.running.load(Ordering::Acquire) && run.steps < s.target.load(Ordering::Acquire);
                if busy {
                    let t = std::time::Instant::now();
                    run.step();
                    *s.seconds.lock().unwrap_or_else(|p| p.into_inner()) += t.elapsed().as_secs_f64();
                    s.steps.store(run.steps, Ordering::Release);
                    dirty = true;
                }
                if dirty && (!busy || shown.elapsed() >= SHOW_EVERY) {
                    drawn_overlay = s.overlay.load(Ordering::Relaxed);
                    let snapshot = Snapshot::of(&run, &base, &region, overlay_of(drawn_overlay));
                    *s.snapshot.lock().unwrap_or_else(|p| p.into_inner()) = Some(snapshot);
                    shown = std::time::Instant::now();
                    dirty = false;
                }
                if !busy {
                    let (lock, wake) = &s.wake;
                    let guard = lock.lock().unwrap_or_else(|p| p.into_inner());
                    let _ = wake.wait_timeout(guard, std::time::Duration::from_millis(50));
                }
            }
        });
        Worker { shared, handle: Some(handle) }
    }

    fn nudge(&self) {
        self.shared.wake.1.notify_all();
    }

    /// Runs on up to `target` steps in all (or pauses: `running` false).
    pub(crate) fn set(&self, running: bool, target: u64) {
        self.shared.target.store(target, Ordering::Release);
        self.shared.running.store(running, Ordering::Release);
        self.nudge();
    }

    /// Whether it is stepping (asked to run and short of its target).
    pub(crate) fn running(&self) -> bool {
        self.shared.running.load(Ordering::Acquire) && self.steps() < self.shared.target.load(Ordering::Acquire)
    }

    /// Steps taken.
    pub(crate) fn steps(&self) -> u64 {
        self.shared.steps.load(Ordering::Acquire)
    }

    /// Seconds its steps took.
    pub(crate) fn seconds(&self) -> f64 {
        *self.shared.seconds.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// What the next snapshot's map and drape show.
    pub(crate) fn set_overlay(&self, overlay: Overlay) {
        if self.shared.overlay.swap(overlay_code(overlay), Ordering::Relaxed) != overlay_code(overlay) {
            self.nudge();
        }
    }

    /// The latest snapshot, once (None while nothing new).
    pub(crate) fn take_snapshot(&self) -> Option<Snapshot> {
        self.shared.snapshot.lock().unwrap_or_else(|p| p.into_inner()).take()
    }

    /// Stops the thread between two steps and takes the run back.
    pub(crate) fn finish(mut self) -> Result<Run, GuiError> {
        self.shared.stop.store(true, Ordering::Release);
        self.nudge();
        let handle = self.handle.take().ok_or("the erosion run's thread is gone")?;
        handle.join().map_err(|_| "the erosion run's thread stopped".into())
    }
}

impl Drop for Worker {
    fn drop(&mut self) {
        // A session dropped without keep or discard (the window closing): the thread stops.
        self.shared.stop.store(true, Ordering::Release);
        self.nudge();
    }
}

/// Where the run's steps are taken.
pub(crate) enum Engine {
    /// The CPU reference, on its thread.
    Cpu(Worker),
    /// The GPU kernels, stepped by the frame without waiting.
    Gpu(Box<GpuRun>),
}
