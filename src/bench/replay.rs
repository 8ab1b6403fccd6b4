//! `terrafuse bench replay`: the cost of replaying a long session and of saving and loading its
//! project file. A synthetic Moon project (procedural terrain, no store to import) with an edit
//! layer of N scripted strokes (every tool, [`super::scripted_strokes`]) and an erosion layer of
//! one run of S steps on 128² cells is saved, loaded and replayed on the CPU (and on the GPU
//! with `--gpu`, compared with the CPU); then a log of 10⁵ strokes is saved and loaded, with
//! the file's size and the process's peak memory.

use super::harness::{Table, timed};
use crate::cli::{CliError, Within};
use std::fmt::Write as _;
use std::path::PathBuf;

use crate::erosion::operation::Operation;
use crate::erosion::params::{Params, gravity_of_body};
use crate::gpu::GpuContext;
use crate::layers::{LayerSpec, NoiseSpec};
use crate::project::Project;
use crate::replay::{self, Engine};

/// What `terrafuse bench replay` measures.
#[derive(Clone, Debug)]
pub struct ReplayBenchSettings {
    /// Strokes of the edit layer.
    pub strokes: usize,
    /// Steps of the erosion run.
    pub steps: u64,
    /// Strokes of the log saved and loaded (10⁵ by default).
    pub log_strokes: usize,
    /// Replay on the GPU too.
    pub gpu: bool,
    /// The folder the project files and the table go to.
    pub out: PathBuf,
}

/// `n` strokes of a modelling session at level 12 (2.6 m samples on the Moon): every tool in
/// turn, radii of 150–400 m, paths of one to four points a few hundred metres long, scattered
/// over 0.4° × 0.4° around 0.5°N 45.2°E; deterministic.
pub fn session_strokes(n: usize) -> Vec<crate::edit::Stroke> {
    use crate::edit::{Falloff, Stroke, Tool};
    let mut state = 2_024u32;
    let mut next = || {
        state = crate::maths::pcg(state);
        f64::from(state) / f64::from(u32::MAX)
    };
    (0..n)
        .map(|k| {
            let tool = Tool::ALL[k % Tool::ALL.len()];
            let (lat, lon) = (0.3 + 0.4 * next(), 45.0 + 0.4 * next());
            let points = 1 + (next() * 3.0) as usize + usize::from(tool == Tool::Ramp);
            let path = (0..points).map(|p| [lat + 0.003 * p as f64 * next(), lon + 0.004 * p as f64]).collect();
            let strength = if tool.strength_in_metres() { 2.0 + 8.0 * next() } else { 0.3 + 0.5 * next() };
            Stroke {
                tool,
                radius_m: 150.0 + 250.0 * next(),
                strength,
                falloff: Falloff::ALL[k % Falloff::ALL.len()],
                spacing: 0.25,
                level: 12,
                path,
                seed: k as u32,
                height_m: None,
            }
        })
        .collect()
}

/// The synthetic session: Moon, fBm terrain, `strokes` strokes ([`session_strokes`]) and one
/// run of `steps` steps (the `rain` preset) on 128² cells of level 12 near 0.5°N 45.2°E.
pub fn synthetic_session(strokes: usize, steps: u64) -> Result<Project, CliError> {
    let mut p = Project::new("moon");
    let noise = NoiseSpec {
        noise_type: Default::default(),
        seed: 7,
        amplitude_m: 800.0,
        wavelength_m: 20_000.0,
        octaves: 4,
        lacunarity: 2.0,
        gain: 0.5,
        placement: Default::default(),
    };
    let mut base = LayerSpec::procedural("terrain", noise);
    base.blend = crate::layers::BlendMode::Over;
    p.layers.push(base);
    let mut edit = LayerSpec::edit("sculpt");
    for stroke in session_strokes(strokes) {
        edit.record_stroke(stroke)?;
    }
    p.layers.push(edit);
    let e = p.ellipsoid()?;
    // 128 cells of level 12 on the Moon (2.6 m) are 0.0110°: a box of that size at the centre.
    let side = 128.0 * crate::ecm::grid::spacing_m(&e, 12) / e.a_m();
    let (lat, lon) = (0.5, 45.2);
    let half = 0.5 * side.to_degrees();
    let params = Params::unscaled("rain", gravity_of_body(&p.body)).ok_or("no rain preset")?;
    let run = Operation {
        region: crate::geodesy::GeoBox::new(lon - half, lat - half, lon + half, lat + half)?,
        level: 12,
        steps,
        seed: 1,
        preset: Some("rain".into()),
        params,
        model: crate::erosion::operation::Model::Hydraulic,
        stream_power: None,
        brush: None,
        device: Default::default(),
    };
    let mut erosion = LayerSpec::erosion("erosion");
    erosion.record_run(run)?;
    p.layers.push(erosion);
    p.check()?;
    Ok(p)
}

