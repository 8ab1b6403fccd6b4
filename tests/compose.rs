//! The layer stack composed on the GPU (Mesa's lavapipe in CI) against the CPU reference, on
//! every layer kind and blend mode, with feathers across a cube face edge and a cube corner; the
//! cache's counters (a composed quad is recomposed only when a layer touching it changes; hidden,
//! transparent and distant layers are not read); and bounds that stay right when a layer raises
//! the terrain by 5 km.

mod common;

use std::path::PathBuf;
use std::time::Duration;

use terrafuse::ecm::{CubeProjection, Edge, QuadId};
use terrafuse::geodesy::Ellipsoid;
use terrafuse::gpu::compose::ComposeOn;
use terrafuse::gpu::{DrawMode, GpuContext, IMAGE_FORMAT, Renderer};
use terrafuse::layers::{
    BlendMode, DetailWhere, ExtentSpec, LayerSpec, LayerTiles, NoiseSpec, NoiseType, Operand, compose_difference,
    compose_quad,
};
use terrafuse::project::{CameraSpec, Project};
use terrafuse::scene::Scene;
use terrafuse::scene::loader::{EdgeFields, read_tile};

/// A renderer whose frames compose on the GPU whatever the adapter (on lavapipe they would
/// compose with the CPU reference by default, and these tests are of the compute pass).
fn renderer(project: &Project) -> Renderer {
    renderer_on(project, ComposeOn::Gpu)
}

fn renderer_on(project: &Project, on: ComposeOn) -> Renderer {
    let (scene, _) = Scene::open(project).unwrap();
    let ctx =
        GpuContext::headless().expect("a GPU adapter (lavapipe in CI: scripts/install-deps, WGPU_BACKEND=vulkan)");
    let mut r = Renderer::new(&ctx, scene, IMAGE_FORMAT).unwrap();
    r.set_compose_on(on);
    r
}

fn noise(noise_type: NoiseType, amplitude_m: f64, wavelength_m: f64, octaves: u32) -> NoiseSpec {
    NoiseSpec {
        noise_type,
        seed: 42,
        amplitude_m,
        wavelength_m,
        octaves,
        lacunarity: 2.0,
        gain: 0.5,
        placement: DetailWhere::Everywhere,
    }
}

fn layer(spec: LayerSpec, blend: BlendMode, opacity: f64) -> LayerSpec {
    LayerSpec { blend, opacity, ..spec }
}

/// The quad of `level` containing a geodetic point (degrees).
fn quad_at(e: &Ellipsoid, lat: f64, lon: f64, level: u8) -> QuadId {
    let p = CubeProjection::Qsc.face_point_from_geodetic(e, lat.to_radians(), lon.to_radians());
    QuadId::containing(p, level).unwrap()
}

/// The raw and edge tiles of a quad's k-th planned layer (datasets; `None` for other kinds).
type SourceTiles = dyn Fn(&Scene, QuadId, usize) -> (Option<Vec<f32>>, Option<Vec<f32>>);

/// The tiles the stores give (read here, on the test's thread).
fn store_tiles(scene: &Scene, quad: QuadId, k: usize) -> (Option<Vec<f32>>, Option<Vec<f32>>) {
    let index = scene.plan(quad).layers[k].index;
    let Some((source, edge)) = scene.layer_tiles(index, quad) else { return (None, None) };
    let mut stores: Vec<_> = scene.datasets.iter().map(|_| None).collect();
    let fields = EdgeFields::default();
    let mut read = |key| read_tile(key, &scene.datasets, &mut stores, &fields).unwrap().grid;
    (Some(read(source)), edge.map(read))
}

/// Composes `quads` on the GPU and on the CPU; returns the largest difference, metres, and the
/// number of samples with data, after checking that both agree on where there is data.
fn gpu_against_cpu(r: &mut Renderer, quads: &[QuadId], tiles: &SourceTiles) -> (f64, usize) {
    r.compose_now(quads).unwrap();
    let (mut worst, mut with_data) = (0f64, 0usize);
    for &quad in quads {
        let gpu = r.read_heights(quad).unwrap().expect("composed");
        let scene = r.scene();
        let plan = scene.plan(quad);
        let sources: Vec<_> = (0..plan.layers.len()).map(|k| tiles(scene, quad, k)).collect();
        let cpu = compose_quad(&scene.stack, &plan, &|k| LayerTiles {
            raw: sources[k].0.as_deref(),
            edge_m: sources[k].1.as_deref(),
        });
        for (k, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            assert_eq!(g.is_nan(), c.is_nan(), "{quad} sample {k}: GPU {g}, CPU {c}");
            if !c.is_nan() {
                worst = worst.max(f64::from((g - c).abs()));
                with_data += 1;
            }
        }
    }
    (worst, with_data)
}

