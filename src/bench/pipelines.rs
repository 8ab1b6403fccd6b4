//! The bias-correction pipelines and the uncertainty of `terrafuse bench compare`: each run as a
//! process of its own (Terrafuse's `coregister --pipeline` and `compare --uncertainty`, xDEM's
//! same workflow through `tests/reference/xdem_bench_pipeline.py`), so that each one's peak
//! resident memory is its own: read from `/proc/PID/status` (VmHWM) while each child runs (a
//! child's own `getrusage` would count the pages it shared with this process when forked). xDEM's
//! `seconds` are its script's own (reading the rasters and the workflow, not Python's start-up
//! and imports); `process s` is each whole process, start-up included, as a user waits for it.

use crate::cli::Context;
use std::fmt::Write as _;
use std::io::Read as _;
use std::path::Path;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use crate::cli::CliError;

/// The workflows: a label, Terrafuse's arguments after the project, xDEM's workflow name.
const WORKFLOWS: [(&str, &[&str], &str); 4] = [
    ("nuth_kaab", &["coregister", "blurred", "--to", "srtm", "--pipeline", "nuth_kaab", "--json"], "nuth_kaab"),
    (
        "nuth_kaab,deramp:1",
        &["coregister", "blurred", "--to", "srtm", "--pipeline", "nuth_kaab,deramp:1", "--json"],
        "nuth_kaab+deramp",
    ),
    (
        "nuth_kaab,terrain_bias:elevation",
        &["coregister", "blurred", "--to", "srtm", "--pipeline", "nuth_kaab,terrain_bias:elevation", "--json"],
        "nuth_kaab+terrain_bias",
    ),
    ("uncertainty of the mean dh", &["compare", "blurred", "srtm", "--uncertainty", "--json"], "uncertainty"),
];

