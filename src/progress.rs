//! Watching long work from another thread: its phase, the units done of the phase's total, and a
//! cancel switch the work checks between units. The work only counts; whoever watches draws (the
//! command line's progress bar on a terminal, the workstation's panels), so library code never
//! prints. A cancelled operation stops with its module's "cancelled" error and keeps nothing it
//! had not finished: an import keeps what it had committed (as a crash would), a stroke or a run
//! leaves the layer and the project as they were.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Shared between long work and whoever watches it.
#[derive(Debug, Default)]
pub struct Watch {
    phase: Mutex<String>,
    done: AtomicU64,
    total: AtomicU64,
    cancel: AtomicBool,
}

/// Where the work stands.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct Progress {
    /// The phase, e.g. `level 9` or `steps` (empty before the first).
    pub phase: String,
    /// Units done in the phase (tiles, steps, quads, operations).
    pub done: u64,
    /// Units the phase does (0: not known yet).
    pub total: u64,
}

/// The work stopped because it was asked to.
#[derive(Clone, Copy, Debug, PartialEq, Eq, thiserror::Error)]
#[error("cancelled")]
pub struct Cancelled;

impl Watch {
    /// Asks the work to stop at its next check.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Whether the work was asked to stop.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// `Err(Cancelled)` once the work was asked to stop (for `?` between units).
    pub fn check(&self) -> Result<(), Cancelled> {
        if self.is_cancelled() { Err(Cancelled) } else { Ok(()) }
    }

    /// Where the work stands now.
    pub fn progress(&self) -> Progress {
        Progress {
            phase: self.phase.lock().unwrap_or_else(|p| p.into_inner()).clone(),
            done: self.done.load(Ordering::Relaxed),
            total: self.total.load(Ordering::Relaxed),
        }
    }

    /// Starts a phase of `total` units (0 when not known), none done.
    pub fn start_phase(&self, phase: &str, total: u64) {
        *self.phase.lock().unwrap_or_else(|p| p.into_inner()) = phase.to_string();
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
    }

    /// One more unit done.
    pub fn advance(&self) {
        self.advance_by(1);
    }

    /// `n` more units done.
    pub fn advance_by(&self, n: u64) {
        self.done.fetch_add(n, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_phase_counts_from_zero_and_a_cancel_is_seen() {
        let w = Watch::default();
        w.start_phase("steps", 10);
        w.advance();
        w.advance_by(3);
        assert_eq!(w.progress(), Progress { phase: "steps".into(), done: 4, total: 10 });
        w.start_phase("tiles", 2);
        assert_eq!(w.progress().done, 0);
        assert_eq!(w.check(), Ok(()));
        w.cancel();
        assert_eq!(w.check(), Err(Cancelled));
    }
}
