//! What a long command tells while it works: lines on standard error (`waiting for terrafuse
//! brush, pid 1234`) and a progress bar drawn from the [`Watch`] the library counts on, on a
//! terminal only and never with `--json`; and the lock every command that changes a project
//! takes ([`change`]), with its `--wait`.

use std::path::Path;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Duration;

use indicatif::{ProgressBar, ProgressStyle};

use super::{CliError, Console};
use crate::files::lock::LockError;
use crate::progress::Watch;
use crate::project::Project;
use crate::project::editing::{Changer, DEFAULT_WAIT, Held};

/// What a running command may tell: a line now, and where it stands.
pub struct Feedback<'a> {
    /// Writes a line to standard error at once (above the progress bar).
    pub note: &'a mut dyn FnMut(&str),
    /// What the library counts on (the bar is drawn from it).
    pub watch: &'a Arc<Watch>,
}

impl Feedback<'_> {
    /// Runs `f` with feedback that tells nothing (tests, the library's own callers).
    pub fn quietly<T>(f: impl FnOnce(&mut Feedback) -> T) -> T {
        let watch = Arc::new(Watch::default());
        f(&mut Feedback { note: &mut |_| {}, watch: &watch })
    }
}

/// `--wait`: how long a command that changes a project waits for another that does.
#[derive(clap::Args, Clone, Debug)]
pub struct WaitArgs {
    /// Seconds to wait while another Terrafuse process (a command, the workstation saving)
    /// changes the project; then give up with nothing changed.
    #[arg(long, value_name = "SECONDS", default_value_t = DEFAULT_WAIT.as_secs_f64(), allow_negative_numbers = true)]
    pub wait: f64,
}

impl Default for WaitArgs {
    fn default() -> WaitArgs {
        WaitArgs { wait: DEFAULT_WAIT.as_secs_f64() }
    }
}

impl WaitArgs {
    /// The wait as a duration; an error names the flag.
    pub fn duration(&self) -> Result<Duration, CliError> {
        if !(self.wait.is_finite() && self.wait >= 0.0 && self.wait <= 1e7) {
            return Err(format!("--wait {}: give a number of seconds within 0 … 10000000", self.wait).into());
        }
        Ok(Duration::from_secs_f64(self.wait))
    }
}

/// Takes the lock of the project at `path` for `holder` (`terrafuse brush`), saying whom it
/// waits for, then reads the project: what the command changes and saves through the [`Held`]
/// while no other Terrafuse process can change it.
pub fn change(path: &Path, holder: &str, wait: &WaitArgs, fb: &mut Feedback) -> Result<(Project, Held), CliError> {
    let note = &mut *fb.note;
    let mut waiting = |who: &str| note(&format!("terrafuse: waiting for {who} to finish changing {}", path.display()));
    Project::load_to_change(path, Changer { holder, wait: wait.duration()?, waiting: &mut waiting }).map_err(
        |e| match e {
            crate::project::ProjectError::Lock(l) => lock_error(l),
            other => other.into(),
        },
    )
}

/// A lock that could not be taken; the flag that waits longer where another process held it.
pub fn lock_error(e: LockError) -> CliError {
    let text = crate::errors::chain(&e);
    match e {
        LockError::Busy { .. } => format!("{text} (wait longer with --wait SECONDS)").into(),
        _ => text.into(),
    }
}

/// Runs `work` with a progress bar on standard error when `show` and the console is a
/// terminal (`c.progress`), drawn from the work's watch every tenth of a second; notes are
/// written above the bar.
pub fn watched<T>(c: &mut Console, show: bool, work: impl FnOnce(&mut Feedback) -> T) -> T {
    let watch = Arc::new(Watch::default());
    let bar = if show && c.progress { ProgressBar::new(0) } else { ProgressBar::hidden() };
    bar.set_style(
        ProgressStyle::with_template("{prefix:>10} [{bar:32}] {pos}/{len}  {elapsed} elapsed, ~{eta} left")
            .expect("a valid template")
            .progress_chars("=> "),
    );
    let stop = AtomicBool::new(false);
    let err = &mut *c.err;
    let result = std::thread::scope(|s| {
        if !bar.is_hidden() {
            let (bar, watch, stop) = (&bar, &watch, &stop);
            s.spawn(move || {
                while !stop.load(Ordering::Relaxed) {
                    let p = watch.progress();
                    bar.set_prefix(p.phase);
                    bar.set_length(p.total);
                    bar.set_position(p.done);
                    std::thread::sleep(Duration::from_millis(100));
                }
            });
        }
        let mut note = |line: &str| {
            bar.suspend(|| {
                let _ = writeln!(err, "{line}");
            });
        };
        let result = work(&mut Feedback { note: &mut note, watch: &watch });
        stop.store(true, Ordering::Relaxed);
        result
    });
    bar.finish_and_clear();
    result
}
