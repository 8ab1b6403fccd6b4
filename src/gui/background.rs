//! Long work started from the window (erosion and landscape runs, comparisons,
//! co-registrations, imports) runs on threads of a pool of its own: one core fewer than the
//! machine has (at least one), at a lower scheduling priority, so that the interface thread and
//! a software GPU (lavapipe draws on the same cores) keep what drawing needs. On two cores a run
//! takes one: measured, a hydraulic run on the CPU otherwise starved the window's frames from
//! 0.1 s to 20 s on lavapipe; with this the frames cost what drawing costs (`tests/gui.rs`).

use std::sync::OnceLock;
use std::thread::JoinHandle;

/// How much lower than the window a background thread runs (`nice` steps).
const NICENESS: i32 = 10;

/// Lowers the calling thread's priority (best effort: a refusal leaves it as it was).
fn lower_priority() {
    // SAFETY: setpriority on the calling thread (who 0 with PRIO_PROCESS is the calling thread
    // on Linux); it touches no memory.
    unsafe {
        let _ = libc::setpriority(libc::PRIO_PROCESS, 0, NICENESS);
    }
}

/// The pool background work's parallel loops run on.
fn pool() -> Option<&'static rayon::ThreadPool> {
    static POOL: OnceLock<Option<rayon::ThreadPool>> = OnceLock::new();
    POOL.get_or_init(|| {
        let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
        rayon::ThreadPoolBuilder::new()
            .num_threads(cores.saturating_sub(1).max(1))
            .thread_name(|k| format!("terrafuse-background-{k}"))
            .start_handler(|_| lower_priority())
            .build()
            .ok()
    })
    .as_ref()
}

/// Runs `work` on a new thread, named `name`, at a lower priority, its parallel loops on the
/// background pool.
pub fn spawn<T: Send + 'static>(name: &str, work: impl FnOnce() -> T + Send + 'static) -> JoinHandle<T> {
    let run = move || {
        lower_priority();
        match pool() {
            Some(pool) => pool.install(work),
            None => work(),
        }
    };
    std::thread::Builder::new()
        .name(format!("terrafuse-{name}"))
        .spawn(run)
        .unwrap_or_else(|_| panic!("the system refused a thread for {name}"))
}
