//! The benchmarks behind `terrafuse bench`, a room of their own above the command line: each
//! measures speed beside the error it buys against a peer (GDAL, xDEM, fastscapelib, the
//! renderer's earlier builds) and writes its table through the shared harness (`harness`:
//! timing, a table written as CSV and as text). `command` runs a parsed `bench` subcommand
//! (`cli::bench_args`); the rest of the command line never imports this room.

mod accuracy;
mod brush;
mod brush_latency;
mod command;
mod compare;
mod compare_large;
mod compose;
mod erosion;
mod harness;
mod import;
mod landscape;
mod pipelines;
mod render;
mod replay;
mod shards;

pub use accuracy::{AccuracyBench, accuracy_bench, accuracy_csv, accuracy_plot, timing_report, write_accuracy_outputs};
pub use brush::{bench_brush, scripted_strokes};
pub use brush_latency::bench_brush_latency;
pub use command::run;
pub use compare::{CompareBenchSettings, bench_compare};
pub use compose::{ComposeBenchRow, ComposeBenchSettings, bench_compose};
pub use erosion::{ErosionBenchSettings, bench_erosion};
pub use import::{WarpComparison, WarpMode, bench_import, warp_comparison};
pub use landscape::{LandscapeBenchSettings, bench_landscape};
pub use render::{RenderBenchRow, RenderBenchSettings, bench_render, render_bench_csv, write_render_bench};
pub use replay::{ReplayBenchSettings, bench_replay, synthetic_session};
pub use shards::{SRTM_SAMPLES, ShardBenchSettings, bench_shards};
