//! The command line: clap's types for every `terrafuse` subcommand. The commands that act on a
//! project take their request types ([`BrushRequest`], [`ErodeRequest`], …) straight from
//! clap; [`super::dispatch::run`] runs them; `main.rs` only parses and prints.

use std::path::PathBuf;

use clap::Subcommand;

use super::bench_args::Bench;
use super::{BrushRequest, CliError, CompareRequest, CoregRequest, ErodeRequest, ProfileRequest, ReplayRequest};

/// A `terrafuse` subcommand.
#[derive(Subcommand)]
pub enum Command {
    /// Print what Terrafuse does, on the bundled landmark sample.
    Overview {
        /// Landmark file: lines of `name lat lon h`.
        #[arg(long, default_value = concat!(env!("CARGO_MANIFEST_DIR"), "/projects/samples/landmarks.txt"))]
        landmarks: PathBuf,
    },
    /// Batch coordinate conversions, one record per line from stdin (or --input) to stdout.
    Geo {
        /// The conversion.
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
        /// The analysis.
        #[command(subcommand)]
        analysis: Analysis,
    },
    /// Import rasters GDAL reads (any CRS) onto the cube map, into a GeoPackage tile store.
    Import {
        /// What to import and how.
        #[command(flatten)]
        import: ImportArgs,
    },
    /// Read a tile store: info, sample, export; merge a sharded import's parts.
    Store {
        /// The subcommand.
        #[command(subcommand)]
        command: StoreCommand,
    },
    /// Run a sharded import on a Slurm cluster.
    Slurm {
        /// The subcommand.
        #[command(subcommand)]
        command: SlurmCommand,
    },
    /// Render one frame of a project to a PNG and report what it drew and what it cost; or, with
    /// --flight, frames along a camera path with frames.csv.
    Render(RenderArgs),
    /// Write a project's composed elevation (every visible layer, as drawn) as a GeoTIFF in any
    /// CRS: float32, NaN nodata, written atomically.
    Export(ExportArgs),
    /// Compare layer A with layer B (the reference) of a project: statistics of A − B over
    /// their overlap at one level, weighted by each sample's cell area on the ellipsoid, by slope
    /// class of B, with a histogram.
    Compare(CompareRequest),
    /// Compute one shard's part of a plan's pending round (`compare|export|import … --plan`):
    /// refuses a project, store or source changed since the plan; does nothing where the part
    /// is there. An import's part is PLAN.parts/part-IIII.gpkg.
    Shard {
        /// The plan.
        plan: PathBuf,
        /// The shard: 0 … N−1, or `env` for the array index of Slurm (SLURM_ARRAY_TASK_ID),
        /// Kubernetes (JOB_COMPLETION_INDEX) or AWS Batch (AWS_BATCH_JOB_ARRAY_INDEX).
        shard: String,
    },
    /// Join a plan's parts: print what `compare` prints, write the export's GeoTIFF, or merge an
    /// import's parts into its store, once every round is complete; else exit 3 naming the round
    /// and the shards to run (again).
    Merge {
        /// The plan.
        plan: PathBuf,
        /// An import's store (default: the plan's name with .gpkg).
        #[arg(long)]
        store: Option<PathBuf>,
    },
    /// Sharded comparisons on this machine.
    Shards {
        /// The subcommand.
        #[command(subcommand)]
        command: ShardsCommand,
    },
    /// Co-register layer A onto layer B (Nuth & Kääb 2011 on the ellipsoid): the horizontal
    /// shift (east, north, metres) and vertical offset that align A with B, and the statistics of
    /// A − B before and after.
    Coregister(CoregRequest),
    /// Appends a brush stroke to an edit layer (made on top when missing), or moves its undo
    /// position, and saves the project atomically.
    Brush(BrushRequest),
    /// Runs erosion headless on a region (the box rounded out to whole quads of the level),
    /// appends the run to an erosion layer (made on top when missing) or moves its undo
    /// position, prints the budgets and the time, and saves the project atomically.
    Erode(ErodeRequest),
    /// Every visible layer's elevation (each alone) and the composed stack's along the geodesic
    /// between two points.
    Profile(ProfileRequest),
    /// Open the workstation: a window with the project's terrain, its views and its visual
    /// settings (needs an X11 display; `xvfb-run` provides one for screenshots).
    View {
        /// The project file (JSON).
        project: PathBuf,
        /// The view: a named one, a camera, a level of detail.
        #[command(flatten)]
        look: LookArgs,
        /// Window width, pixels.
        #[arg(long, default_value_t = 1280, allow_negative_numbers = true)]
        width: u32,
        /// Window height, pixels.
        #[arg(long, default_value_t = 800, allow_negative_numbers = true)]
        height: u32,
        /// Once the view has loaded, write a picture of the whole window to this PNG and close.
        #[arg(long)]
        screenshot: Option<PathBuf>,
        /// Seconds a --screenshot run waits for the view to load.
        #[arg(long, default_value_t = 300.0, allow_negative_numbers = true)]
        timeout: f64,
    },
    /// Rebuild every edit and erosion layer of a project from its operations and print a digest
    /// per layer; --check compares the project's recorded checks (exit status 1 on a mismatch,
    /// naming the check and the first differing tile), --record writes them.
    Replay(ReplayRequest),
    /// Project files: check one, bring one to the current version, print the schema.
    Project {
        /// The subcommand.
        #[command(subcommand)]
        command: ProjectCommand,
    },
    /// Benchmarks that report speed beside error.
    Bench {
        /// The benchmark.
        #[command(subcommand)]
        bench: Bench,
    },
}

