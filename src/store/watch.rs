//! Watching an import from another thread (the workstation's progress bar): its phase, the tiles
//! done of the phase's total, and a cancel switch the import checks after every tile. A cancelled
//! import stops with [`StoreError`] "cancelled" and keeps what it had committed (in transactions
//! of 32 tiles, as a crash would): the store stays valid and a later import resumes it.

use std::sync::Mutex;
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};

/// Shared between an import and whoever watches it.
#[derive(Debug, Default)]
pub struct ImportWatch {
    phase: Mutex<String>,
    done: AtomicU64,
    total: AtomicU64,
    cancel: AtomicBool,
}

/// Where an import stands.
#[derive(Clone, Debug, Default, PartialEq, Eq)]
pub struct ImportProgress {
    /// The phase, e.g. `level 9` (empty before the first).
    pub phase: String,
    /// Tiles done in the phase.
    pub done: u64,
    /// Tiles the phase computes.
    pub total: u64,
}

impl ImportWatch {
    /// Asks the import to stop after the tiles in flight.
    pub fn cancel(&self) {
        self.cancel.store(true, Ordering::Relaxed);
    }

    /// Whether the import was asked to stop.
    pub fn is_cancelled(&self) -> bool {
        self.cancel.load(Ordering::Relaxed)
    }

    /// Where the import stands now.
    pub fn progress(&self) -> ImportProgress {
        ImportProgress {
            phase: self.phase.lock().unwrap_or_else(|p| p.into_inner()).clone(),
            done: self.done.load(Ordering::Relaxed),
            total: self.total.load(Ordering::Relaxed),
        }
    }

    pub(super) fn start_phase(&self, phase: &str, total: u64) {
        *self.phase.lock().unwrap_or_else(|p| p.into_inner()) = phase.to_string();
        self.done.store(0, Ordering::Relaxed);
        self.total.store(total, Ordering::Relaxed);
    }

    pub(super) fn advance(&self) {
        self.done.fetch_add(1, Ordering::Relaxed);
    }
}