#[test]
fn every_kind_and_blend_mode_composes_on_the_gpu_as_on_the_cpu_across_a_cube_corner() {
    // The Moon's cube corner between the front, right and top faces (35.26°N, 45°E), with a
    // stack that uses every blend mode, both fractals and both extent shapes: a 30°N cap
    // feathered over 300 km and a box whose western edge runs 0.3° east of the front/right face
    // edge, feathered over 40 km, so both feathers cross face edges and the corner.
    let mut p = Project::new("moon");
    p.layers = vec![
        LayerSpec::constant("base", 1000.0),
        layer(LayerSpec::procedural("hills", noise(NoiseType::Fbm, 400.0, 60_000.0, 8)), BlendMode::Add, 1.0),
        LayerSpec {
            extent: Some(ExtentSpec::Box([-180.0, 30.0, 180.0, 90.0])),
            feather_m: 300_000.0,
            ..layer(LayerSpec::constant("plateau", 1600.0), BlendMode::Max, 0.9)
        },
        LayerSpec {
            weight: 2.0,
            ..layer(LayerSpec::procedural("ridges", noise(NoiseType::Ridged, 300.0, 40_000.0, 6)), BlendMode::Mean, 1.0)
        },
        LayerSpec { offset_m: 900.0, ..layer(LayerSpec::constant("level", 0.0), BlendMode::Mean, 0.7) },
        LayerSpec {
            extent: Some(ExtentSpec::Box([45.3, 0.0, 70.0, 60.0])),
            feather_m: 40_000.0,
            ..layer(LayerSpec::constant("cut", 200.0), BlendMode::Min, 0.8)
        },
        LayerSpec {
            extent: Some(ExtentSpec::Polygon(vec![[40.0, 30.0], [50.0, 30.0], [45.0, 40.0]])),
            feather_m: 20_000.0,
            ..layer(LayerSpec::constant("crater", 2500.0), BlendMode::Over, 0.6)
        },
        layer(LayerSpec::procedural("grit", noise(NoiseType::Fbm, 5.0, 2000.0, 4)), BlendMode::Add, 1.0),
    ];
    let mut r = renderer(&p);
    let e = Ellipsoid::MOON;
    let (lat_c, lon_c) = (35.264_389_682_754_654, 45.0);
    let mut quads = Vec::new();
    for level in [3u8, 6] {
        for (dlat, dlon) in [(-0.2, -0.2), (-0.2, 0.2), (0.3, 0.0)] {
            quads.push(quad_at(&e, lat_c + dlat, lon_c + dlon, level));
        }
    }
    let faces: std::collections::BTreeSet<_> = quads.iter().map(|q| q.face as u8).collect();
    assert_eq!(faces.len(), 3, "three faces meet at the corner: {quads:?}");
    // Each layer is planned somewhere, with a partial mask somewhere.
    let plans: Vec<_> = quads.iter().map(|q| r.scene().plan(*q)).collect();
    for k in 0..p.layers.len() {
        assert!(
            plans.iter().any(|pl| pl.layers.iter().any(|l| l.index == k)),
            "layer {} never planned",
            p.layers[k].name
        );
    }
    let (worst, with_data) = gpu_against_cpu(&mut r, &quads, &|_, _, _| (None, None));
    assert_eq!(with_data, quads.len() * 257 * 257);
    // Tolerance: heights ≈ 1–3 km in f32 (half an ulp 1.2·10⁻⁴ m per operation, ~30 operations
    // per layer), quad-local f32 positions of level-3 quads (≈ 340 km across: 0.02 m) moving the
    // noise by amplitude × 2.5 × 0.02 m / λ (≤ 4·10⁻⁴ m) and the masks by ≤ 1.5 × 0.02 m /
    // feather × the value step (≤ 2·10⁻³ m): 0.02 m bounds it with room.
    println!("GPU − CPU: worst {worst:.2e} m over {with_data} samples");
    assert!(worst < 0.02, "worst GPU − CPU difference {worst} m");
}

fn erzurum() -> PathBuf {
    let dir = common::out_path("compose");
    common::sample_project("erzurum", &dir)
}

