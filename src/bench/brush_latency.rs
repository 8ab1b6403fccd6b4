//! `terrafuse bench brush-latency`: a stroke's latency as the workstation has it, from the
//! pointer's release to the updated image read back: the stroke rasterised (the CPU reference),
//! the quads it changed recomposed and the frame drawn and read back, on the Moon sample session
//! seen from its `sculpt` view. One stroke of each tool in turn, each undone after it is timed
//! (so that every stroke starts from the same session); the undo's latency too.

use super::harness::timed_ms;
use crate::cli::CliError;
use crate::maths::median;
use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use crate::edit::{Falloff, Stroke, Tool};
use crate::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, Renderer};
use crate::project::Project;
use crate::scene::Scene;

/// Runs the benchmark on `project` (its edit layer `sculpt`, view `sculpt`); returns the report.
pub fn bench_brush_latency(project: &Path, rounds: usize, width: u32, height: u32) -> Result<String, CliError> {
    let p = Project::load(project)?;
    let camera = p.view(Some("sculpt"))?;
    let (scene, _) = Scene::open(&p)?;
    let ctx = GpuContext::headless()?;
    let mut r = Renderer::new(&ctx, scene, IMAGE_FORMAT)?;
    let editor = crate::gpu::Editor::new(&ctx)?;
    let index = r.scene().stack.index_of("sculpt").ok_or("the project has no edit layer 'sculpt'")?;
    let settle = |r: &mut Renderer| -> Result<(), CliError> {
        let stats = r.settle(&camera, width, height, Duration::from_secs(120));
        if stats.pending > 0 {
            return Err(format!("the view did not settle ({} quads pending)", stats.pending).into());
        }
        r.render_image(DrawMode::Colour)?;
        Ok(())
    };
    settle(&mut r)?;
    // The same frame with nothing changed: what drawing and reading back cost alone.
    let mut frame_ms = Vec::new();
    for _ in 0..3 {
        let (done, ms) = timed_ms(|| settle(&mut r));
        done?;
        frame_ms.push(ms);
    }
    frame_ms.sort_by(f64::total_cmp);
    let applied = p.layers[index].applied_strokes().len();
    let mut out = String::new();
    let _ = writeln!(
        out,
        "terrafuse bench brush-latency: {} ({width}×{height}, view sculpt), {rounds} strokes per tool; pointer release → image read back",
        ctx.describe()
    );
    let _ = writeln!(out, "a frame with nothing changed (draw and read back): {:.1} ms (median of 3)", frame_ms[1]);
    let _ =
        writeln!(out, "tool      rasterise ms   recompose+draw ms   total ms (median, max)   undo total ms (median)");
    for tool in Tool::ALL {
        let (mut raster, mut rest, mut total, mut undo) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for k in 0..rounds {
            // 8 km strokes over the ridge and the trench (level 4, as the session's).
            let lat = -4.0 + 5.0 * k as f64 / rounds.max(1) as f64;
            let stroke = Stroke {
                tool,
                radius_m: 8000.0,
                strength: if tool.strength_in_metres() { 150.0 } else { 0.6 },
                falloff: Falloff::Smooth,
                spacing: 0.25,
                level: 4,
                path: vec![[lat, 43.0], [lat + 0.5, 44.5]],
                seed: k as u32,
                height_m: None,
            };
            let (done, rasterised_ms) = timed_ms(|| editor.apply_stroke(&mut r, index, stroke));
            done?;
            let (done, rest_ms) = timed_ms(|| settle(&mut r));
            done?;
            raster.push(rasterised_ms);
            rest.push(rest_ms);
            total.push(rasterised_ms + rest_ms);
            let (done, undo_ms) = timed_ms(|| -> Result<(), CliError> {
                editor.set_applied(&mut r, index, applied)?;
                settle(&mut r)
            });
            done?;
            undo.push(undo_ms);
        }
        let max = total.iter().copied().fold(0.0, f64::max);
        let _ = writeln!(
            out,
            "{:<9} {:>12.1} {:>19.1} {:>12.1} {:>9.1} {:>16.1}",
            tool.name(),
            median(raster),
            median(rest),
            median(total.clone()),
            max,
            median(undo)
        );
    }
    Ok(out)
}
