//! `terrafuse bench compose`: what composing the layer stack costs and what it errs, on the
//! Erzurum SRTM sample. Samples per second for 1, 2, 4 and 8 layers and for each kind alone, on
//! the GPU (whatever adapter wgpu finds: lavapipe without a GPU) against the CPU reference, with
//! the largest GPU − CPU difference; procedural detail with and without octave skipping (time,
//! and the error skipping costs against every octave); and the cost of recomposing after a
//! one-layer change in a settled view against recomposing every drawn quad.

use super::harness::timed_ms;
use crate::cli::CliError;
use crate::maths::median;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Duration;

use crate::ecm::{CubeProjection, QuadId};
use crate::gpu::{GpuContext, IMAGE_FORMAT, Renderer};
use crate::layers::{BlendMode, DetailWhere, ExtentSpec, LayerSpec, NoiseSpec, NoiseType, Operand};
use crate::project::{CameraSpec, Project};
use crate::scene::Scene;

/// Settings.
#[derive(Clone, Debug)]
pub struct ComposeBenchSettings {
    /// The Erzurum sample project (its SRTM dataset is the dataset layer).
    pub project: PathBuf,
    /// Quads composed per measurement (level 9, over the SRTM tile).
    pub quads: usize,
    /// Repetitions; the median is reported.
    pub repeats: usize,
    /// Folder for compose.csv.
    pub out: PathBuf,
}

/// One measured configuration.
#[derive(Clone, Debug)]
pub struct ComposeBenchRow {
    /// What was composed.
    pub case: String,
    /// Layers in the stack.
    pub layers: usize,
    /// Samples composed per measurement.
    pub samples: usize,
    /// GPU time, milliseconds (median; dispatch to read-back complete).
    pub gpu_ms: f64,
    /// CPU reference time, milliseconds (median).
    pub cpu_ms: f64,
    /// Largest |GPU − CPU|, metres.
    pub max_diff_m: f64,
    /// For octave-skipping rows: the largest and RMS difference from every octave, metres.
    pub skip_error_m: Option<(f64, f64)>,
}

fn noise(noise_type: NoiseType, amplitude_m: f64, wavelength_m: f64, octaves: u32) -> NoiseSpec {
    NoiseSpec {
        noise_type,
        seed: 9,
        amplitude_m,
        wavelength_m,
        octaves,
        lacunarity: 2.0,
        gain: 0.5,
        placement: DetailWhere::Everywhere,
    }
}

/// The layers the stacks are drawn from, in order: the dataset, a feathered constant, fBm,
/// ridged noise in a mean group with a constant, a min cap, more detail.
fn layer_pool(srtm: &LayerSpec) -> Vec<LayerSpec> {
    vec![
        srtm.clone(),
        LayerSpec {
            blend: BlendMode::Max,
            opacity: 0.6,
            extent: Some(ExtentSpec::Box([40.3, 39.3, 40.9, 40.1])),
            feather_m: 8000.0,
            ..LayerSpec::constant("plateau", 2600.0)
        },
        LayerSpec::procedural("hills", noise(NoiseType::Fbm, 60.0, 12_000.0, 8)),
        LayerSpec {
            blend: BlendMode::Mean,
            ..LayerSpec::procedural("ridges", noise(NoiseType::Ridged, 200.0, 20_000.0, 6))
        },
        LayerSpec { blend: BlendMode::Mean, weight: 0.5, ..LayerSpec::constant("level", 2000.0) },
        LayerSpec { blend: BlendMode::Min, opacity: 0.5, ..LayerSpec::constant("cap", 2800.0) },
        LayerSpec::procedural("detail", noise(NoiseType::Fbm, 8.0, 1000.0, 8)),
        LayerSpec { blend: BlendMode::Add, opacity: 0.3, ..LayerSpec::constant("lift", 25.0) },
    ]
}

/// GPU ms, CPU ms, largest |GPU − CPU| (metres), and the CPU's grids.
type Measured = (f64, f64, f64, Vec<Vec<f32>>);