#[test]
fn datasets_with_scale_offset_valid_range_and_feathers_compose_on_the_gpu_as_on_the_cpu() {
    // The SRTM tile over a constant base: scaled, offset, a valid range that cuts its lowest
    // valleys, inside a box feathered by 5 km, under procedural detail beyond the data (the
    // octaves finer than SRTM's 90 m that a level-10 quad resolves).
    let mut p = Project::load(&erzurum()).unwrap();
    let srtm = p.layers[0].clone();
    p.layers = vec![
        LayerSpec::constant("base", 1500.0),
        LayerSpec {
            scale: 1.1,
            offset_m: -50.0,
            valid_range_m: Some([1300.0, 4000.0]),
            extent: Some(ExtentSpec::Box([40.1, 39.2, 40.7, 39.9])),
            feather_m: 5000.0,
            ..srtm
        },
        layer(
            LayerSpec::procedural(
                "detail",
                NoiseSpec { placement: DetailWhere::BeyondData, ..noise(NoiseType::Fbm, 20.0, 800.0, 8) },
            ),
            BlendMode::Add,
            1.0,
        ),
    ];
    let mut r = renderer(&p);
    let e = Ellipsoid::WGS84;
    let quads: Vec<QuadId> = [(39.2, 40.1, 9u8), (39.5, 40.4, 9), (39.9, 40.7, 10), (39.6, 40.3, 11), (39.0, 40.4, 8)]
        .iter()
        .map(|&(lat, lon, level)| quad_at(&e, lat, lon, level))
        .collect();
    let (worst, with_data) = gpu_against_cpu(&mut r, &quads, &store_tiles);
    assert!(with_data > 4 * 257 * 257);
    // Heights ≈ 2–3 km in f32 (≈ 2·10⁻⁴ m per operation) and quad-local positions of level-8
    // quads (≈ 40 km: 2·10⁻³ m) moving the 5 km feather's mask by ≤ 1.5 × 2·10⁻³ / 5000 × 1.5
    // km: 0.01 m bounds it.
    println!("GPU − CPU with datasets: worst {worst:.2e} m over {with_data} samples");
    assert!(worst < 0.01, "worst GPU − CPU difference {worst} m");
}

#[test]
fn a_dataset_with_bias_corrections_composes_on_the_gpu_as_on_the_cpu() {
    // SRTM around Erzurum with each kind of correction `coregister --apply` writes: a cubic ramp
    // fitted on ±25 km about 40.4°E 39.6°N (held beyond, so the quads farther out test the
    // hold), a bias binned by the layer's own elevation, and two sinusoids along 30°.
    use terrafuse::layers::correction::{Attribute, Bias, Sinusoid};
    let mut p = Project::load(&erzurum()).unwrap();
    let plain = p.layers[0].clone();
    let mut corrected = plain.clone();
    corrected.as_dataset_mut().unwrap().correction = vec![
        Bias::Deramp {
            origin_deg: [40.4, 39.6],
            order: 3,
            coefficients: vec![0.5, 0.2, -0.3, 0.01, -0.02, 0.005, 1e-4, -2e-4, 3e-4, -1e-4],
            box_km: [-25.0, -25.0, 25.0, 25.0],
        },
        Bias::TerrainBias {
            attribute: Attribute::Elevation,
            bins: (0..12).map(|k| [1500.0 + 150.0 * f64::from(k), 2.0 * (f64::from(k) * 0.7).sin()]).collect(),
        },
        Bias::Directional {
            origin_deg: [40.4, 39.6],
            azimuth_deg: 30.0,
            offset_m: 0.1,
            sinusoids: vec![
                Sinusoid { wavelength_m: 3000.0, amplitude_m: 2.0, phase_rad: 0.4 },
                Sinusoid { wavelength_m: 800.0, amplitude_m: 0.8, phase_rad: -1.2 },
            ],
            range_m: [-30_000.0, 30_000.0],
        },
    ];
    p.layers = vec![corrected];
    let mut r = renderer(&p);
    let e = Ellipsoid::WGS84;
    let quads: Vec<QuadId> = [(39.6, 40.4, 9u8), (39.3, 40.1, 10), (39.9, 40.7, 10), (39.6, 40.3, 11), (39.0, 40.4, 8)]
        .iter()
        .map(|&(lat, lon, level)| quad_at(&e, lat, lon, level))
        .collect();
    let (worst, with_data) = gpu_against_cpu(&mut r, &quads, &store_tiles);
    assert!(with_data > 4 * 257 * 257);
    // As the plain datasets' test (heights in f32, ≈ 2·10⁻⁴ m per operation), plus the
    // corrections in f32: east and north from O to ≈ 4 mm at 60 km, moving the ramp (≤ 5 m/km at
    // the box's edge) by 2·10⁻⁵ m and the sinusoids' phase by 3·10⁻⁵ rad (6·10⁻⁵ m at 2 m): 0.01 m.
    println!("GPU − CPU with corrections: worst {worst:.2e} m over {with_data} samples");
    assert!(worst < 0.01, "worst GPU − CPU difference {worst} m");
    // The corrections change the heights by metres (this compares something).
    let scene = r.scene();
    let q = quads[0];
    let plan = scene.plan(q);
    let (raw, _) = store_tiles(scene, q, 0);
    let tiles = |_: usize| LayerTiles { raw: raw.as_deref(), edge_m: None };
    let with = compose_quad(&scene.stack, &plan, &tiles);
    let mut bare = scene.stack.clone();
    bare.set(0, plain).unwrap();
    let without = compose_quad(&bare, &plan, &tiles);
    let moved = with.iter().zip(&without).map(|(a, b)| f64::from((a - b).abs())).fold(0.0, f64::max);
    assert!(moved > 1.0, "the corrections moved the heights by at most {moved} m");
}

