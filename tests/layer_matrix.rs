//! The layer conformance matrix: every kind of layer through every consumer that picks a level
//! or composes heights, on the CPU reference (`render` on lavapipe). Rows are
//! [`LayerKind::ALL`]; columns are [`Consumer::ALL`]; `fixture` matches kinds exhaustively, so a
//! new kind does not compile until it has its row, and each test walks every kind, so a new
//! consumer is a new column for all of them. docs/layer-model.md draws the same table.
//!
//! The fixture: a Moon project with a constant base at 1 000 m, procedural hills, and the layer
//! under test (`k`) on top, over the front/right face edge at 45°E (the brushed stroke:
//! a 20 km `raise` at level 6 from 0.2°N 44°E to 0.2°S 46°E).

mod common;

use std::path::{Path, PathBuf};

use terrafuse::edit::{Falloff, Stroke, Tool};
use terrafuse::erosion::operation::Operation;
use terrafuse::erosion::params::{Params, gravity_of_body};
use terrafuse::export::{ComposeOn, ComposedExport, export_composed};
use terrafuse::geodesy::GeoBox;
use terrafuse::layers::{BlendMode, LayerKind, LayerSpec, NoiseSpec, NoiseType, Operand};
use terrafuse::project::Project;

/// What reads a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Consumer {
    /// `export` at its default level.
    Export,
    /// `compare` with and without the layer, at its default level.
    Compare,
    /// `erode` on top of the layer, then `compare` with and without the run.
    Erode,
    /// `brush` on top of the layer, then `export`.
    Brush,
    /// `profile` along a line, against the export's samples on it.
    Profile,
    /// `render` on lavapipe: a hidden layer draws nothing.
    Render,
    /// `render --swipe` on lavapipe: each side draws its layer with the other hidden.
    Swipe,
    /// Replay: the rebuilt rasters against the cached ones.
    Replay,
    /// Every consumer, with the layer hidden or at opacity 0.
    Hidden,
    /// Save → load → export.
    SaveLoad,
}

impl Consumer {
    const ALL: [Consumer; 10] = [
        Consumer::Export,
        Consumer::Compare,
        Consumer::Erode,
        Consumer::Brush,
        Consumer::Profile,
        Consumer::Render,
        Consumer::Swipe,
        Consumer::Replay,
        Consumer::Hidden,
        Consumer::SaveLoad,
    ];
}

