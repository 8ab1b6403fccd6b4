//! Watching an import from another thread (the workstation's progress bar): the import counts
//! tiles on a [`crate::progress::Watch`] and checks its cancel switch after every tile. A
//! cancelled import stops with [`super::StoreError`] "cancelled" and keeps what it had committed
//! (in transactions of 32 tiles, as a crash would): the store stays valid and a later import
//! resumes it.

/// Shared between an import and whoever watches it.
pub type ImportWatch = crate::progress::Watch;

/// Where an import stands.
pub type ImportProgress = crate::progress::Progress;