/// `terrafuse project …`.
#[derive(Subcommand)]
pub enum ProjectCommand {
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
        /// How long to wait for another process changing the project (or the file at --out).
        #[command(flatten)]
        wait: super::WaitArgs,
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
pub struct LookArgs {
    /// A named view of the project (default: its default view).
    #[arg(long, conflicts_with = "camera")]
    pub view: Option<String>,
    /// A camera: lat,lon,alt,heading,pitch[,fov] (degrees, metres above the ellipsoid).
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Split quads while a sample covers more than this many pixels (the project's default): the
    /// data's level, and the floor of the geometry's.
    #[arg(long, allow_negative_numbers = true)]
    pub lod_threshold: Option<f64>,
    /// Draw the mesh as coarsely as keeps its geometric error under this many pixels on screen
    /// (the project's `detail.max_pixel_error`, default 1).
    #[arg(long, allow_negative_numbers = true)]
    pub pixel_error: Option<f64>,
}

/// `terrafuse import`.
#[derive(clap::Args, Clone)]
pub struct ImportArgs {
    /// Source rasters (GeoTIFF, COG, VRT, …); where they overlap the first with data wins.
    #[arg(required_unless_present = "manifest", conflicts_with = "manifest")]
    pub sources: Vec<PathBuf>,
    /// The store (a GeoPackage; created if missing); with --shard, the shard's partial store.
    #[arg(long, required_unless_present = "plan")]
    pub store: Option<PathBuf>,
    /// Body: wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres).
    #[arg(long, required_unless_present = "manifest")]
    pub body: Option<String>,
    /// Plan a sharded import instead: write this manifest (the finest level's quads cut into
    /// --shards runs along a Hilbert curve per face) and import nothing.
    #[arg(long, requires = "shards", conflicts_with_all = ["store", "manifest"])]
    pub plan: Option<PathBuf>,
    /// Shards of the plan.
    #[arg(long, requires = "plan", allow_negative_numbers = true)]
    pub shards: Option<usize>,
    /// Import one shard of this manifest (with --shard and --store).
    #[arg(long, requires = "shard")]
    pub manifest: Option<PathBuf>,
    /// The shard: 0 … N−1, or `env` for the array index of Slurm (SLURM_ARRAY_TASK_ID),
    /// Kubernetes (JOB_COMPLETION_INDEX) or AWS Batch (AWS_BATCH_JOB_ARRAY_INDEX).
    #[arg(long, requires = "manifest")]
    pub shard: Option<String>,
    /// With --shard: build the partial store in this folder (node-local disk) and copy it to
    /// --store when complete.
    #[arg(long, requires = "shard")]
    pub work_dir: Option<PathBuf>,
    /// Dataset name (default: the first source's file name).
    #[arg(long)]
    pub name: Option<String>,
    /// Finest level: auto (from the source resolution) or 0–30.
    #[arg(long, default_value = "auto")]
    pub max_level: String,
    /// Resampling at the finest level: bilinear, cubic or nearest.
    #[arg(long, default_value = "bilinear")]
    pub resampling: String,
    /// Where samples fall in the sources: lattice (exact on a coarse lattice per quad,
    /// interpolated within 10⁻³ source pixel, measured on every quad, else exact) or exact
    /// (every sample through PROJ).
    #[arg(long, default_value = "lattice")]
    pub transform: String,
    /// Vertical datum of the source heights: ellipsoidal, egm96, egm2008 or geoid:GRIDFILE
    /// (geoid heights are converted to ellipsoidal ones through PROJ), or unspecified.
    #[arg(long, default_value = "unspecified")]
    pub vertical_datum: String,
    /// Memory budget (GDAL cache, source windows, tiles in flight), e.g. 2GiB.
    #[arg(long, default_value = "2GiB")]
    pub memory_budget: String,
    /// Worker threads (default: all cores).
    #[arg(long, allow_negative_numbers = true)]
    pub threads: Option<usize>,
    /// No progress bar.
    #[arg(long)]
    pub quiet: bool,
}

/// `terrafuse shards …`.
#[derive(Subcommand)]
pub enum ShardsCommand {
    /// Run a plan's pending shards as local processes, round after round, and merge.
    Run {
        /// The plan.
        plan: PathBuf,
        /// An import's store (default: the plan's name with .gpkg).
        #[arg(long)]
        store: Option<PathBuf>,
        /// Shard processes at once.
        #[arg(long, default_value_t = 2, allow_negative_numbers = true)]
        jobs: usize,
    },
}

/// `terrafuse slurm …`.
#[derive(Subcommand)]
pub enum SlurmCommand {
    /// Submit a plan's missing shards as a job array and a merge job that runs after it
    /// (--dependency=afterok): a comparison's or an export's PLAN (`compare`/`export … --plan`),
    /// whose merge submits the next round itself and writes the result to PARTS/slurm/result.*;
    /// or an import's --manifest (each shard built on node-local disk, copied to --parts when
    /// complete). After failures, run it again: only missing shards are submitted.
    Submit(SubmitArgs),
}

/// `terrafuse slurm submit`.
#[derive(clap::Args, Clone)]
pub struct SubmitArgs {
    /// A comparison's or an export's plan (`terrafuse compare|export … --plan PLAN --shards N`).
    #[arg(value_name = "PLAN.json", conflicts_with_all = ["manifest", "parts", "store"])]
    pub plan: Option<PathBuf>,
    /// An import's manifest (`terrafuse import … --plan MANIFEST --shards N`).
    #[arg(long, required_unless_present = "plan")]
    pub manifest: Option<PathBuf>,
    /// With --manifest: folder for the partial stores, on storage every node sees (also the
    /// scripts and logs, in PARTS/slurm).
    #[arg(long, required_unless_present = "plan")]
    pub parts: Option<PathBuf>,
    /// With --manifest: the merged store.
    #[arg(long, required_unless_present = "plan")]
    pub store: Option<PathBuf>,
    /// CPUs per task, and the import's threads.
    #[arg(long, default_value_t = 2, allow_negative_numbers = true)]
    pub threads: usize,
    /// Memory budget per task.
    #[arg(long, default_value = "2GiB")]
    pub memory_budget: String,
    /// Node-local folder a task builds its shard in (a shell word, expanded on the node).
    #[arg(long, default_value = "${TMPDIR:-/tmp}")]
    pub work_dir: String,
    /// An extra sbatch argument for both jobs (repeat it): --sbatch-arg=--partition=short.
    #[arg(long, allow_hyphen_values = true)]
    pub sbatch_arg: Vec<String>,
    /// The terrafuse executable the nodes run (default: this one).
    #[arg(long)]
    pub terrafuse: Option<PathBuf>,
    /// Print the sbatch commands without submitting.
    #[arg(long)]
    pub dry_run: bool,
}

/// `terrafuse store …`.
#[derive(Subcommand)]
pub enum StoreCommand {
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
        #[arg(long, allow_negative_numbers = true)]
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
        #[arg(long, allow_negative_numbers = true)]
        level: Option<u8>,
    },
    /// Write a dataset as a GeoTIFF in any CRS.
    Export {
        /// The store.
        store: PathBuf,
        /// The GeoTIFF to write.
        out: PathBuf,
        /// The output grid.
        #[command(flatten)]
        raster: RasterArgs,
        /// Dataset (needed when the store has several).
        #[arg(long)]
        dataset: Option<String>,
        /// Level to read (default: the finest the output resolution needs).
        #[arg(long, allow_negative_numbers = true)]
        level: Option<u8>,
    },
}

/// The output raster of `export` and `store export`.
#[derive(clap::Args)]
pub struct RasterArgs {
    /// Output CRS (EPSG:4326, EPSG:32637, a PROJ string, WKT).
    #[arg(long)]
    pub crs: String,
    /// xmin,ymin,xmax,ymax in the output CRS.
    #[arg(long, allow_hyphen_values = true)]
    pub bounds: String,
    /// Pixel size in CRS units: one value, or x,y.
    #[arg(long)]
    pub resolution: String,
}

/// An output grid: the CRS, the bounds (xmin, ymin, xmax, ymax) and the pixel size (x, y).
pub type OutputGrid = (String, [f64; 4], (f64, f64));

impl RasterArgs {
    /// The CRS, the bounds and the pixel size (x, y), checked for shape.
    pub fn parse(self) -> Result<OutputGrid, CliError> {
        let b = parse_numbers(&self.bounds, "--bounds")?;
        if b.len() != 4 {
            return Err("--bounds takes xmin,ymin,xmax,ymax".into());
        }
        let r = parse_numbers(&self.resolution, "--resolution")?;
        let resolution = match r.as_slice() {
            [v] => (*v, *v),
            [x, y] => (*x, *y),
            _ => return Err("--resolution takes one value or x,y".into()),
        };
        Ok((self.crs, [b[0], b[1], b[2], b[3]], resolution))
    }
}

/// `terrafuse geo …`: the conversion.
#[derive(Subcommand, Clone, Copy)]
pub enum GeoCommand {
    /// `lat lon` (degrees) → `face x y`, x and y in [-1, 1] (PROJ's qsc metres / a).
    ToFace,
    /// `face x y` → `lat lon` (degrees).
    FromFace,
    /// `lat lon h` (degrees, metres above the ellipsoid) → `X Y Z` (metres, ECEF).
    ToEcef,
    /// `X Y Z` (metres, ECEF) → `lat lon h`.
    FromEcef,
}

/// `terrafuse analyze …`.
#[derive(Subcommand)]
pub enum Analysis {
    /// Angular and areal distortion of the cube projections and the alternative grids.
    Tissot {
        /// Points per chart side for the pointwise supremum.
        #[arg(long, default_value_t = 600, allow_negative_numbers = true)]
        samples: usize,
        /// Quadtree level whose cells are measured (2-12).
        #[arg(long, default_value_t = 10, allow_negative_numbers = true)]
        level: u8,
    },
    /// Per level: largest displacement and normal deviation of the static maps, and the flat
    /// rule that drops them (fitted for the body).
    Cutoff {
        /// Body: wgs84, moon, mars, a=A,b=B, a=A,rf=F or r=R (metres).
        #[arg(long, default_value = "wgs84")]
        body: String,
        /// Tolerance on the flat path's position error, metres.
        #[arg(long, default_value_t = crate::ecm::geometry::FlatRule::DEFAULT_TOLERANCE_M, allow_negative_numbers = true)]
        tolerance_m: f64,
        /// Cap the tolerance at this fraction of the f32 limit at each level's draw distance
        /// (0: the absolute tolerance alone).
        #[arg(long, default_value_t = 0.25, allow_negative_numbers = true)]
        limit_fraction: f64,
        /// Deepest level in the table (≤ 30).
        #[arg(long, default_value_t = 30, allow_negative_numbers = true)]
        max_level: u8,
        /// Samples per quad edge in the scan.
        #[arg(long, default_value_t = 17, allow_negative_numbers = true)]
        samples: u32,
    },
}

/// Comma-separated numbers of an option.
pub fn parse_numbers(text: &str, what: &str) -> Result<Vec<f64>, CliError> {
    text.split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| crate::Invalid(format!("{what}: '{v}' is not a number")).into()))
        .collect()
}