fn dir(name: &str) -> PathBuf {
    let dir = common::out_path(&format!("layer_matrix/{name}"));
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// The one folder the LOLA sample is imported into for every test of this file.
fn lola_dir() -> PathBuf {
    dir("lola")
}

/// The LOLA global grid (levels 0–1) as a dataset layer called `name`.
fn lola(name: &str) -> LayerSpec {
    let sample = Project::load(&common::sample_project("moon-lola", &lola_dir())).unwrap();
    let layer = sample.layers.into_iter().find(LayerSpec::is_data).unwrap();
    LayerSpec { name: name.into(), ..layer.with_dataset_name("lola_global") }
}

fn hills() -> NoiseSpec {
    NoiseSpec {
        noise_type: NoiseType::Fbm,
        seed: 11,
        amplitude_m: 300.0,
        wavelength_m: 80_000.0,
        octaves: 3,
        lacunarity: 2.0,
        gain: 0.5,
        placement: Default::default(),
    }
}

/// The brushed stroke of the issue: across the front/right face edge, at level 6.
fn stroke() -> Stroke {
    Stroke {
        tool: Tool::Raise,
        radius_m: 20_000.0,
        strength: 200.0,
        falloff: Falloff::Smooth,
        spacing: 0.25,
        level: 6,
        path: vec![[0.2, 44.0], [-0.2, 46.0]],
        seed: 0,
        height_m: None,
    }
}

/// The layer of `kind` the matrix tests, and the level its detail goes to (None: it adds none
/// beyond the stack below).
fn fixture(kind: LayerKind) -> (Vec<LayerSpec>, LayerSpec, Option<u8>) {
    let mut below = vec![
        LayerSpec::constant("base", 1000.0),
        LayerSpec { blend: BlendMode::Add, ..LayerSpec::procedural("hills", hills()) },
    ];
    let (layer, detail) = match kind {
        // The bundled LOLA global grid (levels 0–1), imported once for this file's tests.
        LayerKind::Dataset => (lola("k"), Some(1)),
        LayerKind::Constant => (LayerSpec { blend: BlendMode::Max, ..LayerSpec::constant("k", 1100.0) }, None),
        LayerKind::Procedural => {
            let n = NoiseSpec { seed: 5, amplitude_m: 40.0, wavelength_m: 20_000.0, octaves: 4, ..hills() };
            let level = terrafuse::layers::kind::noise_detail_level(&n, &terrafuse::geodesy::Ellipsoid::MOON);
            (LayerSpec::procedural("k", n), Some(level))
        }
        LayerKind::Edit => {
            let mut edit = LayerSpec::edit("k");
            edit.record_stroke(stroke()).unwrap();
            (edit, Some(6))
        }
        LayerKind::Erosion => {
            let mut erosion = LayerSpec::erosion("k");
            // Talus collapse above 0.2° (LOLA upsampled to 300 m cells slopes by a degree or two): moves metres of material in a few steps, so that what it
            // moves shows in f32 heights of kilometres.
            let params = Params {
                talus_deg: 0.2,
                thermal_per_s: 2.0,
                ..Params::preset("thermal", gravity_of_body("moon")).unwrap()
            };
            let run = Operation {
                region: GeoBox::new(44.8, -0.2, 45.2, 0.2).unwrap(),
                level: 5,
                steps: 10,
                seed: 1,
                preset: Some("thermal".into()),
                params,
                model: terrafuse::erosion::operation::Model::Hydraulic,
                stream_power: None,
                brush: None,
                device: Default::default(),
            };
            erosion.record_run(run).unwrap();
            (erosion, Some(5))
        }
        LayerKind::Difference => {
            below.push(LayerSpec { visible: false, ..LayerSpec::constant("zero", 0.0) });
            (LayerSpec::difference("k", Operand::Layer("hills".into()), Operand::Layer("zero".into())), None)
        }
    };
    (below, layer, detail)
}

fn project(layers: Vec<LayerSpec>, path: &Path) -> PathBuf {
    let mut p = Project::new("moon");
    p.layers = layers;
    p.save(path).unwrap();
    path.to_path_buf()
}

/// Exports a 3.6° × 2° box around the stroke at 0.004° (≈ 121 m) on the CPU; the level used and
/// the samples (read back through GDAL).
fn export(project: &Path, level: Option<u8>) -> (u8, Vec<f32>) {
    export_on(project, level, ComposeOn::Cpu)
}

/// [`export`], composed where `on` says.
fn export_on(project: &Path, level: Option<u8>, on: ComposeOn) -> (u8, Vec<f32>) {
    let device = if on == ComposeOn::Gpu { "gpu" } else { "cpu" };
    let out = project.with_extension(format!("{}-{device}.tif", level.map_or("auto".into(), |l| l.to_string())));
    let report = export_composed(&ComposedExport {
        project: project.to_path_buf(),
        out: out.clone(),
        crs: "+proj=longlat +R=1737400 +no_defs".into(),
        bounds: [43.2, -1.0, 46.8, 1.0],
        resolution: (0.004, 0.004),
        level,
        compose_on: on,
        difference: None,
        attribute: None,
        layer: None,
        cog: false,
    })
    .unwrap_or_else(|e| panic!("{}: {e}", project.display()));
    let raw = out.with_extension("raw");
    common::run_tool("gdal_translate", &["-q", "-of", "ENVI", out.to_str().unwrap(), raw.to_str().unwrap()], "");
    let bytes = std::fs::read(&raw).unwrap();
    (report.level, bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect())
}

fn same_bits(a: &[f32], b: &[f32]) -> bool {
    a.len() == b.len() && a.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits())
}

