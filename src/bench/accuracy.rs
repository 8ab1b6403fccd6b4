//! `terrafuse bench accuracy`: the vertex accuracy of every approach per body, level and
//! distance, as a report, a CSV and a plot, and the vertex timings.

use crate::cli::Within;
use crate::cli::{CliError, fitted_rule};
use std::fmt::Write as _;
use std::hint::black_box;
use std::path::Path;
use std::time::Instant;

use glam::{DVec3, Vec3};

use crate::ecm::accuracy::{self, AccuracyRow, AccuracySettings, Approach, F32_EPSILON};
use crate::ecm::geometry::{self, QuadBounds, QuadFrame, QuadGeometry, Split, StaticMaps};
use crate::ecm::{CubeProjection, Face, QuadId};
use crate::geodesy::Ellipsoid;

/// Options of `terrafuse bench accuracy`.
#[derive(Clone, Debug)]
pub struct AccuracyBench {
    /// Bodies to measure.
    pub bodies: Vec<Ellipsoid>,
    /// What to measure.
    pub settings: AccuracySettings,
    /// Tolerance of the flat rule, metres.
    pub tolerance_m: f64,
    /// Cap of the flat rule's tolerance as a fraction of the f32 limit at the draw distance.
    pub limit_fraction: f64,
}

/// Runs the accuracy benchmark: rows for every body, approach, level and distance, and the
/// report text (tables and timings).
pub fn accuracy_bench(bench: &AccuracyBench) -> (String, Vec<AccuracyRow>) {
    let mut rows = Vec::new();
    let mut out = String::new();
    let s = &bench.settings;
    let _ = writeln!(
        out,
        "Rendered position error against the exact f64 position (terrafuse bench accuracy)\n\
         {} trials × ({} random + 9 nearest) vertices per level and distance, {} samples per quad edge, seed {}, \
         slopes ≤ {}, camera where the LOD rule (t = {} px, {} px over {}°) draws the level",
        s.trials, s.random_vertices, s.samples, s.seed, s.slope, s.lod.threshold_px, s.lod.width_px, s.lod.fov_deg
    );
    let _ = writeln!(out, "ratio = largest error / that vertex's f32 limit |P − C|·2⁻²⁴ (goal for ecm: ≤ 2)");
    for ellipsoid in &bench.bodies {
        let started = Instant::now();
        let rule = fitted_rule(ellipsoid, bench.tolerance_m, bench.limit_fraction);
        let fit_s = started.elapsed().as_secs_f64();
        let body_rows = accuracy::measure(ellipsoid, CubeProjection::Qsc, &rule, s);
        let _ = writeln!(
            out,
            "\n{}: flat rule fitted in {:.2} s (A = {:.3e} m, B = {:.3e} m, first flat level {})",
            ellipsoid.name(),
            fit_s,
            rule.curvature_m,
            rule.cone_m,
            rule.first_flat_level().map_or("none".into(), |l| l.to_string())
        );
        out.push_str(&ratio_matrix(&body_rows, s));
        rows.extend(body_rows);
    }
    out.push_str(&over_goal(&rows));
    (out, rows)
}

/// Per approach and distance: the largest ratio over all levels, and the largest error.
fn ratio_matrix(rows: &[AccuracyRow], s: &AccuracySettings) -> String {
    let mut out = String::new();
    let _ = write!(out, "{:<24}", "max ratio (max error m)");
    for d in &s.distances_m {
        let _ = write!(out, " {:>18}", format!("d = {d:.0e} m"));
    }
    out.push('\n');
    for approach in Approach::ALL {
        let _ = write!(out, "{:<24}", approach.name());
        for &d in &s.distances_m {
            let cell = rows.iter().filter(|r| r.approach == approach && r.camera_distance_m == d);
            let (ratio, error) =
                cell.fold((0.0f64, 0.0f64), |acc, r| (acc.0.max(r.ratio_to_limit), acc.1.max(r.max_error_m)));
            let _ = write!(out, " {:>18}", format!("{ratio:.3} ({error:.1e})"));
        }
        out.push('\n');
    }
    out
}