#[test]
fn a_difference_of_a_shifted_layer_and_a_composed_group_composes_on_the_gpu_as_on_the_cpu() {
    // Erzurum: the SRTM tile shown under fBm detail; the blurred and shifted copy hidden, moved
    // 300 m east by its shift. The difference draws blurred alone minus the group srtm + detail,
    // beside heights that must not change.
    let dir = common::out_path("compose-difference");
    let mut p = Project::load(&common::sample_project("erzurum-compare", &dir)).unwrap();
    let srtm = p.layers.iter().find(|l| l.name == "srtm").unwrap().clone();
    let blurred = p.layers.iter().find(|l| l.name == "blurred").unwrap().clone();
    let detail = layer(LayerSpec::procedural("detail", noise(NoiseType::Fbm, 15.0, 900.0, 6)), BlendMode::Add, 0.8);
    let group = Operand::Group(vec!["srtm".into(), "detail".into()]);
    p.layers = vec![
        srtm,
        detail,
        blurred.with_shift_m([300.0, 0.0]),
        LayerSpec::difference("dh", Operand::Layer("blurred".into()), group),
    ];
    let mut r = renderer(&p);
    let e = Ellipsoid::WGS84;
    // Inside the tile, and across its edges (where one side has no data).
    let quads: Vec<QuadId> =
        [(39.5, 40.4, 9u8), (39.02, 40.5, 9), (39.98, 40.97, 10), (39.5, 40.0, 9), (39.6, 40.3, 8)]
            .iter()
            .map(|&(lat, lon, level)| quad_at(&e, lat, lon, level))
            .collect();
    let (worst_heights, _) = gpu_against_cpu(&mut r, &quads, &store_tiles);
    let (mut worst, mut with_data, mut without) = (0f64, 0usize, 0usize);
    for &quad in &quads {
        let gpu = r.read_difference(quad).unwrap().expect("a difference is drawn");
        let scene = r.scene();
        let plan = scene.plan(quad);
        let d = plan.difference.as_ref().expect("the plan has the difference");
        assert_eq!(d.a.layers.len(), 1, "A: blurred alone");
        assert!(d.b.layers.len() == 2, "B: srtm and detail, {:?}", d.b.layers);
        let mut stores: Vec<_> = scene.datasets.iter().map(|_| None).collect();
        let fields = EdgeFields::default();
        let tiles: Vec<Option<Vec<f32>>> =
            d.a.layers
                .iter()
                .chain(&d.b.layers)
                .map(|l| {
                    scene
                        .layer_tiles(l.index, quad)
                        .map(|(source, _)| read_tile(source, &scene.datasets, &mut stores, &fields).unwrap().grid)
                })
                .collect();
        let cpu = compose_difference(&scene.stack, d, &|k| LayerTiles { raw: tiles[k].as_deref(), edge_m: None });
        for (k, (g, c)) in gpu.iter().zip(&cpu).enumerate() {
            assert_eq!(g.is_nan(), c.is_nan(), "{quad} sample {k}: GPU dh {g}, CPU {c}");
            if c.is_nan() {
                without += 1;
            } else {
                worst = worst.max(f64::from((g - c).abs()));
                with_data += 1;
            }
        }
    }
    println!(
        "dh GPU − CPU: worst {worst:.2e} m over {with_data} samples ({without} without); heights {worst_heights:.2e} m"
    );
    assert!(with_data > 2 * 257 * 257, "{with_data}");
    assert!(without > 10_000, "the quads across the tile's edges have samples where one side has none: {without}");
    // Each side as the heights test (≤ 0.01 m); their difference adds one f32 rounding.
    assert!(worst < 0.02, "worst GPU − CPU dh {worst} m");
    assert!(worst_heights < 0.01, "heights {worst_heights} m");
    // The heights are the stack's alone: the same with the difference hidden.
    let before: Vec<_> = quads.iter().map(|q| r.read_heights(*q).unwrap().unwrap()).collect();
    let mut hidden = r.scene().stack.layers[3].spec.clone();
    hidden.visible = false;
    r.update_layer(3, hidden).unwrap();
    assert!(r.scene().plan(quads[0]).difference.is_none());
    r.compose_now(&quads).unwrap();
    for (q, b) in quads.iter().zip(&before) {
        let after = r.read_heights(*q).unwrap().unwrap();
        assert!(after.iter().zip(b).all(|(x, y)| x.to_bits() == y.to_bits()), "{q}: heights changed");
    }
}

fn cam(lat: f64, lon: f64, alt: f64, heading: f64, pitch: f64) -> CameraSpec {
    CameraSpec { lat, lon, alt, heading, pitch, fov: 50.0 }
}

