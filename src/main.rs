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
#[command(name = "terrafuse", version, about = "Planetary terrain workstation on the Ellipsoidal Cube Map")]
struct Args {
    #[command(subcommand)]
    command: Command,
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
    /// Benchmarks that report speed beside error.
    Bench {
        #[command(subcommand)]
        bench: Bench,
    },
}

#[derive(Subcommand)]
enum Bench {
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
            eprintln!("terrafuse: {error:#}");
            ExitCode::FAILURE
        }
    }
}

fn run(args: Args) -> Result<ExitCode> {
    match args.command {
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
            cli::write_accuracy_outputs(&bench, &rows, &csv, Some(&plot)).map_err(anyhow::Error::msg)?;
            println!("\nwrote {} and {}", csv.display(), plot.display());
            if !no_timing {
                print!("{}", cli::timing_report(&bodies[0], samples));
            }
        }
    }
    Ok(ExitCode::SUCCESS)
}
