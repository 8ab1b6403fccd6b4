//! `terrafuse bench …`: clap's types for the benchmark commands ([`crate::bench::run`] runs
//! them).

use std::path::PathBuf;

use clap::Subcommand;

/// `terrafuse bench …`.
#[derive(Subcommand)]
pub enum Bench {
    /// Replay of a long session (N strokes and an erosion run of S steps) on the CPU and, with
    /// --gpu, the GPU; saving and loading its project file and a log of 10⁵ strokes.
    Replay {
        /// Strokes of the edit layer.
        #[arg(long, default_value_t = 10_000, allow_negative_numbers = true)]
        strokes: usize,
        /// Steps of the erosion run (128² cells).
        #[arg(long, default_value_t = 10_000, allow_negative_numbers = true)]
        steps: u64,
        /// Strokes of the log that is saved and loaded.
        #[arg(long, default_value_t = 100_000, allow_negative_numbers = true)]
        log_strokes: usize,
        /// Replay on the GPU too (lavapipe without a hardware GPU).
        #[arg(long)]
        gpu: bool,
        /// The folder the files and the table (replay-bench.md) go to.
        #[arg(long, default_value = "out/bench-replay")]
        out: PathBuf,
    },
    /// Brushing: rebuilding an edit layer from N scripted strokes on the CPU, one more stroke,
    /// and its undo.
    Brush {
        /// Strokes in the session.
        #[arg(long, default_value_t = 1000, allow_negative_numbers = true)]
        strokes: usize,
        /// The level they are rasterised at.
        #[arg(long, default_value_t = 6, allow_negative_numbers = true)]
        level: u8,
        /// Rebuild on the GPU rasteriser as well (and compare with the CPU's).
        #[arg(long)]
        gpu: bool,
    },
    /// Erosion: cell-steps per second of the CPU reference on square grids, the bytes a step
    /// moves, and the error against the step size.
    Erosion {
        /// Grid sizes, cells a side.
        #[arg(long, value_delimiter = ',', default_value = "256,512,1024")]
        sizes: Vec<usize>,
        /// Steps timed per grid.
        #[arg(long, default_value_t = 20, allow_negative_numbers = true)]
        steps: u64,
        /// The largest grid the CPU reference runs (larger: the GPU only).
        #[arg(long = "cpu-max", default_value_t = 1024, allow_negative_numbers = true)]
        cpu_max: usize,
        /// Also time the GPU kernels.
        #[arg(long)]
        gpu: bool,
        /// The device's memory bandwidth, GB/s, for the share of it a step reaches.
        #[arg(long = "bandwidth-gbs", allow_negative_numbers = true)]
        bandwidth_gbs: Option<f64>,
    },
    /// A stroke's latency in the workstation: pointer release to the updated image read back
    /// (rasterise, recompose, draw), per tool, on the Moon sample session.
    BrushLatency {
        /// The brushing project (edit layer and view `sculpt`).
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-brushing.json"))]
        project: PathBuf,
        /// Strokes per tool.
        #[arg(long, default_value_t = 5, allow_negative_numbers = true)]
        rounds: usize,
        /// Image width, pixels.
        #[arg(long, default_value_t = 1280, allow_negative_numbers = true)]
        width: u32,
        /// Image height, pixels.
        #[arg(long, default_value_t = 800, allow_negative_numbers = true)]
        height: u32,
    },
    /// Comparison statistics and co-registration: time on the Erzurum pair and on a synthetic
    /// pair with a known shift, beside xDEM's in the same run, and both tools' shift error;
    /// writes compare.txt.
    Compare {
        /// The Erzurum comparison project.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/erzurum-compare.json"))]
        project: PathBuf,
        /// Edge of the synthetic rasters, pixels.
        #[arg(long, default_value_t = 4096, allow_negative_numbers = true)]
        size: usize,
        /// Folder for the synthetic pair, its stores and compare.txt.
        #[arg(long, default_value = "out/bench-compare")]
        out: PathBuf,
    },
    /// Comparisons of growing size, each in a process of its own: two layers of a project compared
    /// at each level (default: the whole Moon, the `sculpt` layer against LOLA, 2.5·10⁷ to
    /// 4·10⁸ samples; with --procedural a noise pair at any level), their samples, time,
    /// nanoseconds a sample, peak memory and median and NMAD; writes compare-size.txt.
    CompareSize {
        /// The project.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-brushing.json"))]
        project: PathBuf,
        /// Layer A.
        #[arg(long, default_value = "sculpt")]
        a: String,
        /// Layer B, the reference.
        #[arg(long, default_value = "lola_global")]
        b: String,
        /// Levels (comma-separated; the Moon's LOLA grid allows 0–5).
        #[arg(long, value_delimiter = ',', default_value = "3,4,5")]
        levels: Vec<u8>,
        /// Compare a procedural pair instead (written to --out: `terrain+error` against
        /// `terrain`, fBm on the Moon, everywhere; level 6 is 1.6·10⁹ samples).
        #[arg(long)]
        procedural: bool,
        /// Folder for compare-size.txt.
        #[arg(long, default_value = "out/bench-compare-size")]
        out: PathBuf,
    },
    /// Landscape evolution (stream power): cell-steps per second on the CPU beside fastscapelib
    /// 0.3.0 on the same grids in the same run, and how far apart the results are; writes
    /// landscape.csv.
    Landscape {
        /// Grid edges, cells (comma-separated).
        #[arg(long, value_delimiter = ',', default_value = "128,256,512")]
        sizes: Vec<usize>,
        /// Steps per run.
        #[arg(long, default_value_t = 50, allow_negative_numbers = true)]
        steps: u64,
        /// Folder for landscape.csv.
        #[arg(long, default_value = "out/bench-landscape")]
        out: PathBuf,
    },
    /// The layer stack's composition: samples per second on the GPU against the CPU reference
    /// for 1, 2, 4, 8 layers and each kind, the GPU − CPU difference, octave skipping (time and
    /// error), and recomposition after a one-layer change; writes compose.csv.
    Compose {
        /// The Erzurum sample project (or another with one dataset layer over Erzurum).
        #[arg(long, default_value = "projects/erzurum.json")]
        project: PathBuf,
        /// Level-9 quads per measurement.
        #[arg(long, default_value_t = 16, allow_negative_numbers = true)]
        quads: usize,
        /// Repetitions (the median is reported).
        #[arg(long, default_value_t = 5, allow_negative_numbers = true)]
        repeats: usize,
        /// Folder for compose.csv.
        #[arg(long, default_value = "out/bench")]
        out: PathBuf,
    },
    /// A sharded import with 1, 2, 4… shard processes at once against one process: shard, merge
    /// and pyramid times, and a projection to a cluster (default: SRTM 3″ on 64 nodes).
    Shards(BenchShardsArgs),
    /// Import against gdalwarp into the same QSC grid: throughput, peak memory, difference.
    Import {
        /// What to import and how.
        #[command(flatten)]
        import: BenchImportArgs,
    },
    /// Frame time against screen-space error over the pixel error τ (and the level-of-detail
    /// threshold t), on the projects' views (the camera path); writes render.csv and render.png.
    Render {
        /// Project files.
        #[arg(long, value_delimiter = ',', default_values = [concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-lola.json"), concat!(env!("CARGO_MANIFEST_DIR"), "/projects/erzurum.json")])]
        projects: Vec<PathBuf>,
        /// Thresholds (pixels per sample); the smallest, with its quads whole, is the reference.
        #[arg(long, value_delimiter = ',', default_values_t = [1.5])]
        thresholds: Vec<f64>,
        /// Pixel errors τ for the adaptive rows (pixels).
        #[arg(long, value_delimiter = ',', default_values_t = [0.05, 0.5, 1.0, 2.0, 4.0])]
        pixel_errors: Vec<f64>,
        /// Image width.
        #[arg(long, default_value_t = 1280, allow_negative_numbers = true)]
        width: u32,
        /// Image height.
        #[arg(long, default_value_t = 1024, allow_negative_numbers = true)]
        height: u32,
        /// Timed frames per view and threshold.
        #[arg(long, default_value_t = 3, allow_negative_numbers = true)]
        frames: usize,
        /// Folder for render.csv and render.png.
        #[arg(long, default_value = "out/bench")]
        out: PathBuf,
    },
    /// Error of the rendered position against the exact one, per approach, body, level and
    /// camera distance; writes a CSV and a PNG plot, and prints timings.
    Accuracy(BenchAccuracyArgs),
}

