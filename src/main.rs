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
    }
    Ok(ExitCode::SUCCESS)
}
