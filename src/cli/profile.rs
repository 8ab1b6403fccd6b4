//! `terrafuse profile PROJECT --from LAT,LON --to LAT,LON`: every visible layer's elevation and
//! the composed stack's along the geodesic, as a summary table and optionally CSV.

use super::error::Context;
use super::{CliError, Within};
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::compare::{ProfileOptions, profile};
use crate::project::Project;

/// What `terrafuse profile` was asked.
#[derive(clap::Args, Clone, Debug)]
pub struct ProfileRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// Start: LAT,LON in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub from: Option<String>,
    /// End: LAT,LON in degrees.
    #[arg(long, allow_hyphen_values = true)]
    pub to: Option<String>,
    /// A profile line saved in the project (comparison.profiles) instead of --from and --to.
    #[arg(long)]
    pub line: Option<String>,
    /// Samples along the line (default: one per sample spacing of the level).
    #[arg(long, allow_negative_numbers = true)]
    pub samples: Option<usize>,
    /// Level to sample (default: the finest among the datasets).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Write the profile as CSV (distance_m, lat_deg, lon_deg, a column per layer, composed).
    #[arg(long)]
    pub csv: Option<PathBuf>,
}

fn parse_point(option: &str, text: &str) -> Result<[f64; 2], CliError> {
    let v: Vec<f64> = text
        .split(',')
        .map(|s| s.trim().parse::<f64>())
        .collect::<Result<_, _>>()
        .context(format_args!("{option} {text} (give LAT,LON in degrees)"))?;
    match v[..] {
        [lat, lon] => Ok([lat, lon]),
        _ => Err(format!("{option} {text}: give LAT,LON in degrees").into()),
    }
}

/// Samples the profile, writes the CSV if asked; returns what to print.
pub fn profile_command(request: &ProfileRequest) -> Result<String, CliError> {
    let project = Project::load(&request.project)?;
    let (from, to) = match (&request.line, &request.from, &request.to) {
        (Some(name), None, None) => {
            let line = project.comparison.profiles.get(name).ok_or_else(|| {
                let saved: Vec<&str> = project.comparison.profiles.keys().map(String::as_str).collect();
                format!("--line {name}: not a profile line of the project (saved: {})", saved.join(", "))
            })?;
            (line.from, line.to)
        }
        (None, Some(from), Some(to)) => (parse_point("--from", from)?, parse_point("--to", to)?),
        _ => return Err("give --from LAT,LON and --to LAT,LON, or --line NAME (a line saved in the project)".into()),
    };
    let opts = ProfileOptions { from, to, samples: request.samples, level: request.level };
    let p = profile(&project, &opts).within(request.project.display())?;
    if let Some(path) = &request.csv {
        crate::files::write_atomic(path, p.csv().as_bytes()).map_err(CliError::file(path, "cannot write"))?;
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "profile of {:.3} km along the geodesic, {} samples at level {}",
        p.length_m / 1e3,
        p.distance_m.len(),
        p.level
    );
    let mut columns: Vec<(&str, &Vec<f64>)> = p.layers.iter().map(|(n, h)| (n.as_str(), h)).collect();
    columns.push(("composed", &p.composed));
    for (name, h) in &columns {
        let valid: Vec<f64> = h.iter().copied().filter(|v| !v.is_nan()).collect();
        let (lo, hi) = valid.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), &v| (a.min(v), b.max(v)));
        let _ = writeln!(out, "{name:>16}: {} of {} samples with data, {lo:.1} … {hi:.1} m", valid.len(), h.len());
    }
    let _ = write!(out, "{:>10} {:>11} {:>11}", "km", "lat", "lon");
    for (name, _) in &columns {
        let _ = write!(out, " {name:>12}");
    }
    out.push('\n');
    let every = (p.distance_m.len() / 10).max(1);
    for k in (0..p.distance_m.len()).step_by(every).chain(std::iter::once(p.distance_m.len() - 1)) {
        let _ = write!(out, "{:>10.3} {:>11.6} {:>11.6}", p.distance_m[k] / 1e3, p.lat_deg[k], p.lon_deg[k]);
        for (_, h) in &columns {
            let _ = write!(out, " {:>12.2}", h[k]);
        }
        out.push('\n');
    }
    if let Some(path) = &request.csv {
        let _ = writeln!(out, "wrote {}", path.display());
    }
    Ok(out)
}
