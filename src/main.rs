//! `terrafuse`: parses the command line, gives the library the process's standard streams and
//! environment, prints what it returns, and opens the workstation (`terrafuse view`, or
//! `terrafuse` alone). Everything else is in the library: the commands' types in
//! `terrafuse::cli::args`, running them in `terrafuse::cli::dispatch` (the benchmarks in
//! `terrafuse::bench`).

use std::io;
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::Result;
use clap::Parser;
use terrafuse::cli::{self, Console, Trace, args::Command};

#[derive(Parser)]
#[command(
    name = "terrafuse",
    version,
    about = "Planetary terrain workstation on the Ellipsoidal Cube Map",
    after_help = "Without a command, opens the workstation on the last project (or the bundled Moon sample)."
)]
struct Args {
    #[command(subcommand)]
    command: Option<Command>,
}

/// The project the workstation opens without arguments when no recent one exists.
const BUNDLED_SAMPLE: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-lola.json");

/// The workstation's configuration folder: `$XDG_CONFIG_HOME/terrafuse`, else
/// `$HOME/.config/terrafuse`.
fn config_dir() -> Option<PathBuf> {
    let base = std::env::var_os("XDG_CONFIG_HOME")
        .map(PathBuf::from)
        .filter(|p| p.is_absolute())
        .or_else(|| std::env::var_os("HOME").map(|h| PathBuf::from(h).join(".config")))?;
    Some(base.join("terrafuse"))
}

/// How much `render` traces: `TERRAFUSE_DEBUG` (steps), with `TERRAFUSE_DEBUG_QUADS` (quads).
fn trace() -> Trace {
    match (std::env::var_os("TERRAFUSE_DEBUG"), std::env::var_os("TERRAFUSE_DEBUG_QUADS")) {
        (None, _) => Trace::Off,
        (Some(_), None) => Trace::Steps,
        (Some(_), Some(_)) => Trace::Quads,
    }
}

/// The window driven from a folder with its frames slowed, for the tests that drive the real
/// window: `TERRAFUSE_DEBUG_WINDOW` (the folder), `TERRAFUSE_FRAME_DELAY_MS` (default 0).
fn debug_hook() -> Option<terrafuse::gui::app::DebugHook> {
    let dir = PathBuf::from(std::env::var_os("TERRAFUSE_DEBUG_WINDOW")?);
    let delay_ms = std::env::var("TERRAFUSE_FRAME_DELAY_MS").ok().and_then(|v| v.parse::<u64>().ok()).unwrap_or(0);
    Some(terrafuse::gui::app::DebugHook {
        dir,
        frame_delay: std::time::Duration::from_millis(delay_ms),
        ..Default::default()
    })
}

/// Opens the workstation (`terrafuse view`, or `terrafuse` alone).
fn workstation(opts: &terrafuse::gui::ViewOptions) -> Result<()> {
    if std::env::var_os("DISPLAY").is_none() {
        anyhow::bail!(
            "the workstation needs an X11 display and DISPLAY is not set (on Wayland desktops XWayland \
             provides one; without a display use `xvfb-run terrafuse view … --screenshot OUT.png`, or \
             `terrafuse render` for images)"
        );
    }
    if let Some(r) = terrafuse::project::recovery::find(&opts.project) {
        eprintln!("terrafuse: note: {}", r.notice());
    }
    let opened = terrafuse::gui::open(opts)?;
    for line in opened.imported() {
        eprintln!("{line}");
    }
    let report = terrafuse::gui::run(opts, opened)?;
    print!("{report}");
    Ok(())
}

/// Keeps headless commands quiet without a desktop session: Mesa's Vulkan device-select layer
/// asks libwayland for a display, which prints "error: XDG_RUNTIME_DIR is invalid or not set in
/// the environment" on every GPU command when the variable is unset. A private, empty folder
/// (mode 0700, as the variable requires) answers it; the workstation keeps the environment as
/// it is.
fn quiet_without_a_desktop() {
    use std::os::unix::fs::{DirBuilderExt, MetadataExt, PermissionsExt};
    if std::env::var_os("XDG_RUNTIME_DIR").is_some() {
        return;
    }
    // SAFETY: getuid has no preconditions and cannot fail.
    let uid = unsafe { libc::getuid() };
    let dir = std::env::temp_dir().join(format!("terrafuse-runtime-{uid}"));
    let _ = std::fs::DirBuilder::new().mode(0o700).create(&dir);
    let private = std::fs::symlink_metadata(&dir)
        .is_ok_and(|m| m.is_dir() && m.uid() == uid && m.permissions().mode() & 0o777 == 0o700);
    if private {
        // SAFETY: called first thing in main, before any thread exists.
        unsafe { std::env::set_var("XDG_RUNTIME_DIR", &dir) };
    }
}

fn main() -> ExitCode {
    let args = Args::parse();
    if !matches!(args.command, None | Some(Command::View { .. })) {
        quiet_without_a_desktop();
    }
    match run(args) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("terrafuse: {}", terrafuse::errors::chain(&*error));
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<ExitCode> {
    let opts = match args.command {
        None => {
            let config = config_dir();
            let recent = terrafuse::gui::recent::Recent::load(config.as_deref());
            let project = recent.last().map_or_else(|| PathBuf::from(BUNDLED_SAMPLE), std::path::Path::to_path_buf);
            eprintln!("terrafuse: opening {}", project.display());
            terrafuse::gui::ViewOptions {
                project,
                view: None,
                camera: None,
                lod_threshold: None,
                pixel_error: None,
                width: 1280,
                height: 800,
                screenshot: None,
                timeout: std::time::Duration::from_secs(300),
                config_dir: config,
                debug: debug_hook(),
            }
        }
        Some(Command::View { project, look, width, height, screenshot, timeout }) => {
            if !(timeout.is_finite() && timeout > 0.0) {
                anyhow::bail!("--timeout {timeout} must be a positive number of seconds");
            }
            terrafuse::gui::ViewOptions {
                project,
                view: look.view,
                camera: look.camera,
                lod_threshold: look.lod_threshold,
                pixel_error: look.pixel_error,
                width,
                height,
                screenshot,
                timeout: std::time::Duration::from_secs_f64(timeout),
                config_dir: config_dir(),
                debug: debug_hook(),
            }
        }
        Some(command) => {
            let var = |name: &str| std::env::var(name).ok();
            let mut console = Console {
                input: &mut io::stdin().lock(),
                out: &mut io::stdout().lock(),
                err: &mut io::stderr(),
                trace: trace(),
                var: &var,
                progress: io::IsTerminal::is_terminal(&io::stderr()),
            };
            let code = match command {
                Command::Bench { bench } => terrafuse::bench::run(bench, &mut console)?,
                command => cli::run(command, &mut console)?,
            };
            return Ok(ExitCode::from(code));
        }
    };
    workstation(&opts)?;
    Ok(ExitCode::SUCCESS)
}
