//! The layer conformance matrix: every kind of layer through every consumer that picks a level
//! or composes heights, on the CPU reference. Rows are [`LayerKind::ALL`]; columns are
//! [`Consumer::ALL`]; `fixture` matches kinds exhaustively, so a new kind does not compile until
//! it has its row, and each test walks every kind, so a new consumer is a new column for all of
//! them. ARCHITECTURE.md draws the same table.
//!
//! The fixture: a Moon project with a constant base at 1 000 m, procedural hills, and the layer
//! under test (`k`) on top, over the front/right face edge at 45°E (the brushed stroke:
//! a 20 km `raise` at level 6 from 0.2°N 44°E to 0.2°S 46°E).

mod common;

use std::path::{Path, PathBuf};

use terrafuse::cli::{ComposeOn, ComposedExport, export_composed};
use terrafuse::edit::{Falloff, Stroke, Tool};
use terrafuse::erosion::operation::Operation;
use terrafuse::erosion::params::{Params, gravity_of_body};
use terrafuse::geodesy::GeoBox;
use terrafuse::layers::{BlendMode, LayerKind, LayerSpec, NoiseSpec, NoiseType, Operand};
use terrafuse::project::Project;

/// What reads a layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Consumer {
    /// `export` at its default level.
    Export,
    /// Every consumer, with the layer hidden or at opacity 0.
    Hidden,
    /// Save → load → export.
    SaveLoad,
}

impl Consumer {
    const ALL: [Consumer; 3] = [Consumer::Export, Consumer::Hidden, Consumer::SaveLoad];
}

fn dir(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join("layer_matrix").join(name);
    std::fs::create_dir_all(&dir).unwrap();
    dir
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
fn fixture(kind: LayerKind, dir: &Path) -> (Vec<LayerSpec>, LayerSpec, Option<u8>) {
    let mut below = vec![
        LayerSpec::constant("base", 1000.0),
        LayerSpec { blend: BlendMode::Add, ..LayerSpec::procedural("hills", hills()) },
    ];
    let (layer, detail) = match kind {
        LayerKind::Dataset => {
            // The bundled LOLA global grid (levels 0–1), imported once into this test's folder.
            let sample = Project::load(&common::sample_project("moon-lola", dir)).unwrap();
            let mut lola = sample.layers.into_iter().find(LayerSpec::is_data).unwrap();
            lola.name = "k".into();
            lola = lola.with_dataset_name("lola_global");
            (lola, Some(1))
        }
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
            let params = Params::preset("rain", gravity_of_body("moon")).unwrap();
            let run = Operation {
                region: GeoBox::new(44.8, -0.2, 45.2, 0.2).unwrap(),
                level: 5,
                steps: 10,
                seed: 1,
                preset: Some("rain".into()),
                params,
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
    let out = project.with_extension(format!("{}.tif", level.map_or("auto".into(), |l| l.to_string())));
    let report = export_composed(&ComposedExport {
        project: project.to_path_buf(),
        out: out.clone(),
        crs: "+proj=longlat +R=1737400 +no_defs".into(),
        bounds: [43.2, -1.0, 46.8, 1.0],
        resolution: (0.004, 0.004),
        level,
        compose_on: ComposeOn::Cpu,
        difference: None,
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
    // What ARCHITECTURE.md's table lists; a kind or consumer added without it fails here.
    let table = std::fs::read_to_string(common::repo_path("ARCHITECTURE.md")).unwrap();
    let start = table.find("<!-- layer matrix -->").expect("ARCHITECTURE.md has the layer matrix");
    let matrix = &table[start..];
    for kind in LayerKind::ALL {
        assert!(matrix.contains(&format!("| {} |", kind.name())), "ARCHITECTURE.md's matrix lacks the row {kind:?}");
    }
    for consumer in Consumer::ALL {
        let column = format!("{consumer:?}").to_lowercase();
        assert!(matrix.contains(&column), "ARCHITECTURE.md's matrix lacks the column {column}");
    }
}

#[test]
fn export_composes_at_the_finest_level_any_layer_adds_detail_at() {
    let d = dir("export");
    // The level 121 m pixels ask for on the Moon: 9 820 m / 2^l ≤ 121 m → l = 7 (77 m).
    let wanted = 7u8;
    for kind in LayerKind::ALL {
        assert!(Consumer::ALL.contains(&Consumer::Export));
        let (mut layers, layer, detail) = fixture(kind, &d);
        let below_detail = terrafuse::layers::kind::noise_detail_level(&hills(), &terrafuse::geodesy::Ellipsoid::MOON);
        layers.push(layer);
        let path = project(layers, &d.join(format!("{}.json", kind.name())));
        let (level, auto) = export(&path, None);
        let expected = wanted.min(detail.unwrap_or(0).max(below_detail));
        assert_eq!(level, expected, "{kind:?}: default level");
        // The default export equals the export at that level asked for, bit for bit.
        let (_, at) = export(&path, Some(expected));
        assert!(same_bits(&auto, &at), "{kind:?}: the default export differs from --level {expected}");
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
        let (below, layer, _) = fixture(kind, &d);
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
        let (mut layers, layer, _) = fixture(kind, &d);
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