/// Where the ECM path is above twice the f32 limit.
fn over_goal(rows: &[AccuracyRow]) -> String {
    let over: Vec<&AccuracyRow> =
        rows.iter().filter(|r| r.approach == Approach::Ecm && r.ratio_to_limit > 2.0).collect();
    let mut out = String::new();
    if over.is_empty() {
        let _ = writeln!(out, "\necm is within 2× the f32 limit at every body, level and distance measured.");
    } else {
        let _ = writeln!(
            out,
            "\necm above 2× the f32 limit ({} of {} cells):",
            over.len(),
            rows.len() / Approach::ALL.len()
        );
        for r in over {
            let _ = writeln!(
                out,
                "  {} level {} d = {:e} m: ratio {:.3}, max error {:.3e} m, limit {:.3e} m",
                r.body, r.level, r.camera_distance_m, r.ratio_to_limit, r.max_error_m, r.f32_limit_m
            );
        }
    }
    out
}

/// The rows as CSV with the columns
/// `approach,body,level,camera_distance_m,max_error_m,rms_error_m,f32_limit_m,ratio_to_limit`.
pub fn accuracy_csv(rows: &[AccuracyRow]) -> String {
    let mut table = super::harness::Table::new(&[
        "approach",
        "body",
        "level:",
        "camera_distance_m:",
        "max_error_m:",
        "rms_error_m:",
        "f32_limit_m:",
        "ratio_to_limit:",
    ]);
    for r in rows {
        table.row(vec![
            r.approach.name().to_string(),
            r.body.to_string(),
            r.level.to_string(),
            format!("{:e}", r.camera_distance_m),
            format!("{:e}", r.max_error_m),
            format!("{:e}", r.rms_error_m),
            format!("{:e}", r.f32_limit_m),
            format!("{:e}", r.ratio_to_limit),
        ]);
    }
    table.csv()
}

/// Colour of an approach in the plot.
fn colour(approach: Approach) -> plotters::style::RGBColor {
    use plotters::style::RGBColor;
    match approach {
        Approach::Ecm => RGBColor(0, 114, 178),
        Approach::EcmCutoff => RGBColor(86, 180, 233),
        Approach::EcmPaper => RGBColor(230, 159, 0),
        Approach::NaiveF32 => RGBColor(213, 94, 0),
        Approach::LinearCameraRelative => RGBColor(204, 121, 167),
        Approach::Sphere => RGBColor(0, 158, 115),
    }
}

/// The level the renderer draws right under a camera `d` metres above the terrain: the finest
/// level whose draw distance is still at least d (the coarsest measured level if none is).
fn foot_level(ellipsoid: &Ellipsoid, settings: &AccuracySettings, d: f64) -> u8 {
    let min = settings.levels.iter().copied().min().unwrap_or(0);
    settings
        .levels
        .iter()
        .copied()
        .filter(|&l| settings.lod.draw_distance_m(ellipsoid, l, settings.samples) >= d)
        .max()
        .unwrap_or(min)
}