#[test]
fn the_matrix_has_a_cell_for_every_kind_and_consumer() {
    // What docs/layer-model.md's table lists; a kind or consumer added without it fails here.
    let table = std::fs::read_to_string(common::repo_path("docs/layer-model.md")).unwrap();
    let start = table.find("<!-- layer matrix -->").expect("docs/layer-model.md has the layer matrix");
    let matrix = &table[start..];
    for kind in LayerKind::ALL {
        assert!(
            matrix.contains(&format!("| {} |", kind.name())),
            "docs/layer-model.md's matrix lacks the row {kind:?}"
        );
    }
    for consumer in Consumer::ALL {
        let column = format!("{consumer:?}").to_lowercase();
        assert!(matrix.contains(&column), "docs/layer-model.md's matrix lacks the column {column}");
    }
}

#[test]
fn export_composes_at_the_finest_level_any_layer_adds_detail_at() {
    let d = dir("export");
    // The level 121 m pixels ask for on the Moon: 9 820 m / 2^l ≤ 121 m → l = 7 (77 m).
    let wanted = 7u8;
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Export));
        let (mut layers, layer, detail) = fixture(kind);
        let below_detail = terrafuse::layers::kind::noise_detail_level(&hills(), &terrafuse::geodesy::Ellipsoid::MOON);
        layers.push(layer);
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        let (level, auto) = export(&path, None);
        let expected = wanted.min(detail.unwrap_or(0).max(below_detail));
        assert_eq!(level, expected, "{kind:?}: default level");
        // The default export equals the export at that level asked for, bit for bit.
        let (_, at) = export(&path, Some(expected));
        assert!(same_bits(&auto, &at), "{kind:?}: the default export differs from --level {expected}");
        // On the GPU (lavapipe) the same level, within the compose kernels' budget (tests/compose.rs:
        // heights of kilometres in f32, quad-local f32 positions moving noise and masks: 0.02 m).
        let (gpu_level, gpu) = export_on(&path, None, ComposeOn::Gpu);
        assert_eq!(gpu_level, expected, "{kind:?}: the GPU export's level");
        let worst = auto.iter().zip(&gpu).map(|(a, b)| (a - b).abs()).fold(0f32, f32::max);
        assert!(worst < 0.02, "{kind:?}: GPU − CPU export differs by {worst} m");
    }
}

#[test]
fn a_brushed_layer_exports_at_its_strokes_level_by_default() {
    // The defect: the default export composed a level-6 stroke at the datasets' level (1) and
    // smeared it (peak 780 m instead of 800 m over the 1 000 m base).
    let d = dir("brushed");
    let mut edit = LayerSpec::edit("sculpt");
    edit.record_stroke(stroke()).unwrap();
    let path = project(vec![LayerSpec::constant("base", 1000.0), edit], &d.join("brushed.json"));
    let (level, auto) = export(&path, None);
    assert_eq!(level, 6);
    let (_, at6) = export(&path, Some(6));
    assert!(same_bits(&auto, &at6));
    // Overlapping dabs raise the path's middle by 800 m (the figure); the level the
    // export used to pick (1) smears it below that.
    let peak = |h: &[f32]| h.iter().copied().filter(|h| h.is_finite()).fold(f32::MIN, f32::max) - 1000.0;
    assert!((peak(&auto) - 800.0).abs() < 1.0, "peak {} m, not 800 m", peak(&auto));
    let (_, at1) = export(&path, Some(1));
    assert!(peak(&at1) < 790.0, "at level 1 the stroke peaks at {} m: not smeared?", peak(&at1));
}