#[test]
fn a_composed_quad_is_recomposed_only_when_a_layer_touching_it_changes() {
    let mut p = Project::load(&erzurum()).unwrap();
    let srtm = p.layers[0].clone();
    p.layers = vec![
        srtm,
        // Touches the east of the tile only.
        LayerSpec {
            extent: Some(ExtentSpec::Box([40.6, 39.0, 41.0, 40.2])),
            feather_m: 2000.0,
            ..layer(LayerSpec::constant("east", 3000.0), BlendMode::Max, 0.5)
        },
        // Far away: never touches the view.
        LayerSpec { extent: Some(ExtentSpec::Box([-10.0, -10.0, 0.0, 0.0])), ..LayerSpec::constant("far", 0.0) },
        LayerSpec { visible: false, ..layer(LayerSpec::constant("hidden", 100.0), BlendMode::Add, 1.0) },
        layer(LayerSpec::constant("clear", 100.0), BlendMode::Add, 0.0),
    ];
    let mut r = renderer(&p);
    let camera = cam(39.3, 40.42, 30_000.0, 0.0, -45.0);
    let settled = r.settle(&camera, 320, 240, Duration::from_secs(120));
    assert_eq!(settled.pending, 0);
    let first = r.compose_counters();
    assert!(first.quads > 0);
    // Hidden, transparent and distant layers are never read: at most 2 layers per quad.
    assert!(first.layers_read <= 2 * first.quads, "{first:?}");
    // Nothing changed: nothing is recomposed.
    for _ in 0..3 {
        r.prepare(&camera, 320, 240);
    }
    assert_eq!(r.compose_counters().quads, first.quads, "an unchanged stack recomposes nothing");
    // The far layer changes: it touches no drawn quad.
    let mut far = p.layers[2].clone();
    far.offset_m = 10.0;
    r.update_layer(2, far).unwrap();
    let s = r.prepare(&camera, 320, 240);
    assert!(s.composed.is_empty(), "{s:?}");
    // The east layer changes: exactly the drawn quads it touches are recomposed, and of the
    // quads above them the ones whose data their coarser strides show (up to five levels up) and
    // it touches (the view is settled, so the frame draws the same quads and composes no new
    // ones).
    let touches = |r: &Renderer, q: &QuadId, layer: usize| r.scene().plan(*q).layers.iter().any(|l| l.index == layer);
    let mut east = p.layers[1].clone();
    east.opacity = 0.9;
    r.update_layer(1, east).unwrap();
    let s = r.prepare(&camera, 320, 240);
    let drawn = r.drawn().to_vec();
    let mut touching: Vec<QuadId> = drawn.iter().copied().filter(|q| touches(&r, q, 1)).collect();
    assert!(!touching.is_empty() && touching.len() < drawn.len(), "{} of {}", touching.len(), drawn.len());
    let mut composed = s.composed.clone();
    composed.sort();
    touching.sort();
    let drawn_recomposed: Vec<QuadId> = composed.iter().copied().filter(|q| drawn.contains(q)).collect();
    assert_eq!(drawn_recomposed, touching, "recomposed exactly the drawn quads the edited layer touches");
    for q in &composed {
        let above_a_drawn_one = drawn.iter().any(|d| d.ancestors().take(5).any(|a| a == *q));
        assert!(drawn.contains(q) || (above_a_drawn_one && touches(&r, q, 1)), "{q} recomposed");
    }
    // Showing the hidden layer recomposes every drawn quad with data (it has no extent).
    let mut hidden = p.layers[3].clone();
    hidden.visible = true;
    r.update_layer(3, hidden).unwrap();
    let s = r.prepare(&camera, 320, 240);
    assert!(s.composed.iter().all(|q| touches(&r, q, 3)));
    let stack = &r.scene().stack;
    let with_data: Vec<QuadId> = r.drawn().iter().copied().filter(|q| r.scene().plan(*q).has_data(stack)).collect();
    assert!(
        !with_data.is_empty() && with_data.iter().all(|q| s.composed.contains(q)),
        "{with_data:?} vs {:?}",
        s.composed
    );
}

#[test]
fn raising_the_terrain_by_5_km_culls_and_cracks_nothing() {
    let p = Project::load(&common::sample_project("moon-lola", &common::out_path("compose"))).unwrap();
    let mut p2 = p.clone();
    p2.layers.push(layer(LayerSpec::constant("raise", 5000.0), BlendMode::Add, 0.0));
    let mut r = renderer(&p2);
    // Looking towards the horizon from low over Tycho (the horizon dips 10.6° at 30 km):
    // terrain fills the lower half of the image.
    let camera = cam(-43.3, -11.2, 30_000.0, 0.0, -22.0);
    let coverage = |r: &mut Renderer| {
        let s = r.settle(&camera, 240, 180, Duration::from_secs(120));
        assert_eq!(s.pending, 0);
        let image = r.render_image(DrawMode::Probe).unwrap();
        let (ids, surface) = (image.ids.unwrap(), image.surface.unwrap());
        let lower = &ids[ids.len() / 2..];
        let holes = lower.iter().filter(|id| id[0] == 0).count();
        let heights: Vec<f32> =
            lower.iter().zip(&surface[ids.len() / 2..]).filter(|(id, _)| id[0] != 0).map(|(_, s)| s[3]).collect();
        (holes, heights.iter().copied().fold(f32::INFINITY, f32::min), r.drawn().len())
    };
    let (holes, low, _) = coverage(&mut r);
    assert_eq!(holes, 0);
    let mut raise = p2.layers.last().unwrap().clone();
    raise.opacity = 1.0;
    r.update_layer(p2.layers.len() - 1, raise).unwrap();
    let (holes, raised_low, quads) = coverage(&mut r);
    assert_eq!(holes, 0, "no quad culled or cracked after raising by 5 km ({quads} quads)");
    // Every sample is 5 km higher; the lowest visible one may be another place: ≥ 2.5 km higher.
    assert!(raised_low > low + 2500.0, "lowest visible height {low} → {raised_low}");
}

