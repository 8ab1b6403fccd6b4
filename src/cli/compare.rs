//! `terrafuse compare PROJECT A B`: the statistics of A − B over their overlap (see
//! [`crate::compare`]), as a table for people or JSON with stable field names for scripts, and
//! optionally every sample as CSV.

use super::{CliError, Feedback, WaitArgs, Within};
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::compare::pipeline::{Attribute, Correction, step_name};
use crate::compare::{
    CompareOptions, Comparison, CoregOptions, Coregistration, Stable, Step, Weighting, compare, coregister,
};
use crate::compare::{Uncertainty, UncertaintyOptions, uncertainty};
use crate::geodesy::GeoBox;
use crate::layers::correction::Bias;
use crate::project::Project;

/// What `terrafuse compare` was asked.
#[derive(clap::Args, Clone, Debug)]
pub struct CompareRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// Layer A.
    pub a: String,
    /// Layer B, the reference.
    pub b: String,
    /// Level to compare at (default: the coarser dataset's finest, or finer where strokes, erosion runs or noise on either side add detail below it, stepped back past 4096 quads; a level given is read whatever its size, in bounded memory).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Only inside WEST,SOUTH,EAST,NORTH (degrees; east < west crosses ±180°).
    #[arg(long, allow_hyphen_values = true)]
    pub region: Option<String>,
    /// Count every sample once (as xDEM and demcompare count pixels) instead of weighting by area.
    #[arg(long)]
    pub unweighted: bool,
    /// Print JSON (stable field names: count, nodata_count, mean_m, median_m, std_m, rmse_m,
    /// nmad_m, min_m, max_m, le90_m, p90_abs_m, histogram, by_slope).
    #[arg(long)]
    pub json: bool,
    /// The slope classes of B (always reported, `by_slope` in the JSON): their edges in degrees,
    /// increasing within 0–90 (default 0,5,10,20,30,45,90); `--by-slope` alone keeps the default.
    #[arg(long, value_name = "EDGES", num_args = 0..=1, default_missing_value = "")]
    pub by_slope: Option<String>,
    /// Also write every sample (lon_deg, lat_deg, dh_m, area_m2, slope_deg) as CSV.
    #[arg(long)]
    pub samples: Option<PathBuf>,
    /// Also propagate the errors (Hugonnet et al. 2022): the mean dh and the volume change over
    /// the area with their 1σ, the binned error and the variogram (`uncertainty` in the JSON).
    #[arg(long)]
    pub uncertainty: bool,
    /// With --uncertainty: the area of the mean and volume, a layer (where it has data) or a
    /// vector file of polygons (inside them); default: every sample with data.
    #[arg(long, requires = "uncertainty")]
    pub area: Option<String>,
    /// With --uncertainty: fit the error model on stable terrain only, a layer (where it has
    /// data) or a vector file of unstable terrain (polygons left out).
    #[arg(long, requires = "uncertainty")]
    pub stable: Option<String>,
    /// Most differences held in memory; a comparison that may have more writes them to a scratch
    /// file in the temporary folder and reads them back in passes, in bounded memory.
    #[arg(long, default_value_t = crate::compare::sample::MEMORY_SAMPLES, allow_negative_numbers = true)]
    pub memory_samples: usize,
    /// Compute nothing: check the project and arguments, cut the quads into --shards runs along
    /// a Hilbert curve and write this plan (then `terrafuse shard PLAN I` for each shard and
    /// `terrafuse merge PLAN`, or `terrafuse shards run PLAN`).
    #[arg(long, value_name = "PLAN.json", requires = "shards", conflicts_with_all = ["uncertainty", "samples"])]
    pub plan: Option<PathBuf>,
    /// With --plan: the number of shards.
    #[arg(long, requires = "plan", allow_negative_numbers = true)]
    pub shards: Option<usize>,
    /// With --plan: the folder of the shards' parts (default: PLAN.parts beside the plan).
    #[arg(long, requires = "plan")]
    pub parts: Option<PathBuf>,
}

