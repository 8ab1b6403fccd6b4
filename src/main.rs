//! `terrafuse`: parses the command line and calls the library.

use std::io::{self, BufReader};
use std::path::PathBuf;
use std::process::ExitCode;

use anyhow::{Context, Result};
use clap::{Parser, Subcommand};
use terrafuse::cli::{self, GeoOperation};
use terrafuse::ecm::CubeProjection;
use terrafuse::geodesy::Ellipsoid;

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

/// Says on stderr that a project has a recovery file with unsaved changes.
fn note_recovery(project: &std::path::Path) {
    if let Some(r) = terrafuse::project::recovery::find(project) {
        eprintln!("terrafuse: note: {}", r.notice());
    }
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
    note_recovery(&opts.project);
    let opened = terrafuse::gui::open(opts)?;
    for line in opened.imported() {
        eprintln!("{line}");
    }
    let report = terrafuse::gui::run(opts, opened)?;
    print!("{report}");
    Ok(())
}

#[derive(Subcommand)]
enum Command {
    /// Print what Terrafuse does, on the bundled landmark sample.
    Overview {
        /// Landmark file: lines of `name lat lon h`.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/samples/landmarks.txt"))]
        landmarks: PathBuf,
    },
    /// Batch coordinate conversions, one record per line from stdin (or --input) to stdout.
    Geo {
        #[command(subcommand)]
        operation: GeoCommand,
        /// Body: wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres).
        #[arg(long, global = true, default_value = "wgs84")]
        body: String,
        /// Cube projection for to-face/from-face: qsc, gnomonic, adjusted-gnomonic.
        #[arg(long, global = true, default_value = "qsc")]
        projection: String,
        /// Read records from this file instead of standard input.
        #[arg(long, global = true)]
        input: Option<PathBuf>,
    },
    /// Analyses of the cube map.
    Analyze {
        #[command(subcommand)]
        analysis: Analysis,
    },
    /// Import rasters GDAL reads (any CRS) onto the cube map, into a GeoPackage tile store.
    Import {
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Read a tile store: info, sample, export; merge a sharded import's parts.
    Store {
        #[command(subcommand)]
        command: StoreCommand,
    },
    /// Run a sharded import on a Slurm cluster.
    Slurm {
        #[command(subcommand)]
        command: SlurmCommand,
    },
    /// Render one frame of a project to a PNG and report what it drew and what it cost.
    Render {
        /// The project file (JSON).
        project: PathBuf,
        /// The PNG to write.
        #[arg(long)]
        out: PathBuf,
        /// Image width, pixels.
        #[arg(long, default_value_t = 1280)]
        width: u32,
        /// Image height, pixels.
        #[arg(long, default_value_t = 1024)]
        height: u32,
        #[command(flatten)]
        look: LookArgs,
        /// A,B[,POSITION]: layer A left of a vertical line at POSITION (0–1 of the width,
        /// default 0.5), layer B right of it (each shown with the other hidden); or the name of
        /// a swipe saved in the project (comparison.swipes), with its view.
        #[arg(long)]
        swipe: Option<String>,
    },
    /// Write a project's composed elevation (every visible layer, as drawn) as a GeoTIFF in any
    /// CRS: float32, NaN nodata, written atomically.
    Export {
        /// The project file (JSON).
        project: PathBuf,
        /// The GeoTIFF to write.
        out: PathBuf,
        #[command(flatten)]
        raster: RasterArgs,
        /// Level to compose (default: the output's pixel size, no finer than the finest dataset
        /// unless procedural layers add detail).
        #[arg(long)]
        level: Option<u8>,
        /// Where to compose: gpu (the renderer's pass) or cpu (the reference, bit for bit).
        #[arg(long, default_value = "gpu", value_parser = ["gpu", "cpu"])]
        compose: String,
        /// A,B: write layer A − layer B (each composed alone) instead of the stack.
        #[arg(long)]
        difference: Option<String>,
    },
    /// Compare layer A with layer B (the reference) of a project: statistics of A − B over
    /// their overlap at one level, weighted by each sample's cell area on the ellipsoid, by slope
    /// class of B, with a histogram.
    Compare {
        /// The project file (JSON).
        project: PathBuf,
        /// Layer A.
        a: String,
        /// Layer B, the reference.
        b: String,
        /// Level to compare at (default: the coarser dataset's finest, or finer where strokes, erosion runs or noise on either side add detail below it, within 4096 quads).
        #[arg(long)]
        level: Option<u8>,
        /// Only inside WEST,SOUTH,EAST,NORTH (degrees; east < west crosses ±180°).
        #[arg(long, allow_hyphen_values = true)]
        region: Option<String>,
        /// Count every sample once (as xDEM and demcompare count pixels) instead of weighting by area.
        #[arg(long)]
        unweighted: bool,
        /// Print JSON (stable field names: count, nodata_count, mean_m, median_m, std_m, rmse_m,
        /// nmad_m, min_m, max_m, le90_m, p90_abs_m, histogram, by_slope).
        #[arg(long)]
        json: bool,
        /// Also write every sample (lon_deg, lat_deg, dh_m, area_m2, slope_deg) as CSV.
        #[arg(long)]
        samples: Option<PathBuf>,
    },
    /// Co-register layer A onto layer B (Nuth & Kääb 2011 on the ellipsoid): the horizontal
    /// shift (east, north, metres) and vertical offset that align A with B, and the statistics of
    /// A − B before and after.
    Coregister {
        /// The project file (JSON).
        project: PathBuf,
        /// The layer to move.
        a: String,
        /// The reference layer.
        #[arg(long = "to")]
        b: String,
        /// Level to work at (default: one finer than the coarser dataset's finest, where A and B
        /// are smoothed alike by interpolation).
        #[arg(long)]
        level: Option<u8>,
        /// Only inside WEST,SOUTH,EAST,NORTH (degrees).
        #[arg(long, allow_hyphen_values = true)]
        region: Option<String>,
        /// Write the result into the project: A's shift_m and offset_m.
        #[arg(long)]
        apply: bool,
        /// Print JSON (east_m, north_m, up_m, iterations, before, after).
        #[arg(long)]
        json: bool,
    },
    /// Appends a brush stroke to an edit layer (made on top when missing), or moves its undo
    /// position, and saves the project atomically.
    Brush {
        /// The project file (JSON).
        project: PathBuf,
        /// The edit layer.
        #[arg(long)]
        layer: String,
        /// raise, lower, smooth, flatten, ramp, noise or restore.
        #[arg(long)]
        tool: Option<String>,
        /// Brush radius on the surface, metres.
        #[arg(long = "radius-m")]
        radius_m: Option<f64>,
        /// Metres per dab (raise, lower, noise).
        #[arg(long = "strength-m", allow_hyphen_values = true)]
        strength_m: Option<f64>,
        /// A fraction 0–1 per dab (restore and the tools that read the terrain).
        #[arg(long)]
        strength: Option<f64>,
        /// The path: LAT,LON;LAT,LON;… degrees.
        #[arg(long, allow_hyphen_values = true)]
        path: Option<String>,
        /// smooth, linear, spherical or tip.
        #[arg(long)]
        falloff: Option<String>,
        /// Dab spacing, a fraction of the radius (default 0.25).
        #[arg(long)]
        spacing: Option<f64>,
        /// The level it is rasterised at (default: the coarsest with samples at most a tenth of
        /// the radius apart).
        #[arg(long)]
        level: Option<u8>,
        /// Noise seed.
        #[arg(long)]
        seed: Option<u32>,
        /// Flatten: the height to flatten to, metres above the ellipsoid (default: the terrain's
        /// under the path's first point, before the stroke).
        #[arg(long = "height-m", allow_hyphen_values = true)]
        height_m: Option<f64>,
        /// Undo this many strokes (no stroke).
        #[arg(long)]
        undo: Option<usize>,
        /// Redo this many strokes (no stroke).
        #[arg(long)]
        redo: Option<usize>,
    },
    /// Runs erosion headless on a region (the box rounded out to whole quads of the level),
    /// appends the run to an erosion layer (made on top when missing) or moves its undo
    /// position, prints the budgets and the time, and saves the project atomically.
    Erode {
        /// The project file (JSON).
        project: PathBuf,
        /// The erosion layer.
        #[arg(long)]
        layer: String,
        /// The box: WEST,SOUTH,EAST,NORTH degrees (west > east crosses the antimeridian).
        #[arg(long, allow_hyphen_values = true)]
        region: Option<String>,
        /// The level whose samples are the cells (default: the coarsest with 512 cells along the
        /// box's north–south side, as the workstation chooses).
        #[arg(long)]
        level: Option<u8>,
        /// Steps (each the preset's Δt or less, by the CFL bound).
        #[arg(long)]
        steps: Option<u64>,
        /// rain, river, thermal or gentle (default rain).
        #[arg(long)]
        preset: Option<String>,
        /// Overrides a parameter: FIELD=VALUE (repeatable), e.g. rain_m_s=2e-5, border=closed.
        #[arg(long)]
        set: Vec<String>,
        /// The seed of the rounding dither.
        #[arg(long)]
        seed: Option<u64>,
        /// Run on the GPU (lavapipe too).
        #[arg(long, conflicts_with = "cpu")]
        gpu: bool,
        /// Run the CPU reference (bit for bit reproducible; the default without a hardware GPU).
        #[arg(long)]
        cpu: bool,
        /// Print JSON (steps, simulated_s, water_unexplained_rel, soil_unexplained_rel,
        /// water_out_m3, soil_out_m3, seconds, …).
        #[arg(long)]
        json: bool,
        /// Undo this many runs (no run).
        #[arg(long)]
        undo: Option<usize>,
        /// Redo this many runs (no run).
        #[arg(long)]
        redo: Option<usize>,
    },
    /// Every visible layer's elevation (each alone) and the composed stack's along the geodesic
    /// between two points.
    Profile {
        /// The project file (JSON).
        project: PathBuf,
        /// Start: LAT,LON in degrees.
        #[arg(long, allow_hyphen_values = true)]
        from: Option<String>,
        /// End: LAT,LON in degrees.
        #[arg(long, allow_hyphen_values = true)]
        to: Option<String>,
        /// A profile line saved in the project (comparison.profiles) instead of --from and --to.
        #[arg(long)]
        line: Option<String>,
        /// Samples along the line (default: one per sample spacing of the level).
        #[arg(long)]
        samples: Option<usize>,
        /// Level to sample (default: the finest among the datasets).
        #[arg(long)]
        level: Option<u8>,
        /// Write the profile as CSV (distance_m, lat_deg, lon_deg, a column per layer, composed).
        #[arg(long)]
        csv: Option<PathBuf>,
    },
    /// Open the workstation: a window with the project's terrain, its views and its visual
    /// settings (needs an X11 display; `xvfb-run` provides one for screenshots).
    View {
        /// The project file (JSON).
        project: PathBuf,
        #[command(flatten)]
        look: LookArgs,
        /// Window width, pixels.
        #[arg(long, default_value_t = 1280)]
        width: u32,
        /// Window height, pixels.
        #[arg(long, default_value_t = 800)]
        height: u32,
        /// Once the view has loaded, write a picture of the whole window to this PNG and close.
        #[arg(long)]
        screenshot: Option<PathBuf>,
        /// Seconds a --screenshot run waits for the view to load.
        #[arg(long, default_value_t = 300.0)]
        timeout: f64,
    },
    /// Rebuild every edit and erosion layer of a project from its operations and print a digest
    /// per layer; --check compares the project's recorded checks (exit status 1 on a mismatch,
    /// naming the check and the first differing tile), --record writes them.
    Replay {
        /// The project file (JSON).
        project: PathBuf,
        /// Compare with the digests recorded in the project's "checks"; exit 1 on a mismatch.
        #[arg(long)]
        check: bool,
        /// Write the digests of the project's checks into it (from the CPU reference).
        #[arg(long, conflicts_with_all = ["check", "gpu"])]
        record: bool,
        /// Rebuild on the GPU (lavapipe too); with --check, each layer is compared with the CPU
        /// reference within its stated tolerance.
        #[arg(long, conflicts_with = "cpu")]
        gpu: bool,
        /// Rebuild with the CPU reference, bit for bit (the default).
        #[arg(long)]
        cpu: bool,
        /// Print JSON (project, engine, layers[name, kind, operations, tiles, digest, seconds],
        /// checks[name, digest, expected, ok, first_differing_tile], seconds, passed).
        #[arg(long)]
        json: bool,
    },
    /// Project files: check one, bring one to the current version, print the schema.
    Project {
        #[command(subcommand)]
        command: ProjectCommand,
    },
    /// Benchmarks that report speed beside error.
    Bench {
        #[command(subcommand)]
        bench: Bench,
    },
}

#[derive(Subcommand)]
enum ProjectCommand {
    /// Load and check a project (every field, its stores and sources there, a recovery file)
    /// and summarise it.
    Check {
        /// The project file (JSON).
        project: PathBuf,
    },
    /// Rewrite a project in the current version (atomically); --out writes a copy elsewhere
    /// with its relative paths rewritten to reach the same files.
    Upgrade {
        /// The project file (JSON).
        project: PathBuf,
        /// Write here instead of over the project.
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Print the JSON Schema of project files (docs/project.schema.json), or with --markdown
    /// the field reference of docs/project-format.md.
    Schema {
        /// The reference as Markdown tables instead.
        #[arg(long)]
        markdown: bool,
    },
}

/// Where a frame looks from, and its level of detail.
#[derive(clap::Args, Clone)]
struct LookArgs {
    /// A named view of the project (default: its default view).
    #[arg(long, conflicts_with = "camera")]
    view: Option<String>,
    /// A camera: lat,lon,alt,heading,pitch[,fov] (degrees, metres above the ellipsoid).
    #[arg(long, allow_hyphen_values = true)]
    camera: Option<String>,
    /// Split quads while a sample covers more than this many pixels (the project's default).
    #[arg(long)]
    lod_threshold: Option<f64>,
}

#[derive(clap::Args, Clone)]
struct ImportArgs {
    /// Source rasters (GeoTIFF, COG, VRT, …); where they overlap the first with data wins.
    #[arg(required_unless_present = "manifest", conflicts_with = "manifest")]
    sources: Vec<PathBuf>,
    /// The store (a GeoPackage; created if missing); with --shard, the shard's partial store.
    #[arg(long, required_unless_present = "plan")]
    store: Option<PathBuf>,
    /// Body: wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres).
    #[arg(long, required_unless_present = "manifest")]
    body: Option<String>,
    /// Plan a sharded import instead: write this manifest (the finest level's quads cut into
    /// --shards runs along a Hilbert curve per face) and import nothing.
    #[arg(long, requires = "shards", conflicts_with_all = ["store", "manifest"])]
    plan: Option<PathBuf>,
    /// Shards of the plan.
    #[arg(long, requires = "plan")]
    shards: Option<usize>,
    /// Import one shard of this manifest (with --shard and --store).
    #[arg(long, requires = "shard")]
    manifest: Option<PathBuf>,
    /// The shard: 0 … N−1, or `env` for the array index of Slurm (SLURM_ARRAY_TASK_ID),
    /// Kubernetes (JOB_COMPLETION_INDEX) or AWS Batch (AWS_BATCH_JOB_ARRAY_INDEX).
    #[arg(long, requires = "manifest")]
    shard: Option<String>,
    /// With --shard: build the partial store in this folder (node-local disk) and copy it to
    /// --store when complete.
    #[arg(long, requires = "shard")]
    work_dir: Option<PathBuf>,
    /// Dataset name (default: the first source's file name).
    #[arg(long)]
    name: Option<String>,
    /// Finest level: auto (from the source resolution) or 0–30.
    #[arg(long, default_value = "auto")]
    max_level: String,
    /// Resampling at the finest level: bilinear, cubic or nearest.
    #[arg(long, default_value = "bilinear")]
    resampling: String,
    /// Where samples fall in the sources: lattice (exact on a coarse lattice per quad,
    /// interpolated within 10⁻³ source pixel, measured on every quad, else exact) or exact
    /// (every sample through PROJ).
    #[arg(long, default_value = "lattice")]
    transform: String,
    /// Vertical datum of the source heights: ellipsoidal, egm96, egm2008 or geoid:GRIDFILE
    /// (geoid heights are converted to ellipsoidal ones through PROJ), or unspecified.
    #[arg(long, default_value = "unspecified")]
    vertical_datum: String,
    /// Memory budget (GDAL cache, source windows, tiles in flight), e.g. 2GiB.
    #[arg(long, default_value = "2GiB")]
    memory_budget: String,
    /// Worker threads (default: all cores).
    #[arg(long)]
    threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    quiet: bool,
}

/// The shard a task runs: a number, or `env` for the scheduler's array index.
fn shard_index(text: &str) -> Result<usize> {
    if text == "env" {
        const VARS: [&str; 3] = ["SLURM_ARRAY_TASK_ID", "JOB_COMPLETION_INDEX", "AWS_BATCH_JOB_ARRAY_INDEX"];
        let (var, value) = VARS
            .iter()
            .find_map(|v| std::env::var(v).ok().map(|x| (*v, x)))
            .ok_or_else(|| anyhow::anyhow!("--shard env: none of {} is set", VARS.join(", ")))?;
        return value.trim().parse().map_err(|_| anyhow::anyhow!("--shard env: {var}={value} is not a shard number"));
    }
    text.parse().map_err(|_| anyhow::anyhow!("--shard {text}: give a shard number 0 … N−1, or env"))
}

#[derive(Subcommand)]
enum SlurmCommand {
    /// Submit a plan's missing shards as a job array (one shard per task, built on node-local
    /// disk, copied to --parts when complete) and a merge job that runs after it
    /// (--dependency=afterok). After failures, run it again: only missing shards are submitted.
    Submit(SubmitArgs),
}

#[derive(clap::Args, Clone)]
struct SubmitArgs {
    /// The manifest (`terrafuse import … --plan MANIFEST --shards N`).
    #[arg(long)]
    manifest: PathBuf,
    /// Folder for the partial stores, on storage every node sees (also the scripts and logs, in
    /// PARTS/slurm).
    #[arg(long)]
    parts: PathBuf,
    /// The merged store.
    #[arg(long)]
    store: PathBuf,
    /// CPUs per task, and the import's threads.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Memory budget per task.
    #[arg(long, default_value = "2GiB")]
    memory_budget: String,
    /// Node-local folder a task builds its shard in (a shell word, expanded on the node).
    #[arg(long, default_value = "${TMPDIR:-/tmp}")]
    work_dir: String,
    /// An extra sbatch argument for both jobs (repeat it): --sbatch-arg=--partition=short.
    #[arg(long, allow_hyphen_values = true)]
    sbatch_arg: Vec<String>,
    /// The terrafuse executable the nodes run (default: this one).
    #[arg(long)]
    terrafuse: Option<PathBuf>,
    /// Print the sbatch commands without submitting.
    #[arg(long)]
    dry_run: bool,
}

#[derive(Subcommand)]
enum StoreCommand {
    /// Merge the partial stores of a sharded import into STORE (one transaction per shard; a
    /// shard merged before is skipped) and, when every shard is in, build the pyramid. Exits 3
    /// when shards are still missing.
    Merge {
        /// The store (created if missing).
        store: PathBuf,
        /// Partial stores (`terrafuse import --manifest M --shard I --store PART`).
        #[arg(required = true)]
        parts: Vec<PathBuf>,
        /// Worker threads for the pyramid (default: all cores).
        #[arg(long)]
        threads: Option<usize>,
        /// No progress bar.
        #[arg(long)]
        quiet: bool,
    },
    /// Body, datasets, levels, tile counts, extents and provenance.
    Info {
        /// The store.
        store: PathBuf,
    },
    /// Heights at `lat lon` lines from stdin (degrees), bilinear; `nan` where there are no data.
    Sample {
        /// The store.
        store: PathBuf,
        /// Dataset (needed when the store has several).
        #[arg(long)]
        dataset: Option<String>,
        /// Level to sample (default: the finest).
        #[arg(long)]
        level: Option<u8>,
    },
    /// Write a dataset as a GeoTIFF in any CRS.
    Export {
        /// The store.
        store: PathBuf,
        /// The GeoTIFF to write.
        out: PathBuf,
        #[command(flatten)]
        raster: RasterArgs,
        /// Dataset (needed when the store has several).
        #[arg(long)]
        dataset: Option<String>,
        /// Level to read (default: the finest the output resolution needs).
        #[arg(long)]
        level: Option<u8>,
    },
}

/// The output raster of `export` and `store export`.
#[derive(clap::Args)]
struct RasterArgs {
    /// Output CRS (EPSG:4326, EPSG:32637, a PROJ string, WKT).
    #[arg(long)]
    crs: String,
    /// xmin,ymin,xmax,ymax in the output CRS.
    #[arg(long, allow_hyphen_values = true)]
    bounds: String,
    /// Pixel size in CRS units: one value, or x,y.
    #[arg(long)]
    resolution: String,
}

impl RasterArgs {
    /// The CRS, the bounds and the pixel size (x, y), checked for shape.
    fn parse(self) -> anyhow::Result<(String, [f64; 4], (f64, f64))> {
        let b = parse_numbers(&self.bounds, "--bounds")?;
        anyhow::ensure!(b.len() == 4, "--bounds takes xmin,ymin,xmax,ymax");
        let r = parse_numbers(&self.resolution, "--resolution")?;
        let resolution = match r.as_slice() {
            [v] => (*v, *v),
            [x, y] => (*x, *y),
            _ => anyhow::bail!("--resolution takes one value or x,y"),
        };
        Ok((self.crs, [b[0], b[1], b[2], b[3]], resolution))
    }
}

#[derive(Subcommand)]
enum Bench {
    /// Replay of a long session (N strokes and an erosion run of S steps) on the CPU and, with
    /// --gpu, the GPU; saving and loading its project file and a log of 10⁵ strokes.
    Replay {
        /// Strokes of the edit layer.
        #[arg(long, default_value_t = 10_000)]
        strokes: usize,
        /// Steps of the erosion run (128² cells).
        #[arg(long, default_value_t = 10_000)]
        steps: u64,
        /// Strokes of the log that is saved and loaded.
        #[arg(long, default_value_t = 100_000)]
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
        #[arg(long, default_value_t = 1000)]
        strokes: usize,
        /// The level they are rasterised at.
        #[arg(long, default_value_t = 6)]
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
        #[arg(long, default_value_t = 20)]
        steps: u64,
        /// The largest grid the CPU reference runs (larger: the GPU only).
        #[arg(long = "cpu-max", default_value_t = 1024)]
        cpu_max: usize,
        /// Also time the GPU kernels.
        #[arg(long)]
        gpu: bool,
        /// The device's memory bandwidth, GB/s, for the share of it a step reaches.
        #[arg(long = "bandwidth-gbs")]
        bandwidth_gbs: Option<f64>,
    },
    /// A stroke's latency in the workstation: pointer release to the updated image read back
    /// (rasterise, recompose, draw), per tool, on the Moon sample session.
    BrushLatency {
        /// The brushing project (edit layer and view `sculpt`).
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-brushing.json"))]
        project: PathBuf,
        /// Strokes per tool.
        #[arg(long, default_value_t = 5)]
        rounds: usize,
        /// Image width, pixels.
        #[arg(long, default_value_t = 1280)]
        width: u32,
        /// Image height, pixels.
        #[arg(long, default_value_t = 800)]
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
        #[arg(long, default_value_t = 4096)]
        size: usize,
        /// Folder for the synthetic pair, its stores and compare.txt.
        #[arg(long, default_value = "out/bench-compare")]
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
        #[arg(long, default_value_t = 16)]
        quads: usize,
        /// Repetitions (the median is reported).
        #[arg(long, default_value_t = 5)]
        repeats: usize,
        /// Folder for compose.csv.
        #[arg(long, default_value = "out/bench")]
        out: PathBuf,
    },
    /// A sharded import with 1, 2, 4… shard processes at once against one process: shard, merge
    /// and pyramid times, and a projection to a cluster (default: SRTM 3″ on 64 nodes).
    Shards {
        /// Source raster.
        source: PathBuf,
        /// Body: wgs84, moon, mars, a=A,b=B.
        #[arg(long)]
        body: String,
        /// Level: auto or 0–30.
        #[arg(long, default_value = "auto")]
        level: String,
        /// Shard counts, comma-separated.
        #[arg(long, default_value = "1,2,4")]
        shards: String,
        /// Threads per process.
        #[arg(long, default_value_t = 1)]
        threads: usize,
        /// Nodes of the cluster projected to.
        #[arg(long, default_value_t = 64)]
        nodes: usize,
        /// Cores per node.
        #[arg(long, default_value_t = 32)]
        cores: usize,
        /// Output samples of the projected import (default: SRTM 3″, 872 tiles of 6000²).
        #[arg(long)]
        samples: Option<f64>,
        /// Work folder (default: a temporary folder, removed after).
        #[arg(long)]
        work: Option<PathBuf>,
    },
    /// Import against gdalwarp into the same QSC grid: throughput, peak memory, difference.
    Import {
        #[command(flatten)]
        import: BenchImportArgs,
    },
    /// Frame time against screen-space error over the level-of-detail threshold t, on the
    /// projects' views (the camera path); writes render.csv and render.png.
    Render {
        /// Project files.
        #[arg(long, value_delimiter = ',', default_values = [concat!(env!("CARGO_MANIFEST_DIR"), "/projects/moon-lola.json"), concat!(env!("CARGO_MANIFEST_DIR"), "/projects/erzurum.json")])]
        projects: Vec<PathBuf>,
        /// Thresholds (pixels per sample); the smallest is the reference.
        #[arg(long, value_delimiter = ',', default_values_t = [0.5, 1.0, 1.5, 2.0, 4.0, 8.0])]
        thresholds: Vec<f64>,
        /// Image width.
        #[arg(long, default_value_t = 1280)]
        width: u32,
        /// Image height.
        #[arg(long, default_value_t = 1024)]
        height: u32,
        /// Timed frames per view and threshold.
        #[arg(long, default_value_t = 3)]
        frames: usize,
        /// Folder for render.csv and render.png.
        #[arg(long, default_value = "out/bench")]
        out: PathBuf,
    },
    /// Error of the rendered position against the exact one, per approach, body, level and
    /// camera distance; writes a CSV and a PNG plot, and prints timings.
    Accuracy {
        /// Bodies, comma-separated: wgs84, moon, mars, a=A,b=B, a=A,rf=F, r=R.
        #[arg(long, default_value = "wgs84,moon,mars")]
        bodies: String,
        /// Levels: a range such as 0-30, or a comma-separated list.
        #[arg(long, default_value = "0-30")]
        levels: String,
        /// Camera distances above the terrain in metres, comma-separated.
        #[arg(long, default_value = "1,10,100,1e3,1e4,1e5,1e6,1e7,1e8")]
        distances: String,
        /// Random quads per level and distance.
        #[arg(long, default_value_t = 8)]
        trials: usize,
        /// Random vertices per quad (besides the one under the camera and its neighbours).
        #[arg(long, default_value_t = 40)]
        vertices: usize,
        /// Seed of the random choices.
        #[arg(long, default_value_t = 2012)]
        seed: u64,
        /// Samples per quad edge.
        #[arg(long, default_value_t = terrafuse::ecm::geometry::DEFAULT_SAMPLES)]
        samples: u32,
        /// Tolerance of the flat rule (ecm-cutoff), metres.
        #[arg(long, default_value_t = terrafuse::ecm::geometry::FlatRule::DEFAULT_TOLERANCE_M)]
        tolerance_m: f64,
        /// Cap the tolerance at this fraction of the f32 limit at each level's draw distance
        /// (0: the absolute tolerance alone).
        #[arg(long, default_value_t = 0.25)]
        limit_fraction: f64,
        /// Where to write the CSV.
        #[arg(long, default_value = "accuracy.csv")]
        csv: PathBuf,
        /// Where to write the PNG plot.
        #[arg(long, default_value = "accuracy.png")]
        plot: PathBuf,
        /// Skip the timings.
        #[arg(long)]
        no_timing: bool,
    },
}

#[derive(Subcommand, Clone, Copy)]
enum GeoCommand {
    /// `lat lon` (degrees) → `face x y`, x and y in [-1, 1] (PROJ's qsc metres / a).
    ToFace,
    /// `face x y` → `lat lon` (degrees).
    FromFace,
    /// `lat lon h` (degrees, metres above the ellipsoid) → `X Y Z` (metres, ECEF).
    ToEcef,
    /// `X Y Z` (metres, ECEF) → `lat lon h`.
    FromEcef,
}

#[derive(Subcommand)]
enum Analysis {
    /// Angular and areal distortion of the cube projections and the alternative grids.
    Tissot {
        /// Points per chart side for the pointwise supremum.
        #[arg(long, default_value_t = 600)]
        samples: usize,
        /// Quadtree level whose cells are measured (2-12).
        #[arg(long, default_value_t = 10)]
        level: u8,
    },
    /// Per level: largest displacement and normal deviation of the static maps, and the flat
    /// rule that drops them (fitted for the body).
    Cutoff {
        /// Body: wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres).
        #[arg(long, default_value = "wgs84")]
        body: String,
        /// Tolerance on the flat path's position error, metres.
        #[arg(long, default_value_t = terrafuse::ecm::geometry::FlatRule::DEFAULT_TOLERANCE_M)]
        tolerance_m: f64,
        /// Cap the tolerance at this fraction of the f32 limit at each level's draw distance
        /// (0: the absolute tolerance alone).
        #[arg(long, default_value_t = 0.25)]
        limit_fraction: f64,
        /// Deepest level in the table (≤ 30).
        #[arg(long, default_value_t = 30)]
        max_level: u8,
        /// Samples per quad edge in the scan.
        #[arg(long, default_value_t = 17)]
        samples: u32,
    },
}

#[derive(clap::Args, Clone)]
struct BenchImportArgs {
    /// Source raster.
    source: PathBuf,
    /// Body: wgs84, moon, mars, a=A,b=B.
    #[arg(long)]
    body: String,
    /// Level: auto or 0–30.
    #[arg(long, default_value = "auto")]
    level: String,
    /// Worker threads for both tools.
    #[arg(long, default_value_t = 2)]
    threads: usize,
    /// Folder for the stores and gdalwarp outputs (default: a temporary folder).
    #[arg(long)]
    work: Option<PathBuf>,
}

fn import_options(a: &ImportArgs) -> Result<terrafuse::store::ImportOptions> {
    Ok(terrafuse::store::ImportOptions {
        sources: a.sources.clone(),
        store: a.store.clone().or_else(|| a.plan.clone()).unwrap_or_default(),
        body: a.body.as_deref().unwrap_or_default().parse()?,
        name: a.name.clone(),
        level: a.max_level.parse()?,
        resampling: a.resampling.parse()?,
        transform: a.transform.parse()?,
        vertical: a.vertical_datum.parse()?,
        memory_budget: cli::parse_bytes(&a.memory_budget)?,
        threads: a.threads,
        progress: !a.quiet,
        finest_only: false,
        watch: None,
    })
}

fn parse_numbers(text: &str, what: &str) -> Result<Vec<f64>> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| anyhow::anyhow!("{what}: '{v}' is not a number")))
        .collect()
}