#[test]
fn a_hidden_or_transparent_layer_changes_no_output_bit_for_bit() {
    let d = dir("hidden");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Hidden));
        let (below, layer, _) = fixture(kind);
        let without = project(below.clone(), &d.join(format!("{}-without.json", kind.name())));
        let (level, reference) = export(&without, None);
        for (what, changed) in [
            ("hidden", LayerSpec { visible: false, ..layer.clone() }),
            ("opacity 0", LayerSpec { opacity: 0.0, ..layer.clone() }),
        ] {
            let mut layers = below.clone();
            layers.push(changed);
            let path = project(layers, &d.join(format!("{}-{}.json", kind.name(), what.replace(' ', ""))));
            let (l, heights) = export(&path, None);
            assert_eq!(l, level, "{kind:?} {what}: the default level moved");
            assert!(same_bits(&heights, &reference), "{kind:?} {what}: the export changed");
        }
    }
}

#[test]
fn every_kind_survives_save_load_and_exports_unchanged() {
    let d = dir("save_load");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::SaveLoad));
        let (mut layers, layer, _) = fixture(kind);
        layers.push(layer.clone());
        let first = project(layers, &d.join(format!("{}-a.json", kind.name())));
        let loaded = Project::load(&first).unwrap();
        assert_eq!(loaded.layers.last(), Some(&layer), "{kind:?}: the layer read back differs");
        let second = d.join(format!("{}-b.json", kind.name()));
        loaded.save(&second).unwrap();
        assert_eq!(std::fs::read_to_string(&first).unwrap(), std::fs::read_to_string(&second).unwrap());
        let (_, a) = export(&first, None);
        let (_, b) = export(&second, None);
        assert!(same_bits(&a, &b), "{kind:?}: the export changed after save and load");
    }
}

/// The same layer of `kind` over the LOLA grid ("ground"), for the consumers that need a dataset
/// to bound what they read (`compare`); a dataset layer is a second copy of the grid 5 m up.
fn on_ground(kind: LayerKind) -> Vec<LayerSpec> {
    let (_, layer, _) = fixture(kind);
    let layer = match kind {
        LayerKind::Dataset => LayerSpec { offset_m: 5.0, ..layer },
        LayerKind::Difference => {
            LayerSpec::difference("k", Operand::Layer("ground".into()), Operand::Layer("zero".into()))
        }
        _ => layer,
    };
    let mut layers = vec![lola("ground")];
    if kind == LayerKind::Difference {
        layers.push(LayerSpec { visible: false, ..LayerSpec::constant("zero", 0.0) });
    }
    layers.push(layer);
    layers
}

/// The box erosion runs are asked for, `WEST,SOUTH,EAST,NORTH`.
const BOX: &str = "44.5,-0.5,45.5,0.5";

/// The box comparisons cover: the stroke, and the runs' regions (their boxes rounded out to
/// whole quads of level 5, 2.6° wide).
const WIDE: &str = "42,-3,48,3";

fn compare_groups(path: &Path, a: &[&str], b: &[&str]) -> Result<terrafuse::compare::Comparison, String> {
    let project = Project::load(path).unwrap();
    let group = |names: &[&str]| Operand::Group(names.iter().map(|n| n.to_string()).collect());
    let opts = terrafuse::compare::CompareOptions { region: Some(WIDE.parse().unwrap()), ..Default::default() };
    terrafuse::compare::compare_operands(&project, &group(a), &group(b), &opts).map_err(|e| e.to_string())
}