/// Parses `--by-slope EDGES`: the slope classes' edges, degrees (none or empty: the default).
fn parse_slope_classes(edges: Option<&str>) -> Result<Vec<f64>, CliError> {
    let text = edges.unwrap_or("").trim();
    if text.is_empty() {
        return Ok(crate::compare::stats::SLOPE_CLASSES_DEG.to_vec());
    }
    let bad = |problem: &str| CliError::Usage(format!("--by-slope {text}: {problem}"));
    let edges: Vec<f64> = text
        .split(',')
        .map(|v| v.trim().parse::<f64>().map_err(|_| bad(&format!("'{}' is not a slope in degrees", v.trim()))))
        .collect::<Result<_, _>>()?;
    if edges.len() < 2 || edges.windows(2).any(|w| w[0] >= w[1]) || edges[0] < 0.0 || edges[edges.len() - 1] > 90.0 {
        return Err(bad("give two or more increasing edges within 0–90 degrees, e.g. 0,10,30,90"));
    }
    Ok(edges)
}

/// Parses `--region WEST,SOUTH,EAST,NORTH`.
fn parse_region(region: Option<&str>) -> Result<Option<GeoBox>, CliError> {
    region.map(super::geo::parse_box).transpose()
}

/// Runs the comparison; returns what to print.
pub fn compare_command(request: &CompareRequest, fb: &mut Feedback) -> Result<String, CliError> {
    let region = parse_region(request.region.as_deref())?;
    let slope_classes_deg = parse_slope_classes(request.by_slope.as_deref())?;
    if let (Some(plan), Some(shards)) = (&request.plan, request.shards) {
        let opts = CompareOptions {
            level: request.level,
            region,
            weighting: if request.unweighted { Weighting::Samples } else { Weighting::Area },
            slope_classes_deg,
            ..CompareOptions::default()
        };
        let made = crate::compare::sharded::plan(
            &request.project,
            [&request.a, &request.b],
            &opts,
            request.json,
            shards,
            plan,
            request.parts.as_deref(),
        )
        .within(request.project.display())?;
        let quads: usize = made.shards.iter().map(Vec::len).sum();
        return Ok(format!(
            "planned {} − {} at level {}: {quads} quads in {shards} shards along a Hilbert curve → {} (parts in {})\n{}",
            made.a,
            made.b,
            made.level,
            plan.display(),
            made.parts.display(),
            super::plans::next_steps(plan, shards)
        ));
    }
    let project = Project::load(&request.project)?;
    // The uncertainty first: it holds its samples and may refuse a level the statistics take.
    let uncertainty = if request.uncertainty {
        let names: Vec<&str> = project.layers.iter().map(|l| l.name.as_str()).collect();
        let opts = UncertaintyOptions {
            level: request.level,
            region,
            stable: request.stable.as_deref().map(|s| Stable::parse(&names, s)),
            area: request.area.as_deref().map(|s| Stable::parse(&names, s)),
            keep_samples: false,
            fit_quads: None,
            watch: Some(fb.watch.clone()),
        };
        Some(uncertainty(&project, &request.a, &request.b, &opts).within(request.project.display())?)
    } else {
        None
    };
    let opts = CompareOptions {
        level: request.level.or(uncertainty.as_ref().map(|u| u.level)),
        region,
        weighting: if request.unweighted { Weighting::Samples } else { Weighting::Area },
        keep_samples: request.samples.is_some(),
        memory_samples: request.memory_samples,
        scratch: Some(std::env::temp_dir()),
        watch: Some(fb.watch.clone()),
        slope_classes_deg,
    };
    let started = std::time::Instant::now();
    let c = compare(&project, &request.a, &request.b, &opts).within(request.project.display())?;
    let seconds = started.elapsed().as_secs_f64();
    let samples = c.stats.count + c.stats.nodata_count;
    (fb.note)(&format!(
        "terrafuse: compared {samples} samples at level {} in {seconds:.1} s ({:.0} ns a sample)",
        c.level,
        seconds * 1e9 / samples.max(1) as f64
    ));
    if let Some(path) = &request.samples {
        let mut csv = String::from("lon_deg,lat_deg,dh_m,area_m2,slope_deg\n");
        for s in &c.samples {
            let _ = writeln!(csv, "{:.8},{:.8},{},{},{}", s.lon_deg, s.lat_deg, s.dh_m, s.area_m2, s.slope_deg);
        }
        crate::files::write_atomic(path, csv.as_bytes()).map_err(CliError::file(path, "cannot write"))?;
    }
    if request.json {
        let mut json = serde_json::to_value(&c)?;
        if let (Some(u), Some(object)) = (&uncertainty, json.as_object_mut()) {
            object.insert("uncertainty".into(), serde_json::to_value(u)?);
        }
        return Ok(serde_json::to_string_pretty(&json)? + "\n");
    }
    Ok(table(&c) + &uncertainty.map(|u| uncertainty_table(&u)).unwrap_or_default())
}

