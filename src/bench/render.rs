//! `terrafuse bench render`: frame time against error, over the pixel error τ that selects the
//! geometry (and the level-of-detail threshold t that selects the data).
//!
//! For each project and each of its views (the camera path), the finest rendering (the smallest
//! t, every patch of a drawn quad at stride 1: the finest mesh) is the reference; every setting is
//! rendered to the same pixels and compared with it: height difference at each pixel (metres),
//! the difference of the rendered surface positions seen from the camera (pixels), and the share
//! of terrain pixels whose colour is the reference's within 2/255, over the pixels both draw
//! terrain in. Each t is drawn with its quads whole (`whole`) and, for each τ, with patches culled
//! and drawn at the stride their error allows (`adaptive`).

use super::harness::timed_ms;
use crate::cli::CliError;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::cli::open_renderer;
use crate::gpu::{DrawMode, RenderedImage};

/// Settings of the benchmark.
#[derive(Clone, Debug)]
pub struct RenderBenchSettings {
    /// Project files.
    pub projects: Vec<PathBuf>,
    /// Thresholds, pixels per sample.
    pub thresholds: Vec<f64>,
    /// Pixel errors τ for the adaptive rows, pixels.
    pub pixel_errors: Vec<f64>,
    /// Image size.
    pub width: u32,
    /// Image size.
    pub height: u32,
    /// Timed frames per camera and threshold.
    pub frames: usize,
    /// Folder for the CSV and the plot.
    pub out: PathBuf,
}

/// One measurement.
#[derive(Clone, Debug)]
pub struct RenderBenchRow {
    /// Project file name.
    pub project: String,
    /// View name.
    pub view: String,
    /// `whole` (every patch of a drawn quad at stride 1) or `adaptive` (culled, strided).
    pub patches: &'static str,
    /// Threshold.
    pub threshold: f64,
    /// The pixel error τ (NaN for whole quads).
    pub pixel_error: f64,
    /// The largest projected geometric error drawn, pixels, as the renderer computed it.
    pub max_error_px: f64,
    /// Share of terrain pixels (in both) whose colour is the reference's within 2/255.
    pub same_colour: f64,
    /// Quads and triangles drawn.
    pub quads: usize,
    /// Triangles.
    pub triangles: u64,
    /// Pixels that show terrain.
    pub terrain_pixels: usize,
    /// Deepest level drawn.
    pub max_level: u8,
    /// CPU frame preparation (selection, per-quad values), ms, mean over frames.
    pub cpu_ms: f64,
    /// Of which selection, ms.
    pub select_ms: f64,
    /// GPU terrain pass, ms, mean over frames (NaN without timestamps).
    pub gpu_ms: f64,
    /// Wall time of a whole frame (prepare, draw, read back), ms, mean.
    pub wall_ms: f64,
    /// Height error against the finest rendering, metres: mean, max.
    pub height_error_m: (f64, f64),
    /// Surface position error seen from the camera, pixels: mean, max.
    pub position_error_px: (f64, f64),
    /// Share of pixels where one draws terrain and the other sky.
    pub coverage_mismatch: f64,
}

/// The errors of `image` against `reference`: height (mean, max), position seen from the eye
/// (mean, max), the share of pixels where one is terrain and the other sky, and the share of
/// terrain pixels whose colour is within 2/255.
type Errors = ((f64, f64), (f64, f64), f64, f64);

