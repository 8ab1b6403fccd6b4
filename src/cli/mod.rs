//! The logic behind the `terrafuse` subcommands, kept out of `main.rs` so it can be tested: the
//! command line's types (`args`, `bench_args`), running a parsed command (`dispatch`) on a
//! `console`, and one file per command. The benchmarks behind `terrafuse bench` have a room of
//! their own above this one (`crate::bench`).

pub mod args;
pub mod bench_args;
mod brush;
mod compare;
mod console;
mod dispatch;
mod edit_target;
mod erode;
mod erode_landscape;
mod erode_report;
mod error;
mod feedback;
mod flight;
mod geo;
mod geometry;
mod plans;
mod profile;
mod project;
mod render;
mod replay;
mod report;
mod shard;
mod sharded;
mod slurm;
mod store;

pub use crate::export::ComposeOn;
pub use brush::{BrushRequest, brush_command};
pub use compare::{CompareRequest, CoregRequest, compare_command, coregister_command, table as compare_table};
pub use console::Console;
pub use dispatch::run;
pub use erode::{ErodeOn, ErodeRequest, erode_command, params_of};
pub use error::{CliError, Context, Within};
pub use feedback::{Feedback, WaitArgs};
pub use flight::{FlightFrame, FlightRequest, frames_csv, render_flight};
pub use geo::{BatchReport, GeoOperation, run_batch};
pub use geometry::{cutoff_report, fitted_rule};
pub use profile::{ProfileRequest, profile_command};
pub use project::{project_check, project_upgrade};
pub use render::{RenderRequest, Trace, frame_report, open_renderer, render, request_camera, write_png};
pub use replay::{ReplayOutcome, ReplayRequest, replay_command};
pub use report::{overview, tissot_report};
pub use shard::{array_ranges, merge_summary, plan_summary, shard_summary};
pub use slurm::{SubmitRequest, slurm_submit};
pub use store::{
    default_work_dir, import_summary, lattice_line, parse_bytes, sample_lines, store_difference, store_info,
};

/// Formats a float with full precision: the shortest decimal that reads back to the same f64
/// (like `%.17g`, but without trailing noise), in exponent form for very large or small values.
pub fn format_f64(value: f64) -> String {
    format!("{value:?}")
}
