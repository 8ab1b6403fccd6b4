//! Brushing as a user scripts it (`terrafuse brush`) and as the renderer composes it: the Moon
//! sample session replayed and rendered, an edit layer composed on the GPU as on the CPU across a
//! cube face edge and corner, no crack at the corner seen straight down, undo and redo through the
//! command line, and bad strokes refused without touching the file.

mod common;

use std::time::Duration;

use common::{repo_path, sample_project, terrafuse};
use terrafuse::ecm::{CubeProjection, QuadId};
use terrafuse::edit::EditRaster;
use terrafuse::geodesy::Ellipsoid;
use terrafuse::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, Renderer, Scene};
use terrafuse::layers::LayerKind;
use terrafuse::project::Project;

fn run(args: &[&str]) -> String {
    let out = terrafuse(args, "");
    assert!(out.status.success(), "terrafuse {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

fn renderer(project: &Project) -> Renderer {
    let (scene, _) = Scene::open(project).unwrap();
    let ctx =
        GpuContext::headless().expect("a GPU adapter (lavapipe in CI: scripts/install-deps, WGPU_BACKEND=vulkan)");
    Renderer::new(&ctx, scene, IMAGE_FORMAT).unwrap()
}

fn quad_at(e: &Ellipsoid, lat: f64, lon: f64, level: u8) -> QuadId {
    let p = CubeProjection::Qsc.face_point_from_geodetic(e, lat.to_radians(), lon.to_radians());
    QuadId::containing(p, level).unwrap()
}

#[test]
fn the_moon_session_composes_on_the_gpu_as_on_the_cpu_across_a_face_edge_and_a_corner() {
    let dir = repo_path("tests/out/brush-compose");
    let p = Project::load(&sample_project("moon-brushing", &dir)).unwrap();
    let edit = p.layers.iter().find(|l| l.kind == LayerKind::Edit).expect("the sample's edit layer");
    assert!(edit.strokes.len() >= 5, "a session of strokes");
    let mut r = renderer(&p);
    let e = Ellipsoid::MOON;
    // On the ridge across the front/right face edge (45°E), on the trench, on the corner.
    let quads: Vec<QuadId> = [(0.0, 44.5, 4u8), (0.0, 45.5, 4), (-4.0, 45.2, 5), (35.0, 44.7, 4), (35.5, 45.3, 3)]
        .iter()
        .map(|&(lat, lon, level)| quad_at(&e, lat, lon, level))
        .collect();
    let faces: std::collections::BTreeSet<_> = quads.iter().map(|q| q.face as u8).collect();
    assert!(faces.len() >= 3, "three faces: {quads:?}");
    r.compose_now(&quads).unwrap();
    let cpu = r.scene().compose_cpu(&quads).unwrap();
    // The same quads without the edit layer: the deltas are what the layer adds.
    let mut bare = p.clone();
    bare.layers.retain(|l| l.kind != LayerKind::Edit);
    let base = Scene::open(&bare).unwrap().0.compose_cpu(&quads).unwrap();
    let (mut worst, mut edited) = (0f64, 0usize);
    for q in &quads {
        let gpu = r.read_heights(*q).unwrap().expect("composed");
        for ((g, c), b) in gpu.iter().zip(&cpu[q]).zip(&base[q]) {
            assert_eq!(g.is_nan(), c.is_nan());
            if !c.is_nan() {
                worst = worst.max(f64::from((g - c).abs()));
                edited += usize::from((c - b).abs() > 1.0);
            }
        }
    }
    println!("edit layer GPU − CPU: worst {worst:.2e} m; {edited} samples moved by more than 1 m");
    // Far from every stroke the edit layer is not even read.
    let edit_index = r.scene().stack.index_of("sculpt").unwrap();
    let far = quad_at(&e, -40.0, -100.0, 4);
    assert!(r.scene().plan(far).layers.iter().all(|l| l.index != edit_index), "read where no stroke reached");
    assert!(r.scene().plan(quads[0]).layers.iter().any(|l| l.index == edit_index));
    assert!(edited > 20_000, "the strokes change the terrain there: {edited}");
    // Heights of ±6 km in f32 (half an ulp 2.4·10⁻⁴ m), an add of the delta: 10⁻³ m.
    assert!(worst < 1e-3, "GPU − CPU {worst} m");
}

#[test]
fn the_brushed_corner_seen_straight_down_has_no_crack_and_the_session_rebuilds_bit_for_bit() {
    let dir = repo_path("tests/out/brush-corner");
    let path = sample_project("moon-brushing", &dir);
    let mut p = Project::load(&path).unwrap();
    // A background no terrain colour has (the ramp is viridis): any background pixel inside the
    // view, which looks straight down on the corner from 200 km, is a crack.
    p.visuals.background = [255, 0, 255, 255];
    p.visuals.isolines.enabled = false;
    let mut r = renderer(&p);
    let camera = p.view(Some("corner")).unwrap();
    let stats = r.settle(&camera, 400, 400, Duration::from_secs(120));
    assert_eq!(stats.pending, 0);
    let image = r.render_image(DrawMode::Colour).unwrap();
    let cracks = image.rgba.chunks(4).filter(|px| px == &[255, 0, 255, 255]).count();
    assert_eq!(cracks, 0, "{cracks} background pixels in a view filled by terrain");
    let faces: std::collections::BTreeSet<_> = r.drawn().iter().map(|q| q.face as u8).collect();
    assert_eq!(faces.len(), 3, "the corner's three faces are drawn");
    // Replay: the strokes rebuild the same tiles, twice and in another thread pool.
    let edit = p.layers.iter().find(|l| l.kind == LayerKind::Edit).unwrap();
    let once = EditRaster::build(Ellipsoid::MOON, edit.applied_strokes(), &terrafuse::edit::ellipsoid_below).unwrap();
    let again = rayon::ThreadPoolBuilder::new().num_threads(1).build().unwrap().install(|| {
        EditRaster::build(Ellipsoid::MOON, edit.applied_strokes(), &terrafuse::edit::ellipsoid_below).unwrap()
    });
    assert_eq!(once, again);
    let scene_raster = r.scene().edits.values().next().unwrap();
    assert_eq!(**scene_raster, once);
}

#[test]
fn strokes_undo_and_redo_from_the_command_line_and_bad_strokes_leave_the_file_as_it_was() {
    let dir = repo_path("tests/out/brush-cli");
    let path = sample_project("moon-brushing", &dir);
    let p = path.to_str().unwrap();
    let strokes = |path: &std::path::Path| {
        let q = Project::load(path).unwrap();
        let l = q.layers.iter().find(|l| l.kind == LayerKind::Edit).unwrap().clone();
        (l.strokes.len(), l.applied_strokes().len())
    };
    let (n, applied) = strokes(&path);
    assert_eq!(n, applied);
    let report = run(&[
        "brush",
        p,
        "--layer",
        "sculpt",
        "--tool",
        "lower",
        "--radius-m",
        "8000",
        "--strength-m",
        "50",
        "--path",
        "10,30;10.2,30.3",
    ]);
    assert!(report.contains(&format!("layer 'sculpt': stroke {n} (lower, radius 8000 m")), "{report}");
    assert_eq!(strokes(&path), (n + 1, n + 1));
    run(&["brush", p, "--layer", "sculpt", "--undo", "2"]);
    assert_eq!(strokes(&path), (n + 1, n - 1));
    run(&["brush", p, "--layer", "sculpt", "--redo", "1"]);
    assert_eq!(strokes(&path), (n + 1, n));
    // A new stroke after an undo drops the undone one (redo ends).
    let report = run(&[
        "brush",
        p,
        "--layer",
        "sculpt",
        "--tool",
        "raise",
        "--radius-m",
        "8000",
        "--strength-m",
        "20",
        "--path",
        "11,31",
    ]);
    assert!(report.contains("1 undone strokes dropped"), "{report}");
    assert_eq!(strokes(&path), (n + 1, n + 1));
    // A new edit layer is made on top when named.
    let report = run(&[
        "brush",
        p,
        "--layer",
        "more",
        "--tool",
        "noise",
        "--radius-m",
        "9000",
        "--strength-m",
        "30",
        "--path",
        "12,32",
    ]);
    assert!(report.contains("made edit layer 'more' on top of the stack"), "{report}");
    // The tools that read the terrain below: a flatten to a given height and a ramp.
    for args in [
        vec!["--tool", "flatten", "--radius-m", "6000", "--strength", "0.7", "--path", "12,32", "--height-m", "-900"],
        vec!["--tool", "ramp", "--radius-m", "5000", "--strength", "0.9", "--path", "12,31.8;12.1,32.2"],
    ] {
        let mut all = vec!["brush", p, "--layer", "more"];
        all.extend(args.iter().copied());
        let report = run(&all);
        assert!(report.contains(&format!("({}, radius", args[1])), "{report}");
    }
    let before = std::fs::read(&path).unwrap();
    for (args, expected) in [
        (
            vec!["--tool", "dig", "--radius-m", "10", "--strength-m", "1", "--path", "0,0"],
            "--tool dig: not one of raise, lower",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "1e10", "--strength-m", "1", "--path", "0,0"],
            "--radius-m: 10000000000 must be",
        ),
        (
            vec!["--tool", "restore", "--radius-m", "100", "--strength-m", "1", "--path", "0,0"],
            "--strength: restore takes",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "100", "--strength-m", "1", "--path", "0;1"],
            "--path: point 0 '0' is not LAT,LON",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "100", "--strength-m", "1", "--path", "95,0"],
            "--path: point 0 [95, 0]",
        ),
        (
            vec!["--tool", "ramp", "--radius-m", "100", "--strength", "0.5", "--path", "0,0"],
            "--path: a ramp runs from the path's first point to its last",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "100", "--strength-m", "1", "--path", "0,0", "--height-m", "5"],
            "--height-m: is the flatten height",
        ),
        (vec!["--undo", "99"], "--undo 99: only"),
    ] {
        let mut all = vec!["brush", p, "--layer", "sculpt"];
        all.extend(args.iter().copied());
        let out = terrafuse(&all, "");
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success() && err.contains(expected), "{args:?}: {err}\n  expected: {expected}");
        assert_eq!(std::fs::read(&path).unwrap(), before, "{args:?} changed the file");
    }
    let out = terrafuse(&["brush", p, "--layer", "lola_global", "--undo", "1"], "");
    assert!(String::from_utf8_lossy(&out.stderr).contains("--layer lola_global: a dataset layer, not an edit layer"));
}