/// `--gpu` or `--cpu`: where a command that rebuilds layers runs (`erode`, `replay`), declared
/// once. Neither: the command's default (`erode`: the GPU where there is a hardware one,
/// `replay`: the CPU).
#[derive(clap::Args, Clone, Copy, Debug, Default)]
pub struct EngineArgs {
    /// Run on the GPU (lavapipe too).
    #[arg(long, conflicts_with = "cpu")]
    pub gpu: bool,
    /// Run the CPU reference, bit for bit reproducible (the default of `replay`, and of `erode`
    /// without a hardware GPU).
    #[arg(long)]
    pub cpu: bool,
}

/// `terrafuse render`'s arguments.
#[derive(clap::Args, Clone)]
pub struct RenderArgs {
    /// The project file (JSON).
    #[arg(required_unless_present = "list_colour_maps")]
    pub project: Option<PathBuf>,
    /// The PNG to write.
    #[arg(long, required_unless_present_any = ["flight", "list_colour_maps"], conflicts_with = "flight")]
    pub out: Option<PathBuf>,
    /// List the colour maps a project's visuals.colour_map.preset may name, and stop.
    #[arg(long = "list-colour-maps", exclusive = true)]
    pub list_colour_maps: bool,
    /// A camera path: LAT,LON,ALT,HEADING,PITCH[,FOV];LAT,… (degrees, metres above the
    /// ellipsoid), flown along geodesics, the altitude geometrically.
    #[arg(long, allow_hyphen_values = true, requires = "out_dir", conflicts_with_all = ["swipe", "view", "camera"])]
    pub flight: Option<String>,
    /// Frames along the flight.
    #[arg(long, default_value_t = 60, requires = "flight", allow_negative_numbers = true)]
    pub frames: usize,
    /// Folder for the flight's frame_0000.png … and frames.csv.
    #[arg(long, requires = "flight")]
    pub out_dir: Option<PathBuf>,
    /// Draw without geomorphing (to measure the pops it hides).
    #[arg(long)]
    pub no_geomorph: bool,
    /// Where frames compose the layer stack: gpu (the compute pass) or cpu (the reference);
    /// default: gpu on a hardware adapter, cpu on a software one (where it is faster).
    #[arg(long, value_parser = ["gpu", "cpu"])]
    pub compose: Option<String>,
    /// Image width, pixels.
    #[arg(long, default_value_t = 1280, allow_negative_numbers = true)]
    pub width: u32,
    /// Image height, pixels.
    #[arg(long, default_value_t = 1024, allow_negative_numbers = true)]
    pub height: u32,
    /// The view: a named one, a camera, a level of detail.
    #[command(flatten)]
    pub look: LookArgs,
    /// A,B[,POSITION]: layer A left of a vertical line at POSITION (0–1 of the width,
    /// default 0.5), layer B right of it (each shown with the other hidden); or the name of
    /// a swipe saved in the project (comparison.swipes), with its view.
    #[arg(long)]
    pub swipe: Option<String>,
}