#[test]
fn a_settled_view_stays_settled_when_detail_fills_the_gpu_cache() {
    // Procedural detail refines far below SRTM's finest level and fills a small GPU cache. Split
    // quads whose children are all culled must keep their slots: evicting them once made every
    // other frame collapse to a few coarse quads (and `settle` stop on the collapsed one).
    let mut p = Project::load(&erzurum()).unwrap();
    p.detail.gpu_cache_mib = 256;
    p.layers.push(layer(
        LayerSpec::procedural(
            "detail",
            NoiseSpec { placement: DetailWhere::BeyondData, ..noise(NoiseType::Fbm, 14.0, 140.0, 7) },
        ),
        BlendMode::Add,
        1.0,
    ));
    let mut r = renderer(&p);
    let camera = cam(39.55, 40.3, 2600.0, 60.0, -25.0);
    let settled = r.settle(&camera, 400, 300, Duration::from_secs(300));
    let deepest = settled.selection.quads.iter().map(|q| q.level).max().unwrap();
    assert!(deepest > 9, "detail refines below the data's level 9: {:?}", settled.selection.per_level());
    let drawn = r.drawn().to_vec();
    for _ in 0..6 {
        let s = r.prepare(&camera, 400, 300);
        assert_eq!(s.selection.quads, drawn, "the drawn set stays the same frame after frame");
    }
}

#[test]
fn a_feathered_max_layer_beside_a_dataset_agrees_on_where_there_is_data() {
    // The bench's two-layer stack: SRTM under a feathered `max` plateau that reaches past the
    // tile, so at some samples the plateau alone gives data.
    let mut p = Project::load(&erzurum()).unwrap();
    p.layers.push(LayerSpec {
        blend: BlendMode::Max,
        opacity: 0.6,
        extent: Some(ExtentSpec::Box([40.3, 39.3, 40.9, 40.1])),
        feather_m: 8000.0,
        ..LayerSpec::constant("plateau", 2600.0)
    });
    let mut r = renderer(&p);
    let e = Ellipsoid::WGS84;
    let mut quads = Vec::new();
    for row in 0..8 {
        for c in 0..8 {
            let q = quad_at(&e, 39.2 + 0.1 * f64::from(row), 40.05 + 0.1 * f64::from(c), 9);
            if !quads.contains(&q) && quads.len() < 16 {
                quads.push(q);
            }
        }
    }
    let (worst, _) = gpu_against_cpu(&mut r, &quads, &store_tiles);
    assert!(worst < 0.01, "{worst}");
}

#[test]
fn the_version_1_moon_project_loads_as_over_layers_first_listed_on_top_and_saves_in_the_current_version() {
    let v1 = common::repo_path("tests/fixtures/moon-lola-v1.json");
    assert!(std::fs::read_to_string(&v1).unwrap().contains("\"datasets\""));
    let p = Project::load(&v1).unwrap();
    assert_eq!(p.version, terrafuse::project::VERSION);
    let names: Vec<&str> = p.layers.iter().map(|l| l.name.as_str()).collect();
    assert_eq!(names, ["lola_global", "lola_north"], "the first listed (north) wins, so it is on top");
    assert!(p.layers.iter().all(|l| l.blend == BlendMode::Over && l.extent.is_none()));
    let out = common::out_path("compose");
    std::fs::create_dir_all(&out).unwrap();
    let saved = out.join("moon-migrated.json");
    p.save(&saved).unwrap();
    let text = std::fs::read_to_string(&saved).unwrap();
    assert!(
        text.contains(&format!("\"version\": {}", terrafuse::project::VERSION))
            && text.contains("\"layers\"")
            && !text.contains("\"datasets\"")
    );
    assert_eq!(Project::load(&saved).unwrap().layers, p.layers);
}