/// `terrafuse bench import`.
#[derive(clap::Args, Clone)]
pub struct BenchImportArgs {
    /// Source raster.
    pub source: PathBuf,
    /// Body: wgs84, moon, mars, a=A,b=B.
    #[arg(long)]
    pub body: String,
    /// Level: auto or 0–30.
    #[arg(long, default_value = "auto")]
    pub level: String,
    /// Worker threads for both tools.
    #[arg(long, default_value_t = 2, allow_negative_numbers = true)]
    pub threads: usize,
    /// Folder for the stores and gdalwarp outputs (default: a temporary folder).
    #[arg(long)]
    pub work: Option<PathBuf>,
}

/// `terrafuse bench shards`.
#[derive(clap::Args, Clone)]
pub struct BenchShardsArgs {
    /// Source raster.
    pub source: PathBuf,
    /// Body: wgs84, moon, mars, a=A,b=B.
    #[arg(long)]
    pub body: String,
    /// Level: auto or 0–30.
    #[arg(long, default_value = "auto")]
    pub level: String,
    /// Shard counts, comma-separated.
    #[arg(long, default_value = "1,2,4")]
    pub shards: String,
    /// Threads per process.
    #[arg(long, default_value_t = 1, allow_negative_numbers = true)]
    pub threads: usize,
    /// Nodes of the cluster projected to.
    #[arg(long, default_value_t = 64, allow_negative_numbers = true)]
    pub nodes: usize,
    /// Cores per node.
    #[arg(long, default_value_t = 32, allow_negative_numbers = true)]
    pub cores: usize,
    /// Output samples of the projected import (default: SRTM 3″, 872 tiles of 6000²).
    #[arg(long, allow_negative_numbers = true)]
    pub samples: Option<f64>,
    /// Work folder (default: a temporary folder, removed after).
    #[arg(long)]
    pub work: Option<PathBuf>,
}