#[test]
fn compare_works_at_the_finest_level_either_side_adds_detail_at() {
    let d = dir("compare");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Compare));
        let path = project(on_ground(kind), &d.join(format!("{}.json", kind.name())));
        let result = compare_groups(&path, &["ground", "k"], &["ground"]);
        if kind == LayerKind::Difference {
            let e = result.unwrap_err();
            assert!(e.contains("k: is a difference layer"), "{e}");
            continue;
        }
        let c = result.unwrap_or_else(|e| panic!("{kind:?}: {e}"));
        let (_, _, detail) = fixture(kind);
        // The coarser dataset's level (1), or the finer one at which the layer adds detail.
        assert_eq!(c.level, detail.unwrap_or(1).max(1), "{kind:?}");
        let s = &c.stats;
        match kind {
            // f32 heights of a few km carry ±0.5 mm.
            LayerKind::Dataset => assert!((s.mean_m - 5.0).abs() < 1e-3 && s.nmad_m < 1e-3, "{kind:?}: {s:?}"),
            LayerKind::Constant => assert!(s.min_m > -1e-3, "{kind:?}: `max` only raises: {s:?}"),
            LayerKind::Edit => assert!((s.max_m - 800.0).abs() < 1.0, "{kind:?}: the stroke's peak: {s:?}"),
            _ => assert!(s.count > 0 && s.std_m > 0.0, "{kind:?}: {s:?}"),
        }
    }
}

#[test]
fn erode_then_compare_measures_the_volume_the_run_reports() {
    let d = dir("erode");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Erode));
        let mut layers = on_ground(kind);
        layers.push(LayerSpec::erosion("wash"));
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        let p = path.to_str().unwrap();
        let out = common::terrafuse(
            &[
                "erode",
                p,
                "--layer",
                "wash",
                "--region",
                BOX,
                "--level",
                "5",
                "--steps",
                "40",
                "--seed",
                "3",
                "--preset",
                "thermal",
                "--set",
                "talus_deg=0.2",
                "--set",
                "thermal_per_s=2",
                "--cpu",
                "--json",
            ],
            "",
        );
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(out.status.success(), "{kind:?}: {stderr}");
        let run: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let (change, eroded, deposited) = (
            run["volume_change_m3"].as_f64().unwrap(),
            run["eroded_m3"].as_f64().unwrap(),
            run["deposited_m3"].as_f64().unwrap(),
        );
        if kind == LayerKind::Constant {
            // `max 1100` over the grid is a plane at 1 100 m here: nothing to move.
            assert_eq!((eroded, deposited, change), (0.0, 0.0, 0.0), "{kind:?}: {run}");
        } else {
            assert!(eroded > 1e6 && deposited > 1e6, "{kind:?}: the run moved too little to measure: {run}");
        }
        let below: Vec<&str> = if kind == LayerKind::Difference { vec!["ground"] } else { vec!["ground", "k"] };
        let mut with = below.clone();
        with.push("wash");
        let c = compare_groups(&path, &with, &below).unwrap();
        // The run's level, or the stroke's where the edit layer adds finer detail.
        let (_, _, detail) = fixture(kind);
        let expected = if kind == LayerKind::Dataset { 5 } else { detail.unwrap_or(0).max(5) };
        assert_eq!(c.level, expected, "{kind:?}: compared at the finest level a layer adds detail at");
        let measured = c.stats.mean_m * c.area_km2 * 1e6;
        // The samples' cell areas are the ellipsoid's, the run's the chords' products: within
        // 0.1 % of the volume the run moved.
        assert!(
            (measured - change).abs() <= 1e-3 * (eroded + deposited) + 1e-6,
            "{kind:?}: compare measures {measured} m³, erode reports {change} m³ (moved {})",
            eroded + deposited
        );
    }
}