/// Parses `0-30` or `3,5,7` into levels ≤ 30.
fn parse_levels(text: &str) -> Result<Vec<u8>> {
    let levels: Vec<u8> = if let Some((a, b)) = text.split_once('-') {
        let (a, b): (u8, u8) = (a.trim().parse()?, b.trim().parse()?);
        (a..=b).collect()
    } else {
        text.split(',').map(|v| v.trim().parse::<u8>()).collect::<Result<_, _>>()?
    };
    match levels.iter().find(|&&l| l > terrafuse::ecm::MAX_LEVEL) {
        Some(l) => anyhow::bail!("level {l} is past the deepest level, 30"),
        None if levels.is_empty() => anyhow::bail!("no levels in '{text}'"),
        None => Ok(levels),
    }
}

/// Parses comma-separated positive distances in metres.
fn parse_distances(text: &str) -> Result<Vec<f64>> {
    let d: Vec<f64> = text.split(',').map(|v| v.trim().parse::<f64>()).collect::<Result<_, _>>()?;
    match d.iter().find(|v| !(v.is_finite() && **v > 0.0)) {
        Some(v) => anyhow::bail!("camera distance {v} is not a positive number of metres"),
        None => Ok(d),
    }
}

/// Splits a body list at commas that start a new body (`wgs84,moon` but not `a=1,b=2`).
fn split_bodies(text: &str) -> Vec<String> {
    let mut bodies: Vec<String> = Vec::new();
    for part in text.split(',') {
        let starts_new = !part.starts_with("b=") && !part.starts_with("rf=");
        match bodies.last_mut() {
            Some(last) if !starts_new => {
                last.push(',');
                last.push_str(part);
            }
            _ => bodies.push(part.to_string()),
        }
    }
    bodies
}

