//! `terrafuse erode --model stream-power`: the landscape-evolution flags checked into
//! [`LandscapeParams`] (a bad value refused by its flag), and the run's report.

use std::fmt::Write as _;
use std::path::Path;

use super::{CliError, ErodeRequest};
use crate::erosion::landscape::flow::Routing;
use crate::erosion::landscape::{LandscapeOutcome, LandscapeParams};
use crate::erosion::layer::Outcome;

/// The flag of a [`LandscapeParams`] field.
pub fn flag_of(field: &str) -> String {
    match field {
        "uplift_m_per_year" => "--uplift-m-per-year".into(),
        "kd_m2_per_year" => "--kd-m2-per-year".into(),
        "dt_years" => "--dt-years".into(),
        f => format!("--{f}"),
    }
}

/// The stream-power parameters the request asks for (None for a hydraulic run), checked.
pub fn params_of(request: &ErodeRequest) -> Result<Option<LandscapeParams>, CliError> {
    let given = [
        ("--years", request.years),
        ("--dt-years", request.dt_years),
        ("--uplift-m-per-year", request.uplift_m_per_year),
        ("--k", request.k),
        ("--m", request.m),
        ("--n", request.n),
        ("--kd-m2-per-year", request.kd_m2_per_year),
        ("--deposition", request.deposition),
    ];
    if request.model.as_deref() != Some("stream-power") {
        if let Some((flag, _)) = given.iter().find(|(_, v)| v.is_some()) {
            return Err(format!("{flag}: a stream-power flag; add --model stream-power").into());
        }
        if request.routing.is_some() {
            return Err("--routing: a stream-power flag; add --model stream-power".into());
        }
        return Ok(None);
    }
    if request.engine.gpu {
        return Err("--gpu: the stream-power model runs on the CPU reference".into());
    }
    if request.preset.is_some() || !request.set.is_empty() {
        return Err("--preset and --set are the hydraulic model's; a stream-power run takes --k, --m, --n, …".into());
    }
    let d = LandscapeParams::default();
    let params = LandscapeParams {
        uplift_m_per_year: request.uplift_m_per_year.unwrap_or(d.uplift_m_per_year),
        k: request.k.unwrap_or(d.k),
        m: request.m.unwrap_or(d.m),
        n: request.n.unwrap_or(d.n),
        kd_m2_per_year: request.kd_m2_per_year.unwrap_or(d.kd_m2_per_year),
        deposition: request.deposition.unwrap_or(d.deposition),
        routing: if request.routing.as_deref() == Some("mfd") { Routing::Mfd } else { Routing::D8 },
        years: request.years.unwrap_or(d.years),
        dt_years: request.dt_years.unwrap_or(d.dt_years),
    };
    params.check().map_err(|e| CliError::Usage(format!("{}: {}", flag_of(e.field), e.problem)))?;
    Ok(Some(params))
}

/// A finished stream-power run, for the report.
pub struct Report<'a> {
    /// The layer.
    pub layer: &'a str,
    /// The run's index in the layer.
    pub run: usize,
    /// What the layer recorded.
    pub outcome: &'a Outcome,
    /// The run's figures.
    pub figures: &'a LandscapeOutcome,
}

impl Report<'_> {
    /// The text report.
    pub fn text(&self, cached: Option<&Path>, path: &Path) -> String {
        let (o, f, r) = (self.outcome, self.figures, &self.outcome.region);
        let mut out = String::new();
        let _ = writeln!(
            out,
            "layer '{}': stream-power run {} on {} × {} cells at level {} ({} quads) on the CPU reference",
            self.layer,
            self.run,
            r.width,
            r.height,
            r.level,
            o.quads.len()
        );
        let _ = writeln!(
            out,
            "{} steps, {} years simulated, in {:.2} s; change of height {:.2} … {:.2} m",
            o.steps, f.simulated_years, o.seconds, o.range_m.0, o.range_m.1
        );
        let _ = writeln!(
            out,
            "budgets: uplifted {:.4e} m³, eroded {:.4e} m³, deposited {:.4e} m³, out through base level {:.4e} m³; unexplained {:.1e}",
            f.uplifted_m3, f.eroded_m3, f.deposited_m3, f.outflow_m3, f.unexplained_rel
        );
        if let Some(c) = cached {
            let _ = writeln!(out, "cached {}", c.display());
        }
        let _ = writeln!(out, "saved {}", path.display());
        out
    }

    /// The JSON report.
    pub fn json(&self, cached: Option<&Path>, path: &Path) -> String {
        let f = self.figures;
        let figures = serde_json::json!({
            "model": "stream-power",
            "simulated_years": f.simulated_years,
            "uplifted_m3": f.uplifted_m3,
            "eroded_m3": f.eroded_m3,
            "deposited_m3": f.deposited_m3,
            "outflow_m3": f.outflow_m3,
            "unexplained_rel": f.unexplained_rel,
        });
        super::erode_report::report_json(self.outcome, "CPU reference", cached, path, figures)
    }
}