/// Times composing `quads` with a stack on the GPU and the CPU; the largest difference.
fn measure(
    ctx: &GpuContext,
    base: &Project,
    layers: Vec<LayerSpec>,
    quads: &[QuadId],
    repeats: usize,
    octave_skipping: bool,
) -> Result<Measured, CliError> {
    let mut p = base.clone();
    p.layers = layers;
    let (mut scene, _) = Scene::open(&p)?;
    scene.octave_skipping = octave_skipping;
    let mut renderer = Renderer::new(ctx, scene.clone(), IMAGE_FORMAT)?;
    // The first run uploads maps and source tiles; the timed runs recompose what is resident.
    renderer.compose_now(quads)?;
    renderer.read_heights(quads[0])?;
    let mut gpu = Vec::new();
    for _ in 0..repeats {
        renderer.invalidate_composed();
        let (done, ms) = timed_ms(|| -> Result<(), CliError> {
            renderer.compose_now(quads)?;
            renderer.read_heights(quads[0])?; // waits for the GPU
            Ok(())
        });
        done?;
        gpu.push(ms);
    }
    let mut cpu = Vec::new();
    let mut cpu_grids = Default::default();
    for _ in 0..repeats.clamp(1, 3) {
        let (grids, ms) = timed_ms(|| scene.compose_cpu(quads));
        cpu_grids = grids?;
        cpu.push(ms);
    }
    let mut worst = 0f64;
    let mut grids = Vec::new();
    for q in quads {
        let g = renderer.read_heights(*q)?.unwrap_or_default();
        let c = &cpu_grids[q];
        for (a, b) in g.iter().zip(c) {
            if a.is_nan() != b.is_nan() {
                worst = f64::INFINITY;
            } else if !a.is_nan() {
                worst = worst.max(f64::from((a - b).abs()));
            }
        }
        grids.push(c.clone());
    }
    Ok((median(gpu), median(cpu), worst, grids))
}

/// Runs the benchmark; returns the rows and a report.
pub fn bench_compose(settings: &ComposeBenchSettings) -> Result<(Vec<ComposeBenchRow>, String), CliError> {
    let base = Project::load(&settings.project)?;
    let srtm = base
        .layers
        .iter()
        .find(|l| l.is_data())
        .cloned()
        .ok_or_else(|| format!("{}: the benchmark needs a dataset layer", settings.project.display()))?;
    let ctx = GpuContext::headless()?;
    let e = base.ellipsoid()?;
    // Level-9 quads (SRTM's finest, 70 m samples) over the tile, row by row.
    let mut quads = Vec::new();
    'rows: for r in 0..8 {
        for c in 0..8 {
            let (lat, lon) = (39.2 + 0.1 * f64::from(r), 40.05 + 0.1 * f64::from(c));
            let p = CubeProjection::Qsc.face_point_from_geodetic(&e, lat.to_radians(), lon.to_radians());
            let q = QuadId::containing(p, 9)?;
            if !quads.contains(&q) {
                quads.push(q);
            }
            if quads.len() >= settings.quads.max(1) {
                break 'rows;
            }
        }
    }
    let samples = quads.len() * 257 * 257;
    let pool = layer_pool(&srtm);
    let repeats = settings.repeats.max(1);
    let mut rows = Vec::new();
    let mut row = |case: String, layers: Vec<LayerSpec>, skipping: bool| -> Result<Vec<Vec<f32>>, CliError> {
        let n = layers.len();
        let (gpu_ms, cpu_ms, max_diff_m, grids) = measure(&ctx, &base, layers, &quads, repeats, skipping)?;
        rows.push(ComposeBenchRow { case, layers: n, samples, gpu_ms, cpu_ms, max_diff_m, skip_error_m: None });
        Ok(grids)
    };
    for n in [1usize, 2, 4, 8] {
        row(format!("{n} layers"), pool[..n].to_vec(), true)?;
    }
    let constant = LayerSpec::constant("constant", 2000.0);
    row("dataset alone".into(), vec![srtm.clone()], true)?;
    row("constant alone".into(), vec![constant.clone()], true)?;
    row(
        "fbm alone (8 octaves)".into(),
        vec![constant.clone(), LayerSpec::procedural("fbm", noise(NoiseType::Fbm, 60.0, 12_000.0, 8))],
        true,
    )?;
    row(
        "ridged alone (8 octaves)".into(),
        vec![constant.clone(), LayerSpec::procedural("ridged", noise(NoiseType::Ridged, 60.0, 12_000.0, 8))],
        true,
    )?;
    row(
        "feathered extent alone".into(),
        vec![constant.clone(), LayerSpec { feather_m: 8000.0, ..pool[1].clone() }],
        true,
    )?;
    let mut faded = srtm.clone();
    if let Some(d) = faded.as_dataset_mut() {
        d.feather_edge_m = 5000.0;
    }
    row("dataset, 5 km edge feather".into(), vec![constant.clone(), faded.clone()], true)?;
    let fields = edge_field_cost(&base, faded, &quads)?;
    // Octave skipping: 16 octaves from 20 km down to 0.6 m; level 9 resolves those ≥ 70 m.
    let detail = vec![srtm.clone(), LayerSpec::procedural("detail", noise(NoiseType::Fbm, 40.0, 20_000.0, 16))];
    let skipped = row("fbm 16 octaves, skipping".into(), detail.clone(), true)?;
    let full = row("fbm 16 octaves, every octave".into(), detail, false)?;
    let (mut worst, mut sum2, mut count) = (0f64, 0f64, 0usize);
    for (a, b) in skipped.iter().flatten().zip(full.iter().flatten()) {
        if !a.is_nan() && !b.is_nan() {
            let d = f64::from(a - b);
            worst = worst.max(d.abs());
            sum2 += d * d;
            count += 1;
        }
    }
    let k = rows.len() - 2;
    rows[k].skip_error_m = Some((worst, (sum2 / count.max(1) as f64).sqrt()));

    let recompose = recompose_cost(&ctx, &base, &pool[..4])?;
    let difference = difference_cost(&ctx, &base, &pool[..4], &quads, repeats)?;
    let mut report = String::new();
    let _ = writeln!(
        report,
        "terrafuse bench compose: {} quads of 257² ({} samples) at level 9, adapter {}",
        quads.len(),
        samples,
        ctx.describe()
    );
    let _ = writeln!(
        report,
        "{:<32} {:>6} {:>10} {:>12} {:>10} {:>12} {:>12}",
        "case", "layers", "GPU ms", "GPU Msamp/s", "CPU ms", "CPU Msamp/s", "max |G−C| m"
    );
    for r in &rows {
        let _ = writeln!(
            report,
            "{:<32} {:>6} {:>10.2} {:>12.2} {:>10.1} {:>12.2} {:>12.2e}",
            r.case,
            r.layers,
            r.gpu_ms,
            r.samples as f64 / r.gpu_ms / 1e3,
            r.cpu_ms,
            r.samples as f64 / r.cpu_ms / 1e3,
            r.max_diff_m
        );
    }
    if let Some((worst, rms)) = rows[k].skip_error_m {
        let _ = writeln!(
            report,
            "octave skipping at level 9 (70 m samples): {:.2}× faster on the GPU, {:.2}× on the CPU; costs max {worst:.3} m, RMS {rms:.3} m against every octave",
            rows[k + 1].gpu_ms / rows[k].gpu_ms,
            rows[k + 1].cpu_ms / rows[k].cpu_ms
        );
    }
    report.push_str(&fields);
    report.push_str(&recompose);
    report.push_str(&difference);
    write_csv(&settings.out, &rows)?;
    Ok((rows, report))
}