fn compare(reference: &RenderedImage, image: &RenderedImage, focal_px: f64) -> Errors {
    let (rs, ri) = (reference.surface.as_ref().unwrap(), reference.ids.as_ref().unwrap());
    let (s, i) = (image.surface.as_ref().unwrap(), image.ids.as_ref().unwrap());
    let (mut n, mut mismatch, mut terrain, mut same) = (0usize, 0usize, 0usize, 0usize);
    let (mut h_sum, mut h_max, mut p_sum, mut p_max) = (0f64, 0f64, 0f64, 0f64);
    for k in 0..rs.len() {
        let (a, b) = (ri[k][0] > 0, i[k][0] > 0);
        if a != b {
            mismatch += 1;
            continue;
        }
        if a {
            terrain += 1;
            let d = (0..3).map(|c| reference.rgba[4 * k + c].abs_diff(image.rgba[4 * k + c])).max().unwrap_or(0);
            same += usize::from(d <= 2);
        }
        // Both terrain, both with data.
        if !a || ri[k][3] & 1 == 0 || i[k][3] & 1 == 0 {
            continue;
        }
        let dh = f64::from((s[k][3] - rs[k][3]).abs());
        let p = glam::DVec3::new(f64::from(s[k][0]), f64::from(s[k][1]), f64::from(s[k][2]));
        let q = glam::DVec3::new(f64::from(rs[k][0]), f64::from(rs[k][1]), f64::from(rs[k][2]));
        // The difference as an angle from the eye, in pixels.
        let dp = (p - q).length() / q.length().max(1e-9) * focal_px;
        h_sum += dh;
        h_max = h_max.max(dh);
        p_sum += dp;
        p_max = p_max.max(dp);
        n += 1;
    }
    let n = n.max(1) as f64;
    let same = same as f64 / terrain.max(1) as f64;
    ((h_sum / n, h_max), (p_sum / n, p_max), mismatch as f64 / rs.len() as f64, same)
}

/// Runs the benchmark; returns the rows and a report (device, table).
pub fn bench_render(settings: &RenderBenchSettings) -> Result<(Vec<RenderBenchRow>, String), CliError> {
    let mut rows = Vec::new();
    let mut report = String::new();
    let finest = settings.thresholds.iter().copied().fold(f64::INFINITY, f64::min);
    for project_path in &settings.projects {
        let (project, mut renderer, lines) = open_renderer(project_path)?;
        for l in lines {
            let _ = writeln!(report, "{}: {l}", project_path.display());
        }
        let name = project_path.file_stem().map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        for (view, camera) in &project.views {
            renderer.set_threshold(finest);
            renderer.set_adaptive_patches(false);
            renderer.settle(camera, settings.width, settings.height, Duration::from_secs(600));
            let reference = renderer.render_image(DrawMode::Probe)?;
            let focal = renderer.last_camera().map_or(1.0, |c| c.focal_px(settings.height));
            let settings_of =
                |t: f64| std::iter::once((t, None)).chain(settings.pixel_errors.iter().map(move |&e| (t, Some(e))));
            for (t, pixel_error) in settings.thresholds.iter().flat_map(|&t| settings_of(t)) {
                let adaptive = pixel_error.is_some();
                renderer.set_threshold(t);
                renderer.set_adaptive_patches(adaptive);
                if let Some(e) = pixel_error {
                    renderer.set_pixel_error(e);
                }
                let settled = renderer.settle(camera, settings.width, settings.height, Duration::from_secs(600));
                let probe = renderer.render_image(DrawMode::Probe)?;
                let (height_error_m, position_error_px, coverage_mismatch, same_colour) =
                    compare(&reference, &probe, focal);
                let (mut cpu, mut select, mut gpu, mut wall) = (0.0, 0.0, 0.0, 0.0);
                let frames = settings.frames.max(1);
                for _ in 0..frames {
                    let ((stats, image), ms) = timed_ms(|| {
                        let stats = renderer.prepare(camera, settings.width, settings.height);
                        (stats, renderer.render_image(DrawMode::Colour))
                    });
                    let image = image?;
                    wall += ms;
                    cpu += stats.prepare_ms;
                    select += stats.select_ms;
                    gpu += image.gpu_ms.unwrap_or(f64::NAN);
                }
                let f = frames as f64;
                rows.push(RenderBenchRow {
                    project: name.clone(),
                    view: view.clone(),
                    patches: if adaptive { "adaptive" } else { "whole" },
                    threshold: t,
                    pixel_error: pixel_error.unwrap_or(f64::NAN),
                    max_error_px: settled.max_error_px,
                    same_colour,
                    quads: settled.selection.quads.len(),
                    triangles: settled.triangles,
                    terrain_pixels: probe.ids.as_ref().map_or(0, |ids| ids.iter().filter(|id| id[0] > 0).count()),
                    max_level: settled.selection.quads.iter().map(|q| q.level).max().unwrap_or(0),
                    cpu_ms: cpu / f,
                    select_ms: select / f,
                    gpu_ms: gpu / f,
                    wall_ms: wall / f,
                    height_error_m,
                    position_error_px,
                    coverage_mismatch,
                });
            }
        }
    }
    let _ = writeln!(
        report,
        "{:<10} {:<10} {:<8} {:>5} {:>5} {:>7} {:>6} {:>6} {:>10} {:>7} {:>4} {:>8} {:>8} {:>9} {:>9} {:>10} {:>10} {:>9} {:>9} {:>7}",
        "project",
        "view",
        "patches",
        "t",
        "τ",
        "err px",
        "same",
        "quads",
        "triangles",
        "tri/px",
        "Lmax",
        "cpu ms",
        "sel ms",
        "gpu ms",
        "frame ms",
        "dh mean m",
        "dh max m",
        "dp mean",
        "dp max",
        "cover"
    );
    for r in &rows {
        let v = row_values(r);
        let widths = [10, 10, 8, 5, 5, 7, 6, 6, 10, 7, 4, 8, 8, 9, 9, 10, 10, 9, 9, 7];
        let cells: Vec<String> = v
            .iter()
            .zip(widths)
            .enumerate()
            .map(|(k, (value, w))| if k < 3 { format!("{value:<w$}") } else { format!("{value:>w$}") })
            .collect();
        let _ = writeln!(report, "{}", cells.join(" "));
    }
    let _ = writeln!(
        report,
        "τ: the pixel error the geometry was selected by; err px: the largest geometric error drawn, on screen (the renderer's f64 bound); same: share of terrain pixels within 2/255 of the reference's colour; dh: height difference against the whole quads at t = {finest} at the same pixel; dp: the surface position difference seen from the eye, pixels; cover: share of pixels that are terrain in one and sky in the other"
    );
    Ok((rows, report))
}

