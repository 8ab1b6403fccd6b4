//! [`Console`]: what a command reads and writes besides its files. `main.rs` gives the
//! process's standard streams and environment, so that the library neither prints nor reads the
//! environment itself.

use std::io::{BufRead, Write};

use super::error::Context;
use super::{CliError, Trace};

/// What a command reads and writes besides its files: `main.rs` gives the process's.
pub struct Console<'a> {
    /// Records for `geo` and `store sample`.
    pub input: &'a mut dyn BufRead,
    /// The report.
    pub out: &'a mut dyn Write,
    /// Progress, notes and refused records.
    pub err: &'a mut dyn Write,
    /// How much `render` traces (from `TERRAFUSE_DEBUG`, `TERRAFUSE_DEBUG_QUADS`).
    pub trace: Trace,
    /// An environment variable's value (for `import --shard env`).
    pub var: &'a dyn Fn(&str) -> Option<String>,
    /// Whether standard error is a terminal (long commands draw a progress bar there).
    pub progress: bool,
}

impl Console<'_> {
    /// Writes `text` to the report.
    pub fn print(&mut self, text: impl std::fmt::Display) -> Result<(), CliError> {
        write!(self.out, "{text}").and_then(|()| self.out.flush()).context("cannot write to standard output")
    }

    /// Writes a line to standard error (a note: a failure to write it is not the command's).
    pub fn note(&mut self, line: impl std::fmt::Display) {
        let _ = writeln!(self.err, "{line}");
    }

    /// Notes that a project has a recovery file with unsaved changes.
    pub fn note_recovery(&mut self, project: &std::path::Path) {
        if let Some(r) = crate::project::recovery::find(project) {
            self.note(format_args!("terrafuse: note: {}", r.notice()));
        }
    }
}