/// Runs a command to its end; its standard output, seconds, and the last peak resident memory
/// read while it ran (bytes; 0 where /proc is not there).
pub(super) fn run_measured(mut command: Command) -> Result<(String, f64, u64), CliError> {
    let start = Instant::now();
    let mut child = command.stdout(Stdio::piped()).stderr(Stdio::piped()).spawn().map_err(|e| e.to_string())?;
    let status_path = format!("/proc/{}/status", child.id());
    let mut peak = 0u64;
    // Both pipes drained while it runs, so that a talkative child never blocks on a full one.
    let drain = |pipe: Option<Box<dyn std::io::Read + Send>>| {
        std::thread::spawn(move || {
            let mut text = String::new();
            if let Some(mut p) = pipe {
                let _ = p.read_to_string(&mut text);
            }
            text
        })
    };
    let stdout = drain(child.stdout.take().map(|p| Box::new(p) as Box<dyn std::io::Read + Send>));
    let stderr = drain(child.stderr.take().map(|p| Box::new(p) as Box<dyn std::io::Read + Send>));
    loop {
        if let Ok(status) = std::fs::read_to_string(&status_path) {
            let hwm = status.lines().find(|l| l.starts_with("VmHWM:"));
            if let Some(kb) = hwm.and_then(|l| l.split_whitespace().nth(1)?.parse::<u64>().ok()) {
                peak = peak.max(kb * 1024);
            }
        }
        if child.try_wait().map_err(|e| e.to_string())?.is_some() {
            break;
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let status = child.wait().map_err(|e| e.to_string())?;
    let (stdout, stderr) = (stdout.join().unwrap_or_default(), stderr.join().unwrap_or_default());
    if !status.success() {
        return Err(format!("{command:?}: {stderr}").into());
    }
    Ok((stdout, start.elapsed().as_secs_f64(), peak))
}

/// Where the workflows run: the Erzurum project, the Python with xDEM and the folder of its
/// scripts, and the pair warped for xDEM.
pub(super) struct PipelineBench<'a> {
    /// The Erzurum comparison project.
    pub project: &'a Path,
    /// `.venv-ref/bin/python`.
    pub python: &'a Path,
    /// `tests/reference`.
    pub reference_dir: &'a Path,
    /// The reference, warped to a transverse Mercator.
    pub reference_tm: &'a Path,
    /// The moved raster, warped the same way.
    pub moved_tm: &'a Path,
    /// The pair warped the same way at Terrafuse's sample spacing (metres, the last): as many
    /// samples for xDEM as Terrafuse reads.
    pub fine: (&'a Path, &'a Path, f64),
}

/// The table: each workflow by Terrafuse on the Erzurum project and by xDEM on its warped pair.
pub(super) fn pipelines_table(bench: &PipelineBench) -> Result<String, CliError> {
    let mut out = heading("workflow (Erzurum pair)");
    for workflow in WORKFLOWS {
        workflow_rows(&mut out, bench, workflow)?;
    }
    Ok(out)
}

/// Nuth & Kääb alone as a whole workflow (fit, apply, the NMAD after) by both tools on another
/// pair (the synthetic one: `ref` and `moved`).
pub(super) fn nuth_kaab_table(bench: &PipelineBench, pair: &str) -> Result<String, CliError> {
    let mut out = heading(&format!("workflow ({pair})"));
    let args: &[&str] = &["coregister", "moved", "--to", "ref", "--pipeline", "nuth_kaab", "--json"];
    workflow_rows(&mut out, bench, ("nuth_kaab", args, "nuth_kaab"))?;
    Ok(out)
}

fn heading(pair: &str) -> String {
    format!(
        "{pair:<34} {:<10} {:>9} {:>10} {:>10} {:>22}\n",
        "tool", "seconds", "process s", "peak MiB", "NMAD after / σ mean m"
    )
}

/// A workflow's rows: Terrafuse's on the project, xDEM's on the pair warped to 90 m and to
/// Terrafuse's sample spacing.
fn workflow_rows(
    out: &mut String,
    bench: &PipelineBench,
    (label, args, workflow): (&str, &[&str], &str),
) -> Result<(), CliError> {
    let exe = std::env::current_exe().context("this program's path")?;
    let mut command = Command::new(&exe);
    command.arg(args[0]).arg(bench.project).args(&args[1..]);
    let (json, seconds, peak) = run_measured(command)?;
    let v: serde_json::Value = serde_json::from_str(&json)?;
    let value = v["after"]["nmad_m"].as_f64().or_else(|| v["uncertainty"]["mean_dh_sigma_m"].as_f64());
    let _ = writeln!(
        out,
        "{label:<34} {:<10} {seconds:>9.2} {seconds:>10.2} {:>10.0} {:>22.4}",
        "Terrafuse",
        peak as f64 / 1048576.0,
        value.unwrap_or(f64::NAN)
    );
    let (fine_ref, fine_moved, fine_m) = bench.fine;
    for (tool, reference, moved) in [
        ("xDEM 90 m".to_string(), bench.reference_tm, bench.moved_tm),
        (format!("xDEM {fine_m:.0} m"), fine_ref, fine_moved),
    ] {
        let mut python = Command::new(bench.python);
        let script = bench.reference_dir.join("xdem_bench_pipeline.py");
        python.arg(script).arg(reference).arg(moved).arg(workflow);
        match run_measured(python) {
            Ok((json, process, peak)) => {
                let x: serde_json::Value = serde_json::from_str(&json)?;
                let value = x["nmad_after_m"].as_f64().or_else(|| x["sigma_mean_m"].as_f64());
                let _ = writeln!(
                    out,
                    "{:<34} {tool:<10} {:>9.2} {process:>10.2} {:>10.0} {:>22.4}",
                    "",
                    x["seconds"].as_f64().unwrap_or(f64::NAN),
                    peak as f64 / 1048576.0,
                    value.unwrap_or(f64::NAN)
                );
            }
            Err(e) => {
                // A Python traceback's last line says what failed.
                let error = crate::errors::chain(&e);
                let last = error.lines().rev().find(|l| !l.trim().is_empty()).unwrap_or_default().trim();
                let _ = writeln!(out, "{:<34} {tool:<10} failed: {last}", "");
            }
        }
    }
    Ok(())
}