/// A row's values as printed: the table and the CSV share them.
fn row_values(r: &RenderBenchRow) -> [String; 20] {
    [
        r.project.chars().take(10).collect(),
        r.view.clone(),
        r.patches.to_string(),
        r.threshold.to_string(),
        if r.pixel_error.is_nan() { "-".into() } else { r.pixel_error.to_string() },
        format!("{:.3}", r.max_error_px),
        format!("{:.3}", r.same_colour),
        r.quads.to_string(),
        r.triangles.to_string(),
        format!("{:.2}", r.triangles as f64 / r.terrain_pixels.max(1) as f64),
        r.max_level.to_string(),
        format!("{:.3}", r.cpu_ms),
        format!("{:.3}", r.select_ms),
        format!("{:.2}", r.gpu_ms),
        format!("{:.1}", r.wall_ms),
        format!("{:.3}", r.height_error_m.0),
        format!("{:.2}", r.height_error_m.1),
        format!("{:.3}", r.position_error_px.0),
        format!("{:.2}", r.position_error_px.1),
        format!("{:.4}", r.coverage_mismatch),
    ]
}

/// The CSV of the rows.
pub fn render_bench_csv(rows: &[RenderBenchRow]) -> String {
    let mut table = super::harness::Table::new(&[
        "project",
        "view",
        "patches",
        "threshold_px:",
        "pixel_error_px:",
        "max_error_px:",
        "same_colour:",
        "quads:",
        "triangles:",
        "triangles_per_terrain_pixel:",
        "max_level:",
        "cpu_ms:",
        "select_ms:",
        "gpu_ms:",
        "frame_ms:",
        "height_error_mean_m:",
        "height_error_max_m:",
        "position_error_mean_px:",
        "position_error_max_px:",
        "coverage_mismatch:",
    ]);
    for r in rows {
        table.row(row_values(r).to_vec());
    }
    table.csv()
}