/// `terrafuse export`'s arguments.
#[derive(clap::Args)]
pub struct ExportArgs {
    /// The project file (JSON).
    pub project: PathBuf,
    /// The GeoTIFF to write.
    pub out: PathBuf,
    /// The output grid.
    #[command(flatten)]
    pub raster: RasterArgs,
    /// Level to compose (default: the output's pixel size, no finer than the finest dataset
    /// unless procedural layers add detail).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Where to compose: gpu (the renderer's pass) or cpu (the reference, bit for bit).
    #[arg(long, default_value = "gpu", value_parser = ["gpu", "cpu"])]
    pub compose: String,
    /// A,B: write layer A − layer B (each composed alone) instead of the stack.
    #[arg(long)]
    pub difference: Option<String>,
    /// Write a terrain attribute of the composed heights instead of the heights: slope,
    /// aspect, hillshade, curvature, planform_curvature, profile_curvature, tpi, tri or
    /// roughness (xDEM's definitions, in true metres on the ellipsoid).
    #[arg(long)]
    pub attribute: Option<String>,
    /// Compose this layer alone (as compare takes it) instead of the visible stack.
    #[arg(long, conflicts_with = "difference")]
    pub layer: Option<String>,
    /// Write a Cloud-Optimized GeoTIFF (GDAL's COG driver: tiled, with overviews, the header
    /// first) instead of a plain tiled GeoTIFF.
    #[arg(long)]
    pub cog: bool,
    /// Export nothing: check the project and arguments, cut the output's rows into --shards
    /// runs and write this plan (then `terrafuse shard PLAN I` for each shard and `terrafuse
    /// merge PLAN`, which writes OUT; or `terrafuse shards run PLAN`, `terrafuse slurm submit PLAN`).
    #[arg(long, value_name = "PLAN.json", requires = "shards")]
    pub plan: Option<PathBuf>,
    /// With --plan: the number of shards.
    #[arg(long, requires = "plan", allow_negative_numbers = true)]
    pub shards: Option<usize>,
    /// With --plan: the folder of the shards' parts (default: PLAN.parts beside the plan).
    #[arg(long, requires = "plan")]
    pub parts: Option<PathBuf>,
}