/// What a drawn difference layer adds: the same 4-layer stack composed with and without a
/// difference of its top dataset alone minus the whole stack as a group (both operands composed
/// beside the heights), and the difference's largest |GPU − CPU|.
fn difference_cost(
    ctx: &GpuContext,
    base: &Project,
    layers: &[LayerSpec],
    quads: &[QuadId],
    repeats: usize,
) -> Result<String, CliError> {
    let names: Vec<String> = layers.iter().map(|l| l.name.clone()).collect();
    let dataset = layers.iter().find(|l| l.is_data()).ok_or("the stack has no dataset")?.name.clone();
    let mut with = layers.to_vec();
    with.push(LayerSpec::difference("dh", Operand::Layer(dataset), Operand::Group(names)));
    let time = |layers: Vec<LayerSpec>| -> Result<(f64, Renderer, Scene), CliError> {
        let mut p = base.clone();
        p.layers = layers;
        let (scene, _) = Scene::open(&p)?;
        let mut renderer = Renderer::new(ctx, scene.clone(), IMAGE_FORMAT)?;
        renderer.compose_now(quads)?;
        let mut gpu = Vec::new();
        for _ in 0..repeats {
            renderer.invalidate_composed();
            let (done, ms) = timed_ms(|| -> Result<(), CliError> {
                renderer.compose_now(quads)?;
                renderer.read_heights(quads[0])?;
                Ok(())
            });
            done?;
            gpu.push(ms);
        }
        Ok((median(gpu), renderer, scene))
    };
    let (plain_ms, _, _) = time(layers.to_vec())?;
    let (with_ms, renderer, scene) = time(with)?;
    let cpu = scene.compose_cpu_with_difference(quads)?;
    let mut worst = 0f64;
    for q in quads {
        let gpu = renderer.read_difference(*q)?.unwrap_or_default();
        let Some(Some(c)) = cpu.get(q).map(|(_, d)| d.as_ref()) else { continue };
        for (a, b) in gpu.iter().zip(c) {
            if a.is_nan() != b.is_nan() {
                worst = f64::INFINITY;
            } else if !a.is_nan() {
                worst = worst.max(f64::from((a - b).abs()));
            }
        }
    }
    Ok(format!(
        "a drawn difference (dataset alone − the 4-layer stack as a group): GPU {plain_ms:.2} ms → {with_ms:.2} ms ({:.2}×) for the same quads; dh max |GPU − CPU| {worst:.2e} m\n",
        with_ms / plain_ms
    ))
}