/// Plots, per body, the largest error against the camera distance at the level drawn under the
/// camera (top), and the largest ratio to the f32 limit over all levels (bottom), one line per
/// approach; returns PNG bytes.
pub fn accuracy_plot(
    rows: &[AccuracyRow],
    bodies: &[Ellipsoid],
    settings: &AccuracySettings,
) -> Result<Vec<u8>, CliError> {
    use plotters::prelude::*;
    super::harness::register_font();
    let (w, h) = (560 * bodies.len().max(1) as u32, 1000u32);
    let mut buffer = vec![0u8; (w * h * 3) as usize];
    let distances: Vec<f64> = {
        let mut d: Vec<f64> = rows.iter().map(|r| r.camera_distance_m).collect();
        d.sort_by(f64::total_cmp);
        d.dedup();
        d
    };
    let (d_min, d_max) = (distances.first().copied().unwrap_or(1.0), distances.last().copied().unwrap_or(10.0));
    let series = |body: &Ellipsoid, approach: Approach, ratio: bool| -> Vec<(f64, f64)> {
        distances
            .iter()
            .map(|&d| {
                let level = foot_level(body, settings, d);
                let v = rows
                    .iter()
                    .filter(|r| r.body == body.name() && r.approach == approach && r.camera_distance_m == d)
                    .filter(|r| ratio || r.level == level)
                    .map(|r| if ratio { r.ratio_to_limit } else { r.max_error_m })
                    .fold(0.0, f64::max);
                (d, v.max(1e-12))
            })
            .collect()
    };
    let err = |e: &dyn std::fmt::Display| e.to_string();
    {
        let root = BitMapBackend::with_buffer(&mut buffer, (w, h)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| err(&e))?;
        let (top, bottom) = root.split_vertically(h / 2);
        let tops = top.split_evenly((1, bodies.len().max(1)));
        let bottoms = bottom.split_evenly((1, bodies.len().max(1)));
        for (k, body) in bodies.iter().enumerate() {
            for (area, ratio) in [(&tops[k], false), (&bottoms[k], true)] {
                let (y_range, y_desc) =
                    if ratio { (0.1f64..1e12, "max error / f32 limit") } else { (1e-10f64..1e8, "max error (m)") };
                let mut chart = ChartBuilder::on(area)
                    .caption(
                        format!(
                            "{}: {}",
                            body.name(),
                            if ratio {
                                "ratio to the f32 limit, max over levels"
                            } else {
                                "error at the level drawn under the camera"
                            }
                        ),
                        ("sans-serif", 18),
                    )
                    .margin(12)
                    .x_label_area_size(40)
                    .y_label_area_size(64)
                    .build_cartesian_2d((d_min..d_max).log_scale(), y_range.log_scale())
                    .map_err(|e| err(&e))?;
                chart
                    .configure_mesh()
                    .x_desc("camera distance above the terrain (m)")
                    .y_desc(y_desc)
                    .x_label_formatter(&|v| format!("{v:.0e}"))
                    .y_label_formatter(&|v| format!("{v:.0e}"))
                    .draw()
                    .map_err(|e| err(&e))?;
                for approach in Approach::ALL {
                    let c = colour(approach);
                    let points = series(body, approach, ratio);
                    chart
                        .draw_series(LineSeries::new(points.clone(), c.stroke_width(2)))
                        .map_err(|e| err(&e))?
                        .label(approach.name())
                        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
                    chart.draw_series(points.iter().map(|&p| Circle::new(p, 3, c.filled()))).map_err(|e| err(&e))?;
                }
                let reference: Vec<(f64, f64)> = if ratio {
                    distances.iter().map(|&d| (d, 2.0)).collect()
                } else {
                    distances.iter().map(|&d| (d, d * F32_EPSILON)).collect()
                };
                chart
                    .draw_series(LineSeries::new(reference, BLACK.stroke_width(1)))
                    .map_err(|e| err(&e))?
                    .label(if ratio { "goal: 2× limit" } else { "f32 limit at d" })
                    .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], BLACK));
                chart
                    .configure_series_labels()
                    .position(if ratio { SeriesLabelPosition::UpperRight } else { SeriesLabelPosition::UpperLeft })
                    .background_style(WHITE.mix(0.85))
                    .border_style(BLACK)
                    .label_font(("sans-serif", 12))
                    .draw()
                    .map_err(|e| err(&e))?;
            }
        }
        root.present().map_err(|e| err(&e))?;
    }
    super::harness::plot_png(w, h, buffer)
}

/// Writes the CSV and the plot atomically, creating their folders; errors name the file.
pub fn write_accuracy_outputs(
    bench: &AccuracyBench,
    rows: &[AccuracyRow],
    csv: &Path,
    plot: Option<&Path>,
) -> Result<(), CliError> {
    for path in std::iter::once(csv).chain(plot) {
        if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
            std::fs::create_dir_all(dir).map_err(CliError::file(path, "cannot write"))?;
        }
    }
    crate::files::write_atomic(csv, accuracy_csv(rows).as_bytes()).map_err(CliError::file(csv, "cannot write"))?;
    if let Some(plot) = plot {
        let png = accuracy_plot(rows, &bench.bodies, &bench.settings)
            .within(format_args!("cannot draw {}", plot.display()))?;
        crate::files::write_atomic(plot, &png).map_err(CliError::file(plot, "cannot write"))?;
    }
    Ok(())
}