/// The uncertainty as text: the mean and volume with their 1σ, the model and the variogram.
pub fn uncertainty_table(u: &Uncertainty) -> String {
    let mut out = String::new();
    let area = u.area.as_deref().unwrap_or("every sample with data");
    let _ = writeln!(out, "uncertainty over {area} ({:.3} km²):", u.area_m2 / 1e6);
    let _ = writeln!(
        out,
        "  mean dh {:+.3} ± {:.3} m (1σ), volume change {:+.4e} ± {:.4e} m³ (1σ)",
        u.mean_dh_m, u.mean_dh_sigma_m, u.volume_m3, u.volume_sigma_m3
    );
    let h = &u.heteroscedasticity;
    let _ = writeln!(
        out,
        "  error model: σ = {:.3} × √({:.3}² + ({:.3} tan slope)² + ({:.3} curvature)²) m; mean σ {:.3} m over the area",
        h.scale, h.base_m, h.slope_m, h.curvature_m, u.mean_error_m
    );
    let models: Vec<String> =
        u.variogram.models.iter().map(|m| format!("range {:.0} m sill {:.3}", m.range_m, m.psill)).collect();
    let _ = writeln!(
        out,
        "  spatial correlation: {} ({} effective samples); fitted on {} stable samples{}{}",
        models.join(" + "),
        u.effective_samples.round(),
        u.stable_count,
        u.stable.as_deref().map(|s| format!(", {s}")).unwrap_or_default(),
        if u.fit_quad_count < u.quad_count {
            format!(" of {} quads in {} (the mean and volume over all)", u.fit_quad_count, u.quad_count)
        } else {
            String::new()
        }
    );
    let _ = writeln!(out, "  NMAD of dh (m) by slope (rows, degrees) and maximal curvature (columns, 100/m):");
    let edges = |e: &[f64], k: usize| format!("{:.2}–{:.2}", e[k], e[k + 1]);
    let _ = write!(out, "{:>14}", "");
    for j in 0..h.max_curvature_edges.len() - 1 {
        let _ = write!(out, "{:>12}", edges(&h.max_curvature_edges, j));
    }
    let _ = writeln!(out);
    for (i, row) in h.nmad_m.iter().enumerate() {
        let _ = write!(out, "{:>14}", edges(&h.slope_edges_deg, i));
        for v in row {
            let _ = write!(out, "{:>12}", v.map_or("–".to_string(), |v| format!("{v:.3}")));
        }
        let _ = writeln!(out);
    }
    out
}

/// The statistics as a table.
pub fn table(c: &Comparison) -> String {
    let s = &c.stats;
    let mut out = String::new();
    let weighting = match c.weighting {
        Weighting::Area => format!(
            "weighted by cell area on the ellipsoid ({:.1} km², largest/smallest cell {:.6})",
            c.area_km2, c.weight_ratio
        ),
        Weighting::Samples => "every sample counted once".to_string(),
    };
    let _ = writeln!(out, "{} − {} at level {} ({:.1} m samples), {weighting}", c.a, c.b, c.level, c.spacing_m);
    let _ = writeln!(out, "samples: {} compared, {} without data on a side", s.count, s.nodata_count);
    let _ = writeln!(
        out,
        "mean {:.3} m  median {:.3} m  std {:.3} m  RMSE {:.3} m  NMAD {:.3} m",
        s.mean_m, s.median_m, s.std_m, s.rmse_m, s.nmad_m
    );
    let _ = writeln!(
        out,
        "min {:.3} m  max {:.3} m  LE90 {:.3} m  90th percentile of |dh| {:.3} m",
        s.min_m, s.max_m, s.le90_m, s.p90_abs_m
    );
    let _ = writeln!(
        out,
        "{:>12} {:>10} {:>10} {:>10} {:>10} {:>10}",
        "slope of B", "samples", "mean m", "median m", "NMAD m", "RMSE m"
    );
    for k in &c.by_slope {
        let _ = writeln!(
            out,
            "{:>12} {:>10} {:>10.3} {:>10.3} {:>10.3} {:>10.3}",
            format!("{}–{}°", k.min_deg, k.max_deg),
            k.stats.count,
            k.stats.mean_m,
            k.stats.median_m,
            k.stats.nmad_m,
            k.stats.rmse_m
        );
    }
    let h = &c.histogram;
    if let (Some(lo), Some(hi)) = (h.edges_m.first(), h.edges_m.last()) {
        let peak = h.count.iter().copied().max().unwrap_or(1).max(1);
        let _ = writeln!(out, "histogram of dh, {lo:.2} … {hi:.2} m ({} bins):", h.count.len());
        for (k, n) in h.count.iter().enumerate().step_by(2) {
            let n2 = n + h.count.get(k + 1).copied().unwrap_or(0);
            let bar = "#".repeat(((n2 as f64 / (2 * peak) as f64) * 60.0).round() as usize);
            let _ = writeln!(out, "{:>9.2} m {bar}", h.edges_m[k]);
        }
    }
    out
}