#[test]
fn hiding_and_showing_the_only_layer_brings_the_terrain_back() {
    let mut p = Project::load(&common::sample_project("moon-lola", &common::out_path("compose"))).unwrap();
    p.detail.gpu_cache_mib = 256;
    let mut r = renderer(&p);
    let camera = cam(15.0, -20.0, 3_500_000.0, 0.0, -90.0);
    let with_data = |r: &mut Renderer| {
        let s = r.settle(&camera, 160, 120, Duration::from_secs(300));
        let image = r.render_image(DrawMode::Probe).unwrap();
        let ids = image.ids.unwrap();
        (ids.iter().filter(|id| id[0] != 0 && id[3] & 1 == 1).count(), ids.iter().filter(|id| id[0] != 0).count(), s)
    };
    let (data, drawn, _) = with_data(&mut r);
    assert!(data > 0 && data == drawn, "{data} of {drawn}");
    let mut layer = p.layers[0].clone();
    layer.visible = false;
    r.update_layer(0, layer.clone()).unwrap();
    let (data, drawn, _) = with_data(&mut r);
    assert!(data == 0 && drawn > 0, "hidden: {data} of {drawn} pixels with data");
    layer.visible = true;
    r.update_layer(0, layer).unwrap();
    let (data, drawn, s) = with_data(&mut r);
    assert!(
        data > 0 && data == drawn,
        "shown again: {data} of {drawn} pixels with data ({} quads)",
        s.selection.quads.len()
    );
}

#[test]
fn a_dataset_fades_in_from_its_own_no_data_edge_by_the_distance_on_the_surface_without_seams() {
    // The SRTM tile (40°E to 40°50'E) over a constant 0 m with feather_edge_m = 5 km: the
    // composed height is α·v, so α = h / v at every sample with data, and α must be
    // smoothstep(d / 5 km) with d the distance to the raster's west edge along the parallel,
    // N(φ)·cos φ·Δλ (independent of the distance field: geodesy on the raster's bounds).
    let feather = 5000.0;
    let mut p = Project::load(&erzurum()).unwrap();
    let srtm = p.layers[0].clone();
    p.layers = vec![LayerSpec::constant("base", 0.0), srtm.with_feather_edge_m(feather)];
    let mut r = renderer(&p);
    let e = Ellipsoid::WGS84;
    let a = quad_at(&e, 39.5, 40.02, 10);
    let level9 = quad_at(&e, 39.5, 40.02, 9);
    let mut quads = vec![a, level9];
    for q in [a, level9] {
        quads.extend(Edge::ALL.map(|edge| q.neighbour(edge).quad));
    }
    let (worst, with_data) = gpu_against_cpu(&mut r, &quads, &store_tiles);
    println!("GPU − CPU with an edge feather: worst {worst:.2e} m over {with_data} samples");
    assert!(worst < 0.01, "worst GPU − CPU difference {worst} m");

    // The mask against the independent distance.
    let scene = r.scene();
    let plan = scene.plan(a);
    let raw = store_tiles(scene, a, 1).0.unwrap();
    let composed = r.read_heights(a).unwrap().unwrap();
    let (mut worst_alpha, mut in_band) = (0f64, 0);
    for k in 0..257 * 257 {
        let (v, h) = (f64::from(raw[k]), f64::from(composed[k]));
        if v.is_nan() || v.abs() < 100.0 {
            continue;
        }
        let (_, lon, lat) = terrafuse::ecm::points::sample_point(&e, a, 257, (k % 257) as u32, (k / 257) as u32);
        let n = e.a_m() / (1.0 - e.e2() * lat.sin().powi(2)).sqrt();
        let d = n * lat.cos() * (lon - 40f64.to_radians());
        let expected = terrafuse::maths::smoothstep(d / feather);
        worst_alpha = worst_alpha.max((h / v - expected).abs());
        in_band += usize::from(d < feather);
    }
    assert_eq!(plan.layers.len(), 2);
    assert!(in_band > 10_000, "the quad should cross the feather band: {in_band} samples in it");
    // d is known to about 150 m (the store's edge within a sample of the raster's, the field's
    // level-9 spacing of 70 m, bilinear resampling to level 10): 1.5 × 150 / 5000 = 0.045.
    println!("edge mask against smoothstep(d / F): worst {worst_alpha:.4} over {in_band} samples in the band");
    assert!(worst_alpha < 0.05, "edge mask off by {worst_alpha}");

    // No seam: neighbouring quads agree on their shared edges, at level 10 (fields resampled
    // from level-9 ancestors, two of them across the edges to other parents) and at level 9
    // (fields of their own), where the band crosses the edge.
    let mut crossed = 0;
    for q in [a, level9] {
        let ours = r.read_heights(q).unwrap().unwrap();
        let raw = store_tiles(r.scene(), q, 1).0.unwrap();
        for edge in Edge::ALL {
            let theirs_quad = q.neighbour(edge).quad;
            assert_eq!(theirs_quad.face, q.face, "the test's quads are inside one face");
            let theirs = r.read_heights(theirs_quad).unwrap().unwrap();
            let (mut seam, mut fading) = (0f32, 0);
            for t in 0..257 {
                let (k_ours, k_theirs) = match edge {
                    Edge::East => (t * 257 + 256, t * 257),
                    Edge::West => (t * 257, t * 257 + 256),
                    Edge::North => (256 * 257 + t, t),
                    Edge::South => (t, 256 * 257 + t),
                };
                let (o, n) = (ours[k_ours], theirs[k_theirs]);
                assert_eq!(o.is_nan(), n.is_nan());
                if !o.is_nan() {
                    seam = seam.max((o - n).abs());
                }
                let v = raw[k_ours];
                fading += usize::from(v > 100.0 && o < 0.99 * v && o > 0.0);
            }
            println!("seam between {q} and {theirs_quad}: {seam:.2e} m, {fading} edge samples fading");
            assert!(seam < 0.01, "a seam of {seam} m between {q} and {theirs_quad}");
            crossed += usize::from(fading > 0);
        }
    }
    assert!(crossed >= 2, "the feather band should cross shared edges");
}