/// `terrafuse bench accuracy`.
#[derive(clap::Args, Clone)]
pub struct BenchAccuracyArgs {
    /// Bodies, comma-separated: wgs84, moon, mars, a=A,b=B, a=A,rf=F, r=R.
    #[arg(long, default_value = "wgs84,moon,mars")]
    pub bodies: String,
    /// Levels: a range such as 0-30, or a comma-separated list.
    #[arg(long, default_value = "0-30")]
    pub levels: String,
    /// Camera distances above the terrain in metres, comma-separated.
    #[arg(long, default_value = "1,10,100,1e3,1e4,1e5,1e6,1e7,1e8")]
    pub distances: String,
    /// Random quads per level and distance.
    #[arg(long, default_value_t = 8, allow_negative_numbers = true)]
    pub trials: usize,
    /// Random vertices per quad (besides the one under the camera and its neighbours).
    #[arg(long, default_value_t = 40, allow_negative_numbers = true)]
    pub vertices: usize,
    /// Seed of the random choices.
    #[arg(long, default_value_t = 2012, allow_negative_numbers = true)]
    pub seed: u64,
    /// Samples per quad edge.
    #[arg(long, default_value_t = crate::ecm::geometry::DEFAULT_SAMPLES, allow_negative_numbers = true)]
    pub samples: u32,
    /// Tolerance of the flat rule (ecm-cutoff), metres.
    #[arg(long, default_value_t = crate::ecm::geometry::FlatRule::DEFAULT_TOLERANCE_M, allow_negative_numbers = true)]
    pub tolerance_m: f64,
    /// Cap the tolerance at this fraction of the f32 limit at each level's draw distance
    /// (0: the absolute tolerance alone).
    #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
    pub limit_fraction: f64,
    /// Where to write the CSV.
    #[arg(long, default_value = "accuracy.csv")]
    pub csv: PathBuf,
    /// Where to write the PNG plot.
    #[arg(long, default_value = "accuracy.png")]
    pub plot: PathBuf,
    /// Skip the timings.
    #[arg(long)]
    pub no_timing: bool,
}