/// What `terrafuse coregister` was asked.
#[derive(clap::Args, Clone, Debug)]
pub struct CoregRequest {
    /// The project file (JSON).
    pub project: PathBuf,
    /// The layer to move.
    pub a: String,
    /// The reference layer.
    #[arg(long = "to")]
    pub b: String,
    /// Level to work at (default: the coarser dataset's finest, the data's own; A is read
    /// between its samples by bicubic interpolation).
    #[arg(long, allow_negative_numbers = true)]
    pub level: Option<u8>,
    /// Only inside WEST,SOUTH,EAST,NORTH (degrees).
    #[arg(long, allow_hyphen_values = true)]
    pub region: Option<String>,
    /// The bias corrections, in order: nuth_kaab, vertical, deramp:ORDER (1–3),
    /// terrain_bias:elevation|max_curvature|slope, directional:AZIMUTH (degrees from north).
    #[arg(long, default_value = "nuth_kaab")]
    pub pipeline: String,
    /// Fit on stable terrain only: a layer (where it has data) or a vector file of unstable
    /// terrain (polygons left out, e.g. glacier outlines).
    #[arg(long)]
    pub stable: Option<String>,
    /// Write the result into the project: the shift and raise into A's shift_m and offset_m,
    /// the deramp, terrain and directional biases after its correction.
    #[arg(long)]
    pub apply: bool,
    /// Print JSON (east_m, north_m, up_m, iterations, steps, before, after).
    #[arg(long)]
    pub json: bool,
    /// With --apply: how long to wait for another process changing the project.
    #[command(flatten)]
    pub wait: WaitArgs,
}

/// Runs the co-registration (and applies it); returns what to print. With `--apply` the project
/// is held (locked) from before it is read until the corrected layer is saved.
pub fn coregister_command(request: &CoregRequest, fb: &mut Feedback) -> Result<String, CliError> {
    let region = parse_region(request.region.as_deref())?;
    let (mut project, held) = if request.apply {
        let (project, held) =
            super::feedback::change(&request.project, "terrafuse coregister --apply", &request.wait, fb)?;
        (project, Some(held))
    } else {
        (Project::load(&request.project)?, None)
    };
    let pipeline = Step::parse_list(&request.pipeline)?;
    if request.apply
        && let Some(step) = pipeline.iter().find(|s| matches!(s, Step::TerrainBias(a) if *a != Attribute::Elevation))
    {
        return Err(CliError::from(format!(
            "--apply: {} cannot be stored in a layer: a layer's terrain bias reads only its own elevation \
             (slope and curvature need the neighbouring samples, which composition does not read)",
            step_name(step)
        )));
    }
    let names: Vec<&str> = project.layers.iter().map(|l| l.name.as_str()).collect();
    let stable = request.stable.as_deref().map(|s| Stable::parse(&names, s));
    let opts = CoregOptions {
        level: request.level,
        region,
        pipeline,
        stable,
        scratch: Some(std::env::temp_dir()),
        watch: Some(fb.watch.clone()),
        ..CoregOptions::default()
    };
    let c = coregister(&project, &request.a, &request.b, &opts).within(request.project.display())?;
    if request.apply {
        let layer = project.layers.iter_mut().find(|l| l.name == request.a).ok_or("the layer vanished")?;
        c.apply_to(layer)?;
        held.as_ref().ok_or("the project is not held")?.save(&project)?;
    }
    if request.json {
        return Ok(serde_json::to_string_pretty(&c)? + "\n");
    }
    Ok(coreg_table(&c, request.apply))
}