fn main() -> ExitCode {
    match run(Args::parse()) {
        Ok(code) => code,
        Err(error) => {
            eprintln!("terrafuse: {}", terrafuse::errors::chain(&*error));
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<ExitCode> {
    let Some(command) = args.command else {
        let config = config_dir();
        let recent = terrafuse::gui::recent::Recent::load(config.as_deref());
        let project = recent.last().map_or_else(|| PathBuf::from(BUNDLED_SAMPLE), std::path::Path::to_path_buf);
        eprintln!("terrafuse: opening {}", project.display());
        let opts = terrafuse::gui::ViewOptions {
            project,
            view: None,
            camera: None,
            lod_threshold: None,
            width: 1280,
            height: 800,
            screenshot: None,
            timeout: std::time::Duration::from_secs(300),
            config_dir: config,
        };
        workstation(&opts)?;
        return Ok(ExitCode::SUCCESS);
    };
    match command {
        Command::Overview { landmarks } => {
            let text = std::fs::read_to_string(&landmarks)
                .with_context(|| format!("cannot read landmark file {}", landmarks.display()))?;
            print!("{}", cli::overview(&text));
            let (table, _) = cli::tissot_report(600, 10);
            print!("\n{table}");
        }
        Command::Geo { operation, body, projection, input } => {
            let ellipsoid: Ellipsoid = body.parse()?;
            let projection: CubeProjection = projection.parse()?;
            let operation = match operation {
                GeoCommand::ToFace => GeoOperation::ToFace,
                GeoCommand::FromFace => GeoOperation::FromFace,
                GeoCommand::ToEcef => GeoOperation::ToEcef,
                GeoCommand::FromEcef => GeoOperation::FromEcef,
            };
            let stdout = io::stdout().lock();
            let stderr = io::stderr().lock();
            let report = match input {
                Some(path) => {
                    let file = std::fs::File::open(&path)
                        .with_context(|| format!("cannot open input file {}", path.display()))?;
                    cli::run_batch(operation, &ellipsoid, projection, BufReader::new(file), stdout, stderr)?
                }
                None => cli::run_batch(operation, &ellipsoid, projection, io::stdin().lock(), stdout, stderr)?,
            };
            if report.refused > 0 {
                eprintln!("terrafuse: {} of {} records refused", report.refused, report.refused + report.converted);
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Analyze { analysis: Analysis::Tissot { samples, level } } => {
            let (table, _) = cli::tissot_report(samples, level);
            print!("{table}");
        }
        Command::Analyze { analysis: Analysis::Cutoff { body, tolerance_m, limit_fraction, max_level, samples } } => {
            let ellipsoid: Ellipsoid = body.parse()?;
            anyhow::ensure!(tolerance_m > 0.0, "the tolerance must be a positive number of metres");
            anyhow::ensure!(limit_fraction >= 0.0, "the limit fraction must be 0 or more");
            let (table, _) =
                cli::cutoff_report(&ellipsoid, tolerance_m, limit_fraction, max_level.min(30), samples.max(3));
            print!("{table}");
        }
        Command::Render { project, out, width, height, look, swipe } => {
            note_recovery(&project);
            let report = cli::render(
                &cli::RenderRequest {
                    project: &project,
                    out: &out,
                    width,
                    height,
                    view: look.view.as_deref(),
                    camera: look.camera.as_deref(),
                    lod_threshold: look.lod_threshold,
                    swipe: swipe.as_deref(),
                    trace: match (std::env::var_os("TERRAFUSE_DEBUG"), std::env::var_os("TERRAFUSE_DEBUG_QUADS")) {
                        (None, _) => cli::Trace::Off,
                        (Some(_), None) => cli::Trace::Steps,
                        (Some(_), Some(_)) => cli::Trace::Quads,
                    },
                },
                &mut |line| eprintln!("{line}"),
            )?;
            print!("{report}");
        }
        Command::Profile { project, from, to, line, samples, level, csv } => {
            let request = cli::ProfileRequest { project, from, to, line, samples, level, csv };
            print!("{}", cli::profile_command(&request)?);
        }
        Command::Compare { project, a, b, level, region, unweighted, json, samples } => {
            let request = cli::CompareRequest { project, a, b, level, region, unweighted, json, samples };
            print!("{}", cli::compare_command(&request)?);
        }
        Command::Brush {
            project,
            layer,
            tool,
            radius_m,
            strength_m,
            strength,
            path,
            falloff,
            spacing,
            level,
            seed,
            height_m,
            undo,
            redo,
        } => {
            let request = cli::BrushRequest {
                project,
                layer,
                tool,
                radius_m,
                strength_m,
                strength,
                path,
                falloff,
                spacing,
                level,
                seed,
                height_m,
                undo,
                redo,
            };
            print!("{}", cli::brush_command(&request)?);
        }
        Command::Replay { project, check, record, gpu, cpu: _, json } => {
            note_recovery(&project);
            let request = cli::ReplayRequest { project, check, record, gpu, json };
            let outcome = cli::replay_command(&request)?;
            print!("{}", outcome.report);
            if !outcome.passed {
                eprintln!("terrafuse: replay: a check failed (see above)");
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Project { command } => match command {
            ProjectCommand::Check { project } => {
                print!("{}", cli::project_check(&project)?)
            }
            ProjectCommand::Upgrade { project, out } => {
                print!("{}", cli::project_upgrade(&project, out.as_deref())?)
            }
            ProjectCommand::Schema { markdown: false } => print!("{}", terrafuse::project::Project::schema()),
            ProjectCommand::Schema { markdown: true } => print!("{}", terrafuse::project::reference::markdown()),
        },
        Command::Erode { project, layer, region, level, steps, preset, set, seed, gpu, cpu, json, undo, redo } => {
            let on = match (gpu, cpu) {
                (true, _) => cli::ErodeOn::Gpu,
                (_, true) => cli::ErodeOn::Cpu,
                _ => cli::ErodeOn::Auto,
            };
            let request =
                cli::ErodeRequest { project, layer, region, level, steps, preset, set, seed, on, json, undo, redo };
            print!("{}", cli::erode_command(&request)?);
        }
        Command::Coregister { project, a, b, level, region, apply, json } => {
            let request = cli::CoregRequest { project, a, b, level, region, apply, json };
            print!("{}", cli::coregister_command(&request)?);
        }
        Command::Export { project, out, raster, level, compose, difference } => {
            let (crs, bounds, resolution) = raster.parse()?;
            let difference = match difference.as_deref().map(|d| d.split(',').map(str::trim).collect::<Vec<_>>()) {
                None => None,
                Some(v) if v.len() == 2 && v[0] != v[1] => Some((v[0].to_string(), v[1].to_string())),
                Some(v) => anyhow::bail!("--difference {}: give two different layers A,B", v.join(",")),
            };
            let opts = cli::ComposedExport {
                project,
                out,
                crs,
                bounds,
                resolution,
                level,
                compose_on: if compose == "cpu" { cli::ComposeOn::Cpu } else { cli::ComposeOn::Gpu },
                difference,
            };
            let report = cli::export_composed(&opts)?;
            println!(
                "wrote {} ({}×{} pixels, level {}, {} quads composed on the {}, {} pixels with data)",
                opts.out.display(),
                report.size.0,
                report.size.1,
                report.level,
                report.quads,
                report.composer,
                report.valid
            );
        }
        Command::View { project, look, width, height, screenshot, timeout } => {
            if !(timeout.is_finite() && timeout > 0.0) {
                anyhow::bail!("--timeout {timeout} must be a positive number of seconds");
            }
            let opts = terrafuse::gui::ViewOptions {
                project,
                view: look.view,
                camera: look.camera,
                lod_threshold: look.lod_threshold,
                width,
                height,
                screenshot,
                timeout: std::time::Duration::from_secs_f64(timeout),
                config_dir: config_dir(),
            };
            workstation(&opts)?;
        }
        Command::Import { import } => match (&import.plan, &import.manifest) {
            (Some(plan), _) => {
                let opts = import_options(&import)?;
                let report = terrafuse::store::shard::plan(&opts, plan, import.shards.unwrap_or(0))?;
                print!("{}", cli::plan_summary(plan, &report));
            }
            (None, Some(manifest)) => {
                let shard = shard_index(import.shard.as_deref().unwrap_or_default())?;
                let store = import.store.clone().unwrap_or_default();
                let opts = terrafuse::store::shard::ShardOptions {
                    manifest: manifest.clone(),
                    shard,
                    store: store.clone(),
                    work_dir: import.work_dir.clone(),
                    threads: import.threads,
                    memory_budget: cli::parse_bytes(&import.memory_budget)?,
                    progress: !import.quiet,
                    watch: None,
                };
                let report = terrafuse::store::shard::import_shard(&opts)?;
                print!("{}", cli::shard_summary(&store, shard, &report));
            }
            (None, None) => {
                let opts = import_options(&import)?;
                let report = terrafuse::store::import(&opts)?;
                print!("{}", cli::import_summary(&opts.store, &report));
            }
        },
        Command::Store { command: StoreCommand::Merge { store, parts, threads, quiet } } => {
            let opts = terrafuse::store::merge::MergeOptions {
                store: store.clone(),
                parts,
                threads,
                progress: !quiet,
                watch: None,
            };
            let report = terrafuse::store::merge::merge(&opts)?;
            print!("{}", cli::merge_summary(&store, &report));
            if !report.complete {
                return Ok(ExitCode::from(3));
            }
        }
        Command::Slurm { command: SlurmCommand::Submit(a) } => {
            print!(
                "{}",
                cli::slurm_submit(&cli::SubmitRequest {
                    manifest: a.manifest,
                    parts: a.parts,
                    store: a.store,
                    threads: a.threads,
                    memory_budget: a.memory_budget,
                    work_dir: a.work_dir,
                    sbatch_args: a.sbatch_arg,
                    terrafuse: a.terrafuse,
                    dry_run: a.dry_run,
                })?
            );
        }
        Command::Store { command: StoreCommand::Info { store } } => {
            print!("{}", cli::store_info(&store)?);
        }
        Command::Store { command: StoreCommand::Sample { store, dataset, level } } => {
            let s = terrafuse::store::Store::open_read_only(&store)?;
            let mut reader = terrafuse::store::GridReader::new(s, dataset.as_deref().unwrap_or(""))?;
            let finest = reader.finest_level();
            let level = level.unwrap_or(finest);
            anyhow::ensure!(
                level <= finest,
                "{}: dataset {} has levels 0–{finest}, not {level}",
                store.display(),
                reader.dataset()
            );
            let (_, refused) =
                cli::sample_lines(&mut reader, level, io::stdin().lock(), io::stdout().lock(), io::stderr().lock())?;
            if refused > 0 {
                eprintln!("terrafuse: {refused} lines refused");
                return Ok(ExitCode::FAILURE);
            }
        }
        Command::Store { command: StoreCommand::Export { store, out, raster, dataset, level } } => {
            let (crs, bounds, resolution) = raster.parse()?;
            let opts = terrafuse::store::export::ExportOptions { store, dataset, crs, bounds, resolution, level, out };
            let report = terrafuse::store::export::export(&opts)?;
            println!(
                "wrote {} ({}×{} pixels, level {}, {} with data)",
                opts.out.display(),
                report.size.0,
                report.size.1,
                report.level,
                report.valid
            );
        }
        Command::Bench { bench: Bench::Replay { strokes, steps, log_strokes, gpu, out } } => {
            let settings = cli::ReplayBenchSettings { strokes, steps, log_strokes, gpu, out };
            let mut show = |part: &str| {
                print!("{part}");
                let _ = std::io::Write::flush(&mut std::io::stdout());
            };
            cli::bench_replay(&settings, &mut show)?;
        }
        Command::Bench { bench: Bench::Erosion { sizes, steps, cpu_max, gpu, bandwidth_gbs } } => {
            let settings = cli::ErosionBenchSettings { sizes, steps, cpu_max, gpu, bandwidth_gbs };
            print!("{}", cli::bench_erosion(&settings)?);
        }
        Command::Bench { bench: Bench::BrushLatency { project, rounds, width, height } } => {
            print!("{}", cli::bench_brush_latency(&project, rounds, width, height)?);
        }
        Command::Bench { bench: Bench::Brush { strokes, level, gpu } } => {
            print!("{}", cli::bench_brush(strokes, level, gpu)?);
        }
        Command::Bench { bench: Bench::Compare { project, size, out } } => {
            anyhow::ensure!((64..=16384).contains(&size), "--size {size} must lie within 64–16384 pixels");
            let root = PathBuf::from(env!("CARGO_MANIFEST_DIR"));
            let settings = cli::CompareBenchSettings {
                project,
                out,
                size,
                python: root.join(".venv-ref/bin/python"),
                reference_dir: root.join("tests/reference"),
            };
            print!("{}", cli::bench_compare(&settings)?);
        }
        Command::Bench { bench: Bench::Compose { project, quads, repeats, out } } => {
            anyhow::ensure!(quads > 0 && repeats > 0, "--quads and --repeats must be at least 1");
            let settings = cli::ComposeBenchSettings { project, quads, repeats, out: out.clone() };
            let (_, report) = cli::bench_compose(&settings)?;
            print!("{report}");
            println!("wrote {}", out.join("compose.csv").display());
        }
        Command::Bench { bench: Bench::Render { projects, thresholds, width, height, frames, out } } => {
            anyhow::ensure!(thresholds.iter().all(|t| t.is_finite() && *t > 0.0), "--thresholds must be positive");
            let settings = cli::RenderBenchSettings { projects, thresholds, width, height, frames, out: out.clone() };
            let (rows, report) = cli::bench_render(&settings)?;
            print!("{report}");
            let (csv, png) = cli::write_render_bench(&out, &rows)?;
            println!("wrote {} and {}", csv.display(), png.display());
        }
        Command::Bench {
            bench: Bench::Shards { source, body, level, shards, threads, nodes, cores, samples, work },
        } => {
            let dir = work.clone().unwrap_or_else(cli::default_work_dir);
            let settings = cli::ShardBenchSettings {
                source,
                body,
                level,
                shards: shards
                    .split(',')
                    .map(|n| n.trim().parse::<usize>().map_err(|_| anyhow::anyhow!("--shards: '{n}' is not a number")))
                    .collect::<Result<_>>()?,
                threads,
                work: dir.clone(),
                nodes,
                cores,
                projected_samples: samples.unwrap_or(cli::SRTM_SAMPLES),
            };
            let report = cli::bench_shards(&settings, &mut |line| eprintln!("{line}"));
            if work.is_none() {
                let _ = std::fs::remove_dir_all(&dir);
            }
            print!("{}", report?);
        }
        Command::Bench { bench: Bench::Import { import } } => {
            let work = import.work.clone().unwrap_or_else(cli::default_work_dir);
            let opts = terrafuse::store::ImportOptions {
                sources: vec![import.source.clone()],
                store: work.join("bench-store.gpkg"),
                body: import.body.parse()?,
                name: Some("bench".into()),
                level: import.level.parse()?,
                resampling: terrafuse::store::Resampling::Bilinear,
                transform: terrafuse::store::lattice::Transform::Lattice,
                vertical: terrafuse::store::VerticalDatum::Unspecified,
                memory_budget: 2 << 30,
                threads: Some(import.threads),
                progress: false,
                finest_only: true,
                watch: None,
            };
            print!("{}", cli::bench_import(&opts, &work, import.threads.max(1))?);
            if import.work.is_none() {
                let _ = std::fs::remove_dir_all(&work);
            }
        }
        Command::Bench {
            bench:
                Bench::Accuracy {
                    bodies,
                    levels,
                    distances,
                    trials,
                    vertices,
                    seed,
                    samples,
                    tolerance_m,
                    limit_fraction,
                    csv,
                    plot,
                    no_timing,
                },
        } => {
            let bodies: Vec<Ellipsoid> = split_bodies(&bodies).iter().map(|b| b.parse()).collect::<Result<_, _>>()?;
            anyhow::ensure!(samples >= 2, "a quad needs at least 2 samples per edge");
            let settings = terrafuse::ecm::accuracy::AccuracySettings {
                levels: parse_levels(&levels)?,
                distances_m: parse_distances(&distances)?,
                trials: trials.max(1),
                random_vertices: vertices,
                seed,
                samples,
                ..Default::default()
            };
            anyhow::ensure!(tolerance_m > 0.0 && limit_fraction >= 0.0, "the tolerance must be positive");
            let bench = cli::AccuracyBench { bodies: bodies.clone(), settings, tolerance_m, limit_fraction };
            let (report, rows) = cli::accuracy_bench(&bench);
            print!("{report}");
            cli::write_accuracy_outputs(&bench, &rows, &csv, Some(&plot))?;
            println!("\nwrote {} and {}", csv.display(), plot.display());
            if !no_timing {
                print!("{}", cli::timing_report(&bodies[0], samples));
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