#[test]
fn brush_then_export_adds_the_stroke_over_every_kind() {
    let d = dir("brush");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Brush));
        let (mut layers, layer, detail) = fixture(kind);
        layers.push(layer);
        let before = project(layers.clone(), &d.join(format!("{}-before.json", kind.name())));
        layers.push(LayerSpec::edit("sculpt"));
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        let out = common::terrafuse(
            &[
                "brush",
                path.to_str().unwrap(),
                "--layer",
                "sculpt",
                "--tool",
                "raise",
                "--radius-m",
                "20000",
                "--strength-m",
                "200",
                "--falloff",
                "smooth",
                "--spacing",
                "0.25",
                "--level",
                "6",
                "--path",
                "0.2,44;-0.2,46",
            ],
            "",
        );
        assert!(out.status.success(), "{kind:?}: {}", String::from_utf8_lossy(&out.stderr));
        let (level, after) = export(&path, None);
        assert_eq!(level, detail.unwrap_or(0).clamp(6, 7), "{kind:?}");
        let (_, under) = export(&before, Some(level));
        let peak = after.iter().zip(&under).map(|(a, b)| a - b).filter(|d| d.is_finite()).fold(f32::MIN, f32::max);
        assert!((peak - 800.0).abs() < 1.0, "{kind:?}: the stroke adds {peak} m at most, not 800 m");
    }
}

#[test]
fn profile_samples_what_export_samples_on_the_same_line() {
    let d = dir("profile");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Profile));
        let (mut layers, layer, _) = fixture(kind);
        layers.push(layer);
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        // An export whose row 250 lies on the equator; the profile along it from pixel 100 to
        // pixel 800 takes one sample per pixel centre (on the equator the geodesic is the line).
        let out = path.with_extension("tif");
        let report = export_composed(&ComposedExport {
            project: path.clone(),
            out: out.clone(),
            crs: "+proj=longlat +R=1737400 +no_defs".into(),
            bounds: [43.2, -0.998, 46.8, 1.002],
            resolution: (0.004, 0.004),
            level: None,
            compose_on: ComposeOn::Cpu,
            difference: None,
            attribute: None,
            layer: None,
            cog: false,
        })
        .unwrap();
        let raw = out.with_extension("raw");
        common::run_tool("gdal_translate", &["-q", "-of", "ENVI", out.to_str().unwrap(), raw.to_str().unwrap()], "");
        let bytes = std::fs::read(&raw).unwrap();
        let grid: Vec<f32> = bytes.chunks_exact(4).map(|c| f32::from_le_bytes([c[0], c[1], c[2], c[3]])).collect();
        let width = report.size.0;
        let lon = |i: usize| 43.2 + (i as f64 + 0.5) * 0.004;
        let profile = terrafuse::compare::profile(
            &Project::load(&path).unwrap(),
            &terrafuse::compare::ProfileOptions {
                from: [0.0, lon(100)],
                to: [0.0, lon(800)],
                samples: Some(701),
                level: None,
            },
        )
        .unwrap();
        assert_eq!(profile.level, report.level, "{kind:?}: profile and export pick the same level");
        for (k, h) in profile.composed.iter().enumerate() {
            let e = f64::from(grid[250 * width + 100 + k]);
            assert!((h - e).abs() < 2e-3, "{kind:?}: sample {k}: profile {h} m, export {e} m");
        }
    }
}

#[test]
fn render_draws_nothing_of_a_hidden_layer() {
    let d = dir("render");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Render));
        let (below, layer, _) = fixture(kind);
        let png = |layers: Vec<LayerSpec>, name: &str| -> Vec<u8> {
            let path = project(layers, &d.join(format!("{}-{name}.json", kind.name())));
            render(&path, &path.with_extension("png"), &[])
        };
        let without = png(below.clone(), "without");
        let mut hidden = below.clone();
        hidden.push(LayerSpec { visible: false, ..layer.clone() });
        assert!(png(hidden, "hidden") == without, "{kind:?}: a hidden layer changed the picture");
        if matches!(kind, LayerKind::Edit | LayerKind::Procedural | LayerKind::Difference) {
            let mut shown = below.clone();
            shown.push(layer.clone());
            assert!(png(shown, "shown") != without, "{kind:?}: the shown layer changed nothing in view");
        }
    }
}