/// Plot: GPU pass time and triangles (top) and mean errors (bottom) against the pixel error τ, one
/// line per view and threshold (the adaptive rows).
pub fn render_bench_plot(rows: &[RenderBenchRow]) -> Result<Vec<u8>, CliError> {
    use plotters::prelude::*;
    super::harness::register_font();
    let (w, h) = (1100u32, 900u32);
    let mut buffer = vec![0u8; (w * h * 3) as usize];
    let err = |e: &dyn std::fmt::Display| e.to_string();
    let rows: Vec<&RenderBenchRow> = rows.iter().filter(|r| r.pixel_error.is_finite()).collect();
    let mut keys: Vec<(String, String, String)> =
        rows.iter().map(|r| (r.project.clone(), r.view.clone(), format!("t {}", r.threshold))).collect();
    keys.sort();
    keys.dedup();
    let t_min = rows.iter().map(|r| r.pixel_error).fold(f64::INFINITY, f64::min).max(1e-3);
    let t_max = rows.iter().map(|r| r.pixel_error).fold(0.0, f64::max).max(t_min * 2.0);
    let palette = [RED, BLUE, GREEN, MAGENTA, CYAN, BLACK, RGBColor(230, 140, 0), RGBColor(120, 60, 160)];
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let panels = root.split_evenly((2, 2));
        type Metric = (&'static str, fn(&RenderBenchRow) -> f64);
        let metrics: [Metric; 4] = [
            ("GPU terrain pass (ms)", |r| if r.gpu_ms.is_finite() { r.gpu_ms } else { r.wall_ms }),
            ("triangles", |r| r.triangles as f64),
            ("height error, mean (m)", |r| r.height_error_m.0),
            ("position error, mean (px)", |r| r.position_error_px.0),
        ];
        for (panel, (label, metric)) in panels.iter().zip(metrics) {
            let values: Vec<f64> = rows.iter().map(|r| metric(r)).filter(|v| v.is_finite() && *v > 0.0).collect();
            let lo = values.iter().copied().fold(f64::INFINITY, f64::min).min(1.0) * 0.5;
            let hi = values.iter().copied().fold(0.0, f64::max).max(lo * 10.0) * 2.0;
            let mut chart = ChartBuilder::on(panel)
                .caption(format!("{label} against τ"), ("sans-serif", 18))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(70)
                .build_cartesian_2d((t_min..t_max).log_scale(), (lo.max(1e-6)..hi).log_scale())
                .map_err(|e| err(&e))?;
            chart
                .configure_mesh()
                .x_desc("pixel error τ (px)")
                .y_desc(label)
                .y_label_formatter(&|v| format!("{v:.1e}"))
                .draw()
                .map_err(|e| err(&e))?;
            for (k, (project, view, t)) in keys.iter().enumerate() {
                let c = palette[k % palette.len()];
                let points: Vec<(f64, f64)> = rows
                    .iter()
                    .filter(|r| &r.project == project && &r.view == view && format!("t {}", r.threshold) == *t)
                    .map(|r| (r.pixel_error, metric(r).max(lo.max(1e-6))))
                    .collect();
                chart
                    .draw_series(LineSeries::new(points.clone(), c.stroke_width(2)))
                    .map_err(|e| err(&e))?
                    .label(format!("{project} {view} {t}"))
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
                chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, c.filled()))).map_err(|e| err(&e))?;
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .label_font(("sans-serif", 11))
                .draw()
                .map_err(|e| err(&e))?;
        }
        root.present().map_err(|e| err(&e))?;
    }
    super::harness::plot_png(w, h, buffer)
}

/// Writes `render.csv` and `render.png` into `dir` atomically; returns their paths.
pub fn write_render_bench(dir: &Path, rows: &[RenderBenchRow]) -> Result<(PathBuf, PathBuf), CliError> {
    std::fs::create_dir_all(dir).map_err(CliError::file(dir, "cannot create"))?;
    let (csv, png) = (dir.join("render.csv"), dir.join("render.png"));
    crate::files::write_atomic(&csv, render_bench_csv(rows).as_bytes())
        .map_err(CliError::file(&csv, "cannot write"))?;
    crate::files::write_atomic(&png, &render_bench_plot(rows)?).map_err(CliError::file(&png, "cannot write"))?;
    Ok((csv, png))
}
