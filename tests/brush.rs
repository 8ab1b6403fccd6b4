//! Brushing as a user scripts it (`terrafuse brush`) and as the renderer composes it: the Moon
//! sample session replayed and rendered, an edit layer composed on the GPU as on the CPU across a
//! cube face edge and corner, no crack at the corner seen straight down, undo and redo through the
//! command line, and bad strokes refused without touching the file.

mod common;

use std::time::Duration;

use common::{sample_project, terrafuse};
use terrafuse::ecm::{CubeProjection, QuadId};
use terrafuse::edit::EditRaster;
use terrafuse::geodesy::Ellipsoid;
use terrafuse::gpu::{DrawMode, Editor, GpuContext, IMAGE_FORMAT, Renderer};
use terrafuse::layers::LayerKind;
use terrafuse::project::Project;
use terrafuse::scene::Scene;

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
    let dir = common::out_path("brush-compose");
    let p = Project::load(&sample_project("moon-brushing", &dir)).unwrap();
    let edit = p.layers.iter().find(|l| l.kind() == LayerKind::Edit).expect("the sample's edit layer");
    assert!(edit.strokes().len() >= 5, "a session of strokes");
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
    bare.layers.retain(|l| l.kind() != LayerKind::Edit);
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
    let dir = common::out_path("brush-corner");
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
    // Replay: the strokes (every tool; smooth, flatten and ramp read the LOLA grid below) rebuild
    // the same tiles, twice and in another thread pool, and as the scene built them.
    let edit = p.layers.iter().find(|l| l.kind() == LayerKind::Edit).unwrap();
    for tool in terrafuse::edit::Tool::ALL {
        assert!(edit.strokes().iter().any(|s| s.tool == tool), "the session has a {} stroke", tool.name());
    }
    let index = p.layers.iter().position(|l| l.kind() == LayerKind::Edit).unwrap();
    let below = r.scene().below(index).unwrap();
    let below = |q| Ok(below.heights_cpu(q)?);
    let once = EditRaster::build(Ellipsoid::MOON, edit.applied_strokes(), &below).unwrap();
    let again = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| EditRaster::build(Ellipsoid::MOON, edit.applied_strokes(), &below).unwrap());
    assert_eq!(once, again);
    let scene_raster = r.scene().edits.values().next().unwrap();
    assert_eq!(**scene_raster, once);
    // Without the terrain below, the strokes that read it give other tiles (they did read it).
    let blind = EditRaster::build(Ellipsoid::MOON, edit.applied_strokes(), &terrafuse::edit::ellipsoid_below).unwrap();
    assert_ne!(blind, once);
}

