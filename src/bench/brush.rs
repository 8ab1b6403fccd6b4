//! `terrafuse bench brush`: the time to rebuild an edit layer from N strokes on the CPU (the
//! reference replay checks against), and the time of one more stroke and of undoing it, on a
//! scripted session of every rasterised tool scattered over a 4° patch of the Moon across the
//! front/right face edge. Deterministic: the strokes come from a fixed PCG sequence.

use super::harness::{timed, timed_ms};
use crate::cli::CliError;
use std::fmt::Write as _;

use crate::ecm::QuadId;
use crate::ecm::grid::GRID;
use crate::ecm::points::sample_point;
use crate::edit::{EditRaster, Falloff, Stroke, Tool};
use crate::geodesy::Ellipsoid;
use crate::maths::pcg;

/// The session: `n` strokes of 1–4 points, radius 2–8 km, at `level`.
pub fn scripted_strokes(n: usize, level: u8) -> Vec<Stroke> {
    let mut state = 12_345u32;
    let mut next = || {
        state = pcg(state);
        f64::from(state) / f64::from(u32::MAX)
    };
    (0..n)
        .map(|k| {
            let tool = Tool::ALL[k % Tool::ALL.len()];
            let (lat, lon) = (-2.0 + 4.0 * next(), 43.0 + 4.0 * next());
            // A ramp runs between two points at least.
            let points = 1 + (next() * 4.0) as usize + usize::from(tool == Tool::Ramp);
            let path = (0..points).map(|p| [lat + 0.05 * p as f64 * next(), lon + 0.05 * p as f64]).collect();
            let strength = if tool.strength_in_metres() { 5.0 + 20.0 * next() } else { 0.3 };
            Stroke {
                tool,
                radius_m: 2000.0 + 6000.0 * next(),
                strength,
                falloff: Falloff::ALL[k % 4],
                spacing: 0.25,
                level,
                path,
                seed: k as u32,
                height_m: None,
            }
        })
        .collect()
}

/// The terrain under the scripted session's edit layer: waves of 300 m over 5 km (a function of
/// the position, so that smooth, flatten and ramp have something to read).
fn waves_below(q: QuadId) -> Result<Vec<f32>, crate::errors::Failure> {
    let e = Ellipsoid::MOON;
    Ok((0..GRID * GRID)
        .map(|k| {
            let p = sample_point(&e, q, GRID, k % GRID, k / GRID).0;
            (300.0 * (p.x / 800.0).sin() * (p.z / 800.0).cos()) as f32
        })
        .collect())
}

/// Runs the benchmark (`gpu`: the rebuild on the GPU rasteriser as well); returns the report.
pub fn bench_brush(strokes: usize, level: u8, gpu: bool) -> Result<String, CliError> {
    let e = Ellipsoid::MOON;
    let session = scripted_strokes(strokes, level);
    let (raster, build_s) = timed(|| EditRaster::build(e, &session, &waves_below));
    let mut raster = raster?;
    let extra = scripted_strokes(strokes + 1, level).pop().ok_or("no stroke")?;
    let (touched, stroke_ms) = timed_ms(|| raster.apply(strokes, &extra, &waves_below));
    let touched = touched?;
    let mut all = session.clone();
    all.push(extra);
    let mut without_history = raster.clone();
    without_history.clear_history();
    let (done, undo_ms) = timed_ms(|| raster.undo_to(&all, strokes, &waves_below));
    done?;
    let (done, recompute_ms) = timed_ms(|| without_history.undo_to(&all, strokes, &waves_below));
    done?;
    if without_history != raster {
        return Err("the two undo paths disagree".into());
    }
    let mut out = String::new();
    let _ = writeln!(
        out,
        "terrafuse bench brush: {strokes} strokes (every tool in turn; radius 2–8 km) at level {level} on the Moon, CPU ({} threads)",
        rayon::current_num_threads()
    );
    let _ = writeln!(out, "rebuild from the strokes: {build_s:.2} s ({} tiles)", raster.tiles.len());
    let _ = writeln!(
        out,
        "one more stroke: {stroke_ms:.1} ms ({} quads); its undo: {undo_ms:.2} ms from the history, {recompute_ms:.0} ms recomputed (same tiles)",
        touched.len()
    );
    if gpu {
        let ctx = crate::gpu::GpuContext::headless()?;
        let kernel = crate::gpu::brush::StrokeKernel::new(&ctx.device)?;
        let rasteriser = kernel.on_context(&ctx);
        let (on_gpu, gpu_s) = timed(|| -> Result<EditRaster, CliError> {
            let mut on_gpu = EditRaster::new(e, level);
            for (k, stroke) in session.iter().enumerate() {
                on_gpu.apply_with(k, stroke, &waves_below, &rasteriser)?;
            }
            Ok(on_gpu)
        });
        let on_gpu = on_gpu?;
        let mut worst = 0f64;
        for (q, tile) in &raster.tiles {
            let other = on_gpu.tile(*q).ok_or_else(|| format!("{q}: on the CPU, not on the GPU"))?;
            worst = tile.iter().zip(other).fold(worst, |w, (a, b)| w.max(f64::from(a - b).abs()));
        }
        let _ = writeln!(
            out,
            "rebuild on the GPU ({}): {gpu_s:.2} s, largest |GPU − CPU| over the layer {worst:.2e} m",
            ctx.describe()
        );
    }
    Ok(out)
}