#[test]
fn a_settled_view_after_swapping_the_shown_dataset_equals_a_fresh_renderers_pixel_for_pixel() {
    // Regression: a drawn quad whose layers changed stays drawn with its old heights until its
    // new sources arrive, and `settle` took the view for complete meanwhile (the old dataset
    // stayed on screen). Such quads now count as pending.
    let p = common::sample_project("erzurum-compare", &common::out_path("compose-swap"));
    let project = Project::load(&p).unwrap();
    let camera = project.view(None).unwrap();
    let mut swapped = project.clone();
    swapped.layers[0].visible = false; // srtm
    swapped.layers[1].visible = true; // blurred
    let mut r = renderer(&swapped);
    r.settle(&camera, 320, 240, Duration::from_secs(120));
    for (index, visible) in [(0, true), (1, false)] {
        let spec = LayerSpec { visible, ..r.scene().stack.layers[index].spec.clone() };
        r.update_layer(index, spec).unwrap();
    }
    let before = r.compose_counters().quads;
    r.settle(&camera, 320, 240, Duration::from_secs(120));
    assert!(r.compose_counters().quads > before, "nothing was recomposed");
    let edited = r.render_image(DrawMode::Colour).unwrap();
    let mut fresh = renderer(&project);
    fresh.settle(&camera, 320, 240, Duration::from_secs(120));
    let reference = fresh.render_image(DrawMode::Colour).unwrap();
    let differing = edited.rgba.chunks(4).zip(reference.rgba.chunks(4)).filter(|(a, b)| a != b).count();
    assert_eq!(differing, 0, "{differing} pixels differ from a fresh renderer's");
}

#[test]
fn frames_composed_by_the_cpu_reference_hold_the_heights_and_draw_the_pixels_the_compute_pass_does() {
    // A software adapter composes its frames with the CPU reference (faster there); the heights
    // it writes into the slots, the drawn difference's A − B among them, must be those of the
    // compute pass within its f32 contract, and the images the same.
    let p = common::sample_project("erzurum-compare", &common::out_path("compose-frame-cpu"));
    let project = Project::load(&p).unwrap();
    let camera = project.view(None).unwrap();
    let mut settled = [ComposeOn::Gpu, ComposeOn::Cpu].map(|on| {
        let mut r = renderer_on(&project, on);
        let s = r.settle(&camera, 320, 240, Duration::from_secs(120));
        assert_eq!(s.pending, 0, "{on:?}: the view settles");
        (r, s)
    });
    assert_eq!(settled[0].1.selection.quads, settled[1].1.selection.quads, "the same quads are drawn");
    let mut worst = 0f64;
    let mut compared = 0;
    let mut differences = 0;
    for q in settled[0].1.selection.quads.clone() {
        let read = |r: &Renderer| [r.read_heights(q).unwrap(), r.read_difference(q).unwrap()];
        let [gpu, cpu] = [read(&settled[0].0), read(&settled[1].0)];
        for (what, gpu, cpu) in [("heights", &gpu[0], &cpu[0]), ("A − B", &gpu[1], &cpu[1])] {
            assert_eq!(gpu.is_some(), cpu.is_some(), "{q}: {what} on one side only");
            let (Some(gpu), Some(cpu)) = (gpu, cpu) else { continue };
            differences += usize::from(what == "A − B");
            for (g, c) in gpu.iter().zip(cpu) {
                assert_eq!(g.is_nan(), c.is_nan(), "{q}: {what}: no data on one side only");
                if !g.is_nan() {
                    worst = worst.max(f64::from((g - c).abs()));
                    compared += 1;
                }
            }
        }
    }
    assert!(compared > 100_000 && differences > 0, "only {compared} samples, {differences} differences compared");
    // The compute pass against the reference: within 10⁻³ m (tests above, every layer kind).
    assert!(worst < 1e-3, "the slots differ by {worst} m");
    let images = settled.each_mut().map(|(r, _)| r.render_image(DrawMode::Colour).unwrap());
    let off = images[0].rgba.iter().zip(&images[1].rgba).filter(|(a, b)| a.abs_diff(**b) > 1).count();
    assert_eq!(off, 0, "{off} channels differ by more than 1/255");
}