/// Best of `repeats` timings of `f`, seconds.
fn best_of(repeats: usize, mut f: impl FnMut()) -> f64 {
    (0..repeats.max(1))
        .map(|_| {
            let t = Instant::now();
            f();
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// One vertex's inputs in the timing loop: s, t, the maps [oₑ, nₑ, δn], h, and the f64 surface
/// point and normal.
struct TimedVertex {
    s: f32,
    t: f32,
    maps: [Vec3; 3],
    h: f32,
    point: DVec3,
    normal: DVec3,
}

/// Timings beside the errors: computing one quad's maps per sample, bounds per quad, and
/// reconstructing positions per vertex in f32 for each approach (CPU, one thread; the renderer
/// runs the same arithmetic on the GPU).
pub fn timing_report(ellipsoid: &Ellipsoid, samples: u32) -> String {
    let p = CubeProjection::Qsc;
    let quad = QuadId::new(Face::Right, 10, 300, 700).unwrap_or(QuadId::root(Face::Right));
    let n = samples.max(2);
    let count = f64::from(n * n);
    let maps_s = best_of(3, || {
        black_box(StaticMaps::compute(ellipsoid, p, black_box(quad), n));
    });
    let g = QuadGeometry::compute(ellipsoid, p, quad, n);
    let bounds_s = best_of(3, || {
        black_box(QuadBounds::compute(black_box(&g), -500.0, 4000.0));
    });
    let camera = g.corners_ecef[0] + g.corner_normals[0] * 3000.0;
    let frame = g.frame(camera, 2000.0);
    let inputs: Vec<TimedVertex> = (0..n)
        .flat_map(|j| (0..n).map(move |i| (i, j)))
        .map(|(i, j)| {
            let (s, t) = geometry::sample_st(n, i, j);
            let maps = g.maps_at(i, j).unwrap_or([Vec3::ZERO; 3]);
            let point = geometry::interpolate_f64(g.split, &g.corners_ecef, s, t) + maps[0].as_dvec3();
            TimedVertex {
                s: s as f32,
                t: t as f32,
                maps,
                h: 1000.0 + (i + j) as f32,
                point,
                normal: maps[1].as_dvec3(),
            }
        })
        .collect();
    let relative = g.corners_ecef.map(|q| (q - camera).as_vec3());
    let normals = g.corner_normals.map(|v| v.as_vec3());
    let time_vertices = |f: &dyn Fn(&TimedVertex) -> Vec3| {
        1e9 * best_of(5, || {
            let mut acc = Vec3::ZERO;
            for v in &inputs {
                acc += f(black_box(v));
            }
            black_box(acc);
        }) / count
    };
    let split = g.split;
    let per_vertex: Vec<(&str, f64)> = vec![
        ("ecm", time_vertices(&|v| geometry::vertex_f32(split, &frame, v.s, v.t, Some(v.maps), v.h))),
        ("ecm-cutoff (flat quad)", time_vertices(&|v| geometry::vertex_f32(split, &frame, v.s, v.t, None, v.h))),
        ("ecm-paper", time_vertices(&|v| geometry::bilerp_f32(&relative, v.s, v.t) + v.maps[0] + v.maps[1] * v.h)),
        ("naive-f32", time_vertices(&|v| (v.point + v.normal * f64::from(v.h)).as_vec3() - camera.as_vec3())),
        (
            "linear-camera-relative",
            time_vertices(&|v| {
                geometry::bilerp_f32(&relative, v.s, v.t) + geometry::bilerp_f32(&normals, v.s, v.t).normalize() * v.h
            }),
        ),
        (
            "sphere (f64, then cast)",
            time_vertices(&|v| ((v.point - camera) + v.point.normalize() * f64::from(v.h)).as_vec3()),
        ),
    ];
    let frame_ns =
        1e9 * best_of(5, || {
            for _ in 0..1000 {
                black_box(QuadFrame::new(&g.corners_ecef, &g.corner_normals, black_box(camera), 2000.0));
            }
        }) / 1000.0;
    let mut out = String::new();
    let _ = writeln!(
        out,
        "\nTimings on this CPU (one thread, best of several runs; {} on {quad}, {n}×{n} samples)",
        ellipsoid.name()
    );
    let _ = writeln!(
        out,
        "  static maps (oₑ, nₑ, δn in f64 → f32): {:.1} ns per sample, {:.1} ms per quad",
        1e9 * maps_s / count,
        1e3 * maps_s
    );
    let _ = writeln!(out, "  bounding box of a quad (every sample, two heights): {:.2} ms", 1e3 * bounds_s);
    let _ = writeln!(out, "  per-quad frame values (anchor, corners at h₀; f64): {frame_ns:.1} ns per quad");
    let _ = writeln!(out, "  split of this quad: {:?}", Split::of(quad));
    let _ = writeln!(out, "  per-vertex position, CPU reference of the vertex stage:");
    for (name, ns) in per_vertex {
        let _ = writeln!(out, "    {name:<26} {ns:>6.2} ns per vertex");
    }
    out
}