/// A correction in a line.
fn describe(c: &Correction) -> String {
    match c {
        Correction::NuthKaab { east_m, north_m, up_m } => {
            format!("move east {east_m:+.3} m, north {north_m:+.3} m, up {up_m:+.3} m")
        }
        Correction::Vertical { up_m } => format!("raise {up_m:+.3} m"),
        Correction::Bias(Bias::Deramp { order, coefficients, origin_deg, .. }) => format!(
            "order {order} about {:.4}°E {:.4}°N, coefficients (m/km^k) {}",
            origin_deg[0],
            origin_deg[1],
            coefficients.iter().map(|c| format!("{c:+.4}")).collect::<Vec<_>>().join(" ")
        ),
        Correction::Bias(Bias::TerrainBias { attribute, bins }) => {
            let range =
                bins.iter().map(|b| b[1]).fold((f64::INFINITY, f64::NEG_INFINITY), |r, v| (r.0.min(v), r.1.max(v)));
            format!("{} bins of {}, bias {:+.3} … {:+.3} m", bins.len(), attribute.name(), range.0, range.1)
        }
        Correction::Bias(Bias::Directional { azimuth_deg, offset_m, sinusoids, .. }) => format!(
            "along {azimuth_deg}°: offset {offset_m:+.3} m{}",
            sinusoids
                .iter()
                .map(|s| format!(", {:.3} m at {:.0} m wavelength", s.amplitude_m, s.wavelength_m))
                .collect::<String>()
        ),
    }
}

fn coreg_table(c: &Coregistration, applied: bool) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{} onto {} at level {} ({:.1} m samples), pipeline {}:",
        c.a,
        c.b,
        c.level,
        c.spacing_m,
        c.pipeline.join(",")
    );
    if let Some(stable) = &c.stable {
        let _ = writeln!(out, "stable terrain: {stable}, {} samples", c.stable_count);
    }
    for (name, step) in c.pipeline.iter().zip(&c.steps) {
        let _ = writeln!(out, "  {name}: {}", describe(&step.correction));
        for (k, [e, n, bias]) in step.moves.iter().flatten().enumerate() {
            let _ = writeln!(
                out,
                "    iteration {:>2}: step east {e:+.3} m, north {n:+.3} m (vertical bias {bias:+.3} m)",
                k + 1
            );
        }
        let _ = writeln!(
            out,
            "    stable terrain: NMAD {:.3} → {:.3} m, median {:+.3} → {:+.3} m",
            step.before.nmad_m, step.after.nmad_m, step.before.median_m, step.after.median_m
        );
    }
    let state = match (c.iterations, c.converged) {
        (0, _) => String::new(),
        (n, true) => format!(" (converged, {n} iterations)"),
        (n, false) => format!(" (NOT converged: the last step was over the tolerance; {n} iterations)"),
    };
    let _ =
        writeln!(out, "move {} east {:+.3} m, north {:+.3} m, up {:+.3} m{state}", c.a, c.east_m, c.north_m, c.up_m);
    for (name, s) in [("before", &c.before), ("after", &c.after)] {
        let _ = writeln!(
            out,
            "{name:>6}: {} samples, mean {:+.3} m, median {:+.3} m, std {:.3} m, NMAD {:.3} m, RMSE {:.3} m",
            s.count, s.mean_m, s.median_m, s.std_m, s.nmad_m, s.rmse_m
        );
    }
    if applied {
        let biases: Vec<String> = c.biases().iter().map(|b| b.step_name()).collect();
        let corrected =
            if biases.is_empty() { String::new() } else { format!(", {} added to its correction", biases.join(", ")) };
        let _ = writeln!(out, "applied: {}'s shift_m and offset_m updated in the project{corrected}", c.a);
    }
    out
}