/// Runs the benchmark; returns the table (also written to `out/replay-bench.md`), handing each
/// part to `progress` as it is measured (a long run shows where it is).
pub fn bench_replay(s: &ReplayBenchSettings, progress: &mut dyn FnMut(&str)) -> Result<String, CliError> {
    std::fs::create_dir_all(&s.out).map_err(CliError::file(&s.out, "cannot create"))?;
    let mut out = String::new();
    let p = synthetic_session(s.strokes, s.steps)?;
    let path = s.out.join("replay-bench.json");
    let (saved, save_s) = timed(|| p.save(&path));
    saved?;
    let (loaded, load_s) = timed(|| Project::load(&path));
    let loaded = loaded?;
    let bytes = std::fs::metadata(&path).map_or(0, |m| m.len());
    let _ = writeln!(
        out,
        "session: {} strokes (level 12, every tool, radii 150–400 m) and one erosion run of {} steps on 128² cells (level 12, rain), Moon, fBm terrain",
        s.strokes, s.steps
    );
    let _ =
        writeln!(out, "project file {:.1} MB: saved in {save_s:.3} s, loaded in {load_s:.3} s\n", bytes as f64 / 1e6);
    let mut table = Table::new(&["engine", "layer", "operations:", "tiles:", "seconds:", "GPU − CPU (m):"]);
    out += &table.markdown_header();
    progress(&out);
    // Each row shows as soon as it is measured.
    let mut add = |table: &mut Table, out: &mut String, row: Vec<String>| {
        table.row(row);
        let line = table.markdown_row(table.rows().len() - 1);
        progress(&line);
        *out += &line;
    };
    let cpu = replay::replay(&loaded, Engine::Cpu)?;
    for l in &cpu.layers {
        let row = vec!["cpu".into(), l.name.clone(), l.operations.to_string(), l.digests.tiles.len().to_string()];
        add(&mut table, &mut out, [row, vec![format!("{:.2}", l.seconds), String::new()]].concat());
    }
    if s.gpu {
        let ctx = GpuContext::headless().within("--gpu")?;
        let gpu = replay::replay(&loaded, Engine::Gpu(&ctx))?;
        for l in &gpu.layers {
            let uid = gpu.scene.stack.layers[l.index].uid;
            let difference = match (gpu.scene.edits.get(&uid), cpu.scene.edits.get(&uid)) {
                (Some(a), Some(b)) => format!("{:.2e}", replay::largest_difference_m(a, b)),
                _ => "-".into(),
            };
            let row = vec![
                format!("gpu ({})", ctx.info.name),
                l.name.clone(),
                l.operations.to_string(),
                l.digests.tiles.len().to_string(),
                format!("{:.2}", l.seconds),
                difference,
            ];
            add(&mut table, &mut out, row);
        }
    }
    // The long log: save and load only.
    let mut log = Project::new("moon");
    let mut edit = LayerSpec::edit("sculpt");
    for stroke in super::scripted_strokes(s.log_strokes, 9) {
        edit.record_stroke(stroke)?;
    }
    log.layers.push(edit);
    let log_path = s.out.join("log-bench.json");
    let (saved, save_s) = timed(|| log.save(&log_path));
    saved?;
    let before = crate::store::import::peak_rss_bytes();
    let (again, load_s) = timed(|| Project::load(&log_path));
    let again = again?;
    let peak = crate::store::import::peak_rss_bytes();
    if again.layers != log.layers {
        return Err("the log did not load back the same".into());
    }
    let bytes = std::fs::metadata(&log_path).map_or(0, |m| m.len());
    let _ = writeln!(
        out,
        "\nlog of {} strokes: {:.1} MB, saved (checked, serialised, written, fsynced) in {save_s:.3} s, loaded and checked in {load_s:.3} s; peak memory of the process {:.0} MB (before loading {:.0} MB)",
        s.log_strokes,
        bytes as f64 / 1e6,
        peak as f64 / 1e6,
        before as f64 / 1e6
    );
    progress(&out[out.rfind("\nlog of").unwrap_or(0)..]);
    let table = s.out.join("replay-bench.md");
    crate::files::write_atomic(&table, out.as_bytes()).map_err(CliError::file(table, "cannot write"))?;
    Ok(out)
}