/// What the loader spends on no-data edge distances: one field per level-9 quad (the edge
/// level of a 5 km feather on Earth), each over the quad's 3 × 3 neighbourhood.
fn edge_field_cost(base: &Project, faded: LayerSpec, quads: &[QuadId]) -> Result<String, CliError> {
    let mut p = base.clone();
    p.layers = vec![faded];
    let (scene, _) = Scene::open(&p)?;
    let fields = crate::scene::loader::EdgeFields::default();
    let mut stores: Vec<_> = scene.datasets.iter().map(|_| None).collect();
    let (done, total_ms) = timed_ms(|| -> Result<(), CliError> {
        for &q in quads {
            if let Some((_, Some(edge))) = scene.layer_tiles(0, q) {
                crate::scene::loader::read_tile(edge, &scene.datasets, &mut stores, &fields)?;
            }
        }
        Ok(())
    });
    done?;
    let ms = total_ms / quads.len().max(1) as f64;
    Ok(format!(
        "no-data edge distances (5 km feather, level-9 fields over 3 × 3 quads, CPU, loader side): {ms:.1} ms per quad\n"
    ))
}

/// A settled 30 km view of Erzurum with the four first layers and a small feathered patch: the
/// frame after editing the patch (a few quads), after editing the fBm hills (every drawn quad),
/// and after every drawn quad is invalidated.
fn recompose_cost(ctx: &GpuContext, base: &Project, layers: &[LayerSpec]) -> Result<String, CliError> {
    let mut p = base.clone();
    p.layers = layers.to_vec();
    p.layers.push(LayerSpec {
        blend: BlendMode::Max,
        extent: Some(ExtentSpec::Box([40.55, 39.25, 40.65, 39.35])),
        feather_m: 1500.0,
        ..LayerSpec::constant("patch", 2400.0)
    });
    let (patch, hills) = (p.layers.len() - 1, 2);
    let (scene, _) = Scene::open(&p)?;
    let mut r = Renderer::new(ctx, scene, IMAGE_FORMAT)?;
    let camera = CameraSpec { lat: 39.3, lon: 40.42, alt: 30_000.0, heading: 0.0, pitch: -45.0, fov: 50.0 };
    let settled = r.settle(&camera, 640, 480, Duration::from_secs(300));
    let drawn = settled.selection.quads.len();
    let frame = |r: &mut Renderer| -> Result<(f64, usize, usize), CliError> {
        let (s, ms) = timed_ms(|| -> Result<_, CliError> {
            let s = r.prepare(&camera, 640, 480);
            r.wait_idle()?;
            Ok(s)
        });
        let s = s?;
        Ok((ms, s.composed.len(), s.layers_read))
    };
    let edit = |r: &mut Renderer, index: usize| -> Result<Vec<(f64, usize, usize)>, CliError> {
        let mut spec = p.layers[index].clone();
        (0..5)
            .map(|k| {
                spec.opacity = 0.8 + 0.04 * f64::from(k);
                r.update_layer(index, spec.clone())?;
                frame(r)
            })
            .collect()
    };
    let local = edit(&mut r, patch)?;
    let global = edit(&mut r, hills)?;
    let all: Vec<_> = (0..5)
        .map(|_| {
            r.invalidate_composed();
            frame(&mut r)
        })
        .collect::<Result<_, _>>()?;
    let m = |v: &[(f64, usize, usize)]| (median(v.iter().map(|x| x.0).collect()), v[0].1, v[0].2);
    let mut out = format!(
        "recomposition in a settled 30 km view ({drawn} quads drawn, 5 layers), frame time with the GPU finished:\n"
    );
    for (name, v) in [
        ("edit of a 10 km patch", &local),
        ("edit of the fBm hills (everywhere)", &global),
        ("every quad invalidated", &all),
    ] {
        let (ms, quads, read) = m(v);
        let _ = writeln!(out, "  {name:<36} {ms:>8.1} ms  {quads:>3} quads recomposed, {read:>3} layers read");
    }
    Ok(out)
}

fn write_csv(dir: &Path, rows: &[ComposeBenchRow]) -> Result<(), CliError> {
    let columns = ["case", "layers:", "samples:", "gpu_ms:", "cpu_ms:", "max_diff_m:", "skip_max_m:", "skip_rms_m:"];
    let mut table = super::harness::Table::new(&columns);
    for r in rows {
        let (a, b) = r.skip_error_m.map_or((String::new(), String::new()), |(a, b)| (a.to_string(), b.to_string()));
        let (layers, samples) = (r.layers.to_string(), r.samples.to_string());
        table.row(vec![
            r.case.to_string(),
            layers,
            samples,
            r.gpu_ms.to_string(),
            r.cpu_ms.to_string(),
            r.max_diff_m.to_string(),
            a,
            b,
        ]);
    }
    table.write_csv(&dir.join("compose.csv"))
}