#[test]
fn strokes_undo_and_redo_from_the_command_line_and_bad_strokes_leave_the_file_as_it_was() {
    let dir = common::out_path("brush-cli");
    let path = sample_project("moon-brushing", &dir);
    let p = path.to_str().unwrap();
    let strokes = |path: &std::path::Path| {
        let q = Project::load(path).unwrap();
        let l = q.layers.iter().find(|l| l.kind() == LayerKind::Edit).unwrap().clone();
        (l.strokes().len(), l.applied_strokes().len())
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
    // A name the project does not have is refused (the nearest named), unless --create makes it.
    let out =
        terrafuse(&["brush", p, "--layer", "scuplt", "--tool", "raise", "--radius-m", "9000", "--path", "1,2"], "");
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success() && err.contains("did you mean 'sculpt'? add --create"), "{err}");
    let report = run(&[
        "brush",
        p,
        "--layer",
        "more",
        "--create",
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
        (
            vec!["--tool", "raise", "--radius-m", "-5", "--strength-m", "1", "--path", "0,0"],
            "--radius-m: -5 must be a distance in metres",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "100", "--strength-m", "1", "--path", "-2,420;0,44"],
            "--path: point 0 [-2, 420] is not [lat, lon] in degrees (latitude within ±90, longitude within ±180)",
        ),
        (
            vec!["--tool", "raise", "--radius-m", "100", "--strength-m", "1", "--path", "-2,42;0,44", "--level", "10"],
            "tiles (1.7 GiB of heights), over the budget of 2048 from the project's detail.max_edit_tiles",
        ),
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

#[test]
fn the_gpu_rasteriser_agrees_with_the_cpu_reference_for_every_tool_across_a_face_edge_and_a_corner() {
    // One stroke of each tool on the GPU and on the CPU, in sequence on the same raster: across
    // the front/right face edge at 45°E, over the cube corner (45°E, 35.26°N) and over the front
    // face's centre (where the GPU reads exact points), with terrain
    // below for flatten and ramp (a tilt of 3 cm per metre plus 50 m waves). The GPU's δ stays
    // within GPU_TOLERANCE × scale × dabs of the CPU's at every sample (scale: the largest of
    // the strengths in metres and the |δ| and |goal| involved), and both touch the same tiles.
    use terrafuse::ecm::points::sample_point;
    use terrafuse::edit::kernel::CpuRasteriser;
    use terrafuse::edit::{Falloff, Stroke, Tool};
    use terrafuse::gpu::brush::{GPU_TOLERANCE, StrokeKernel};
    let e = Ellipsoid::MOON;
    let height = |p: glam::DVec3| 0.03 * p.dot(glam::DVec3::new(0.0, 0.6, 0.8)) + 50.0 * (p.x / 700.0).sin();
    let below = |q: QuadId| -> Result<Vec<f32>, terrafuse::errors::Failure> {
        Ok((0..257 * 257)
            .map(|k| height(sample_point(&e, q, 257, (k % 257) as u32, (k / 257) as u32).0) as f32)
            .collect())
    };
    let stroke = |tool, strength, falloff, path: &[[f64; 2]]| Stroke {
        tool,
        radius_m: 4000.0,
        strength,
        falloff,
        spacing: 0.25,
        level: 9,
        path: path.to_vec(),
        seed: 7,
        height_m: None,
    };
    let edge = [[0.2, 44.9], [0.25, 45.1]];
    let corner = [[35.2, 44.9], [35.3, 45.1]];
    let strokes = vec![
        stroke(Tool::Raise, 40.0, Falloff::Smooth, &edge),
        stroke(Tool::Lower, 15.0, Falloff::Tip, &corner),
        stroke(Tool::Noise, 25.0, Falloff::Linear, &corner),
        stroke(Tool::Raise, 30.0, Falloff::Spherical, &corner),
        Stroke { height_m: Some(-200.0), ..stroke(Tool::Flatten, 0.6, Falloff::Smooth, &edge) },
        stroke(Tool::Flatten, 0.5, Falloff::Linear, &corner),
        stroke(Tool::Ramp, 0.8, Falloff::Smooth, &corner),
        stroke(Tool::Restore, 0.4, Falloff::Smooth, &edge),
        stroke(Tool::Smooth, 0.7, Falloff::Smooth, &corner),
        // Inside a face (the GPU's ring reads; near a face edge the CPU's).
        stroke(Tool::Smooth, 0.9, Falloff::Spherical, &[[10.0, 20.0], [10.05, 20.1]]),
        // The front face's centre, where QSC's four sectors meet.
        stroke(Tool::Raise, 20.0, Falloff::Linear, &[[0.0, -0.05], [0.02, 0.05]]),
    ];
    let ctx = GpuContext::headless().expect("a GPU adapter (lavapipe in CI)");
    let kernel = StrokeKernel::new(&ctx.device).unwrap();
    let gpu = kernel.on_context(&ctx);
    let mut on_cpu = EditRaster::new(e, 9);
    let mut on_gpu = EditRaster::new(e, 9);
    let mut worst = 0f64;
    for (k, s) in strokes.iter().enumerate() {
        let a = on_cpu.apply_with(k, s, &below, &CpuRasteriser).unwrap();
        let b = on_gpu.apply_with(k, s, &below, &gpu).unwrap();
        assert_eq!(a, b, "stroke {k}: the same tiles touched");
        // Carry on from the same δ (the CPU's), so that each stroke is compared alone.
        let dabs = terrafuse::edit::dabs::dab_centres(&e, s).unwrap().len() as f64;
        let (lo, hi) = on_cpu.range_m();
        let scale =
            if s.tool.strength_in_metres() { s.strength.abs() } else { 0.0 }.max(lo.abs().max(hi.abs())).max(400.0); // the goals: terrain of ±(tilt + waves) and the -200 m flatten
        for q in &a {
            let (c, g) = (on_cpu.tile(*q).unwrap(), on_gpu.tile(*q).unwrap());
            for (x, y) in c.iter().zip(g) {
                let d = f64::from(x - y).abs() / (scale * dabs);
                worst = worst.max(d);
                assert!(d <= GPU_TOLERANCE, "stroke {k} ({:?}) at {q}: CPU {x}, GPU {y}", s.tool);
            }
        }
        on_gpu = on_cpu.clone();
    }
    eprintln!("worst GPU − CPU: {worst:.2e} of scale × dabs (tolerance {GPU_TOLERANCE:.0e})");
}

#[test]
fn a_stroke_recomposes_only_the_quads_it_changed_and_undo_restores_their_heights() {
    // The sample session composed at level 4 (its edit layer's level) over the strokes' area;
    // one more small stroke inside one quad: composing the same quads again recomposes that quad
    // alone (the layer's other quads keep their stamps), and its heights moved; undone, they are
    // back bit for bit.
    use terrafuse::edit::{Falloff, Stroke, Tool};
    let dir = common::out_path("brush-recompose");
    let p = Project::load(&sample_project("moon-brushing", &dir)).unwrap();
    let mut r = renderer(&p);
    let e = Ellipsoid::MOON;
    let index = r.scene().stack.index_of("sculpt").unwrap();
    let target = quad_at(&e, -1.0, 44.0, 4);
    // The target and its neighbours on its face (the right face's across the edge are not needed).
    let quads: Vec<QuadId> = (0..3u32)
        .flat_map(|dx| (0..3u32).map(move |dy| (target.x + dx, target.y + dy)))
        .filter_map(|(x, y)| QuadId::new(target.face, 4, x.checked_sub(1)?, y.checked_sub(1)?).ok())
        .collect();
    let covered = quads.iter().filter(|q| r.scene().plan(**q).layers.iter().any(|l| l.index == index)).count();
    assert!(covered >= 3, "{covered} of the quads read the edit layer");
    r.compose_now(&quads).unwrap();
    let before = r.read_heights(target).unwrap().unwrap();
    let n0 = r.compose_counters().quads;
    r.compose_now(&quads).unwrap();
    assert_eq!(r.compose_counters().quads, n0, "nothing changed, nothing recomposed");
    // 3 km radius at the quad's centre (the quad spans about 170 km).
    let (lat, lon) = {
        let (p, _, _) = terrafuse::ecm::points::sample_point(&e, target, 257, 128, 128);
        let g = terrafuse::geodesy::geodetic_from_ecef(&e, p);
        (g.lat_rad.to_degrees(), g.lon_rad.to_degrees())
    };
    let stroke = Stroke {
        tool: Tool::Raise,
        radius_m: 3000.0,
        strength: 100.0,
        falloff: Falloff::Smooth,
        spacing: 0.25,
        level: 4,
        path: vec![[lat, lon]],
        seed: 0,
        height_m: None,
    };
    let applied = p.layers[index].applied_strokes().len();
    Editor::new(&GpuContext::headless().unwrap()).unwrap().apply_stroke(&mut r, index, stroke).unwrap();
    r.compose_now(&quads).unwrap();
    assert_eq!(r.compose_counters().quads, n0 + 1, "the stroke's quad alone is recomposed");
    let after = r.read_heights(target).unwrap().unwrap();
    let moved = before.iter().zip(&after).filter(|(a, b)| (*a - *b).abs() > 50.0).count();
    assert!(moved > 0, "the raise shows");
    Editor::new(&GpuContext::headless().unwrap()).unwrap().set_applied(&mut r, index, applied).unwrap();
    r.compose_now(&quads).unwrap();
    assert_eq!(r.compose_counters().quads, n0 + 2, "undo recomposes the same quad");
    let undone = r.read_heights(target).unwrap().unwrap();
    assert!(undone.iter().zip(&before).all(|(a, b)| a.to_bits() == b.to_bits()), "undo restores the heights");
}

#[test]
fn edit_rasters_are_cached_beside_the_project_and_rebuilt_when_stale_or_unreadable() {
    let dir = common::out_path("brush-cache");
    let path = sample_project("moon-brushing", &dir);
    let stores = dir.join("stores");
    let caches = || -> Vec<std::path::PathBuf> {
        let mut v: Vec<_> = std::fs::read_dir(&stores)
            .map(|d| d.flatten().map(|e| e.path()).filter(|p| p.to_string_lossy().contains("edits-sculpt-")).collect())
            .unwrap_or_default();
        v.sort();
        v
    };
    for old in caches() {
        std::fs::remove_file(old).unwrap(); // not left behind by an earlier run
    }
    let mut p = Project::load(&path).unwrap();
    let open = |p: &Project| {
        let (scene, report) = Scene::open(p).unwrap();
        let raster = (**scene.edits.values().next().unwrap()).clone();
        (raster, report.edits.join("\n"))
    };
    let (built, line) = open(&p);
    assert!(line.contains("rebuilt from 8 strokes") && line.contains("saved to"), "{line}");
    assert_eq!(caches().len(), 1);
    let (read, line) = open(&p);
    assert!(line.contains("8 strokes read from"), "{line}");
    assert_eq!(read, built, "the cache gives the tiles bit for bit");
    // Cut short: ignored, rebuilt (and saved again).
    let cache = caches().pop().unwrap();
    let bytes = std::fs::read(&cache).unwrap();
    std::fs::write(&cache, &bytes[..bytes.len() / 2]).unwrap();
    let (again, line) = open(&p);
    assert!(line.contains("rebuilt"), "{line}");
    assert_eq!(again, built);
    // Another undo position: another digest, another cache; the previous one is kept (a redo
    // reads it) among the layer's most recent few.
    let index = p.layers.iter().position(|l| l.kind() == LayerKind::Edit).unwrap();
    p.layers[index].as_edit_mut().unwrap().applied = Some(7);
    let (undone, line) = open(&p);
    assert!(line.contains("rebuilt from 7 strokes"), "{line}");
    assert_ne!(undone, built);
    assert_eq!(caches().len(), 2, "{:?}", caches());
    p.layers[index].as_edit_mut().unwrap().applied = None;
    let (redone, line) = open(&p);
    assert!(line.contains("8 strokes read from"), "{line}");
    assert_eq!(redone, built);
    for k in (3..7).rev() {
        p.layers[index].as_edit_mut().unwrap().applied = Some(k);
        open(&p);
    }
    assert_eq!(caches().len(), terrafuse::edit::cache::KEPT, "only the most recent are kept: {:?}", caches());
    // A layer below changed: the strokes that read the terrain read another one.
    p.layers[index].as_edit_mut().unwrap().applied = None;
    p.layers[0].offset_m = 100.0;
    let (_, line) = open(&p);
    assert!(line.contains("rebuilt from 8 strokes"), "{line}");
}