#[test]
fn replay_rebuilds_what_the_cache_holds_bit_for_bit() {
    use terrafuse::ecm::QuadId;
    let d = dir("replay");
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Replay));
        let (mut layers, layer, _) = fixture(kind);
        layers.push(layer);
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        let p = Project::load(&path).unwrap();
        let (cached, _) = terrafuse::scene::Scene::open(&p).unwrap();
        let replayed = terrafuse::replay::replay(&p, terrafuse::replay::Engine::Cpu).unwrap();
        let e = terrafuse::geodesy::Ellipsoid::MOON;
        let point = terrafuse::ecm::CubeProjection::Qsc.face_point_from_geodetic(&e, 0.0, 45f64.to_radians());
        for level in [1, 5, 6] {
            let q = QuadId::containing(point, level).unwrap();
            let (a, b) = (cached.heights_cpu(q).unwrap(), replayed.scene.heights_cpu(q).unwrap());
            assert!(same_bits(&a, &b), "{kind:?}: {q} differs after replay");
        }
    }
}

#[test]
fn no_consumer_names_a_kind() {
    // Outside `src/layers/` a kind is only displayed (`LayerKind::name`); what a consumer needs
    // it asks the layer (`src/layers/kind.rs`) or reads from the layer's payload.
    let mut offenders = Vec::new();
    let mut stack = vec![common::repo_path("src")];
    while let Some(dir) = stack.pop() {
        for entry in std::fs::read_dir(&dir).unwrap().flatten() {
            let path = entry.path();
            if path.ends_with("layers") {
                continue;
            }
            if path.is_dir() {
                stack.push(path);
            } else if path.extension().is_some_and(|e| e == "rs") {
                let text = std::fs::read_to_string(&path).unwrap();
                for kind in LayerKind::ALL {
                    if text.contains(&format!("LayerKind::{kind:?}")) {
                        offenders.push(format!("{}: LayerKind::{kind:?}", path.display()));
                    }
                }
            }
        }
    }
    assert!(offenders.is_empty(), "consumers that match kinds instead of asking the layer: {offenders:#?}");
}

/// Renders `project` on lavapipe from above the stroke (160 × 120), with `extra` arguments; RGBA.
fn render(project: &Path, out: &Path, extra: &[&str]) -> Vec<u8> {
    let mut args = vec![
        "render",
        project.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--width",
        "160",
        "--height",
        "120",
        "--camera",
        "0,45,300000,0,-90",
    ];
    args.extend_from_slice(extra);
    let run = common::terrafuse(&args, "");
    assert!(run.status.success(), "{}: {}", project.display(), String::from_utf8_lossy(&run.stderr));
    image::open(out).unwrap().to_rgba8().into_raw()
}

#[test]
fn swipe_draws_each_side_as_the_stack_with_the_other_hidden() {
    let d = dir("swipe");
    let (w, h) = (160usize, 120usize);
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Swipe));
        let (mut layers, layer, _) = fixture(kind);
        layers.push(layer);
        let path = project(layers.clone(), &d.join(format!("{}.json", kind.name())));
        let swiped = render(&path, &d.join(format!("{}-swipe.png", kind.name())), &["--swipe", "k,hills,0.5"]);
        let without = |name: &str| {
            let mut hidden = layers.clone();
            hidden.iter_mut().filter(|l| l.name == name).for_each(|l| l.visible = false);
            let path = project(hidden, &d.join(format!("{}-no-{name}.json", kind.name())));
            render(&path, &path.with_extension("png"), &[])
        };
        let (left, right) = (without("hills"), without("k"));
        // Away from the swipe line (its two-pixel rule), each side is the stack with the other
        // layer hidden, pixel for pixel.
        for y in 0..h {
            for x in (0..w).filter(|x| x.abs_diff(w / 2) > 2) {
                let i = 4 * (y * w + x);
                let want = if x < w / 2 { &left[i..i + 4] } else { &right[i..i + 4] };
                assert_eq!(&swiped[i..i + 4], want, "{kind:?}: pixel ({x}, {y})");
            }
        }
    }
}
